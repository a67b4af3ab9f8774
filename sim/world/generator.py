"""Random scenarios: each seed draws a new road and/or new traffic from a scenario's ``[generator]``.

``realize(spec, seed)`` returns a concrete ``ScenarioSpec`` (no generator section) named
``"<name>-seed<seed>"``: the road is drawn when the file has no ``[road]``, the traffic (ego and
vehicles) when it has neither ``[ego]`` nor ``[[vehicles]]``; everything else (duration, sensor and
tracker overrides) is kept. The drawn scenario goes through the same validation as a file, so it is
valid by construction or the call raises ``ScenarioError``. A drawn road never overlaps itself: one
that winds back to within its width plus ``ROAD_SELF_CLEARANCE`` of itself is drawn again
(``draw_clear_road``). The ranges and rules are documented on
``sim.world.scenario.GeneratorSpec``; with ``classes`` (``sim.world.scenario.VehicleClass``) each drawn vehicle is
a car, van, truck, bus, motorcycle ... with the class's share as its probability, and the class's
length and width.

Randomness: one ``numpy.random.Generator`` seeded from ``SeedSequence(seed, spawn_key=(GEN_STREAM,))``
(kept apart from the world's and the sensors' streams); the same spec + seed gives the same scenario.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from sim.world.families import LANE_WIDTH as FAMILY_LANE_WIDTH
from sim.world.families import ROAD_MARGIN as FAMILY_ROAD_MARGIN
from sim.world.families import draw_family
from sim.world.scenario import GeneratorSpec, LaneChange, RoadSpec, ScenarioError, ScenarioSpec, parse_scenario
from tracker.road import Road

#: Stream tag mixed into the seed for the generator's random numbers.
GEN_STREAM = 0x47454E  # "GEN"
#: Bumper-to-bumper distance (m) kept between drawn vehicles in the same lane at the start.
MIN_BUMPER_GAP = 10.0
#: Draws per vehicle before a vehicle that finds no free spot is dropped.
PLACEMENT_ATTEMPTS = 50
#: Road beyond the ego's furthest reach (m), so that vehicles ahead have room too.
ROAD_MARGIN = 150.0
#: Range of drawn lane-change durations (s).
LANE_CHANGE_DURATION = (3.0, 6.0)
#: Clear space (m) kept between a drawn road's edges where it winds back towards itself: the
#: centerlines of two parts of the road further apart along it than (pi / 2) x (road width + this)
#: are at least (road width + this) apart, so the road never overlaps itself (a road that does gives
#: one place two Frenet coordinates).
ROAD_SELF_CLEARANCE = 10.0
#: Roads drawn before a generator whose ranges keep making roads that come back onto themselves is
#: reported as an error.
ROAD_ATTEMPTS = 100
#: Spacing (m) of the centerline samples of the self-clearance test.
CLEARANCE_STEP = 1.0


def _uniform(rng: np.random.Generator, bounds: tuple[float, float]) -> float:
    lo, hi = bounds
    return float(lo) if lo == hi else float(rng.uniform(lo, hi))


def _integer(rng: np.random.Generator, bounds: tuple[int, int]) -> int:
    return int(rng.integers(bounds[0], bounds[1] + 1))


def draw_road(gen: GeneratorSpec, rng: np.random.Generator, lanes: int, min_length: float, oncoming: int = 0) -> dict[str, Any]:
    """A road table (``RoadSpec`` data): straights and curves until at least ``min_length`` m."""
    segments: list[list[float]] = []
    total = 0.0
    k_lo, k_hi = 1.0 / gen.radius[1], 1.0 / gen.radius[0]
    while True:
        straight = _uniform(rng, gen.straight_length)
        segments.append([straight, 0.0, 0.0])
        total += straight
        if total >= min_length:
            break
        kappa = float(rng.choice([-1.0, 1.0])) * _uniform(rng, (k_lo, k_hi))
        ramp_in, arc, ramp_out = _uniform(rng, gen.ramp_length), _uniform(rng, gen.arc_length), _uniform(rng, gen.ramp_length)
        segments += [[ramp_in, 0.0, kappa], [arc, kappa, kappa], [ramp_out, kappa, 0.0]]
        total += ramp_in + arc + ramp_out
    heading = _uniform(rng, (-math.pi, math.pi))
    road = {"lanes": lanes, "lane_width": gen.lane_width, "closed": False, "start": [0.0, 0.0, heading], "segments": segments}
    if oncoming:
        road["oncoming"] = oncoming
    return road


def self_clearance(road: Road, clearance: float) -> float:
    """The smallest distance (m) between two centerline points of ``road`` that lie further apart
    along it than ``(pi / 2) clearance`` (inf when none comes within ``clearance``): on an arc a chord
    is at least ``2 / pi`` of its arc length up to half a turn, so only a road winding back towards
    itself brings such points within ``clearance``. Samples every ``CLEARANCE_STEP`` m (a cKDTree)."""
    s = np.arange(0.0, road.length + CLEARANCE_STEP, CLEARANCE_STEP)
    xy, _, _ = road.frame(np.minimum(s, road.length))
    pairs = cKDTree(xy).query_pairs(clearance, output_type="ndarray")
    gap = np.abs(s[pairs[:, 0]] - s[pairs[:, 1]])
    if road.closed:  # the start and the end of a closed road are neighbours
        gap = np.minimum(gap, road.length - gap)
    far = pairs[gap > 0.5 * math.pi * clearance]
    if len(far) == 0:
        return math.inf
    return float(np.min(np.linalg.norm(xy[far[:, 0]] - xy[far[:, 1]], axis=1)))


def draw_clear_road(gen: GeneratorSpec, rng: np.random.Generator, lanes: int, min_length: float,
                    where: str = "generator", oncoming: int = 0) -> dict[str, Any]:
    """``draw_road`` until the road keeps ``ROAD_SELF_CLEARANCE`` m between its edges wherever it
    winds back towards itself (``self_clearance`` of the centerline at least the road's width plus
    that); ``ScenarioError`` after ``ROAD_ATTEMPTS`` draws."""
    clearance = lanes * gen.lane_width + ROAD_SELF_CLEARANCE
    for _ in range(ROAD_ATTEMPTS):
        road = draw_road(gen, rng, lanes, min_length, oncoming)
        spec = RoadSpec.model_validate(road)
        if self_clearance(spec.build(), clearance) >= clearance:
            return road
    raise ScenarioError(
        f"{where}: {ROAD_ATTEMPTS} drawn roads of {min_length:.0f} m all came back within {clearance:.1f} m of "
        f"themselves (the road's width plus {ROAD_SELF_CLEARANCE:g} m); draw larger radii (generator.radius = "
        f"{list(gen.radius)}) or longer straights (generator.straight_length = {list(gen.straight_length)})"
    )


def _maneuvers(gen: GeneratorSpec, rng: np.random.Generator, lane: int, group: list[int], duration: float) -> list[dict[str, Any]]:
    """Poisson-timed lane changes (to an adjacent lane of ``group``, the lanes of the vehicle's direction,
    one at a time) and speed changes."""
    out: list[dict[str, Any]] = []
    t, current = 0.0, lane
    if gen.lane_change_rate > 0 and len(group) > 1:
        while True:
            t += float(rng.exponential(1.0 / gen.lane_change_rate))
            length = _uniform(rng, LANE_CHANGE_DURATION)
            if t + length >= duration:
                break
            options = [k for k in (current - 1, current + 1) if k in group]
            current = int(rng.choice(options))
            out.append({"kind": "lane_change", "t": round(t, 3), "lane": current, "duration": round(length, 3), "wait_for_gap": True})
            t += length + 1.0
    t = 0.0
    if gen.speed_change_rate > 0:
        while True:
            t += float(rng.exponential(1.0 / gen.speed_change_rate))
            if t >= duration:
                break
            out.append({"kind": "speed", "t": round(t, 3), "speed": round(_uniform(rng, gen.speed), 3),
                        "accel": round(_uniform(rng, (1.0, 3.0)), 3)})
    return sorted(out, key=lambda m: m["t"])


def draw_traffic(gen: GeneratorSpec, rng: np.random.Generator, lanes: int, road_length: float, closed: bool,
                 duration: float, ego_s: float, directions: list[int] | None = None) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """The ego (at ``ego_s``) and the other vehicles as scenario tables, without overlap. With
    ``gen.classes`` each vehicle first draws its class (one uniform number against the cumulative
    shares), then its length and width from that class; without, from ``gen.length`` / ``gen.width``
    (the draws, and so the traffic of a seed, are then exactly those of a generator without classes).
    ``directions`` (per lane, +1 along ``s``, -1 against; default all +1): the ego drives in a lane along
    ``s``; a vehicle drawn into a lane against ``s`` is placed ``gen.oncoming_spawn`` m ahead of the ego."""
    directions = [1] * lanes if directions is None else list(directions)
    along = [k for k in range(lanes) if directions[k] > 0]
    against = [k for k in range(lanes) if directions[k] < 0]
    ego = {
        "lane": along[_integer(rng, (0, len(along) - 1))],
        "s": round(ego_s, 3),
        "speed": round(_uniform(rng, gen.ego_speed), 3),
        "behaviour": "idm",
        "length": 4.8,
        "width": 2.0,
    }
    placed: list[tuple[int, float, float]] = [(ego["lane"], ego["s"], ego["length"])]
    classes = gen.class_bounds() if gen.classes is not None else None
    vehicles: list[dict[str, Any]] = []
    for _ in range(_integer(rng, gen.vehicles)):
        u = float(rng.uniform())
        behaviour = "scripted" if u < gen.scripted_fraction else "constant" if u < gen.scripted_fraction + gen.constant_fraction else "idm"
        height = None
        if classes is None:
            length, width = round(_uniform(rng, gen.length), 3), round(_uniform(rng, gen.width), 3)
        else:
            k = min(int(np.searchsorted(classes[0], rng.uniform(), side="right")), len(classes[0]) - 1)
            length, width = round(_uniform(rng, tuple(classes[1][k])), 3), round(_uniform(rng, tuple(classes[2][k])), 3)
            height = gen.classes[k].height_of(length)  # type: ignore[index]  (no draw: the stream is unchanged)
        for _attempt in range(PLACEMENT_ATTEMPTS):
            lane = _integer(rng, (0, lanes - 1))
            s = ego_s + _uniform(rng, gen.spawn if directions[lane] > 0 else gen.oncoming_spawn)
            if closed:
                s %= road_length
            elif not 0.5 * length <= s <= road_length - 0.5 * length:
                continue
            clear = True
            for other_lane, other_s, other_length in placed:
                ds = s - other_s
                if closed:
                    ds = (ds + 0.5 * road_length) % road_length - 0.5 * road_length
                if other_lane == lane and abs(ds) < 0.5 * (length + other_length) + MIN_BUMPER_GAP:
                    clear = False
                    break
            if clear:
                break
        else:
            continue  # no room: drop this vehicle
        vehicle: dict[str, Any] = {
            "lane": lane,
            "s": round(s, 3),
            "speed": round(_uniform(rng, gen.speed), 3),
            "behaviour": behaviour,
            "length": length,
            "width": width,
        }
        if height is not None:
            vehicle["height"] = height
        if behaviour == "scripted":
            vehicle["maneuvers"] = _maneuvers(gen, rng, lane, along if directions[lane] > 0 else against, duration)
        placed.append((lane, vehicle["s"], length))
        vehicles.append(vehicle)
    return ego, vehicles


def _drawn_header(spec: ScenarioSpec, seed: int) -> dict[str, Any]:
    """What a drawn scenario keeps of its file: the name ``<name>-seed<seed>``, description, duration,
    sensor and tracker overrides and faults."""
    data: dict[str, Any] = {"name": f"{spec.name}-seed{int(seed)}"[:64], "description": spec.description,
                            "duration": spec.duration, "sensors": spec.sensors, "tracker": spec.tracker}
    if spec.faults is not None:
        data["faults"] = spec.faults.model_dump()
    return data


def _realize_family(spec: ScenarioSpec, seed: int) -> ScenarioSpec:
    """A ``[family]`` scenario's seed (``sim.world.families``): the conflict and traffic of
    ``draw_family``, on a road drawn from the same stream with the family's bend radius, long enough for
    the ego's drive at its speed over the duration and for every vehicle, plus ``families.ROAD_MARGIN``."""
    fam = spec.family
    assert fam is not None
    drawn = draw_family(fam.kind, fam.params, seed)
    where = f"{spec.source or spec.name} (family {fam.kind!r}, seed {seed})"
    half = 0.5 * drawn.lanes * FAMILY_LANE_WIDTH
    needed = drawn.ego_s + drawn.ego_speed * spec.duration / (1.0 - half / drawn.radius) + FAMILY_ROAD_MARGIN
    needed = max([needed] + [v["s"] + FAMILY_ROAD_MARGIN for v in drawn.vehicles])
    gen = GeneratorSpec(radius=(drawn.radius, drawn.radius), lanes=(drawn.lanes, drawn.lanes), lane_width=FAMILY_LANE_WIDTH,
                        straight_length=(40.0, 120.0), arc_length=(60.0, 160.0), ramp_length=(20.0, 40.0))
    data = _drawn_header(spec, seed)
    data.update(road=draw_clear_road(gen, drawn.rng, drawn.lanes, needed, where, drawn.oncoming),
                ego={"lane": 0, "s": drawn.ego_s, "speed": round(drawn.ego_speed, 3)}, vehicles=drawn.vehicles)
    if drawn.hazard_t is not None and drawn.hazard_t < spec.duration:
        data["hazard_t"] = round(drawn.hazard_t, 3)
    return parse_scenario(data, where)


def realize(spec: ScenarioSpec, seed: int = 0) -> ScenarioSpec:
    """The concrete scenario that ``seed`` draws from ``spec``'s generator, or from its ``[family]``
    (``sim.world.families.draw_family``, then the road); ``spec`` itself when it has neither. See the module notes."""
    if spec.family is None and spec.generator is None:
        return spec
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer; got {seed!r}")
    if spec.family is not None:
        return _realize_family(spec, int(seed))
    gen = spec.generator
    assert gen is not None
    rng = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(GEN_STREAM,)))
    data = _drawn_header(spec, seed)
    oncoming = 0
    if spec.road is not None:
        lanes = spec.road.lanes
    else:  # fixed traffic on a drawn road: draw only lane counts that hold every lane it uses
        used = [v.lane for _, v in spec._all()]
        used += [m.lane for _, v in spec._all() for m in v.maneuvers if isinstance(m, LaneChange)]
        low = max(gen.lanes[0], max(used, default=-1) + 1)
        if low > gen.lanes[1]:
            raise ScenarioError(
                f"{spec.source or spec.name}: generator.lanes = {list(gen.lanes)} cannot hold lane {low - 1} "
                f"used by the fixed traffic; raise its upper bound to at least {low}"
            )
        lanes = _integer(rng, (low, gen.lanes[1]))
        if gen.oncoming != (0, 0):  # (no draw otherwise: one-way generators keep their streams)
            oncoming = _integer(rng, gen.oncoming)
    ego_s = max(0.0, -gen.spawn[0]) + 10.0
    if spec.ego is not None:
        ego_s = spec.ego.s
        ego_speed = spec.ego.max_speed()
    else:
        ego_speed = gen.ego_speed[1]
    if spec.road is None:
        half = 0.5 * lanes * gen.lane_width
        factor = 1.0 / (1.0 - half / gen.radius[0])
        needed = ego_s + factor * ego_speed * spec.duration + ROAD_MARGIN
        if oncoming:  # oncoming vehicles are placed up to oncoming_spawn ahead of the ego
            needed = max(needed, ego_s + gen.oncoming_spawn[1] + ROAD_MARGIN)
        road = draw_clear_road(gen, rng, lanes, needed, f"{spec.source or spec.name} (generator, seed {seed})", oncoming)
    else:
        road = spec.road.to_config()
    data["road"] = road
    if spec.ego is None:
        if spec.road is not None:
            built = spec.build_road()
            length, closed = built.length, built.closed
            lanes, directions = built.lanes, [int(d) for d in built.lane_directions]
        else:  # a curvature-profile road is exactly as long as its segments
            length, closed = float(sum(seg[0] for seg in road["segments"])), False
            directions = [1] * (lanes - oncoming) + [-1] * oncoming
        ego, vehicles = draw_traffic(gen, rng, lanes, length, closed, spec.duration, ego_s, directions)
        data["ego"], data["vehicles"] = ego, vehicles
    else:
        data["ego"] = spec.ego.model_dump(exclude_none=True)
        data["vehicles"] = [v.model_dump(exclude_none=True) for v in spec.vehicles]
    where = f"{spec.source or spec.name} (generator, seed {seed})"
    return parse_scenario(data, where)
