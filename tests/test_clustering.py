"""Tests of tracker/clustering.py."""

from __future__ import annotations

import numpy as np
import pytest

from tracker import compiled
from tracker.clustering import (associate_radar, continued_ends, distance_partition, fragment_owners, occluded_ends,
                                points_in_rectangles, split_across)
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


def test_associate_radar_greedy_within_gate():
    clusters = [np.array([[10.0, 0.0], [10.0, 1.0]]), np.array([[20.0, 0.0]]), np.array([[40.0, 0.0]])]
    radar = np.array([[10.5, 0.5], [19.0, 0.0], [10.2, 0.0], [45.0, 0.0]])
    out = associate_radar(clusters, radar, gate=2.0)
    # cluster 0 takes its nearest detection (2: 0.2 m), cluster 1 takes detection 1, cluster 2 none
    np.testing.assert_array_equal(out, [2, 1, -1])
    np.testing.assert_array_equal(associate_radar(clusters, np.zeros((0, 2))), [-1, -1, -1])


@pytest.mark.parametrize("seed", range(5))
def test_dense_components_equal_scipys(seed):
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    from tracker.clustering import dense_components

    rng = np.random.default_rng(seed)
    count = int(rng.integers(1, 60))
    adj = rng.random((count, count)) < 1.5 / count
    _, want = connected_components(csr_matrix(adj), directed=False)
    np.testing.assert_array_equal(dense_components(adj), want)
    assert dense_components(np.zeros((0, 0), dtype=bool)).shape == (0,)


def _oracle_partition(points: np.ndarray, threshold: float) -> np.ndarray:
    """Connected components of the whole threshold graph (scipy), relabelled by first point."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    pairs = cKDTree(points).query_pairs(threshold, output_type="ndarray")
    n = len(points)
    labels = connected_components(coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n)),
                                  directed=False)[1]
    _, first = np.unique(labels, return_index=True)
    rank = np.empty(len(first), dtype=int)
    rank[np.argsort(first)] = np.arange(len(first))
    return rank[labels]


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("order", ["scan", "shuffled"])
def test_distance_partition_equals_the_whole_graph_components(seed, order):
    # a scan-like cloud (objects as dense arcs, clutter) in scan order, and the same shuffled: the run
    # decomposition must give exactly the components of the full graph (shuffled: hundreds of runs,
    # the sparse path; scan order: few runs, the dense path)
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
        np.testing.assert_array_equal(distance_partition(pts, threshold), _oracle_partition(pts, threshold))


def test_split_across_cuts_wide_groups_at_their_largest_lateral_gap():
    """A group wider than ``width`` across the road is cut at its largest gap in ``n`` (again while a
    part is still wider); narrow groups, and wide ones without a gap of ``gap`` (one vehicle at an
    angle, its side continuous), stay whole."""
    n = np.array([0.0, 0.2, 0.4, 1.2, 1.5, 3.0, 3.1, 5.0, 5.2, 5.3])
    one = np.zeros(len(n), dtype=int)
    assert split_across(n, one, 3.5, 0.5).tolist() == [0] * 7 + [1] * 3  # cut at 3.1 | 5.0
    assert split_across(n, one, 2.0, 0.5).tolist() == [0] * 5 + [1] * 2 + [2] * 3  # and at 1.5 | 3.0
    assert split_across(n, one, 6.0, 0.5).tolist() == [0] * 10  # narrow enough
    side = np.linspace(-1.0, 4.0, 60)  # a bus at an angle: 5 m across, no gap
    assert split_across(side, np.zeros(60, dtype=int), 3.0, 0.5).tolist() == [0] * 60
    # two groups, in any order of the points: each is cut on its own; parts numbered by group, then n
    rng = np.random.default_rng(1)
    order = rng.permutation(20)
    both = split_across(np.r_[n, n][order], np.r_[one + 7, one + 3][order], 3.5, 0.5)
    assert both.tolist() == np.r_[[2] * 7 + [3] * 3, [0] * 7 + [1] * 3][order].tolist()
    assert split_across(np.zeros(0), np.zeros(0, dtype=int), 3.0, 0.5).tolist() == []


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


@pytest.mark.parametrize("kernels", ["numpy", "compiled"])
def test_continued_ends_flags_a_side_that_goes_on_in_another_cluster(kernels, monkeypatch):
    """A truck's left side 2 m to the right of the lidar, seen from 15 to 30 m ahead with rays every
    0.2 deg (gaps 0.4-1.6 m along it: grazing). One return is missing (at 22 m ahead), and the side
    falls apart into two clusters. The near part's far end and the far part's near end go on in the
    other part: continued; the far part's far end and the near part's near end are free. A return
    1 m beside the side's line beyond the far end (another car's corner) does not continue it; nor
    does the next ray's return farther than ``rays`` ray gaps along it."""
    if kernels == "compiled" and not compiled.available():
        pytest.skip("numba not installed")
    monkeypatch.setenv(compiled.ENV_SWITCH, "1" if kernels == "compiled" else "0")
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
