"""Safety-critical scenario families: each seed draws a new road, a new conflict and new traffic.

A scenario file with a ``[family]`` table (``sim.world.scenario.FamilySpec``) names a ``kind`` and, for
every parameter of that kind, the range ``[low, high]`` its seeds draw from (uniformly; count
parameters are whole numbers drawn uniformly from ``low..high``). ``sim.world.generator.realize(spec,
seed)`` returns the concrete ``ScenarioSpec`` of one seed, named ``"<name>-seed<seed>"``, with
``hazard_t`` set to the time of the family's critical moment: ``draw_family`` draws the conflict and the
traffic, then the road is drawn on the same stream. The drawn scenario is validated like a file. This
module imports nothing of ``sim.world``: the scenario model checks its tables with ``check_family``.

What every family draws: a road (``sim.world.generator.draw_clear_road``: straights and bends whose
radius is drawn from ``radius``, heading and bend directions at random; long enough for the ego's
drive and every vehicle plus ``ROAD_MARGIN``), the ego's speed, the actors
of the conflict (their classes, sizes, speeds, gaps and timing) and ``background`` other vehicles
(IDM, no lane changes, classes by ``BACKGROUND_CLASSES``) placed at random in lanes and stretches of
road that the conflict does not use, so the traffic differs per seed everywhere. The ego starts at
``EGO_S`` in lane 0 (the rightmost) unless the family says otherwise.

The kinds (``FAMILIES``), and what makes each hard for perception:

- ``cut-in``: a faster vehicle in the next lane cuts in at a short gap (``gap_s`` x the ego's speed,
  bumper to bumper, when its lane change starts) and then brakes. The tracker must see the lateral
  motion of a vehicle that is close, partly beside the ego and seen on one or two faces, and give it
  a place in the ego's lane early.
- ``cut-out``: the ego follows a lead that swerves into the next lane at the last moment
  (``reveal_ttc`` s before it would reach a vehicle standing in the lane). The standing vehicle was
  hidden behind the lead; it must be born, confirmed and given zero speed within a second or two.
- ``brake-behind-truck``: the ego follows a truck that follows a car; the car brakes hard, the truck
  brakes in turn. The car is hidden behind the truck; the planner reacts to the truck's track, whose
  speed must follow a hard deceleration without lag.
- ``merge-fast-rear``: a slow vehicle ahead makes the planner want the next lane, where a fast
  vehicle approaches from behind. Whether the change is safe is decided by a rear track: its presence
  and its speed while it closes in at up to 12 m/s.
- ``oncoming``: a winding two-lane road with traffic both ways; the ego follows a lead while cars,
  vans and trucks come the other way. On a bend an oncoming track placed half a lane off, or with its
  heading wrong, lies in the ego's lane: a phantom lead closing at twice the speed.
- ``lane-splitting``: slow traffic in two lanes and a motorcycle riding on the line between the ego's
  lane and the next, overtaking from behind. A narrow target next to larger ones (clusters merge), seen
  by few returns; placed half a lane off it is in the ego's path.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

#: Stream tag mixed into the seed for a family's random numbers (apart from the world's and sensors').
FAMILY_STREAM = 0x46414D  # "FAM"
#: Where the ego starts (m along the road), in lane 0.
EGO_S = 120.0
#: Bumper-to-bumper clearance (m) kept between a background vehicle and any other vehicle in its lane at the start.
BACKGROUND_GAP = 12.0
#: Stretch (m, relative to the ego's start) over which background vehicles are placed.
BACKGROUND_SPAN = (-60.0, 200.0)
#: Background vehicles drive at the ego's speed plus a value drawn in this range (m/s).
BACKGROUND_SPEED = (-3.0, 3.0)
#: Draws per background vehicle before one that finds no room is left out.
PLACEMENT_ATTEMPTS = 50
#: Road beyond the farthest the ego can reach in the duration (m).
ROAD_MARGIN = 150.0
#: Vehicle classes: (length range m, width range m).
CLASSES: dict[str, tuple[tuple[float, float], tuple[float, float]]] = {
    "car": ((4.2, 5.0), (1.75, 1.95)),
    "van": ((5.2, 6.2), (1.95, 2.1)),
    "truck": ((10.0, 16.0), (2.45, 2.55)),
    "motorcycle": ((2.0, 2.3), (0.75, 0.9)),
}
#: Class shares of the background traffic.
BACKGROUND_CLASSES = {"car": 0.8, "van": 0.12, "truck": 0.08}


@dataclass(frozen=True)
class Param:
    """A family parameter: its ``unit``, one line of ``meaning``, the hard ``bounds`` its range must
    lie within, and whether it is a whole number (``integer``)."""

    unit: str
    meaning: str
    bounds: tuple[float, float]
    integer: bool = False


#: Parameters shared by every family.
_COMMON = {
    "radius": Param("m", "radius of the road's bends", (60.0, 5000.0)),
    "ego_speed": Param("m/s", "the ego's speed at the start (the planner's set speed)", (3.0, 35.0)),
    "background": Param("vehicles", "other vehicles placed away from the conflict", (0, 12), integer=True),
}


@dataclass(frozen=True)
class Family:
    """A registered family: one line of ``description``, its own ``params`` (besides ``_COMMON``) and
    the ``build(draw, rng) -> (road kwargs, ego, actors, busy, hazard_t)`` that makes one seed."""

    description: str
    params: Mapping[str, Param]
    build: Callable[..., dict[str, Any]]

    def all_params(self) -> dict[str, Param]:
        """The common parameters and the family's own."""
        return {**_COMMON, **self.params}


def _vehicle(rng: np.random.Generator, shares: Mapping[str, float], lane_width: float) -> tuple[str, float, float]:
    """(class, length m, width m) drawn from ``shares``; widths leave 0.5 m in the lane."""
    names = list(shares)
    p = np.array([shares[k] for k in names], float)
    name = names[int(rng.choice(len(names), p=p / p.sum()))]
    (l_lo, l_hi), (w_lo, w_hi) = CLASSES[name]
    width = min(float(rng.uniform(w_lo, w_hi)), lane_width - 0.5)
    return name, round(float(rng.uniform(l_lo, l_hi)), 2), round(width, 2)


class _Draw:
    """Draws each parameter once from its range (``draw("gap_s")``), in the order of use."""

    def __init__(self, family: Family, params: Mapping[str, tuple[float, float]], rng: np.random.Generator) -> None:
        self.table = family.all_params()
        self.params = params
        self.rng = rng

    def __call__(self, name: str) -> float:
        lo, hi = self.params[name]
        if self.table[name].integer:
            return int(self.rng.integers(int(lo), int(hi) + 1))
        return float(lo) if lo == hi else float(self.rng.uniform(lo, hi))


def _car(lane: int, s: float, speed: float, size: tuple[str, float, float], **extra: Any) -> dict[str, Any]:
    return {"lane": lane, "s": round(s, 2), "speed": round(speed, 3), "length": size[1], "width": size[2], **extra}


# -- the families -------------------------------------------------------------------------------------
def _cut_in(d: _Draw, rng: np.random.Generator, lane_width: float) -> dict[str, Any]:
    lanes = d("lanes")
    v = d("ego_speed")
    ego = (EGO_S, v)
    dv, t_cut, gap = d("speed_diff"), d("cut_t"), d("gap_s") * v
    change, decel, drop = d("change_duration"), d("brake_decel"), d("brake_drop")
    size = _vehicle(rng, {"car": 0.75, "van": 0.25}, lane_width)
    s0 = EGO_S + gap + 0.5 * (size[1] + 4.8) - dv * t_cut
    cutter = _car(1, s0, v + dv, size, behaviour="scripted", maneuvers=[
        {"t": round(t_cut, 3), "kind": "lane_change", "lane": 0, "duration": round(change, 3)},
        {"t": round(t_cut + change, 3), "kind": "brake", "speed": round(max(v - drop, 2.0), 3), "decel": round(decel, 3)},
    ])
    return {"lanes": lanes, "ego": ego, "actors": [cutter], "busy": {0, 1}, "hazard_t": t_cut}


def _cut_out(d: _Draw, rng: np.random.Generator, lane_width: float) -> dict[str, Any]:
    lanes = d("lanes")
    v = d("ego_speed")
    headway, reveal_ttc, t_reveal, change = d("headway"), d("reveal_ttc"), d("reveal_t"), d("change_duration")
    lead_size = _vehicle(rng, {"car": 0.7, "van": 0.3}, lane_width)
    stopped_size = _vehicle(rng, {"car": 0.6, "van": 0.25, "truck": 0.15}, lane_width)
    s_lead = EGO_S + headway * v + 0.5 * (lead_size[1] + 4.8)
    s_stop = s_lead + v * t_reveal + reveal_ttc * v + 0.5 * (lead_size[1] + stopped_size[1])
    lead = _car(0, s_lead, v, lead_size, behaviour="scripted", maneuvers=[
        {"t": round(t_reveal, 3), "kind": "lane_change", "lane": 1, "duration": round(change, 3)}])
    stopped = _car(0, s_stop, 0.0, stopped_size, behaviour="constant")
    return {"lanes": lanes, "ego": (EGO_S, v), "actors": [lead, stopped], "busy": {0, 1}, "hazard_t": t_reveal}


def _brake_behind_truck(d: _Draw, rng: np.random.Generator, lane_width: float) -> dict[str, Any]:
    lanes = d("lanes")
    v = d("ego_speed")
    truck_headway, car_headway, t_brake = d("truck_headway"), d("car_headway"), d("brake_t")
    decel, to_speed = d("brake_decel"), d("brake_to")
    truck = _vehicle(rng, {"truck": 1.0}, lane_width)
    car = _vehicle(rng, {"car": 0.8, "van": 0.2}, lane_width)
    s_truck = EGO_S + truck_headway * v + 0.5 * (truck[1] + 4.8)
    s_car = s_truck + car_headway * v + 0.5 * (truck[1] + car[1])
    actors = [
        _car(0, s_truck, v, truck, behaviour="idm", lane_changes=False),
        _car(0, s_car, v, car, behaviour="scripted", maneuvers=[
            {"t": round(t_brake, 3), "kind": "brake", "speed": round(min(to_speed, v), 3), "decel": round(decel, 3)}]),
    ]
    return {"lanes": lanes, "ego": (EGO_S, v), "actors": actors, "busy": {0}, "hazard_t": t_brake}


def _merge_fast_rear(d: _Draw, rng: np.random.Generator, lane_width: float) -> dict[str, Any]:
    lanes = d("lanes")
    v = d("ego_speed")
    drop, lead_gap, dv, rear_gap = d("lead_speed_drop"), d("lead_gap"), d("rear_speed_diff"), d("rear_gap")
    lead = _vehicle(rng, {"car": 0.6, "van": 0.2, "truck": 0.2}, lane_width)
    rear = _vehicle(rng, {"car": 0.85, "van": 0.15}, lane_width)
    actors = [
        _car(0, EGO_S + lead_gap + 0.5 * (lead[1] + 4.8), max(v - drop, 2.0), lead, behaviour="idm", lane_changes=False),
        _car(1, EGO_S - rear_gap - 0.5 * (rear[1] + 4.8), v + dv, rear, behaviour="idm", lane_changes=False),
    ]
    return {"lanes": lanes, "ego": (EGO_S, v), "actors": actors, "busy": {0, 1}, "hazard_t": rear_gap / dv}


def _oncoming(d: _Draw, rng: np.random.Generator, lane_width: float) -> dict[str, Any]:
    v = d("ego_speed")
    lead_size = _vehicle(rng, {"car": 0.8, "van": 0.2}, lane_width)
    lead_gap, lead_drop = d("lead_gap"), d("lead_speed_drop")
    actors = [_car(0, EGO_S + lead_gap + 0.5 * (lead_size[1] + 4.8), max(v - lead_drop, 2.0), lead_size,
                   behaviour="idm", lane_changes=False)]
    count = d("oncoming_vehicles")
    spawn = sorted(float(rng.uniform(*d.params["oncoming_spawn"])) for _ in range(count))
    first_meet = math.inf
    placed: list[tuple[float, float]] = []
    for ahead in spawn:
        size = _vehicle(rng, {"car": 0.7, "van": 0.15, "truck": 0.15}, lane_width)
        s = EGO_S + ahead
        if any(abs(s - other) < 0.5 * (size[1] + length) + BACKGROUND_GAP for other, length in placed):
            continue
        speed = d("oncoming_speed")
        placed.append((s, size[1]))
        actors.append(_car(1, s, speed, size, behaviour="idm", lane_changes=False))
        first_meet = min(first_meet, ahead / (v + speed))
    return {"lanes": 2, "oncoming": 1, "ego": (EGO_S, v), "actors": actors, "busy": {0, 1},
            "hazard_t": first_meet if math.isfinite(first_meet) else None}


def _lane_splitting(d: _Draw, rng: np.random.Generator, lane_width: float) -> dict[str, Any]:
    lanes = d("lanes")
    v = d("ego_speed")
    lead = _vehicle(rng, {"car": 0.8, "van": 0.2}, lane_width)
    actors = [_car(0, EGO_S + 1.5 * v + 0.5 * (lead[1] + 4.8), v, lead, behaviour="idm", lane_changes=False)]
    moto = _vehicle(rng, {"motorcycle": 1.0}, lane_width)
    dv, rear_gap = d("moto_speed_diff"), d("moto_gap")
    s_moto = EGO_S - rear_gap - 0.5 * (moto[1] + 4.8)
    # the queue in the next lane: a vehicle every 1.2-2.5 s of headway, from behind the ego to well ahead
    # (none beside the motorcycle's start, where the two would touch)
    s = EGO_S - float(rng.uniform(10.0, 25.0))
    while s < EGO_S + 120.0:
        size = _vehicle(rng, {"car": 0.85, "van": 0.15}, lane_width)
        if abs(s - s_moto) > 0.5 * (size[1] + moto[1]) + 2.0:
            actors.append(_car(1, s, v, size, behaviour="idm", lane_changes=False))
        s += size[1] + 5.0 + float(rng.uniform(1.2, 2.5)) * v
    actors.append(_car(0, s_moto, v + dv, moto, behaviour="constant", offset=round(0.5 * lane_width, 3)))
    return {"lanes": lanes, "ego": (EGO_S, v), "actors": actors, "busy": {0, 1}, "hazard_t": rear_gap / dv}


_LANES = Param("lanes", "driving lanes along the road", (2, 4), integer=True)
FAMILIES: dict[str, Family] = {
    "cut-in": Family(
        "a faster vehicle in the next lane cuts in at a short gap, then brakes",
        {"lanes": _LANES,
         "gap_s": Param("s", "bumper-to-bumper gap to the ego / the ego's speed when the lane change starts", (0.2, 5.0)),
         "speed_diff": Param("m/s", "how much faster than the ego the cutter drives", (0.0, 15.0)),
         "cut_t": Param("s", "time the lane change starts (the hazard)", (1.0, 30.0)),
         "change_duration": Param("s", "duration of the lane change", (1.0, 8.0)),
         "brake_decel": Param("m/s^2", "the cutter's deceleration after the cut-in", (0.5, 9.0)),
         "brake_drop": Param("m/s", "how far below the ego's speed the cutter slows", (0.0, 20.0))},
        _cut_in),
    "cut-out": Family(
        "the lead swerves late into the next lane and reveals a vehicle standing in the ego's lane",
        {"lanes": _LANES,
         "headway": Param("s", "the ego's time gap to the lead at the start", (0.5, 4.0)),
         "reveal_ttc": Param("s", "the lead's distance to the standing vehicle / its speed when it swerves", (0.5, 8.0)),
         "reveal_t": Param("s", "time the lead swerves (the hazard)", (1.0, 30.0)),
         "change_duration": Param("s", "duration of the lead's lane change", (1.0, 8.0))},
        _cut_out),
    "brake-behind-truck": Family(
        "a car brakes hard two vehicles ahead, hidden behind the truck the ego follows",
        {"lanes": _LANES,
         "truck_headway": Param("s", "the ego's time gap to the truck", (0.5, 4.0)),
         "car_headway": Param("s", "the truck's time gap to the car", (0.5, 4.0)),
         "brake_t": Param("s", "time the car brakes (the hazard)", (1.0, 30.0)),
         "brake_decel": Param("m/s^2", "the car's deceleration", (1.0, 9.0)),
         "brake_to": Param("m/s", "the speed the car brakes to", (0.0, 30.0))},
        _brake_behind_truck),
    "merge-fast-rear": Family(
        "a slow vehicle ahead invites a lane change while a fast vehicle approaches from behind in the target lane",
        {"lanes": _LANES,
         "lead_speed_drop": Param("m/s", "how much slower than the ego the vehicle ahead drives", (0.0, 20.0)),
         "lead_gap": Param("m", "bumper-to-bumper gap to the slow vehicle at the start", (5.0, 200.0)),
         "rear_speed_diff": Param("m/s", "how much faster than the ego the rear vehicle drives", (0.5, 20.0)),
         "rear_gap": Param("m", "bumper-to-bumper gap behind the ego to the rear vehicle at the start", (2.0, 150.0))},
        _merge_fast_rear),
    "oncoming": Family(
        "a winding two-lane road with traffic both ways; the ego follows a lead",
        {"lead_gap": Param("m", "bumper-to-bumper gap to the lead at the start", (5.0, 200.0)),
         "lead_speed_drop": Param("m/s", "how much slower than the ego the lead drives", (0.0, 20.0)),
         "oncoming_vehicles": Param("vehicles", "oncoming vehicles (fewer when two would overlap)", (1, 12), integer=True),
         "oncoming_speed": Param("m/s", "speed of each oncoming vehicle", (2.0, 35.0)),
         "oncoming_spawn": Param("m", "where each oncoming vehicle starts, ahead of the ego", (20.0, 1000.0))},
        _oncoming),
    "lane-splitting": Family(
        "a motorcycle overtakes on the line between the ego's lane and a queue in the next lane",
        {"lanes": _LANES,
         "moto_speed_diff": Param("m/s", "how much faster than the traffic the motorcycle rides", (0.5, 20.0)),
         "moto_gap": Param("m", "bumper-to-bumper distance behind the ego where the motorcycle starts", (2.0, 150.0))},
        _lane_splitting),
}
#: Lane width (m) of every family's road.
LANE_WIDTH = 3.5


def check_family(kind: str, params: Mapping[str, tuple[float, float]]) -> None:
    """``ValueError`` naming the problem when ``kind`` is not a family, a parameter is missing or
    unknown, or a range is reversed, outside its bounds or (for counts) not whole."""
    if kind not in FAMILIES:
        raise ValueError(f"family.kind = {kind!r}: not a family; choose one of: {', '.join(FAMILIES)}")
    table = FAMILIES[kind].all_params()
    unknown = sorted(set(params) - set(table))
    if unknown:
        raise ValueError(f"family.params.{unknown[0]}: not a parameter of {kind!r}; its parameters: {', '.join(table)}")
    missing = [k for k in table if k not in params]
    if missing:
        p = table[missing[0]]
        raise ValueError(f"family.params.{missing[0]}: missing; give its range [low, high] ({p.unit}: {p.meaning})")
    for name, (lo, hi) in params.items():
        p = table[name]
        if lo > hi:
            raise ValueError(f"family.params.{name} = {[lo, hi]}: low must be <= high")
        if lo < p.bounds[0] or hi > p.bounds[1]:
            raise ValueError(f"family.params.{name} = {[lo, hi]}: must lie within [{p.bounds[0]:g}, {p.bounds[1]:g}] {p.unit}")
        if p.integer and (lo != int(lo) or hi != int(hi)):
            raise ValueError(f"family.params.{name} = {[lo, hi]}: a count; give whole numbers")


def _background(rng: np.random.Generator, count: int, lanes: int, directions: list[int], busy: set[int],
                taken: list[tuple[int, float, float]], v: float, lane_width: float) -> list[dict[str, Any]]:
    """``count`` IDM vehicles without lane changes in lanes outside ``busy`` (or, on a road whose lanes are
    all busy, beyond ``BACKGROUND_SPAN``'s far end in any lane of the ego's direction), clear of ``taken``
    ((lane, s, length) of every vehicle so far) by ``BACKGROUND_GAP`` m between bumpers."""
    free = [k for k in range(lanes) if k not in busy and directions[k] > 0]
    out: list[dict[str, Any]] = []
    for _ in range(count):
        size = _vehicle(rng, BACKGROUND_CLASSES, lane_width)
        for _attempt in range(PLACEMENT_ATTEMPTS):
            if free:
                lane = int(rng.choice(free))
                s = EGO_S + float(rng.uniform(*BACKGROUND_SPAN))
            else:
                lane = int(rng.choice([k for k in range(lanes) if directions[k] > 0]))
                s = EGO_S + BACKGROUND_SPAN[1] + float(rng.uniform(0.0, 150.0))
            if all(k != lane or abs(s - s2) >= 0.5 * (size[1] + l2) + BACKGROUND_GAP for k, s2, l2 in taken):
                speed = max(v + float(rng.uniform(*BACKGROUND_SPEED)), 2.0)
                if not free:  # ahead of everything in a busy lane: no slower than the ego, so it stays out of the conflict
                    speed = v + abs(float(rng.uniform(*BACKGROUND_SPEED)))
                out.append(_car(lane, s, speed, size, behaviour="idm", lane_changes=False))
                taken.append((lane, s, size[1]))
                break
    return out


@dataclass(frozen=True)
class FamilyDraw:
    """What one seed of a family draws, before its road: ``radius`` (m) of the road's bends, ``lanes``
    and ``oncoming`` lanes, the ego's ``ego_s`` (m) and ``ego_speed`` (m/s), the ``vehicles`` (scenario
    tables: the conflict's actors, then the background), ``hazard_t`` (s or None) and the ``rng`` whose
    stream the road is drawn from next (``sim.world.generator.realize``)."""

    radius: float
    lanes: int
    oncoming: int
    ego_s: float
    ego_speed: float
    vehicles: list[dict[str, Any]]
    hazard_t: float | None
    rng: np.random.Generator


def draw_family(kind: str, params: Mapping[str, tuple[float, float]], seed: int) -> FamilyDraw:
    """The conflict and the traffic that ``seed`` draws for family ``kind`` with ranges ``params``
    (module docstring); the road is drawn by ``sim.world.generator.realize`` from the returned ``rng``."""
    family = FAMILIES[kind]
    rng = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(FAMILY_STREAM,)))
    draw = _Draw(family, params, rng)
    radius = draw("radius")
    count = draw("background")
    built = family.build(draw, rng, LANE_WIDTH)
    lanes, oncoming = int(built["lanes"]), int(built.get("oncoming", 0))
    ego_s, ego_v = built["ego"]
    directions = [1] * (lanes - oncoming) + [-1] * oncoming
    taken = [(0, ego_s, 4.8)] + [(a["lane"], a["s"], a["length"]) for a in built["actors"]]
    background = _background(rng, count, lanes, directions, set(built["busy"]), taken, ego_v, LANE_WIDTH)
    hazard = built["hazard_t"]
    return FamilyDraw(float(radius), lanes, oncoming, float(ego_s), float(ego_v), built["actors"] + background,
                      None if hazard is None else float(hazard), rng)


__all__ = ["CLASSES", "FAMILIES", "Family", "FamilyDraw", "Param", "check_family", "draw_family"]
