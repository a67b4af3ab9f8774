"""Tests of sim/world/lanes.py, sim/world/traffic.py and sim/world/world.py: highway-env traffic on our
road, and truth."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from highway_env.road.lane import lane_from_config

from sim import load_scenario
from sim.world.lanes import FrenetLane, build_network
from sim.world.scenario import parse_scenario, polygons_overlap
from sim.world.truth import Snapshot, rectangle_corners
from sim.world.world import World
from tracker.angles import wrap_angle

STANDARD = ["curvy-multi", "chicane-follow", "curve-single", "cut-in", "occlusion", "dense-highway", "circuit"]


def scenario(**overrides: object) -> dict:
    """A small scenario as plain data: a 3-lane road with a 100 m radius left bend."""
    data: dict = {
        "name": "unit",
        "description": "unit test",
        "duration": 10.0,
        "road": {"lanes": 3, "segments": [[60.0, 0.0, 0.0], [30.0, 0.0, 0.01], [300.0, 0.01, 0.01], [200.0, 0.0, 0.0]]},
        "ego": {"lane": 1, "s": 30.0, "speed": 15.0},
        "vehicles": [],
    }
    data.update(overrides)
    return data


def all_rectangles(snap: Snapshot) -> tuple[np.ndarray, np.ndarray]:
    """Corners (N+1, 4, 2) of the ego and the other vehicles, and their ids (ego = 0)."""
    ego = snap.ego
    corners = rectangle_corners(
        np.vstack([[ego.x, ego.y], snap.xy]),
        np.concatenate([[ego.yaw], snap.yaw]),
        np.concatenate([[ego.length], snap.length]),
        np.concatenate([[ego.width], snap.width]),
    )
    return corners, np.concatenate([[0], snap.ids])


# -- lanes ---------------------------------------------------------------------------------------
def test_lane_mapping_and_coordinates() -> None:
    spec = parse_scenario(scenario())
    road = spec.build_road()
    network, _ = build_network(road, spec.road.to_config())
    lanes = network.graph["a"]["b"]
    assert [lane.offset for lane in lanes] == pytest.approx([-3.5, 0.0, 3.5])  # id k = our lane k, growing leftward
    for k, lane in enumerate(lanes):
        for s, lat in [(10.0, 0.0), (120.0, 1.2), (300.0, -0.7)]:
            xy = lane.position(s, lat)
            np.testing.assert_allclose(xy, road.to_cartesian(s, road.lane_center(k) + lat), atol=1e-12)
            s2, lat2 = lane.local_coordinates(xy)
            assert (s2, lat2) == pytest.approx((s, lat), abs=1e-7)
            assert lane.heading_at(s) == pytest.approx(float(road.heading(s)), abs=1e-12)
            assert lane.width_at(s) == 3.5
    # positive lateral is to the left (+y when the road heads +x at s = 10)
    assert lanes[0].position(10.0, 1.0)[1] > lanes[0].position(10.0, 0.0)[1]
    # highway-env's closest-lane search agrees with our lane index
    xy = road.to_cartesian(150.0, road.lane_center(2) - 0.4)
    assert network.get_closest_lane_index(xy, float(road.heading(150.0))) == ("a", "b", 2)


def test_lane_config_round_trip() -> None:
    spec = parse_scenario(scenario())
    network, _ = build_network(spec.build_road(), spec.road.to_config())
    lane = network.graph["a"]["b"][2]
    copy = lane_from_config(lane.to_config())
    assert isinstance(copy, FrenetLane) and copy.index == 2
    np.testing.assert_allclose(copy.position(200.0, 0.3), lane.position(200.0, 0.3), atol=1e-9)


def test_two_way_lanes_with_parking_round_trip_and_end_at_s_0() -> None:
    # lanes 0..3: parking (2.5 m, along s), driving along s, driving against s, parking (against s); the
    # lanes against s run their local frame from the far end and end (after_end) near s = 0
    road_table = {"lanes": 2, "oncoming": 1, "parking": "both", "segments": [[300.0, 0.0, 0.0]]}
    spec = parse_scenario(scenario(road=road_table, vehicles=[], ego={"lane": 1, "s": 30.0, "speed": 10.0}))
    network, _ = build_network(spec.build_road(), spec.road.to_config())
    lanes = network.graph["a"]["b"]
    assert [(lane.offset, lane.width, lane.direction, lane.kind) for lane in lanes] == [
        (-4.75, 2.5, 1, "parking"), (-1.75, 3.5, 1, "driving"), (1.75, 3.5, -1, "driving"), (4.75, 2.5, -1, "parking")]
    for k in (0, 3):
        copy = lane_from_config(lanes[k].to_config())
        assert (copy.direction, copy.width) == (lanes[k].direction, lanes[k].width)
        np.testing.assert_allclose(copy.position(200.0, 0.3), lanes[k].position(200.0, 0.3), atol=1e-9)
    assert lanes[2].position(0.0, 0.0) == pytest.approx([300.0, 1.75]) and lanes[2].position(300.0, 0.0) == pytest.approx([0.0, 1.75])
    assert lanes[2].after_end(np.array([1.0, 1.75])) and not lanes[2].after_end(np.array([299.0, 1.75]))


def test_closed_lane_never_ends() -> None:
    spec = load_scenario("circuit")
    network, _ = build_network(spec.build_road())
    lane = network.graph["a"]["b"][0]
    assert not lane.after_end(lane.position(lane.length - 0.1, 0.0))
    assert lane.local_coordinates(lane.position(lane.length + 5.0, 0.0))[0] == pytest.approx(5.0, abs=1e-6)


# -- determinism and time ------------------------------------------------------------------------
def test_same_seed_gives_identical_truth() -> None:
    spec = load_scenario("curvy-multi")
    times = np.arange(1, 41) * 0.1
    a = World(spec, seed=7).run(times)
    b = World(spec, seed=7).run(times)
    for sa, sb in zip(a, b):
        for name in ("ids", "xy", "yaw", "v", "yaw_rate", "length", "width", "s", "n", "xi", "xi_dot"):
            assert np.array_equal(getattr(sa, name), getattr(sb, name)), name
        assert sa.ego == sb.ego


def test_truth_does_not_depend_on_when_it_is_observed() -> None:
    spec = load_scenario("cut-in")
    lidar = World(spec)
    both = World(spec)
    lidar_times = [0.1 * k for k in range(1, 81)]
    radar_times = [0.023 + k / 14 for k in range(0, 112)]
    merged = sorted(set(lidar_times) | set(radar_times))
    by_lidar = {t: s for t, s in zip(lidar_times, lidar.run(lidar_times))}
    by_both = {t: s for t, s in zip(merged, both.run(merged))}
    for t in lidar_times:
        assert np.array_equal(by_lidar[t].xy, by_both[t].xy) and by_lidar[t].ego == by_both[t].ego
    silent = World(spec)
    silent.advance(8.0)
    assert silent.snapshot().ego == by_lidar[lidar_times[-1]].ego


def test_time_only_moves_forward() -> None:
    world = World(parse_scenario(scenario()))
    world.advance(1.0)
    world.advance(1.0)  # the same time again is fine
    with pytest.raises(ValueError, match="time only moves forward"):
        world.advance(0.5)
    with pytest.raises(ValueError, match="finite"):
        world.advance(float("nan"))


def test_partial_steps_follow_the_kinematics() -> None:
    """Truth between grid times: the held action over the remaining fraction of a step; at a grid
    time it equals the stepped state."""
    spec = load_scenario("chicane-follow")
    coarse, fine = World(spec), World(spec)
    for k in range(1, 101):
        t = 0.05 * k
        fine.advance(t - 0.02)
        mid = fine.snapshot()
        end = fine.truth_at(t)
        assert coarse.truth_at(t).ego == end.ego
        # positions advance by speed x time along the (slipping) heading: |dx| = v * 0.02
        assert math.hypot(end.xy[0, 0] - mid.xy[0, 0], end.xy[0, 1] - mid.xy[0, 1]) == pytest.approx(mid.v[0] * 0.02, rel=1e-9)


# -- truth ---------------------------------------------------------------------------------------
def test_truth_frenet_matches_the_road() -> None:
    spec = load_scenario("curvy-multi")
    world = World(spec)
    road = world.road
    for t in np.arange(0.0, 12.0, 0.37):
        snap = world.truth_at(float(t))
        s, n = road.to_frenet(snap.xy)
        np.testing.assert_allclose(snap.s, s, atol=1e-6)
        np.testing.assert_allclose(snap.n, n, atol=1e-6)
        np.testing.assert_allclose(snap.xi, wrap_angle(snap.yaw - road.heading(snap.s)), atol=1e-9)
        assert snap.t == pytest.approx(float(t))


def test_xi_dot_is_the_rate_of_xi() -> None:
    world = World(load_scenario("cut-in"))  # the cut-in vehicle (id 1) turns during its lane change
    for t0 in (6.51, 7.26, 8.01):
        a = world.truth_at(t0)
        b = world.truth_at(t0 + 0.02)  # inside the same 0.05 s step
        rate = wrap_angle(b.xi - a.xi) / 0.02
        np.testing.assert_allclose(rate, a.xi_dot, atol=2e-3)
        np.testing.assert_allclose(wrap_angle(b.yaw - a.yaw) / 0.02, a.yaw_rate, atol=1e-9)
    assert np.max(np.abs(a.xi_dot)) > 0.01  # it was turning relative to the road


def test_truth_ids_sizes_and_ego() -> None:
    spec = parse_scenario(
        scenario(
            vehicles=[
                {"lane": 0, "s": 60.0, "speed": 15.0, "behaviour": "constant", "length": 12.0, "width": 2.5},
                {"lane": 2, "s": 45.0, "speed": 14.0, "length": 4.0, "width": 1.8},
            ]
        )
    )
    world = World(spec)
    snap = world.truth_at(2.0)
    assert list(snap.ids) == [1, 2]
    assert list(snap.length) == [12.0, 4.0] and list(snap.width) == [2.5, 1.8]
    assert (snap.ego.length, snap.ego.width) == (4.8, 2.0)
    assert snap.v[0] == 15.0  # a constant-speed vehicle keeps its speed exactly
    ego = world.ego_state()
    assert (ego.x, ego.y) == (snap.ego.x, snap.ego.y) and ego.lane == 1


def test_scripted_lane_change_ends_in_its_lane_in_time() -> None:
    for start, duration, source, target in [(1.0, 3.0, 0, 2), (2.0, 4.0, 2, 1), (1.5, 2.0, 1, 0)]:
        spec = parse_scenario(
            scenario(
                vehicles=[
                    {
                        "lane": source,
                        "s": 70.0,
                        "speed": 16.0,
                        "behaviour": "scripted",
                        "maneuvers": [{"t": start, "kind": "lane_change", "lane": target, "duration": duration}],
                    }
                ]
            )
        )
        world = World(spec)
        road = world.road
        before = world.truth_at(start)
        assert road.lane_index(before.n[0]) == source
        done = world.truth_at(start + duration)
        assert road.lane_index(done.n[0]) == target
        assert abs(done.n[0] - road.lane_center(target)) < 0.3
        # straightened out along the lane (the peak is ~0.2 rad); on this R = 100 m bend the body
        # keeps a small angle -beta ~ -L kappa / 2 = -0.024 rad to the road (the centre's slip)
        assert abs(done.xi[0]) < 0.05
        later = world.truth_at(start + duration + 2.0)
        assert abs(later.n[0] - road.lane_center(target)) < 0.1


def test_brake_and_speed_maneuvers() -> None:
    spec = parse_scenario(
        scenario(
            vehicles=[
                {
                    "lane": 0,
                    "s": 80.0,
                    "speed": 16.0,
                    "behaviour": "scripted",
                    "maneuvers": [
                        {"t": 1.0, "kind": "brake", "speed": 8.0, "decel": 4.0},
                        {"t": 5.0, "kind": "speed", "speed": 12.0, "accel": 1.0},
                    ],
                }
            ]
        )
    )
    world = World(spec)
    v = [world.truth_at(t).v[0] for t in (1.0, 1.5, 2.0, 4.0, 6.0, 9.5)]
    assert v[0] == pytest.approx(16.0, abs=0.3)
    assert v[1] == pytest.approx(v[0] - 2.0, abs=0.15) and v[2] == pytest.approx(v[0] - 4.0, abs=0.3)  # 4 m/s^2
    assert v[3] == pytest.approx(8.0, abs=0.3)
    assert v[4] == pytest.approx(9.0, abs=0.3)  # 1 m/s^2 from t = 5
    assert v[5] == pytest.approx(12.0, abs=0.3)


def test_open_road_end_removes_vehicles() -> None:
    spec = parse_scenario(
        scenario(
            road={"lanes": 2, "segments": [[400.0, 0.0, 0.0]]},
            ego={"lane": 0, "s": 30.0, "speed": 10.0},
            vehicles=[{"lane": 1, "s": 380.0, "speed": 20.0, "behaviour": "constant"}],
        )
    )
    world = World(spec)
    assert list(world.truth_at(0.5).ids) == [1]
    snap = world.truth_at(2.0)
    assert len(snap) == 0 and world.removed == {1: pytest.approx(1.0 + 0.05, abs=0.051)}


def test_closed_road_wraps_s() -> None:
    spec = load_scenario("circuit")
    world = World(spec)
    road = world.road
    traffic = world.traffic
    ego, ahead = traffic.vehicles[0], traffic.vehicles[1]  # ego at s = 1010, vehicle 1 at s = 20 in lane 0
    front, _ = traffic.neighbour_vehicles(ego)
    assert front is ahead
    assert ego.lane_distance_to(ahead) == pytest.approx(20.0 + road.length - 1010.0, abs=1e-6)
    ego_s = []
    for t in np.arange(0.1, 8.0, 0.1):
        world.advance(float(t))
        ego_s.append(world.ego_state().s)
        snap = world.snapshot()
        assert np.all((snap.s >= 0) & (snap.s < road.length))
    ego_s = np.array(ego_s)
    assert ego_s[0] > 1000 and ego_s[-1] < 100  # it crossed the start line
    steps = np.diff(ego_s)
    assert np.all((steps > 0) | (steps < -road.length + 10))  # monotone up to the wrap


# -- the shipped scenarios: on the road, no collisions --------------------------------------------
@pytest.mark.parametrize("name", STANDARD)
def test_vehicles_stay_on_the_road_and_do_not_collide(name: str) -> None:
    spec = load_scenario(name)
    duration = min(spec.duration, 20.0)
    world = World(spec)
    road = world.road
    for t in np.arange(0.2, duration + 1e-9, 0.2):
        snap = world.truth_at(float(t))
        corners, ids = all_rectangles(snap)
        s, n = road.to_frenet(corners.reshape(-1, 2))
        assert np.all(n >= road.right_edge - 0.05) and np.all(n <= road.left_edge + 0.05), (name, t)
        if not road.closed:
            assert np.all(s[:4] <= road.length)  # the ego never runs off the end
        centre = np.vstack([[snap.ego.x, snap.ego.y], snap.xy])
        d = np.hypot(*(centre[:, None, :] - centre[None, :, :]).transpose(2, 0, 1))
        for i, j in np.argwhere(np.triu(d < 8.0, k=1)):
            assert not polygons_overlap(corners[i], corners[j]), f"{name}: vehicles {ids[i]} and {ids[j]} overlap at t = {t:.1f} s"
    assert world.collisions == []


def test_world_records_collisions(tmp_path: Path) -> None:
    """A constant-speed car that ignores a stopped one runs into it; the world records it."""
    spec = parse_scenario(
        scenario(
            vehicles=[
                {"lane": 0, "s": 40.0, "speed": 15.0, "behaviour": "constant"},
                {"lane": 0, "s": 70.0, "speed": 1.0, "behaviour": "scripted", "maneuvers": [{"t": 0.0, "kind": "brake"}]},
            ]
        )
    )
    world = World(spec)
    world.advance(4.0)
    assert [(a, b) for _, a, b in world.collisions] == [(1, 2)]
    assert 1.5 < world.collisions[0][0] < 2.5


def test_vehicles_stand_on_the_sloped_road_with_their_heights():
    """hill-vlp16: a 4 % grade and 3 % bank; the snapshot's ground heights are the road surface's
    (sim.world.ground.RoadGround gives the same at the vehicles' centres) and the heights the scenario's."""
    from sim.world.ground import RoadGround

    spec = load_scenario("hill-vlp16")
    world = World(spec, 0)
    snap = world.truth_at(2.0)
    surface = RoadGround(world.road, spec.road.grade, spec.road.bank)
    np.testing.assert_allclose(snap.z, surface.height(snap.xy), atol=1e-6)
    np.testing.assert_allclose(snap.z, 0.04 * snap.s + 0.03 * snap.n, atol=1e-9)  # all within the road's edges
    assert snap.ego.z == pytest.approx(0.04 * world.ego_state().s + 0.03 * world.ego_state().n)
    assert snap.height.tolist() == [3.6, 2.0, 1.5, 1.2, 1.5]  # truck (given), van, car, motorcycle, car
    flat = World(load_scenario("curve-single"), 0).truth_at(0.0)
    assert flat.z.tolist() == [0.0] and flat.height.tolist() == [1.5] and flat.ego.z == 0.0


def test_poses_at_gives_truth_at_poses_without_road_coordinates_and_the_rig_the_same_frames():
    """``World.poses_at`` returns ``truth_at``'s poses exactly (ids, centres, yaw, speed, yaw rate,
    extent, the ego) with NaN road coordinates; a rig given it for its radar cycles delivers the very
    same frames (radar detections, lidar, truth) as without it."""
    from sim.sensors.rig import RigConfig, SensorRig

    spec = load_scenario("curvy-multi")
    a, b = World(spec, seed=3), World(spec, seed=3)
    for t in (0.0, 0.37, 0.4, 1.234):
        full, pose = a.truth_at(t), b.poses_at(t)
        for name in ("ids", "xy", "yaw", "v", "yaw_rate", "length", "width", "height"):
            assert np.array_equal(getattr(full, name), getattr(pose, name)), name
        assert full.ego == pose.ego
        assert np.isnan(pose.s).all() and np.isnan(pose.xi_dot).all() and np.isfinite(full.s).all()
    rig = SensorRig(RigConfig())
    w1, w2 = World(spec, seed=3), World(spec, seed=3)
    plain = list(rig.frames(w1.truth_at, 1.5, seed=7))
    fast = list(rig.frames(w2.truth_at, 1.5, seed=7, poses_at=w2.poses_at))
    assert len(plain) == len(fast) == 16
    for p, f in zip(plain, fast):
        assert len(p.radar) > 0 or len(f.radar) == 0
        for name in ("t", "xy", "velocity", "target_id", "unit"):
            assert np.array_equal(getattr(p.radar, name), getattr(f.radar, name)), name
        assert np.array_equal(p.lidar.points, f.lidar.points)
        assert np.array_equal(p.truth.s, f.truth.s) and np.array_equal(p.truth.xy, f.truth.xy)
    assert sum(len(p.radar) for p in plain) > 20
