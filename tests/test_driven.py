"""sim.world.driven: recorded traffic with a driven ego -- its start from the planning problem, its
kinematics, collisions with recorded vehicles that do not react, the goal -- on synthetic recordings
(exact geometry) and on a real one."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.world.driven import EGO_LENGTH, EGO_WIDTH, DrivenReplayWorld, planned_duration
from sim.world.recording import PlanningProblem, RecordedVehicle, Recording
from tracker import Road

#: A straight two-lane road along x, lane centres at y = -1.75 and 1.75 m.
ROAD = Road.from_waypoints(np.array([[-50.0, 0.0], [300.0, 0.0]]), lanes=2, lane_width=3.5, right_edge=-3.5)


def _recording(cars: list[RecordedVehicle], **planning) -> Recording:
    args = {"id": 9, "t": 0.0, "x": 0.0, "y": -1.75, "yaw": 0.0, "v": 10.0, "goal": (), "goal_time": (4.0, 5.0)}
    args.update(planning)
    return Recording("synthetic", tuple(cars), dt=0.1, planning=PlanningProblem(**args))


def _standing(vid: int, x: float, y: float = -1.75, length: float = 4.5, width: float = 1.8, end: float = 6.0) -> RecordedVehicle:
    t = np.arange(0.0, end + 1e-9, 0.1)
    return RecordedVehicle(vid, t, np.column_stack([np.full(t.shape, x), np.full(t.shape, y)]), np.zeros(t.shape),
                           np.zeros(t.shape), length, width)


def test_the_ego_starts_at_the_planning_problem_and_drives_by_the_bicycle_model():
    world = DrivenReplayWorld(_recording([_standing(1, 200.0)]), ROAD)
    assert world.duration == pytest.approx(5.0)  # the goal interval's end
    ego = world.ego_state()
    assert (ego.x, ego.y, ego.yaw, ego.v, ego.s - 50.0, ego.n, ego.lane) == pytest.approx((0.0, -1.75, 0.0, 10.0, 0.0, -1.75, 0))
    assert (ego.length, ego.width) == (EGO_LENGTH, EGO_WIDTH)
    # a held action: 1 m/s^2, straight; after 1.03 s (between grid times) x = v t + a t^2 / 2 on the 0.05 s grid
    # (speed updated after the position each step, as highway-env's Euler step)
    world.ego.action = {"acceleration": 1.0, "steering": 0.0}
    world.ego.act = lambda action=None: None  # hold the action (a driver that does nothing)
    snap = world.truth_at(1.03)
    steps, dt = 20, 0.05
    x = sum((10.0 + 1.0 * dt * k) * dt for k in range(steps)) + (10.0 + 1.0 * dt * steps) * 0.03
    assert (snap.ego.x, snap.ego.y, snap.ego.v) == pytest.approx((x, -1.75, 11.03))
    assert snap.ids.tolist() == [1] and snap.xy[0] == pytest.approx((200.0, -1.75))
    assert world.collisions == [] and world.goal_reached_at is None


def test_a_collision_with_a_recorded_vehicle_and_the_goal():
    """A standing car 30 m ahead in the ego's lane: an ego that holds 10 m/s touches it when its front
    (x + 2.4) reaches the car's back (30 - 2.25), at t = 2.535 s: the grid time 2.55 s records it, once."""
    square = np.array([[10.0, -3.0], [12.0, -3.0], [12.0, -0.5], [10.0, -0.5]])
    world = DrivenReplayWorld(_recording([_standing(4, 30.0), _standing(5, 30.0, y=1.75)], goal=(square,)), ROAD)
    world.ego.act = lambda action=None: None
    world.ego.action = {"acceleration": 0.0, "steering": 0.0}
    world.truth_at(4.0)
    assert world.collisions == [(pytest.approx(2.55), 0, 4)]  # not the car in the other lane
    assert world.goal_reached_at == pytest.approx(1.0)  # the centre enters x >= 10 m at t = 1.0 s
    info = world.info()
    assert info["replay_ego"] == "planned" and info["goal_reached_s"] == pytest.approx(1.0)
    assert info["goal_time_s"] == [4.0, 5.0] and info["replay_vehicles"] == 2


def test_duration_and_errors():
    cars = [_standing(1, 100.0, end=3.0)]
    assert planned_duration(_recording(cars)) == pytest.approx(3.0)  # the recording ends before the goal time
    assert planned_duration(_recording(cars, goal_time=None)) == pytest.approx(3.0)
    with pytest.raises(ValueError, match="has no planning problem"):
        DrivenReplayWorld(Recording("none", tuple(cars), dt=0.1), ROAD)
    with pytest.raises(ValueError, match="nothing to drive"):
        planned_duration(_recording(cars, t=3.0))


def test_a_real_recording_driven_from_its_planning_problem():
    pytest.importorskip("commonroad")
    from sim.world.replay import ReplayWorld, load_recording
    from sim.world.scenario import SCENARIO_DIR, parse_scenario

    path = SCENARIO_DIR / "real" / "USA_US101-3_1_T-1.xml.gz"
    spec = parse_scenario({"name": "r", "description": "d", "replay": {"file": str(path)}}, "test")
    world = DrivenReplayWorld.from_spec(spec, seed=0)
    recording, _ = load_recording(str(path))
    p = recording.planning
    assert world.duration == pytest.approx(p.goal_time[1] - p.t) == pytest.approx(8.0)
    # the route holds the start and the goal region's centre, on the road
    assert world.road.on_road(np.array([[p.x, p.y], p.goal_center])).all()
    snap = world.truth_at(0.0)
    assert (snap.ego.x, snap.ego.y, snap.ego.yaw, snap.ego.v) == pytest.approx((p.x, p.y, p.yaw, p.v))
    # every recorded vehicle is truth (the planning problem's vehicle is not among them), as the replay has them
    replay = ReplayWorld.from_spec(spec, seed=0)
    at = world.truth_at(2.0)
    assert set(at.ids.tolist()) >= set(replay.truth_at(2.0).ids.tolist()) | {replay.ego_id} - {0}
    j = int(np.flatnonzero(at.ids == replay.ego_id)[0])
    ego = recording.vehicle(replay.ego_id)
    assert at.xy[j] == pytest.approx(ego.state_at(2.0)[:2])
    with pytest.raises(ValueError, match="replay.ego = .* names a recorded vehicle"):
        DrivenReplayWorld.from_spec(parse_scenario({"name": "r", "description": "d",
                                                    "replay": {"file": str(path), "ego": replay.ego_id}}, "test"))
    assert math.isfinite(world.ego_state().s)
