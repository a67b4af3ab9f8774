"""sim.world.families: every shipped family draws valid, different scenarios per seed (the same for the
same seed) whose conflicts have the drawn geometry, checked on the simulated world; bad [family]
tables get one-line errors naming the field."""

from __future__ import annotations

import numpy as np
import pytest

from sim.world.families import FAMILIES, check_family
from sim.world.generator import realize
from sim.world.scenario import (
    ScenarioError,
    load_scenario,
    load_suite,
    parse_scenario,
    resolve_scenario_path,
)
from sim.world.world import World

SUITE = [p.name for p in load_suite(resolve_scenario_path("closed-loop")).paths]


def family(name: str):
    return load_scenario(name)


def test_the_closed_loop_suite_holds_one_file_per_family():
    kinds = {family(p).family.kind for p in SUITE}
    assert kinds == set(FAMILIES)


@pytest.mark.parametrize("name", SUITE)
def test_each_seed_draws_a_new_valid_scenario_and_the_same_seed_the_same(name):
    spec = family(name)
    assert not spec.concrete
    drawn = [realize(spec, seed) for seed in range(8)]
    for seed, d in enumerate(drawn):
        assert d.concrete and d.name == f"{spec.name}-seed{seed}"
        assert d.hazard_t is not None and 0.0 <= d.hazard_t < spec.duration
    assert realize(spec, 3).model_dump() == drawn[3].model_dump()
    # road, ego speed and traffic all differ between seeds
    assert len({d.road.start[2] for d in drawn}) == 8
    assert len({d.ego.speed for d in drawn}) == 8
    assert len({tuple((v.lane, v.s) for v in d.vehicles) for d in drawn}) == 8


def _params(name: str) -> dict:
    return family(name).family.params


def test_cut_in_starts_its_lane_change_at_the_drawn_gap():
    """At the maneuver's time the cutter is ahead of the ego (which cruises: IDM with nothing ahead in its
    lane) by gap_s x the ego's speed, bumper to bumper; it is faster by speed_diff."""
    params = _params("family-cut-in")
    for seed in range(4):
        spec = realize(family("family-cut-in"), seed)
        cutter = spec.vehicles[0]
        t_cut = cutter.maneuvers[0].t
        assert params["cut_t"][0] <= t_cut <= params["cut_t"][1]
        assert params["speed_diff"][0] <= cutter.speed - spec.ego.speed <= params["speed_diff"][1]
        world = World(spec, seed)
        snap = world.truth_at(t_cut)
        ego_s = world.ego_state().s
        j = int(np.flatnonzero(snap.ids == 1)[0])
        gap = snap.s[j] - ego_s - 0.5 * (snap.length[j] + spec.ego.length)
        v = world.ego_state().v
        assert params["gap_s"][0] - 0.05 <= gap / v <= params["gap_s"][1] + 0.05, (seed, gap / v)
        assert abs(snap.n[j] - spec.build_road().lane_center(1)) < 0.05  # still in its lane


def test_cut_out_hides_a_standing_vehicle_behind_the_lead():
    params = _params("family-cut-out")
    for seed in range(4):
        spec = realize(family("family-cut-out"), seed)
        lead, standing = spec.vehicles[0], spec.vehicles[1]
        assert standing.speed == 0.0 and standing.behaviour == "constant" and standing.lane == lead.lane == spec.ego.lane
        assert spec.ego.s < lead.s < standing.s
        t_reveal = lead.maneuvers[0].t
        assert spec.hazard_t == pytest.approx(t_reveal, abs=1e-3)
        # designed: at the reveal the lead is reveal_ttc x its speed from the standing vehicle, bumpers apart
        designed = (standing.s - lead.s - 0.5 * (lead.length + standing.length) - lead.speed * t_reveal) / lead.speed
        assert params["reveal_ttc"][0] - 1e-6 <= designed <= params["reveal_ttc"][1] + 1e-6
        headway = (lead.s - spec.ego.s - 0.5 * (lead.length + spec.ego.length)) / spec.ego.speed
        assert params["headway"][0] - 1e-3 <= headway <= params["headway"][1] + 1e-3


def test_brake_behind_truck_orders_ego_truck_car():
    for seed in range(4):
        spec = realize(family("family-brake-behind-truck"), seed)
        truck, car = spec.vehicles[0], spec.vehicles[1]
        assert 10.0 <= truck.length <= 16.0 and truck.lane == car.lane == 0
        assert spec.ego.s < truck.s < car.s
        world = World(spec, seed)
        brake = car.maneuvers[0]
        v_before = world.truth_at(brake.t + 0.1).v[1]  # braking from the first 0.05 s step at or after t
        v_after = world.truth_at(brake.t + 1.0).v[1]
        assert v_before - v_after == pytest.approx(min(0.9 * brake.decel, v_before - brake.speed), abs=0.05)


def test_merge_fast_rear_puts_a_faster_vehicle_behind_in_the_next_lane():
    params = _params("family-merge-fast-rear")
    for seed in range(4):
        spec = realize(family("family-merge-fast-rear"), seed)
        slow, rear = spec.vehicles[0], spec.vehicles[1]
        assert slow.lane == 0 and rear.lane == 1 and slow.s > spec.ego.s > rear.s
        assert params["rear_speed_diff"][0] <= rear.speed - spec.ego.speed <= params["rear_speed_diff"][1]
        assert params["lead_speed_drop"][0] <= spec.ego.speed - slow.speed <= params["lead_speed_drop"][1]


def test_oncoming_vehicles_drive_against_s_on_a_two_way_road():
    for seed in range(3):
        spec = realize(family("family-oncoming"), seed)
        road = spec.build_road()
        assert road.lanes == 2 and list(road.lane_directions) == [1, -1]
        world = World(spec, seed)
        a, b = world.truth_at(0.0), world.truth_at(2.0)
        oncoming = [i for i, v in enumerate(spec.vehicles) if v.lane == 1]
        assert len(oncoming) >= 1
        for i in oncoming:
            j0, j1 = int(np.flatnonzero(a.ids == i + 1)[0]), int(np.flatnonzero(b.ids == i + 1)[0])
            assert b.s[j1] < a.s[j0] - 10.0  # against s


def test_lane_splitting_motorcycle_rides_on_the_line_between_the_lanes():
    """The motorcycle keeps its path on the line between lanes 0 and 1 (``offset`` = half a lane) while it
    passes the ego and the queue, without touching anyone."""
    for seed in range(3):
        spec = realize(family("family-lane-splitting"), seed)
        moto_id = next(i + 1 for i, v in enumerate(spec.vehicles) if v.offset != 0.0)
        moto = spec.vehicles[moto_id - 1]
        assert moto.width < 1.0 and moto.offset == pytest.approx(1.75)
        road = spec.build_road()
        line = 0.5 * (road.lane_center(0) + road.lane_center(1))
        world = World(spec, seed)
        for t in np.arange(0.0, spec.duration, 1.0):
            snap = world.truth_at(float(t))
            j = int(np.flatnonzero(snap.ids == moto_id)[0])
            assert abs(snap.n[j] - line) < 0.1, (seed, t, snap.n[j] - line)
        assert all(0 not in c[1:] and moto_id not in c[1:] for c in world.collisions), world.collisions


def test_family_tables_are_checked_with_one_line_errors():
    good = dict(_params("family-cut-in"))
    check_family("cut-in", good)
    cases = [
        ("cut-out-typo", good, "family.kind = 'cut-out-typo': not a family"),
        ("cut-in", {**good, "gap": (0.5, 1.0)}, "family.params.gap: not a parameter of 'cut-in'"),
        ("cut-in", {k: v for k, v in good.items() if k != "gap_s"}, "family.params.gap_s: missing"),
        ("cut-in", {**good, "gap_s": (1.5, 0.5)}, "family.params.gap_s = [1.5, 0.5]: low must be <= high"),
        ("cut-in", {**good, "gap_s": (0.0, 1.0)}, "family.params.gap_s = [0.0, 1.0]: must lie within [0.2, 5] s"),
        ("cut-in", {**good, "background": (1.0, 2.5)}, "family.params.background = [1.0, 2.5]: a count"),
        ("cut-in", {**good, "lanes": (1, 2)}, "family.params.lanes = [1, 2]: must lie within [2, 4] lanes"),
    ]
    for kind, params, message in cases:
        with pytest.raises(ValueError, match=None) as info:
            check_family(kind, params)
        assert message in str(info.value), str(info.value)


def test_a_family_file_with_its_own_road_or_traffic_is_an_error():
    data = {"name": "x", "description": "d", "duration": 10.0,
            "family": {"kind": "cut-in", "params": {k: list(v) for k, v in _params("family-cut-in").items()}}}
    parse_scenario(data)
    with pytest.raises(ScenarioError, match="road: a family draws its road and traffic per seed"):
        parse_scenario({**data, "road": {"lanes": 2, "segments": [[500.0, 0.0, 0.0]]}})
    with pytest.raises(ScenarioError, match="family.params.ego_speed: missing; give its range"):
        parse_scenario({**data, "family": {"kind": "cut-in", "params": {"radius": [100.0, 200.0]}}})
    with pytest.raises(ScenarioError, match="hazard_t = 12.0: must be < duration"):
        parse_scenario({"name": "x", "description": "d", "duration": 10.0, "hazard_t": 12.0,
                        "road": {"segments": [[500.0, 0.0, 0.0]]}, "ego": {"lane": 0, "s": 20.0, "speed": 10.0}})


def test_vehicle_offset_is_bounded_by_half_the_lane():
    base = {"name": "x", "description": "d", "duration": 5.0, "road": {"segments": [[500.0, 0.0, 0.0]]},
            "ego": {"lane": 0, "s": 20.0, "speed": 10.0}}
    parse_scenario({**base, "vehicles": [{"lane": 0, "s": 60.0, "speed": 10.0, "offset": 1.75, "width": 0.8}]})
    with pytest.raises(ScenarioError, match=r"vehicles\[0\].offset = 1.8: must be within half the lane's width"):
        parse_scenario({**base, "vehicles": [{"lane": 0, "s": 60.0, "speed": 10.0, "offset": 1.8, "width": 0.8}]})
