"""The Stone Soup GM-PHD baseline (sim/baselines/stonesoup_gmphd.py): input centroids, the Cartesian
view it reports, the install hint, and that it tracks a car end to end."""

import math
import sys

import numpy as np
import pytest

from sim import load_scenario
from sim.baselines.stonesoup_gmphd import (
    INSTALL_HINT,
    MissingBaselineError,
    StoneSoupGMPHD,
    _cartesian_view,
    import_stonesoup,
)
from sim.evaluation.runner import run_scenario
from tracker import EgoState, Frame, Road, TrackerConfig

pytest.importorskip("stonesoup")


def _road() -> Road:
    return Road.from_curvature([(300.0, 0.0, 0.0)], start=(0.0, 0.0, 0.0), lanes=3)


def test_centroids_are_cluster_means_in_the_global_frame():
    tracker = StoneSoupGMPHD(_road(), TrackerConfig.for_variant("curvilinear-lidar"))
    # two tight groups of points in E (ego at (100, 0) heading +x, so E is G shifted by 100 m), each point
    # at its own bearing (the bearing filter keeps them all)
    a = np.array([[10.0, 0.0], [10.0, 0.3], [10.0, 0.6], [10.5, 0.9]])
    b = np.array([[30.0, -2.0], [30.0, -2.5], [30.5, -3.0]])
    frame = Frame(0.0, EgoState(100.0, 0.0, 0.0, 20.0), np.vstack([a, b, [[np.nan, 0.0]]]))
    c = tracker.centroids(frame)
    order = np.argsort(c[:, 0])
    np.testing.assert_allclose(c[order], [a.mean(axis=0) + [100.0, 0.0], b.mean(axis=0) + [100.0, 0.0]], atol=1e-12)
    assert tracker.stats["points_nonfinite"] == 1
    # ego heading +y at (100, -10): E's x axis is G's y axis, so the group lands on the road near (99.5, 0.1)
    frame = Frame(0.0, EgoState(100.0, -10.0, math.pi / 2, 20.0), a)
    np.testing.assert_allclose(tracker.centroids(frame), [[100.0 - a[:, 1].mean(), -10.0 + a[:, 0].mean()]], atol=1e-12)


def test_cartesian_view_of_the_velocity_state():
    cov = np.diag([0.5, 0.2, 0.3, 0.1, 0.01])
    mean, out = _cartesian_view(np.array([1.0, 3.0, 2.0, 4.0, 0.05]), cov)
    np.testing.assert_allclose(mean, [1.0, 2.0, 5.0, math.atan2(4.0, 3.0), 0.05, 0.0, 0.0])
    c, s = 0.6, 0.8
    assert out[0, 0] == 0.5 and out[1, 1] == 0.3 and out[4, 4] == 0.01
    assert out[2, 2] == pytest.approx(c * c * 0.2 + s * s * 0.1)  # var of the speed
    assert out[3, 3] == pytest.approx((s * s * 0.2 + c * c * 0.1) / 25.0)  # var of the heading
    assert np.allclose(out, out.T)


def test_missing_stonesoup_says_how_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "stonesoup.updater.pointprocess", None)
    with pytest.raises(MissingBaselineError, match="baselines"):
        import_stonesoup()
    assert "pip install" in INSTALL_HINT


def test_tracks_the_curve_single_car_end_to_end():
    result = run_scenario(load_scenario("curve-single"), 0, "stonesoup-gmphd", duration=4.0, roadside=False)
    m = result.metrics
    assert m["frames"] == 41 and m["truth_count_mean"] == 1.0
    assert m["cardinality_error_mean"] <= 0.15
    # a centroid of the visible sides, not the rectangle centre: about half a car length off (measured 2.3 m)
    assert 1.0 < m["pos_rmse_m"] < 3.0 and m["yaw_rmse_deg"] < 5.0
    assert m["length_rmse_m"] is None and m["width_rmse_m"] is None  # no extent: missing, not zero
    assert result.settings["estimates_extent"] is False
