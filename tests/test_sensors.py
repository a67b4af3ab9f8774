"""sim.sensors: ray casting (against the pymunk oracle and the numpy oracle), the scene, lidar, radar,
roadside clutter, the rig."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from oracles.radar import visible as visible_oracle
from oracles.raycast import cast_numpy
from oracles.scene import scene_segments as scene_oracle

from sim.sensors import (
    FRONT_RADAR,
    REAR_RADAR,
    ClutterConfig,
    Lidar,
    LidarConfig,
    RadarConfig,
    RadarUnit,
    RadarUnitConfig,
    RayGrid,
    RigConfig,
    RoadsideObjects,
    Segments,
    SensorRig,
    cast,
    cast_pymunk,
    generate_roadside,
)
from sim.sensors.lidar3d import EGO_BODY_ID
from sim.sensors.raycast import ray_returns
from sim.sensors.scene import scene_segments
from sim.world.truth import EgoPose, Snapshot
from tracker.frame import Frame

EGO = EgoPose(0.0, 0.0, 0.0, 0.0, 0.0, 4.8, 2.0)
EXACT = LidarConfig(range_noise_std=0.0, dropout_probability=0.0)  # noise-free, no dropout
RES = math.radians(0.2)


def snapshot(cars, ego: EgoPose = EGO, t: float = 0.0) -> Snapshot:
    """A snapshot from rows ``(x, y, yaw, length, width[, v[, yaw_rate]])``; ids 1..N."""
    rows = [tuple(c) + (0.0,) * (7 - len(c)) for c in cars]
    arr = np.array(rows, dtype=float).reshape(-1, 7)
    return Snapshot(
        t=t,
        ego=ego,
        ids=np.arange(1, len(rows) + 1),
        xy=arr[:, :2],
        yaw=arr[:, 2],
        length=arr[:, 3],
        width=arr[:, 4],
        v=arr[:, 5],
        yaw_rate=arr[:, 6],
    )


class StraightRoad:
    """Road stub: straight along +x from the origin; ``lanes`` lanes centred on the centerline."""

    def __init__(self, length: float = 400.0, lanes: int = 3, lane_width: float = 3.5) -> None:
        self.length = length
        self.closed = False
        self.right_edge = -0.5 * lanes * lane_width
        self.left_edge = 0.5 * lanes * lane_width

    def to_cartesian(self, s, n):
        return np.stack([np.asarray(s, dtype=float), np.asarray(n, dtype=float)], axis=-1)

    def heading(self, s):
        return np.zeros(np.shape(s))


class ArcRoad:
    """Road stub: a closed circle of radius ``radius`` about the origin, driven counter-clockwise
    (left turn), so ``n = radius - |p|`` (positive toward the centre, to the left)."""

    def __init__(self, radius: float = 120.0, lanes: int = 2, lane_width: float = 3.5) -> None:
        self.radius = radius
        self.length = 2 * math.pi * radius
        self.closed = True
        self.right_edge = -0.5 * lanes * lane_width
        self.left_edge = 0.5 * lanes * lane_width

    def to_cartesian(self, s, n):
        phi = np.asarray(s, dtype=float) / self.radius
        r = self.radius - np.asarray(n, dtype=float)
        return np.stack([r * np.cos(phi), r * np.sin(phi)], axis=-1)

    def heading(self, s):
        return np.asarray(s, dtype=float) / self.radius + math.pi / 2

    def lateral(self, xy):
        return self.radius - np.hypot(xy[:, 0], xy[:, 1])


def grid_count(low: float, high: float, res: float = RES) -> int:
    """Rays of the full-circle grid with bearings in [low, high] (rad, no wrap)."""
    angles = RayGrid.full_circle(res).angles
    return int(np.sum((angles >= low) & (angles <= high)))


def points_per_vehicle(scan, vehicle_id: int) -> int:
    return int(np.sum(scan.vehicle_id == vehicle_id))


# --------------------------------------------------------------------------------------------------
# ray casting


def random_scene(seed: int, vehicles: int = 25):
    """Random vehicles (some overlapping each other, none over the origin) plus roadside clutter of a
    straight road passing the origin, with the sensor at a random pose."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-90.0, 90.0, (vehicles, 2))
    length = rng.uniform(0.5, 12.0, vehicles)
    width = rng.uniform(0.3, 2.6, vehicles)
    clear = np.hypot(xy[:, 0], xy[:, 1]) > 0.5 * np.hypot(length, width) + 0.5
    cars = np.column_stack([xy, rng.uniform(-math.pi, math.pi, vehicles), length, width])[clear]
    ego = EgoPose(0.0, 0.0, float(rng.uniform(-math.pi, math.pi)))
    road = StraightRoad(length=240.0)
    objects = generate_roadside(road, ClutterConfig(tree_density=8.0, parked_car_density=3.0), rng=rng)
    shift = np.array([-120.0, rng.uniform(-3.0, 3.0)])
    moved = [objects.polygon(k) + shift for k in range(len(objects))]
    objects = RoadsideObjects.from_polygons(list(objects.kind), moved)
    return snapshot(cars, ego), objects


@pytest.mark.parametrize("seed", range(6))
def test_caster_matches_pymunk_oracle(seed):
    snap, objects = random_scene(seed)
    segments = scene_segments(snap, objects, (0.0, 0.0), snap.ego.yaw)
    assert len(segments) > 300
    fan_centre = float(np.random.default_rng(seed).uniform(-3.0, 3.0))
    grids = [
        RayGrid.full_circle(RES),
        RayGrid(7.3 + fan_centre, RES, 1800),  # a full circle starting anywhere
        RayGrid.fan(fan_centre, math.radians(60), RES),
        RayGrid.fan(fan_centre, math.radians(150), RES),  # wider than a half turn
    ]
    for grid in grids:
        fast = cast(segments, grid, 100.0)
        oracle = cast_pymunk(segments, grid, 100.0)
        both = fast.hit & oracle.hit
        assert both.sum() > 0.3 * grid.count
        assert np.array_equal(fast.hit, oracle.hit)
        np.testing.assert_allclose(fast.range[both], oracle.range[both], rtol=0.0, atol=1e-9)
        assert np.array_equal(fast.owner[both], oracle.owner[both])
        # culling back faces changes nothing for closed polygons seen from outside
        assert np.array_equal(cast(segments, grid, 100.0, cull_back_faces=False).range, fast.range)


@pytest.mark.parametrize("seed", range(4))
def test_caster_matches_the_numpy_oracle(seed):
    """``cast`` (``cast_kernel``) against the vectorised numpy caster (``oracles.raycast``): the same
    owners and ranges bit for bit, on full circles and fans (narrow and wider than a half turn), with
    and without back-face culling, for a loose segment set too, and for segments wholly or partly
    beyond ``max_range``."""
    snap, objects = random_scene(seed)
    segments = scene_segments(snap, objects, (0.0, 0.0), snap.ego.yaw)
    rng = np.random.default_rng(100 + seed)
    loose = Segments(rng.uniform(-60, 60, (40, 2)), rng.uniform(-60, 60, (40, 2)), np.arange(40))
    fan_centre = float(rng.uniform(-3.0, 3.0))
    grids = [RayGrid.full_circle(RES), RayGrid(7.3 + fan_centre, RES, 1800), RayGrid.fan(fan_centre, math.radians(60), RES),
             RayGrid.fan(fan_centre, math.radians(150), RES), RayGrid.fan(math.pi, math.radians(45), math.radians(0.1))]
    for grid in grids:
        for segs, cull in [(segments, True), (segments, False), (loose, False)]:
            for max_range in (100.0, 25.0):
                ref = cast_numpy(segs, grid, max_range, cull_back_faces=cull)
                got = cast(segs, grid, max_range, cull_back_faces=cull)
                assert ref.hit.sum() > 0.05 * grid.count
                assert np.array_equal(got.owner, ref.owner)
                assert np.array_equal(got.range, ref.range)


@pytest.mark.parametrize("seed", range(3))
def test_scene_matches_the_numpy_oracle(seed):
    """``scene_segments`` (``scene_kernel``) against the numpy scene (``oracles.scene``): the same
    edges in the same order with the same owners, within 1e-9 m, with and without a range limit and
    roadside objects; and a lidar scan the same as the oracles' scene, cast and the lidar's returns."""
    snap, objects = random_scene(seed)
    for roadside in (objects, None):
        for max_range in (None, 60.0):
            ref = scene_oracle(snap, roadside, (1.5, -0.5), snap.ego.yaw + 0.3, max_range)
            new = scene_segments(snap, roadside, (1.5, -0.5), snap.ego.yaw + 0.3, max_range)
            assert np.array_equal(new.owner, ref.owner) and len(ref) >= 8
            np.testing.assert_allclose(new.a, ref.a, rtol=0.0, atol=1e-9)
            np.testing.assert_allclose(new.b, ref.b, rtol=0.0, atol=1e-9)
    lidar = Lidar(LidarConfig())
    scan = lidar.scan(snap, objects, rng=np.random.default_rng(5))
    ego, cfg, grid = snap.ego, lidar.config, lidar.grid
    ref = cast_numpy(scene_oracle(snap, objects, (ego.x, ego.y), ego.yaw, cfg.max_range), grid, cfg.max_range)
    idx, measured, vehicle_id, _ = ray_returns(ref.hit, ref.range, ref.owner, snap.ids, cfg, np.random.default_rng(5))
    np.testing.assert_array_equal(scan.azimuth, grid.angles[idx])
    np.testing.assert_array_equal(scan.vehicle_id, vehicle_id)
    np.testing.assert_allclose(scan.points, grid.directions[idx] * measured[:, None], rtol=0.0, atol=1e-9)


def test_lidar_with_pymunk_caster_gives_the_same_scan():
    snap, objects = random_scene(11)
    fast = Lidar(EXACT).scan(snap, objects, rng=np.random.default_rng(0))
    oracle = Lidar(replace(EXACT, caster="pymunk")).scan(snap, objects, rng=np.random.default_rng(0))
    np.testing.assert_array_equal(fast.azimuth, oracle.azimuth)
    np.testing.assert_allclose(fast.points, oracle.points, rtol=0.0, atol=1e-9)
    np.testing.assert_array_equal(fast.vehicle_id, oracle.vehicle_id)


def test_ray_hits_exact_range_and_wraps_at_pi():
    # a wall across the +-pi seam, 10 m behind the origin: every ray within +-45 deg of pi hits it
    wall = Segments([[-10.0, -10.0]], [[-10.0, 10.0]], [0])  # interior on its left (x < -10): a x b < 0
    grid = RayGrid.full_circle(RES)
    res = cast(wall, grid, 100.0)
    behind = np.abs(np.abs(grid.angles) - math.pi) <= math.radians(45) - 1e-9
    assert np.array_equal(res.hit, behind)
    np.testing.assert_allclose(res.range[behind], 10.0 / np.abs(np.cos(grid.angles[behind])), rtol=1e-13)
    assert res.hit[np.argmax(grid.angles)]  # the ray at exactly pi
    # beyond max_range: nothing
    assert not cast(wall, grid, 9.99).hit.any()
    # a fan of +-150 deg leaves a 60 deg gap behind; a near wall spans the gap and both fan ends
    near_wall = Segments([[-5.0, -10.0]], [[-5.0, 10.0]], [0])  # bearings 180 -+ 63.4 deg
    fan = RayGrid.fan(0.0, math.radians(150), RES)
    res = cast(near_wall, fan, 100.0)
    expected = np.abs(fan.angles) >= math.pi - math.atan2(10.0, 5.0) + 1e-9
    assert (fan.angles[expected] > 0).sum() == (fan.angles[expected] < 0).sum() > 100  # both ends of the fan
    assert np.array_equal(res.hit, expected)
    np.testing.assert_allclose(res.range[expected], 5.0 / np.abs(np.cos(fan.angles[expected])), rtol=1e-13)


def test_caster_input_errors():
    grid = RayGrid.full_circle(RES)
    with pytest.raises(ValueError, match="max_range"):
        cast(Segments(np.zeros((0, 2)), np.zeros((0, 2)), []), grid, -1.0)
    with pytest.raises(ValueError, match="whole rays"):
        RayGrid.full_circle(math.radians(0.7))
    with pytest.raises(ValueError, match="same number of segments"):
        Segments(np.zeros((2, 2)), np.zeros((3, 2)), [0, 1])


# --------------------------------------------------------------------------------------------------
# lidar


def test_car_straight_behind_another_gets_no_points():
    lidar = Lidar(EXACT)
    cars = [(20.0, 0.0, 0.0, 4.8, 2.0), (30.0, 0.0, 0.0, 4.8, 2.0)]
    scan = lidar.scan(snapshot(cars), rng=np.random.default_rng(0))
    front = math.atan2(1.0, 17.6)
    assert points_per_vehicle(scan, 1) == grid_count(-front, front)
    assert points_per_vehicle(scan, 2) == 0
    alone = lidar.scan(snapshot(cars[1:]), rng=np.random.default_rng(0))
    assert points_per_vehicle(alone, 1) > 0


def test_half_hidden_car_gets_fewer_points_exactly_its_unoccluded_bearings():
    lidar = Lidar(EXACT)
    blocker = (20.0, 0.0, 0.0, 4.8, 2.0)
    target = (30.0, 1.5, 0.0, 4.8, 2.0)  # rear face x = 27.6, y in [0.5, 2.5]
    alone = lidar.scan(snapshot([target]), rng=np.random.default_rng(0))
    both = lidar.scan(snapshot([blocker, target]), rng=np.random.default_rng(0))
    low, high = math.atan2(0.5, 32.4), math.atan2(2.5, 27.6)  # target's bearings: side face corner .. rear-left corner
    shadow = math.atan2(1.0, 17.6)  # the blocker's rear-left corner
    assert points_per_vehicle(alone, 1) == grid_count(low, high)
    assert points_per_vehicle(both, 2) == grid_count(shadow, high)
    assert 0 < points_per_vehicle(both, 2) < points_per_vehicle(alone, 1)
    # the visible points are the unoccluded ones: all left of the shadow edge
    assert np.all(np.arctan2(both.points_on(2)[:, 1], both.points_on(2)[:, 0]) > shadow)


@pytest.mark.parametrize("resolution_deg", [0.2, 0.1])
@pytest.mark.parametrize("distance", [10.0, 50.0])
@pytest.mark.parametrize("side", [1.0, -1.0])  # ahead, and behind (bearing pi: the wrap)
def test_point_count_on_a_car_follows_the_angular_resolution(distance, resolution_deg, side):
    length, width = 4.8, 1.8
    lidar = Lidar(replace(EXACT, resolution_deg=resolution_deg))
    scan = lidar.scan(snapshot([(side * distance, 0.0, 0.0, length, width)]), rng=np.random.default_rng(0))
    half_angle = math.atan2(0.5 * width, distance - 0.5 * length)  # the near face subtends +-half_angle
    expected = 2 * math.floor(half_angle / math.radians(resolution_deg)) + 1  # rays at 0, +-res, ...
    assert points_per_vehicle(scan, 1) == expected
    if distance == 10.0 and resolution_deg == 0.2:
        assert expected == 2 * 33 + 1
    # all points on the near face
    np.testing.assert_allclose(np.abs(scan.points[:, 0]), distance - 0.5 * length, atol=1e-9)


def box_of_walls(distance: float = 20.0) -> Snapshot:
    """Four long thin 'vehicles' forming a closed box around the ego: every ray hits."""
    d, t, span = distance, 1.0, 2 * distance + 4.0
    return snapshot([(d, 0, 0, t, span), (-d, 0, 0, t, span), (0, d, 0, span, t), (0, -d, 0, span, t)])


def test_range_noise_std_and_dropout_rate_match_the_configuration():
    sigma, p_drop = 0.03, 0.1
    snap = box_of_walls()
    truth = Lidar(EXACT).scan(snap, rng=np.random.default_rng(0))
    assert len(truth) == 1800
    noisy = Lidar(LidarConfig(range_noise_std=sigma, dropout_probability=p_drop))
    scans = [noisy.scan(snap, rng=np.random.default_rng(s)) for s in range(3)]
    residuals, kept = [], 0
    for scan in scans:
        index = np.searchsorted(truth.azimuth, scan.azimuth)
        np.testing.assert_array_equal(truth.azimuth[index], scan.azimuth)
        residuals.append(scan.range - truth.range[index])
        # points lie on their rays at the measured range
        np.testing.assert_allclose(np.hypot(*scan.points.T), scan.range, rtol=1e-12)
        kept += len(scan)
    residuals = np.concatenate(residuals)
    assert abs(residuals.std() / sigma - 1.0) < 0.10
    assert abs(residuals.mean()) < 4 * sigma / math.sqrt(residuals.size)
    rays = 3 * 1800
    dropped = rays - kept
    assert abs(dropped - p_drop * rays) < 4 * math.sqrt(rays * p_drop * (1 - p_drop))


def test_lidar_min_and_max_range():
    lidar = Lidar(replace(EXACT, min_range=5.0, max_range=30.0))
    near = lidar.scan(snapshot([(4.0, 0.0, 0.0, 2.0, 1.0)]), rng=np.random.default_rng(0))  # near face at 3 m
    far = lidar.scan(snapshot([(32.0, 0.0, 0.0, 2.0, 1.0)]), rng=np.random.default_rng(0))  # near face at 31 m
    assert len(near) == 0 and len(far) == 0


def test_points_are_in_the_ego_frame():
    ego = EgoPose(100.0, -50.0, 2.0)
    # a car 15 m straight ahead of the ego, in G
    ahead = np.array([100.0, -50.0]) + 15.0 * np.array([math.cos(2.0), math.sin(2.0)])
    scan = Lidar(EXACT).scan(snapshot([(ahead[0], ahead[1], 2.0, 4.0, 2.0)], ego), rng=np.random.default_rng(0))
    np.testing.assert_allclose(scan.points[:, 0], 13.0, atol=1e-9)
    assert np.all(np.abs(scan.points[:, 1]) <= 1.0 + 1e-9)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"resolution_deg": 0.7}, "whole rays"),
        ({"max_range": 0.0}, "max_range"),
        ({"range_noise_std": -0.1}, "range_noise_std"),
        ({"dropout_probability": 1.5}, "dropout_probability"),
        ({"caster": "cuda"}, "caster"),
        ({"min_range": 200.0}, "min_range"),
    ],
)
def test_lidar_config_errors(kwargs, message):
    with pytest.raises(ValueError, match=message):
        LidarConfig(**kwargs)


# --------------------------------------------------------------------------------------------------
# roadside clutter


def test_clutter_lies_outside_the_road_bounds_and_is_reproducible():
    road = StraightRoad(length=500.0)
    config = ClutterConfig()
    objects = generate_roadside(road, config, rng=np.random.default_rng(5))
    kinds = {k: int(np.sum(objects.kind == k)) for k in ("post", "tree", "parked_car")}
    assert kinds["post"] == 2 * 50  # both sides, every 10 m over [0, 500)
    assert kinds["tree"] > 0 and kinds["parked_car"] > 0
    n = objects.vertices[:, 1]
    assert np.all((n >= road.left_edge + config.clearance) | (n <= road.right_edge - config.clearance))
    # every object wholly on one side
    for k in range(len(objects)):
        side = np.sign(objects.polygon(k)[:, 1])
        assert np.all(side == side[0])
    again = generate_roadside(road, config, rng=np.random.default_rng(5))
    np.testing.assert_array_equal(again.vertices, objects.vertices)
    other = generate_roadside(road, config, rng=np.random.default_rng(6))
    assert other.vertices.shape != objects.vertices.shape or not np.array_equal(other.vertices, objects.vertices)


def test_clutter_counts_follow_the_densities():
    road = StraightRoad(length=10_000.0)
    config = ClutterConfig(post_spacing=0.0, tree_density=3.0, parked_car_density=1.5)
    objects = generate_roadside(road, config, rng=np.random.default_rng(1))
    for kind, density in (("tree", 3.0), ("parked_car", 1.5)):
        mean = 2 * density * road.length / 100.0
        assert abs(np.sum(objects.kind == kind) - mean) < 4 * math.sqrt(mean)
    assert np.sum(objects.kind == "post") == 0


def test_clutter_on_a_curved_road_stays_outside_the_bounds():
    road = ArcRoad(radius=80.0)
    config = ClutterConfig(tree_offset=(4.0, 8.0))
    objects = generate_roadside(road, config, rng=np.random.default_rng(2))
    n = road.lateral(objects.vertices)
    assert np.all((n > road.left_edge + 0.2) | (n < road.right_edge - 0.2))


def test_clutter_along_the_real_road_is_off_road():
    from tracker.road import Road

    road = Road.from_curvature(
        [(50, 0, 0), (40, 0, 1 / 60), (80, 1 / 60, 1 / 60), (40, 1 / 60, 0)], start=(0.0, 0.0, 0.0), lanes=3
    )
    config = ClutterConfig(tree_density=5.0, parked_car_density=3.0)
    objects = generate_roadside(road, config, rng=np.random.default_rng(0))
    assert len(objects) > 40
    assert not road.on_road(objects.vertices, margin=config.clearance - 0.05).any()


def test_lidar_sees_clutter_and_clutter_occludes():
    road = StraightRoad(length=200.0)
    objects = generate_roadside(road, ClutterConfig(post_spacing=2.0), rng=np.random.default_rng(0))
    ego = EgoPose(100.0, 0.0, 0.0)
    scan = Lidar(EXACT).scan(snapshot([], ego), objects, rng=np.random.default_rng(0))
    assert np.sum(scan.roadside_index >= 0) > 100
    # a car parked beyond the posts (n = 12 m) is partly hidden by them
    car = (110.0, 12.0, 0.0, 4.8, 2.0)
    with_posts = Lidar(EXACT).scan(snapshot([car], ego), objects, rng=np.random.default_rng(0))
    without = Lidar(EXACT).scan(snapshot([car], ego), rng=np.random.default_rng(0))
    assert points_per_vehicle(with_posts, 1) < points_per_vehicle(without, 1)


def test_walls_hedges_and_curbs_line_the_edges():
    """Walls, hedges and curbs are chains of quads the road's whole length: a wall's face 1.5 m and a
    hedge's 2.0 +- 0.3 m outside the edge, a curb's face on it; 3.0, 1.6 and 0.15 m high. They come
    after the other kinds, curbs last, so the flat scene (the 2-D lidar's and the radar's: no curbs)
    keeps every other object's index; the random draws before them are the same as without them."""
    road = StraightRoad(length=500.0)
    config = ClutterConfig(wall_sides=("left",), hedge_sides=("right",), curb_sides=("left", "right"))
    objects = generate_roadside(road, config, rng=np.random.default_rng(5))
    plain = generate_roadside(road, ClutterConfig(), rng=np.random.default_rng(5))
    assert objects.kind[:len(plain)].tolist() == plain.kind.tolist()
    np.testing.assert_array_equal(objects.vertices[:len(plain.vertices)], plain.vertices)
    counts = {k: int(np.sum(objects.kind == k)) for k in ("wall", "hedge", "curb")}
    assert counts == {"wall": 250, "hedge": 500, "curb": 500}
    assert objects.kind[-500:].tolist() == ["curb"] * 500
    for kind, low, high in (("wall", 1.5, 1.8), ("hedge", 1.7 - 1e-9, 3.3 + 1e-9), ("curb", 0.0, 0.15)):
        k = np.flatnonzero(objects.kind == kind)
        y = np.concatenate([objects.polygon(i)[:, 1] for i in k])
        beyond = np.where(y > 0, y - road.left_edge, road.right_edge - y)
        assert beyond.min() >= low - 1e-9 and beyond.max() <= high + 1e-9, kind
        assert np.all(objects.height[k] == {"wall": 3.0, "hedge": 1.6, "curb": 0.15}[kind])
        along = np.concatenate([objects.polygon(i)[:, 0] for i in k])
        assert along.min() == pytest.approx(0.0) and along.max() == pytest.approx(500.0)
    flat = objects.flat_scene()
    assert len(flat) == len(objects) - 500 and "curb" not in flat.kind.tolist()
    np.testing.assert_array_equal(flat.vertices, objects.vertices[:len(flat.vertices)])


def test_the_2d_lidar_and_the_radar_pass_over_curbs():
    """Curbs are below the 2-D lidar's scan plane and the radar's beam: a rig with them gives the
    same frames as one without; a 3-D lidar sees them."""
    road = StraightRoad(length=300.0)
    curbs = generate_roadside(road, ClutterConfig(curb_sides=("left", "right")), rng=np.random.default_rng(3))
    plain = generate_roadside(road, ClutterConfig(), rng=np.random.default_rng(3))

    def world(t):
        base = moving_world(t)
        ego = EgoPose(base.ego.x + 100.0, 0.0, 0.0, 20.0)
        return Snapshot(t, ego, base.ids, base.xy + [100.0, 0.0], base.yaw, base.v, base.yaw_rate, base.length, base.width)

    a, b = SensorRig(roadside=curbs).run(world, 0.3, seed=2), SensorRig(roadside=plain).run(world, 0.3, seed=2)
    for fa, fb in zip(a, b):
        np.testing.assert_array_equal(fa.frame.lidar, fb.frame.lidar)
        np.testing.assert_array_equal(fa.frame.radar.as_array(), fb.frame.radar.as_array())
    three_d = SensorRig(RigConfig(lidar=LidarConfig(model="vlp16")), roadside=curbs).run(world, 0.0, seed=2)
    curb_index = np.flatnonzero(curbs.kind == "curb")
    assert np.isin(three_d[0].lidar.roadside_index, curb_index).sum() > 100


def test_clutter_config_errors():
    with pytest.raises(ValueError, match="post_offset puts objects within"):
        ClutterConfig(post_offset=0.2)
    with pytest.raises(ValueError, match="tree_radius"):
        ClutterConfig(tree_radius=(0.5, 0.1))
    with pytest.raises(ValueError, match="guardrail_sides"):
        ClutterConfig(guardrail_sides=("middle",))
    with pytest.raises(ValueError, match="curb_sides must be a list"):
        ClutterConfig(curb_sides="left")
    with pytest.raises(ValueError, match="wall_thickness must be > 0"):
        ClutterConfig(wall_thickness=0.0)
    with pytest.raises(ValueError, match="hedge_offset puts objects within"):
        ClutterConfig(hedge_offset=0.5)
    with pytest.raises(ValueError, match="no attribute 'length'"):
        generate_roadside(object(), rng=np.random.default_rng(0))
    with pytest.raises(ValueError, match="rng"):
        generate_roadside(StraightRoad(), rng=0)


# --------------------------------------------------------------------------------------------------
# radar

PERFECT = replace(FRONT_RADAR, detection_probability=1.0, false_alarm_rate=0.0)


def detect_many(unit: RadarUnit, snap: Snapshot, cycles: int, seed: int = 0, roadside=None):
    rng = np.random.default_rng(seed)
    return [unit.detect(snap, roadside, rng=rng) for _ in range(cycles)]


def test_radar_field_of_view_and_range():
    front = RadarUnit(PERFECT)  # mounted at (2.4, 0), +-45 deg, 150 m
    mount = 2.4

    def car_at(bearing_deg: float, dist: float):
        b = math.radians(bearing_deg)
        return (mount + dist * math.cos(b), dist * math.sin(b), b, 2.0, 1.0)

    inside = [car_at(35.0, 30.0), car_at(-35.0, 30.0), car_at(0.0, 148.0)]
    outside = [car_at(55.0, 30.0), car_at(-55.0, 30.0), car_at(0.0, 152.0), car_at(180.0, 20.0)]
    scans = detect_many(front, snapshot(inside + outside), 50)
    for scan in scans:
        assert sorted(scan.target_id.tolist()) == [1, 2, 3]
    rear = RadarUnit(replace(REAR_RADAR, detection_probability=1.0, false_alarm_rate=0.0))  # (-2.4, 0), 80 m
    cars = [(-2.4 - 78.0, 0.0, 0.0, 2.0, 1.0), (-2.4 - 82.0, 3.0, 0.0, 2.0, 1.0), (20.0, 0.0, 0.0, 2.0, 1.0)]
    for scan in detect_many(rear, snapshot(cars), 20):
        assert scan.target_id.tolist() == [1]
        assert scan.unit.tolist() == [0]


@pytest.mark.parametrize("seed", range(4))
def test_radar_visibility_matches_the_numpy_oracle(seed):
    """``RadarUnit.visible`` (``visible_kernel``) against the numpy scene, cast and nearest hits
    (``oracles.radar``): the same vehicles, their nearest points within 1e-9 m; front and rear units,
    with and without roadside objects, near and beyond the range limit, and a wide fan."""
    snap, objects = random_scene(seed)
    units = [RadarUnit(PERFECT), RadarUnit(replace(REAR_RADAR, max_range=30.0)),
             RadarUnit(replace(PERFECT, half_fov_deg=120.0, min_range=3.0, visibility_resolution_deg=0.25))]
    seen = 0
    for unit in units:
        for roadside in (objects, None):
            rows_ref, near_ref = visible_oracle(unit, snap, roadside)
            rows, near = unit.visible(snap, roadside)
            assert np.array_equal(rows, rows_ref)
            np.testing.assert_allclose(near, near_ref, rtol=0.0, atol=1e-9)
            seen += rows.size
    assert seen > 20


def test_radar_detection_probability():
    unit = RadarUnit(replace(FRONT_RADAR, false_alarm_rate=0.0))
    scans = detect_many(unit, snapshot([(30.0, 0.0, 0.0, 4.8, 2.0)]), 2000)
    rate = np.mean([len(s) for s in scans])
    assert abs(rate - 0.9) < 4 * math.sqrt(0.9 * 0.1 / 2000)


def test_radar_false_alarm_count_matches_its_rate_and_stays_in_the_field_of_view():
    lam, cycles = 3.0, 2000
    config = replace(REAR_RADAR, false_alarm_rate=lam)
    unit = RadarUnit(config)
    scans = detect_many(unit, snapshot([]), cycles)
    total = sum(len(s) for s in scans)
    assert abs(total - lam * cycles) < 4 * math.sqrt(lam * cycles)
    xy = np.concatenate([s.xy for s in scans])
    assert np.all(np.concatenate([s.target_id for s in scans]) == -1)
    rel = xy - config.mount_position(EGO.length)
    dist = np.hypot(rel[:, 0], rel[:, 1])
    bearing = np.arctan2(rel[:, 1], -rel[:, 0])  # from the rear boresight (-x)
    assert np.all((dist >= config.min_range - 1e-9) & (dist <= config.max_range + 1e-9))
    assert np.all(np.abs(bearing) <= math.radians(config.half_fov_deg) + 1e-12)
    # uniform over the sector's area: half of them beyond max_range / sqrt(2)
    assert abs(np.mean(dist > config.max_range / math.sqrt(2)) - 0.5) < 4 * math.sqrt(0.25 / total)


def test_radar_position_and_velocity_noise_and_velocity_in_ego_axes():
    ego = EgoPose(10.0, 5.0, 0.7, 20.0)
    heading = 1.2
    centre = np.array([10.0, 5.0]) + 30.0 * np.array([math.cos(0.7), math.sin(0.7)])
    snap = snapshot([(centre[0], centre[1], heading, 4.8, 2.0, 25.0)], ego)
    unit = RadarUnit(replace(FRONT_RADAR, detection_probability=1.0, false_alarm_rate=0.0))
    rows, nearest = unit.visible(snap)
    assert rows.tolist() == [0]
    scans = detect_many(unit, snap, 2000)
    xy = np.concatenate([s.xy for s in scans])
    vel = np.concatenate([s.velocity for s in scans])
    truth_v = 25.0 * np.array([math.cos(heading - 0.7), math.sin(heading - 0.7)])  # G velocity in E's axes
    for axis in range(2):
        assert abs((xy[:, axis] - nearest[0, axis]).std() / 0.5 - 1.0) < 0.10
        assert abs((vel[:, axis] - truth_v[axis]).std() / 0.2 - 1.0) < 0.10
    np.testing.assert_allclose(vel.mean(axis=0), truth_v, atol=4 * 0.2 / math.sqrt(2000))
    np.testing.assert_allclose(xy.mean(axis=0), nearest[0], atol=4 * 0.5 / math.sqrt(2000))


def test_radar_position_is_the_nearest_visible_point():
    unit = RadarUnit(PERFECT)
    # a car 20 m ahead of the mount, seen from behind: nearest point is the middle of its rear face
    rows, nearest = unit.visible(snapshot([(2.4 + 20.0, 0.0, 0.0, 4.0, 2.0)]))
    np.testing.assert_allclose(nearest, [[2.4 + 18.0, 0.0]], atol=1e-12)
    # half hidden behind a blocker: the nearest *visible* point is the first one past the shadow
    blocker = (2.4 + 10.0, -0.75, 0.0, 2.0, 1.5)  # near face 9 m ahead of the mount, y in [-1.5, 0]
    rows, nearest = unit.visible(snapshot([blocker, (2.4 + 20.0, 0.0, 0.0, 4.0, 2.0)]))
    assert rows.tolist() == [0, 1]
    first_ray = 18.0 * math.tan(math.radians(FRONT_RADAR.visibility_resolution_deg))
    assert nearest[1, 0] == pytest.approx(2.4 + 18.0)
    assert nearest[1, 1] == pytest.approx(first_ray, abs=1e-9)


def test_fully_hidden_target_is_never_detected():
    unit = RadarUnit(PERFECT)
    snap = snapshot([(20.0, 0.0, 0.0, 4.8, 2.0), (30.0, 0.0, 0.0, 4.8, 2.0)])
    for scan in detect_many(unit, snap, 200):
        assert scan.target_id.tolist() == [1]
    # hidden by roadside objects alone
    box = np.array([[10.0, -3.0], [11.0, -3.0], [11.0, 3.0], [10.0, 3.0]])
    wall = RoadsideObjects.from_polygons(["parked_car"], [box])
    for scan in detect_many(unit, snapshot([(30.0, 0.0, 0.0, 4.8, 2.0)]), 50, roadside=wall):
        assert len(scan) == 0


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"mount": "roof"}, "mount"),
        ({"half_fov_deg": 190.0}, "half_fov_deg"),
        ({"detection_probability": 1.2}, "detection_probability"),
        ({"false_alarm_rate": -1.0}, "false_alarm_rate"),
        ({"rate_hz": 0.0}, "rate_hz"),
    ],
)
def test_radar_config_errors(kwargs, message):
    with pytest.raises(ValueError, match=message):
        RadarUnitConfig(**kwargs)


def test_radar_units_need_unique_names():
    with pytest.raises(ValueError, match="unique names"):
        RadarConfig(units=(FRONT_RADAR, FRONT_RADAR))


# --------------------------------------------------------------------------------------------------
# the rig: frames, timing, ego-motion compensation, reproducibility


def moving_world(t: float) -> Snapshot:
    """Ego driving +x at 20 m/s, turning slowly; a car ahead at 25 m/s, one behind at 22 m/s."""
    ego = EgoPose(20.0 * t, 0.0, 0.05 * t, 20.0, 0.05)
    return snapshot(
        [(30.0 + 25.0 * t, 0.0, 0.0, 4.8, 2.0, 25.0), (-25.0 + 22.0 * t, 3.5, 0.0, 4.8, 2.0, 22.0)], ego, t
    )


def test_rig_timing_radar_rate_and_frame_contents():
    radar = RadarConfig(units=tuple(replace(u, detection_probability=1.0) for u in (FRONT_RADAR, REAR_RADAR)))
    rig = SensorRig(RigConfig(radar=radar))
    calls = []

    def truth_at(t):
        calls.append(t)
        return moving_world(t)

    frames = rig.run(truth_at, 2.0, seed=1)
    assert calls == sorted(calls) and len(calls) == len(set(calls))
    times = np.array([f.frame.t for f in frames])
    np.testing.assert_allclose(times, np.arange(21) / 10.0, atol=1e-12)
    previous = -np.inf
    for f in frames:
        assert isinstance(f.frame, Frame)
        assert f.truth.t == f.frame.t
        assert np.all((f.frame.radar.t > previous) & (f.frame.radar.t <= f.frame.t))
        np.testing.assert_array_equal(f.frame.lidar, f.lidar.points)
        previous = f.frame.t
    for index, unit in enumerate(radar.units):
        mine = [f.radar.t[(f.radar.unit == index) & (f.radar.target_id >= 0)] for f in frames]
        stamps = np.unique(np.concatenate(mine))
        # the tracked car is always visible with P_D = 1: one cycle per 1/14 s from the unit's phase
        expected = unit.phase_s + np.arange(math.floor((2.0 - unit.phase_s) * 14.0) + 1) / 14.0
        np.testing.assert_allclose(stamps, expected, atol=1e-12)
        assert len(stamps) == 28
        assert np.min(np.abs(stamps[:, None] - times[None, :])) > 1e-3  # not in phase with the lidar
    assert rig.frame_times(2.0).shape == (21,)


def test_rig_compensates_ego_motion_into_the_frame_time_ego_frame():
    noiseless = replace(PERFECT, position_noise_std=0.0, velocity_noise_std=0.0)
    exact = RadarConfig(units=(noiseless,))
    rig = SensorRig(RigConfig(radar=exact))
    frames = rig.run(moving_world, 1.0, seed=0)
    checked = 0
    for f in frames:
        ego_f = f.truth.ego
        for t_r, xy, vel in zip(f.frame.radar.t, f.frame.radar.xy, f.frame.radar.velocity):
            snap_r = moving_world(float(t_r))
            _, nearest = RadarUnit(exact.units[0]).visible(snap_r)  # in E at t_r
            e = snap_r.ego
            c, s = math.cos(e.yaw), math.sin(e.yaw)
            g = np.array([e.x + c * nearest[0, 0] - s * nearest[0, 1], e.y + s * nearest[0, 0] + c * nearest[0, 1]])
            c, s = math.cos(ego_f.yaw), math.sin(ego_f.yaw)
            d = g - [ego_f.x, ego_f.y]
            np.testing.assert_allclose(xy, [c * d[0] + s * d[1], -s * d[0] + c * d[1]], atol=1e-9)
            v_g = np.array([25.0, 0.0])
            np.testing.assert_allclose(vel, [c * v_g[0] + s * v_g[1], -s * v_g[0] + c * v_g[1]], atol=1e-9)
            checked += 1
    assert checked == 14


def test_rig_same_seed_identical_output_and_other_seed_differs():
    road = StraightRoad(length=300.0)
    objects = generate_roadside(road, rng=np.random.default_rng(3))
    rig = SensorRig(roadside=objects)

    def world(t):
        base = moving_world(t)
        ego = EgoPose(base.ego.x + 100.0, 0.0, 0.0, 20.0)
        shifted = base.xy + [100.0, 0.0]
        return Snapshot(t, ego, base.ids, shifted, base.yaw, base.v, base.yaw_rate, base.length, base.width)

    first, second = rig.run(world, 0.5, seed=7), rig.run(world, 0.5, seed=7)
    other = rig.run(world, 0.5, seed=8)
    assert len(first) == len(second) == 6
    for a, b in zip(first, second):
        np.testing.assert_array_equal(a.frame.lidar, b.frame.lidar)
        np.testing.assert_array_equal(a.frame.radar.as_array(), b.frame.radar.as_array())
        np.testing.assert_array_equal(a.radar.target_id, b.radar.target_id)
    assert any(not np.array_equal(a.frame.lidar, c.frame.lidar) for a, c in zip(first, other))


def test_rig_lidar_noise_does_not_depend_on_radar_settings():
    a = SensorRig(RigConfig()).run(moving_world, 0.3, seed=4)
    b = SensorRig(RigConfig(radar=RadarConfig(units=()))).run(moving_world, 0.3, seed=4)
    for fa, fb in zip(a, b):
        np.testing.assert_array_equal(fa.frame.lidar, fb.frame.lidar)
        assert len(fb.frame.radar) == 0


def test_rig_is_lazy_and_endless_without_duration():
    calls = []

    def truth_at(t):
        calls.append(t)
        return moving_world(t)

    stream = SensorRig().frames(truth_at, None, seed=0)
    for _ in range(3):
        frame = next(stream).frame
    assert frame.t == pytest.approx(0.2)
    assert max(calls) == pytest.approx(0.2)


def test_rig_errors():
    with pytest.raises(ValueError, match="seed"):
        SensorRig().run(moving_world, 1.0, seed=-1)
    with pytest.raises(ValueError, match="duration"):
        SensorRig().run(moving_world, float("nan"))
    with pytest.raises(ValueError, match="returned a snapshot at t="):
        SensorRig().run(lambda t: moving_world(0.0), 0.5)
    with pytest.raises(ValueError, match="must return a sim.world.truth.Snapshot"):
        SensorRig().run(lambda t: None, 0.5)


def test_reusing_a_seed_sequence_gives_identical_output():
    seq = np.random.SeedSequence(11)
    a = SensorRig(RigConfig()).run(moving_world, 0.3, seed=seq)
    b = SensorRig(RigConfig()).run(moving_world, 0.3, seed=seq)
    for fa, fb in zip(a, b):
        np.testing.assert_array_equal(fa.frame.lidar, fb.frame.lidar)
        np.testing.assert_array_equal(fa.frame.radar.as_array(), fb.frame.radar.as_array())


# -- the 3-D lidar in the rig ----------------------------------------------------------------------
VLP16 = LidarConfig(model="vlp16", range_noise_std=0.0, dropout_probability=0.0)


def test_lidar_config_keeps_3d_settings_for_the_vlp16_model():
    assert VLP16.lidar3d_config().rays == 28_800 and VLP16.lidar3d_config().mount_z == 1.9
    with pytest.raises(ValueError, match=r'LidarConfig.mount_z applies to the 3-D lidar only; set model = "vlp16"'):
        LidarConfig(mount_z=2.0)
    with pytest.raises(ValueError, match="LidarConfig.model must be one of"):
        LidarConfig(model="hdl64")


def test_lidar_config_models_of_real_sizes_take_their_tables_and_azimuth_steps():
    """A 3-D model's beams and azimuth step come from ``LIDAR3D_MODELS`` unless the azimuth step is set;
    the mount and the ranges are the config's; the VLP-16's evenly spaced grid fields are refused for
    the others (their tables are fixed)."""
    assert LidarConfig().azimuth_step_deg == 0.2 and LidarConfig(model="vlp16").azimuth_step_deg == 0.2
    os1 = LidarConfig(model="os1-128", mount_z=2.1, max_range=120.0)
    assert os1.azimuth_step_deg == 360.0 / 1024 and os1.rays == 1024
    c3 = os1.lidar3d_config()
    assert (c3.beams, c3.azimuth_count, c3.mount_z, c3.max_range) == (128, 1024, 2.1, 120.0)
    assert LidarConfig(model="hdl64e", resolution_deg=0.2).lidar3d_config().rays == 64 * 1800
    assert LidarConfig(model="vlp32c").lidar3d_config().elevations_deg[0] == -25.0
    with pytest.raises(ValueError, match="LidarConfig.beams sets the VLP-16's evenly spaced beams; model 'hdl64e'"):
        LidarConfig(model="hdl64e", beams=32)


def test_rig_with_the_vlp16_delivers_raw_clouds_labelled_by_what_they_hit():
    """Frames carry (N, 3) clouds in the lidar's frame: ground rings within the beams' reach, the car's
    side, nothing else; the same seed gives the same clouds."""
    snap = snapshot([(15.0, 3.5, 0.0, 4.8, 2.0)])
    rig = SensorRig(RigConfig(lidar=replace(VLP16, range_noise_std=0.03)))
    frames = rig.run(lambda t: replace(snap, t=t), 0.2, seed=4)
    scan = frames[0].lidar
    assert frames[0].frame.lidar.shape == (len(scan), 3)
    assert np.array_equal(frames[0].frame.lidar, scan.points)
    assert scan.ground.sum() > 10_000 and (scan.vehicle_id == 1).sum() > 100
    assert set(np.unique(scan.vehicle_id)) == {EGO_BODY_ID, -1, 1}  # the ego's own roof, the ground, the car
    # ground returns lie on z = 0 in G (the sensor 1.9 m up), within the noise along slanted rays
    z = scan.points_global()[scan.ground, 2]
    assert np.abs(z).max() < 0.03 * 5
    again = SensorRig(RigConfig(lidar=replace(VLP16, range_noise_std=0.03))).run(lambda t: replace(snap, t=t), 0.2, seed=4)
    assert np.array_equal(again[1].frame.lidar, frames[1].frame.lidar)


def test_a_roof_lidar_sees_the_egos_own_roof_where_its_low_beams_come_down_on_it():
    """VLP-16 1.9 m up over the centre of a 4.8 x 2.0 x 1.5 m ego: a ray of elevation el < 0 and azimuth
    az reaches the roof's height 0.4 m lower at the horizontal distance d = 0.4 / tan(-el); it returns
    from the roof (``EGO_BODY_ID``, at z = 1.5 m in E) exactly when (d cos az, d sin az) lies on it. The
    tracker's crop of the ego's box removes those returns and nothing else; a lidar inside the box
    (set into the bumper) does not see the body."""
    from tracker.cloud import CloudConfig, process_cloud

    ego = EgoPose(0.0, 0.0, 0.4, length=4.8, width=2.0, height=1.5)
    snap = snapshot([(14.0, -4.0, 0.3, 4.8, 2.0)], ego=ego)
    scan = SensorRig(RigConfig(lidar=VLP16)).run(lambda t: replace(snap, t=t), 0.0, seed=1)[0].lidar
    cfg = VLP16.lidar3d_config()
    az = np.repeat(cfg.azimuths, cfg.beams)  # ray i = azimuth i // beams, beam i % beams
    el = np.tile(cfg.elevations, cfg.azimuth_count)
    with np.errstate(divide="ignore", invalid="ignore"):
        d = np.where(el < 0, 0.4 / np.tan(-el), np.inf)
        on_roof = (np.abs(d * np.cos(az)) <= 2.4) & (np.abs(d * np.sin(az)) <= 1.0)
    body = scan.vehicle_id == EGO_BODY_ID
    assert body.sum() == on_roof.sum() > 1000
    roof_e = scan.points[body] + [0.0, 0.0, 1.9]  # the sensor frame is E shifted up (no mount rotation)
    np.testing.assert_allclose(roof_e[:, 2], 1.5, atol=1e-9)
    result = process_cloud(scan.points, CloudConfig(ego_length=4.8, ego_width=2.0, ego_height=1.5))
    assert (result.ego_body == body).all() and result.stats.ego_body == body.sum()
    assert (result.kept == (scan.vehicle_id >= 0)).all()  # the car stays, the ground and the roof go
    bumper = replace(VLP16, mount_x=2.3, mount_z=0.6)
    scan = SensorRig(RigConfig(lidar=bumper)).run(lambda t: replace(snap, t=t), 0.0, seed=1)[0].lidar
    assert not (scan.vehicle_id == EGO_BODY_ID).any() and (scan.vehicle_id == 1).sum() > 50


def test_projected_3d_returns_of_a_box_agree_with_the_2d_lidar_of_its_rectangle():
    """The tracker's pipeline (ground removal, projection) turns the VLP-16's cloud of two vehicles
    into the 2-D lidar's points of the same rectangles: per azimuth the nearest projected return is
    the 2-D lidar's point at that azimuth (exactly without noise; within the noise with it)."""
    from tracker.cloud import process_cloud

    snap = snapshot([(14.0, -4.0, 0.3, 4.8, 2.0), (-20.0, 3.5, 0.0, 12.0, 2.5)])
    flat = Lidar(EXACT).scan(snap, rng=np.random.default_rng(0))
    key2 = np.round(np.degrees(flat.azimuth) / 0.2).astype(int)
    for noise, tol in ((0.0, 1e-9), (0.03, 0.12)):
        rig = SensorRig(RigConfig(lidar=replace(VLP16, range_noise_std=noise)))
        scan = rig.run(lambda t: replace(snap, t=t), 0.0, seed=1)[0].lidar
        result = process_cloud(scan.points)
        assert (result.kept == (scan.vehicle_id >= 0)).all()  # the ground goes, the vehicles stay
        key3 = np.round(np.degrees(scan.azimuth[result.kept]) / 0.2).astype(int)
        pts = result.points_2d
        order = np.lexsort((np.hypot(pts[:, 0], pts[:, 1]), key3))  # per azimuth, nearest first
        first = np.ones(len(order), dtype=bool)
        first[1:] = key3[order][1:] != key3[order][:-1]
        nearest = dict(zip(key3[order][first].tolist(), pts[order][first]))
        assert sorted(nearest) == sorted(key2.tolist())
        gap = np.array([np.linalg.norm(nearest[k] - p) for k, p in zip(key2.tolist(), flat.points)])
        assert gap.max() < tol, (noise, gap.max())


def test_roadside_objects_follow_the_edges_of_a_road_whose_lanes_change():
    """On a road whose right lane ends (a 3.5 m lane tapering out between s = 100 and 150 m), the roadside
    objects stand beyond the edge at their ``s``, none on the road surface."""
    from tracker import LaneLayout, Road

    layout = LaneLayout([0.0, 100.0, 150.0, 300.0], [[-5.25, -1.75, 1.75], [-5.25, -1.75, 1.75],
                                                      [-1.75, -1.75, 1.75], [-1.75, -1.75, 1.75]])
    road = Road.from_curvature([(300.0, 0.0, 0.0)], layout=layout)
    objects = generate_roadside(road, ClutterConfig(tree_density=20.0, parked_car_density=10.0),
                                rng=np.random.default_rng(4))
    s, n = road.to_frenet(objects.centre)
    right, left = road.edges(s)
    beyond = (n < right) | (n > left)
    assert len(s) > 40 and beyond.all()
    late = (s > 160.0) & (n < 0)
    assert late.sum() > 3 and n[late].max() > -5.25  # beside the narrowed road, not where the lane was


def test_a_rig_of_two_lidars_merges_their_clouds_in_the_vehicle_frame():
    """A VLP-32C on the roof and an OS1-128 above it: the rig's cloud is each lidar's own scan (the two
    drawn one after the other from the one stream) moved into E by its mount, each point's lidar and
    ring known; its points lie in G where each lidar alone puts them; a lidar spike moves a point
    along its own lidar's ray."""
    from sim.sensors.lidar3d import merge_scans
    from sim.sensors.rig import SceneLidar3D
    from sim.world.ground import FlatGround
    from tracker.cloud import mount_rotation

    rig_cfg = LidarConfig(model="vlp32c", mount_x=0.5, rig=({"model": "os1-128", "mount_z": 2.3, "mount_yaw_deg": 10.0},))
    ego = EgoPose(3.0, -1.0, 0.3, length=4.8, width=2.0, height=1.5)
    snap = snapshot([(14.0, -4.0, 0.3, 4.8, 2.0), (-20.0, 3.5, 0.0, 12.0, 2.5)], ego=ego)
    scene = SceneLidar3D(rig_cfg, None, FlatGround())
    assert scene.frame == "vehicle" and len(scene.sensors) == 2
    merged = scene.scan(snap, rng=np.random.default_rng(7))
    rng = np.random.default_rng(7)
    alone = [SceneLidar3D(c, None, FlatGround()).scan(snap, rng=rng) for c in (replace(rig_cfg, rig=()), rig_cfg.rig_config(0))]
    assert len(merged) == len(alone[0]) + len(alone[1]) and merged.rays == 32 * 1800 + 128 * 1024
    assert merged.frame == "vehicle" and merged.sensors().tolist() == [0] * len(alone[0]) + [1] * len(alone[1])
    np.testing.assert_allclose(merged.points_global(), np.concatenate([a.points_global() for a in alone]), atol=1e-9)
    # the mounts: the OS1-128's points are its sensor-frame points turned by 10 deg and raised to 2.3 m
    second = merged.points[merged.sensor == 1]
    np.testing.assert_allclose(second, alone[1].points @ mount_rotation(0.0, 0.0, math.radians(10.0)).T + [0.0, 0.0, 2.3], atol=1e-9)
    np.testing.assert_allclose(merged.point_origins()[merged.sensor == 0], np.tile([0.5, 0.0, 1.9], (len(alone[0]), 1)))
    assert merged.beam[merged.sensor == 1].max() > 31 and (merged.vehicle_id == 1).sum() > 200  # rings beyond the VLP-32C's 32
    # the ranges are each point's distance from its own lidar
    np.testing.assert_allclose(np.linalg.norm(merged.points - merged.point_origins(), axis=1), merged.range, atol=1e-9)
    with pytest.raises(ValueError, match="one mount per scan"):
        merge_scans(alone, [], np.zeros(3), 0.0)
    # a spike fault keeps a point on its own lidar's ray
    from sim.sensors.faults import FaultInjector
    from sim.world.scenario import FaultsSpec

    faults = FaultInjector(FaultsSpec(lidar_spikes=0.5), rig_cfg, np.random.default_rng(1))
    sf = SensorRig(RigConfig(lidar=rig_cfg)).run(lambda t: replace(snap, t=t), 0.0, seed=2)[0]
    spiked = faults.frame(sf).lidar
    moved = spiked.range != sf.lidar.range
    assert moved.sum() > 1000
    np.testing.assert_allclose(np.linalg.norm(spiked.points - spiked.point_origins(), axis=1), spiked.range, atol=1e-9)
    direction = (spiked.points - spiked.point_origins())[moved] / spiked.range[moved, None]
    before = (sf.lidar.points - sf.lidar.point_origins())[moved] / sf.lidar.range[moved, None]
    np.testing.assert_allclose(direction, before, atol=1e-9)


def test_rig_configuration_errors_and_a_rig_scenario_tracked():
    """One-line errors for a rig's lidars; a scenario with a rig runs, the tracker told the merged cloud's
    frame; ``--lidar-model`` replaces the rig by one lidar."""
    import tomllib

    from sim.evaluation.runner import rig_config_for, run_scenario, tracker_config_for, with_lidar_model
    from sim.world.scenario import SCENARIO_DIR, parse_scenario

    with pytest.raises(ValueError, match=r"LidarConfig.rig: a rig of several lidars is of 3-D lidars"):
        LidarConfig(rig=({"model": "vlp16"},))
    with pytest.raises(ValueError, match=r"LidarConfig.rig\[0\].model must be a 3-D model"):
        LidarConfig(model="vlp16", rig=({"model": "2d"},))
    with pytest.raises(ValueError, match=r"LidarConfig.rig\[0\].mount_h: unknown key"):
        LidarConfig(model="vlp16", rig=({"model": "vlp16", "mount_h": 1.0},))
    data = tomllib.loads((SCENARIO_DIR / "curve-single.toml").read_text())
    data["sensors"] = {"lidar": {"model": "vlp32c", "rig": [{"model": "os1-128", "mount_z": 2.2}]}}
    spec = parse_scenario(data, "test")
    rig, _ = rig_config_for(spec)
    config = tracker_config_for(spec, "curvilinear-fused", rig)
    assert config.cloud.frame == "vehicle" and config.cloud.mount_z == 1.9
    assert config.detection.lidar_resolution == pytest.approx(math.radians(360.0 / 1800))  # the finer of 0.2 and 0.35 deg
    result = run_scenario(spec, seed=0, duration=2.0)
    assert result.metrics["pos_rmse_m"] < 0.3 and result.metrics["cloud_vehicle_kept"] > 0.99
    single = with_lidar_model(spec, "vlp16")
    assert "rig" not in single.sensors["lidar"] and rig_config_for(single)[0].lidar.rig == ()


def test_an_organized_scan_has_every_ray_nan_where_nothing_returned():
    """``organized``: one row per ray in firing order, NaN where the ray returned nothing; its returning
    rows are the plain scan's (the same draws)."""
    from sim.sensors.rig import SceneLidar3D
    from sim.world.ground import FlatGround

    snap = snapshot([(14.0, -4.0, 0.3, 4.8, 2.0)])
    plain = SceneLidar3D(replace(VLP16, dropout_probability=0.01), None, FlatGround()).scan(snap, rng=np.random.default_rng(3))
    organized = SceneLidar3D(replace(VLP16, dropout_probability=0.01, organized=True), None, FlatGround()).scan(
        snap, rng=np.random.default_rng(3))
    assert len(organized) == organized.rays == 28_800 > len(plain)
    finite = np.isfinite(organized.range)
    assert finite.sum() == len(plain) and np.isnan(organized.points[~finite]).all()
    np.testing.assert_array_equal(organized.points[finite], plain.points)
    np.testing.assert_array_equal(organized.vehicle_id[finite], plain.vehicle_id)
    assert (organized.vehicle_id[~finite] == -1).all() and not organized.ground[~finite].any()
    np.testing.assert_array_equal(organized.beam, np.tile(np.arange(16), 1800))  # firing order: azimuth-major
    with pytest.raises(ValueError, match=r"LidarConfig.organized applies to the 3-D lidar only"):
        LidarConfig(organized=True)
