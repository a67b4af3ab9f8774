"""Scenario files: TOML read with ``tomllib``, validated by pydantic into a typed ``ScenarioSpec``.

A scenario file holds (SI units: m, s, rad, m/s, 1/m)::

    name = "cut-in"                       # identifier (letters, digits, "-", "_")
    description = "one line"              # shown by `eot scenarios`
    duration = 20.0                       # s, simulated time
    hazard_t = 6.0                        # s, optional: the critical moment (a family sets it)

    [road]                                # exactly one of `segments` / `waypoints`
    lanes = 2                             # lane 0 is the rightmost
    lane_width = 3.5                      # m
    closed = false                        # closed roads wrap s
    start = [0.0, 0.0, 0.0]               # x, y (m), heading (rad) of s = 0 (segments only)
    segments = [[100, 0, 0], [40, 0, 0.01]]  # rows (length m, kappa_start 1/m, kappa_end 1/m)
    # waypoints = [[0, 0], [50, 5]]       # or a cubic Hermite spline through points (m)
    # headings = [0.0, 0.1]               # optional, rad, one per waypoint
    grade = 0.0                           # optional: rise per m of s (|grade| <= 0.15; open roads)
    bank = 0.0                            # optional: rise per m of n to the left (|bank| <= 0.15)

    [ego]                                 # the vehicle that carries the sensors
    lane = 0
    s = 30.0                              # m, arc length of the rectangle centre
    speed = 20.0                          # m/s

    [[vehicles]]                          # the other vehicles (ids 1, 2, ... in file order)
    lane = 1
    s = 50.0
    speed = 22.0
    behaviour = "scripted"                # "idm" (default) | "constant" | "scripted"
    maneuvers = [{ t = 2.0, kind = "lane_change", lane = 0, duration = 4.0 }]
    # kinds: lane_change (lane, duration s, wait_for_gap), speed (speed m/s, accel m/s^2 <= 8),
    #        brake (speed m/s, default 0 = stop; decel m/s^2 <= 9, constant until the speed is reached)
    length = 4.8                          # m; 2-20 (a 2.2 m motorcycle, an 18 m bus)
    width = 2.0                           # m; 0.6-3.0 and <= lane_width - 0.5
    height = 1.5                          # m; 0.8-5.0, optional (default by length); 3-D lidar only
    offset = 0.0                          # m, path off the lane centre (left +), at most half the lane

    [sensors]                             # optional overrides, applied by the runner
    lidar = { model = "vlp16" }           #   "2d" (default) or "vlp16": the 3-D lidar (sim.sensors.lidar3d)
    [tracker]                             # optional overrides, applied by the runner
    [faults]                              # optional sensor faults, applied by the runner (sim.sensors.faults)
    lidar_dropout = [[6.0, 8.0]]          # intervals [start, end) s: lidar frames carry no points
    radar_dropout = [[6.0, 8.0]]          # intervals [start, end) s: no radar detections
    radar_missing = false                 # true: no radar detections in the whole run
    lidar_time_offset = 0.05              # s, in [0, lidar period): each scan is measured this long
                                          #   before the time it is stamped with (uncompensated latency)
    lidar_spikes = 0.05                   # fraction of each scan's points moved to a random range
                                          #   (uniform in the lidar's [min_range, max_range]) on their ray
    duplicate_frames = [5.0]              # times s: the first frame at or after each is delivered twice
    [family]                              # optional: a safety-critical family (sim.world.families), drawn
    kind = "cut-in"                       #   per seed; no [road], [ego], [[vehicles]] or [generator] then
    params = { gap_s = [0.5, 1.5], ... }  #   a range [low, high] for every parameter of the kind
    [generator]                           # optional: draw a new road and/or traffic per seed
    classes = [                           # optional vehicle classes of the drawn traffic
        { name = "car", length = [4.2, 5.2], width = [1.7, 2.1], share = 0.8 },
        { name = "truck", length = [10.0, 16.0], width = 2.5, share = 0.2 },
    ]

Every table rejects unknown keys (highway-env silently ignores typos; this does not). Errors raise
``ScenarioError`` (a ``ValueError``) naming the file, the field, the value and what is allowed.

Defaults (see the models below): lanes 2, lane_width 3.5 m, closed false, start (0, 0, 0);
vehicle behaviour "idm", length 4.8 m and width 2.0 m (the paper's target), target_speed = speed,
lane_changes (MOBIL, idm only) true for vehicles and false for the ego; lane change duration 4 s,
speed change accel 2 m/s^2, brake to 0 m/s at 4 m/s^2 (constant deceleration, landing on the
target speed). A vehicle standing still on the road: behaviour "constant" with speed 0.
Faults (``FaultsSpec``): none by default; intervals must lie within [0, duration] with start < end,
duplicate times within [0, duration).
Generator vehicle classes (``VehicleClass``): ``length`` and ``width`` are a number or a range
``[low, high]`` (m, drawn uniformly), ``share`` > 0 and the shares must sum to 1 within 1e-6 (they are
not normalised: a typo in a share is an error, not a silent re-weighting); without ``classes`` the
generator draws every vehicle from its ``length`` / ``width`` ranges.
"""

from __future__ import annotations

import functools
import math
import re
import tomllib
from importlib import resources
from dataclasses import fields, is_dataclass, replace
from pathlib import Path
from typing import Annotated, Any, Literal, Union

import numpy as np
from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, PrivateAttr, Strict, ValidationError, model_validator

from sim.world.truth import default_height, rectangle_corners
from tracker import Road
from tracker.lanes import MIN_LANE_WIDTH, LaneLayout

StrictFloat = Annotated[float, Strict()]
StrictInt = Annotated[int, Strict()]
StrictBool = Annotated[bool, Strict()]
StrictStr = Annotated[str, Strict()]

#: Largest allowed road curvature magnitude (1/m): radius >= 20 m.
MAX_CURVATURE = 0.05
#: Clearance (m) required between vehicle rectangles at the start (beyond touching).
START_CLEARANCE = 0.5
#: Largest allowed speed (m/s) anywhere in a scenario (highway-env's Vehicle.MAX_SPEED).
MAX_SPEED = 40.0
#: Default width (m) of a parking lane (``road.parking``).
PARKING_WIDTH = 2.5


def shipped_scenario_dir() -> Path:
    """The folder of the shipped scenario files: ``sim/scenarios``, package data read through
    ``importlib.resources``. In the repository it is a symbolic link to the top-level ``scenarios/``
    (the one source of the files), which a wheel (``pip install .``) copies into the package, so a
    source checkout, an editable install and a regular install all find the same files."""
    shipped = resources.files("sim") / "scenarios"
    if not isinstance(shipped, Path):  # pragma: no cover (a zipped install; pip never makes one)
        raise RuntimeError(f"the shipped scenarios must be a folder on disk; got {shipped!r}")
    return shipped


#: Folder of the shipped scenario files (``shipped_scenario_dir``).
SCENARIO_DIR = shipped_scenario_dir()


class ScenarioError(ValueError):
    """A scenario file (or spec) is invalid; the message names the file, field, value and fix."""


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


# -- road ----------------------------------------------------------------------------------------
class RouteSpec(_Model):
    """The route through a lane map (``road.map``): from ``start = (x m, y m, yaw rad)`` in the map's frame
    to the optional ``goal = (x m, y m)``, through the optional ``via`` points (m); without a goal the
    route goes on straightest to the end of the map (``tracker.maps.route_road``)."""

    start: tuple[StrictFloat, StrictFloat, StrictFloat]
    goal: tuple[StrictFloat, StrictFloat] | None = None
    via: list[tuple[StrictFloat, StrictFloat]] | None = Field(default=None, min_length=1)


class RoadSpec(_Model):
    """The road: ``lanes`` lanes of ``lane_width`` m, from a curvature profile (``segments``: rows
    ``(length m, kappa_start 1/m, kappa_end 1/m)`` starting at ``start = (x m, y m, heading rad)``)
    or from ``waypoints`` (m, with optional ``headings`` rad). ``closed`` roads wrap ``s``. The
    centerline runs down the middle of the carriageway. |curvature| <= 0.05 1/m and below
    1 / (2 x half-width of the road), so the edges never fold over.

    ``grade`` (0; |grade| <= 0.15) and ``bank`` (0; |bank| <= 0.15): the road surface rises ``grade`` m
    per m of ``s`` and ``bank`` m per m of ``n`` (toward the left); beside the road the ground is level
    across (``sim.world.ground.RoadGround``). Only the 3-D lidar and the vehicles' heights see them (the
    vehicles drive the 2-D road); a closed road cannot have a grade.

    Two-way roads: ``oncoming`` (0) of the ``lanes`` driving lanes carry traffic against ``s``: the
    leftmost ones with ``drive_on = "right"`` (the default), the rightmost with ``"left"``; vehicles in
    them drive against ``s``. ``parking`` (none; ``"right"``, ``"left"`` or ``"both"``) adds a parking
    lane of ``parking_width`` m (2.5; 2-3.5) outside the driving lanes on that side, of the direction of
    the driving lane next to it (``tracker.lanes.LaneLayout``, kind ``"parking"``). Lanes are numbered
    across the whole road, 0 the rightmost, parking lanes included; the driving lanes stay centred on
    the centerline.

    Roads from lane maps: ``map`` (a CommonRoad ``.xml``, Lanelet2 ``.osm`` or OpenDRIVE ``.xodr`` file,
    relative to the scenario file; needs the ``maps`` extra) and ``route`` (``RouteSpec``) instead of
    ``segments`` or ``waypoints``: the road is the route's corridor (``tracker.maps.route_road``), its
    lanes those of the map along the route, which may begin and end (a vehicle must start where its lane
    exists; traffic keeps its lane, so a lane that ends squeezes its vehicles onto its boundary)."""

    lanes: StrictInt = Field(default=2, ge=1, le=6)
    lane_width: StrictFloat = Field(default=3.5, ge=2.5, le=5.0)
    closed: StrictBool = False
    start: tuple[StrictFloat, StrictFloat, StrictFloat] | None = None
    segments: list[tuple[StrictFloat, StrictFloat, StrictFloat]] | None = Field(default=None, min_length=1)
    waypoints: list[tuple[StrictFloat, StrictFloat]] | None = Field(default=None, min_length=2)
    headings: list[StrictFloat] | None = None
    grade: StrictFloat = Field(default=0.0, ge=-0.15, le=0.15)
    bank: StrictFloat = Field(default=0.0, ge=-0.15, le=0.15)
    oncoming: StrictInt = Field(default=0, ge=0, le=6)
    drive_on: Literal["right", "left"] = "right"
    parking: Literal["right", "left", "both"] | None = None
    parking_width: StrictFloat = Field(default=PARKING_WIDTH, ge=2.0, le=3.5)
    map: StrictStr | None = Field(default=None, min_length=1)
    route: RouteSpec | None = None

    @model_validator(mode="after")
    def _lanes(self) -> RoadSpec:
        if self.oncoming > self.lanes:
            raise ValueError(f"road.oncoming = {self.oncoming}: at most road.lanes ({self.lanes}) of the driving lanes can carry oncoming traffic")
        if self.parking is None and self.parking_width != PARKING_WIDTH:
            raise ValueError("road.parking_width needs road.parking (\"right\", \"left\" or \"both\")")
        if self.drive_on != "right" and self.oncoming == 0:
            raise ValueError("road.drive_on applies to two-way roads; give road.oncoming (the lanes against s) too")
        return self

    @model_validator(mode="after")
    def _shape(self) -> RoadSpec:
        if self.closed and self.grade != 0.0:
            raise ValueError(f"road.grade = {self.grade!r}: a closed road cannot climb all the way round; use 0 (bank is allowed)")
        if (self.map is None) != (self.route is None):
            raise ValueError("road.map and road.route go together: a lane map file and the route through it")
        if sum(x is not None for x in (self.segments, self.waypoints, self.map)) != 1:
            raise ValueError("road: give exactly one of `segments` (curvature profile), `waypoints` or `map` (with `route`)")
        if self.map is not None:
            fixed = [k for k in ("lanes", "lane_width", "closed", "start", "headings", "grade", "bank", "oncoming",
                                 "drive_on", "parking", "parking_width") if k in self.model_fields_set]
            if fixed:
                raise ValueError(f"road.{fixed[0]}: a road from a lane map takes its lanes and shape from the map "
                                 "(road.map, road.route); leave it out")
        if self.waypoints is not None and self.start is not None:
            raise ValueError("road.start applies to `segments` only; a waypoint road starts at its first waypoint")
        if self.headings is not None:
            if self.waypoints is None:
                raise ValueError("road.headings needs `waypoints`")
            if len(self.headings) != len(self.waypoints):
                raise ValueError(
                    f"road.headings has {len(self.headings)} entries; it needs one per waypoint ({len(self.waypoints)})"
                )
        if self.segments is not None:
            half = self.half_width
            limit = min(MAX_CURVATURE, 1.0 / (2.0 * half))
            for i, (length, k0, k1) in enumerate(self.segments):
                if not length > 0:
                    raise ValueError(f"road.segments[{i}] length = {length!r}: must be > 0 m")
                for name, k in (("kappa_start", k0), ("kappa_end", k1)):
                    if abs(k) > limit:
                        raise ValueError(
                            f"road.segments[{i}] {name} = {k!r}: |curvature| must be <= {limit:.4g} 1/m "
                            f"(radius >= {1 / limit:.1f} m for {self.lanes} lanes of {self.lane_width} m)"
                        )
        return self

    def to_config(self) -> dict[str, Any]:
        """Plain-data form (JSON-serialisable) from which ``RoadSpec.model_validate`` rebuilds it (a
        level road leaves out ``grade`` and ``bank``)."""
        out = self.model_dump(exclude_none=True)
        if self.map is not None:  # a lane map's road is its map and route, nothing else
            return {"map": out["map"], "route": out["route"]}
        for key in ("grade", "bank"):
            if out.get(key) == 0.0:
                del out[key]
        for key, default in (("oncoming", 0), ("drive_on", "right"), ("parking_width", PARKING_WIDTH)):
            if out.get(key) == default:
                del out[key]
        return out

    # -- the lanes across the road ----------------------------------------------------------------
    @property
    def total_lanes(self) -> int:
        """Lanes across the road: the driving ``lanes`` and the parking lanes (0, 1 or 2)."""
        return self.lanes + {None: 0, "right": 1, "left": 1, "both": 2}[self.parking]

    @property
    def half_width(self) -> float:
        """The largest distance (m) from the centerline to a road edge: the driving lanes are centred on
        the centerline, the parking lanes lie outside them."""
        half = 0.5 * self.lanes * self.lane_width
        return half + (self.parking_width if self.parking is not None else 0.0)

    def layout(self) -> LaneLayout | None:
        """The ``tracker.lanes.LaneLayout`` of a road with parking lanes (``None`` without: the road is then
        built from ``lanes``, ``lane_width``, ``oncoming`` and ``drive_on``). Driving lanes centred on the
        centerline, the ``oncoming`` leftmost (rightmost with ``drive_on = "left"``) against ``s``; a
        parking lane of ``parking_width`` on the right and/or left outside them, of the direction of the
        driving lane next to it."""
        if self.parking is None:
            return None
        driving = LaneLayout.uniform(self.lanes, self.lane_width, oncoming=self.oncoming, drive_on=self.drive_on)
        bounds = list(driving.boundaries[0])
        directions = [int(d) for d in driving.directions]
        kinds = ["driving"] * self.lanes
        if self.parking in ("right", "both"):
            bounds.insert(0, bounds[0] - self.parking_width)
            directions.insert(0, directions[0])
            kinds.insert(0, "parking")
        if self.parking in ("left", "both"):
            bounds.append(bounds[-1] + self.parking_width)
            directions.append(directions[-1])
            kinds.append("parking")
        return LaneLayout([0.0], [bounds], directions, kinds)

    def build(self) -> Road:
        """The ``tracker.Road`` this spec describes (raises ``ValueError`` if it cannot be built)."""
        if self.map is not None:
            assert self.route is not None
            return _map_road(self.map, self.route.start, self.route.goal,
                             None if self.route.via is None else tuple(tuple(p) for p in self.route.via))
        layout = self.layout()
        lanes: dict[str, Any]
        if layout is not None:
            lanes = {"layout": layout}
        elif self.oncoming:
            lanes = {"lanes": self.lanes, "lane_width": self.lane_width, "oncoming": self.oncoming, "drive_on": self.drive_on}
        else:
            lanes = {"lanes": self.lanes, "lane_width": self.lane_width}
        if self.segments is not None:
            return Road.from_curvature(
                self.segments,
                start=self.start or (0.0, 0.0, 0.0),
                closed=self.closed,
                **lanes,
            )
        return Road.from_waypoints(
            np.asarray(self.waypoints, dtype=float),
            None if self.headings is None else np.asarray(self.headings, dtype=float),
            closed=self.closed,
            **lanes,
        )


# -- maneuvers -----------------------------------------------------------------------------------
class LaneChange(_Model):
    """At time ``t`` (s) start a lane change to ``lane``, completed within ``duration`` s (a smooth
    quintic lateral profile). With ``wait_for_gap`` the start is delayed until the target lane is
    clear (no rectangle alongside, and MOBIL's safe-braking test for the new follower passes)."""

    kind: Literal["lane_change"]
    t: StrictFloat = Field(ge=0.0)
    lane: StrictInt = Field(ge=0)
    duration: StrictFloat = Field(default=4.0, ge=1.0, le=20.0)
    wait_for_gap: StrictBool = False


class SpeedChange(_Model):
    """At time ``t`` (s) set the target speed to ``speed`` (m/s), reached at up to ``accel`` m/s^2
    (both speeding up and slowing down; default 2, at most 8): the rate holds until the speed is
    within ``accel x 0.6 s`` of the target, which it then approaches smoothly (highway-env's
    speed-tracking gain). Re-accelerating from a stop is a speed change from 0."""

    kind: Literal["speed"]
    t: StrictFloat = Field(ge=0.0)
    speed: StrictFloat = Field(ge=0.0, le=MAX_SPEED)
    accel: StrictFloat = Field(default=2.0, gt=0.0, le=8.0)


class Brake(_Model):
    """At time ``t`` (s) brake at a constant ``decel`` m/s^2 (default 4, at most 9: 6-8 is an
    emergency stop) down to exactly ``speed`` m/s (default 0: a stop), then hold that speed; a stopped
    vehicle stands still until a later ``speed`` maneuver. Repeated stop-and-go is a list of brakes
    and speed changes. (The IDM term still brakes it harder behind a slower vehicle.)"""

    kind: Literal["brake"]
    t: StrictFloat = Field(ge=0.0)
    speed: StrictFloat = Field(default=0.0, ge=0.0, le=MAX_SPEED)
    decel: StrictFloat = Field(default=4.0, gt=0.0, le=9.0)


Maneuver = Annotated[Union[LaneChange, SpeedChange, Brake], Field(discriminator="kind")]

BEHAVIOURS = ("idm", "constant", "scripted")


# -- vehicles ------------------------------------------------------------------------------------
class VehicleSpec(_Model):
    """One vehicle at the start: ``lane`` (0 = rightmost), ``s`` (m, rectangle centre), ``speed``
    (m/s), ``behaviour``:

    - ``"idm"``: highway-env ``IDMVehicle`` (IDM car following, MOBIL lane changes unless
      ``lane_changes = false``), cruising at ``target_speed`` (default: ``speed``);
    - ``"constant"``: keeps its lane at constant ``speed``, ignoring traffic;
    - ``"scripted"``: keeps its lane and follows ``maneuvers`` (lane changes, speed changes,
      braking) at their times; IDM car following keeps it from running into the vehicle ahead.

    ``length`` (4.8 m; 2-20 m) and ``width`` (2.0 m; 0.6-3 m) size its rectangle: a 2.2 x 0.8 m
    motorcycle, a 6 x 2.1 m van, a 12-18 x 2.5 m truck or bus. ``height`` (m, 0.8-5; default by
    length, ``sim.world.truth.default_height``: motorcycle 1.2, car 1.5, van 2.0, truck 3.5) is seen only by
    the 3-D lidar. ``behaviour = "constant"`` with
    ``speed = 0`` is a vehicle standing still on the road (broken down, parked); such a vehicle may
    have ``facing = "backward"``: it stands facing against its lane's traffic (a car parked the other
    way round). Every other vehicle drives in its lane's direction: along ``s``, or against it in the
    oncoming lanes of a two-way road (``RoadSpec.oncoming``). A vehicle in a parking lane starts standing
    (speed 0); a scripted one can pull out (a speed change and a lane change to the driving lane of
    the same direction next to it). Lane changes stay within lanes of one direction. ``offset`` (0 m)
    moves the vehicle's path off its lane's centre (to the left of its driving direction; at most half
    the lane width): a motorcycle filtering between two lanes rides on the line between them."""

    lane: StrictInt = Field(ge=0)
    s: StrictFloat
    speed: StrictFloat = Field(ge=0.0, le=MAX_SPEED)
    behaviour: Literal["idm", "constant", "scripted"] = "idm"
    target_speed: StrictFloat | None = Field(default=None, ge=0.0, le=MAX_SPEED)
    lane_changes: StrictBool | None = None
    length: StrictFloat = Field(default=4.8, ge=2.0, le=20.0)
    width: StrictFloat = Field(default=2.0, ge=0.6, le=3.0)
    height: StrictFloat | None = Field(default=None, ge=0.8, le=5.0)
    maneuvers: list[Maneuver] = Field(default_factory=list)
    facing: Literal["forward", "backward"] = "forward"
    #: Lateral offset (m) of the vehicle's path from its lane's centre, to the left of its driving direction
    #: (0: the centre); at most half the lane width: a motorcycle riding on the line between two lanes.
    offset: StrictFloat = Field(default=0.0, ge=-2.5, le=2.5)

    @model_validator(mode="after")
    def _behaviour_fields(self) -> VehicleSpec:
        if self.facing == "backward" and not (self.behaviour == "constant" and self.speed == 0.0):
            raise ValueError("facing = \"backward\" (against the lane's traffic) needs a standing vehicle: "
                             "behaviour = \"constant\" and speed = 0")
        if self.maneuvers and self.behaviour != "scripted":
            raise ValueError(f"maneuvers need behaviour = \"scripted\"; this vehicle's behaviour is {self.behaviour!r}")
        if self.lane_changes and self.behaviour != "idm":
            raise ValueError(f"lane_changes = true needs behaviour = \"idm\"; this vehicle's behaviour is {self.behaviour!r}")
        if self.target_speed is not None and self.behaviour == "constant":
            raise ValueError("target_speed does not apply to behaviour \"constant\" (it keeps `speed`)")
        times = [m.t for m in self.maneuvers]
        if times != sorted(times):
            raise ValueError(f"maneuvers must be in time order; got t = {times}")
        return self

    @property
    def box_height(self) -> float:
        """The vehicle's height (m): ``height``, else the default for its length."""
        return float(self.height) if self.height is not None else float(default_height(self.length))

    @property
    def cruise_speed(self) -> float:
        """The speed (m/s) the vehicle initially aims for."""
        return self.speed if self.target_speed is None else self.target_speed

    @property
    def mobil(self) -> bool:
        """Whether MOBIL lane changes are on (idm only; default on for vehicles)."""
        return self.behaviour == "idm" and (True if self.lane_changes is None else self.lane_changes)

    def max_speed(self) -> float:
        """An upper bound (m/s) on the speeds this vehicle will aim for."""
        speeds = [self.speed, self.cruise_speed] + [m.speed for m in self.maneuvers if not isinstance(m, LaneChange)]
        return max(speeds)


class EgoSpec(VehicleSpec):
    """The ego vehicle (id 0): like ``VehicleSpec`` but MOBIL lane changes are off by default."""

    @property
    def mobil(self) -> bool:
        return self.behaviour == "idm" and bool(self.lane_changes)


# -- generator -----------------------------------------------------------------------------------
FloatRange = tuple[StrictFloat, StrictFloat]
IntRange = tuple[StrictInt, StrictInt]
#: Tolerance (absolute) on the sum of the generator's class shares.
SHARE_TOLERANCE = 1e-6
#: Bounds (m) of vehicle lengths and widths (those of ``VehicleSpec``).
LENGTH_BOUNDS = (2.0, 20.0)
WIDTH_BOUNDS = (0.6, 3.0)


def _extent(value: Any) -> Any:
    """A single number ``x`` (m) as the range ``(x, x)``; anything else unchanged."""
    if isinstance(value, float):
        return (value, value)
    return value


def _shown(extent: tuple[float, float]) -> str:
    """An extent as the user wrote it: ``6.0`` for ``(6.0, 6.0)``, else ``[low, high]``."""
    return repr(extent[0]) if extent[0] == extent[1] else repr(list(extent))


#: A length or width (m): a number or a range ``[low, high]``, stored as ``(low, high)``.
Extent = Annotated[FloatRange, BeforeValidator(_extent)]


class VehicleClass(_Model):
    """A class of drawn vehicles (``generator.classes``): ``name`` (letters, digits, "-", "_";
    unique), ``length`` and ``width`` (m; a number, or a range ``[low, high]`` drawn uniformly;
    stored as ``(low, high)``; lengths 2-20 m, widths 0.6-3 m and at most the lane width - 0.5 m)
    and ``share`` (the probability that a drawn vehicle is of this class, in (0, 1]; the shares of
    all classes sum to 1 within 1e-6); ``height`` (m, 0.8-5; default: the class's by ``name`` when it
    is car, van, truck, bus or motorcycle (``sim.world.truth.CLASS_HEIGHTS``), else by each vehicle's
    length). Checked by ``GeneratorSpec``, which knows the class's index."""

    name: StrictStr = Field(min_length=1, max_length=32)
    length: Extent
    width: Extent
    share: StrictFloat = Field(gt=0.0, le=1.0)
    height: StrictFloat | None = Field(default=None, ge=0.8, le=5.0)

    def height_of(self, length: float) -> float:
        """The height (m) of a vehicle of this class with ``length`` (m)."""
        if self.height is not None:
            return float(self.height)
        return float(default_height(length, self.name))


class GeneratorSpec(_Model):
    """Ranges ``[low, high]`` (drawn uniformly) from which each seed draws a new road and/or new
    traffic (``sim.world.generator``); defaults in brackets.

    Road (when the file has no ``[road]``): an open road of ``lanes`` [2, 3] lanes of ``lane_width``
    [3.5 m], alternating straights (``straight_length`` [30, 150] m) and curves (clothoid ramp in of
    ``ramp_length`` [20, 50] m, arc of ``arc_length`` [40, 160] m, ramp out), each curve turning left
    or right with curvature uniform in ``[1/radius_high, 1/radius_low]`` (``radius`` [60, 400] m),
    until it is long enough for the ego to drive the scenario's duration; a road that winds back to
    within its width plus ``sim.world.generator.ROAD_SELF_CLEARANCE`` (10 m) of itself is drawn again.
    Traffic (when the file has no ``[ego]`` and no ``[[vehicles]]``): the ego (idm, no MOBIL,
    ``ego_speed`` [14, 20] m/s) and ``vehicles`` [3, 8] others at ``spawn`` [-60, 120] m from the
    ego along the road, ``speed`` [12, 25] m/s, ``length`` [4.2, 5.2] m, ``width`` [1.7, 2.1] m
    (or, with ``classes`` [none], a class drawn by its ``share`` and that class's length and width;
    ``length`` / ``width`` must then be left out), placed without overlap (10 m between bumpers in
    a lane; a vehicle that finds no room after 50 draws is dropped). A fraction ``scripted_fraction`` [0.4] is scripted, ``constant_fraction`` [0]
    constant, the rest idm with MOBIL. Scripted vehicles get Poisson-timed lane changes to an
    adjacent lane (``lane_change_rate`` [0.08] per second, 3-6 s long, waiting for a gap) and speed
    changes (``speed_change_rate`` [0.04] per second, to a speed in ``speed``).
    Two-way roads: ``oncoming`` [0, 0] lanes of a drawn road (the leftmost; right-hand traffic) carry
    traffic against ``s`` (at most ``lanes`` - 1: the ego drives along ``s``); a drawn vehicle placed in
    one of them drives against ``s``, at ``oncoming_spawn`` [40, 400] m ahead of the ego (it meets the
    ego during the run), and changes lanes only among the oncoming lanes. With ``[0, 0]`` nothing about
    the drawn scenarios changes."""

    straight_length: FloatRange = (30.0, 150.0)
    arc_length: FloatRange = (40.0, 160.0)
    ramp_length: FloatRange = (20.0, 50.0)
    radius: FloatRange = (60.0, 400.0)
    lanes: IntRange = (2, 3)
    lane_width: StrictFloat = Field(default=3.5, ge=2.5, le=5.0)
    vehicles: IntRange = (3, 8)
    speed: FloatRange = (12.0, 25.0)
    ego_speed: FloatRange = (14.0, 20.0)
    spawn: FloatRange = (-60.0, 120.0)
    length: FloatRange = (4.2, 5.2)
    width: FloatRange = (1.7, 2.1)
    scripted_fraction: StrictFloat = Field(default=0.4, ge=0.0, le=1.0)
    constant_fraction: StrictFloat = Field(default=0.0, ge=0.0, le=1.0)
    lane_change_rate: StrictFloat = Field(default=0.08, ge=0.0, le=1.0)
    speed_change_rate: StrictFloat = Field(default=0.04, ge=0.0, le=1.0)
    classes: list[VehicleClass] | None = Field(default=None, min_length=1, max_length=16)
    oncoming: IntRange = (0, 0)
    oncoming_spawn: FloatRange = (40.0, 400.0)

    @model_validator(mode="after")
    def _classes(self) -> GeneratorSpec:
        if self.classes is None:
            return self
        both = sorted({"length", "width"} & self.model_fields_set)
        if both:
            raise ValueError(
                f"generator.{both[0]}: not used when generator.classes is given (each class has its own "
                "length and width); drop it"
            )
        names = [c.name for c in self.classes]
        for i, c in enumerate(self.classes):
            if not _NAME.match(c.name):
                raise ValueError(f"generator.classes[{i}].name = {c.name!r}: use letters, digits, '-' and '_'")
            if c.name in names[:i]:
                raise ValueError(f"generator.classes[{i}].name = {c.name!r}: class names must be unique")
            for field, (low, high) in (("length", LENGTH_BOUNDS), ("width", WIDTH_BOUNDS)):
                lo, hi = getattr(c, field)
                if lo > hi:
                    raise ValueError(f"generator.classes[{i}].{field} = {[lo, hi]}: low must be <= high")
                if lo < low or hi > high:
                    raise ValueError(f"generator.classes[{i}].{field} = {_shown((lo, hi))}: must lie within [{low}, {high}] m")
        total = math.fsum(c.share for c in self.classes)
        if abs(total - 1.0) > SHARE_TOLERANCE:
            shares = ", ".join(f"{c.name} {c.share!r}" for c in self.classes)
            raise ValueError(
                f"generator.classes share: the shares sum to {total:.9g} ({shares}); they must sum to 1 "
                f"(within {SHARE_TOLERANCE:g})"
            )
        for i, c in enumerate(self.classes):
            if c.width[1] > self.lane_width - 0.5:
                raise ValueError(
                    f"generator.classes[{i}].width = {_shown(c.width)}: widths must leave 0.5 m in a {self.lane_width} m lane"
                )
        return self

    def class_bounds(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The classes as arrays: cumulative shares (K,) rescaled to end at exactly 1 (the shares sum
        to 1 within ``SHARE_TOLERANCE``), length bounds (K, 2) and width bounds (K, 2) in m. Without
        ``classes``: one class from ``length`` / ``width``."""
        if self.classes is None:
            return np.ones(1), np.array([self.length], float), np.array([self.width], float)
        cumulative = np.cumsum([c.share for c in self.classes])
        cumulative /= cumulative[-1]
        return (
            cumulative,
            np.array([c.length for c in self.classes], float),
            np.array([c.width for c in self.classes], float),
        )

    @model_validator(mode="after")
    def _ranges(self) -> GeneratorSpec:
        positive = {"straight_length", "arc_length", "ramp_length", "radius", "length", "width"}
        nonneg = {"speed", "ego_speed", "vehicles", "oncoming", "oncoming_spawn"}
        for name in type(self).model_fields:
            value = getattr(self, name)
            if not isinstance(value, tuple):
                continue
            lo, hi = value
            if lo > hi:
                raise ValueError(f"generator.{name} = {list(value)}: low must be <= high")
            if name in positive and lo <= 0:
                raise ValueError(f"generator.{name} = {list(value)}: values must be > 0")
            if name in nonneg and lo < 0:
                raise ValueError(f"generator.{name} = {list(value)}: values must be >= 0")
        if self.lanes[0] < 1 or self.lanes[1] > 6:
            raise ValueError(f"generator.lanes = {list(self.lanes)}: lanes must be within 1..6")
        if self.oncoming[0] < 0 or self.oncoming[1] >= self.lanes[0]:
            raise ValueError(f"generator.oncoming = {list(self.oncoming)}: must lie within 0..{self.lanes[0] - 1} "
                             f"(fewer than the fewest lanes drawn, generator.lanes = {list(self.lanes)}: the ego drives along s)")
        if self.speed[1] > MAX_SPEED or self.ego_speed[1] > MAX_SPEED:
            raise ValueError(f"generator speeds must be <= {MAX_SPEED} m/s")
        if self.scripted_fraction + self.constant_fraction > 1.0:
            raise ValueError("generator.scripted_fraction + constant_fraction must be <= 1")
        if self.width[1] > self.lane_width - 0.5:
            raise ValueError(f"generator.width = {list(self.width)}: widths must leave 0.5 m in a {self.lane_width} m lane")
        half = 0.5 * self.lanes[1] * self.lane_width
        if self.radius[0] < max(1.0 / MAX_CURVATURE, 2.0 * half):
            raise ValueError(
                f"generator.radius = {list(self.radius)}: radii must be >= {max(1.0 / MAX_CURVATURE, 2.0 * half):.1f} m"
            )
        if self.spawn[1] - self.spawn[0] < 20.0:
            raise ValueError(f"generator.spawn = {list(self.spawn)}: the range must span at least 20 m")
        return self


# -- families ------------------------------------------------------------------------------------
class FamilySpec(_Model):
    """A safety-critical scenario family (``sim.world.families``): ``kind`` names the family and
    ``params`` gives, for every parameter of that kind, the range ``[low, high]`` each seed draws it
    from (uniformly). Every parameter must be in the file: the ranges are the scenario's design.
    ``sim.world.families.FAMILIES`` lists the kinds, their parameters, units and hard bounds."""

    kind: StrictStr = Field(min_length=1)
    params: dict[str, FloatRange]

    @model_validator(mode="after")
    def _known(self) -> FamilySpec:
        from sim.world.families import check_family

        check_family(self.kind, self.params)
        return self


# -- faults --------------------------------------------------------------------------------------
#: A time interval ``[start, end)`` (s).
Interval = tuple[StrictFloat, StrictFloat]


class FaultsSpec(_Model):
    """Sensor faults injected by the runner (``sim.sensors.faults``); every default is "no fault".

    - ``lidar_dropout``: intervals ``[start, end)`` (s) in which lidar frames carry no points (the
      frame still arrives, with the ego pose and any radar detections);
    - ``radar_dropout``: intervals ``[start, end)`` (s) in which frames carry no radar detections;
      ``radar_missing`` (false): no radar detections in the whole run;
    - ``lidar_time_offset`` (0 s; at least 0, below the lidar's period): each scan is measured this
      long before the time it is stamped with, while the ego pose and the radar keep the true time (a
      lidar clock running late, or an uncompensated latency);
    - ``lidar_spikes`` (0; a fraction in [0, 1]): each point of a scan is, with this probability,
      moved along its ray to a range drawn uniformly in the lidar's ``[min_range, max_range]``;
    - ``duplicate_frames`` (none): times (s); the first frame at or after each time is delivered
      twice (the same frame, the same timestamp)."""

    lidar_dropout: list[Interval] = Field(default_factory=list, max_length=100)
    radar_dropout: list[Interval] = Field(default_factory=list, max_length=100)
    radar_missing: StrictBool = False
    lidar_time_offset: StrictFloat = Field(default=0.0, ge=0.0, lt=1.0)
    lidar_spikes: StrictFloat = Field(default=0.0, ge=0.0, le=1.0)
    duplicate_frames: list[StrictFloat] = Field(default_factory=list, max_length=1000)

    @model_validator(mode="after")
    def _intervals(self) -> FaultsSpec:
        for name in ("lidar_dropout", "radar_dropout"):
            for i, (start, end) in enumerate(getattr(self, name)):
                if not 0.0 <= start < end:
                    raise ValueError(f"faults.{name}[{i}] = {[start, end]}: need 0 <= start < end (s)")
        for i, t in enumerate(self.duplicate_frames):
            if t < 0.0:
                raise ValueError(f"faults.duplicate_frames[{i}] = {t!r}: times must be >= 0 s")
        return self

    @property
    def active(self) -> bool:
        """Whether any fault is set."""
        return bool(self.lidar_dropout or self.radar_dropout or self.radar_missing or self.lidar_time_offset
                    or self.lidar_spikes or self.duplicate_frames)

    def check_duration(self, duration: float) -> None:
        """``ValueError`` when an interval ends after ``duration`` (s) or a duplicate time is not before it."""
        for name in ("lidar_dropout", "radar_dropout"):
            for i, (start, end) in enumerate(getattr(self, name)):
                if end > duration:
                    raise ValueError(f"faults.{name}[{i}] = {[start, end]}: must end by the duration ({duration} s)")
        for i, t in enumerate(self.duplicate_frames):
            if t >= duration:
                raise ValueError(f"faults.duplicate_frames[{i}] = {t!r}: must be < duration ({duration} s)")


# -- replayed traffic ----------------------------------------------------------------------------
class ReplaySpec(_Model):
    """Recorded traffic to replay (``sim.world.replay``) instead of simulated traffic: ``file`` a CommonRoad
    scenario (``.xml`` or ``.xml.gz``, relative to the scenario file; needs the ``maps`` extra), its lane
    map and recorded vehicles; ``ego`` the id of the recorded vehicle that carries the sensors (default:
    the rule of ``sim.world.recording.Recording.pick_ego``); ``truth`` "smoothed" (default: the
    recording through ``sim.world.smoothing``) or "raw" (as recorded). The road is the ego's route
    through the map; the scenario's ``duration`` defaults to the ego's recorded time."""

    file: StrictStr = Field(min_length=1)
    ego: StrictInt | None = None
    truth: Literal["smoothed", "raw"] = "smoothed"


# -- the scenario --------------------------------------------------------------------------------
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_-]*$")


def scenario_name(text: str, fallback: str = "recording") -> str:
    """``text`` made a valid scenario name (``_NAME``, at most 64 characters): other characters become
    "-", leading "-" and "_" go; ``fallback`` when nothing is left (a recording's file name as a name)."""
    name = "".join(c if c.isalnum() or c in "-_" else "-" for c in text).lstrip("-_")[:64]
    return name or fallback


class ScenarioSpec(_Model):
    """A validated scenario: ``name``, one-line ``description``, ``duration`` (s), ``road``, ``ego``,
    ``vehicles``, optional ``sensors`` / ``tracker`` overrides (tables passed to the runner, applied
    with ``apply_overrides``) and an optional ``generator``. With a generator the file may leave out
    the road and/or the traffic (ego and vehicles together); ``sim.world.generator.realize(spec, seed)``
    draws what is missing. A concrete spec (no generator) has a road and an ego.

    Checks beyond types: lanes exist, vehicles fit in their lanes, start positions lie on the road
    and rectangles do not overlap (0.5 m clearance), maneuvers fit in the duration and target
    existing lanes, and on an open road the ego cannot reach the road's end within the duration."""

    name: StrictStr = Field(min_length=1, max_length=64)
    description: StrictStr = Field(min_length=1, max_length=200)
    duration: StrictFloat = Field(gt=0.0, le=3600.0)
    road: RoadSpec | None = None
    ego: EgoSpec | None = None
    vehicles: list[VehicleSpec] = Field(default_factory=list)
    sensors: dict[str, Any] = Field(default_factory=dict)
    tracker: dict[str, Any] = Field(default_factory=dict)
    faults: FaultsSpec | None = None
    generator: GeneratorSpec | None = None
    replay: ReplaySpec | None = None
    family: FamilySpec | None = None
    #: Time (s) of the scenario's critical moment (a family's cut-in, reveal or brake; None: none named);
    #: the closed loop's sensor-dropout modes silence the sensors around it.
    hazard_t: StrictFloat | None = Field(default=None, ge=0.0)

    _road: Road | None = PrivateAttr(default=None)
    _source: Path | None = PrivateAttr(default=None)

    @model_validator(mode="before")
    @classmethod
    def _replay_duration(cls, data: Any) -> Any:
        """A replay's duration defaults to its ego's recorded time (read from the recording): filled in
        here when the ``[replay]`` table's fields are usable; otherwise those fields' own checks report what
        is wrong, and a placeholder stands in for the duration (no replay spec validates without them)."""
        replay = data.get("replay") if isinstance(data, dict) else None
        if not isinstance(replay, dict) or "duration" in data:
            return data
        ego = replay.get("ego")
        usable = (isinstance(replay.get("file"), str) and replay.get("truth", "smoothed") in ("smoothed", "raw")
                  and (ego is None or (isinstance(ego, int) and not isinstance(ego, bool))))
        if not usable:
            return {**data, "duration": 1.0}
        return {**data, "duration": _replay_checked(replay["file"], replay.get("truth", "smoothed"), ego)[0]}

    @model_validator(mode="after")
    def _consistent(self) -> ScenarioSpec:
        if not _NAME.match(self.name):
            raise ValueError(f"name = {self.name!r}: use letters, digits, '-' and '_' (starting with a letter or digit)")
        if "\n" in self.description:
            raise ValueError("description must be one line")
        if self.faults is not None:
            self.faults.check_duration(self.duration)
        if self.replay is not None:
            return self._check_replay()
        if self.hazard_t is not None and self.hazard_t >= self.duration:
            raise ValueError(f"hazard_t = {self.hazard_t}: must be < duration ({self.duration} s)")
        if self.family is not None:
            given = [k for k in ("road", "ego", "vehicles", "generator") if k in self.model_fields_set]
            if given:
                raise ValueError(f"{given[0]}: a family draws its road and traffic per seed (family.kind = "
                                 f"{self.family.kind!r}); leave it out")
            return self
        if self.generator is None:
            if self.road is None:
                raise ValueError("road: missing; a scenario without a [generator] needs a [road] table")
            if self.ego is None:
                raise ValueError("ego: missing; a scenario without a [generator] needs an [ego] table")
        else:
            if self.ego is None and self.vehicles:
                raise ValueError("ego: missing; give [ego] and [[vehicles]] together, or neither (the generator draws both)")
            if self.road is not None and self.ego is not None:
                raise ValueError("generator: nothing to draw; the file already has a road and traffic (drop [generator] or one of them)")
            if self.road is not None and self.ego is None and (self.road.map is not None or self.road.parking is not None):
                what = "a lane map's lanes, which begin and end" if self.road.map is not None else "parking lanes"
                raise ValueError(f"generator: cannot draw traffic on a road with {what}; the drawn traffic needs "
                                 "driving lanes that exist along the whole road (give [ego] and [[vehicles]])")
            if self.road is not None and self.generator.oncoming != (0, 0):
                raise ValueError(f"generator.oncoming = {list(self.generator.oncoming)}: applies to drawn roads; this "
                                 "file's [road] sets its own (road.oncoming)")
        if self.generator is not None and self.generator.classes and self.road is not None:
            for i, c in enumerate(self.generator.classes):
                if c.width[1] > self.road.lane_width - 0.5:
                    raise ValueError(
                        f"generator.classes[{i}].width = {_shown(c.width)}: must be <= {self.road.lane_width - 0.5} m "
                        "(this road's lane width - 0.5 m)"
                    )
        if self.road is not None:
            try:
                road = self.road.build()
            except ValueError as exc:
                raise ValueError(f"road: cannot be built: {exc}") from None
            self._road = road
            if self.ego is not None:
                self._check_traffic(road)
        return self

    def _check_replay(self) -> ScenarioSpec:
        assert self.replay is not None
        given = [k for k in ("road", "ego", "vehicles", "generator") if k in self.model_fields_set]
        if given:
            raise ValueError(f"{given[0]}: a replay takes its road and traffic from the recording (replay.file); leave it out")
        longest, self._road = _replay_checked(self.replay.file, self.replay.truth, self.replay.ego)
        if self.duration > longest + 1e-9:
            raise ValueError(f"duration = {self.duration}: the ego is recorded for {longest:g} s; use at most that")
        return self

    # -- cross-field checks -------------------------------------------------------------------
    def _all(self) -> list[tuple[str, VehicleSpec]]:
        out: list[tuple[str, VehicleSpec]] = [("ego", self.ego)] if self.ego is not None else []
        return out + [(f"vehicles[{i}]", v) for i, v in enumerate(self.vehicles)]

    def _check_traffic(self, road: Road) -> None:
        assert self.road is not None
        lanes = road.lanes
        allowed_lanes = f"this road has lanes 0..{lanes - 1} (0 is the rightmost)"
        directions = [int(d) for d in road.lane_directions]
        kinds = road.layout.kinds
        for where, v in self._all():
            if v.lane >= lanes:
                raise ValueError(f"{where}.lane = {v.lane}: lane {v.lane} does not exist; {allowed_lanes}")
            widths = lane_widths(road, v.s)
            if widths[v.lane] < MIN_LANE_WIDTH:
                raise ValueError(f"{where}.lane = {v.lane}: lane {v.lane} does not exist at s = {v.s} m (it begins or "
                                 "ends elsewhere along this road)")
            if abs(v.offset) > 0.5 * widths[v.lane]:
                raise ValueError(f"{where}.offset = {v.offset}: must be within half the lane's width "
                                 f"({0.5 * widths[v.lane]:g} m) of its centre")
            if v.width > widths[v.lane] - 0.5:
                what = "lane width" if kinds[v.lane] == "driving" else f"the {kinds[v.lane]} lane's width"
                raise ValueError(f"{where}.width = {v.width}: must be <= {widths[v.lane] - 0.5:g} m ({what} - 0.5 m)")
            if where == "ego" and kinds[v.lane] != "driving":
                raise ValueError(f"ego.lane = {v.lane}: lane {v.lane} is a {kinds[v.lane]} lane; the ego drives in a driving lane")
            if kinds[v.lane] != "driving" and v.speed != 0.0:
                raise ValueError(f"{where}.speed = {v.speed}: lane {v.lane} is a {kinds[v.lane]} lane; a vehicle there "
                                 "must start standing (speed = 0) and may pull out with maneuvers")
            if v.facing == "backward" and where == "ego":
                raise ValueError("ego.facing = 'backward': only a standing vehicle can face against its lane's traffic")
            if not road.closed and not (0.5 * v.length <= v.s <= road.length - 0.5 * v.length):
                raise ValueError(
                    f"{where}.s = {v.s}: must be within [{0.5 * v.length:.2f}, {road.length - 0.5 * v.length:.2f}] m "
                    f"(the vehicle must lie on this open road of length {road.length:.2f} m)"
                )
            if road.closed and not (0.0 <= v.s < road.length):
                raise ValueError(f"{where}.s = {v.s}: must be within [0, {road.length:.2f}) m on this closed road")
            for j, m in enumerate(v.maneuvers):
                if m.t >= self.duration:
                    raise ValueError(f"{where}.maneuvers[{j}].t = {m.t}: must be < duration ({self.duration} s)")
                if isinstance(m, LaneChange):
                    if m.lane >= lanes:
                        raise ValueError(f"{where}.maneuvers[{j}].lane = {m.lane}: lane {m.lane} does not exist; {allowed_lanes}")
                    if directions[m.lane] != directions[v.lane]:
                        raise ValueError(
                            f"{where}.maneuvers[{j}].lane = {m.lane}: lane {m.lane} carries traffic "
                            f"{_DIRECTION_WORDS[directions[m.lane]]} and this vehicle's lane {v.lane} "
                            f"{_DIRECTION_WORDS[directions[v.lane]]}; lane changes stay within one direction")
        assert self.ego is not None
        if not road.closed:
            # s runs faster than the vehicle on the inside of a curve: s_dot = v / (1 - kappa n)
            kappa = np.abs(road.curvature(np.linspace(0.0, road.length, max(2, int(road.length) + 1))))
            edge = max(abs(road.right_edge), abs(road.left_edge))
            factor = 1.0 / max(1.0 - float(kappa.max()) * edge, 0.1)
            travel = factor * self.ego.max_speed() * self.duration + 0.5 * self.ego.length
            if directions[self.ego.lane] < 0 and self.ego.s - travel < 0.0:
                raise ValueError(
                    f"duration = {self.duration}: the ego (s = {self.ego.s} m, up to {self.ego.max_speed()} m/s, "
                    f"driving against s in lane {self.ego.lane}) could reach s = {self.ego.s - travel:.1f} m, beyond "
                    "the start of this open road; start the ego further along or shorten the duration"
                )
            reach = self.ego.s + travel
            if directions[self.ego.lane] > 0 and reach > road.length:
                raise ValueError(
                    f"duration = {self.duration}: the ego (s = {self.ego.s} m, up to {self.ego.max_speed()} m/s) "
                    f"could reach s = {reach:.1f} m, beyond the end of this open road ({road.length:.1f} m); "
                    "lengthen the road, start the ego earlier or shorten the duration"
                )
        self._check_overlap(road)

    def _check_overlap(self, road: Road) -> None:
        items = self._all()
        s = np.array([v.s for _, v in items])
        directions = road.lane_directions
        n = np.array([road.lane_center(v.lane, None if road.uniform else v.s) + directions[v.lane] * v.offset
                      for _, v in items])
        xy = road.to_cartesian(s, n)
        yaw = road.heading(s)
        corners = rectangle_corners(
            xy, yaw, np.array([v.length for _, v in items]) + START_CLEARANCE, np.array([v.width for _, v in items]) + START_CLEARANCE
        )
        reach = 0.5 * np.hypot([v.length for _, v in items], [v.width for _, v in items]) + START_CLEARANCE
        for i in range(len(items)):
            for j in range(i + 1, len(items)):
                if np.hypot(*(xy[i] - xy[j])) > reach[i] + reach[j]:
                    continue
                if polygons_overlap(corners[i], corners[j]):
                    raise ValueError(
                        f"{items[j][0]}.s = {items[j][1].s}: its rectangle overlaps {items[i][0]}'s "
                        f"(s = {items[i][1].s}, lane {items[i][1].lane}) at the start; keep at least "
                        f"{START_CLEARANCE} m between vehicles"
                    )

    # -- conveniences -------------------------------------------------------------------------
    @property
    def source(self) -> Path | None:
        """The file this spec was loaded from (``None`` when built in code)."""
        return self._source

    @property
    def concrete(self) -> bool:
        """Whether the spec can be simulated as it is (no generator or family section)."""
        return self.generator is None and self.family is None

    def build_road(self) -> Road:
        """The ``tracker.Road`` of this scenario (built once at validation and shared)."""
        if self.replay is not None:
            if self._road is None:
                self._road = _replay_checked(self.replay.file, self.replay.truth, self.replay.ego)[1]
            return self._road
        if self.road is None:
            raise ValueError(f"scenario {self.name!r} has no road; draw one with sim.world.generator.realize(spec, seed)")
        if self._road is None:
            self._road = self.road.build()
        return self._road


_DIRECTION_WORDS = {1: "along s", -1: "against s"}


def _replay_checked(path: str, truth: str, ego: int | None) -> tuple[float, Road]:
    """The ego's recorded time (s) in the recording ``path`` and the replay's road (``sim.world.replay``);
    ``ValueError`` naming the field (``replay.file`` or ``replay.ego``) when either cannot be had."""
    from sim.world.replay import load_recording, replay_ego, replay_road

    try:
        recording, _ = load_recording(path, truth)
    except (OSError, ValueError, ImportError) as exc:
        raise ValueError(f"replay.file = {path!r}: {' '.join(str(exc).split())}") from None
    try:
        car = recording.vehicle(replay_ego(path, ego))
    except ValueError as exc:
        raise ValueError(f"replay.ego = {ego!r}: {' '.join(str(exc).split())}") from None
    try:
        road = replay_road(path, truth, car.id)
    except (OSError, ValueError, ImportError) as exc:
        raise ValueError(f"replay.file = {path!r}: {' '.join(str(exc).split())}") from None
    return round(car.end - car.start, 9), road


@functools.lru_cache(maxsize=8)
def _map_road(path: str, start: tuple[float, float, float], goal: tuple[float, float] | None,
              via: tuple[tuple[float, float], ...] | None) -> Road:
    """The road of a route through the lane map ``path`` (``tracker.maps``; read once per process)."""
    from tracker.maps import read_map, route_road  # numpy and scipy only; the readers import their libraries

    if not Path(path).is_file():
        raise ValueError(f"road.map = {path!r}: no such file")
    try:
        return route_road(read_map(path), start, goal, via=via)
    except ImportError as exc:
        raise ValueError(f"road.map = {path!r}: {exc}") from None


def lane_widths(road: Road, s: float = 0.0) -> list[float]:
    """Each lane's width (m) at ``s``, lane 0 (rightmost) first: ``road.lane_width`` on a road of equal lanes,
    else from its layout's boundaries (0 where a lane does not exist)."""
    if getattr(road.layout, "_uniform", None) is not None:
        return [float(road.lane_width)] * road.lanes
    return [float(w) for w in np.diff(road.layout.boundaries_at(float(s)))]


def polygons_overlap(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two convex polygons (K, 2) overlap (separating-axis test; touching counts as not)."""
    for poly in (a, b):
        edges = np.roll(poly, -1, axis=0) - poly
        normals = np.column_stack([-edges[:, 1], edges[:, 0]])
        pa, pb = a @ normals.T, b @ normals.T
        if np.any((pa.max(axis=0) <= pb.min(axis=0)) | (pb.max(axis=0) <= pa.min(axis=0))):
            return False
    return True


# -- loading and error messages ------------------------------------------------------------------
def _loc_text(loc: tuple[Any, ...]) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        elif part in ("lane_change", "speed", "brake") and out.endswith("]") and "maneuvers" in out:
            continue  # pydantic's discriminator tag, not a field
        else:
            out += ("." if out else "") + str(part)
    return out


def _model_at(loc: tuple[Any, ...]) -> type[BaseModel] | None:
    """The model class that holds the field at ``loc`` (for listing the allowed keys)."""
    sub: dict[str, type[BaseModel]] = {
        "road": RoadSpec, "ego": EgoSpec, "vehicles": VehicleSpec, "generator": GeneratorSpec, "classes": VehicleClass,
        "faults": FaultsSpec,
    }
    tags: dict[str, type[BaseModel]] = {"lane_change": LaneChange, "speed": SpeedChange, "brake": Brake}
    model: type[BaseModel] | None = ScenarioSpec
    parts = iter(p for p in loc[:-1] if not isinstance(p, int))
    for part in parts:
        if model is None:
            return None
        if part == "maneuvers":
            model = tags.get(next(parts, None))  # type: ignore[arg-type]
        else:
            model = sub.get(part) if part in model.model_fields else None
    return model


def _describe(error: dict[str, Any]) -> str:
    loc = tuple(error.get("loc", ()))
    kind = error.get("type", "")
    field = _loc_text(loc)
    msg = str(error.get("msg", ""))
    if kind == "value_error":
        text = msg.removeprefix("Value error, ")
        return text
    value = error.get("input")
    if kind == "missing":
        return f"{field}: missing; this field is required"
    if kind == "extra_forbidden":
        model = _model_at(loc)
        allowed = ", ".join(model.model_fields) if model is not None else "see the scenario format in sim/world/scenario.py"
        return f"{field} = {value!r}: unknown key; allowed keys here: {allowed}"
    if kind == "union_tag_invalid" or kind == "union_tag_not_found":
        return f"{field}: maneuver kind must be one of 'lane_change', 'speed', 'brake'; got {value!r}"
    if kind == "tuple_type" and "classes" in loc and loc[-1] in ("length", "width"):
        return f"{field} = {value!r}: must be a float (e.g. 6.0) or a range [low, high] of floats (m)"
    if kind == "literal_error":
        return f"{field} = {value!r}: {msg[0].lower() + msg[1:]}"
    shown = value if not isinstance(value, dict) else "{...}"
    return f"{field} = {shown!r}: {msg[0].lower() + msg[1:]}"


def format_validation_error(exc: ValidationError, where: str) -> str:
    """A readable message for a pydantic ``ValidationError`` of a scenario from ``where``."""
    lines = [_describe(e) for e in exc.errors(include_url=False)]
    if len(lines) == 1:
        return f"{where}: {lines[0]}"
    return f"{where}: {len(lines)} problems:\n" + "\n".join(f"  - {line}" for line in lines)


def parse_scenario(data: dict[str, Any], where: str = "<scenario>") -> ScenarioSpec:
    """Validate a scenario given as plain data (as read from TOML); errors name ``where``."""
    try:
        return ScenarioSpec.model_validate(data)
    except ValidationError as exc:
        raise ScenarioError(format_validation_error(exc, where)) from None


def resolve_scenario_path(path: str | Path) -> Path:
    """``path`` if it exists; else a scenario of that name in the repository's ``scenarios/``
    folder (``"cut-in"`` -> ``scenarios/cut-in.toml``)."""
    p = Path(path)
    if p.is_file():
        return p
    found = shipped_scenario(path)
    if found is None:
        raise ScenarioError(f"{path}: no such scenario file (nor a shipped scenario of that name in {SCENARIO_DIR})")
    return found


def shipped_scenario(name: str | Path) -> Path | None:
    """The shipped scenario or suite file ``name`` names (``None``: none): ``scenarios/NAME.toml``, a path
    inside ``scenarios/`` (``real/real-us101-3``), or a file of that name one folder down
    (``real-us101-3`` -> ``scenarios/real/real-us101-3.toml``)."""
    p = Path(name)
    rel = p if p.suffix == ".toml" else p.with_name(f"{p.name}.toml")
    for candidate in (SCENARIO_DIR / rel.name, SCENARIO_DIR / rel, *sorted(SCENARIO_DIR.glob(f"*/{rel.name}"))):
        if candidate.is_file():
            return candidate
    return None


def load_scenario(path: str | Path) -> ScenarioSpec:
    """Read and validate a scenario TOML file (or a shipped scenario's name, e.g. ``"cut-in"``).

    Raises ``ScenarioError`` (a ``ValueError``) naming the file, the field, the value and what is
    allowed; unknown keys are errors."""
    p = resolve_scenario_path(path)
    data = read_scenario_data(p)
    if "scenarios" in data and "road" not in data and "generator" not in data and "replay" not in data:
        raise ScenarioError(f"{p}: this is a suite file (it lists scenarios); load it with sim.world.scenario.load_suite")
    spec = parse_scenario(data, str(p))
    spec._source = p
    return spec


def read_scenario_data(path: Path) -> dict[str, Any]:
    """The plain data of the scenario file ``path`` (TOML), with a lane map's path (``road.map``) made
    absolute from the file's folder; ``ScenarioError`` for a file that is not TOML."""
    try:
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{path}: not valid TOML: {exc}") from None
    road = data.get("road")
    if isinstance(road, dict) and isinstance(road.get("map"), str) and not Path(road["map"]).is_absolute():
        road["map"] = str((Path(path).parent / road["map"]).resolve())  # a map file relative to the scenario file
    replay = data.get("replay")
    if isinstance(replay, dict) and isinstance(replay.get("file"), str) and not Path(replay["file"]).is_absolute():
        replay["file"] = str((Path(path).parent / replay["file"]).resolve())  # a recording relative to the scenario file
    return data


# -- suites --------------------------------------------------------------------------------------
class SuiteSpec(_Model):
    """A suite file: ``name``, ``description`` and ``scenarios`` (file names relative to the suite)."""

    name: StrictStr = Field(min_length=1)
    description: StrictStr = Field(min_length=1)
    scenarios: list[StrictStr] = Field(min_length=1)


class Suite:
    """A loaded suite: ``name``, ``description`` and the ``paths`` of its scenario files."""

    def __init__(self, name: str, description: str, paths: list[Path]) -> None:
        self.name, self.description, self.paths = name, description, paths

    def load(self) -> list[ScenarioSpec]:
        """Every scenario of the suite, validated."""
        return [load_scenario(p) for p in self.paths]


def load_suite(path: str | Path) -> Suite:
    """Read a suite file (``scenarios = ["cut-in.toml", ...]``); every listed file must exist."""
    p = Path(path)
    if not p.is_file():
        p = shipped_scenario(p) or p
    try:
        with open(p, "rb") as fh:
            data = tomllib.load(fh)
    except FileNotFoundError:
        raise ScenarioError(f"{path}: no such suite file") from None
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{p}: not valid TOML: {exc}") from None
    try:
        suite = SuiteSpec.model_validate(data)
    except ValidationError as exc:
        raise ScenarioError(format_validation_error(exc, str(p))) from None
    paths = []
    for i, name in enumerate(suite.scenarios):
        q = p.parent / (name if name.endswith(".toml") else f"{name}.toml")
        if not q.exists():
            raise ScenarioError(f"{p}: scenarios[{i}] = {name!r}: no such file {q}")
        paths.append(q)
    return Suite(suite.name, suite.description, paths)


def is_suite_file(path: Path) -> bool:
    """Whether a TOML file is a suite (has ``scenarios`` and no ``road``/``generator``)."""
    try:
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
    except (OSError, tomllib.TOMLDecodeError):
        return False
    return "scenarios" in data and "road" not in data and "generator" not in data and "replay" not in data


# -- overrides -----------------------------------------------------------------------------------
def apply_overrides(config: Any, overrides: dict[str, Any], where: str) -> Any:
    """A copy of the dataclass ``config`` with the fields in ``overrides`` replaced (nested
    dataclass fields take nested tables). Unknown keys raise ``ScenarioError`` naming ``where``
    (e.g. ``"scenarios/cut-in.toml: sensors.lidar"``) and the allowed keys; the config's own
    checks (its ``__post_init__``) report bad values."""
    if not is_dataclass(config):
        raise TypeError(f"apply_overrides needs a dataclass instance; got {type(config).__name__}")
    names = {f.name for f in fields(config)}
    changes: dict[str, Any] = {}
    for key, value in overrides.items():
        if key not in names:
            raise ScenarioError(f"{where}.{key} = {value!r}: unknown key; allowed keys here: {', '.join(sorted(names))}")
        current = getattr(config, key)
        if is_dataclass(current) and isinstance(value, dict):
            changes[key] = apply_overrides(current, value, f"{where}.{key}")
        else:
            changes[key] = value
    try:
        return replace(config, **changes)
    except (TypeError, ValueError) as exc:
        raise ScenarioError(f"{where}: {exc}") from None

