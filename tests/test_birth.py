"""Tests of tracker/birth.py: road births, cluster births from an L-shape, the Cartesian mapping."""

from __future__ import annotations

import numpy as np
import pytest

from tracker import EgoState, Road
from tracker.birth import cluster_births, road_births, to_cartesian_gaussians
from tracker.config import BirthConfig
from tracker.measurement import rectangle_corners, rectangle_scan
from tracker.track import curvilinear_to_cartesian
from tracker.transforms import to_local


@pytest.fixture(scope="module")
def road() -> Road:
    return Road.from_curvature([(2 * np.pi * 200.0, 1 / 200.0, 1 / 200.0)], closed=True, lanes=3)


def test_road_births_per_lane_at_the_range_limits(road):
    cfg = BirthConfig()
    means, covs = road_births(road, 10.0, 15.0, 100.0, cfg)
    assert means.shape == (6, 7) and covs.shape == (6, 7, 7)
    np.testing.assert_allclose(np.sort(np.unique(np.round(means[:, 0], 6))), np.sort(road.wrap_s([105.0, -85.0])))
    np.testing.assert_allclose(np.sort(means[:3, 1]), road.lane_centers)
    assert np.all(means[:, 2] == 15.0) and np.all(means[:, 5] == cfg.length)
    open_road = Road.from_curvature([(150.0, 0.0, 0.0)], lanes=2)
    means, _ = road_births(open_road, 10.0, 15.0, 100.0, cfg)  # behind the start: only ahead
    np.testing.assert_allclose(means[:, 0], 105.0)


def test_cluster_birth_from_an_l_shape(road):
    # a 4.8 x 2 m car in the left lane, 20 m ahead of the ego, seen on its rear and right side
    s_car, n_car = 60.0, road.lane_centers[2]
    xy, theta, _ = road.frame(np.array([s_car]))
    centre = road.to_cartesian(s_car, n_car)
    ego_s, ego_n = 40.0, road.lane_centers[1]
    ego_xy = road.to_cartesian(ego_s, ego_n)
    ego_yaw = float(road.heading(ego_s))
    ego = EgoState(ego_xy[0], ego_xy[1], ego_yaw, 15.0)
    corners = to_local(rectangle_corners(centre, np.array(theta[0]), np.array(4.8), np.array(2.0)), ego_xy, ego_yaw)
    points, _ = rectangle_scan(corners, np.arange(-np.pi, np.pi, np.radians(0.2)))
    means, covs = cluster_births([points], [np.array([17.0, 0.5])], ego, road, BirthConfig())
    assert means.shape == (1, 7)
    s, n, v, xi, _, length, width = means[0]
    assert s == pytest.approx(s_car, abs=0.3) and n == pytest.approx(n_car, abs=0.3)
    assert abs(xi) < 0.05
    assert length == pytest.approx(4.8, abs=0.2) and width == pytest.approx(2.0, abs=0.2)
    assert v == pytest.approx(17.0, abs=0.6)  # radar velocity along the fitted heading
    # too few points: no birth (one return without radar; two with min_cluster_points raised to 3)
    assert len(cluster_births([points[:1]], [None], ego, road, BirthConfig())[0]) == 0
    assert len(cluster_births([points[:2]], [None], ego, road, BirthConfig())[0]) == 1
    assert len(cluster_births([points[:2]], [None], ego, road, BirthConfig(min_cluster_points=3))[0]) == 0


def test_a_cluster_birth_without_radar_takes_the_prior_speed_it_is_given(road):
    # the car of the test above, seen by the lidar alone: the ego's speed (15 m/s, std speed_std)
    # without a prior speed, the given one (its lane's flow, tracker.flow) with one; a radar velocity
    # wins over either
    s_car, n_car = 60.0, road.lane_centers[2]
    theta = road.frame(np.array([s_car]))[1]
    centre = road.to_cartesian(s_car, n_car)
    ego_xy = road.to_cartesian(40.0, road.lane_centers[1])
    ego_yaw = float(road.heading(40.0))
    ego = EgoState(ego_xy[0], ego_xy[1], ego_yaw, 15.0)
    corners = to_local(rectangle_corners(centre, np.array(theta[0]), np.array(4.8), np.array(2.0)), ego_xy, ego_yaw)
    points, _ = rectangle_scan(corners, np.arange(-np.pi, np.pi, np.radians(0.2)))
    cfg = BirthConfig()
    means, covs = cluster_births([points, points], [None, None], ego, road, cfg, prior_speeds=[None, (9.0, 1.5)])
    assert means[0, 2] == 15.0 and covs[0, 2, 2] == pytest.approx(cfg.speed_std**2)
    assert means[1, 2] == 9.0 and covs[1, 2, 2] == pytest.approx(1.5**2)
    means, _ = cluster_births([points], [np.array([17.0, 0.5])], ego, road, cfg, prior_speeds=[(9.0, 1.5)])
    assert means[0, 2] == pytest.approx(17.0, abs=0.6)


@pytest.mark.parametrize("classes", [True, False], ids=["vehicle-classes", "off"])
def test_cluster_birth_of_a_wide_rear_gets_a_long_vehicles_length(classes):
    """A 2.55 m wide rear straight ahead on a straight road (a bus): with the vehicle classes' prior the
    birth has a truck's or bus's length (the classes' mixture given the fitted width,
    ``BirthConfig.fit_width_std``; 12-14 m, std 3-5 m) and its centre half of it beyond the rear;
    without it a car's 4.5 m. A 1.8 m rear stays a car (4.5 m, std ``length_std``)."""
    from oracles.update import class_length_prior as oracle_prior

    road = Road.from_curvature([(500.0, 0.0, 0.0)], lanes=3)
    ego_s, n_lane = 40.0, road.lane_centers[1]
    ego_xy = road.to_cartesian(ego_s, n_lane)
    ego_yaw = float(road.heading(ego_s))
    ego = EgoState(ego_xy[0], ego_xy[1], ego_yaw, 15.0)
    cfg = BirthConfig() if classes else BirthConfig(classes=None)
    for width, long in ((2.55, classes), (1.8, False)):
        s_rear = 60.0  # the rear's arc length; the vehicle is 16 m long, only its rear in view
        centre = road.to_cartesian(s_rear + 8.0, n_lane)
        theta = float(road.heading(s_rear + 8.0))
        corners = to_local(rectangle_corners(centre, np.array(theta), np.array(16.0), np.array(width)), ego_xy, ego_yaw)
        points, _ = rectangle_scan(corners, np.arange(-np.pi, np.pi, np.radians(0.2)))
        means, covs = cluster_births([points], [None], ego, road, cfg)
        s, n, _, _, _, length, w = means[0]
        assert w == pytest.approx(width, abs=0.15)
        if long:
            expected, var = oracle_prior(np.array([w]), np.array([cfg.fit_width_std**2]), cfg.classes)
            assert 12.0 < expected[0] < 14.0 and 3.0 < var[0] ** 0.5 < 5.0
            assert length == pytest.approx(expected[0], abs=0.05) and covs[0, 5, 5] == pytest.approx(var[0], rel=0.02)
        else:
            assert length == cfg.length and covs[0, 5, 5] == pytest.approx(cfg.length_std**2)
        assert s == pytest.approx(s_rear + 0.5 * length, abs=0.4)


@pytest.mark.parametrize("limits", [True, False], ids=["limits", "no-limits"])
def test_a_cluster_birth_is_no_longer_or_wider_than_any_vehicle(limits):
    """A cluster tracing a 34 m x 3.6 m rectangle in the next lane ahead (two vehicles' points in one
    connected component: buses nose to tail, a car beside them) is no one vehicle: the birth's extent
    is projected onto BirthConfig.max_length / max_width (25 m, 3 m), its end nearest the sensor kept;
    without the limits the birth is as long and as wide as the fitted cluster (beyond both limits)."""
    road = Road.from_curvature([(500.0, 0.0, 0.0)], lanes=3)
    ego_s = 40.0
    ego_xy = road.to_cartesian(ego_s, road.lane_centers[1])
    ego_yaw = float(road.heading(ego_s))
    ego = EgoState(ego_xy[0], ego_xy[1], ego_yaw, 15.0)
    s_rear, n_mid = 60.0, road.lane_centers[2]
    centre = road.to_cartesian(s_rear + 17.0, n_mid)
    corners = to_local(rectangle_corners(centre, np.array(float(road.heading(s_rear + 17.0))), np.array(34.0),
                                         np.array(3.6)), ego_xy, ego_yaw)
    points, _ = rectangle_scan(corners, np.arange(-np.pi, np.pi, np.radians(0.2)))
    cfg = BirthConfig() if limits else BirthConfig(max_length=None, max_width=None)
    means, _ = cluster_births([points], [None], ego, road, cfg)
    s, _, _, _, _, length, width = means[0]
    if limits:
        assert length == pytest.approx(25.0) and width == pytest.approx(3.0)
        assert s - 0.5 * length == pytest.approx(s_rear, abs=0.5)  # the near end (the rear) stays put
    else:
        assert length > 27.0 and width > 3.4  # beyond both limits


EGO_S = 40.0  # the ego of the helpers below drives in the middle lane at this s (m)


def _ego(road: Road, speed: float) -> EgoState:
    """The ego in the middle lane at ``EGO_S``, along the road, at ``speed`` m/s."""
    xy = road.to_cartesian(EGO_S, road.lane_centers[1])
    return EgoState(xy[0], xy[1], float(road.heading(EGO_S)), speed)


def _sparse_cluster(road: Road, ahead: float, n_car: float):
    """One lidar point on the rear corner of a 4.8 x 2 m car ``ahead`` m ahead of the ego (which
    drives in the middle lane), the rest of it hidden: the point, the ego, the car's centre (s, n)."""
    ego = _ego(road, 20.0)
    s_car = EGO_S + ahead
    corners = to_local(rectangle_corners(road.to_cartesian(s_car, n_car), np.array(float(road.heading(s_car))),
                                         np.array(4.8), np.array(2.0)), (ego.x, ego.y), ego.yaw)
    nearest = corners[np.argmin(np.hypot(corners[:, 0], corners[:, 1]))]
    return nearest[None, :], ego, (s_car, n_car)


def test_a_far_cluster_of_one_point_with_a_radar_detection_seeds_a_birth_along_the_road(road):
    """One point 85 m ahead (a car mostly hidden behind another) and a radar detection on it: a birth in
    the road's direction, its centre half a car length beyond the point, the radar's speed, a wide
    spread along the road. Without the radar, nearer than ``sparse_min_range``, or with
    ``min_cluster_points_radar=None``: no birth (single lidar points are clutter)."""
    point, ego, (s_car, n_car) = _sparse_cluster(road, 85.0, road.lane_centers[2])
    theta = float(road.heading(s_car)) - ego.yaw
    radar_velocity = 18.0 * np.array([np.cos(theta), np.sin(theta)])
    cfg = BirthConfig()
    means, covs = cluster_births([point], [radar_velocity], ego, road, cfg)
    assert means.shape == (1, 7)
    s, n, v, xi, _, length, width = means[0]
    assert s == pytest.approx(s_car, abs=0.3)  # the point is the rear corner: 2.4 m behind the centre
    assert abs(n - n_car) <= 1.0 + 1e-6  # the point lies on the rear, within half a width of the centre
    assert xi == 0.0 and v == pytest.approx(18.0, abs=0.01)  # the radar velocity along the road
    assert (length, width) == (cfg.length, cfg.width)
    assert covs[0, 0, 0] == pytest.approx((0.5 * cfg.length) ** 2)
    assert len(cluster_births([point], [None], ego, road, cfg)[0]) == 0
    assert len(cluster_births([point], [radar_velocity], ego, road, BirthConfig(min_cluster_points_radar=None))[0]) == 0
    near, ego, _ = _sparse_cluster(road, cfg.sparse_min_range - 10.0, road.lane_centers[2])
    assert len(cluster_births([near], [radar_velocity], ego, road, cfg)[0]) == 0


def test_two_points_with_a_radar_detection_seed_a_birth_at_any_range(road):
    """``BirthConfig.min_cluster_points_fused`` (2): two points 30 m ahead (a car coming out from behind
    another) that a radar detection joined seed a birth along the road with the radar's speed; without
    the radar, or with ``min_cluster_points_fused=None`` (30 m is nearer than ``sparse_min_range``), two
    points seed nothing, and one point with the radar seeds nothing at 30 m."""
    point, ego, (s_car, n_car) = _sparse_cluster(road, 30.0, road.lane_centers[2])
    theta = float(road.heading(s_car)) - ego.yaw
    along = np.array([np.cos(theta), np.sin(theta)])
    two = np.vstack([point, point + 0.3 * np.array([-along[1], along[0]]) * np.sign(-point[0, 1] or 1.0)])
    radar_velocity = 15.0 * along
    cfg = BirthConfig(min_cluster_points=3)  # without radar three points (the default 2 would take two alone)
    means, _ = cluster_births([two], [radar_velocity], ego, road, cfg)
    assert means.shape == (1, 7)
    assert means[0, 3] == 0.0 and means[0, 2] == pytest.approx(15.0, abs=0.01)
    assert abs(means[0, 0] - s_car) < 1.0 and abs(means[0, 1] - n_car) <= 1.3
    assert len(cluster_births([two], [None], ego, road, cfg)[0]) == 0
    assert len(cluster_births([two], [radar_velocity], ego, road, BirthConfig(min_cluster_points=3, min_cluster_points_fused=None))[0]) == 0
    assert len(cluster_births([point], [radar_velocity], ego, road, cfg)[0]) == 0


def _segment(road: Road, s: float, n: float, length: float, angle: float, count: int = 10):
    """``count`` points along a segment ``length`` m long turned ``angle`` rad from the road's direction,
    centred at ``(s, n)``, in E of the ego (``_ego``); the points and the ego."""
    ego = _ego(road, 15.0)
    heading = float(road.heading(s)) + angle
    t = np.linspace(-0.5, 0.5, count)[:, None] * length
    xy = road.to_cartesian(s, n)[None, :] + t * np.array([np.cos(heading), np.sin(heading)])
    return to_local(xy, (ego.x, ego.y), ego.yaw), ego


def test_a_short_cluster_is_born_along_its_lane(road):
    """Ten returns within 0.2 m (the end of a car's left side peeking out from behind another vehicle,
    the car beside the ego in the right lane) show no orientation: the birth takes the lane's direction,
    its unseen width beyond the points, away from the sensor. With ``min_oriented_extent`` 0 the fit's
    axes are taken: the patch's 40 deg. A 2 m side at 20 deg keeps its heading either way."""
    n_side = road.lane_centers[0] + 1.0  # the left side of a car in the right lane
    patch, ego = _segment(road, 41.0, n_side, 0.2, np.radians(40.0))
    means, _ = cluster_births([patch], [None], ego, road, BirthConfig())
    assert means.shape == (1, 7)
    assert abs(means[0, 3]) < 0.02  # the lane's direction at the points (the curve turns 0.01 rad over the shift)
    assert means[0, 1] < n_side - 0.5  # the unseen width lies to the right, away from the sensor
    loose, _ = cluster_births([patch], [None], ego, road, BirthConfig(min_oriented_extent=0.0))
    assert abs(loose[0, 3]) > np.radians(35.0)
    side, ego = _segment(road, 50.0, n_side, 2.0, np.radians(20.0))
    for cfg in (BirthConfig(), BirthConfig(min_oriented_extent=0.0)):
        means, _ = cluster_births([side], [None], ego, road, cfg)
        assert means[0, 3] == pytest.approx(np.radians(20.0), abs=np.radians(2.0))


def test_cartesian_births_match_the_exact_conversion(road):
    means = np.array([[30.0, 3.5, 20.0, 0.1, 0.02, 4.8, 2.0]])
    covs = np.diag([1e-6] * 7)[None]
    m, c = to_cartesian_gaussians(road, means, covs)
    np.testing.assert_allclose(m, curvilinear_to_cartesian(road, means), atol=1e-6)
    assert c.shape == (1, 7, 7) and np.all(np.linalg.eigvalsh(c[0]) > -1e-12)


@pytest.mark.parametrize("ahead", [True, False], ids=["car-ahead", "car-behind"])
def test_a_birth_seen_from_its_rear_has_its_centre_correlated_with_its_unseen_length(ahead):
    """A car straight ahead (behind) on a straight road shows only its rear (front): the birth's centre
    is that end plus (minus) half the unseen length, ``s = e +- L/2``, so ``cov(s, L) = +- var(L)/2``,
    ``var(s) = var(e) + var(L)/4`` and the end itself, ``s -+ L/2``, keeps the fit's ``var(e)`` (0.5^2).
    The width is seen: no lateral coupling."""
    road = Road.from_curvature([(500.0, 0.0, 0.0)], lanes=3)
    ego = EgoState(100.0, 0.0, 0.0, 15.0)
    centre = np.array([125.0 if ahead else 75.0, 0.0])
    cfg = BirthConfig()
    width = cfg.width + 0.2  # wider than the prior width: the fitted rear is the width
    corners = to_local(rectangle_corners(centre, np.array(0.0), np.array(4.8), np.array(width)), np.array([100.0, 0.0]), 0.0)
    points, _ = rectangle_scan(corners, np.arange(-np.pi, np.pi, np.radians(0.2)))
    means, covs = cluster_births([points], [None], ego, road, cfg)
    p = covs[0]
    sign = 1.0 if ahead else -1.0
    var_l = cfg.length_std**2
    assert means[0, 5] == pytest.approx(cfg.length)
    # the centre half the prior length beyond the visible end
    assert means[0, 0] == pytest.approx(centre[0] - sign * 2.4 + sign * 0.5 * cfg.length, abs=0.05)
    assert p[0, 5] == pytest.approx(sign * 0.5 * var_l, rel=1e-3) and p[5, 0] == p[0, 5]  # the fit's heading: ~1e-4 rad off
    assert p[0, 0] == pytest.approx(0.25 + 0.25 * var_l, rel=1e-3)
    end = np.array([1.0, 0, 0, 0, 0, -sign * 0.5, 0])  # s -+ L/2: the visible end
    assert end @ p @ end == pytest.approx(0.25, rel=1e-3)
    assert p[1, 5] == pytest.approx(0.0, abs=0.01) and np.all(p[:2, 6] == 0.0)  # the fit's heading: 0.01 rad off
    np.testing.assert_allclose(p, p.T)
    assert np.linalg.eigvalsh(p).min() > 0.0


def test_a_birth_seen_from_its_side_couples_its_lateral_position_with_its_unseen_width():
    """A car abeam in the next lane shows its whole side (longer than the prior length): no coupling
    with ``L``; the unseen width puts the centre half a width beyond the side, away from the ego:
    ``cov(n, W) = var(W) / 2``. A wide rear (a truck's or bus's length from the vehicle classes, too
    spread for a linear shift) and a sparse cluster are left uncoupled."""
    road = Road.from_curvature([(500.0, 0.0, 0.0)], lanes=3)
    ego = EgoState(100.0, 0.0, 0.0, 15.0)
    corners = to_local(rectangle_corners(np.array([100.0, 4.0]), np.array(0.0), np.array(4.8), np.array(2.0)),
                       np.array([100.0, 0.0]), 0.0)
    points, _ = rectangle_scan(corners, np.arange(-np.pi, np.pi, np.radians(0.2)))
    cfg = BirthConfig()
    means, covs = cluster_births([points], [None], ego, road, cfg)
    p = covs[0]
    assert means[0, 1] == pytest.approx(3.0 + 0.5 * cfg.width, abs=0.05)  # the side at n = 3
    assert p[1, 6] == pytest.approx(0.5 * cfg.width_std**2, rel=1e-3)
    assert p[1, 1] == pytest.approx(0.25 + 0.25 * cfg.width_std**2, rel=1e-3)
    assert np.all(p[:2, 5] == 0.0)
    # a 2.55 m wide rear ahead: a bus, whose long prior length is not coupled; two points: no coupling
    bus = to_local(rectangle_corners(np.array([130.0, 0.0]), np.array(0.0), np.array(12.0), np.array(2.55)),
                   np.array([100.0, 0.0]), 0.0)
    bus_points, _ = rectangle_scan(bus, np.arange(-np.pi, np.pi, np.radians(0.2)))
    means, covs = cluster_births([bus_points, bus_points[:2]], [None, np.array([15.0, 0.0])], ego, road, cfg)
    assert means[0, 5] > 12.0 and np.all(covs[:, :2, 5:] == 0.0)


@pytest.mark.parametrize("near_end_shadowed", [True, False], ids=["near-end-shadowed", "far-end-shadowed"])
def test_a_side_whose_near_end_borders_a_shadow_may_go_on_either_way(near_end_shadowed):
    """A car abeam-ahead on a straight road shows 2 m of its left side, from x = 110 to 112 (the side at
    y = 4); the prior length 4.5 m leaves 2.5 m unseen. Away from the sensor (ahead) is where the birth
    puts it, correlated with L: centre 112.25, ``cov(s, L) = var(L) / 2``. When the cluster's *near* end
    (x = 110) borders another object's shadow, the unseen part may lie behind that object as well: the
    centre stays at the points' (111) and ``var(s)`` takes ``(2.5 / 2)^2`` more, uncorrelated with L.
    A shadow at the far end changes nothing (it agrees with "away")."""
    road = Road.from_curvature([(500.0, 0.0, 0.0)], lanes=3)
    ego = EgoState(100.0, 0.0, 0.0, 15.0)
    x = np.linspace(110.0, 112.0, 9)
    points = np.column_stack([x - 100.0, np.full_like(x, 4.0)])  # in E (ego at x = 100, heading +x)
    near, far = points[0], points[-1]
    shadowed = [(near, far) if near_end_shadowed else (far, near)]
    cfg = BirthConfig()
    means, covs = cluster_births([points], [None], ego, road, cfg, shadowed)
    plain_means, plain_covs = cluster_births([points], [None], ego, road, cfg)
    s, p = means[0, 0], covs[0]
    missing = cfg.length - 2.0
    if near_end_shadowed:
        assert s == pytest.approx(111.0, abs=0.05)
        assert p[0, 5] == pytest.approx(0.0, abs=1e-3)
        assert p[0, 0] == pytest.approx(0.25 + (0.5 * missing) ** 2, rel=1e-2)
    else:
        np.testing.assert_allclose(means, plain_means)
        np.testing.assert_allclose(covs, plain_covs)
        assert s == pytest.approx(111.0 + 0.5 * missing, abs=0.05)
        assert p[0, 5] == pytest.approx(0.5 * cfg.length_std**2, rel=1e-2)
    # across the side both ends lie on one line: the width's unseen half is placed as always (the fit's
    # heading is ~0.01 rad off, so a different centre along the side moves n by ~1 cm)
    assert means[0, 1] == pytest.approx(4.0 + 0.5 * cfg.width, abs=0.05)
    assert means[0, 1] == pytest.approx(plain_means[0, 1], abs=0.02)
    assert np.linalg.eigvalsh(p).min() > 0.0


def test_a_rear_whose_near_end_borders_a_shadow_is_born_as_before():
    """Across the road the shadow rule does not apply (``BirthConfig.shadow_aware`` acts along the
    length only): 1.2 m of a rear 20 m ahead, its near end (in bearing) next to another object's
    shadow, is born exactly as without the flags, the unseen width placed away from the sensor."""
    road = Road.from_curvature([(500.0, 0.0, 0.0)], lanes=3)
    ego = EgoState(100.0, 0.0, 0.0, 15.0)
    y = np.linspace(1.0, 2.2, 7)
    points = np.column_stack([np.full_like(y, 20.0), y])  # in E: a rear across the road, 1-2.2 m left
    means, covs = cluster_births([points], [None], ego, road, BirthConfig(), [(points[0], points[-1])])
    plain_means, plain_covs = cluster_births([points], [None], ego, road, BirthConfig())
    np.testing.assert_allclose(means, plain_means)
    np.testing.assert_allclose(covs, plain_covs)


@pytest.mark.parametrize("closed", [False, True])
def test_visible_road_births_equal_their_steps_and_the_oracle(closed):
    """``visible_road_births``' one compiled call (``tracker.birth.road_births_kernel``) gives bit for
    bit what its steps give (``road_births``, the acceleration state, ``to_vehicle``, ``entering_view``):
    no tracks, tracks hiding some births, tracks beside some births, 7 and 8 state coordinates, an open
    road's ends (births beyond them left out); and the oracle (its occlusion in numpy) keeps the same
    components."""
    from oracles import birth as oracle
    from tracker.birth import entering_view, visible_road_births
    from tracker.measurement import to_vehicle

    if closed:
        road = Road.from_waypoints(np.array([[100.0, 0.0], [0.0, 100.0], [-100.0, 0.0], [0.0, -100.0]]), closed=True,
                                   lanes=3, lane_width=3.5)
    else:
        road = Road.from_curvature([(120.0, 0.0, 0.0), (200.0, 0.0, 0.01)], lanes=3, lane_width=3.5)
    config = BirthConfig()
    rng = np.random.default_rng(1)
    kept = []
    for trial in range(12):
        s_ego = float(rng.uniform(0.0, road.length)) if trial % 3 else 10.0  # near an open road's start
        x, y, c, sn, _ = road.frame1(s_ego)
        ego = EgoState(x, y, float(np.arctan2(sn, c)), float(rng.uniform(5, 30)), 0.0)
        count = int(rng.integers(0, 6))
        track_s = s_ego + rng.choice([-1.0, 1.0], count) * rng.uniform(5.0, 60.0, count)
        tracks_state = np.zeros((count, 7))
        tracks_state[:, 0] = np.mod(track_s, road.length) if closed else np.clip(track_s, 0.0, road.length)
        tracks_state[:, 1] = rng.choice(road.lane_centers, count)
        tracks_state[:, 5:7] = [4.5, 1.9]
        tracks = to_vehicle(tracks_state, ego, road)
        labels = np.arange(count)
        for accel in (None, 0.25):
            got = visible_road_births(road, s_ego, ego, 60.0, config, accel, tracks, labels, 3.0)
            means, covs = road_births(road, s_ego, ego.v, 60.0, config)
            if accel is not None:
                means = np.concatenate([means, np.zeros((len(means), 1))], axis=1)
                covs = np.pad(covs, ((0, 0), (0, 1), (0, 1)))
                covs[:, 7, 7] = accel
            if len(means) and count:
                keep = entering_view(to_vehicle(means, ego, road), tracks, labels, 3.0)
                means, covs = means[keep], covs[keep]
            np.testing.assert_array_equal(got[0], means)
            np.testing.assert_array_equal(got[1], covs)
            ref = oracle.visible_road_births(road, s_ego, ego, 60.0, config, accel, tracks, labels, 3.0)
            np.testing.assert_array_equal(ref[0], got[0])
            np.testing.assert_array_equal(ref[1], got[1])
            kept.append(len(got[0]) / max(len(road_births(road, s_ego, ego.v, 60.0, config)[0]), 1))
    assert min(kept) < 1.0 and max(kept) == 1.0  # some births dropped, and frames with all of them


def test_visible_road_births_needs_one_label_per_track():
    from tracker.birth import visible_road_births
    from tracker.measurement import to_vehicle

    road = Road.from_curvature([(200.0, 0.0, 0.0)], lanes=2, lane_width=3.5)
    ego = EgoState(50.0, 0.0, 0.0, 10.0, 0.0)
    tracks = to_vehicle(np.array([[60.0, 1.75, 10.0, 0.0, 0.0, 4.5, 1.9]] * 2), ego, road)
    with pytest.raises(ValueError, match="one label per track"):
        visible_road_births(road, 50.0, ego, 60.0, BirthConfig(), None, tracks, np.array([1]), 3.0)


def test_cluster_birth_in_an_oncoming_lane_ignores_a_passing_vehicles_radar_velocity():
    """A car in the oncoming lane of a straight two-way road, 30 m ahead: its birth heads pi and takes
    the speed of a radar velocity against s (12 m/s); a radar velocity along s (the ego lane's car
    passing it, whose detection the cluster picked up) would be -12 m/s along that heading, so the
    birth takes the speed prior (the ego's speed) instead."""
    road = Road.from_curvature([(500.0, 0.0, 0.0)], lanes=2, oncoming=1)
    ego = EgoState(100.0, -1.75, 0.0, 10.0)
    corners = to_local(rectangle_corners(np.array([130.0, 1.75]), np.array(np.pi), np.array(4.8), np.array(2.0)),
                       np.array([100.0, -1.75]), 0.0)
    points, _ = rectangle_scan(corners, np.arange(-np.pi, np.pi, np.radians(0.2)))
    own, _ = cluster_births([points], [np.array([-12.0, 0.0])], ego, road, BirthConfig())
    passing, _ = cluster_births([points], [np.array([12.0, 0.0])], ego, road, BirthConfig())
    for means in (own, passing):
        assert abs(abs(means[0, 3]) - np.pi) < 0.05 and means[0, 1] == pytest.approx(1.75, abs=0.3)
    assert own[0, 2] == pytest.approx(12.0, abs=0.1) and passing[0, 2] == 10.0


@pytest.mark.parametrize("course_sign", [1.0, -1.0])
def test_a_cluster_birth_crossing_the_road_heads_along_its_radar_course(course_sign):
    """A 4.8 x 2 m car crossing a straight road 25 m ahead, its length across the road, its radar velocity
    8 m/s across (either way): its birth heads +-pi/2 from the road, the way the radar says, with the
    crossing side as its length and the radar's speed. Without the radar, or with it switched off, the
    birth takes the quarter turn nearest the road: the 4.8 m side is then its width."""
    road = Road.from_curvature([(500.0, 0.0, 0.0)], lanes=3)
    ego = EgoState(100.0, 0.0, 0.0, 10.0)
    corners = to_local(rectangle_corners(np.array([125.0, 1.0]), np.array(course_sign * np.pi / 2), np.array(4.8),
                                         np.array(2.0)), np.array([100.0, 0.0]), 0.0)
    points, _ = rectangle_scan(corners, np.arange(-np.pi, np.pi, np.radians(0.2)))
    velocity = np.array([0.3, course_sign * 8.0])
    crossing, _ = cluster_births([points], [velocity], ego, road, BirthConfig())
    assert crossing[0, 3] == pytest.approx(course_sign * np.pi / 2, abs=0.05)
    assert crossing[0, 5] == pytest.approx(4.8, abs=0.2) and crossing[0, 6] == pytest.approx(2.0, abs=0.2)
    assert crossing[0, 2] == pytest.approx(8.0, abs=0.1)
    for velocities, cfg in (([None], BirthConfig()), ([velocity], BirthConfig(crossing_min_speed=None))):
        along, _ = cluster_births([points], velocities, ego, road, cfg)
        assert abs(along[0, 3]) < 0.05 and along[0, 6] >= 2.9  # the crossing side read as a width
    # a slow radar velocity says little of the course: the road's direction
    slow, _ = cluster_births([points], [velocity / 4.0], ego, road, BirthConfig())
    assert abs(slow[0, 3]) < 0.05
