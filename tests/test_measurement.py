"""Tests of tracker/measurement.py: the rectangle measurement model against exact contour points, and its
kernels (``to_vehicle``'s, ``tracker.structure``) against the numpy oracle ``oracles.measurement``."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from oracles.measurement import build_structure as oracle_structure
from oracles.measurement import to_vehicle as oracle_to_vehicle
from oracles.measurement import visible_sides
from scenes import Car, Scene, kernel_roads

from tracker import Road, Tracker
from tracker.config import MeasurementConfig, TrackerConfig
from tracker.frame import EgoState
from tracker.measurement import (
    CENTRE,
    Cluster,
    FROM_A,
    FROM_B,
    FULL,
    ClusterBatch,
    build_structure,
    generating_points,
    predict_measurements,
    prepare_cluster,
    rectangle_corners,
    rectangle_scan,
    to_vehicle,
)
from tracker.ukf import UnscentedTransform
from tracker.update import update, update_pairs

EXACT = MeasurementConfig()


def cornered(points: np.ndarray, config: MeasurementConfig = EXACT, velocity=None) -> Cluster:
    """``prepare_cluster`` with MATLAB's model of the ends: the extreme points are the corners (no
    end-gap margins), so the generating points of a noise-free scan are its points."""
    c = prepare_cluster(points, config, velocity=velocity)
    return dataclasses.replace(c, end_margin=np.zeros((3, 2)), end_gap=np.zeros((3, 2)))
R80 = 80.0


@pytest.fixture(scope="module")
def circle80() -> Road:
    return Road.from_curvature([(2 * np.pi * R80, 1 / R80, 1 / R80)], closed=True, lanes=2)


def corners_of(state: np.ndarray) -> np.ndarray:
    """Corners in E of a Cartesian state seen from an ego at the origin with yaw 0."""
    return rectangle_corners(state[:2], np.asarray(state[3]), np.asarray(state[5]), np.asarray(state[6]))


def bearing(p: np.ndarray) -> np.ndarray:
    return np.arctan2(p[..., 1], p[..., 0])


def two_sided_scan(k: np.ndarray, far_a: int, corner: int, far_b: int, n_a: int = 30, n_b: int = 20) -> np.ndarray:
    """Exact contour points from far corner ``far_a`` to ``corner`` to ``far_b``, corners included."""
    b = bearing(k)
    rays = np.concatenate([np.linspace(b[far_a], b[corner], n_a), np.linspace(b[corner], b[far_b], n_b)[1:]])
    pts, hit = rectangle_scan(k, rays)
    assert hit.all()
    return pts


ORIGIN = (0.0, 0.0, 0.0)
# a car ahead-left, heading +x: its rear (side 2) and right side (side 3) face the lidar; corner K3
AHEAD_LEFT = np.array([12.0, 3.5, 10.0, 0.1, 0.0, 4.7, 1.9])


def test_two_sided_exact_contour_generating_points_within_1cm() -> None:
    k = corners_of(AHEAD_LEFT)
    assert visible_sides(k).tolist() == [False, False, True, True]
    pts = two_sided_scan(k, 0, 3, 2)
    shuffled = pts[np.random.default_rng(0).permutation(len(pts))]
    c = cornered(shuffled, EXACT)
    assert c.two_sided and c.size == len(pts)
    np.testing.assert_allclose(c.points[c.corner], k[3], atol=1e-9)  # the corner index is the corner
    y = generating_points(AHEAD_LEFT, c, ORIGIN, config=EXACT, coordinates="cartesian")
    assert np.abs(y - c.points).max() < 0.01
    assert np.abs(y - c.points).max() < 1e-9  # in fact exact


def test_one_sided_exact_contour_generating_points_within_1cm() -> None:
    state = np.array([15.0, 0.2, 10.0, 0.0, 0.0, 4.5, 1.8])  # straight ahead: only its rear is visible
    k = corners_of(state)
    assert visible_sides(k).tolist() == [False, False, True, False]
    b = bearing(k)
    pts, _ = rectangle_scan(k, np.linspace(b[3], b[2], 25))
    c = cornered(pts, EXACT)
    assert not c.two_sided
    y = generating_points(state, c, ORIGIN, config=EXACT, coordinates="cartesian")
    assert np.abs(y - c.points).max() < 0.01
    st = build_structure(ClusterBatch.of([c]), np.array([0]), k[None], EXACT)
    assert st.sides[0, 0] == 2 and st.mode[0, 0] == FULL


def test_curvilinear_state_goes_through_road_and_ego_pose(circle80: Road) -> None:
    """State (s, n, xi) on a radius-80 road, ego in the other lane with a yaw offset: the model's
    rectangle matches one built by hand, and exact contour points are reproduced within 1 cm."""
    state = np.array([40.0, 1.75, 15.0, 0.05, 0.0, 4.7, 1.9])
    s_e = 28.0
    ego_xy = circle80.to_cartesian(s_e, -1.75)
    ego = (ego_xy[0], ego_xy[1], float(circle80.heading(s_e)) + 0.02)
    # by hand: centre in G, heading theta + xi, into E
    theta = float(circle80.heading(40.0))
    centre_g = circle80.position(40.0) + 1.75 * np.array([-np.sin(theta), np.cos(theta)])
    c, s = np.cos(ego[2]), np.sin(ego[2])
    d = centre_g - ego_xy
    centre_e = np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])
    k_hand = rectangle_corners(centre_e, np.asarray(theta + 0.05 - ego[2]), np.asarray(4.7), np.asarray(1.9))
    rect = to_vehicle(state, ego, circle80)
    np.testing.assert_allclose(rect.corners(), k_hand, atol=1e-9)
    vis = visible_sides(k_hand)
    assert vis.sum() == 2
    j = int(np.flatnonzero(vis & np.roll(vis, 1))[0])  # sides j - 1 and j visible: corner K_j
    pts = two_sided_scan(k_hand, (j + 1) % 4, j, (j - 1) % 4)
    cl = cornered(pts, EXACT)
    y = generating_points(state, cl, ego, circle80, EXACT)
    assert np.abs(y - cl.points).max() < 0.01


def test_corner_index_found_with_noise() -> None:
    """Noise 2 cm: the corner split lands within two points of the true corner in 20 of 20 draws; and
    the fitted-line corner (chord end) is within 5 cm of the true corner."""
    k = corners_of(AHEAD_LEFT)
    pts = two_sided_scan(k, 0, 3, 2, n_a=40, n_b=30)
    true_index = 39
    every_point = dataclasses.replace(EXACT, max_cluster_points=len(pts))  # no downsampling: indices as given
    rng = np.random.default_rng(1)
    for _ in range(20):
        noisy = pts + 0.02 * rng.standard_normal(pts.shape)
        c = cornered(noisy[rng.permutation(len(noisy))], every_point)
        assert c.two_sided and c.size == len(pts)
        assert abs(c.corner - true_index) <= 2
        assert np.hypot(*(c.chord_end[1] - k[3])) < 0.05


def test_partial_visibility_keeps_the_length_from_shrinking() -> None:
    """The far 60 % of the long side is hidden (occluded). With the rule (0.6) the points are anchored
    at the observed corner with their measured spacing and 10 updates leave L at 4.7 m; without it
    (threshold 0) the generating points are spread over the whole side and L shrinks towards the
    visible 1.9 m."""
    state = AHEAD_LEFT.copy()
    k = corners_of(state)
    b = bearing(k)
    visible_end = k[3] + 0.4 * (k[0] - k[3])  # only 40 % of the right side, next to the corner
    rays = np.concatenate([np.linspace(bearing(visible_end), b[3], 15), np.linspace(b[3], b[2], 20)[1:]])
    pts, _ = rectangle_scan(k, rays)
    cfg = MeasurementConfig(lidar_sigma=0.05)  # the contour includes the corners
    cl = cornered(pts, cfg)
    st = build_structure(ClusterBatch.of([cl]), np.array([0]), k[None], cfg)
    assert st.two_sided[0] and st.mode[0, 0] == FROM_B and st.mode[0, 1] == FULL
    y = generating_points(state, cl, ORIGIN, config=cfg, coordinates="cartesian")
    assert np.abs(y - cl.points).max() < 0.01  # anchored at the corner: exact for the true state
    lengths = {}
    for threshold in (0.6, 0.0):
        tc = TrackerConfig(
            coordinates="cartesian",
            measurement=MeasurementConfig(lidar_sigma=0.05, partial_visibility=threshold),
        )
        ut = UnscentedTransform(tc.ukf)
        mean, cov = state.copy(), np.diag([0.1, 0.1, 0.5, 0.02, 0.01, 0.5, 0.1]) ** 2
        c2 = cornered(pts, tc.measurement)
        for _ in range(10):
            mean, cov, _ = update(mean, cov, c2, ORIGIN, None, tc, ut)
            cov = cov + np.diag([1e-4, 1e-4, 1e-3, 1e-5, 1e-5, 1e-3, 1e-4])
        lengths[threshold] = mean[5]
    assert abs(lengths[0.6] - 4.7) < 0.1
    assert lengths[0.0] < 4.7 - 1.0


def test_a_side_ending_in_a_shadow_is_partial_and_anchored_at_its_free_end() -> None:
    """A car 30 m straight ahead shows its rear, traversed from K3 (right, the lower bearing) to K2. When
    the rear's left part lies in a nearer object's shadow (``ClusterBatch.occluded_end[:, 1]``), the
    rear is partially visible however much of it shows, and the visible right end anchors it at K3
    (``FROM_A``), even when the prediction sits 0.6 m too far right and the nearest-anchor rule picks
    the centre; mirrored for a shadow on the right (``FROM_B``). Without the flags or with a blunt free
    end: the rules before; with both ends in shadows: partially visible however much shows, anchored
    by the nearest-anchor rule (the window's spread: the next test)."""
    truth = np.array([30.0, 0.0, 10.0, 0.0, 0.0, 4.7, 1.9])
    k = corners_of(truth)
    predicted = corners_of(truth + np.array([0.0, -0.6, 0.0, 0.0, 0.0, 0.0, 0.0]))[None]
    b3, b2 = bearing(k[3]), bearing(k[2])
    for share, first_end in ((0.35, True), (0.35, False), (0.97, True)):
        lo, hi = (b3, b3 + share * (b2 - b3)) if first_end else (b2 - share * (b2 - b3), b2)
        pts, hit = rectangle_scan(k, np.linspace(lo, hi, 12))
        assert hit.all()
        batch = ClusterBatch.of([cornered(pts, EXACT)])
        shadow = np.array([[not first_end, first_end]])  # the end away from the visible one is occluded
        flagged = build_structure(dataclasses.replace(batch, occluded_end=shadow), np.array([0]), predicted, EXACT)
        plain = build_structure(batch, np.array([0]), predicted, EXACT)
        assert flagged.sides[0, 0] == plain.sides[0, 0] == 2 and not flagged.two_sided[0]
        assert flagged.mode[0, 0] == (FROM_A if first_end else FROM_B)
        if share > 0.9:
            assert plain.mode[0, 0] == FULL  # taken as the whole rear: stretched over it
        elif first_end:
            assert plain.mode[0, 0] == CENTRE  # the 0.6 m error made the centre the nearest anchor
        # a blunt free end (half a ray gap wider than shadow_free_gap: a far or grazing side) is no
        # corner to anchor at; nor does a shadow at both ends say where the side ends: the rules before
        blunt = dataclasses.replace(batch, occluded_end=shadow, end_gap=np.full_like(batch.end_gap, 0.5))
        assert build_structure(blunt, np.array([0]), predicted, EXACT).mode[0, 0] == \
            build_structure(dataclasses.replace(blunt, occluded_end=None), np.array([0]), predicted, EXACT).mode[0, 0]
        both = build_structure(dataclasses.replace(batch, occluded_end=np.array([[True, True]])), np.array([0]), predicted, EXACT)
        if plain.mode[0, 0] != FULL:
            assert both.mode[0, 0] == plain.mode[0, 0]
        else:  # the nearest anchor of the prediction 0.6 m right: the end K2 (the side's last point)
            assert both.mode[0, 0] == FROM_B


def _window_factor(structure) -> np.ndarray:
    """Each valid point's first end-gap noise factor's length (m): its shift along the side per unit."""
    f = structure.factors[0, 0, : 2 * int(structure.valid[0].sum())].reshape(-1, 2)
    return np.linalg.norm(f, axis=1)


def test_a_side_seen_between_two_shadows_is_a_window_anywhere_along_it() -> None:
    """A car 30 m straight ahead shows the middle 35 % of its 1.9 m rear between two nearer objects'
    shadows (both ``ClusterBatch.occluded_end`` flags). The points are a window onto the rear, which may
    lie anywhere along it: the rear is partially visible, anchored by the nearest-anchor rule, and every
    point shares one more shift along the rear, of standard deviation ``(W - chord) / sqrt(12)`` (a
    uniform place over the unseen 65 %), above the end gaps' own. An end flagged because it lies within
    ``shadow_range_margin`` of the lidar's range is the range limit, not a shadow: no window there."""
    truth = np.array([30.0, 0.0, 10.0, 0.0, 0.0, 4.7, 1.9])
    k = corners_of(truth)
    b3, b2 = bearing(k[3]), bearing(k[2])
    pts, hit = rectangle_scan(k, np.linspace(b3 + 0.3 * (b2 - b3), b3 + 0.65 * (b2 - b3), 12))
    assert hit.all()
    batch = ClusterBatch.of([cornered(pts, EXACT)])
    both = dataclasses.replace(batch, occluded_end=np.array([[True, True]]))
    plain = build_structure(batch, np.array([0]), k[None], EXACT)
    window = build_structure(both, np.array([0]), k[None], EXACT)
    assert plain.mode[0, 0] == window.mode[0, 0] == CENTRE and not window.two_sided[0]
    spread = (1.9 - batch.chord_len[0, 0]) / np.sqrt(12.0)
    assert 0.3 < spread < 0.4
    np.testing.assert_allclose(_window_factor(window), np.hypot(_window_factor(plain), spread), rtol=1e-12)
    # seen from 32 m of range (30 m inside the last 5 m): both flags are the range limit's
    limited = build_structure(both, np.array([0]), k[None], EXACT, lidar_range=32.0)
    np.testing.assert_array_equal(limited.factors, plain.factors)
    # the whole rear between two shadows (a predicted side the chord covers): partial, not stretched
    whole, _ = rectangle_scan(k, np.linspace(b3, b2, 12))
    wide = ClusterBatch.of([cornered(whole, EXACT)])
    assert build_structure(wide, np.array([0]), k[None], EXACT).mode[0, 0] == FULL
    flagged = build_structure(dataclasses.replace(wide, occluded_end=np.array([[True, True]])), np.array([0]),
                              k[None], EXACT)
    assert flagged.mode[0, 0] != FULL


def test_a_window_sliding_along_a_side_does_not_drag_the_track() -> None:
    """The rear of a car 30 m ahead seen through a 0.6 m gap between two nearer objects, the gap
    sliding from the rear's left end to its right end over 12 frames (both ends flagged in shadows). The
    nearest anchor alone (the window rule off: the flags read as the range limit) drags the estimate
    sideways with the gap; with the window's spread it stays near the truth."""
    truth = np.array([30.0, 0.0, 10.0, 0.0, 0.0, 4.7, 1.9])
    k = corners_of(truth)
    b3, b2 = bearing(k[3]), bearing(k[2])
    config = TrackerConfig(coordinates="cartesian")
    ut = UnscentedTransform(config.ukf)
    error = {}
    for label, lidar_range in (("window", 100.0), ("off", 32.0)):
        mean = truth.copy()
        cov = np.diag([0.1, 0.2, 0.5, 0.02, 0.01, 0.3, 0.1]) ** 2
        for start in np.linspace(0.65, 0.05, 12):  # the gap's first ray, as a share of the rear from K3
            pts, _ = rectangle_scan(k, np.linspace(b3 + start * (b2 - b3), b3 + (start + 0.3) * (b2 - b3), 10))
            batch = dataclasses.replace(ClusterBatch.of([cornered(pts, config.measurement)]),
                                        occluded_end=np.array([[True, True]]))
            cfg = dataclasses.replace(config, detection=dataclasses.replace(config.detection, lidar_range=lidar_range))
            res = update_pairs(mean[None], cov[None], batch, np.zeros(1, int), np.zeros(1, int), ORIGIN, None, cfg, ut)
            mean, cov = res.mean[0], res.cov[0] + np.diag([1e-4, 4e-3, 1e-3, 1e-5, 1e-5, 1e-3, 1e-4])
        error[label] = abs(mean[1] - truth[1])
    assert error["window"] < 0.25  # 0.15 m: the centre anchor's pull, weakened
    assert error["off"] > 0.8 and error["off"] > 4.0 * error["window"]  # 1.2 m: most of the gap's travel


def test_a_two_sided_part_ending_in_a_shadow_is_partial_unless_longer_than_predicted() -> None:
    """A 16 m bus 25 m ahead, 5 m left, shows its right side and rear, rays every 0.05 deg; its front
    1.2 m lie in a nearer object's shadow (``ClusterBatch.occluded_end[:, 0]``, the side's far end is
    the cluster's first point). Predicted at its true 16 m, the visible side covers over 90 % of it:
    partially visible and anchored at the corner (``FROM_B``), not the whole side (``FULL``, which would
    pull the length to what shows). Predicted 12 m long (same rear-right corner), the side is longer
    than predicted: measured whole, to the last return (no end-gap margin at the shadowed end, so the
    first point is the far corner: ``c1 = 0``). No shadow flags, or the shadow at the other end (the
    rear's): ``FULL``."""
    bus = np.array([25.0, 5.0, 10.0, 0.0, 0.0, 16.0, 2.5])
    k = corners_of(bus)  # K0 front-right (lowest bearing), K3 rear-right, K2 rear-left
    visible_front = k[0] + 1.2 * (k[3] - k[0]) / 16.0
    pts, hit = rectangle_scan(k, np.arange(bearing(visible_front), bearing(k[2]), np.radians(0.05)))
    assert hit.all()
    config = MeasurementConfig()
    batch = ClusterBatch.of([prepare_cluster(pts, config)])
    assert batch.two_sided[0]
    shadowed = dataclasses.replace(batch, occluded_end=np.array([[True, False]]))
    true_length = corners_of(bus)[None]
    short = corners_of(bus + np.array([-2.0, 0.0, 0.0, 0.0, 0.0, -4.0, 0.0]))[None]  # 12 m, same K3
    np.testing.assert_allclose(short[0, 3], k[3], atol=1e-12)
    sd = np.array([[1.0, 0.2]])

    def structure(b, corners=true_length, cfg=config):
        st = build_structure(b, np.array([0]), corners, cfg, extent_sd=sd)
        assert st.two_sided[0] and st.sides[0].tolist() == [3, 2]  # the right side, then the rear
        return st

    covered = batch.chord_len[0, 1] + batch.end_margin[0, 1].sum()
    assert 0.9 * 16.0 < covered < 16.0  # what the rule is about: over partial_visibility, short of the side
    assert structure(shadowed).mode[0, 0] == FROM_B
    assert structure(batch).mode[0, 0] == FULL  # no flags
    assert structure(dataclasses.replace(batch, occluded_end=np.array([[False, True]]))).mode[0, 0] == FULL
    longer = structure(shadowed, corners=short)
    assert longer.mode[0, 0] == FULL and abs(longer.c1[0, 0]) < 1e-12  # to the last return
    unflagged = structure(batch, corners=short)
    assert unflagged.mode[0, 0] == FULL and unflagged.c1[0, 0] > 0.0  # the end-gap margin beyond it
    # the oracle agrees
    other = oracle_structure(shadowed, np.array([0]), short, config, extent_sd=sd)
    np.testing.assert_array_equal(other.mode, longer.mode)
    np.testing.assert_allclose(other.coef, longer.coef, atol=1e-12)
    np.testing.assert_allclose(other.r, longer.r, atol=1e-12)


def test_a_short_side_with_both_ends_sharp_and_free_is_the_whole_side() -> None:
    """A motorcycle (2.2 x 0.8 m) 20 m straight ahead shows its whole 0.8 m rear; predicted as a car
    (1.9 m wide) the rear covers 42 % of the predicted one. With shadow flags saying neither end borders a nearer object, both ends sharp (half a ray gap,
    ~4 cm here): the whole rear (``FULL``), so the width can shrink to it. Not without the shadow
    flags (nothing says an end is free), not with an end in a shadow or continuing in another cluster,
    not with a blunt end (half a ray gap over ``shadow_free_gap``): partially visible, anchored."""
    truth = np.array([20.0, 0.0, 10.0, 0.0, 0.0, 2.2, 0.8])
    k = corners_of(truth)
    predicted = corners_of(np.array([20.0, 0.0, 10.0, 0.0, 0.0, 4.7, 1.9]) + np.array([1.25, 0, 0, 0, 0, 0, 0]))[None]
    rays = np.arange(bearing(k[3]) - 0.01, bearing(k[2]) + 0.01, np.radians(0.2))
    pts, hit = rectangle_scan(k, rays)
    config = MeasurementConfig()
    batch = ClusterBatch.of([prepare_cluster(pts, config)])
    assert np.all(batch.end_gap[0, 0] < 0.05) and not batch.two_sided[0]
    free = dataclasses.replace(batch, occluded_end=np.array([[False, False]]))
    structure = build_structure(free, np.array([0]), predicted, config)
    assert structure.sides[0, 0] == 2 and structure.mode[0, 0] == FULL
    for other in (batch, dataclasses.replace(batch, occluded_end=np.array([[False, True]])),
                  dataclasses.replace(free, continued_end=np.array([[True, False]])),
                  dataclasses.replace(free, end_gap=np.full_like(batch.end_gap, 0.35))):
        assert build_structure(other, np.array([0]), predicted, config).mode[0, 0] != FULL


def test_each_part_of_a_two_sided_cluster_with_a_sharp_free_end_is_its_whole_side() -> None:
    """A motorcycle (2.2 x 0.8 m) 15 m ahead-left shows its rear (0.8 m) and right side (2.2 m), rays
    every 0.2 deg; predicted as a car (4.5 x 1.8 m) with the same rear-right corner, the parts cover
    44 % and 49 % of the predicted sides. With both far ends sharp and free, both parts with at least ``whole_min_points`` points, the shrinks within 3 sd + 0.3
    m of the extent's sd, both parts are whole (``FULL``); each condition that fails keeps its part(s)
    partially visible, anchored at the corner (``FROM_B`` / ``FROM_A``): no extent sd
    (the gate cannot be checked), no shadow flags, a far end in a shadow or continuing in another
    cluster (that part only), a blunt far end (half a ray gap above ``shadow_free_gap`` and the
    predicted side going on less than one ray gap beyond it), too few points per part, an sd too small
    for the shrink (that side only)."""
    moto = np.array([15.0, 3.5, 10.0, 0.0, 0.0, 2.2, 0.8])
    k = corners_of(moto)
    car = moto + np.array([1.15, 0.5, 0.0, 0.0, 0.0, 2.3, 1.0])  # same rear-right corner K3
    predicted = corners_of(car)[None]
    np.testing.assert_allclose(predicted[0, 3], k[3], atol=1e-12)
    b = bearing(k)
    pts, hit = rectangle_scan(k, np.arange(b[0] + 1e-4, b[2], np.radians(0.2)))
    assert hit.all()
    config = MeasurementConfig()
    batch = ClusterBatch.of([prepare_cluster(pts, config)])
    assert batch.two_sided[0] and np.all(batch.end_gap[0, [1, 2], [0, 1]] < config.shadow_free_gap)
    free = dataclasses.replace(batch, occluded_end=np.zeros((1, 2), dtype=bool))
    sd = np.array([[1.0, 0.4]])  # a car prior's L, W sds: shrinks of 2.3 m and 1.0 m pass the gate

    def modes(b, cfg=config, extent_sd=sd):
        st = build_structure(b, np.array([0]), predicted, cfg, extent_sd=extent_sd)
        assert st.two_sided[0] and st.sides[0].tolist() == [3, 2]  # the right side, then the rear
        return st.mode[0].tolist()

    assert modes(free) == [FULL, FULL]
    assert modes(free, extent_sd=None) == [FROM_B, FROM_A]
    assert modes(batch) == [FROM_B, FROM_A]  # no shadow flags: nothing says an end is free
    assert modes(dataclasses.replace(free, occluded_end=np.array([[True, False]]))) == [FROM_B, FULL]
    assert modes(dataclasses.replace(free, continued_end=np.array([[False, True]]))) == [FULL, FROM_A]
    # a far end with half a ray gap of 0.35 m or 1.1 m (> shadow_free_gap) is still sharp: the predicted
    # side goes on 2.3 m beyond the last return, where the next ray (0.7 m, 2.2 m on) would have hit it;
    # with 1.2 m (the next ray 2.4 m on, past the predicted end) it is blunt
    blunt = free.end_gap.copy()
    for half_gap, expected in ((0.35, FULL), (1.1, FULL), (1.2, FROM_B)):
        blunt[0, 1, 0] = half_gap
        assert modes(dataclasses.replace(free, end_gap=blunt)) == [expected, FULL]
    assert modes(free, dataclasses.replace(config, whole_min_points=40)) == [FROM_B, FROM_A]
    assert modes(free, extent_sd=np.array([[0.2, 0.4]])) == [FROM_B, FULL]  # 2.3 m > 3 x 0.2 + 0.3


def test_three_points_per_part_show_a_whole_side() -> None:
    """The motorcycle of the test above seen with rays every 1.0 deg: 5 returns, 3 on each part (the corner
    counted in both), both far ends sharp and free. Three points fix each part's line with one to spare,
    so both parts are whole with the default ``whole_min_points`` (3); with 4 each stays partially
    visible, anchored at the corner, and the car's predicted extent would never shrink to the
    motorcycle's."""
    moto = np.array([15.0, 3.5, 10.0, 0.0, 0.0, 2.2, 0.8])
    k = corners_of(moto)
    predicted = corners_of(moto + np.array([1.15, 0.5, 0.0, 0.0, 0.0, 2.3, 1.0]))[None]  # a car, the same corner
    b = bearing(k)
    pts, hit = rectangle_scan(k, np.arange(b[0] + 1e-4, b[2], np.radians(1.0)))
    config = MeasurementConfig()
    assert config.whole_min_points == 3 and hit.sum() == 5
    batch = ClusterBatch.of([prepare_cluster(pts[hit], config)])
    free = dataclasses.replace(batch, occluded_end=np.zeros((1, 2), dtype=bool))
    sd = np.array([[1.0, 0.4]])
    for points, expected in ((3, [FULL, FULL]), (4, [FROM_B, FROM_A])):
        st = build_structure(free, np.array([0]), predicted, dataclasses.replace(config, whole_min_points=points),
                             extent_sd=sd)
        assert st.two_sided[0] and st.sides[0].tolist() == [3, 2] and st.mode[0].tolist() == expected, points


def test_end_gap_correction_removes_the_length_bias_of_a_scanning_lidar() -> None:
    """Rays every 0.2 deg at random phase: the extreme returns lie inside the side's ends by up to one
    gap. With the correction the covered extent (chord + margins) is unbiased to 1 cm; without it the
    chord underestimates the side by about one gap (here the grazing right side has ~0.14 m gaps)."""
    k = corners_of(AHEAD_LEFT)
    b = bearing(k)
    res = np.radians(0.2)
    rng = np.random.default_rng(2)
    raw, corrected = [], []
    for _ in range(200):
        phase = rng.uniform(0, res)
        rays = np.arange(b[0] + phase, b[2], res)
        pts, _ = rectangle_scan(k, rays)
        c = prepare_cluster(pts, MeasurementConfig())
        assert c.two_sided
        raw.append(c.chord_len[1])
        corrected.append(c.chord_len[1] + c.end_margin[1].sum())
    true_side = 4.7
    assert np.mean(raw) < true_side - 0.05
    assert abs(np.mean(corrected) - true_side) < 0.01


def test_downsampling_bound_keeps_extremes_and_corner() -> None:
    k = corners_of(AHEAD_LEFT)
    pts = two_sided_scan(k, 0, 3, 2, n_a=300, n_b=200)
    cfg = MeasurementConfig(max_cluster_points=40)
    c = cornered(pts, cfg)
    assert c.raw_count == len(pts)
    assert c.size <= 40
    np.testing.assert_allclose(c.points[c.corner], k[3], atol=1e-9)
    np.testing.assert_allclose(c.points[0], k[0], atol=1e-9)
    np.testing.assert_allclose(c.points[-1], k[2], atol=1e-9)
    # lines and extents come from all points: the same as without downsampling
    full = cornered(pts, MeasurementConfig(max_cluster_points=10_000))
    np.testing.assert_allclose(c.chord_len, full.chord_len, atol=1e-12)
    y = generating_points(AHEAD_LEFT, c, ORIGIN, config=cfg, coordinates="cartesian")
    assert np.abs(y - c.points).max() < 0.01


def test_single_point_generating_point_on_nearest_visible_side() -> None:
    k = corners_of(AHEAD_LEFT)
    p = k[3] + 0.3 * (k[0] - k[3])  # on the right side
    c = cornered(p[None], EXACT)
    y = generating_points(AHEAD_LEFT, c, ORIGIN, config=EXACT, coordinates="cartesian")
    np.testing.assert_allclose(y[0], p, atol=1e-9)


def test_single_point_is_not_matched_to_a_side_seen_at_grazing_incidence() -> None:
    # the dense-highway scenario: a car 92 m behind in the left lane, turned 3 deg to its right. Its left
    # side (1) faces the sensor at 89.8 deg incidence (apparent width 0.02 m) and its rear-left corner
    # lies nearest a lone return 0.5 m farther out; the front (0, apparent width 1.8 m) faces the sensor
    behind = np.array([-94.0, 3.9, 20.0, np.radians(-3.0), 0.0, 4.5, 1.8])
    k = corners_of(behind)
    point = k[2] + np.array([-0.5, 0.1])  # beyond the rear-left corner
    c = cornered(point[None], EXACT)
    assert visible_sides(k[None])[0].tolist() == [True, True, False, False]
    grazing = build_structure(ClusterBatch.of([c]), np.array([0]), k[None],
                              dataclasses.replace(EXACT, single_point_min_apparent=0.0))
    assert grazing.sides[0, 0] == 1  # the model before: the grazing side's far corner
    st = build_structure(ClusterBatch.of([c]), np.array([0]), k[None], EXACT)
    assert st.sides[0, 0] == 0  # the side facing the sensor
    y = generating_points(behind, c, ORIGIN, config=EXACT, coordinates="cartesian")[0]
    front_x = k[0, 0] + (y[1] - k[0, 1]) * (k[1, 0] - k[0, 0]) / (k[1, 1] - k[0, 1])
    assert abs(y[0] - front_x) < 1e-9  # the generating point lies on the front, about a car length from the return


def test_one_or_two_sided_decision_uses_data_and_prediction() -> None:
    k = corners_of(AHEAD_LEFT)
    pts = two_sided_scan(k, 0, 3, 2)
    c = cornered(pts, EXACT)
    assert c.two_sided and c.eigen_ratio < 50
    line = cornered(np.column_stack([np.full(30, 10.0), np.linspace(-1, 1, 30)]), EXACT)
    assert not line.two_sided and line.eigen_ratio > 50
    # five returns on a 0.5 m face 36 m away, 3 cm of range noise: elongated less than the eigenvalue
    # ratio asks (noise across a short chord), but their RMS distance from one line is the noise's
    face = np.column_stack([36.0 + 0.03 * np.array([1, -1, 1, -1, 1]), np.linspace(-0.25, 0.25, 5)])
    noisy = cornered(face, EXACT)
    assert noisy.eigen_ratio < 50 and not noisy.two_sided
    assert cornered(face, MeasurementConfig(two_side_min_residual=0.0)).two_sided
    # a real corner of as few returns: 0.5 m of rear and 0.4 m of side
    corner = cornered(np.array([[10.0, -0.5], [10.0, 0.0], [10.0, 0.5], [10.2, 0.5], [10.4, 0.5]]), EXACT)
    assert corner.two_sided
    # a car beside the sensor, its front face nearly edge-on: 300 returns along 4.9 m of side, 7 across
    # the 2.1 m face; the face's few points leave the eigenvalue ratio above 50, but no line passes
    # within 0.15 m (RMS) of the points (MeasurementConfig.two_side_line_residual)
    side = np.column_stack([np.linspace(-5.05, -0.2, 300), np.full(300, 2.15)])
    front = np.column_stack([np.full(7, -0.15), np.linspace(4.2, 2.3, 7)])
    grazing = np.vstack([front, side])
    ratio = cornered(grazing, MeasurementConfig(two_side_line_residual=None))
    assert ratio.eigen_ratio > 50 and not ratio.two_sided
    beside = cornered(grazing, EXACT)
    assert beside.two_sided and beside.eigen_ratio > 50
    # the face and the side, each to where the fitted lines meet at the corner (-0.15, 2.15)
    assert np.allclose(np.sort(beside.chord_len[1:]), [2.05, 4.9], atol=0.03)
    # ... but two parked cars' sides one behind the other, 0.8 m apart across, are no corner
    row = np.vstack([np.column_stack([np.linspace(-9.0, -4.6, 150), np.full(150, 2.95)]),
                     np.column_stack([np.linspace(-4.0, 0.0, 150), np.full(150, 2.15)])])
    offset = cornered(row, EXACT)
    assert offset.eigen_ratio > 50 and np.sqrt(np.linalg.eigvalsh(np.cov(row.T, bias=True))[0]) > 0.15
    assert not offset.two_sided
    # ... nor, where the rays lie more than SPLIT_MAX_SPACING apart at the corner (a 0.2 deg lidar beyond
    # 45 m), a face and a long side: there one vehicle's face and the next one's side in a row look alike
    # the same bearings, the L scaled 25 times: the corner at 54 m, its rays 0.18 deg (0.17 m) apart
    far = grazing * 25.0
    assert cornered(far, MeasurementConfig(two_side_line_residual=None)).eigen_ratio > 50
    assert not cornered(far, EXACT).two_sided
    # ... while a single side with 3 cm of range noise stays one line
    rng = np.random.default_rng(0)
    wall = np.column_stack([np.linspace(-5.0, 0.0, 300), 2.15 + 0.03 * rng.standard_normal(300)])
    assert not cornered(wall, EXACT).two_sided
    # a prediction that shows only one side (straight ahead) overrules the data's L
    ahead = corners_of(np.array([12.0, 0.0, 10.0, 0.0, 0.0, 4.7, 1.9]))
    st = build_structure(ClusterBatch.of([c]), np.array([0, 0]), np.stack([k, ahead]), EXACT)
    assert st.two_sided.tolist() == [True, False]


def test_non_finite_points_are_dropped_and_counted() -> None:
    k = corners_of(AHEAD_LEFT)
    pts = two_sided_scan(k, 0, 3, 2)
    bad = np.vstack([pts, [[np.nan, 1.0], [np.inf, 0.0]]])
    c = cornered(bad, EXACT)
    assert c.dropped == 2 and c.size == len(pts)
    with pytest.raises(ValueError, match="at least one finite point"):
        prepare_cluster(np.full((3, 2), np.nan))
    with pytest.raises(ValueError, match=r"\(N, 2\)"):
        prepare_cluster(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="velocity"):
        prepare_cluster(pts, velocity=[1.0, np.nan])


def test_radar_rows_predict_absolute_velocity_in_e() -> None:
    k = corners_of(AHEAD_LEFT)
    pts = two_sided_scan(k, 0, 3, 2)
    c = cornered(pts, EXACT, velocity=[9.9, 1.0])
    ego = (5.0, -2.0, 0.3)
    state = np.array([20.0, 3.0, 12.0, 0.5, 0.0, 4.7, 1.9])  # Cartesian, psi = 0.5 in G
    rect = to_vehicle(state[None, None], ego, coordinates="cartesian")  # one pair, one sigma point
    paper = dataclasses.replace(EXACT, radar_rows="velocity")
    st = build_structure(ClusterBatch.of([c]), np.array([0]), rect.corners()[:, 0], paper, use_radar=True)
    y = predict_measurements(rect, st)
    np.testing.assert_allclose(y[0, 0, -2:], 12.0 * np.array([np.cos(0.2), np.sin(0.2)]), atol=1e-12)
    np.testing.assert_allclose(st.z[0, -2:], [9.9, 1.0])
    assert st.mask[0, -2:].all()
    off = build_structure(ClusterBatch.of([c]), np.array([0]), rect.corners()[:, 0], EXACT, use_radar=False)
    assert not off.mask[0, -2:].any()


def test_radar_speed_row_is_the_velocity_along_the_predicted_heading() -> None:
    """``radar_rows="speed"`` (default): one row, ``u . v_radar`` against ``u . v (cos psi_E, sin psi_E)``
    with ``u`` the predicted mean's heading in E (psi_E = 0.2 here); the second row is masked out.
    A sigma point turned by 0.1 rad predicts ``v cos 0.1``."""
    k = corners_of(AHEAD_LEFT)
    c = cornered(two_sided_scan(k, 0, 3, 2), EXACT, velocity=[9.9, 1.0])
    ego = (5.0, -2.0, 0.3)
    state = np.array([20.0, 3.0, 12.0, 0.5, 0.0, 4.7, 1.9])
    turned = state + np.array([0, 0, 0, 0.1, 0, 0, 0])
    mean = to_vehicle(state[None, None], ego, coordinates="cartesian")
    rect = to_vehicle(np.stack([state, turned])[None], ego, coordinates="cartesian")  # (1 pair, 2 sigma points)
    assert EXACT.radar_rows == "speed"
    st = build_structure(ClusterBatch.of([c]), np.array([0]), mean.corners()[:, 0], EXACT, use_radar=True)
    u = np.array([np.cos(0.2), np.sin(0.2)])
    assert st.z[0, -2] == pytest.approx(u @ [9.9, 1.0], abs=1e-12)
    assert st.mask[0, -2] and not st.mask[0, -1]
    y = predict_measurements(rect, st)
    np.testing.assert_allclose(y[0, :, -2], [12.0, 12.0 * np.cos(0.1)], atol=1e-9)
    np.testing.assert_allclose(y[0, :, -1], 0.0)
    with pytest.raises(ValueError, match="radar_rows"):
        dataclasses.replace(EXACT, radar_rows="doppler")


def test_structure_batched_over_pairs_equals_one_by_one() -> None:
    k = corners_of(AHEAD_LEFT)
    c1 = prepare_cluster(two_sided_scan(k, 0, 3, 2), MeasurementConfig())
    b = bearing(k)
    c2 = prepare_cluster(rectangle_scan(k, np.linspace(b[0], b[3], 12))[0], MeasurementConfig())
    rects = np.stack([k, corners_of(AHEAD_LEFT + np.array([0.3, -0.2, 0, 0.05, 0, 0.2, 0.1]))])
    batch = ClusterBatch.of([c1, c2])
    pairs = [(0, 0), (1, 0), (0, 1), (1, 1)]
    together = build_structure(batch, np.array([c for _, c in pairs]), rects[[r for r, _ in pairs]], MeasurementConfig())
    for i, (r, c) in enumerate(pairs):
        alone = build_structure(ClusterBatch.of([[c1, c2][c]]), np.array([0]), rects[r][None], MeasurementConfig())
        m = [c1, c2][c].size
        for name in ("a", "b", "c1", "c2"):
            np.testing.assert_array_equal(getattr(together, name)[i, :m], getattr(alone, name)[0, :m])
        np.testing.assert_array_equal(together.factors[i, :, : 2 * m], alone.factors[0, :, : 2 * m])


def test_rectangle_axes_recipe_equals_the_corner_recipe() -> None:
    """predict_measurements evaluates y = centre + (ax L + gx) e_x + (ay W + gy) e_y; for perturbed
    sigma-point rectangles this equals the corner recipe K[a] + c1 (K[b] - K[a]) + c2 unit(K[b] - K[a])."""
    rng = np.random.default_rng(5)
    k = corners_of(AHEAD_LEFT)
    b = bearing(k)
    visible_end = k[3] + 0.4 * (k[0] - k[3])
    clusters = [
        prepare_cluster(two_sided_scan(k, 0, 3, 2) + 0.02 * rng.standard_normal((49, 2))),
        prepare_cluster(rectangle_scan(k, np.linspace(bearing(visible_end), b[3], 10))[0]),  # one side, partial
        prepare_cluster(k[3][None] + 0.3 * (k[0] - k[3])),  # a single point
    ]
    st = build_structure(ClusterBatch.of(clusters), np.arange(3), np.stack([k] * 3), MeasurementConfig())
    states = AHEAD_LEFT + rng.normal(0, [0.3, 0.3, 1.0, 0.1, 0.05, 0.4, 0.2], (3, 15, 7))
    rect = to_vehicle(states, ORIGIN, coordinates="cartesian")
    y = predict_measurements(rect, st)
    corners = rect.corners()  # (3, 15, 4, 2)
    for p, cl in enumerate(clusters):
        for i in range(cl.size):
            ka = corners[p, :, st.a[p, i]]
            kb = corners[p, :, st.b[p, i]]
            d = kb - ka
            expect = ka + st.c1[p, i] * d + st.c2[p, i] * d / np.linalg.norm(d, axis=1, keepdims=True)
            np.testing.assert_allclose(y[p, :, 2 * i: 2 * i + 2], expect, atol=1e-12)


def test_euler_conversion_follows_the_exact_one_with_the_papers_error() -> None:
    """``to_vehicle(..., euler_s0=s_ego)`` (the ``paper`` variant's measurement model) integrates the
    local cubic heading polynomial in 0.5 m Euler steps: on a radius-80 m circle (a cubic heading fits
    exactly) the heading is exact and the centre drifts with the distance from the ego -- the
    right-Riemann sum's error ``~ step / 2 * kappa * d`` (0.06 m at 20 m, 0.24 m at 80 m) -- while the
    exact conversion has none."""
    road = Road.from_curvature([(2 * np.pi * 80.0, 1 / 80.0, 1 / 80.0)], closed=True, lanes=2)
    s_ego = 10.0
    xy = road.to_cartesian(s_ego, -1.75)
    ego = (float(xy[0]), float(xy[1]), float(road.heading(s_ego)))
    errors = []
    for d in (5.0, 20.0, 40.0, 80.0):
        state = np.array([[s_ego + d, 1.75, 10.0, 0.02, 0.0, 4.8, 2.0]])
        exact, euler = to_vehicle(state, ego, road), to_vehicle(state, ego, road, euler_s0=s_ego)
        assert abs(float(exact.psi[0] - euler.psi[0])) < 1e-9
        errors.append(float(np.linalg.norm(exact.center - euler.center)))
        assert errors[-1] == pytest.approx(0.25 * d / 80.0, rel=0.25)
    assert errors == sorted(errors)


def test_the_points_of_a_part_going_on_behind_a_shadow_update_with_the_shadowed_sigma() -> None:
    """A car 15 m ahead shows the left 1.2 m of its 1.9 m rear; with an end of it bordering a nearer
    object's shadow (``occluded_end``) it is partially visible, anchored at the other end, and its
    points' variance in the update is ``MeasurementConfig.shadowed_lidar_sigma^2`` (0.15 m); with the
    rule off, or with no end in a shadow (the flags say both ends are free: the whole side of a narrow
    vehicle; no flags: partially visible by its extent, but nothing hides it), ``lidar_sigma^2``
    (0.1 m). The radar's row keeps its variance."""
    car = np.array([15.0, 0.3, 10.0, 0.0, 0.0, 4.5, 1.9])
    k = corners_of(car)
    assert visible_sides(k).tolist() == [False, False, True, False]  # the rear: K2 (left) -> K3 (right)
    right_end = k[2] + 1.2 * (k[3] - k[2]) / 1.9
    pts, hit = rectangle_scan(k, np.linspace(bearing(k[2]), bearing(right_end), 24))
    assert hit.all()
    config = MeasurementConfig()
    batch = ClusterBatch.of([prepare_cluster(pts, config)])
    batch = dataclasses.replace(batch, fused=np.array([True]), velocity=np.array([[10.0, 0.0]]))
    lidar_rows = np.repeat(batch.valid[0], 2)

    def variances(b, cfg=config, anchored=False):
        st = build_structure(b, np.array([0]), k[None], cfg, extent_sd=np.array([[0.5, 0.2]]))
        other = oracle_structure(b, np.array([0]), k[None], cfg, extent_sd=np.array([[0.5, 0.2]]))
        np.testing.assert_allclose(other.r, st.r, atol=1e-15)
        assert (st.mode[0, 0] in (FROM_A, FROM_B, CENTRE)) == anchored
        assert st.r[0, -2] == pytest.approx(config.radar_velocity_sigma**2)  # the radar's speed row
        return np.unique(st.r[0, :-2][lidar_rows])

    for end in ([[True, False]], [[False, True]]):
        flagged = dataclasses.replace(batch, occluded_end=np.array(end))
        assert variances(flagged, anchored=True) == pytest.approx([0.15**2])
        off = dataclasses.replace(config, shadowed_lidar_sigma=None)
        assert variances(flagged, off, anchored=True) == pytest.approx([0.1**2])
    assert variances(dataclasses.replace(batch, occluded_end=np.array([[False, False]]))) == pytest.approx([0.1**2])
    # no shadow flags at all: partially visible by its extent, anchored, but no shadow said so
    assert variances(batch, anchored=True) == pytest.approx([0.1**2])


# -- the kernels against the numpy oracle ------------------------------------------------------------
def assert_fields_equal(a, b, skip=()) -> None:
    """Dataclasses ``a`` (oracle) and ``b`` (kernel): integer and boolean fields equal, float fields
    within 1e-9 with the same non-finite entries, the same shapes and dtypes."""
    for name in a.__dataclass_fields__:
        if name in skip:
            continue
        x, y = np.asarray(getattr(a, name)), np.asarray(getattr(b, name))
        assert x.shape == y.shape and x.dtype == y.dtype, (name, x.shape, y.shape, x.dtype, y.dtype)
        if x.dtype.kind in "bi":
            np.testing.assert_array_equal(x, y, err_msg=name)
        else:
            np.testing.assert_array_equal(np.isfinite(x), np.isfinite(y), err_msg=name)
            fin = np.isfinite(x)
            np.testing.assert_allclose(y[fin], x[fin], rtol=0.0, atol=1e-9, err_msg=name)
            np.testing.assert_array_equal(x[~fin], y[~fin], err_msg=name)


def _scene_pairs(monkeypatch):
    """The batches, pairs and predicted mean rectangles ``build_structure`` sees in 30 frames of a
    tracker on a 3-lane curve with a truck and radar (recorded from ``tracker.update``'s staged path)."""
    import tracker.update

    road = Road.from_curvature([(150.0, 0.0, 0.0), (300.0, 0.0, 1 / 120.0)], lanes=3, lane_width=3.5)
    scene = Scene(road, Car(60.0, -3.5, 14.0),
                  [Car(80.0, -3.5, 14.0), Car(75.0, 0.0, 17.0, length=11.0, width=2.5), Car(50.0, 3.5, 18.0),
                   Car(95.0, 0.0, 12.0)], radar=True)
    seen = []

    def record(batch, ci, corners, *args, **kwargs):
        seen.append((batch, np.array(ci), np.array(corners), kwargs.get("extent_sd")))
        return build_structure(batch, ci, corners, *args, **kwargs)

    monkeypatch.setattr(tracker.update, "build_structure", record)
    monkeypatch.setattr(tracker.update, "_update_clusters_fused", lambda *args: None)  # the staged path builds it
    monkeypatch.setattr(tracker.update, "_update_pairs_fused", lambda *args: None)
    tr = Tracker(road, TrackerConfig())
    rng = np.random.default_rng(3)
    for k in range(30):
        tr.step(scene.frame(0.1 * k, rng))
    return seen


@pytest.mark.parametrize("radar_rows", ["speed", "velocity"])
def test_the_structure_kernel_equals_the_oracle(radar_rows, monkeypatch):
    """``build_structure`` (``tracker.structure.structure_kernel``) against ``oracles.measurement``'s on
    the pairs of a tracked scene (a bus, radar, shadows), with the recorded shadow flags and extent sds,
    random ones (every combination of the two ends; sds that open or shut the gate) and none, radar rows
    on and off: the same decisions, the numbers within 1e-9."""
    config = MeasurementConfig(radar_rows=radar_rows)
    pairs = _scene_pairs(monkeypatch)
    assert len(pairs) >= 20
    assert any(b.occluded_end is not None and b.occluded_end.any() for b, _, _, _ in pairs)  # the scene has shadows
    assert any(b.continued_end is not None for b, _, _, _ in pairs)
    assert all(sd is not None for _, _, _, sd in pairs)
    whole_parts = 0
    for batch, clu, corners, extent_sd in pairs:
        rng = np.random.default_rng(len(clu))
        fused = dataclasses.replace(batch, fused=np.arange(len(batch.fused)) % 2 == 0,
                                    velocity=rng.normal(size=batch.velocity.shape))
        flags = rng.random((len(batch.points), 2)) < 0.4
        for occluded, continued, sd in ((batch.occluded_end, batch.continued_end, extent_sd),
                                        (flags, rng.random(flags.shape) < 0.3, rng.uniform(0.0, 2.0, extent_sd.shape)),
                                        (None, None, None)):
            variant = dataclasses.replace(fused, occluded_end=occluded, continued_end=continued)
            for use_radar in (True, False):
                ref = oracle_structure(variant, clu, corners, config, use_radar, extent_sd=sd)
                got = build_structure(variant, clu, corners, config, use_radar, extent_sd=sd)
                assert_fields_equal(ref, got)
            if sd is not None:
                unsized = build_structure(variant, clu, corners, config, extent_sd=None)  # the rule needs the sd
                whole_parts += int((got.mode != unsized.mode).sum())
    assert whole_parts > 0  # the two-sided rule decided some parts


@pytest.mark.parametrize("name", ["clothoid-open", "hermite-closed"])
def test_the_exact_conversion_to_e_equals_the_oracle(name):
    """``to_vehicle`` of curvilinear states (``tracker.centerline.rectangles_kernel``) against the road's
    frame in numpy (``oracles.measurement.to_vehicle``): any leading shape, empty batches, 7 and 8 state
    columns, states beyond an open road's ends and across a closed road's seam, extents below
    ``MIN_EXTENT`` and a NaN extent; a non-finite ``s`` is refused."""
    road = kernel_roads()[name]
    rng = np.random.default_rng(2)
    ego = EgoState(120.0, -40.0, 0.7, 12.0, 0.05)
    for shape, dim in (((40,), 7), ((6, 15), 7), ((5, 3, 2), 8), ((0,), 7), ((4, 0), 8)):
        x = rng.normal(0.0, 1.0, shape + (dim,))
        x[..., 0] = rng.uniform(-30.0, road.length + 30.0, shape)
        x[..., 1] = rng.uniform(-8.0, 8.0, shape)
        x[..., 3] = rng.uniform(-0.5, 0.5, shape)
        x[..., 5:7] = rng.uniform(-1.0, 15.0, shape + (2,))  # below MIN_EXTENT too
        if road.closed:
            x[..., 0] %= road.length
        if x.size:
            x.reshape(-1, dim)[0, 5] = np.nan  # a NaN extent stays NaN (numpy.maximum's rule)
        ref = oracle_to_vehicle(x, ego, road)
        got = to_vehicle(x, ego, road)
        for field in ("center", "psi", "v", "length", "width"):
            a, b = getattr(ref, field), getattr(got, field)
            assert a.shape == b.shape and a.dtype == b.dtype
            np.testing.assert_allclose(b, a, rtol=0.0, atol=1e-9)
            if field in ("v", "length", "width"):
                np.testing.assert_array_equal(b, a)  # copied or floored: exact
        assert got.corners().shape == ref.corners().shape
        np.testing.assert_allclose(got.corners(), ref.corners(), rtol=0.0, atol=1e-9)
        if x.size:
            np.testing.assert_allclose(got.take(np.array([0])).corners(), ref.corners()[[0]], rtol=0.0, atol=1e-9)
    with pytest.raises(ValueError, match="finite"):
        to_vehicle(np.full((2, 7), np.nan), ego, road)
