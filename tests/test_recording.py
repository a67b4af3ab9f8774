"""sim.world.recording: recorded vehicles, the CommonRoad reader (checked against commonroad-io's own
reading of the same file) and the default ego rule."""

from __future__ import annotations

import gzip
import math

import numpy as np
import pytest

from sim.world.recording import EGO_MAX_LENGTH, RecordedVehicle, Recording, read_commonroad_recording
from sim.world.scenario import SCENARIO_DIR

pytest.importorskip("commonroad")

REAL = SCENARIO_DIR / "real"
US101_3 = REAL / "USA_US101-3_1_T-1.xml.gz"


def _car(vid, t, x, y=0.0, length=4.5, yaw=0.0, v=10.0):
    t = np.asarray(t, dtype=float)
    return RecordedVehicle(vid, t, np.column_stack([np.broadcast_to(x, t.shape), np.broadcast_to(y, t.shape)]),
                           np.full(t.shape, yaw), np.full(t.shape, v), length, 1.8)


def test_commonroad_reader_matches_commonroad_io(tmp_path):
    from commonroad.common.file_reader import CommonRoadFileReader

    plain = tmp_path / "USA_US101-3_1_T-1.xml"
    plain.write_bytes(gzip.decompress(US101_3.read_bytes()))
    scenario, _ = CommonRoadFileReader(str(plain)).open()
    rec = read_commonroad_recording(US101_3)
    assert rec.name == "USA_US101-3_1_T-1" and rec.dt == pytest.approx(0.1) and rec.map_file == US101_3
    assert len(rec) == len(scenario.dynamic_obstacles) == 34
    for ob in scenario.dynamic_obstacles:
        car = rec.vehicle(ob.obstacle_id)
        states = [ob.initial_state, *ob.prediction.trajectory.state_list]
        assert len(car) == len(states)
        np.testing.assert_allclose(car.t, [0.1 * s.time_step for s in states])
        np.testing.assert_allclose(car.xy, [s.position for s in states])
        np.testing.assert_allclose(np.cos(car.yaw), [math.cos(s.orientation) for s in states], atol=1e-12)
        assert (car.length, car.width, car.kind) == (ob.obstacle_shape.length, ob.obstacle_shape.width, "car")
    # the plain file reads the same as the compressed one
    assert [v.id for v in read_commonroad_recording(plain)] == rec.ids


def test_reader_errors_are_one_line(tmp_path):
    with pytest.raises(FileNotFoundError, match="no such recording"):
        read_commonroad_recording(tmp_path / "absent.xml")
    bad = tmp_path / "bad.xml.gz"
    bad.write_bytes(b"not gzip at all")
    with pytest.raises(ValueError, match=r"^bad.xml.gz: not a readable gzip file"):
        read_commonroad_recording(bad)
    broken = tmp_path / "broken.xml"
    broken.write_text("<commonRoad><lanelet")
    with pytest.raises(ValueError, match=r"^broken.xml: commonroad-io cannot read it"):
        read_commonroad_recording(broken)


def test_state_at_is_linear_between_samples_and_none_outside():
    car = RecordedVehicle(3, [0.0, 0.1, 0.2], [[0, 0], [1, 0.5], [2, 1.0]], [0.0, 0.2, 0.4], [10.0, 11.0, 12.0], 4.5, 1.8)
    x, y, yaw, v, rate = car.state_at(0.05)
    assert (x, y, yaw, v) == pytest.approx((0.5, 0.25, 0.1, 10.5))
    assert rate == pytest.approx(2.0)  # central differences of the heading: 0.2 rad per 0.1 s
    assert car.state_at(-0.01) is None and car.state_at(0.21) is None
    assert car.state_at(0.2)[0] == pytest.approx(2.0)


def test_vehicle_validation():
    with pytest.raises(ValueError, match="strictly increasing"):
        _car(1, [0.0, 0.0], 0.0)
    with pytest.raises(ValueError, match="speed v must be >= 0"):
        _car(1, [0.0, 0.1], 0.0, v=-1.0)
    with pytest.raises(ValueError, match="xy has shape"):
        RecordedVehicle(1, [0.0, 0.1], [[0, 0]], [0, 0], [1, 1], 4.0, 2.0)
    with pytest.raises(ValueError, match="length must be a positive number"):
        _car(1, [0.0], 0.0, length=0.0)
    with pytest.raises(ValueError, match="vehicle id 1 appears twice"):
        Recording("r", (_car(1, [0.0], 0.0), _car(1, [0.0], 5.0)))
    with pytest.raises(ValueError, match="no vehicle 9; its vehicles are 1"):
        Recording("r", (_car(1, [0.0], 0.0),)).vehicle(9)


def test_default_ego_rule():
    t = np.round(np.arange(0.0, 2.05, 0.1), 3)
    crowd = [_car(10 + i, t, 30.0 + 6 * i, 3.5) for i in range(3)]  # near vehicle 2, far from vehicle 1
    rec = Recording("r", (
        _car(1, t, -150.0),  # recorded throughout, nobody within range
        _car(2, t, 20.0),  # recorded throughout, three neighbours
        _car(3, t[5:], 25.0),  # as near, but not recorded throughout
        _car(4, t, 22.0, length=EGO_MAX_LENGTH + 6.0, y=-3.5),  # a truck near them: not an ego
        *crowd,
    ))
    assert rec.pick_ego(100.0) == 2
    # a tie goes to the lowest id
    assert Recording("r", (_car(7, t, 0.0), _car(5, t, 10.0))).pick_ego(100.0) == 5
    # nobody recorded throughout: the longest-recorded
    assert Recording("r", (_car(1, t[:5], 0.0), _car(2, t[3:], 10.0))).pick_ego(100.0) == 2


def test_planning_problem_as_the_file_writes_it():
    """The planning problem against the file's own XML (read with the standard library): initial state,
    goal rectangle (centre, and what lies in it) and the goal's time interval (steps x dt)."""
    import xml.etree.ElementTree as ET

    root = ET.fromstring(gzip.open(US101_3).read())
    pp = root.find("planningProblem")
    start, goal = pp.find("initialState"), pp.find("goalState")
    rect = goal.find("position/rectangle")
    dt = float(root.get("timeStepSize"))
    p = read_commonroad_recording(US101_3).planning
    assert p.id == int(pp.get("id"))
    assert (p.x, p.y, p.yaw, p.v, p.t) == pytest.approx((
        float(start.find("position/point/x").text), float(start.find("position/point/y").text),
        float(start.find("orientation/exact").text), float(start.find("velocity/exact").text), 0.0))
    assert p.goal_time == pytest.approx((float(goal.find("time/intervalStart").text) * dt,
                                         float(goal.find("time/intervalEnd").text) * dt))
    cx, cy = float(rect.find("center/x").text), float(rect.find("center/y").text)
    length, width, yaw = (float(rect.find(k).text) for k in ("length", "width", "orientation"))
    assert p.goal_center == pytest.approx((cx, cy), abs=1e-6)
    along, across = np.array([math.cos(yaw), math.sin(yaw)]), np.array([-math.sin(yaw), math.cos(yaw)])
    c = np.array([cx, cy])
    inside = [c, c + 0.45 * length * along, c - 0.45 * width * across]
    outside = [c + 0.55 * length * along, c + 0.55 * width * across, (0.0, 0.0)]
    assert p.reached(np.array(inside)).all() and not p.reached(np.array(outside)).any()


def test_planning_problem_checks_its_values():
    from sim.world.recording import PlanningProblem

    square = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]])
    p = PlanningProblem(1, 0.0, 0.0, 0.0, 0.0, 5.0, (square, square + [4.0, 0.0]), (1.0, 2.0))
    assert p.goal_center == pytest.approx((3.0, 1.0))  # two equal squares: the centroid between them
    assert p.reached(np.array([[1.0, 1.0], [5.0, 1.0], [3.0, 1.0]])).tolist() == [True, True, False]
    assert PlanningProblem(2, 0.0, 0.0, 0.0, 0.0, 5.0).goal_center is None
    with pytest.raises(ValueError, match="initial v is nan"):
        PlanningProblem(3, 0.0, 0.0, 0.0, 0.0, math.nan)
    with pytest.raises(ValueError, match=r"goal polygon needs \(k >= 3, 2\)"):
        PlanningProblem(4, 0.0, 0.0, 0.0, 0.0, 1.0, (square[:2],))
    with pytest.raises(ValueError, match="ends before it starts"):
        PlanningProblem(5, 0.0, 0.0, 0.0, 0.0, 1.0, (), (2.0, 1.0))
