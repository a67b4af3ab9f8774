"""Figures and the GIF: every file is written, has the expected size and frame count, and the
figures cope with runs without tracks."""

from __future__ import annotations

import matplotlib
import numpy as np
import pytest
from oracle_tracker import OracleFactory, SilentTracker
from PIL import Image

from sim import load_scenario
from sim.plots import label_color, plot_gospa, write_figures, write_gif
from sim.runner import run_scenario


@pytest.fixture(scope="module")
def oracle_result():
    spec = load_scenario("curvy-multi")
    return run_scenario(spec, 0, duration=2.0, keep_sensor_data=True, tracker_factory=OracleFactory(spec, 0))


def test_write_figures_and_gif(oracle_result, tmp_path):
    backend = matplotlib.get_backend()
    ticks = []
    paths = write_figures(oracle_result, tmp_path, gif=True, progress=lambda i, n: ticks.append((i, n)))
    assert set(paths) == {"gospa", "gospa_visible", "birdseye", "targets", "gif"}
    for name in ("gospa", "gospa_visible", "birdseye", "targets"):
        with Image.open(paths[name]) as im:
            assert im.format == "PNG" and im.size[0] >= 700 and im.size[1] >= 500
    with Image.open(paths["gif"]) as gif:
        assert gif.format == "GIF" and gif.n_frames == 11  # 21 frames, every 2nd
        assert gif.info["duration"] == pytest.approx(200, abs=10)  # real time: 2 frames of 0.1 s
        first = np.asarray(gif.convert("RGB")).copy()
        gif.seek(10)
        last = np.asarray(gif.convert("RGB"))
    assert not np.array_equal(first, last)  # the view moves with the ego
    assert ticks[-1] == (11, 11)
    assert matplotlib.get_backend() == backend  # figures never switch the session's backend


def test_gif_needs_sensor_data(tmp_path):
    spec = load_scenario("curve-single")
    result = run_scenario(spec, 0, duration=0.3, tracker_factory=SilentTracker)
    with pytest.raises(ValueError, match="keep_sensor_data=True"):
        write_gif(result, tmp_path / "x.gif")


def test_figures_without_tracks(tmp_path):
    spec = load_scenario("curve-single")
    result = run_scenario(spec, 0, duration=0.5, keep_sensor_data=True, tracker_factory=SilentTracker)
    paths = write_figures(result, tmp_path, gif=True)
    assert all(p.stat().st_size > 1000 for p in paths.values())
    # visible-only figure is a different figure
    assert plot_gospa(result, tmp_path / "v.png", visible=True).exists()


def test_label_colours_cycle():
    assert label_color(3) == label_color(13) != label_color(4)
