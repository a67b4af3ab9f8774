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

HARD = ["truck-hairpin", "emergency-brake", "hard-accel", "stop-and-go", "standing-vehicle", "mixed-traffic", "urban-parked"]


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


# -- two-way roads: traffic against s, parking lanes ----------------------------------------------
def two_way(vehicles: list[dict], road: dict | None = None, **overrides: object) -> dict:
    """A straight two-way road 800 m long (lane 0 along s, lane 1 against s), the ego in lane 0."""
    return scenario(vehicles, road=road or {"lanes": 2, "oncoming": 1, "segments": [[800.0, 0.0, 0.0]]},
                    ego={"lane": 0, "s": 20.0, "speed": 10.0}, **overrides)


def truth_of(world: World, vid: int, t: float) -> tuple[float, float, float, float, float]:
    """``(s, n, yaw, v, xi)`` of vehicle ``vid`` at ``t`` (s)."""
    snap = world.truth_at(t)
    k = list(snap.ids).index(vid)
    return float(snap.s[k]), float(snap.n[k]), float(snap.yaw[k]), float(snap.v[k]), float(snap.xi[k])


def test_an_oncoming_car_drives_against_s_in_its_lane_and_leaves_at_s_0() -> None:
    # straight road heading +x: the oncoming car heads -x (yaw pi), s falls at its speed, n stays on
    # its lane centre (+1.75 m), and it leaves the world once its centre passes s = 0 (at 120 / 15 = 8 s)
    world = World(parse_scenario(two_way([{"lane": 1, "s": 120.0, "speed": 15.0, "behaviour": "constant"}])))
    for t in (0.0, 2.0, 5.0, 7.9):
        s, n, yaw, v, xi = truth_of(world, 1, t)
        assert s == pytest.approx(120.0 - 15.0 * t, abs=1e-6) and n == pytest.approx(1.75, abs=1e-9)
        assert abs(abs(yaw) - np.pi) < 1e-9 and abs(abs(xi) - np.pi) < 1e-9 and v == 15.0
    world.advance(8.2)
    assert 1 not in world.truth_at(8.2).ids and world.removed[1] == pytest.approx(8.05, abs=1e-9)


def test_idm_follows_the_vehicle_ahead_in_its_own_direction() -> None:
    # in the lane against s the vehicle ahead has the smaller s: a 20 m/s car 60 m behind (s larger)
    # a 10 m/s car closes in and follows it without touching; gaps and MOBIL are in that direction
    world = World(parse_scenario(two_way([
        {"lane": 1, "s": 400.0, "speed": 10.0, "behaviour": "constant"},
        {"lane": 1, "s": 460.0, "speed": 20.0, "behaviour": "idm"},
    ])))
    ahead, behind = world.traffic.vehicles[1], world.traffic.vehicles[2]
    assert behind.lane_distance_to(ahead) == pytest.approx(60.0, abs=1e-6) and ahead.lane_distance_to(behind) < 0
    assert world.traffic.neighbour_vehicles(behind) == (ahead, None)
    gaps = []
    for t in np.arange(0.5, 12.01, 0.5):
        s1, s2 = truth_of(world, 1, t)[0], truth_of(world, 2, t)[0]
        gaps.append(s2 - s1 - 4.8)
    assert min(gaps) > 5.0 and world.collisions == []
    assert truth_of(world, 2, 12.0)[3] == pytest.approx(10.0, abs=0.5)  # settled behind at its speed


def test_mobil_never_changes_into_the_oncoming_lane() -> None:
    # an IDM car with MOBIL stuck behind a slow car: on a one-way road it overtakes in lane 1; on the
    # two-way road lane 1 carries oncoming traffic, so it stays in lane 0 behind the slow car
    vehicles = [{"lane": 0, "s": 200.0, "speed": 6.0, "behaviour": "constant"},
                {"lane": 0, "s": 150.0, "speed": 16.0, "behaviour": "idm", "lane_changes": True}]
    one_way = World(parse_scenario(scenario(vehicles, ego={"lane": 0, "s": 20.0, "speed": 10.0})))
    two = World(parse_scenario(two_way(vehicles)))
    n_one = [truth_of(one_way, 2, t)[1] for t in np.arange(0.5, 12.01, 0.5)]
    n_two = [truth_of(two, 2, t)[1] for t in np.arange(0.5, 12.01, 0.5)]
    assert max(n_one) > 1.0  # overtook in the lane to the left
    assert max(abs(n + 1.75) for n in n_two) < 0.05 and two.collisions == []
    lanes = two.traffic.network
    assert lanes.side_lanes(("a", "b", 0)) == [] and lanes.side_lanes(("a", "b", 1)) == []


def test_oncoming_lane_frame_round_trips_and_points_against_s() -> None:
    world = World(parse_scenario(two_way([], road={"lanes": 3, "oncoming": 2, "segments": [[300.0, 0.0, 0.01]]})))
    road = world.road
    lane = world.traffic.lanes[2]
    assert lane.direction == -1 and world.traffic.lanes[0].direction == 1
    for local, lateral in ((10.0, 0.3), (150.0, -0.5), (280.0, 0.0)):
        xy = lane.position(local, lateral)
        world.traffic.projector.clear()
        back = lane.local_coordinates(xy)
        assert back == pytest.approx((local, lateral), abs=1e-6)
        # local = length - s, lateral to the left of the driving direction = right of s's direction
        s, n = road.to_frenet(xy)
        assert float(s) == pytest.approx(road.length - local, abs=1e-6)
        assert float(n) == pytest.approx(road.lane_center(2) - lateral, abs=1e-6)
        assert lane.heading_at(local) == pytest.approx(float(road.heading(road.length - local)) - np.pi, abs=1e-9)


def test_oncoming_cars_keep_their_lane_on_a_curve_and_a_closed_road_wraps() -> None:
    # a R 100 m left curve: an oncoming car keeps within 0.15 m of its lane centre, its yaw within
    # 2 deg of the road heading + pi; on a closed ring the same car passes s = 0 and comes round again
    bend = World(parse_scenario(two_way([{"lane": 1, "s": 250.0, "speed": 15.0, "behaviour": "constant"}],
                                        road={"lanes": 2, "oncoming": 1, "segments": [[60.0, 0.0, 0.0], [300.0, 0.01, 0.01]]},
                                        duration=10.0)))
    for t in np.arange(1.0, 10.01, 1.0):
        _, n, _, _, xi = truth_of(bend, 1, t)
        assert abs(n - 1.75) < 0.15 and abs(abs(xi) - np.pi) < np.radians(2.0)
    ring = {"lanes": 2, "oncoming": 1, "closed": True, "segments": [[2 * np.pi * 100.0, 0.01, 0.01]]}
    world = World(parse_scenario(two_way([{"lane": 1, "s": 30.0, "speed": 15.0, "behaviour": "constant"}],
                                         road=ring, duration=10.0)))
    s = [truth_of(world, 1, t)[0] for t in np.arange(0.0, 10.01, 0.5)]
    length = world.road.length
    assert s[0] == 30.0 and s[2] < s[1] < 30.0 and s[4] > 600.0  # 30 - 15 t, past s = 0 at 2 s
    # on the lane 1.75 m inside the R 100 m ring s runs at 15 / (1 - 0.01 x 1.75) m/s
    assert s[-1] == pytest.approx(30.0 - 150.0 / (1.0 - 0.0175) + length, abs=0.2) and 1 not in world.removed


def test_parked_cars_and_a_car_pulling_out() -> None:
    # parking lanes (2.5 m) both sides: lanes 0 (right, along s) .. 3 (left, against s); a car parked
    # backward stands facing -x; the scripted car pulls out of lane 0 into lane 1 and drives off
    road = {"lanes": 2, "oncoming": 1, "parking": "both", "segments": [[800.0, 0.0, 0.0]]}
    vehicles = [{"lane": 0, "s": 100.0, "speed": 0.0, "behaviour": "constant", "facing": "backward", "width": 1.8},
                {"lane": 3, "s": 100.0, "speed": 0.0, "behaviour": "constant", "width": 1.8},
                {"lane": 0, "s": 120.0, "speed": 0.0, "behaviour": "scripted", "width": 1.8,
                 "maneuvers": [{"t": 1.0, "kind": "speed", "speed": 8.0}, {"t": 2.0, "kind": "lane_change", "lane": 1}]}]
    data = two_way(vehicles, road=road)
    data["ego"]["lane"] = 1
    world = World(parse_scenario(data))
    assert [round(c, 3) for c in world.road.lane_centers] == [-4.75, -1.75, 1.75, 4.75]
    for t in (0.0, 6.0, 12.0):
        s, n, yaw, v, _ = truth_of(world, 1, t)
        assert (s, n, v) == (pytest.approx(100.0), pytest.approx(-4.75), 0.0) and abs(abs(yaw) - np.pi) < 1e-9
        s, n, yaw, v, _ = truth_of(world, 2, t)
        assert (s, n, v) == (pytest.approx(100.0), pytest.approx(4.75), 0.0) and abs(abs(yaw) - np.pi) < 1e-9
    s, n, yaw, v, _ = truth_of(world, 3, 12.0)
    assert abs(n + 1.75) < 0.1 and v == pytest.approx(8.0, abs=0.1) and s > 150.0 and world.collisions == []


# -- lanes that vary along s (roads from lane maps) -------------------------------------------------
def test_lane_table_follows_lanes_that_widen_and_begin() -> None:
    """``LaneTable`` against the layout: a lane that widens from 3 to 4 m and an auxiliary lane on the right
    that tapers in between s = 100 and 150 m; centres and widths at s, and the lane of an offset (a lane of
    zero width holds nothing)."""
    from sim.world.lanes import LaneTable
    from tracker import LaneLayout, Road

    stations = [0.0, 100.0, 150.0, 400.0]
    bounds = [[-3.0, -3.0, 0.0, 3.0], [-3.0, -3.0, 0.0, 3.0], [-6.5, -3.0, 0.0, 4.0], [-6.5, -3.0, 0.0, 4.0]]
    road = Road.from_curvature([(400.0, 0.0, 0.0)], layout=LaneLayout(stations, bounds))
    table = LaneTable.of(road)
    assert table.varies and LaneTable.of(road) is table
    for s in (0.0, 50.0, 125.0, 200.0):
        b = road.layout.boundaries_at(s)
        for k in range(3):
            assert table.centre(k, s) == pytest.approx(0.5 * (b[k] + b[k + 1]), abs=1e-9)
            assert table.width(k, s) == pytest.approx(b[k + 1] - b[k], abs=1e-9)
    assert table.lane_of(-3.5, 50.0) == 1  # no auxiliary lane yet: the right lane, clamped
    assert table.lane_of(-3.5, 200.0) == 0
    assert table.lane_of(3.9, 200.0) == 2 and table.lane_of(-1.0, 200.0) == 1


MAP_SCENARIO = "scenarios/maps/freeway-us101.toml"


def test_a_scenario_on_a_lane_map_keeps_its_vehicles_in_their_lanes() -> None:
    """The shipped scenario on the US-101 lane map: every vehicle stays within 0.3 m of its lane's centre
    at its ``s`` (the map's lanes are 3.2-3.9 m wide and curve slightly), and the one in the auxiliary
    lane, which begins about 85 m along the route, drives in it."""
    pytest.importorskip("commonroad")
    from pathlib import Path

    from sim.world.lanes import LaneTable

    spec = load_scenario(Path(__file__).resolve().parents[1] / MAP_SCENARIO)
    world = World(spec)
    road = world.road
    assert not road.uniform and road.lanes == 6
    table = LaneTable.of(road)
    lanes = {i + 1: v.lane for i, v in enumerate(spec.vehicles)}
    worst = 0.0
    for t in np.arange(0.0, spec.duration, 0.5):
        snap = world.truth_at(float(t))
        for vid, s, n in zip(snap.ids, snap.s, snap.n):
            if vid in lanes:
                worst = max(worst, abs(n - table.centre(lanes[vid], float(s))))
    assert worst < 0.3


def test_map_roads_in_scenario_files_are_checked() -> None:
    pytest.importorskip("commonroad")
    from pathlib import Path

    from sim.world.scenario import ScenarioError, load_scenario as load

    here = Path(__file__).resolve().parents[1] / "scenarios" / "maps"
    base = {"name": "m", "description": "unit test", "duration": 4.0,
            "road": {"map": str(here / "USA_US101-4_1_T-1.xml"), "route": {"start": [0.0, 0.0, -0.765]}},
            "ego": {"lane": 5, "s": 15.0, "speed": 5.0}}
    assert parse_scenario(base).build_road().lanes == 6
    with pytest.raises(ScenarioError, match="road.lanes: a road from a lane map takes its lanes"):
        parse_scenario({**base, "road": {**base["road"], "lanes": 3}})
    with pytest.raises(ScenarioError, match="road.map and road.route go together"):
        parse_scenario({**base, "road": {"map": base["road"]["map"]}})
    with pytest.raises(ScenarioError, match="no such file"):
        parse_scenario({**base, "road": {**base["road"], "map": str(here / "missing.xml")}})
    with pytest.raises(ScenarioError, match="lane 0 does not exist at s = 20.0 m"):
        parse_scenario({**base, "vehicles": [{"lane": 0, "s": 20.0, "speed": 5.0}]})
    spec = load(here / "freeway-us101.toml")  # the map's path is relative to the file
    assert Path(spec.road.map).is_absolute() and Path(spec.road.map).is_file()
    config = spec.road.to_config()  # a map's road round-trips as its map and route
    assert set(config) == {"map", "route"} and parse_scenario({**base, "road": config}).build_road().lanes == 6
    with pytest.raises(ScenarioError, match="generator: cannot draw traffic on a road with a lane map's lanes"):
        parse_scenario({"name": "m", "description": "unit test", "duration": 4.0, "road": base["road"],
                        "generator": {}})
    with pytest.raises(ScenarioError, match="generator: cannot draw traffic on a road with parking lanes"):
        parse_scenario({"name": "m", "description": "unit test", "duration": 4.0, "generator": {},
                        "road": {"lanes": 2, "parking": "both", "segments": [[400.0, 0.0, 0.0]]}})
