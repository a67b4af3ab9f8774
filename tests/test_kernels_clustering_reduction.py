"""Kernels of the clustering, the detection model, the births, the reduction and the tracker's steps against their numpy references (moving to tests/oracles)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from tracker import Road, Tracker, TrackerConfig
from tracker import compiled
from tracker.frame import EgoState
from tracker.preparation import prepare_batch

pytest.importorskip("numba")


def _roads():
    open_road = Road.from_curvature([(200.0, 0.0, 0.0), (300.0, 0.0, 1 / 150.0), (600.0, 1 / 150.0, -1 / 80.0)],
                                    lanes=3, lane_width=3.5)
    th = np.linspace(0.0, 2.0 * np.pi, 13)[:-1]
    ring = Road.from_waypoints(np.column_stack([300.0 * np.cos(th), 200.0 * np.sin(th)]), closed=True, lanes=2,
                               lane_width=3.5)
    return {"clothoid-open": open_road, "hermite-closed": ring}


@pytest.mark.parametrize("name", ["clothoid-open", "hermite-closed"])
def test_the_report_centres_equal_to_vehicle_compiled_exactly(name, monkeypatch):
    """``Tracker._extract``'s report-range centres (``tracker.tracker._centres``: one compiled call,
    ``report_centres_kernel``) are ``to_vehicle(means[index]).center``'s compiled numbers bit for bit,
    and numpy's with the kernels off: 7 and 8 columns, beyond an open road's ends, a repeated index, one
    row, none, a non-C-contiguous mixture; a non-finite ``s`` among the rows raises to_vehicle's error."""
    from tracker.measurement import to_vehicle
    from tracker.tracker import _centres

    road = _roads()[name]
    rng = np.random.default_rng(7)
    ego = EgoState(120.0, -40.0, 0.7, 12.0, 0.05)
    for dim in (7, 8):
        means = rng.normal(0.0, 1.0, (30, dim))
        means[:, 0] = rng.uniform(-30.0, road.length + 30.0, 30) % (road.length if road.closed else np.inf)
        means[:, 1] = rng.uniform(-8.0, 8.0, 30)
        means[3, 0] = np.nan  # not among the rows asked for: no error
        for index in (np.array([0, 5, 5, 29, 2]), np.array([11]), np.arange(4, 30), np.zeros(0, dtype=np.intp)):
            index = index.astype(np.intp)
            for switch in ("1", "0"):
                monkeypatch.setenv(compiled.ENV_SWITCH, switch)
                with compiled.pinned():
                    got = _centres(means, index, ego, road, "curvilinear")
                    ref = to_vehicle(means[index], ego, road).center
                assert got.shape == ref.shape == (len(index), 2)
                assert np.array_equal(got, ref)
        monkeypatch.setenv(compiled.ENV_SWITCH, "1")
        strided = np.asfortranarray(means)
        assert np.array_equal(_centres(strided, np.array([1, 2], dtype=np.intp), ego, road, "curvilinear"),
                              to_vehicle(means[[1, 2]], ego, road).center)
        with pytest.raises(ValueError, match="s must be finite"):
            _centres(means, np.array([1, 3], dtype=np.intp), ego, road, "curvilinear")


@pytest.mark.parametrize("seed", range(3))
def test_compiled_detection_model_equals_numpy(seed, monkeypatch):
    """``detection_model`` compiled against numpy: rectangles all around the sensor (across the +-pi
    seam behind it), near and beyond the lidar range, hidden by nearer tracks of other labels and by
    scan returns; without occluders, without a scan, with occlusion off, and for no components."""
    from tracker.config import DetectionConfig
    from tracker.detection import detection_model, occluded_fraction
    from tracker.measurement import Rectangles

    rng = np.random.default_rng(seed)

    def rects(count):
        r, b = rng.uniform(3.0, 110.0, count), rng.uniform(-np.pi, np.pi, count)
        b[:3] = np.pi - rng.uniform(0.0, 0.02, 3)  # straddling the seam behind the sensor
        return Rectangles(np.column_stack([r * np.cos(b), r * np.sin(b)]), rng.uniform(-np.pi, np.pi, count),
                          rng.uniform(0.0, 30.0, count), rng.uniform(2.0, 14.0, count), rng.uniform(1.5, 2.6, count))

    comps, tracks = rects(60), rects(12)
    labels = rng.integers(0, 15, 60)
    track_labels = rng.integers(0, 15, 12)
    scan = np.concatenate([tracks.corners().reshape(-1, 2), rng.uniform(-60.0, 60.0, (400, 2))])
    scan = np.concatenate([scan, scan[:200] * rng.uniform(0.97, 1.03, (200, 1))])  # several beams on one ray
    cases = [(DetectionConfig(), tracks, track_labels, scan), (DetectionConfig(), None, None, scan),
             (DetectionConfig(), tracks, track_labels, None), (DetectionConfig(occlusion=False), tracks, track_labels, scan),
             (DetectionConfig(), tracks.take(np.arange(0)), track_labels[:0], scan[:0])]
    results = []
    for config, occ, occ_labels, sc in cases:
        monkeypatch.setenv(compiled.ENV_SWITCH, "0")
        ref = detection_model(comps, labels, config, occ, occ_labels, scan=sc)
        monkeypatch.setenv(compiled.ENV_SWITCH, "1")
        got = detection_model(comps, labels, config, occ, occ_labels, scan=sc)
        for a, b in zip(ref, got):
            np.testing.assert_allclose(b, a, rtol=1e-12, atol=1e-12)
        results.append(ref)
    for flag in ("0", "1"):  # occluded_fraction on its own (the births' test)
        monkeypatch.setenv(compiled.ENV_SWITCH, flag)
        results.append(occluded_fraction(comps, labels, tracks, track_labels))
    np.testing.assert_allclose(results[-1], results[-2], rtol=1e-12, atol=1e-12)
    assert (results[-1] > 0.0).any()
    p_d = results[0][1]  # occlusion lowers some P_D part-way, range cuts others to 0
    assert ((p_d > 0.0) & (p_d < DetectionConfig().p_detection)).any() and (p_d == 0.0).any()
    monkeypatch.setenv(compiled.ENV_SWITCH, "1")
    empty = detection_model(comps.take(np.arange(0)), labels[:0], DetectionConfig(), tracks, track_labels, scan=scan)
    assert empty[0].shape == (0,) and empty[1].shape == (0,)


@pytest.mark.parametrize("seed", range(4))
def test_compiled_distance_partition_equals_numpy(seed, monkeypatch):
    """Scattered points, a dense random walk (cells holding many points), points exactly on the
    grid's cell boundaries, a few points spread over kilometres (more grid columns than the counting
    sort takes: the cells sorted by argsort) and points too far apart for the grid's keys; thresholds
    from 0.2 to 3 m."""
    from tracker.clustering import distance_partition

    rng = np.random.default_rng(seed)
    clouds = [rng.uniform(-80.0, 80.0, (600, 2)), np.cumsum(rng.normal(0.0, 0.4, (700, 2)), axis=0),
              np.round(rng.uniform(-5.0, 5.0, (300, 2)) / 0.25) * 0.25, rng.uniform(-1.0, 1.0, (1, 2)),
              np.concatenate([rng.uniform(-2000.0, 2000.0, (40, 2)), rng.uniform(0.0, 3.0, (20, 2))]),
              np.array([[0.0, 0.0], [1e18, -1e18], [0.5, 0.0]])]  # keys that would overflow: the numpy path
    for pts in clouds:
        for threshold in (0.2, 0.5 * np.sqrt(2.0), 1.0, 3.0):
            monkeypatch.setenv(compiled.ENV_SWITCH, "0")
            ref = distance_partition(pts, threshold)
            monkeypatch.setenv(compiled.ENV_SWITCH, "1")
            np.testing.assert_array_equal(distance_partition(pts, threshold), ref)


@pytest.mark.parametrize("seed", range(3))
def test_compiled_occluded_ends_equal_numpy(seed, monkeypatch):
    """The bearing ends of clusters of 1-40 points scattered around the sensor (some behind it, across
    the bearing seam, some near the range limit) in a scan of their own points and a few hundred others; windows of 1-5
    rays, and the range cut on and off: the same flags, and some of each."""
    from tracker.clustering import occluded_ends

    rng = np.random.default_rng(seed)
    flags = []
    for _ in range(60):
        clusters = []
        for _ in range(int(rng.integers(1, 12))):
            r, b = rng.uniform(5.0, 100.0), rng.uniform(-np.pi, np.pi)
            centre = r * np.array([np.cos(b), np.sin(b)])
            clusters.append(centre + rng.normal(0.0, 1.0, (int(rng.integers(1, 40)), 2)))
        scan = np.concatenate(clusters + [rng.uniform(-100.0, 100.0, (int(rng.integers(0, 400)), 2))])
        ends = prepare_batch(clusters).bearing_ends()
        for window in np.radians([0.2, 0.5, 1.0]):
            for max_range, range_margin in ((np.inf, 0.0), (100.0, 5.0)):
                monkeypatch.setenv(compiled.ENV_SWITCH, "0")
                ref = occluded_ends(ends, scan, window, 0.5, max_range, range_margin)
                monkeypatch.setenv(compiled.ENV_SWITCH, "1")
                got = occluded_ends(ends, scan, window, 0.5, max_range, range_margin)
                np.testing.assert_array_equal(got, ref)
                flags.append(ref)
    flags = np.concatenate(flags)
    assert flags.any() and (~flags).any() and (flags[:, 0] != flags[:, 1]).any()


@pytest.mark.parametrize("seed", range(3))
def test_compiled_radar_association_equals_numpy(seed, monkeypatch):
    """Clusters (some empty) and detections scattered so that gates overlap and many pairs compete."""
    from tracker.clustering import associate_radar

    rng = np.random.default_rng(seed)
    for _ in range(100):
        clusters = [rng.normal(rng.uniform(-20.0, 20.0, 2), 1.0, (int(rng.integers(0, 30)), 2))
                    for _ in range(int(rng.integers(1, 12)))]
        radar = rng.uniform(-20.0, 20.0, (int(rng.integers(0, 15)), 2))
        monkeypatch.setenv(compiled.ENV_SWITCH, "0")
        ref = associate_radar(clusters, radar, 3.0)
        monkeypatch.setenv(compiled.ENV_SWITCH, "1")
        got = associate_radar(clusters, radar, 3.0)
        assert got.dtype == ref.dtype
        np.testing.assert_array_equal(got, ref)


@pytest.mark.parametrize("seed", range(3))
def test_compiled_merge_equals_numpy(seed, monkeypatch):
    """Mixtures of clumps of components (so that groups form), headings across +-pi and arc lengths
    across a closed road's seam, with and without wrapping."""
    from tracker.reduction import Mixture, merge
    from tracker.ukf import Wrapping

    rng = np.random.default_rng(seed)
    wrappings = [Wrapping(), Wrapping(angles=(3,), periods=((0, 500.0),))]
    for _ in range(60):
        n = int(rng.integers(2, 40))
        centre = rng.choice([0.5, 250.0, 499.6], size=n)
        means = np.column_stack([centre + rng.normal(0, 1.0, n), rng.normal(0, 1.0, n), rng.uniform(5, 30, n),
                                 rng.choice([-3.1, 0.0, 3.1], size=n) + rng.normal(0, 0.05, n), rng.normal(0, 0.1, n),
                                 rng.uniform(3, 12, n), rng.uniform(1.5, 2.6, n)])
        a = rng.normal(size=(n, 7, 7)) * rng.uniform(0.1, 1.0, (n, 1, 1))
        covs = a @ np.swapaxes(a, 1, 2) + 0.05 * np.eye(7)
        mix = Mixture(rng.uniform(0.01, 1.0, n), np.mod(means, [500.0, 1e9, 1e9, 1e9, 1e9, 1e9, 1e9]), covs,
                      rng.integers(0, 50, n))
        for wrapping in wrappings:
            for gate in (4.0, 30.0):
                monkeypatch.setenv(compiled.ENV_SWITCH, "0")
                ref = merge(mix, gate, wrapping)
                monkeypatch.setenv(compiled.ENV_SWITCH, "1")
                got = merge(mix, gate, wrapping)
                np.testing.assert_array_equal(got.labels, ref.labels)
                for name in ("weights", "means", "covs"):
                    np.testing.assert_allclose(getattr(got, name), getattr(ref, name), rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("seed", range(3))
def test_compiled_points_in_rectangles_and_overlap_groups_equal_numpy(seed, monkeypatch):
    """Overlapping and disjoint rectangles of every heading (duplicate hypotheses of one vehicle, trucks
    beside cars), points inside, between and outside them, and on the widened rectangles' corners."""
    from tracker.clustering import points_in_rectangles
    from tracker.measurement import Rectangles
    from tracker.tracker import _duplicate_groups

    rng = np.random.default_rng(seed)
    for _ in range(60):
        t = int(rng.integers(1, 16))
        centre = rng.uniform(-15.0, 15.0, (t, 2))
        rect = Rectangles(centre, rng.uniform(-np.pi, np.pi, t), np.zeros(t), rng.uniform(2.0, 14.0, t),
                          rng.uniform(0.8, 2.6, t))
        # the widened rectangles' corners lie on their circumscribed circles, where the kernel's
        # distance test (skip a rectangle beyond that circle) is at its boundary
        from tracker.measurement import rectangle_corners

        corners = rectangle_corners(centre, rect.psi, rect.length + 1.4, rect.width + 1.4).reshape(-1, 2)
        pts = np.concatenate([rng.uniform(-20.0, 20.0, (300, 2)), centre + rng.normal(0.0, 1.0, (t, 2)), corners])
        results = {}
        for mode in ("0", "1"):
            monkeypatch.setenv(compiled.ENV_SWITCH, mode)
            results[mode] = (points_in_rectangles(pts, rect.center, rect.psi, rect.length, rect.width, 0.7),
                             _duplicate_groups(rect))
        for ref, got in zip(results["0"], results["1"]):
            np.testing.assert_array_equal(got, ref)
        assert results["0"][1].max() < t or t == 1


@pytest.mark.parametrize("seed", range(3))
def test_compiled_overlap_test_of_absorb_overlapping_equals_numpy(seed, monkeypatch):
    """``tracker.reduction.absorb_overlapping`` with its overlap test compiled
    (``tracker.reduction.overlapping_pairs_kernel``) and by numpy: random heavy components of
    a few labels, apart and overlapping, curvilinear (across a closed road's seam too) and Cartesian;
    the same mixtures and counts, and both outcomes (absorbed, none) reached."""
    from tracker.reduction import Mixture, absorb_overlapping
    from tracker.ukf import Wrapping

    rng = np.random.default_rng(seed)
    outcomes = set()
    for _ in range(80):
        n = int(rng.integers(2, 14))
        means = np.column_stack([rng.choice([1.0, 150.0, 499.0], n) + rng.normal(0.0, 6.0, n), rng.normal(0.0, 2.0, n),
                                 rng.uniform(5, 30, n), rng.normal(0.0, 0.3, n), np.zeros(n),
                                 rng.uniform(3.0, 14.0, n), rng.uniform(1.6, 2.6, n)])
        covs = np.broadcast_to(np.diag([1.0, 0.1, 1.0, 0.01, 0.01, rng.uniform(0.1, 2.0), 0.05]), (n, 7, 7)).copy()
        mix = Mixture(rng.uniform(0.3, 1.0, n), np.mod(means, [500.0, *[1e9] * 6]), covs, rng.integers(1, 6, n))
        for wrapping, cartesian in ((Wrapping(angles=(3,)), False), (Wrapping(angles=(3,), periods=((0, 500.0),)), False),
                                    (Wrapping(angles=(3,)), True)):
            args = (mix, 0.5, 0.3, wrapping, cartesian, {1, 2}, {2, 3})
            monkeypatch.setenv(compiled.ENV_SWITCH, "0")
            ref, ref_count = absorb_overlapping(*args)
            monkeypatch.setenv(compiled.ENV_SWITCH, "1")
            got, count = absorb_overlapping(*args)
            assert count == ref_count
            for name in ("weights", "means", "covs", "labels"):
                np.testing.assert_array_equal(getattr(got, name), getattr(ref, name))
            outcomes.add(count > 0)
    assert outcomes == {True, False}


def test_overlapping_pairs_kernel_against_the_rule():
    """``overlapping_pairs_kernel`` against the rule written out here: ``i`` and ``j`` overlap when the
    centres are closer along the road (along ``i``'s heading, Cartesian) than half the lengths' sum
    less ``overlap``, and across it than half the narrower width; ``s`` wraps on a closed road."""
    from tracker.reduction import overlapping_pairs_kernel

    rng = np.random.default_rng(7)
    hits = 0
    for cartesian, period in ((False, 0.0), (False, 300.0), (True, 0.0)):
        for _ in range(30):
            n = int(rng.integers(2, 12))
            m = np.column_stack([rng.choice([2.0, 150.0, 298.0], n) + rng.normal(0.0, 5.0, n), rng.normal(0.0, 2.0, n),
                                 np.zeros(n), rng.normal(0.0, 0.4, n), np.zeros(n), rng.uniform(3.0, 14.0, n),
                                 rng.uniform(1.6, 2.6, n)])
            heading = m[:, 3] if cartesian else np.zeros(n)
            got = overlapping_pairs_kernel(m, np.cos(heading), np.sin(heading), cartesian, 0.3, period)
            for i in range(n):
                for j in range(n):
                    d = m[j, :2] - m[i, :2]
                    if period:
                        d[0] -= period * np.floor(d[0] / period + 0.5)
                    c, s = np.cos(heading[i]), np.sin(heading[i])
                    along, across = (d[0] * c + d[1] * s, -d[0] * s + d[1] * c) if cartesian else (d[0], d[1])
                    rule = (i != j and abs(along) < 0.5 * (m[i, 5] + m[j, 5]) - 0.3
                            and abs(across) < 0.5 * min(m[i, 6], m[j, 6]))
                    assert got[i, j] == rule, (cartesian, period, i, j)
                    hits += rule
    assert hits > 0


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_compiled_merge_of_low_dimensional_mixtures_equals_numpy(dim, monkeypatch):
    """Merging states of one to three coordinates (the position bound reads the first two only where
    they exist): the same groups and moments as numpy."""
    from tracker.reduction import Mixture, merge

    rng = np.random.default_rng(dim)
    for _ in range(50):
        n = int(rng.integers(2, 12))
        root = rng.normal(0.0, 1.0, (n, dim, dim)) * rng.uniform(0.2, 1.5, (n, 1, 1))
        mix = Mixture(rng.uniform(0.05, 1.0, n), rng.choice([0.0, 3.0, 40.0], (n, 1)) + rng.normal(0.0, 1.0, (n, dim)),
                      root @ np.swapaxes(root, 1, 2) + 0.05 * np.eye(dim), rng.integers(0, 9, n))
        monkeypatch.setenv(compiled.ENV_SWITCH, "0")
        ref = merge(mix, 4.0)
        monkeypatch.setenv(compiled.ENV_SWITCH, "1")
        got = merge(mix, 4.0)
        np.testing.assert_array_equal(got.labels, ref.labels)
        for name in ("weights", "means", "covs"):
            np.testing.assert_allclose(getattr(got, name), getattr(ref, name), rtol=1e-9, atol=1e-9)


def test_compiled_merge_at_the_gate_equals_numpy(monkeypatch):
    """Pairs whose distance lies just inside and just outside the gate along one axis of a diagonal
    covariance (where the position bound that lets the kernel skip a pair equals the distance itself):
    the same groups as numpy's merge; a covariance with a zero variance is never skipped by the bound."""
    from tracker.reduction import Mixture, merge

    gate = 4.0
    for axis in (0, 1):
        for factor in (1.0 - 1e-7, 1.0 + 1e-7, 1.0 + 1e-5, 1.0 - 1e-5):
            covs = np.broadcast_to(np.diag([2.0, 0.5, 1.0, 0.01, 0.01, 0.3, 0.05]), (2, 7, 7)).copy()
            means = np.zeros((2, 7))
            means[1, axis] = np.sqrt(gate * covs[0, axis, axis] * factor)
            mix = Mixture(np.array([0.9, 0.6]), means, covs, np.array([1, 2]))
            monkeypatch.setenv(compiled.ENV_SWITCH, "0")
            ref = merge(mix, gate)
            monkeypatch.setenv(compiled.ENV_SWITCH, "1")
            got = merge(mix, gate)
            assert len(got) == len(ref) == (1 if factor < 1.0 else 2), (axis, factor)
            np.testing.assert_array_equal(got.labels, ref.labels)


@pytest.mark.parametrize("seed", range(3))
def test_compiled_continued_ends_equal_numpy(seed, monkeypatch):
    """``continued_ends`` compiled (the scan sorted by bearing, each end searching the bearing window of
    the disc its test can reach) against numpy: ends all around the sensor (across the seam behind it,
    and within a few metres of it, where the disc holds the lidar), returns scattered and returns placed
    on the ends' continuations; the same flags, and some of each."""
    from tracker.clustering import continued_ends

    rng = np.random.default_rng(seed)
    flags = []
    for _ in range(40):
        k = int(rng.integers(1, 12))
        r = np.concatenate([rng.uniform(0.5, 4.0, 2), rng.uniform(4.0, 90.0, 2 * k - 2)])
        b = rng.uniform(-np.pi, np.pi, 2 * k)
        b[:2] = np.pi - rng.uniform(0.0, 0.01, 2)
        ends = np.column_stack([r * np.cos(b), r * np.sin(b)]).reshape(k, 2, 2)
        angle = rng.uniform(-np.pi, np.pi, (k, 2))
        outward = np.stack([np.cos(angle), np.sin(angle)], axis=-1)
        half_gap = rng.uniform(0.05, 1.0, (k, 2))
        on_line = ends + outward * rng.uniform(0.0, 3.0, (k, 2, 1)) + rng.normal(0.0, 0.2, (k, 2, 2))
        scan = np.concatenate([rng.uniform(-90.0, 90.0, (300, 2)), on_line.reshape(-1, 2)])
        monkeypatch.setenv(compiled.ENV_SWITCH, "0")
        ref = continued_ends(ends, outward, half_gap, scan, 2.0, 0.3)
        monkeypatch.setenv(compiled.ENV_SWITCH, "1")
        got = continued_ends(ends, outward, half_gap, scan, 2.0, 0.3)
        np.testing.assert_array_equal(got, ref)
        flags.append(ref)
    flags = np.concatenate([f.ravel() for f in flags])
    assert flags.any() and not flags.all()


def _random_mixture(rng, n: int, dim: int, road_length: float):
    """``n`` random components of ``dim`` (7 or 8) state entries in a few groups of near-duplicates
    (merged by a gate of 4), some across a closed road's start (``s`` below 0 and at or beyond
    ``road_length``), weights partly at 1e-4 (the prune threshold) and 0.5, labels of a few values."""
    centre = rng.choice([-0.4, 0.0, 30.0, road_length - 0.3, road_length, 0.5 * road_length], n)
    means = np.column_stack([centre + rng.choice([0.0, 1.0], n) * rng.normal(0.0, 0.8, n), rng.normal(0.0, 1.5, n),
                             rng.uniform(5, 30, n), rng.normal(0.0, 0.2, n) + rng.choice([0.0, np.pi], n),
                             rng.normal(0.0, 0.05, n), rng.uniform(3.0, 14.0, n), rng.uniform(1.6, 2.6, n),
                             rng.normal(0.0, 0.5, n)])[:, :dim]
    root = rng.normal(0.0, 0.3, (n, dim, dim))
    covs = root @ np.swapaxes(root, 1, 2) + np.diag(rng.uniform(0.05, 2.0, dim))
    weights = np.where(rng.random(n) < 0.2, rng.choice([1e-4, np.nextafter(1e-4, 0.0), 0.5], n), rng.uniform(0.0, 1.0, n))
    return weights, means, covs, rng.integers(1, 5, n)


def _staged_reduce_in_view(mix, near, limit, lateral, bounds, period, **settings):
    """The reduce stage as ``Tracker._reduce`` ran it before ``reduce_in_view``: the mask of the
    components in view and on the road, ``Mixture.take``, ``reduce`` (its compiled merge when the
    kernels are on) and ``numpy.mod`` of ``s``."""
    from tracker.reduction import reduce

    inside = near <= limit
    on_road = (lateral >= bounds[0]) & (lateral <= bounds[1])
    counts = int((~inside).sum()), int((inside & ~on_road).sum())
    mix = reduce(mix.take(inside & on_road), **settings)
    if period is not None and len(mix):
        mix.means[:, 0] = np.mod(mix.means[:, 0], period)
    return mix, counts


@pytest.mark.parametrize("dim", [7, 8])
@pytest.mark.parametrize("seed", range(2))
def test_compiled_reduce_in_view_equals_the_staged_reduction(seed, dim, monkeypatch):
    """``tracker.reduction.reduce_in_view`` by one compiled call (``reduce_kernel``) against the staged
    compiled path it replaces, bit for bit (weights, means, covariances, labels, both counts): random
    mixtures of 0 to 25 components, 7 and 8 state entries, closed (``s`` wraps, before and after the
    merge) and open roads, ranges and lateral offsets at their limits, weights at the prune threshold,
    heavy components of one label left apart (``merge_same_label``'s frames), caps of 3 and 100; and the
    numpy path against it (the same labels and counts, numbers to rounding)."""
    from tracker.reduction import Mixture, reduce_in_view
    from tracker.ukf import Wrapping

    rng = np.random.default_rng(seed)
    length, limit, bounds = 400.0, 60.0, (-3.0, 2.5)
    seen = {"pending": 0, "capped": 0, "merged": 0, "empty": 0}
    for trial in range(120):
        n = int(rng.integers(0, 26)) if trial % 10 else int(trial % 3)  # some empty and single mixtures
        mix = Mixture(*_random_mixture(rng, n, dim, length))
        near = np.where(rng.random(n) < 0.15, limit, rng.uniform(0.0, 1.3 * limit, n))
        lateral = np.where(rng.random(n) < 0.15, rng.choice(bounds, n), mix.means[:, 1] if n else np.zeros(0))
        closed = bool(trial % 2)
        wrapping = Wrapping(angles=(3,), periods=((0, length),) if closed else ())
        settings = dict(prune_threshold=1e-4, merge_gate=4.0, max_components=3 if trial % 4 == 0 else 100,
                        wrapping=wrapping, same_label_distance=None if trial % 5 == 0 else 3.0,
                        same_label_min_weight=0.5, same_label_along_length=bool(trial % 3))
        period = length if closed else None
        monkeypatch.setenv(compiled.ENV_SWITCH, "1")
        ref, ref_counts = _staged_reduce_in_view(mix, near, limit, lateral, bounds, period, **settings)
        got, *counts = reduce_in_view(mix, near, limit, lateral, bounds, s_period=period, **settings)
        assert tuple(counts) == ref_counts
        for name in ("weights", "means", "covs", "labels"):
            a, b = getattr(got, name), getattr(ref, name)
            assert a.shape == b.shape and a.dtype == b.dtype, name
            np.testing.assert_array_equal(a, b, err_msg=name)
        monkeypatch.setenv(compiled.ENV_SWITCH, "0")
        slow, *slow_counts = reduce_in_view(mix, near, limit, lateral, bounds, s_period=period, **settings)
        assert tuple(slow_counts) == ref_counts
        np.testing.assert_array_equal(slow.labels, ref.labels)
        for name in ("weights", "means", "covs"):
            np.testing.assert_allclose(getattr(slow, name), getattr(ref, name), rtol=1e-9, atol=1e-9)
        kept = int(((near <= limit) & (lateral >= bounds[0]) & (lateral <= bounds[1]) & (mix.weights >= 1e-4)).sum())
        heavy = ref.labels[ref.weights >= 0.5]
        seen["pending"] += settings["same_label_distance"] is not None and len(set(heavy.tolist())) < len(heavy)
        seen["capped"] += len(ref) == 3 and settings["max_components"] == 3 and kept > 3
        seen["merged"] += len(ref) < kept
        seen["empty"] += n == 0
    assert all(seen.values()), seen


def test_compiled_reduce_in_view_at_the_limits(monkeypatch):
    """Exact limits: a range equal to the limit is in view, a lateral offset equal to a bound on the
    road, a weight equal to the prune threshold kept (one below it dropped), a pair at the merge gate's
    boundary (distance^2 = gate along one axis, times 1 -+ 1e-7) merged only inside it, and ``s`` of
    a lone component beyond the road's length (or below 0) taken modulo it; compiled and numpy alike."""
    from tracker.reduction import Mixture, reduce_in_view
    from tracker.ukf import Wrapping

    wrapping = Wrapping(angles=(3,), periods=((0, 300.0),))
    settings = dict(prune_threshold=1e-4, merge_gate=4.0, max_components=100, wrapping=wrapping,
                    same_label_distance=3.0, s_period=300.0)
    for factor in (1.0 - 1e-7, 1.0 + 1e-7):
        covs = np.broadcast_to(np.diag([2.0, 0.5, 1.0, 0.01, 0.01, 0.3, 0.05]), (6, 7, 7)).copy()
        means = np.zeros((6, 7))
        means[:, 5:] = 4.5, 1.9
        means[1, 0] = np.sqrt(4.0 * 2.0 * factor)  # at the gate from component 0
        means[2, 0], means[3, 0], means[4, 0], means[5, 0] = 450.0, -150.0, -200.0, 200.0
        weights = np.array([0.9, 0.6, 1e-4, np.nextafter(1e-4, 0.0), 0.3, 0.3])
        mix = Mixture(weights, means, covs, np.arange(6))
        near = np.array([50.0, 50.0, 50.0, 50.0, 60.0, np.nextafter(60.0, 61.0)])
        lateral = np.array([2.5, -3.0, 0.0, 0.0, 0.0, 0.0])
        results = {}
        for switch in ("0", "1"):
            monkeypatch.setenv(compiled.ENV_SWITCH, switch)
            results[switch] = reduce_in_view(mix, near, 60.0, lateral, (-3.0, 2.5), **settings)
        for got, left_view, off_road in results.values():
            assert (left_view, off_road) == (1, 0)
            assert sorted(got.labels.tolist()) == ([0, 2, 4] if factor < 1.0 else [0, 1, 2, 4])
            assert got.means[got.labels == 2, 0] == 150.0 and got.means[got.labels == 4, 0] == 100.0
        np.testing.assert_array_equal(results["0"][0].means, results["1"][0].means)


@pytest.mark.parametrize("seed", range(3))
def test_compiled_drop_inside_updated_equals_numpy(seed, monkeypatch):
    """``Tracker._drop_inside_updated`` by one compiled call (``inside_updated_kernel``) and by numpy
    (``points_in_rectangles`` with margin 0): random components of updated and idle labels around a
    few cars on a curved road, centres on the rectangles' edges too; the same mixture and counter (none
    dropped, some dropped)."""
    from tracker.reduction import Mixture

    rng = np.random.default_rng(seed)
    road = Road.from_curvature([(150.0, 0.0, 0.0), (300.0, 0.0, 1 / 120.0)], lanes=3, lane_width=3.5)
    ego = EgoState(*road.frame(np.array(40.0))[0], float(road.frame(np.array(40.0))[1]), 15.0, 0.0)
    outcomes = set()
    for _ in range(40):
        n = int(rng.integers(1, 14))
        means = np.column_stack([rng.choice([60.0, 80.0, 170.0], n) + rng.normal(0.0, 2.0, n), rng.normal(0.0, 2.0, n),
                                 rng.uniform(5, 20, n), rng.normal(0.0, 0.1, n), np.zeros(n), rng.uniform(3.0, 12.0, n),
                                 rng.uniform(1.6, 2.6, n), np.zeros(n)])
        edge = rng.random(n) < 0.3  # some centres on the heaviest one's front edge
        means[edge, :2] = means[0, :2] + [0.5 * means[0, 5], 0.0]
        labels = rng.integers(1, 7, n)
        mix = Mixture(rng.uniform(0.2, 1.0, n), means, np.broadcast_to(np.eye(8) * 0.1, (n, 8, 8)).copy(), labels)
        strong = set(rng.choice(np.arange(1, 7), 3, replace=False).tolist())
        results = []
        for switch in ("0", "1"):
            monkeypatch.setenv(compiled.ENV_SWITCH, switch)
            tracker = Tracker(road, TrackerConfig())
            tracker.mixture, tracker._strong_labels = mix, strong
            tracker._drop_inside_updated(ego)
            results.append((tracker.mixture, dict(tracker.stats)))
        (ref, ref_stats), (got, stats) = results
        assert stats == ref_stats
        for name in ("weights", "means", "covs", "labels"):
            np.testing.assert_array_equal(getattr(got, name), getattr(ref, name))
        outcomes.add(len(got) < n)
    assert outcomes == {True, False}


def test_absorb_candidates_kernel_equals_numpy():
    """``absorb_candidates_kernel`` against numpy's candidates of ``absorb_overlapping``: the heaviest
    component of each label among those of weight >= the threshold (weights at it, and ties of weight,
    which go in index order), heaviest first; none and one too."""
    from tracker.reduction import absorb_candidates_kernel

    rng = np.random.default_rng(3)
    for _ in range(200):
        n = int(rng.integers(0, 16))
        weights = rng.choice([0.2, 0.5, np.nextafter(0.5, 0.0), 0.7, 0.9], n)
        labels = rng.integers(1, 6, n)
        heavy = np.flatnonzero(weights >= 0.5)
        order = heavy[np.argsort(-weights[heavy], kind="stable")]
        _, first = np.unique(labels[order], return_index=True)
        np.testing.assert_array_equal(absorb_candidates_kernel(weights, labels.astype(np.int64), 0.5),
                                      order[np.sort(first)])


def _cluster_scene(seed: int, config: TrackerConfig, tracks: int | None = None):
    """A tracker with a random mixture and reported tracks, and the points, frame and predicted track
    rectangles its ``_cluster`` sees: overlapping track rectangles (duplicates of one vehicle), points in
    several rectangles, strays just outside them, blobs wide across the road (their lateral offsets are
    their y, with gaps to cut at), lone points (fragments) and radar detections older than the frame."""
    from tracker.frame import Frame, RadarDetections
    from tracker.measurement import Rectangles
    from tracker.motion import LENGTH
    from tracker.reduction import Mixture

    rng = np.random.default_rng(seed)
    road = Road.from_curvature([(300.0, 0.0, 0.0)], lanes=2, lane_width=3.5)
    tracker = Tracker(road, config)
    count = int(rng.integers(0, 7)) if tracks is None else tracks
    center = np.column_stack([rng.uniform(0.0, 60.0, count), rng.uniform(-5.0, 5.0, count)])
    if count > 2:
        center[1] = center[0] + rng.normal(0.0, 0.8, 2)  # a duplicate hypothesis of one vehicle
    psi = rng.normal(0.0, 0.2, count)
    length, width = rng.uniform(3.0, 12.0, count), rng.uniform(1.5, 2.6, count)
    rect = Rectangles(center, psi, np.zeros(count), length, width)
    parts = [rng.uniform([-5.0, -12.0], [70.0, 12.0], (int(rng.integers(1, 25)), 2))]  # clutter, lone points
    for k in range(count):  # each track's points, some a little outside (strays) or past its front
        u = rng.uniform(-0.5, 0.5 + rng.uniform(0.0, 0.6), int(rng.integers(1, 30))) * (length[k] + 2.0)
        v = rng.choice([-0.5, 0.5]) * width[k] + rng.normal(0.0, 0.3, len(u))
        parts.append(center[k] + np.column_stack([u * np.cos(psi[k]) - v * np.sin(psi[k]),
                                                  u * np.sin(psi[k]) + v * np.cos(psi[k])]))
    for _ in range(int(rng.integers(0, 5))):  # blobs up to 9 m across the road, their points 0.3-0.9 m apart
        across = np.cumsum(rng.uniform(0.3, 0.95, int(rng.integers(2, 14))))
        parts.append(np.column_stack([rng.uniform(0.0, 60.0) + rng.normal(0.0, 0.2, len(across)),
                                      rng.uniform(-8.0, 0.0) + across]))
    points = np.concatenate(parts)
    points = points[rng.permutation(len(points))]
    tracker._point_n = points[:, 1] + rng.normal(0.0, 0.05, len(points))
    extra = int(rng.integers(0, 6))
    labels = np.concatenate([rng.permutation(np.arange(1, count + 1)), rng.integers(1, count + 4, extra)])
    covs = np.tile(np.eye(tracker.dim), (count + extra, 1, 1))
    covs[:, LENGTH, LENGTH] = rng.uniform(0.0, 4.0, count + extra)
    tracker.mixture = Mixture(np.full(count + extra, 0.9), np.zeros((count + extra, tracker.dim)), covs, labels)
    tracker._reported = rng.permutation(count).astype(int)
    radar_count = int(rng.integers(0, 15))
    hits = points[rng.integers(0, len(points), radar_count)] + rng.normal(0.0, 1.0, (radar_count, 2))
    radar = RadarDetections(t=rng.uniform(0.9, 1.0, radar_count), x=hits[:, 0], y=hits[:, 1],
                            vx=rng.normal(10.0, 3.0, radar_count), vy=rng.normal(0.0, 1.0, radar_count))
    return tracker, points, Frame(1.0, EgoState(0.0, 0.0, 0.0, 10.0, 0.0), np.zeros((0, 2)), radar), rect


def _clustered(tracker, points, frame, rect) -> tuple:
    """``tracker._cluster``'s result and everything it sets, on a copy of the tracker's state."""
    import copy
    from collections import Counter

    tracker = copy.copy(tracker)
    tracker.stats = Counter()
    with compiled.pinned():
        clusters, velocities = tracker._cluster(points, frame, rect)
    return clusters, velocities, tracker._owned, tracker._component_group, tracker._free_radar, tracker.stats


def _assert_same_clusters(ref: tuple, got: tuple) -> None:
    """Two ``_clustered`` results bit for bit: the clusters' points and order, the velocities (the
    same rows or None), owners, component groups, free detections (values and dtypes) and stats."""
    assert len(ref[0]) == len(got[0])
    for a, b in zip(ref[0], got[0]):
        assert a.dtype == b.dtype and np.array_equal(a, b)
    assert [v is None for v in ref[1]] == [v is None for v in got[1]]
    for a, b in zip(ref[1], got[1]):
        assert a is None or (np.array_equal(a, b) and not b.flags.writeable)
    for a, b in zip(ref[2:5], got[2:5]):
        assert a.dtype == b.dtype and np.array_equal(a, b)
    assert ref[5] == got[5]


_CLUSTER_CONFIGS = {
    "default": {},
    "lenient-fragments": {"fragment_points": 3, "fragment_side_tolerance": None, "fragment_sigmas": 20.0},
    "min-points": {"min_points": 3, "split_gap": 0.2},
    "no-split-no-fragments": {"split_width": None, "fragment_points": None},
}


@pytest.mark.parametrize("settings", list(_CLUSTER_CONFIGS), ids=list(_CLUSTER_CONFIGS))
def test_compiled_clustering_equals_numpy(settings, monkeypatch):
    """``Tracker._cluster`` by ``cluster_points_kernel`` (and ``ordered_clusters_kernel`` after the
    fragments), ``cluster_radar_kernel``: the numpy path's clusters, velocities, owners, component
    groups, free detections and stats bit for bit, on random scenes (no tracks, overlapping track
    rectangles, strays, fragments, clusters cut across the road, more detections than clusters, none)."""
    from tracker.config import ClusteringConfig

    config = dataclasses.replace(TrackerConfig(), clustering=ClusteringConfig(**_CLUSTER_CONFIGS[settings]))
    seen = dict.fromkeys(("clusters_split", "fragment_points_adopted", "clusters_too_small", "clusters_fused"), 0)
    for seed in range(40):
        scene = _cluster_scene(seed, config, tracks=0 if seed < 3 else None)
        monkeypatch.setenv(compiled.ENV_SWITCH, "0")
        ref = _clustered(*scene)
        monkeypatch.setenv(compiled.ENV_SWITCH, "1")
        got = _clustered(*scene)
        _assert_same_clusters(ref, got)
        for name in seen:
            seen[name] += ref[5][name]
    assert seen["clusters_fused"] > 0
    assert (seen["clusters_split"] > 0) == (config.clustering.split_width is not None)
    if settings == "lenient-fragments":
        assert seen["fragment_points_adopted"] > 0
    if settings == "min-points":
        assert seen["clusters_too_small"] > 0


@pytest.mark.parametrize("case", ["one-point", "no-radar", "no-tracks", "nan-offset", "all-inside"])
def test_compiled_clustering_equals_numpy_at_the_edges(case, monkeypatch):
    """The same on the edges: one point, no radar detections, no tracks, a non-finite lateral offset
    (the kernel hands back: the numpy path runs), every point inside one rectangle."""
    from tracker.frame import Frame
    from tracker.measurement import Rectangles

    tracker, points, frame, rect = _cluster_scene(7, TrackerConfig(), tracks=0 if case == "no-tracks" else 3)
    if case == "one-point":
        points, tracker._point_n = points[:1], tracker._point_n[:1]
    if case == "no-radar":
        frame = Frame(frame.t, frame.ego, frame.lidar)
    if case == "nan-offset":
        tracker._point_n = tracker._point_n.copy()
        tracker._point_n[0] = np.nan
    if case == "all-inside":
        rect = Rectangles(np.array([[0.0, 0.0], [0.5, 0.0], [80.0, 0.0]]), np.zeros(3), np.zeros(3),
                          np.array([200.0, 3.0, 4.0]), np.array([40.0, 2.0, 2.0]))
    monkeypatch.setenv(compiled.ENV_SWITCH, "0")
    ref = _clustered(tracker, points, frame, rect)
    monkeypatch.setenv(compiled.ENV_SWITCH, "1")
    _assert_same_clusters(ref, _clustered(tracker, points, frame, rect))
    assert len(ref[0]) >= 1


def test_cluster_radar_ranges_equals_cluster_radar(monkeypatch):
    """``cluster_radar_ranges`` (one compiled call) against ``cluster_radar`` on the clusters' views: the
    same detection per cluster (its velocity row) and free detections, with and without kernels, for
    clusters of one point, more detections than clusters, detections exactly at the gate and none."""
    from tracker.clustering import cluster_radar, cluster_radar_ranges
    from tracker.frame import RadarDetections

    rng = np.random.default_rng(3)
    for trial in range(60):
        sizes = rng.integers(1, 6, int(rng.integers(1, 8)))
        edges = np.concatenate([[0], np.cumsum(sizes)])
        points = rng.uniform(0.0, 20.0, (int(edges[-1]), 2))
        count = int(rng.integers(0, 12))
        hits = points[rng.integers(0, len(points), count)] + rng.normal(0.0, 2.0, (count, 2))
        if count and trial % 3 == 0:
            hits[0] = points[0] + [3.0, 0.0]  # exactly at the gate
        radar = RadarDetections(t=np.full(count, 1.0), x=hits[:, 0], y=hits[:, 1], vx=rng.normal(size=count),
                                vy=rng.normal(size=count))
        keep = rng.random(len(sizes)) < 0.8
        lo, hi = edges[:-1][keep], edges[1:][keep]
        velocities, index = cluster_radar([points[a:b] for a, b in zip(lo, hi)], radar, 1.0, 3.0)
        free = np.setdiff1d(np.arange(count), index)
        for kernels in ("0", "1"):
            monkeypatch.setenv(compiled.ENV_SWITCH, kernels)
            got, got_free = cluster_radar_ranges(points, lo, hi, radar, 1.0, 3.0)
            assert [v is None for v in got] == [v is None for v in velocities]
            assert all(a is None or (np.array_equal(a, b) and not b.flags.writeable) for a, b in zip(velocities, got))
            assert got_free.dtype == np.int64 and np.array_equal(got_free, free)
