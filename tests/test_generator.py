"""Tests of sim/world/generator.py: valid, varied, reproducible random scenarios."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from sim import ScenarioSpec, load_scenario
from sim.world.generator import MIN_BUMPER_GAP, ROAD_SELF_CLEARANCE, draw_traffic, realize, self_clearance
from sim.world.scenario import GeneratorSpec, LaneChange, ScenarioError, parse_scenario
from sim.world.world import World
from tracker import Road

SEEDS = range(50)


@pytest.fixture(scope="module")
def random_road() -> ScenarioSpec:
    return load_scenario("random-road")


@pytest.fixture(scope="module")
def drawn(random_road: ScenarioSpec) -> list[ScenarioSpec]:
    return [realize(random_road, seed) for seed in SEEDS]


def test_fifty_seeds_give_valid_concrete_scenarios(random_road: ScenarioSpec, drawn: list[ScenarioSpec]) -> None:
    gen = random_road.generator
    assert gen is not None
    for seed, spec in zip(SEEDS, drawn):
        assert spec.concrete and spec.name == f"random-road-seed{seed}"
        assert spec.duration == random_road.duration
        # the plain-data form validates again (so the spec is what a file with that content gives)
        again = parse_scenario(spec.model_dump(exclude_none=True))
        assert again.model_dump() == spec.model_dump()
        road = spec.build_road()
        kappa = np.abs(road.curvature(np.linspace(0.0, road.length, 3000)))
        assert kappa.max() <= 1.0 / gen.radius[0] + 1e-9
        assert gen.lanes[0] <= spec.road.lanes <= gen.lanes[1]
        assert len(spec.vehicles) <= gen.vehicles[1]
        for v in spec.vehicles:
            assert gen.speed[0] <= v.speed <= gen.speed[1]
            assert gen.length[0] <= v.length <= gen.length[1] and gen.width[0] <= v.width <= gen.width[1]
            assert gen.spawn[0] - 1e-6 <= v.s - spec.ego.s <= gen.spawn[1] + 1e-6
            for m in v.maneuvers:
                assert m.t < spec.duration
                if isinstance(m, LaneChange):
                    assert m.wait_for_gap
        # the road never comes back within its width plus ROAD_SELF_CLEARANCE of itself
        width = spec.road.lanes * spec.road.lane_width
        assert self_clearance(road, width + ROAD_SELF_CLEARANCE) >= width + ROAD_SELF_CLEARANCE
        # same-lane neighbours keep MIN_BUMPER_GAP between bumpers
        cars = [spec.ego, *spec.vehicles]
        for i, a in enumerate(cars):
            for b in cars[i + 1 :]:
                if a.lane == b.lane:
                    assert abs(a.s - b.s) >= 0.5 * (a.length + b.length) + MIN_BUMPER_GAP - 1e-3


def test_the_seeds_are_varied(drawn: list[ScenarioSpec]) -> None:
    lengths = {round(s.build_road().length, 3) for s in drawn}
    assert len(lengths) == len(drawn)  # every seed draws a different road
    assert {s.road.lanes for s in drawn} == {2, 3}
    counts = [len(s.vehicles) for s in drawn]
    assert min(counts) <= 4 and max(counts) == 8
    behaviours = {v.behaviour for s in drawn for v in s.vehicles}
    assert behaviours == {"idm", "scripted"}
    kinds = {type(m).__name__ for s in drawn for v in s.vehicles for m in v.maneuvers}
    assert kinds == {"LaneChange", "SpeedChange"}
    signs = {np.sign(seg[1]) for s in drawn for seg in s.road.segments if seg[1] == seg[2] and seg[1] != 0}
    assert signs == {-1.0, 1.0}  # left and right bends
    headings = [s.road.start[2] for s in drawn]
    assert np.std(headings) > 1.0


def test_same_seed_same_scenario(random_road: ScenarioSpec, drawn: list[ScenarioSpec]) -> None:
    assert realize(random_road, 3).model_dump() == drawn[3].model_dump()
    assert realize(random_road, 4).model_dump() != drawn[3].model_dump()


def test_a_few_drawn_scenarios_run_cleanly(drawn: list[ScenarioSpec]) -> None:
    for spec in drawn[:4]:
        world = World(spec)
        for t in np.arange(0.5, 5.01, 0.5):
            snap = world.truth_at(float(t))
            assert np.all(world.road.on_road(snap.xy))
        assert world.collisions == []


def test_world_realizes_a_generator_spec(random_road: ScenarioSpec, drawn: list[ScenarioSpec]) -> None:
    world = World(random_road, seed=5)
    assert world.spec.model_dump() == drawn[5].model_dump()


def test_fixed_road_random_traffic(tmp_path: Path) -> None:
    path = tmp_path / "traffic.toml"
    path.write_text(
        'name = "t"\ndescription = "d"\nduration = 10.0\n'
        "[road]\nlanes = 3\nsegments = [[800.0, 0.0, 0.0]]\n"
        "[generator]\nvehicles = [5, 5]\n"
    )
    spec = load_scenario(path)
    a, b = realize(spec, 0), realize(spec, 1)
    assert a.road == spec.road == b.road
    assert [v.s for v in a.vehicles] != [v.s for v in b.vehicles]


def test_fixed_traffic_random_road(tmp_path: Path) -> None:
    path = tmp_path / "road.toml"
    path.write_text(
        'name = "r"\ndescription = "d"\nduration = 10.0\n'
        "[ego]\nlane = 0\ns = 30.0\nspeed = 20.0\n"
        "[[vehicles]]\nlane = 1\ns = 50.0\nspeed = 20.0\n"
        "[generator]\nlanes = [2, 2]\n"
    )
    spec = load_scenario(path)
    a = realize(spec, 0)
    assert a.ego == spec.ego and a.vehicles == spec.vehicles
    assert a.road.segments != realize(spec, 1).road.segments


def test_fixed_traffic_random_road_draws_enough_lanes(tmp_path: Path) -> None:
    path = tmp_path / "lanes.toml"
    body = (
        'name = "l"\ndescription = "d"\nduration = 10.0\n'
        "[ego]\nlane = 2\ns = 30.0\nspeed = 20.0\n"
        "[generator]\nlanes = [{lo}, {hi}]\n"
    )
    path.write_text(body.format(lo=2, hi=4))
    spec = load_scenario(path)
    lanes = {realize(spec, seed).road.lanes for seed in range(12)}
    assert lanes <= {3, 4} and len(lanes) == 2  # never 2: lane 2 must exist
    path.write_text(body.format(lo=1, hi=2))
    with pytest.raises(ScenarioError, match="cannot hold lane 2"):
        realize(load_scenario(path), 0)


def test_generator_errors(tmp_path: Path) -> None:
    path = tmp_path / "bad.toml"
    path.write_text('name = "b"\ndescription = "d"\nduration = 10.0\n[generator]\nspeed = [30.0, 10.0]\n')
    with pytest.raises(ScenarioError, match=r"bad.toml: generator.speed = \[30.0, 10.0\]: low must be <= high"):
        load_scenario(path)
    path.write_text('name = "b"\ndescription = "d"\nduration = 10.0\n[generator]\nradius = [10.0, 50.0]\n')
    with pytest.raises(ScenarioError, match=r"generator.radius .* radii must be >= 20.0 m"):
        load_scenario(path)
    path.write_text('name = "b"\ndescription = "d"\nduration = 10.0\n[generator]\nvehicle = [1, 2]\n')
    with pytest.raises(ScenarioError, match=r"generator.vehicle = \[1, 2\]: unknown key; allowed keys here: .*vehicles"):
        load_scenario(path)
    with pytest.raises(ValueError, match="seed must be a non-negative integer"):
        realize(load_scenario("random-road"), -1)


# -- vehicle classes --------------------------------------------------------------------------------
def test_without_classes_the_draws_are_unchanged(random_road: ScenarioSpec) -> None:
    """No ``classes``: seed 0 draws exactly the traffic it drew before classes existed (pinned)."""
    spec = realize(random_road, 0)
    assert spec.ego.s == 70.0 and spec.ego.speed == 19.091 and spec.ego.lane == 0
    assert [(v.lane, v.s, v.speed, v.length, v.width, v.behaviour) for v in spec.vehicles] == [
        (1, 151.132, 20.817, 4.661, 1.993, "scripted"),
        (0, 116.672, 17.747, 4.623, 2.074, "idm"),
        (1, 77.554, 20.578, 4.902, 1.758, "scripted"),
        (0, 164.859, 12.62, 5.071, 1.852, "idm"),
    ]


CLASSES = {
    "car": ((4.2, 5.2), (1.7, 2.1), 0.6),
    "van": ((6.0, 6.0), (2.1, 2.1), 0.1),
    "truck": ((10.0, 16.0), (2.5, 2.5), 0.2),
    "motorcycle": ((2.2, 2.2), (0.8, 0.8), 0.1),
}


def _classed_generator(**extra: object) -> GeneratorSpec:
    classes = [{"name": k, "length": list(L), "width": list(W), "share": p} for k, (L, W, p) in CLASSES.items()]
    return GeneratorSpec.model_validate({"classes": classes, "lane_width": 3.75, **extra})


def _class_of(length: float, width: float) -> str:
    found = [k for k, (L, W, _) in CLASSES.items() if L[0] <= length <= L[1] and W[0] <= width <= W[1]]
    assert len(found) == 1, (length, width)
    return found[0]


def test_classes_are_drawn_with_their_shares() -> None:
    """4000 drawn vehicles: each class's frequency is within 4.5 binomial standard deviations of its
    share, and every vehicle's size lies in its class's ranges."""
    gen = _classed_generator(vehicles=[100, 100], spawn=[-50.0, 6000.0])
    rng = np.random.default_rng(7)
    drawn: list[str] = []
    while len(drawn) < 4000:
        _, vehicles = draw_traffic(gen, rng, 3, 7000.0, False, 10.0, 100.0)
        drawn += [_class_of(v["length"], v["width"]) for v in vehicles]
    drawn = drawn[:4000]
    for name, (_, _, share) in CLASSES.items():
        freq = drawn.count(name) / len(drawn)
        assert abs(freq - share) < 4.5 * math.sqrt(share * (1 - share) / len(drawn)), (name, freq, share)
    trucks = [v for v in drawn if v == "truck"]
    assert len(trucks) > 600


def test_classes_in_a_scenario_file_are_reproducible_and_valid() -> None:
    spec = load_scenario("mixed-traffic")
    names = {c.name: c for c in spec.generator.classes}
    sizes = set()
    for seed in range(6):
        a = realize(spec, seed)
        assert a.model_dump() == realize(spec, seed).model_dump()  # same seed, same traffic
        for v in a.vehicles:
            cls = [c for c in names.values() if c.length[0] <= v.length <= c.length[1] and c.width[0] <= v.width <= c.width[1]]
            assert cls, (seed, v.length, v.width)
            sizes.add(cls[0].name)
    assert {"car", "truck"} <= sizes
    assert realize(spec, 0).model_dump() != realize(spec, 1).model_dump()


def test_long_drawn_vehicles_keep_the_bumper_gap() -> None:
    gen = _classed_generator(vehicles=[12, 12], spawn=[-60.0, 200.0])
    for seed in range(10):
        ego, vehicles = draw_traffic(gen, np.random.default_rng(seed), 2, 2000.0, False, 10.0, 100.0)
        cars = [ego, *vehicles]
        for i, a in enumerate(cars):
            for b in cars[i + 1 :]:
                if a["lane"] == b["lane"]:
                    assert abs(a["s"] - b["s"]) >= 0.5 * (a["length"] + b["length"]) + MIN_BUMPER_GAP - 1e-3


def test_drawn_classes_carry_their_heights() -> None:
    """A class's height (given, or the default of its name) goes to each drawn vehicle; the draws are
    those of the same classes without heights (a height draws nothing)."""
    gen = _classed_generator(vehicles=[30, 30], spawn=[-50.0, 3000.0])
    _, vehicles = draw_traffic(gen, np.random.default_rng(3), 3, 4000.0, False, 10.0, 100.0)
    named = {c.name: c.height_of(4.8) for c in gen.classes}
    for v in vehicles:
        name = _class_of(v["length"], v["width"])
        assert v["height"] == named[name], (name, v)
    assert {"car": 1.5, "truck": 3.5} == {k: named[k] for k in ("car", "truck")}
    given = GeneratorSpec.model_validate({**gen.model_dump(exclude={"length", "width"}),
                                          "classes": [{**c.model_dump(), "height": 2.4} for c in gen.classes]})
    _, same = draw_traffic(given, np.random.default_rng(3), 3, 4000.0, False, 10.0, 100.0)
    assert [(v["length"], v["width"], v["s"]) for v in same] == [(v["length"], v["width"], v["s"]) for v in vehicles]
    assert {v["height"] for v in same} == {2.4}


# -- roads that wind back onto themselves ------------------------------------------------------------
def test_self_clearance_finds_a_road_that_comes_back_onto_itself() -> None:
    """A 180 deg turn of radius 20 m between two parallel 100 m straights: the straights run 40 m
    apart, so they come within 40 m of each other (the turn's own points never count: along an arc a
    chord is at least 2 / pi of its length) but not within 30 m; a straight road never does."""
    kappa = 1.0 / 20.0
    hairpin = Road.from_curvature([(100.0, 0.0, 0.0), (math.pi * 20.0, kappa, kappa), (100.0, 0.0, 0.0)], lanes=2)
    assert self_clearance(hairpin, 30.0) == math.inf
    assert abs(self_clearance(hairpin, 45.0) - 40.0) < 0.05
    assert self_clearance(Road.from_curvature([(500.0, 0.0, 0.0)], lanes=2), 45.0) == math.inf


def test_drawn_roads_never_overlap_themselves() -> None:
    """mixed-traffic's generator (radius down to 50 m) drew a road that crossed itself on seed 17 and
    one whose centerline ran 9 m from itself (with 11 m of lanes) on seed 1: one place then had two
    Frenet coordinates, and tracks appeared on the other branch. Now every drawn road keeps its width
    plus ROAD_SELF_CLEARANCE between its parts; a generator whose tight curves cannot keep it is an
    error that says what to change."""
    spec = load_scenario("mixed-traffic")
    for seed in (1, 17):
        drawn = realize(spec, seed)
        road = drawn.build_road()
        need = drawn.road.lanes * drawn.road.lane_width + ROAD_SELF_CLEARANCE
        assert self_clearance(road, need) >= need
    tight = parse_scenario({"name": "tight", "description": "d", "duration": 60.0,
                            "generator": {"radius": [20.0, 21.0], "straight_length": [1.0, 2.0],
                                          "arc_length": [200.0, 250.0], "ramp_length": [1.0, 2.0]}})
    with pytest.raises(ScenarioError, match=r"drawn roads .* all came back within .* of themselves .*generator.radius"):
        realize(tight, 0)


# -- two-way roads ------------------------------------------------------------------------------------
def test_generator_draws_two_way_roads_with_oncoming_traffic() -> None:
    # one oncoming lane (the leftmost): the ego drives along s, the vehicles drawn into the oncoming lane
    # are placed oncoming_spawn ahead of the ego and change lanes only among lanes of their direction
    spec = parse_scenario({"name": "two-way", "description": "drawn two-way roads", "duration": 10.0,
                           "generator": {"lanes": [2, 3], "oncoming": [1, 1], "vehicles": [6, 8]}})
    against = 0
    for seed in range(8):
        drawn = realize(spec, seed)
        road = drawn.build_road()
        lanes = road.lanes
        assert drawn.road.oncoming == 1 and road.lane_directions.tolist() == [1] * (lanes - 1) + [-1]
        assert drawn.ego.lane < lanes - 1
        for v in drawn.vehicles:
            changes = [m.lane for m in v.maneuvers if isinstance(m, LaneChange)]
            if v.lane == lanes - 1:
                against += 1
                assert 40.0 <= v.s - drawn.ego.s <= 400.0 and changes == []
            else:
                assert all(k < lanes - 1 for k in changes)
        again = parse_scenario(drawn.model_dump(exclude_none=True))
        assert again.model_dump() == drawn.model_dump()
    assert against >= 8
    world = World(spec, 0)
    world.advance(10.0)
    assert world.collisions == []


def test_one_way_generators_are_unchanged_by_the_two_way_option() -> None:
    # the default oncoming = [0, 0] draws nothing for it: the same scenario as a generator without the key
    base = {"name": "g", "description": "drawn", "duration": 10.0, "generator": {"lanes": [2, 3]}}
    plain = realize(parse_scenario(base), 3)
    explicit = realize(parse_scenario({**base, "generator": {"lanes": [2, 3], "oncoming": [0, 0]}}), 3)
    assert plain.model_dump() == explicit.model_dump() and plain.road.oncoming == 0


@pytest.mark.parametrize(("generator", "road", "expected"), [
    ({"lanes": [2, 3], "oncoming": [1, 2]}, None, "generator.oncoming = [1, 2]: must lie within 0..1"),
    ({"oncoming": [1, 1]}, {"lanes": 2, "segments": [[500.0, 0.0, 0.0]]}, "generator.oncoming = [1, 1]: applies to drawn roads"),
])
def test_two_way_generator_errors(generator: dict, road: dict | None, expected: str) -> None:
    data = {"name": "g", "description": "drawn", "duration": 10.0, "generator": generator}
    if road is not None:
        data["road"] = road
    with pytest.raises(ScenarioError, match=re.escape(expected)):
        parse_scenario(data)
