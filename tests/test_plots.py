"""Figures and the GIF: every file is written, has the expected size and frame count, and the
figures cope with runs without tracks; the bird's-eye view is fitted to the data, every panel has
labelled axes, snapshot titles count what is drawn, and colours follow the true vehicles."""

from __future__ import annotations

import re

import matplotlib
import numpy as np
import pytest
from oracle_tracker import OracleFactory, SilentTracker
from PIL import Image

from sim import load_scenario
from sim.evaluation.plots import (
    UNMATCHED_COLOR,
    VEHICLE_COLORS,
    birdseye_figure,
    gif_frame_count,
    gospa_figure,
    plot_gospa,
    targets_figure,
    track_colors,
    vehicle_color,
    write_figures,
    write_gif,
)
from sim.evaluation.runner import run_scenario


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
    # the bar counts the 4 figures, then the GIF's 11 frames: (0, 15) first, every step once, (15, 15) last
    assert gif_frame_count(oracle_result) == 11
    assert ticks[0] == (0, 15) and ticks[-1] == (15, 15)
    assert [d for d, _ in ticks] == list(range(16)) and {n for _, n in ticks} == {15}
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


def test_vehicle_colours_cycle():
    assert vehicle_color(3) == vehicle_color(3 + len(VEHICLE_COLORS)) != vehicle_color(4)


def test_figures_without_the_gif_count_every_figure(oracle_result, tmp_path):
    ticks = []
    write_figures(oracle_result, tmp_path, progress=lambda i, n: ticks.append((i, n)))
    assert ticks == [(0, 4), (1, 4), (2, 4), (3, 4), (4, 4)]


def _data_points(result) -> np.ndarray:  # noqa: ANN001
    """Every point the overview draws: the ego's path, the scored vehicles' centres, the track centres."""
    pts = [[f.truth.ego.x, f.truth.ego.y] for f in result.frames]
    pts += [xy for f in result.frames for xy, sc in zip(f.truth.xy, f.scored) if sc]
    pts += [row[:2] for f in result.frames for row in f.track_state]
    return np.asarray(pts, dtype=float)


def test_birdseye_overview_is_fitted_to_the_data(oracle_result):
    fig = birdseye_figure(oracle_result)
    top = fig.axes[0]
    pts = _data_points(oracle_result)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    (x0, x1), (y0, y1) = top.get_xlim(), top.get_ylim()
    assert x0 <= lo[0] and x1 >= hi[0] and y0 <= lo[1] and y1 >= hi[1]  # every point inside
    slack = max(5.0, 0.04 * float(np.max(hi - lo))) + 10.0  # the margin, and the 20 m minimum side
    assert lo[0] - x0 <= slack and x1 - hi[0] <= slack and lo[1] - y0 <= slack and y1 - hi[1] <= slack
    assert top.get_aspect() == 1.0  # equal scale kept
    fig.canvas.draw()  # the drawn limits are still the fitted ones (the box adapts, not the limits)
    assert top.get_xlim() == (x0, x1) and top.get_ylim() == (y0, y1)


def test_every_panel_has_labelled_axes_with_units(oracle_result):
    for fig in (birdseye_figure(oracle_result), gospa_figure(oracle_result), targets_figure(oracle_result)):
        axes = fig.axes
        assert all(re.search(r"\(.+\)", ax.get_ylabel()) for ax in axes), [ax.get_ylabel() for ax in axes]
        for ax in axes:  # an x label on the axes, or on the one it shares x with at the bottom
            shared = ax.get_shared_x_axes().get_siblings(ax)
            assert any(re.search(r"\(.+\)", other.get_xlabel()) for other in shared), ax.get_title()
        heading = (fig._suptitle.get_text() if fig._suptitle is not None else "") + axes[0].get_title()
        assert "curvy-multi" in heading and "seed 0" in heading  # the figure says which run it shows


def test_snapshot_titles_count_what_is_drawn(oracle_result):
    fig = birdseye_figure(oracle_result, half_window=20.0)
    frames = {round(f.t, 1): f for f in oracle_result.frames}
    for ax in fig.axes[1:]:
        m = re.match(r"t = ([\d.]+) s: (\d+) vehicles?(?: \((\d+) not scored\))?, (\d+) tracks?", ax.get_title())
        assert m, ax.get_title()
        f = frames[float(m.group(1))]
        (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()

        def shown(corners: np.ndarray) -> int:
            inside = (corners[..., 0] >= x0) & (corners[..., 0] <= x1) & (corners[..., 1] >= y0) & (corners[..., 1] <= y1)
            return int(inside.any(axis=-1).sum())

        polys = ax.collections  # the ego, the vehicles' outlines, the tracks
        vehicles = polys[1].get_paths() if len(polys) > 1 else []
        assert len(vehicles) == len(f.truth)  # all are drawn (clipped to the view); the title counts the visible
        assert int(m.group(2)) == shown(f.truth.corners())
        st = f.track_state
        from sim.world.truth import rectangle_corners

        tracks = rectangle_corners(st[:, :2], st[:, 3], st[:, 5], st[:, 6]) if len(st) else np.zeros((0, 4, 2))
        assert int(m.group(4)) == shown(tracks)


def test_colours_follow_the_true_vehicles(oracle_result):
    assert len(set(VEHICLE_COLORS)) == len(VEHICLE_COLORS) and UNMATCHED_COLOR not in VEHICLE_COLORS
    f = next(f for f in oracle_result.frames if len(f.tracks))
    assert track_colors(f) == [vehicle_color(v) if v >= 0 else UNMATCHED_COLOR for v in f.track_truth_id]
    # the snapshots fill each track with its GOSPA-assigned vehicle's colour
    fig = birdseye_figure(oracle_result)
    for ax in fig.axes[1:]:
        t = float(re.match(r"t = ([\d.]+)", ax.get_title()).group(1))
        g = next(g for g in oracle_result.frames if round(g.t, 1) == t)
        if len(g.tracks):
            faces = ax.collections[2].get_facecolors()[:, :3]
            expected = np.array([matplotlib.colors.to_rgb(c) for c in track_colors(g)])
            np.testing.assert_allclose(faces, expected)
    # targets.png draws each vehicle's line in that vehicle's colour, named in the legend
    fig = targets_figure(oracle_result)
    legend = fig.axes[0].get_legend()
    for text, handle in zip(legend.get_texts(), legend.legend_handles):
        vid = int(text.get_text().split()[-1])
        assert matplotlib.colors.to_hex(handle.get_color()) == vehicle_color(vid)
