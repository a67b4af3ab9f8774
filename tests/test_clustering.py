"""Tests of tracker/clustering.py."""

from __future__ import annotations

import numpy as np
import pytest

from oracles import clustering as oracle
from tracker.clustering import (SPLIT_MAX_CUTS, along_cuts_kernel, associate_radar, continued_ends, distance_partition, fragment_owners,
                                occluded_ends, ordered_clusters_kernel, points_in_rectangles, ray_partition)
from tracker.preparation import prepare_batch


def test_points_in_rectangles_geometry():
    centres = np.array([[10.0, 0.0], [10.0, 3.5]])
    yaw = np.array([0.0, np.pi / 2])
    length, width = np.array([4.0, 4.0]), np.array([2.0, 2.0])
    pts = np.array([[12.4, 0.0], [12.6, 0.0], [10.0, 0.9], [10.0, 6.1], [11.4, 3.5], [30.0, 0.0]])
    idx = points_in_rectangles(pts, centres, yaw, length, width, margin=0.5)
    # rectangle 1 is turned 90 deg: its length runs along y
    np.testing.assert_array_equal(idx, [0, -1, 0, -1, 1, -1])
    assert points_in_rectangles(pts, np.zeros((0, 2)), [], [], []).tolist() == [-1] * 6


def test_distance_partition_components():
    a = np.column_stack([np.linspace(0, 3, 7), np.zeros(7)])  # spacing 0.5
    b = a + [10.0, 0.0]
    c = np.array([[5.0, 5.0]])
    labels = distance_partition(np.vstack([a, c, b]), threshold=0.6)
    np.testing.assert_array_equal(labels, [0] * 7 + [1] + [2] * 7)
    # a threshold below the spacing splits every point apart
    assert len(set(distance_partition(a, 0.4).tolist())) == 7
    assert distance_partition(np.zeros((0, 2)), 1.0).shape == (0,)
    with pytest.raises(ValueError, match="threshold"):
        distance_partition(a, -1.0)
    with pytest.raises(ValueError, match="finite"):  # a point the grid cannot hold, which the whole graph rejects
        distance_partition(np.array([[0.0, 0.0], [np.nan, 1.0]]), 1.0)


def test_associate_radar_greedy_within_gate():
    clusters = [np.array([[10.0, 0.0], [10.0, 1.0]]), np.array([[20.0, 0.0]]), np.array([[40.0, 0.0]])]
    radar = np.array([[10.5, 0.5], [19.0, 0.0], [10.2, 0.0], [45.0, 0.0]])
    out = associate_radar(clusters, radar, gate=2.0)
    # cluster 0 takes its nearest detection (2: 0.2 m), cluster 1 takes detection 1, cluster 2 none
    np.testing.assert_array_equal(out, [2, 1, -1])
    np.testing.assert_array_equal(associate_radar(clusters, np.zeros((0, 2))), [-1, -1, -1])


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("order", ["scan", "shuffled"])
def test_distance_partition_equals_the_whole_graph_components(seed, order):
    # a scan-like cloud (objects as dense arcs, clutter) in scan order, and the same shuffled: exactly
    # the components of the whole graph
    rng = np.random.default_rng(seed)
    parts = []
    for _ in range(12):
        centre = rng.uniform(-60, 60, 2)
        t = np.sort(rng.uniform(0, 1, rng.integers(1, 60)))
        parts.append(centre + np.column_stack([4.0 * t, 1.5 * (t > 0.6) * (t - 0.6)]) + rng.normal(0, 0.05, (len(t), 2)))
    parts.append(rng.uniform(-60, 60, (80 if order == "shuffled" else 10, 2)))  # clutter
    pts = np.vstack(parts)
    pts = pts[np.argsort(np.arctan2(pts[:, 1], pts[:, 0]))] if order == "scan" else pts[rng.permutation(len(pts))]
    for threshold in (0.3, 1.0, 3.0):
        np.testing.assert_array_equal(distance_partition(pts, threshold), oracle.distance_partition(pts, threshold))


@pytest.mark.parametrize("seed", range(4))
def test_distance_partition_equals_the_oracle_on_the_grids_edges(seed):
    """Scattered points, a dense random walk (cells holding many points), points exactly on the
    grid's cell boundaries, a few points spread over kilometres (more grid columns than the counting
    sort takes: the cells sorted by argsort) and points too far apart for the grid's keys (the whole
    graph then); thresholds from 0.2 to 3 m."""
    rng = np.random.default_rng(seed)
    clouds = [rng.uniform(-80.0, 80.0, (600, 2)), np.cumsum(rng.normal(0.0, 0.4, (700, 2)), axis=0),
              np.round(rng.uniform(-5.0, 5.0, (300, 2)) / 0.25) * 0.25, rng.uniform(-1.0, 1.0, (1, 2)),
              np.concatenate([rng.uniform(-2000.0, 2000.0, (40, 2)), rng.uniform(0.0, 3.0, (20, 2))]),
              np.array([[0.0, 0.0], [1e18, -1e18], [0.5, 0.0]])]
    for pts in clouds:
        for threshold in (0.2, 0.5 * np.sqrt(2.0), 1.0, 3.0):
            np.testing.assert_array_equal(distance_partition(pts, threshold), oracle.distance_partition(pts, threshold))


def _cut_across(n: np.ndarray, group: np.ndarray, width: float, gap: float) -> tuple[list[list[int]], int]:
    """The clustering's cuts across the road (``ordered_clusters_kernel``) of free points, one connected
    component per ``group``: the clusters as sorted lists of point indices (sorted), and the parts added."""
    count = len(n)
    pts = np.column_stack([np.arange(count, dtype=float), np.zeros(count)])  # x tells each point's index
    component = np.unique(group, return_inverse=True)[1].reshape(-1).astype(np.int64)
    ordered, edges, _, added = ordered_clusters_kernel(pts, np.full(count, -1, dtype=np.int64), np.zeros(count, dtype=bool),
                                                       component, 0, np.asarray(n, dtype=float), True, width, gap,
                                                       SPLIT_MAX_CUTS)
    return sorted(sorted(ordered[a:b, 0].astype(int).tolist()) for a, b in zip(edges[:-1], edges[1:])), int(added)


def _parts(part: np.ndarray) -> list[list[int]]:
    """A part index per point as sorted lists of point indices (sorted)."""
    return sorted(np.flatnonzero(part == p).tolist() for p in np.unique(part))


def test_clusters_wide_across_the_road_are_cut_at_their_largest_lateral_gap():
    """A cluster wider than ``width`` across the road is cut at its largest gap in ``n`` (again while a
    part is still wider); narrow clusters, and wide ones without a gap of ``gap`` (one vehicle at an
    angle, its side continuous), stay whole; the same parts as ``oracles.clustering.split_across``."""
    n = np.array([0.0, 0.2, 0.4, 1.2, 1.5, 3.0, 3.1, 5.0, 5.2, 5.3])
    one = np.zeros(len(n), dtype=int)
    assert _cut_across(n, one, 3.5, 0.5) == ([list(range(7)), [7, 8, 9]], 1)  # cut at 3.1 | 5.0
    assert _cut_across(n, one, 2.0, 0.5) == ([[0, 1, 2, 3, 4], [5, 6], [7, 8, 9]], 2)  # and at 1.5 | 3.0
    assert _cut_across(n, one, 6.0, 0.5) == ([list(range(10))], 0)  # narrow enough
    side = np.linspace(-1.0, 4.0, 60)  # a bus at an angle: 5 m across, no gap
    assert _cut_across(side, np.zeros(60, dtype=int), 3.0, 0.5) == ([list(range(60))], 0)
    # two clusters, in any order of the points: each is cut on its own
    rng = np.random.default_rng(1)
    order = rng.permutation(20)
    both_n, both_group = np.r_[n, n][order], np.r_[one + 7, one + 3][order]
    got, added = _cut_across(both_n, both_group, 3.5, 0.5)
    assert added == 2 and got == _parts(oracle.split_across(both_n, both_group, 3.5, 0.5))
    for trial in range(30):  # random clusters: the oracle's parts
        count = int(rng.integers(1, 40))
        offsets, group = np.cumsum(rng.uniform(0.0, 1.2, count)), rng.integers(0, 4, count)
        got, _ = _cut_across(offsets, group, 2.5, 0.6)
        assert got == _parts(oracle.split_across(offsets, group, 2.5, 0.6)), trial


def _bearing_ends(cluster: np.ndarray) -> np.ndarray:
    """The cluster's first and last point in bearing order, as the tracker takes them."""
    return prepare_batch([cluster]).bearing_ends()


def test_occluded_ends_flags_the_end_next_to_a_nearer_return():
    """Rays every 0.2 deg. A rear 60 m ahead seen over bearings 0.5-2 deg, with an object 20 m ahead
    returning just below 0.5 deg: its low end borders that object's shadow, its high end borders
    nothing (free). A farther object just beyond the high end (the background) does not occlude; nor
    does a return more than the window away, or one less than the margin nearer."""
    res = np.radians(0.2)
    bearings = np.radians(np.arange(0.5, 2.01, 0.2))
    rear = 60.0 * np.column_stack([np.cos(bearings), np.sin(bearings)])
    def at(r, deg):
        return np.array([[r * np.cos(np.radians(deg)), r * np.sin(np.radians(deg))]])
    occluder = np.vstack([at(20.0, d) for d in (-1.0, -0.7, -0.3, 0.3)])
    scan = np.vstack([rear, occluder, at(80.0, 2.2)])
    np.testing.assert_array_equal(occluded_ends(_bearing_ends(rear), scan, 2.5 * res, 0.5), [[True, False]])
    np.testing.assert_array_equal(occluded_ends(_bearing_ends(rear), np.vstack([rear, at(80.0, 0.3), at(20.0, 2.8)]), 2.5 * res, 0.5),
                                  [[False, False]])  # farther below, nearer but beyond the window above
    np.testing.assert_array_equal(occluded_ends(_bearing_ends(rear), np.vstack([rear, at(59.8, 2.2)]), 2.5 * res, 0.5), [[False, False]])
    np.testing.assert_array_equal(occluded_ends(_bearing_ends(rear), np.vstack([rear, at(55.0, 2.2)]), 2.5 * res, 0.5), [[False, True]])
    # a rear straddling the bearing seam behind the sensor (+-180 deg): its ends are found across it
    seam = 60.0 * np.column_stack([np.cos(np.radians(np.arange(179.1, 181.0, 0.2))), np.sin(np.radians(np.arange(179.1, 181.0, 0.2)))])
    np.testing.assert_array_equal(occluded_ends(_bearing_ends(seam), np.vstack([seam, at(20.0, -178.8)]), 2.5 * res, 0.5), [[False, True]])
    np.testing.assert_array_equal(occluded_ends(_bearing_ends(seam), np.vstack([seam, at(20.0, 178.8)]), 2.5 * res, 0.5), [[True, False]])
    # within range_margin of the lidar's range an end may be the range's cut, not the vehicle's end
    grazing = np.array([[90.0, 40.0], [93.0, 35.0]])  # 98.5 m and 99.4 m away
    np.testing.assert_array_equal(occluded_ends(_bearing_ends(grazing), grazing, 2.5 * res, 0.5, 100.0, 5.0), [[True, True]])
    np.testing.assert_array_equal(occluded_ends(_bearing_ends(grazing), grazing, 2.5 * res, 0.5, 100.0, 1.0), [[True, False]])
    assert occluded_ends(np.zeros((0, 2, 2)), scan, 2.5 * res, 0.5).shape == (0, 2)
    assert not occluded_ends(_bearing_ends(rear), np.zeros((0, 2)), 2.5 * res, 0.5).any()


def test_continued_ends_flags_a_side_that_goes_on_in_another_cluster():
    """A truck's left side 2 m to the right of the lidar, seen from 15 to 30 m ahead with rays every
    0.2 deg (gaps 0.4-1.6 m along it: grazing). One return is missing (at 22 m ahead), and the side
    falls apart into two clusters. The near part's far end and the far part's near end go on in the
    other part: continued; the far part's far end and the near part's near end are free. A return
    1 m beside the side's line beyond the far end (another car's corner) does not continue it; nor
    does the next ray's return farther than ``rays`` ray gaps along it."""
    x = 2.0 / np.tan(np.arange(np.arctan2(2.0, 30.0), np.arctan2(2.0, 15.0), np.radians(0.2)))  # far to near
    x = x[::-1]  # near to far along the side
    side = np.column_stack([x, np.full(len(x), -2.0)])
    hole = int(np.argmin(np.abs(x - 22.0)))
    near, far = side[:hole], side[hole + 1:]
    assert len(near) >= 3 and len(far) >= 3
    batch = prepare_batch([near, far])
    ends, outward, half_gap = batch.side_ends()
    # half the ray gap r^2 db / d at each end (d = 2 m), the near part's ends at 15 m and 22 m
    np.testing.assert_allclose(half_gap[0], 0.5 * np.radians(0.2) * np.hypot(near[[0, -1], 0], 2.0) ** 2 / 2.0, rtol=0.05)
    scan = np.vstack([near, far, [[far[-1, 0] + 0.8, -3.0]]])
    got = continued_ends(ends, outward, half_gap, scan, 3.0, 0.3)
    # bearing order: a side on the right runs from near (lowest bearing) to far
    np.testing.assert_array_equal(got, [[False, True], [True, False]])
    # three ray gaps reach past the hole (two gaps); one gap does not
    np.testing.assert_array_equal(continued_ends(ends, outward, half_gap, scan, 0.9, 0.3), [[False, False], [False, False]])
    assert continued_ends(ends, outward, half_gap, np.zeros((0, 2)), 3.0, 0.3).shape == (2, 2)
    assert continued_ends(np.zeros((0, 2, 2)), np.zeros((0, 2, 2)), np.zeros((0, 2)), scan, 3.0, 0.3).shape == (0, 2)


@pytest.mark.parametrize("ahead", [True, False], ids=["track-ahead", "track-behind"])
def test_fragment_owners_take_small_free_fragments_past_the_far_end_only(ahead: bool) -> None:
    """``fragment_owners``: a 6 x 2.5 m track 50 m ahead in the next lane (or behind: then its rear is
    the far end) whose length is uncertain by 2 m, stretched 4 m at the far end, plus the 1 m margin;
    its right side (2.25 m left of the sensor's axis) faces the sensor. Taken: a one-point and a
    two-point fragment 2-3 m past the far end on that side's line. Not taken: 7 m past it, 2.5 m past
    the near end (that end is not stretched), a three-point fragment, one beside the rectangle, one whose
    other point another track owns; nothing when the length is known to within the margin or the track
    holds no points of its own (``seen``); not the same fragments on the far side's line (the body hides
    them; nor are they on the side facing the sensor); and never a point the rectangle hides from the
    sensor."""
    sign = 1.0 if ahead else -1.0
    centre = np.array([[50.0 * sign, 3.5]])
    pts = np.array([
        [56.0, 2.3],                          # 0: one point 3 m past the far end: taken
        [55.0, 2.35], [55.5, 2.3],            # 1: two points 2-2.5 m past it: taken
        [60.0, 2.3],                          # 2: 7 m past it
        [44.5, 2.3],                          # 3: 2.5 m past the near end
        [55.0, 4.5], [55.4, 4.5], [55.8, 4.5],  # 4: three points
        [55.0, 0.5],                          # 5: beside the rectangle
        [55.2, 3.0], [55.6, 3.0],             # 6: its second point owned by another track
    ]) * [sign, 1.0]
    component = np.array([0, 1, 1, 2, 3, 4, 4, 4, 5, 6, 6])
    free = np.ones(len(pts), dtype=bool)
    free[10] = False
    args = (centre, np.zeros(1), np.array([6.0]), np.array([2.5]))
    sd = np.array([2.0])
    got = fragment_owners(pts, component, free, *args, sd, 1.0, 2, 2.0)
    assert got.tolist() == [0, 0, 0] + [-1] * 8
    for settled in (0.0, 0.45):  # 2 sd within the 1 m margin: not stretched
        assert (fragment_owners(pts, component, free, *args, np.array([settled]), 1.0, 2, 2.0) == -1).all()
    assert (fragment_owners(pts, component, np.zeros(len(pts), dtype=bool), *args, sd, 1.0, 2, 2.0) == -1).all()
    assert (fragment_owners(pts, component, free, np.zeros((0, 2)), np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0),
                            1.0, 2, 2.0) == -1).all()
    assert fragment_owners(pts, component, free, *args, sd, 1.0, 2, 2.0, np.array([True])).tolist() == got.tolist()
    unseen = fragment_owners(pts, component, free, *args, sd, 1.0, 2, 2.0, np.array([False]))
    assert (unseen == -1).all()  # a rectangle holding no points of its own (coasting) takes no fragment
    assert fragment_owners(pts, component, free, *args, sd, 1.0, 2, 2.0, None, 0.3).tolist() == got.tolist()
    far_side = pts.copy()
    far_side[:3, 1] = 7.0 - far_side[:3, 1]  # mirrored about the track's axis: on its left side's line,
    for tolerance in (None, 0.3):  # which the body hides from the sensor (and which does not face it)
        assert (fragment_owners(far_side, component, free, *args, sd, 1.0, 2, 2.0, None, tolerance)[:3] == -1).all()
    # the track straight ahead: its rear hides a point 1.2 m left of its axis past its front
    ahead_of_sensor = (centre * [1.0, 0.0], *args[1:])
    hidden = np.array([[56.0 * sign, 1.2]])
    assert fragment_owners(hidden, np.zeros(1, dtype=int), np.ones(1, dtype=bool), *ahead_of_sensor, sd, 1.0, 2,
                           2.0).tolist() == [-1]
    seen_past = np.array([[56.0 * sign, 1.6]])  # 1.6 m left: the ray passes the rear's corner
    assert fragment_owners(seen_past, np.zeros(1, dtype=int), np.ones(1, dtype=bool), *ahead_of_sensor, sd, 1.0, 2,
                           2.0).tolist() == [0]


def test_segment_crosses_box_by_the_slab_test() -> None:
    """``segment_crosses_box`` against hand-made cases: through the middle, past a corner, ending short
    of the box, starting inside, parallel inside and outside a slab, touching an edge (the box is
    open), an empty box."""
    from tracker.clustering import segment_crosses_box

    start = np.array([[-10.0, 0.0], [-10.0, 2.0], [-10.0, 0.0], [0.0, 0.0], [-10.0, 0.5], [-10.0, 1.5], [-10.0, 1.0],
                      [-10.0, 0.0]])
    end = np.array([[10.0, 0.0], [10.0, 1.5], [-3.0, 0.0], [10.0, 5.0], [10.0, 0.5], [10.0, 1.5], [10.0, 1.0],
                    [10.0, 0.0]])
    half_l = np.array([2.0, 2.0, 2.0, 2.0, 2.0, 2.0, 2.0, 0.0])
    half_w = np.array([1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0])
    assert segment_crosses_box(start, end, half_l, half_w).tolist() == [True, False, False, True, True, False, False,
                                                                         False]


@pytest.mark.parametrize("seed", range(3))
def test_points_in_rectangles_equal_the_oracle(seed):
    """Overlapping and disjoint rectangles of every heading (duplicate hypotheses of one vehicle, trucks
    beside cars), points inside, between and outside them, and on the widened rectangles' corners
    (where the kernel's skip of a rectangle beyond its circumscribed circle is at its boundary)."""
    from tracker.measurement import rectangle_corners

    rng = np.random.default_rng(seed)
    for _ in range(60):
        t = int(rng.integers(1, 16))
        centre = rng.uniform(-15.0, 15.0, (t, 2))
        psi, length, width = rng.uniform(-np.pi, np.pi, t), rng.uniform(2.0, 14.0, t), rng.uniform(0.8, 2.6, t)
        corners = rectangle_corners(centre, psi, length + 1.4, width + 1.4).reshape(-1, 2)
        pts = np.concatenate([rng.uniform(-20.0, 20.0, (300, 2)), centre + rng.normal(0.0, 1.0, (t, 2)), corners])
        np.testing.assert_array_equal(points_in_rectangles(pts, centre, psi, length, width, 0.7),
                                      oracle.points_in_rectangles(pts, centre, psi, length, width, 0.7))


@pytest.mark.parametrize("seed", range(3))
def test_occluded_ends_equal_the_oracle(seed):
    """The bearing ends of clusters of 1-40 points scattered around the sensor (some behind it, across
    the bearing seam, some near the range limit) in a scan of their own points and a few hundred others;
    windows of 1-5 rays, and the range cut on and off: the same flags, and some of each."""
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
                want = oracle.occluded_ends(ends, scan, window, 0.5, max_range, range_margin)
                np.testing.assert_array_equal(occluded_ends(ends, scan, window, 0.5, max_range, range_margin), want)
                flags.append(want)
    flags = np.concatenate(flags)
    assert flags.any() and (~flags).any() and (flags[:, 0] != flags[:, 1]).any()


@pytest.mark.parametrize("seed", range(3))
def test_continued_ends_equal_the_oracle(seed):
    """``continued_ends`` (the scan sorted by bearing, each end searching the bearing window of the disc
    its test can reach) against the oracle's test of every return: ends all around the sensor (across
    the seam behind it, and within a few metres of it, where the disc holds the lidar), returns
    scattered and returns placed on the ends' continuations; the same flags, and some of each."""
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
        want = oracle.continued_ends(ends, outward, half_gap, scan, 2.0, 0.3)
        np.testing.assert_array_equal(continued_ends(ends, outward, half_gap, scan, 2.0, 0.3), want)
        flags.append(want.ravel())
    flags = np.concatenate(flags)
    assert flags.any() and not flags.all()


@pytest.mark.parametrize("seed", range(3))
def test_radar_association_equals_the_oracle(seed):
    """Clusters (some empty) and detections scattered so that gates overlap and many pairs compete."""
    rng = np.random.default_rng(seed)
    taken = 0
    for _ in range(100):
        clusters = [rng.normal(rng.uniform(-20.0, 20.0, 2), 1.0, (int(rng.integers(0, 30)), 2))
                    for _ in range(int(rng.integers(1, 12)))]
        radar = rng.uniform(-20.0, 20.0, (int(rng.integers(0, 15)), 2))
        got = associate_radar(clusters, radar, 3.0)
        assert got.dtype == np.int64
        np.testing.assert_array_equal(got, oracle.associate_radar(clusters, radar, 3.0))
        taken += int((got >= 0).sum())
    assert taken > 0


def test_cluster_radar_ranges_equals_cluster_radar():
    """``cluster_radar_ranges`` (one compiled call) against ``cluster_radar`` on the clusters' views: the
    same detection per cluster (its velocity row, read-only) and free detections, for clusters of one
    point, more detections than clusters, detections exactly at the gate and none."""
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
        got, got_free = cluster_radar_ranges(points, lo, hi, radar, 1.0, 3.0)
        assert [v is None for v in got] == [v is None for v in velocities]
        assert all(a is None or (np.array_equal(a, b) and not b.flags.writeable) for a, b in zip(velocities, got))
        assert got_free.dtype == np.int64 and np.array_equal(got_free, np.setdiff1d(np.arange(count), index))


# --- the cuts along a track's cluster (along_cuts_kernel) ---------------------------------------------

STEP = np.radians(0.2)


def _scan(boxes: list[tuple[float, float, float, float]], bearings: np.ndarray) -> np.ndarray:
    """Exact 2-D lidar returns from the origin at ``bearings`` (rad): per ray the nearest hit of the
    axis-aligned boxes ``(x0, x1, y0, y1)`` (slab method); rays that hit nothing return nothing."""
    d = np.column_stack([np.cos(bearings), np.sin(bearings)])
    best = np.full(len(d), np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        for x0, x1, y0, y1 in boxes:
            tx = np.sort(np.column_stack([x0 / d[:, 0], x1 / d[:, 0]]), axis=1)
            ty = np.sort(np.column_stack([y0 / d[:, 1], y1 / d[:, 1]]), axis=1)
            near = np.maximum(tx[:, 0], ty[:, 0])
            far = np.minimum(tx[:, 1], ty[:, 1])
            hit = (near <= far) & (near > 0)
            best = np.where(hit & (near < best), near, best)
    keep = np.isfinite(best)
    return d[keep] * best[keep, None]


def _cut(points: np.ndarray, scan: np.ndarray, centre, length: float, width: float = 1.8):
    """``along_cuts_kernel`` for one track (heading +x) owning all ``points``."""
    return along_cuts_kernel(points, np.array([0, len(points)]), np.array([0]), np.array([centre], dtype=float),
                             np.ones(1), np.zeros(1), np.array([0.5 * length]), np.array([0.5 * width]), scan, STEP,
                             3.0, 1.0, 0.5, 3)


BEARINGS = np.arange(-60.0, 0.0, 0.2) * np.pi / 180.0 + 1e-4


def test_along_cut_splits_cars_nose_to_tail_and_bounds_the_kept_one():
    # two parked cars 2 m apart, 3 m right of the sensor; a track grown over both owns their points
    cars = [(12.0, 16.5, -4.8, -3.0), (18.5, 23.0, -4.8, -3.0)]
    pts = _scan(cars, BEARINGS)
    ordered, edges, owned, added, bounds = _cut(pts, pts, (17.5, -3.9), 11.0)
    assert added == 1 and len(edges) == 3
    first, second = ordered[edges[0]:edges[1]], ordered[edges[1]:edges[2]]
    assert owned.tolist() == [0, -1]
    # the nearer car, with more points, stays the track's; the other is a free cluster of its own
    assert first[:, 0].max() <= 16.5 + 1e-9 and second[:, 0].min() >= 18.5 - 1e-9
    assert len(first) + len(second) == len(pts)
    # the bound: half a ray gap beyond the kept part's last point along the heading (t from x = 17.5)
    last = first[np.argmax(first[:, 0])]
    half = 0.5 * (last @ last) * STEP / abs(last[1])
    assert bounds[0, 0] == -np.inf
    assert bounds[0, 1] == pytest.approx(last[0] + half - 17.5)
    assert 16.5 - 17.5 <= bounds[0, 1] < 18.5 - 17.5


def test_along_cut_keeps_a_long_side_whole():
    # one 11 m truck: its side's returns are spaced by a ray gap, never a hole
    truck = [(12.0, 23.0, -5.5, -3.0)]
    pts = _scan(truck, BEARINGS)
    *_, added, bounds = _cut(pts, pts, (17.5, -4.25), 11.0)
    assert added == 0 and np.all(np.isinf(bounds))
    # a dropped return (one ray) leaves two ray gaps: still no hole
    side = np.flatnonzero(np.abs(pts[:, 1] + 3.0) < 1e-9)
    holed = np.delete(pts, side[len(side) // 2], axis=0)
    assert _cut(holed, holed, (17.5, -4.25), 11.0)[3] == 0


def test_along_cut_not_at_a_shadow_or_where_the_side_goes_on_in_another_cluster():
    truck = (12.0, 23.0, -5.5, -3.5)
    pole = (8.0, 8.4, -2.0, -1.6)  # nearer: its shadow cuts a hole in the truck's side
    scan = _scan([truck, pole], BEARINGS)
    pts = scan[scan[:, 1] < -3.0]  # the truck's returns
    gaps = np.diff(np.sort(pts[np.abs(pts[:, 1] + 3.5) < 1e-9, 0]))
    assert gaps.max() > 1.5  # the shadow is a hole in the points ...
    assert _cut(pts, scan, (17.5, -4.5), 11.0)[3] == 0  # ... but not in the side
    # the side's returns in the gap belong to another cluster: no hole either
    side = _scan([truck], BEARINGS)
    side = side[np.abs(side[:, 1] + 3.5) < 1e-9]
    middle = (side[:, 0] > 15.0) & (side[:, 0] < 18.0)
    assert middle.sum() >= 3
    assert _cut(side[~middle], side, (17.5, -4.5), 11.0)[3] == 0
    # without them in the scan, it is a hole
    assert _cut(side[~middle], side[~middle], (17.5, -4.5), 11.0)[3] == 1


def test_along_cut_leaves_a_lone_far_return():
    # a part of fewer than min_part points is not cut off (a grazing side's last return)
    cars = [(12.0, 16.5, -4.8, -3.0)]
    pts = np.vstack([_scan(cars, BEARINGS), [[26.0, -3.0], [26.1, -3.0]]])
    assert _cut(pts, pts, (17.5, -3.9), 11.0)[3] == 0


# ray_partition: a 0.2 deg lidar; the adaptive breakpoint rule at 4 deg
RAY_STEP = np.deg2rad(0.2)
FULL_TURN = np.arange(-180.0, 180.0, 0.2) * np.pi / 180.0 + 1e-4
GRAZING = np.deg2rad(4.0)


def test_ray_partition_joins_a_far_side_seen_at_a_grazing_angle():
    # a truck 50 m ahead whose left side lies 5 m to the side: the side's returns are r^2 step / d apart
    truck = (50.0, 58.0, 5.0, 7.5)
    pts = _scan([truck], FULL_TURN)
    side = pts[np.abs(pts[:, 1] - 5.0) < 1e-9]
    side = side[np.argsort(side[:, 0])]
    gaps = np.diff(side[:, 0])
    r = np.hypot(side[:-1, 0], side[:-1, 1])
    assert len(side) >= 4 and np.allclose(gaps, r**2 * RAY_STEP / 5.0, rtol=0.05) and gaps.min() > 1.0
    assert len(np.unique(distance_partition(pts, 1.0))) > 1  # one threshold leaves the side in pieces
    assert ray_partition(pts, 1.0, GRAZING, RAY_STEP).tolist() == [0] * len(pts)
    # a side at 3 deg incidence (2.1 m to the side, 40 m ahead): its returns are 2.7 m apart, beyond the
    # reach at 4 deg (2.0 m there), within it at 2 deg
    rays = np.arange(1, 400) * RAY_STEP
    x = 2.1 / np.tan(rays)
    line = np.column_stack([x, np.full(len(x), 2.1)])[(x >= 40.0) & (x <= 52.0)]
    assert len(line) >= 4
    assert len(np.unique(ray_partition(line, 1.0, GRAZING, RAY_STEP))) == len(line)
    assert ray_partition(line, 1.0, np.deg2rad(2.0), RAY_STEP).tolist() == [0] * len(line)


def test_ray_partition_keeps_apart_cars_a_ray_passes_between():
    # two cars in the next lane 2.5 m apart nose to tail, 40 m ahead: rays pass through the gap and hit
    # nothing, or a wall 30 m behind; either way the cars stay two clusters
    cars = [(40.0, 44.5, 5.0, 6.8), (47.0, 51.5, 5.0, 6.8)]
    for boxes in (cars, cars + [(80.0, 81.0, 5.0, 12.0)]):
        pts = _scan(boxes, FULL_TURN)
        labels = ray_partition(pts, 1.0, GRAZING, RAY_STEP)
        first, second = labels[(pts[:, 0] <= 44.5 + 1e-9)], labels[(pts[:, 0] >= 47.0 - 1e-9) & (pts[:, 0] <= 51.5 + 1e-9)]
        assert len(set(first)) == 1 and len(set(second)) == 1 and first[0] != second[0]


def test_ray_partition_does_not_bridge_a_dropped_return_or_a_wide_gap():
    pts = _scan([(50.0, 58.0, 5.0, 7.5)], FULL_TURN)
    side = np.flatnonzero(np.abs(pts[:, 1] - 5.0) < 1e-9)
    order = side[np.argsort(pts[side, 0])]
    holed = np.delete(pts, order[1], axis=0)  # a ray that returned nothing: two steps between its neighbours
    assert len(np.unique(ray_partition(holed, 1.0, GRAZING, RAY_STEP))) == 2
    assert len(np.unique(ray_partition(pts, 1.0, GRAZING, RAY_STEP, max_gap=1.5))) > 1  # gaps of 1.9 m


def test_ray_partition_joins_across_the_rear_bearing():
    # a side behind the sensor seen at a grazing angle, its returns on rays either side of the bearing pi
    # (the first and last in bearing order), 1.5 m apart: beyond the distance threshold, within the
    # reach at 4 deg (50 m x 0.2 deg / sin 4 deg = 2.5 m)
    rays = np.pi + (np.arange(-2, 3) + 0.5) * RAY_STEP
    r = 50.0 + 1.5 * np.arange(5)
    pts = np.column_stack([r * np.cos(rays), r * np.sin(rays)])
    assert np.ptp(np.arctan2(pts[:, 1], pts[:, 0])) > np.pi  # the bearings wrap
    assert len(np.unique(distance_partition(pts, 1.0))) == 5
    labels = ray_partition(pts, 1.0, GRAZING, RAY_STEP)
    assert labels.tolist() == [0] * 5
    assert labels.tolist() == oracle.ray_partition(pts, 1.0, GRAZING, RAY_STEP, 4.0).tolist()


@pytest.mark.parametrize("seed", range(4))
def test_ray_partition_equals_the_oracle(seed):
    # 30 runs of returns on a 0.2 deg ray grid (some rays empty, bearings jittered), each run a surface
    # whose range grows by 0.3-3 m per ray (steep to grazing) from 5-60 m
    rng = np.random.default_rng(seed)
    rays = np.sort(rng.choice(np.arange(-300, 300), 300, replace=False)) * RAY_STEP
    rays = rays + rng.normal(0.0, 0.02 * RAY_STEP, len(rays))
    r = (np.repeat(rng.uniform(5.0, 60.0, 30), 10)
         + np.repeat(rng.uniform(0.3, 3.0, 30), 10) * np.tile(np.arange(10), 30) + rng.normal(0.0, 0.05, 300))
    pts = np.column_stack([r * np.cos(rays), r * np.sin(rays)])
    pts = pts[rng.permutation(len(pts))]
    count = {}
    for angle, gap in ((GRAZING, 4.0), (np.deg2rad(15.0), 2.0)):
        expected = oracle.ray_partition(pts, 1.0, angle, RAY_STEP, gap)
        assert ray_partition(pts, 1.0, angle, RAY_STEP, gap).tolist() == expected.tolist()
        count[angle] = len(np.unique(expected))
    assert count[GRAZING] < count[np.deg2rad(15.0)] <= len(np.unique(distance_partition(pts, 1.0)))


def test_ray_partition_without_an_angle_is_the_distance_partition_and_checks_its_arguments():
    pts = _scan([(52.0, 56.5, 5.0, 6.8)], FULL_TURN)
    assert ray_partition(pts, 1.0).tolist() == distance_partition(pts, 1.0).tolist()
    for kwargs in ({"grazing_angle": 0.0}, {"grazing_angle": np.pi / 2}):
        with pytest.raises(ValueError, match="grazing_angle must be in"):
            ray_partition(pts, 1.0, **kwargs)
    with pytest.raises(ValueError, match="max_gap must be > 0"):
        ray_partition(pts, 1.0, GRAZING, RAY_STEP, max_gap=0.0)
