"""Tests of sim/world/traffic.py: scripted braking and acceleration at their rates, standstill, long and
small vehicles, and the hard suite's traffic (no overlaps at the start, no collisions, on the road)."""

from __future__ import annotations

import numpy as np
import pytest

from sim import load_scenario
from sim.world.scenario import load_suite, parse_scenario, polygons_overlap
from sim.world.traffic import MAX_REAR_AXLE, ScriptedCar
from sim.world.truth import Snapshot, rectangle_corners
from sim.world.world import World

HARD = ["truck-hairpin", "emergency-brake", "hard-accel", "stop-and-go", "standing-vehicle", "mixed-traffic"]


def scenario(vehicles: list[dict], **overrides: object) -> dict:
    """A 2-lane straight road 800 m long, the ego far behind in lane 1, and ``vehicles``."""
    data: dict = {
        "name": "traffic",
        "description": "unit test",
        "duration": 12.0,
        "road": {"lanes": 2, "segments": [[800.0, 0.0, 0.0]]},
        "ego": {"lane": 1, "s": 20.0, "speed": 10.0},
        "vehicles": vehicles,
    }
    data.update(overrides)
    return data


def speeds(world: World, vid: int, times: np.ndarray) -> np.ndarray:
    """Truth speed (m/s) of vehicle ``vid`` at ``times`` (s)."""
    out = []
    for t in times:
        snap = world.truth_at(float(t))
        out.append(snap.v[list(snap.ids).index(vid)])
    return np.array(out)


def rectangles(snap: Snapshot) -> np.ndarray:
    """Corners (N+1, 4, 2) of the ego and the other vehicles."""
    ego = snap.ego
    return rectangle_corners(
        np.vstack([[ego.x, ego.y], snap.xy]),
        np.concatenate([[ego.yaw], snap.yaw]),
        np.concatenate([[ego.length], snap.length]),
        np.concatenate([[ego.width], snap.width]),
    )


# -- braking, standstill, acceleration --------------------------------------------------------------
@pytest.mark.parametrize("decel", [4.0, 7.0, 8.0])
def test_brake_reaches_standstill_at_the_scripted_deceleration(decel: float) -> None:
    """v(t) = v0 - decel (t - t0) until 0 (within one step's rounding), then exactly 0: an 8 m/s^2
    brake is not clipped to highway-env's ACC_MAX of 6 m/s^2, and the car does not creep."""
    v0, t0 = 20.0, 1.0
    spec = parse_scenario(
        scenario([{"lane": 0, "s": 100.0, "speed": v0, "behaviour": "scripted", "maneuvers": [{"t": t0, "kind": "brake", "decel": decel}]}])
    )
    world = World(spec)
    stop = t0 + v0 / decel
    times = np.arange(0.5, 10.0, 0.05)
    v = speeds(world, 1, times)
    expected = np.clip(v0 - decel * (times - t0), 0.0, v0)
    np.testing.assert_allclose(v, expected, atol=decel * world.step + 1e-9)
    braking = (times > t0 + 0.1) & (times < stop - 0.1)
    slope = np.polyfit(times[braking], v[braking], 1)[0]
    assert slope == pytest.approx(-decel, rel=1e-3)
    assert np.all(v[times > stop + world.step] == 0.0)
    # distance covered while braking: v0^2 / (2 decel) (the car really stops there and stays)
    s_start = world_position_at(spec, 1, t0)
    s_end = world_position_at(spec, 1, 11.0)
    assert s_end - s_start == pytest.approx(v0**2 / (2.0 * decel), abs=v0 * 0.05 + 0.1)


def world_position_at(spec: object, vid: int, t: float) -> float:
    """Arc length (m) of vehicle ``vid`` at time ``t`` (s), from a fresh world."""
    world = World(spec)  # type: ignore[arg-type]
    snap = world.truth_at(t)
    return float(snap.s[list(snap.ids).index(vid)])


def test_brake_to_a_lower_speed_lands_on_it_and_holds() -> None:
    spec = parse_scenario(
        scenario([{"lane": 0, "s": 100.0, "speed": 20.0, "behaviour": "scripted",
                   "maneuvers": [{"t": 1.0, "kind": "brake", "speed": 8.0, "decel": 6.0}]}])
    )
    v = speeds(World(spec), 1, np.array([2.0, 3.0, 3.05, 4.0, 8.0]))
    np.testing.assert_allclose(v[:2], [14.0, 8.0], atol=0.31)  # 6 m/s^2 for 2 s
    np.testing.assert_allclose(v[2:], 8.0, atol=1e-9)  # exactly 8, no overshoot, no creeping


def test_stop_and_go_and_hard_acceleration() -> None:
    """Repeated stops (brake to 0) and restarts (3 m/s^2 speed changes) from a standstill."""
    script = [
        {"t": 0.5, "kind": "brake", "decel": 5.0},  # 10 -> 0 by t = 2.5
        {"t": 4.0, "kind": "speed", "speed": 9.0, "accel": 3.0},  # 3 m/s^2: 0 -> 9, rate-limited up to ~7.2
        {"t": 8.0, "kind": "brake", "decel": 6.0},  # -> 0 by t = 9.5
        {"t": 10.5, "kind": "speed", "speed": 6.0, "accel": 3.0},
    ]
    spec = parse_scenario(scenario([{"lane": 0, "s": 100.0, "speed": 10.0, "behaviour": "scripted", "maneuvers": script}]))
    times = np.array([1.5, 2.6, 3.9, 4.5, 5.5, 6.0, 9.6, 10.4, 11.5])
    v = speeds(World(spec), 1, times)
    np.testing.assert_allclose(v[:3], [5.0, 0.0, 0.0], atol=0.26)
    np.testing.assert_allclose(v[3:5], [1.5, 4.5], atol=0.16)  # 3 m/s^2 from the standstill
    assert v[5] > 5.5
    np.testing.assert_allclose(v[6:8], 0.0, atol=1e-9)
    assert v[8] == pytest.approx(3.0, abs=0.16)


def test_a_standing_vehicle_stays_put_and_traffic_stops_behind_it() -> None:
    spec = parse_scenario(
        scenario(
            [
                {"lane": 0, "s": 200.0, "speed": 0.0, "behaviour": "constant", "length": 2.2, "width": 0.8},
                {"lane": 0, "s": 120.0, "speed": 15.0, "behaviour": "idm", "lane_changes": False, "length": 18.0, "width": 2.5},
            ],
            duration=20.0,
        )
    )
    world = World(spec)
    first = world.truth_at(0.0)
    for t in np.arange(0.5, 20.0, 0.5):
        snap = world.truth_at(float(t))
        assert snap.v[0] == 0.0 and np.allclose(snap.xy[0], first.xy[0], atol=1e-12)
    assert world.collisions == []
    bus_front = snap.s[1] + 9.0
    gap = 200.0 - 1.1 - bus_front  # bumper to bumper (m); IDM aims at 5 m, braking hard from 15 m/s it ends a bit closer
    assert snap.v[1] < 0.2 and 2.0 < gap < 6.0


def test_long_vehicles_use_a_capped_rear_axle() -> None:
    spec = parse_scenario(
        scenario(
            [
                {"lane": 0, "s": 100.0, "speed": 10.0, "behaviour": "scripted", "length": 4.8},
                {"lane": 0, "s": 150.0, "speed": 10.0, "behaviour": "scripted", "length": 16.0, "width": 2.5},
            ]
        )
    )
    car, truck = World(spec).traffic.vehicles[1:]
    assert isinstance(truck, ScriptedCar)
    assert car.rear_axle == 2.4 and truck.rear_axle == MAX_REAR_AXLE == 3.0


def test_a_truck_on_a_tight_bend_keeps_its_lane() -> None:
    """A 16 x 2.5 m truck in the inner lane of a R 40 m bend (3.75 m lanes): body at ~ -l_r kappa =
    -0.075 rad to the road (-0.2 rad with highway-env's l_r = L/2), so its front corner swings out by
    the chord and that angle, ~0.5 m beyond its lane (~1.7 m with l_r = L/2), and never off the road."""
    spec = parse_scenario(
        scenario(
            [{"lane": 1, "s": 60.0, "speed": 10.0, "behaviour": "constant", "length": 16.0, "width": 2.5}],
            road={"lanes": 2, "lane_width": 3.75, "segments": [[40.0, 0.0, 0.0], [30.0, 0.0, 0.025], [200.0, 0.025, 0.025], [200.0, 0.0, 0.0]]},
            ego={"lane": 0, "s": 20.0, "speed": 8.0},
        )
    )
    world = World(spec)
    road = world.road
    for t in np.arange(6.0, 18.0, 1.0):
        snap = world.truth_at(float(t))
        assert snap.xi[0] == pytest.approx(-MAX_REAR_AXLE * 0.025, abs=0.01)
        _, n = road.to_frenet(rectangles(snap)[1])
        assert np.all(n >= road.lane_center(1) - 0.5 * road.lane_width - 0.6) and np.all(n <= road.left_edge)


# -- the hard suite ---------------------------------------------------------------------------------
def hard_worlds() -> list[World]:
    return [World(spec, seed) for spec in load_suite("hard").load() for seed in ((0, 1, 2) if spec.generator else (0,))]


def test_hard_suite_starts_without_overlapping_vehicles() -> None:
    worlds = hard_worlds()
    assert [w.spec.name.removesuffix("-seed0") for w in worlds if not w.spec.name.endswith(("seed1", "seed2"))] == HARD
    for world in worlds:
        corners = rectangles(world.truth_at(0.0))
        for i in range(len(corners)):
            for j in range(i + 1, len(corners)):
                assert not polygons_overlap(corners[i], corners[j]), (world.spec.name, i, j)
        assert world.collisions == []


def test_hard_suite_vehicles_stay_on_the_road_and_do_not_collide() -> None:
    for world in hard_worlds():
        road = world.road
        for t in np.arange(0.25, world.spec.duration + 1e-9, 0.25):
            _, n = road.to_frenet(rectangles(world.truth_at(float(t))).reshape(-1, 2))
            assert np.all(n >= road.right_edge - 0.05) and np.all(n <= road.left_edge + 0.05), (world.spec.name, t)
        assert world.collisions == [], world.spec.name


def test_emergency_brake_scenario_stops_at_7_and_8_mps2() -> None:
    world = World(load_scenario("emergency-brake"))
    times = np.arange(3.0, 10.0, 0.05)
    car, van = speeds(world, 1, times), speeds(World(load_scenario("emergency-brake")), 2, times)
    for v, t0, decel in ((car, 4.0, 8.0), (van, 4.5, 7.0)):
        expected = np.clip(20.0 - decel * (times - t0), 0.0, 20.0)
        np.testing.assert_allclose(v, expected, atol=decel * world.step + 1e-9)
    assert car[-1] == 0.0 and van[-1] == 0.0
