"""Tests of sim/world/scenario.py: the shipped scenarios and suite, and clear errors for malformed files."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from sim import ScenarioSpec, load_scenario
from sim.cli import main
from sim.world.scenario import (
    SCENARIO_DIR,
    Brake,
    RoadSpec,
    ScenarioError,
    SpeedChange,
    apply_overrides,
    load_suite,
    parse_scenario,
)

STANDARD = ["curvy-multi", "chicane-follow", "curve-single", "cut-in", "occlusion", "dense-highway", "circuit",
            "oncoming-winding"]

GOOD = """
name = "tiny"
description = "two cars on a bend"
duration = 5.0

[road]
lanes = 2
lane_width = 3.5
segments = [[100.0, 0.0, 0.0], [50.0, 0.0, 0.01], [200.0, 0.01, 0.01]]

[ego]
lane = 0
s = 30.0
speed = 15.0

[[vehicles]]
lane = 1
s = 60.0
speed = 16.0
behaviour = "scripted"
maneuvers = [{ t = 1.0, kind = "lane_change", lane = 0, duration = 3.0 }]
"""


def write(tmp_path: Path, text: str, name: str = "case.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def load_error(tmp_path: Path, text: str) -> str:
    path = write(tmp_path, text)
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    message = str(info.value)
    assert str(path) in message, f"the error must name the file: {message}"
    return message


# -- the shipped files ---------------------------------------------------------------------------
@pytest.mark.parametrize("name", STANDARD)
def test_shipped_scenarios_load(name: str) -> None:
    spec = load_scenario(name)
    assert isinstance(spec, ScenarioSpec)
    assert spec.name == name
    assert spec.source == SCENARIO_DIR / f"{name}.toml"
    assert spec.description and "\n" not in spec.description
    assert spec.concrete and spec.road is not None and spec.ego is not None


def test_standard_suite_lists_its_eight_scenarios() -> None:
    suite = load_suite(SCENARIO_DIR / "standard.toml")
    assert suite.name == "standard"
    assert [p.stem for p in suite.paths] == STANDARD
    assert [s.name for s in suite.load()] == STANDARD


def test_scenario_requirements_of_the_issue() -> None:
    curvy = load_scenario("curvy-multi")
    kappa = np.abs(curvy.build_road().curvature(np.linspace(0, curvy.build_road().length, 2000)))
    assert 1 / kappa.max() == pytest.approx(60.0, rel=0.01)  # radius down to ~60 m
    assert len(curvy.vehicles) == 5
    dense = load_scenario("dense-highway")
    assert len(dense.vehicles) >= 15 and dense.road.lanes == 3
    assert load_scenario("circuit").build_road().closed
    chicane = load_scenario("chicane-follow")
    assert len(chicane.vehicles) == 1 and chicane.vehicles[0].speed == 18.0
    assert len(load_scenario("curve-single").vehicles) == 1


def test_eot_scenarios_lists_every_file(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["scenarios"]) == 0
    out = capsys.readouterr().out
    for name in STANDARD:
        spec = load_scenario(name)
        assert f"{name}  " in out and spec.description in out
    assert "suite standard" in out


# -- a good file and its defaults ----------------------------------------------------------------
def test_defaults_and_types(tmp_path: Path) -> None:
    spec = load_scenario(write(tmp_path, GOOD))
    ego, car = spec.ego, spec.vehicles[0]
    assert (ego.behaviour, ego.length, ego.width, ego.mobil) == ("idm", 4.8, 2.0, False)
    assert car.mobil is False and car.cruise_speed == 16.0
    assert car.maneuvers[0].duration == 3.0 and car.maneuvers[0].wait_for_gap is False
    assert spec.road.closed is False and spec.build_road().length == pytest.approx(350.0)
    assert spec.build_road() is spec.build_road()  # built once


def test_waypoint_road(tmp_path: Path) -> None:
    text = GOOD.replace(
        "segments = [[100.0, 0.0, 0.0], [50.0, 0.0, 0.01], [200.0, 0.01, 0.01]]",
        "waypoints = [[0, 0], [100, 0], [200, 20], [300, 60]]",
    )
    spec = load_scenario(write(tmp_path, text))
    assert spec.build_road().length > 300.0


# -- malformed files -----------------------------------------------------------------------------
def test_missing_field(tmp_path: Path) -> None:
    message = load_error(tmp_path, GOOD.replace("duration = 5.0\n", ""))
    assert "duration" in message and "missing" in message


def test_missing_vehicle_field(tmp_path: Path) -> None:
    message = load_error(tmp_path, GOOD.replace("speed = 16.0\n", ""))
    assert "vehicles[0].speed" in message and "missing" in message


def test_wrong_type(tmp_path: Path) -> None:
    message = load_error(tmp_path, GOOD.replace("speed = 15.0", 'speed = "fast"'))
    assert "ego.speed" in message and "'fast'" in message and "valid number" in message


def test_wrong_type_bool_for_int(tmp_path: Path) -> None:
    message = load_error(tmp_path, GOOD.replace("lanes = 2", "lanes = true"))
    assert "road.lanes" in message and "True" in message and "integer" in message


def test_unknown_key_lists_the_allowed_ones(tmp_path: Path) -> None:
    message = load_error(tmp_path, GOOD.replace("speed = 16.0", "speed = 16.0\nspead = 3.0"))
    assert "vehicles[0].spead" in message and "unknown key" in message
    assert "behaviour" in message and "maneuvers" in message  # the allowed keys are listed


def test_unknown_key_in_maneuver(tmp_path: Path) -> None:
    message = load_error(tmp_path, GOOD.replace("duration = 3.0 }", "duration = 3.0, lanes = 1 }"))
    assert "vehicles[0].maneuvers[0].lanes" in message and "unknown key" in message and "wait_for_gap" in message


def test_unknown_top_level_key(tmp_path: Path) -> None:
    message = load_error(tmp_path, "seed = 3\n" + GOOD)
    assert "seed" in message and "unknown key" in message and "generator" in message


def test_lane_out_of_range(tmp_path: Path) -> None:
    message = load_error(tmp_path, GOOD.replace("lane = 1\ns = 60.0", "lane = 2\ns = 60.0"))
    assert "vehicles[0].lane = 2" in message and "lanes 0..1" in message


def test_maneuver_lane_out_of_range(tmp_path: Path) -> None:
    message = load_error(tmp_path, GOOD.replace('kind = "lane_change", lane = 0', 'kind = "lane_change", lane = 5'))
    assert "vehicles[0].maneuvers[0].lane = 5" in message and "lanes 0..1" in message


def test_vehicles_overlapping_at_start(tmp_path: Path) -> None:
    message = load_error(tmp_path, GOOD.replace("lane = 1\ns = 60.0", "lane = 0\ns = 33.0"))
    assert "vehicles[0].s = 33.0" in message and "overlaps ego" in message


def test_start_clearance_is_half_a_metre(tmp_path: Path) -> None:
    # side by side in adjacent lanes is fine; nose to tail needs 0.5 m between bumpers (4.8 m cars)
    load_scenario(write(tmp_path, GOOD.replace("lane = 1\ns = 60.0", "lane = 1\ns = 30.0"), "side.toml"))
    load_scenario(write(tmp_path, GOOD.replace("lane = 1\ns = 60.0", "lane = 0\ns = 35.35"), "gap.toml"))
    message = load_error(tmp_path, GOOD.replace("lane = 1\ns = 60.0", "lane = 0\ns = 35.25"))
    assert "vehicles[0].s = 35.25" in message and "0.5 m" in message


def test_bad_maneuver_kind(tmp_path: Path) -> None:
    message = load_error(tmp_path, GOOD.replace('kind = "lane_change"', 'kind = "teleport"'))
    assert "vehicles[0].maneuvers[0]" in message and "lane_change" in message and "teleport" in message


def test_maneuvers_need_scripted(tmp_path: Path) -> None:
    message = load_error(tmp_path, GOOD.replace('behaviour = "scripted"', 'behaviour = "idm"'))
    assert "scripted" in message


def test_bad_behaviour(tmp_path: Path) -> None:
    message = load_error(tmp_path, GOOD.replace('behaviour = "scripted"', 'behaviour = "aggressive"'))
    assert "vehicles[0].behaviour = 'aggressive'" in message and "'idm'" in message


def test_maneuver_after_the_end(tmp_path: Path) -> None:
    message = load_error(tmp_path, GOOD.replace("t = 1.0", "t = 9.0"))
    assert "maneuvers[0].t = 9.0" in message and "duration" in message


def test_negative_speed(tmp_path: Path) -> None:
    message = load_error(tmp_path, GOOD.replace("speed = 15.0", "speed = -1.0"))
    assert "ego.speed = -1.0" in message and "greater than or equal to 0" in message


def test_off_the_road(tmp_path: Path) -> None:
    message = load_error(tmp_path, GOOD.replace("s = 60.0", "s = 400.0"))
    assert "vehicles[0].s = 400.0" in message and "open road" in message


def test_ego_would_run_off_the_end(tmp_path: Path) -> None:
    message = load_error(tmp_path, GOOD.replace("duration = 5.0", "duration = 30.0"))
    assert "duration = 30.0" in message and "end of this open road" in message


def test_road_needs_one_description(tmp_path: Path) -> None:
    message = load_error(tmp_path, GOOD.replace("lane_width = 3.5", "lane_width = 3.5\nwaypoints = [[0, 0], [10, 0]]"))
    assert "exactly one of" in message


def test_too_tight_curvature(tmp_path: Path) -> None:
    message = load_error(tmp_path, GOOD.replace("[50.0, 0.0, 0.01]", "[50.0, 0.0, 0.2]"))
    assert "road.segments[1]" in message and "0.2" in message and "radius" in message


def test_closed_road_that_does_not_close(tmp_path: Path) -> None:
    message = load_error(tmp_path, GOOD.replace("lane_width = 3.5", "lane_width = 3.5\nclosed = true"))
    assert "road" in message and "does not close" in message


def test_toml_syntax_error(tmp_path: Path) -> None:
    message = load_error(tmp_path, GOOD.replace("duration = 5.0", "duration = = 5.0"))
    assert "not valid TOML" in message


def test_several_problems_are_all_reported(tmp_path: Path) -> None:
    message = load_error(tmp_path, GOOD.replace("speed = 15.0", 'speed = "x"').replace("lanes = 2", "lanes = 0"))
    assert "2 problems" in message and "ego.speed" in message and "road.lanes" in message


def test_missing_file() -> None:
    with pytest.raises(ScenarioError, match="no such scenario file"):
        load_scenario("no-such-scenario")


def test_suite_with_missing_member(tmp_path: Path) -> None:
    path = write(tmp_path, 'name = "s"\ndescription = "d"\nscenarios = ["nope.toml"]\n', "suite.toml")
    with pytest.raises(ScenarioError, match=r"scenarios\[0\] = 'nope.toml'"):
        load_suite(path)


def test_parse_scenario_names_where() -> None:
    with pytest.raises(ScenarioError, match="^<here>: .*duration"):
        parse_scenario({"name": "x", "description": "y"}, "<here>")


# -- overrides ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Inner:
    rate: float = 1.0


@dataclass(frozen=True)
class _Config:
    noise: float = 0.1
    inner: _Inner = _Inner()

    def __post_init__(self) -> None:
        if not (isinstance(self.noise, float) and math.isfinite(self.noise) and self.noise >= 0):
            raise ValueError(f"noise must be >= 0; got {self.noise!r}")


def test_apply_overrides() -> None:
    cfg = apply_overrides(_Config(), {"noise": 0.5, "inner": {"rate": 2.0}}, "f.toml: sensors")
    assert cfg == _Config(0.5, _Inner(2.0))
    with pytest.raises(ScenarioError, match=r"f.toml: sensors.nois = 0.5: unknown key; allowed keys here: inner, noise"):
        apply_overrides(_Config(), {"nois": 0.5}, "f.toml: sensors")
    with pytest.raises(ScenarioError, match="noise must be >= 0"):
        apply_overrides(_Config(), {"noise": -1.0}, "f.toml: sensors")


# -- the hard suite and the vehicle sizes and maneuvers it needs ----------------------------------
HARD = ["truck-hairpin", "emergency-brake", "hard-accel", "stop-and-go", "standing-vehicle", "mixed-traffic", "urban-parked"]


def test_hard_suite_lists_its_scenarios_and_is_not_standard(capsys: pytest.CaptureFixture[str]) -> None:
    suite = load_suite("hard")
    assert suite.name == "hard" and [p.stem for p in suite.paths] == HARD
    specs = suite.load()
    assert [s.name for s in specs] == HARD
    assert all(15.0 <= s.duration <= 20.0 and "\n" not in s.description for s in specs)
    assert not set(HARD) & set(STANDARD)
    assert main(["scenarios"]) == 0
    out = capsys.readouterr().out
    assert "suite hard (hard.toml)" in out and all(f"{name}  " in out for name in HARD)


def test_hard_suite_covers_the_vehicles_and_maneuvers_of_the_issue() -> None:
    specs = {s.name: s for s in load_suite("hard").load()}
    vehicles = [v for s in specs.values() for v in s.vehicles]
    sizes = {(v.length, v.width) for v in vehicles}
    assert any(8.0 <= length <= 18.0 and width == 2.5 for length, width in sizes)  # trucks and buses
    assert max(length for length, _ in sizes) == 18.0
    assert (6.0, 2.1) in sizes and (2.2, 0.8) in sizes  # a van, a motorcycle
    brakes = [m for v in vehicles for m in v.maneuvers if isinstance(m, Brake)]
    assert any(m.speed == 0.0 and 6.0 <= m.decel <= 8.0 for m in brakes)  # emergency stops
    speedups = [m for v in vehicles for m in v.maneuvers if isinstance(m, SpeedChange)]
    assert any(m.accel == 3.0 and m.speed >= 22.0 for m in speedups)  # hard acceleration
    stop_and_go = specs["stop-and-go"]
    assert max(sum(isinstance(m, Brake) and m.speed == 0.0 for m in v.maneuvers) for v in stop_and_go.vehicles) >= 2
    assert any(v.behaviour == "constant" and v.speed == 0.0 for v in specs["standing-vehicle"].vehicles)
    radii = {}
    for name, spec in specs.items():
        if spec.road is not None:
            road = spec.build_road()
            radii[name] = 1.0 / np.abs(road.curvature(np.linspace(0.0, road.length, 4000))).max()
    assert radii["truck-hairpin"] == pytest.approx(40.0, rel=0.01) and radii["stop-and-go"] == pytest.approx(50.0, rel=0.01)
    classes = specs["mixed-traffic"].generator.classes
    assert {c.name for c in classes} == {"car", "van", "truck", "bus", "motorcycle"}


def test_vehicle_sizes_and_standing_vehicles(tmp_path: Path) -> None:
    text = GOOD + '\n[[vehicles]]\nlane = 0\ns = 120.0\nspeed = 0.0\nbehaviour = "constant"\nlength = 2.2\nwidth = 0.8\n'
    text += '\n[[vehicles]]\nlane = 1\ns = 160.0\nspeed = 10.0\nlength = 18.0\nwidth = 2.5\n'
    spec = load_scenario(write(tmp_path, text))
    moto, bus = spec.vehicles[1], spec.vehicles[2]
    assert (moto.length, moto.width, moto.speed, moto.max_speed()) == (2.2, 0.8, 0.0, 0.0)
    assert (bus.length, bus.width) == (18.0, 2.5)
    message = load_error(tmp_path, text.replace("width = 0.8", "width = 0.5"))
    assert "vehicles[1].width = 0.5" in message and "greater than or equal to 0.6" in message
    message = load_error(tmp_path, text.replace("length = 18.0", "length = 21.0"))
    assert "vehicles[2].length = 21.0" in message and "less than or equal to 20" in message
    # a long vehicle's rectangle counts for the start clearance: a bus centred 11 m behind a car overlaps it
    message = load_error(tmp_path, text.replace("s = 160.0", "s = 71.0"))
    assert "vehicles[2].s = 71.0: its rectangle overlaps vehicles[0]'s" in message


def test_brake_and_speed_change_limits(tmp_path: Path) -> None:
    ok = GOOD.replace('{ t = 1.0, kind = "lane_change", lane = 0, duration = 3.0 }',
                      '{ t = 1.0, kind = "brake", decel = 8.0 }, { t = 3.0, kind = "speed", speed = 22.0, accel = 3.0 }')
    brake, speed = load_scenario(write(tmp_path, ok)).vehicles[0].maneuvers
    assert isinstance(brake, Brake) and (brake.speed, brake.decel) == (0.0, 8.0)
    assert isinstance(speed, SpeedChange) and (speed.speed, speed.accel) == (22.0, 3.0)
    message = load_error(tmp_path, ok.replace("decel = 8.0", "decel = 9.5"))
    assert "vehicles[0].maneuvers[0].decel = 9.5" in message and "less than or equal to 9" in message
    message = load_error(tmp_path, ok.replace("accel = 3.0", "accel = 0.0"))
    assert "vehicles[0].maneuvers[1].accel = 0.0" in message and "greater than 0" in message


# -- generator vehicle classes --------------------------------------------------------------------
GENERATED = 'name = "g"\ndescription = "d"\nduration = 10.0\n[generator]\n'
CLASSES = (
    'classes = [{ name = "car", length = [4.2, 5.2], width = 2.0, share = 0.7 },'
    ' { name = "truck", length = [10.0, 16.0], width = 2.5, share = 0.3 }]\n'
)


def test_generator_classes_parse(tmp_path: Path) -> None:
    gen = load_scenario(write(tmp_path, GENERATED + CLASSES)).generator
    car, truck = gen.classes
    assert (car.name, car.length, car.width, car.share) == ("car", (4.2, 5.2), (2.0, 2.0), 0.7)
    assert (truck.length, truck.width) == ((10.0, 16.0), (2.5, 2.5))
    cumulative, lengths, widths = gen.class_bounds()
    np.testing.assert_allclose(cumulative, [0.7, 1.0])
    assert cumulative[-1] == 1.0
    np.testing.assert_array_equal(lengths, [[4.2, 5.2], [10.0, 16.0]])
    np.testing.assert_array_equal(widths, [[2.0, 2.0], [2.5, 2.5]])
    assert load_scenario("random-road").generator.classes is None


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        (("share = 0.3", "share = 0.25"), r"generator.classes share: the shares sum to 0.95 \(car 0.7, truck 0.25\); they must sum to 1"),
        (("share = 0.3 }", "share = 0.3, colour = \"red\" }"), r"generator.classes\[1\].colour = 'red': unknown key; allowed keys here: name, length, width, share"),
        (("share = 0.7", "share = 0.0"), r"generator.classes\[0\].share = 0.0: input should be greater than 0"),
        (("[10.0, 16.0]", "[16.0, 10.0]"), r"generator.classes\[1\].length = \[16.0, 10.0\]: low must be <= high"),
        (("[10.0, 16.0]", "22.0"), r"generator.classes\[1\].length = 22.0: must lie within \[2.0, 20.0\] m"),
        (("[10.0, 16.0]", "\"long\""), r"generator.classes\[1\].length = 'long': must be a float"),
        (("width = 2.5", "width = 3.2"), r"generator.classes\[1\].width = 3.2: must lie within \[0.6, 3.0\] m"),
        (("name = \"truck\"", "name = \"car\""), r"generator.classes\[1\].name = 'car': class names must be unique"),
        (("width = 2.0,", ""), r"generator.classes\[0\].width: missing"),
    ],
)
def test_generator_class_errors_name_the_field(tmp_path: Path, change: tuple[str, str], expected: str) -> None:
    message = load_error(tmp_path, GENERATED + CLASSES.replace(*change))
    assert re.search(expected, message), message


def test_generator_classes_exclude_length_and_fit_the_lanes(tmp_path: Path) -> None:
    message = load_error(tmp_path, GENERATED + "length = [4.0, 5.0]\n" + CLASSES)
    assert "generator.length: not used when generator.classes is given" in message
    message = load_error(tmp_path, GENERATED + "lane_width = 2.8\n" + CLASSES)
    assert "generator.classes[1].width = 2.5: widths must leave 0.5 m in a 2.8 m lane" in message
    fixed_road = 'name = "g"\ndescription = "d"\nduration = 10.0\n[road]\nlanes = 2\nlane_width = 2.8\nsegments = [[500.0, 0.0, 0.0]]\n'
    message = load_error(tmp_path, fixed_road + "[generator]\n" + CLASSES)
    assert "generator.classes[1].width = 2.5: must be <= 2.3 m (this road's lane width - 0.5 m)" in message


def test_vehicle_heights_default_by_class_and_can_be_given(tmp_path: Path) -> None:
    """Heights for the 3-D lidar: by length when not given (motorcycle 1.2, car 1.5, van 2.0, truck
    3.5 m), as given otherwise, and bounded."""
    text = GOOD + '\n[[vehicles]]\nlane = 0\ns = 120.0\nspeed = 10.0\nlength = 2.2\nwidth = 0.8\n'
    text += '\n[[vehicles]]\nlane = 1\ns = 160.0\nspeed = 10.0\nlength = 6.0\nwidth = 2.1\n'
    text += '\n[[vehicles]]\nlane = 0\ns = 200.0\nspeed = 10.0\nlength = 12.0\nwidth = 2.5\n'
    text += '\n[[vehicles]]\nlane = 1\ns = 240.0\nspeed = 10.0\nlength = 12.0\nwidth = 2.5\nheight = 4.2\n'
    spec = load_scenario(write(tmp_path, text))
    assert [v.box_height for v in spec.vehicles] == [1.5, 1.2, 2.0, 3.5, 4.2]
    message = load_error(tmp_path, text.replace("height = 4.2", "height = 5.5"))
    assert "vehicles[4].height = 5.5" in message and "less than or equal to 5" in message


def test_road_grade_and_bank(tmp_path: Path) -> None:
    text = GOOD.replace("lane_width = 3.5\n", "lane_width = 3.5\ngrade = 0.04\nbank = -0.03\n")
    spec = load_scenario(write(tmp_path, text))
    assert (spec.road.grade, spec.road.bank) == (0.04, -0.03)
    assert spec.road.to_config()["grade"] == 0.04
    assert "grade" not in load_scenario(write(tmp_path, GOOD)).road.to_config()  # a level road's data is unchanged
    message = load_error(tmp_path, text.replace("grade = 0.04", "grade = 0.2"))
    assert "road.grade = 0.2" in message and "less than or equal to 0.15" in message
    closed = load_error(tmp_path, load_scenario("circuit").source.read_text().replace("[road]\n", "[road]\ngrade = 0.01\n"))
    assert "road.grade = 0.01: a closed road cannot climb" in closed


# -- two-way roads and parking lanes --------------------------------------------------------------
TWO_WAY = GOOD.replace("lane_width = 3.5\n", "lane_width = 3.5\noncoming = 1\n").replace(
    'behaviour = "scripted"\nmaneuvers = [{ t = 1.0, kind = "lane_change", lane = 0, duration = 3.0 }]\n', "")
PARKED = TWO_WAY.replace("oncoming = 1\n", 'oncoming = 1\nparking = "both"\n').replace("lane = 1\ns = 60.0", "lane = 2\ns = 90.0").replace(
    "[ego]\nlane = 0", "[ego]\nlane = 1")


def test_two_way_road_lanes_and_directions(tmp_path: Path) -> None:
    spec = load_scenario(write(tmp_path, TWO_WAY))
    road = spec.build_road()
    assert road.two_way and road.lane_directions.tolist() == [1, -1] and road.lane_centers.tolist() == [-1.75, 1.75]
    left = RoadSpec.model_validate({**spec.road.to_config(), "drive_on": "left"})
    assert left.build().lane_directions.tolist() == [-1, 1]
    # parking lanes of 2.5 m outside the driving lanes, of the direction of their neighbour
    parked = load_scenario(write(tmp_path, PARKED)).build_road()
    assert parked.lanes == 4 and parked.layout.kinds == ("parking", "driving", "driving", "parking")
    assert parked.lane_directions.tolist() == [1, 1, -1, -1]
    assert parked.layout.boundaries[0].tolist() == [-6.0, -3.5, 0.0, 3.5, 6.0]
    assert (parked.right_edge, parked.left_edge) == (-6.0, 6.0)
    one_side = load_scenario(write(tmp_path, PARKED.replace('"both"', '"right"').replace("parking = ", "parking_width = 2.2\nparking = ")))
    assert one_side.build_road().layout.boundaries[0].tolist() == pytest.approx([-5.7, -3.5, 0.0, 3.5])


def test_road_config_round_trips_and_one_way_roads_keep_their_config(tmp_path: Path) -> None:
    left = {**load_scenario(write(tmp_path, PARKED)).road.to_config(), "drive_on": "left", "parking": "left"}
    for road in (load_scenario(write(tmp_path, TWO_WAY)).road, load_scenario(write(tmp_path, PARKED)).road,
                 RoadSpec.model_validate(left)):
        again = RoadSpec.model_validate(road.to_config())
        assert again == road and again.build().layout.boundaries.tolist() == road.build().layout.boundaries.tolist()
    one_way = load_scenario(write(tmp_path, GOOD)).road.to_config()
    assert set(one_way) == {"lanes", "lane_width", "closed", "segments"}


@pytest.mark.parametrize(("change", "expected"), [
    (("oncoming = 1", "oncoming = 3"), "road.oncoming = 3: at most road.lanes (2)"),
    (("oncoming = 1\n", 'drive_on = "left"\n'), "road.drive_on applies to two-way roads"),
    (("oncoming = 1\n", "oncoming = 1\nparking_width = 2.2\n"), "road.parking_width needs road.parking"),
    (("oncoming = 1\n", 'oncoming = 1\nparking = "middle"\n'), "road.parking = 'middle'"),
    (("speed = 16.0\n", 'speed = 16.0\nbehaviour = "scripted"\nmaneuvers = [{ t = 1.0, kind = "lane_change", lane = 0 }]\n'),
     ("vehicles[0].maneuvers[0].lane = 0: lane 0 carries traffic along s and this vehicle's lane 1 against s; "
      "lane changes stay within one direction")),
    (("speed = 16.0\n", 'speed = 16.0\nfacing = "backward"\n'), 'facing = "backward" (against the lane\'s traffic) needs a standing vehicle'),
])
def test_two_way_errors_are_one_line(tmp_path: Path, change: tuple[str, str], expected: str) -> None:
    message = load_error(tmp_path, TWO_WAY.replace(*change, 1))
    assert expected in message and "\n" not in message


def test_parking_lane_rules(tmp_path: Path) -> None:
    parked = '\n[[vehicles]]\nlane = 0\ns = 60.0\nspeed = 0.0\nbehaviour = "constant"\nwidth = 1.8\nfacing = "backward"\n'
    spec = load_scenario(write(tmp_path, PARKED + parked))
    assert spec.vehicles[1].facing == "backward" and spec.vehicles[1].lane == 0
    # a standing vehicle in a driving lane is allowed; a moving one in a parking lane is not
    load_scenario(write(tmp_path, PARKED + parked.replace("lane = 0", "lane = 1")))
    message = load_error(tmp_path, PARKED + parked.replace("speed = 0.0", "speed = 5.0").replace(
        'behaviour = "constant"\n', "").replace('facing = "backward"\n', ""))
    assert "vehicles[1].speed = 5.0: lane 0 is a parking lane; a vehicle there must start standing" in message
    message = load_error(tmp_path, PARKED + parked.replace("width = 1.8", "width = 2.1"))
    assert "vehicles[1].width = 2.1: must be <= 2 m (the parking lane's width - 0.5 m)" in message
    message = load_error(tmp_path, PARKED.replace("[ego]\nlane = 1", "[ego]\nlane = 0\nwidth = 1.8"))
    assert "ego.lane = 0: lane 0 is a parking lane; the ego drives in a driving lane" in message
    # pulling out: a lane change from the parking lane into the driving lane of the same direction
    puller = parked.replace('behaviour = "constant"\n', 'behaviour = "scripted"\n').replace('facing = "backward"\n', "")
    puller += 'maneuvers = [{ t = 1.0, kind = "speed", speed = 8.0 }, { t = 1.5, kind = "lane_change", lane = 1 }]\n'
    spec = load_scenario(write(tmp_path, PARKED + puller))
    assert spec.vehicles[1].maneuvers[1].lane == 1
    message = load_error(tmp_path, PARKED + puller.replace("lane = 1 }", "lane = 2 }"))
    assert "vehicles[1].maneuvers[1].lane = 2: lane 2 carries traffic against s" in message


def test_an_ego_driving_against_s_must_not_reach_the_start(tmp_path: Path) -> None:
    text = TWO_WAY.replace("[ego]\nlane = 0\ns = 30.0", "[ego]\nlane = 1\ns = 330.0").replace("lane = 1\ns = 60.0", "lane = 0\ns = 60.0")
    spec = load_scenario(write(tmp_path, text))
    assert spec.ego.lane == 1
    message = load_error(tmp_path, text.replace("s = 330.0", "s = 60.0").replace("lane = 0\ns = 60.0", "lane = 0\ns = 200.0"))
    assert "driving against s in lane 1) could reach s = " in message and "beyond the start of this open road" in message


def test_two_way_scenarios_have_what_they_are_designed_for() -> None:
    from sim.world.world import World

    # oncoming-winding: about 1 km, bends of R 80-200 m, one lane each way; every oncoming vehicle that
    # passes the ego does so at a closing speed of 25-35 m/s, and nothing collides
    spec = load_scenario("oncoming-winding")
    road = spec.build_road()
    arcs = sorted(1.0 / abs(k0) for _, k0, k1 in spec.road.segments if k0 == k1 != 0.0)  # the bends' radii (m)
    assert road.length == pytest.approx(1000.0) and arcs == pytest.approx([80.0, 100.0, 125.0, 200.0])
    assert road.lane_directions.tolist() == [1, -1] and spec.ego.lane == 0
    assert any(v.length == 12.0 and v.lane == 1 for v in spec.vehicles)
    world = World(spec)
    closest: dict[int, tuple[float, float]] = {}
    for t in np.arange(0.0, spec.duration + 1e-9, 0.1):
        snap = world.truth_at(float(t))
        d = np.hypot(*(snap.xy - (snap.ego.x, snap.ego.y)).T)
        for vid, dist, v, xi in zip(snap.ids.tolist(), d, snap.v, snap.xi):
            if np.cos(xi) < 0 and dist < closest.get(vid, (np.inf, 0.0))[0]:
                closest[vid] = (float(dist), float(v + snap.ego.v))
    passed = [closing for dist, closing in closest.values() if dist < 4.0]
    assert len(passed) == 6 and all(25.0 <= c <= 35.0 for c in passed) and world.collisions == []
    # urban-parked: 13-14 m/s, one lane each way and parking on both kerbs, parked cars on both, some
    # facing against the traffic, and a car that pulls out of the right kerb into the ego's lane
    spec = load_scenario("urban-parked")
    road = spec.build_road()
    assert road.layout.kinds == ("parking", "driving", "driving", "parking") and road.lane_directions.tolist() == [1, 1, -1, -1]
    parked = [v for v in spec.vehicles if v.behaviour == "constant" and v.speed == 0.0]
    assert {v.lane for v in parked} == {0, 3} and sum(v.facing == "backward" for v in parked) >= 4
    moving = [v for v in spec.vehicles if v.speed > 0.0] + [spec.ego]
    assert all(12.5 <= v.speed <= 14.0 for v in moving) and any(v.lane == 2 for v in moving)
    puller = next(v for v in spec.vehicles if v.behaviour == "scripted")
    assert puller.lane == 0 and puller.maneuvers[-1].lane == 1
    world = World(spec)
    world.advance(spec.duration)
    k = list(world.truth_at(spec.duration).ids).index(spec.vehicles.index(puller) + 1)
    assert abs(world.truth_at(spec.duration).n[k] - road.lane_center(1)) < 0.2 and world.collisions == []
