"""Tests of tracker/preprocess.py."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from tracker import Road, TrackerConfig
from tracker.preprocess import bearing_filter, drop_nonfinite, road_bound_mask
from tracker.transforms import to_global, to_local


def test_drop_nonfinite_counts():
    pts = np.array([[1.0, 2.0], [np.nan, 0.0], [3.0, np.inf], [4.0, 5.0]])
    kept, dropped = drop_nonfinite(pts)
    np.testing.assert_array_equal(kept, [[1.0, 2.0], [4.0, 5.0]])
    assert dropped == 2


def test_frame_transforms_round_trip():
    rng = np.random.default_rng(0)
    pts = rng.normal(size=(50, 2)) * 20
    g = to_global(pts, (10.0, -3.0), 0.7)
    np.testing.assert_allclose(to_local(g, (10.0, -3.0), 0.7), pts, atol=1e-12)
    # a point 1 m ahead of an ego heading +y is 1 m north of it
    np.testing.assert_allclose(to_global(np.array([[1.0, 0.0]]), (0.0, 0.0), np.pi / 2), [[0.0, 1.0]], atol=1e-12)


def test_road_bound_mask_keeps_road_points_only():
    road = Road.from_curvature([(200.0, 0.0, 0.0)], lanes=2, lane_width=3.5)  # bounds n in [-3.5, 3.5]
    pts = np.array([[50.0, 0.0], [50.0, 3.9], [50.0, 4.1], [50.0, -8.0], [250.0, 0.0]])
    np.testing.assert_array_equal(road_bound_mask(pts, road, margin=0.5), [True, True, False, False, False])
    assert road_bound_mask(np.zeros((0, 2)), road).shape == (0,)


def test_bearing_filter_keeps_closest_point_per_bin():
    # a wall at x = 10 and points behind it at x = 20 along the same bearings
    y = np.linspace(-2.0, 2.0, 21)
    near = np.column_stack([np.full_like(y, 10.0), y])
    far = 2.0 * near
    pts = np.vstack([far, near])
    kept = bearing_filter(pts, bin_width=np.deg2rad(0.5))
    assert set(kept.tolist()) == set(range(21, 42))
    bearings = np.arctan2(pts[kept, 1], pts[kept, 0])
    assert np.all(np.diff(bearings) > 0)
    with pytest.raises(ValueError, match="bin_width"):
        bearing_filter(pts, 0.0)


def test_lidar_points_take_a_3d_cloud_through_the_ground_removal():
    """An (N, 3) cloud in the lidar's frame (1.9 m up): the level ground ring goes, a wall of points
    1 m up stays and is projected to (x, y) in E; counts name every removal; a 2-D frame passes as is."""
    from tracker.cloud import CloudConfig
    from tracker.frame import Frame
    from tracker.preprocess import lidar_points, preprocess_frame

    az = np.radians(np.arange(-180.0, 180.0, 0.5))
    ground = np.stack([20.0 * np.cos(az), 20.0 * np.sin(az), np.full(az.shape, -1.9)], axis=1)  # z = 0 in E
    ground = np.concatenate([ground * [r / 20.0, r / 20.0, 1.0] for r in (8.0, 12.0, 20.0)])
    wall = np.stack([np.full(20, 15.0), np.linspace(-2, 2, 20), np.full(20, -0.9)], axis=1)  # 1 m up
    cloud = np.concatenate([ground, wall, [[np.nan, 0.0, 0.0]]])
    frame = Frame(0.0, (0.0, 0.0, 0.0), cloud)
    pts, counts, result = lidar_points(frame, CloudConfig())
    np.testing.assert_allclose(pts, wall[:, :2], atol=1e-9)
    assert counts == {"points_nonfinite": 1, "cloud_points": len(cloud), "cloud_ego_body": 0, "cloud_ground": len(ground),
                      "cloud_below_ground": 0, "cloud_above_ceiling": 0, "cloud_low_object": counts["cloud_low_object"], "cloud_seen_over": 0, "cloud_segments_fallback": counts["cloud_segments_fallback"]}
    assert result.kept.sum() == 20
    road = Road.from_curvature([(200.0, 0.0, 0.0)], start=(-50.0, 0.0, 0.0), lanes=2)
    scan, kept, all_counts = preprocess_frame(frame, road, TrackerConfig().clustering)
    assert len(scan) == 20 and all_counts["cloud_ground"] == len(ground) and all_counts["points_off_road"] == 0
    flat = Frame(0.0, (0.0, 0.0, 0.0), wall[:, :2])
    pts2, counts2, none = lidar_points(flat)
    assert none is None and counts2 == {"points_nonfinite": 0} and np.array_equal(pts2, wall[:, :2])


def test_bearing_filter_keeps_every_ray_of_the_lidar_grid():
    """Every ray of a 0.2 deg full-circle scan (bearings -180 + 0.2 k deg) keeps its own bin, whatever
    the range; a second point on a ray (behind the first) is dropped; +-180 deg is one bin."""
    b = -np.pi + np.radians(0.2) * np.arange(1, 1801)
    r = 5.0 + 90.0 * np.random.default_rng(1).random(1800)
    pts = r[:, None] * np.stack([np.cos(b), np.sin(b)], axis=1)
    kept = bearing_filter(pts, np.radians(0.2))
    assert len(kept) == 1800
    behind = np.vstack([pts, 1.5 * pts])
    assert sorted(bearing_filter(behind, np.radians(0.2)).tolist()) == list(range(1800))
    wrap = np.array([[-10.0, 1e-9], [-20.0, -1e-9]])  # just either side of +-180 deg
    assert bearing_filter(wrap).tolist() == [0]


def test_bearing_filter_with_bins_of_the_lidar_step_keeps_only_each_rays_nearest_return():
    """An OS1-128's 1,024 columns (0.3516 deg apart), each with a near return (a vehicle's face) and
    four farther ones on the same ray (returns over its roof): with bins of the lidar's step every
    column keeps its near return and nothing else. With 0.2 deg bins, 8 of the columns lie on bin
    edges (22.5 deg is 112.5 bins), float rounding puts their returns into two bins, and a return
    from behind a face survives: why ``TrackerConfig`` refuses a bin narrower than the step."""
    step = 2.0 * np.pi / 1024
    b = -np.pi + step * np.arange(1, 1025)
    r = 5.0 + 30.0 * np.random.default_rng(2).random(1024)
    u = np.stack([np.cos(b), np.sin(b)], axis=1)
    pts = np.vstack([r[:, None] * u] + [(r + d)[:, None] * u for d in (1.1, 2.3, 3.5, 4.7)])
    assert sorted(bearing_filter(pts, step).tolist()) == list(range(1024))
    narrow = bearing_filter(pts, np.radians(0.2))
    assert (narrow >= 1024).sum() >= 1  # a return from behind a face kept


@pytest.mark.parametrize("closed", [False, True])
def test_filter_points_fused_kernel_equals_staged_path(closed, monkeypatch):
    """``filter_points``' one compiled call (``tracker.preprocess.road_filter_kernel``) gives
    bit for bit what its steps give one by one (``to_global``, ``Road.to_frenet``, ``within_bounds``,
    ``bearing_filter``): returns on and off the road, beyond an open road's ends, a wall behind a car in
    the same bearings; and returns off the seed grid (seeded from the k-d tree, then a second call)."""
    import tracker.preprocess as pre
    from tracker.frame import EgoState

    if closed:
        road = Road.from_waypoints(np.array([[100.0, 0.0], [0.0, 100.0], [-100.0, 0.0], [0.0, -100.0]]), closed=True,
                                   lanes=3, lane_width=3.5)
        ego = EgoState(100.0, 5.0, 1.6, 10.0, 0.0)
    else:
        road = Road.from_curvature([(80.0, 0.0, 0.0), (120.0, 0.0, 0.02)], lanes=3, lane_width=3.5)
        ego = EgoState(5.0, 1.0, 0.05, 10.0, 0.0)
    config = TrackerConfig().clustering
    rng = np.random.default_rng(3)
    car = np.column_stack([np.full(40, 12.0), np.linspace(-1.0, 1.0, 40)])
    # within the seed grid (the road's neighbourhood); some beyond an open road's start (s < 0)
    box = rng.uniform([-40.0, -15.0], [40.0, 15.0], size=(600, 2)) if closed else rng.uniform([-15.0, -15.0], [70.0, 15.0], size=(600, 2))
    scan = np.concatenate([box, car, 1.6 * car,
                           np.array([[-10.0, 0.0], [0.5, 0.0], [0.0, 0.5]])])
    staged = pre._filter_compiled

    def fused_and_staged(points):
        monkeypatch.setattr(pre, "_filter_compiled", staged)
        got = pre.filter_points(points, ego, road, config)
        monkeypatch.setattr(pre, "_filter_compiled", lambda *a: None)
        ref = pre.filter_points(points, ego, road, config)
        assert got[1] == ref[1]
        for a, b in ((got[0], ref[0]), (got[2], ref[2])):
            np.testing.assert_array_equal(a, b)
            assert a.dtype == b.dtype
        return got

    assert staged(scan, ego, road, config) is not None  # the fused call applies
    got = fused_and_staged(scan)
    assert 0 < len(got[0]) < len(scan) and got[1]["points_off_road"] > 0 and got[1]["points_bearing_filtered"] > 0
    # returns far off the seed grid: seeded from the k-d tree and a second call, the same answer
    far = np.concatenate([scan, [[300.0, 300.0], [-200.0, 250.0], [0.0, 30.0]]])
    seeded = []
    monkeypatch.setattr(road, "seed_missing", lambda *a: seeded.append(a) or Road.seed_missing(road, *a))
    # returns surely off the road (their seed-grid cell, or none, lies farther from the centerline than
    # the edges plus the margin) are not projected: no second call
    assert staged(far, ego, road, config) is not None and seeded == []
    fused_and_staged(far)
    clearance, offgrid, extent = road.clearance_kernel_args()
    assert offgrid > extent + config.road_margin
    # with a margin wider than the seed grid's reach they are: seeded from the k-d tree, a second call
    config = replace(config, road_margin=offgrid - extent + 1.0)
    seeded.clear()
    assert staged(far, ego, road, config) is not None and len(seeded) == 1
    fused_and_staged(far)


def test_filter_points_names_a_non_finite_return():
    """A NaN return reaches ``filter_points`` only from a caller that skipped ``drop_nonfinite``: a
    clear error (the fused call hands it to the steps one by one, whose projection names it)."""
    from tracker.frame import EgoState
    from tracker.preprocess import filter_points

    road = Road.from_curvature([(200.0, 0.0, 0.0)], lanes=2, lane_width=3.5)
    scan = np.array([[10.0, 0.0], [np.nan, 1.0], [20.0, 1.0]])
    with pytest.raises(ValueError, match="finite"):
        filter_points(scan, EgoState(5.0, 0.0, 0.0, 10.0, 0.0), road, TrackerConfig().clustering)


@pytest.mark.parametrize("bin_deg", [0.2, 0.37])
def test_bearing_filter_kernel_against_the_oracle(bin_deg):
    """``bearing_filter`` (``bearing_filter_kernel``) against the oracle's sort: a scan of rays on the
    bins' centres, points sharing a bin at equal ranges (the first index wins), points across +-pi (one
    bin when the bins tile the circle, 0.2 deg; not for 0.37 deg); the same indices in the same order."""
    from oracles.preprocess import bearing_filter as oracle_bearing_filter

    rng = np.random.default_rng(13)
    width = np.deg2rad(bin_deg)
    rays = np.arange(-np.pi, np.pi, width)
    ranges = rng.uniform(2.0, 90.0, len(rays))
    pts = [np.column_stack([ranges * np.cos(rays), ranges * np.sin(rays)])]
    pts.append(rng.normal(0.0, 30.0, (500, 2)))
    pts.append(pts[0][::7] * 1.0)  # the same points again: equal ranges in one bin
    pts.append(np.array([[-10.0, 1e-12], [-10.0, -1e-12], [-12.0, 0.0]]))  # across +-pi
    pts = np.concatenate(pts)
    rng.shuffle(pts)
    got = bearing_filter(pts, width)
    assert np.array_equal(got, oracle_bearing_filter(pts, width)) and len(got) >= len(rays) // 2


@pytest.mark.parametrize("resolution_deg", [0.2, 360.0 / 1024])
def test_nearest_per_ray_keeps_the_nearest_return_of_each_ray(resolution_deg):
    """``nearest_per_ray``: of returns stacked along rays (a 3-D cloud's beams projected: up to 128 per
    ray, and returns behind them), each ray keeps exactly its nearest, in ray order; against a
    brute-force oracle per ray; where a ray's returns share its bearing (the beams of a spinning
    lidar), the detection model's occlusion by the scan is the same with the kept returns as with all."""
    from tracker.detection import scan_occluded_fraction
    from tracker.measurement import Rectangles
    from tracker.preprocess import nearest_per_ray

    rng = np.random.default_rng(3)
    res = np.radians(resolution_deg)
    rays = rng.choice(round(2 * np.pi / res), 400, replace=False)
    jitter = rng.uniform(-0.4 * res, 0.4 * res, 4800)  # within the ray's bin
    r = rng.uniform(2.0, 90.0, 4800)
    for bearing in (np.repeat(rays * res, 12) + jitter, np.repeat(rays * res, 12)):
        pts = np.column_stack([r * np.cos(bearing), r * np.sin(bearing)])
        kept = nearest_per_ray(pts, res)
        assert len(kept) == len(rays)
        bins = np.floor(np.arctan2(pts[:, 1], pts[:, 0]) / res + 0.5).astype(int) % round(2 * np.pi / res)
        oracle = {b: pts[bins == b][np.argmin(np.hypot(*pts[bins == b].T))] for b in np.unique(bins)}
        np.testing.assert_array_equal(kept, np.array([oracle[b] for b in sorted(oracle)]))
    # a spinning lidar fires a ray's beams at its bearing: the occlusion by the kept returns is the same
    cars = Rectangles(center=np.array([[40.0, 5.0], [-30.0, -20.0], [10.0, 60.0]]), psi=np.array([0.1, 1.0, 2.0]), v=np.zeros(3),
                      length=np.array([4.5, 12.0, 5.0]), width=np.array([1.8, 2.5, 2.0]))
    np.testing.assert_allclose(scan_occluded_fraction(cars, kept, res), scan_occluded_fraction(cars, pts, res))
    assert len(nearest_per_ray(np.zeros((0, 2)), res)) == 0
    with pytest.raises(ValueError, match="resolution"):
        nearest_per_ray(pts, 0.0)
