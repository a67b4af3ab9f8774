"""The soak run (``sim.studies.soak``, ``eot soak``): streamed windows, the covariance check and the summary."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from sim import cli
from sim.studies.soak import SOAK_SCENARIO, SoakConfig, SoakWindow, bad_covariances, run_soak, summarize_soak
from sim.world.scenario import load_scenario


def test_soak_scenario_is_a_closed_dense_road_for_an_hour():
    spec = load_scenario(SOAK_SCENARIO)
    road = spec.build_road()
    assert road.closed and spec.duration == 3600.0 and spec.road.lanes == 3
    assert len(spec.vehicles) >= 60  # dense: the ego sees some 8 vehicles within the lidar's 100 m
    start, end = road.position(np.array([0.0, road.length - 1e-6]))
    assert np.hypot(*(start - end)) < 1e-3  # the loop closes


def test_bad_covariances_counts_asymmetric_negative_and_nonfinite():
    good = np.diag([1.0, 2, 3, 4, 5, 6, 7])
    negative = good.copy()
    negative[0, 0] = -0.16
    asym = good.copy()
    asym[0, 1] = 1e-3
    nan = good.copy()
    nan[3, 3] = np.nan
    assert bad_covariances(np.stack([good, good])) == 0
    assert bad_covariances(np.stack([good, negative, asym, nan])) == 3
    assert bad_covariances(np.zeros((0, 7, 7))) == 0


def _window(t0, rss, ms, frames=10):
    return SoakWindow(t_start=t0, t_end=t0 + 1.0, frames=frames, components_max=12, components_mean=8.0,
                      tracks_mean=4.0, truth_mean=5.0, rss_mb=rss, nonfinite=0, bad_cov=0, tracker_ms_median=ms,
                      tracker_ms_p95=2 * ms, tracker_ms_max=3 * ms, tracker_cpu_ms_median=ms, gospa_mean=1.0, labels_born=2, wall_s=t0)


def test_summary_compares_first_and_last_windows():
    windows = [_window(float(k), 200.0 + 0.5 * k, 10.0 + k) for k in range(20)]
    s = summarize_soak(windows)
    assert s["frames"] == 200 and s["simulated_s"] == 20.0 and s["edge_windows"] == 2
    assert s["rss_growth_mb"] == pytest.approx(9.5) and s["rss_max_mb"] == pytest.approx(209.5)
    assert s["tracker_ms_median_first"] == pytest.approx(10.5) and s["tracker_ms_median_last"] == pytest.approx(28.5)
    assert s["tracker_cpu_ms_median_last"] == pytest.approx(28.5)
    assert s["labels_born"] == 40 and s["components_max"] == 12


def test_short_soak_streams_windows(tmp_path, capsys):
    spec = load_scenario(SOAK_SCENARIO)
    seen = []
    result = run_soak(SoakConfig(spec, duration_s=3.0, window_s=1.0, roadside=False), on_window=seen.append)
    assert seen == result.windows and len(seen) == 3
    assert [w.frames for w in seen] == [11, 10, 10]  # frames at 0.0 .. 1.0, then (1, 2], (2, 3]
    assert [w.t_end for w in seen] == pytest.approx([1.0, 2.0, 3.0])
    s = result.summary
    assert s["frames"] == 31 and s["nonfinite_frames"] == 0 and s["bad_covariances"] == 0
    assert 3.0 <= s["truth_mean"] <= 15.0 and s["components_max"] >= 1 and s["rss_end_mb"] > 10.0
    code = cli.main(["soak", "--duration", "2", "--window", "1", "--no-roadside", "--out", str(tmp_path), "--quiet"])
    assert code == 0 and "components max" in capsys.readouterr().out
    with open(tmp_path / "soak.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 2 and int(rows[0]["frames"]) == 11
    doc = json.loads((tmp_path / "soak.json").read_text())
    assert doc["scenario"] == SOAK_SCENARIO and doc["summary"]["frames"] == 21


def test_soak_rejects_bad_settings():
    spec = load_scenario(SOAK_SCENARIO)
    with pytest.raises(ValueError, match="duration must be in"):
        SoakConfig(spec, duration_s=7200.0)
    with pytest.raises(ValueError, match="window must be"):
        SoakConfig(spec, window_s=0.0)
