"""Recorded traffic: what a replay needs of a recording, and a reader for CommonRoad scenario files.

A ``Recording`` holds, per recorded vehicle (``RecordedVehicle``), its sample times (s), its rectangle
centre (m, in the map's frame G), heading (rad), speed (m/s), yaw rate (rad/s), length and width (m)
and class (``kind``: "car", "truck", "bus", "motorcycle", ...), plus the lane map the recording was made
on. Any source can build one; ``read_commonroad_recording`` reads a CommonRoad scenario file (``.xml`` or
gzip-compressed ``.xml.gz``; needs commonroad-io, the ``maps`` extra): its dynamic obstacles, their
shapes (rectangles; others are refused) and types.

**The ego of a replay** (``Recording.pick_ego``): one of the recorded vehicles carries the sensors and
leaves the truth set. Without a choice, the rule is: among the vehicles recorded from the first sample
to the last (within ``PRESENT_SLACK`` samples) and no longer than ``EGO_MAX_LENGTH`` (a car, whose
roof a lidar fits), the one with the most (other vehicle, sample) pairs within the lidar's range of it,
the lowest id on a tie; when none is recorded throughout, the longest-recorded such vehicle.

**The planning problem** (``Recording.planning``, ``PlanningProblem``): a CommonRoad file also poses a
planning problem, a vehicle's initial state and a goal (a region of the map and a time interval). In the
NGSIM-derived files it is a recorded vehicle taken out of the traffic (its initial state lies 3-10 m
from every recorded vehicle's), so a driver of one's own can take its place: the closed loop drives its
ego from there (``sim.world.driven``). A file with several problems gives the one with the lowest id.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tracker.checks import finite_array

#: Longest vehicle (m) the default ego rule takes (``Recording.pick_ego``).
EGO_MAX_LENGTH = 6.0
#: Samples of slack at either end for "recorded throughout" (``Recording.pick_ego``).
PRESENT_SLACK = 1.5


def _array(value: object, name: str, where: str, shape: tuple[int, ...]) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.shape != shape:
        raise ValueError(f"{where}: {name} has shape {arr.shape}, expected {shape}")
    return finite_array(arr, f"{where}: {name}")


@dataclass(frozen=True)
class RecordedVehicle:
    """One recorded vehicle: ``id``; sample times ``t`` (K,) s, strictly increasing; centre ``xy`` (K, 2) m
    in G; heading ``yaw`` (K,) rad (unwrapped on construction); ``v`` (K,) speed m/s (>= 0); ``yaw_rate``
    (K,) rad/s (default: the central differences of ``yaw``, 0 for a single sample); ``length``,
    ``width`` m (> 0); ``kind`` its class (default "car")."""

    id: int
    t: np.ndarray
    xy: np.ndarray
    yaw: np.ndarray
    v: np.ndarray
    length: float
    width: float
    kind: str = "car"
    yaw_rate: np.ndarray | None = field(default=None)

    def __post_init__(self) -> None:
        where = f"recorded vehicle {self.id}"
        t = np.asarray(self.t, dtype=float).reshape(-1)
        count = len(t)
        if count == 0:
            raise ValueError(f"{where}: no samples")
        t = _array(t, "t", where, (count,))
        if count > 1 and not (np.diff(t) > 0).all():
            raise ValueError(f"{where}: sample times must be strictly increasing")
        xy = _array(self.xy, "xy", where, (count, 2))
        yaw = np.unwrap(_array(self.yaw, "yaw", where, (count,)))
        v = _array(self.v, "v", where, (count,))
        if (v < 0).any():
            raise ValueError(f"{where}: speed v must be >= 0 m/s (a heading gives the direction)")
        if self.yaw_rate is None:
            rate = np.gradient(yaw, t) if count > 1 else np.zeros(1)
        else:
            rate = _array(self.yaw_rate, "yaw_rate", where, (count,))
        for name in ("length", "width"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float, np.floating)) and math.isfinite(value) and value > 0):
                raise ValueError(f"{where}: {name} must be a positive number of metres; got {value!r}")
        object.__setattr__(self, "id", int(self.id))
        object.__setattr__(self, "length", float(self.length))
        object.__setattr__(self, "width", float(self.width))
        for name, arr in (("t", t), ("xy", xy), ("yaw", yaw), ("v", v), ("yaw_rate", rate)):
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    def __len__(self) -> int:
        return len(self.t)

    @property
    def start(self) -> float:
        """First sample time (s)."""
        return float(self.t[0])

    @property
    def end(self) -> float:
        """Last sample time (s)."""
        return float(self.t[-1])

    def state_at(self, t: float) -> tuple[float, float, float, float, float] | None:
        """``(x, y, yaw, v, yaw_rate)`` at time ``t`` (s), linear between samples (yaw unwrapped); ``None``
        outside ``[start, end]``."""
        if t < self.t[0] - 1e-9 or t > self.t[-1] + 1e-9:
            return None
        if len(self.t) == 1:
            return (float(self.xy[0, 0]), float(self.xy[0, 1]), float(self.yaw[0]), float(self.v[0]), float(self.yaw_rate[0]))
        i = int(min(max(np.searchsorted(self.t, t) - 1, 0), len(self.t) - 2))
        a = min(max((t - self.t[i]) / (self.t[i + 1] - self.t[i]), 0.0), 1.0)

        def mix(arr: np.ndarray) -> float:
            return float((1.0 - a) * arr[i] + a * arr[i + 1])

        return (float((1.0 - a) * self.xy[i, 0] + a * self.xy[i + 1, 0]), float((1.0 - a) * self.xy[i, 1] + a * self.xy[i + 1, 1]),
                mix(self.yaw), mix(self.v), mix(self.yaw_rate))


@dataclass(frozen=True)
class PlanningProblem:
    """A planning problem of a recording (module docstring): its ``id``; the initial state at time ``t``
    (s, the recording's clock): centre ``x``, ``y`` (m, G), heading ``yaw`` (rad), speed ``v`` (m/s); the
    goal region ``goal`` (polygons, each ``(k, 2)`` vertices in m, G; empty: the goal is a time only) and
    the goal's time interval ``goal_time`` (s, on the recording's clock; ``None``: any time)."""

    id: int
    t: float
    x: float
    y: float
    yaw: float
    v: float
    goal: tuple[np.ndarray, ...] = ()
    goal_time: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        where = f"planning problem {self.id}"
        for name in ("t", "x", "y", "yaw", "v"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"{where}: its initial {name} is {getattr(self, name)!r}; it must be finite")
        polygons = tuple(finite_array(p, f"{where} goal polygon") for p in self.goal)
        for p in polygons:
            if p.ndim != 2 or p.shape[1] != 2 or len(p) < 3:
                raise ValueError(f"{where}: a goal polygon needs (k >= 3, 2) vertices; got shape {p.shape}")
        object.__setattr__(self, "goal", polygons)
        if self.goal_time is not None and not self.goal_time[0] <= self.goal_time[1]:
            raise ValueError(f"{where}: goal time interval {self.goal_time!r} ends before it starts")

    @property
    def goal_center(self) -> tuple[float, float] | None:
        """The centroid (m, G) of the goal region (by area, over its polygons); ``None`` without one."""
        if not self.goal:
            return None
        area = cx = cy = 0.0
        for p in self.goal:
            x, y = p[:, 0], p[:, 1]
            cross = x * np.roll(y, -1) - np.roll(x, -1) * y
            a = 0.5 * float(cross.sum())
            if abs(a) < 1e-12:  # a degenerate polygon: its vertices' mean
                area, cx, cy = area + 1e-12, cx + 1e-12 * float(x.mean()), cy + 1e-12 * float(y.mean())
                continue
            area += a
            cx += float(((x + np.roll(x, -1)) * cross).sum()) / 6.0
            cy += float(((y + np.roll(y, -1)) * cross).sum()) / 6.0
        return cx / area, cy / area

    def reached(self, xy: np.ndarray) -> np.ndarray:
        """Whether the points ``xy`` (``(k, 2)`` m, G) lie in the goal region (False everywhere without one)."""
        from tracker.maps.graph import points_in_polygon

        pts = np.asarray(xy, dtype=float).reshape(-1, 2)
        inside = np.zeros(len(pts), dtype=bool)
        for p in self.goal:
            inside |= points_in_polygon(pts, p)
        return inside


@dataclass(frozen=True)
class Recording:
    """Recorded traffic: ``name``, the ``vehicles`` (unique ids), the lane map it was recorded on
    (``map_file``, a file ``tracker.maps.read_map`` reads; ``None``: none), ``dt``, the sampling step
    (s; for the ego rule's slack, ``None``: the median step of the samples) and the file's ``planning``
    problem (``None``: none)."""

    name: str
    vehicles: tuple[RecordedVehicle, ...]
    map_file: Path | None = None
    dt: float | None = None
    planning: PlanningProblem | None = None

    def __post_init__(self) -> None:
        vehicles = tuple(self.vehicles)
        if not vehicles:
            raise ValueError(f"recording {self.name!r}: no vehicles")
        ids = [v.id for v in vehicles]
        if len(set(ids)) != len(ids):
            dup = min(i for i in ids if ids.count(i) > 1)
            raise ValueError(f"recording {self.name!r}: vehicle id {dup} appears twice")
        object.__setattr__(self, "vehicles", vehicles)
        if self.dt is None:
            steps = np.concatenate([np.diff(v.t) for v in vehicles])
            object.__setattr__(self, "dt", float(np.median(steps)) if steps.size else 0.1)

    def __iter__(self) -> Iterator[RecordedVehicle]:
        return iter(self.vehicles)

    def __len__(self) -> int:
        return len(self.vehicles)

    @property
    def ids(self) -> list[int]:
        """The vehicles' ids, in recording order."""
        return [v.id for v in self.vehicles]

    @property
    def span(self) -> tuple[float, float]:
        """First and last sample time (s) over all vehicles."""
        return min(v.start for v in self.vehicles), max(v.end for v in self.vehicles)

    def vehicle(self, vid: int) -> RecordedVehicle:
        """The vehicle with id ``vid``; ``ValueError`` naming the ids when there is none."""
        for v in self.vehicles:
            if v.id == vid:
                return v
        shown = ", ".join(str(i) for i in self.ids[:12]) + (", ..." if len(self) > 12 else "")
        raise ValueError(f"recording {self.name!r}: no vehicle {vid}; its vehicles are {shown}")

    def pick_ego(self, max_range: float) -> int:
        """The default ego (module docstring): recorded throughout, at most ``EGO_MAX_LENGTH`` long, with
        the most (other vehicle, sample) pairs within ``max_range`` m."""
        t0, t1 = self.span
        slack = PRESENT_SLACK * float(self.dt)  # type: ignore[arg-type]
        cars = [v for v in self.vehicles if v.length <= EGO_MAX_LENGTH] or list(self.vehicles)
        full = [v for v in cars if v.start <= t0 + slack and v.end >= t1 - slack]
        if not full:
            longest = max(v.end - v.start for v in cars)
            full = [v for v in cars if v.end - v.start >= longest - 1e-9]

        def neighbours(ego: RecordedVehicle) -> int:
            count = 0
            for other in self.vehicles:
                if other.id == ego.id:
                    continue
                _, ia, ib = np.intersect1d(np.round(ego.t, 6), np.round(other.t, 6), return_indices=True)
                d = np.hypot(*(ego.xy[ia] - other.xy[ib]).T)
                count += int(np.count_nonzero(d <= max_range))
            return count

        return min(full, key=lambda v: (-neighbours(v), v.id)).id


# -- CommonRoad -----------------------------------------------------------------------------------
def read_commonroad_recording(path: str | Path) -> Recording:
    """The recorded vehicles of the CommonRoad scenario ``path`` (``.xml`` or ``.xml.gz``): each dynamic
    obstacle with a rectangle shape and a trajectory, its initial state then its trajectory's states
    (times ``time_step * dt``), its type's value as ``kind``; the file itself is the lane map.

    Raises ``FileNotFoundError`` for a missing file, ``ValueError`` (one line naming the file and the
    obstacle) for a broken one or a vehicle that is not a rectangle, ``ImportError`` without
    commonroad-io."""
    from tracker.maps.commonroad import open_commonroad

    path = Path(path)
    scenario, problems = open_commonroad(path, what="recording", lanelets_only=False, planning=True)
    dt = float(scenario.dt)
    vehicles = []
    for ob in scenario.dynamic_obstacles:
        where = f"{path.name}: obstacle {ob.obstacle_id}"
        shape = ob.obstacle_shape
        if not (hasattr(shape, "length") and hasattr(shape, "width")):
            raise ValueError(f"{where}: its shape is a {type(shape).__name__}; a replay needs rectangles")
        trajectory = getattr(ob.prediction, "trajectory", None)
        states = list(trajectory.state_list) if trajectory is not None else []
        if not states or ob.initial_state.time_step < states[0].time_step:
            states = [ob.initial_state, *states]
        try:
            steps = np.array([int(s.time_step) for s in states])
            xy = np.array([s.position for s in states], dtype=float)
            yaw = np.array([s.orientation for s in states], dtype=float)
            speed = np.array([getattr(s, "velocity", 0.0) for s in states], dtype=float)
        except (AttributeError, TypeError, ValueError) as exc:
            raise ValueError(f"{where}: a state lacks its position, orientation or time step ({exc})") from None
        # a recorded speed below zero is a vehicle reversing: the heading turns round, the speed stays >= 0
        yaw = np.where(speed < 0, yaw + math.pi, yaw)
        kind = getattr(getattr(ob, "obstacle_type", None), "value", "car")
        try:
            vehicles.append(RecordedVehicle(int(ob.obstacle_id), steps * dt, xy, yaw, np.abs(speed),
                                            float(shape.length), float(shape.width), str(kind)))
        except ValueError as exc:
            raise ValueError(f"{path.name}: {exc}") from None
    if not vehicles:
        raise ValueError(f"{path.name}: no recorded vehicles (dynamic obstacles) to replay")
    name = path.name.split(".")[0]
    return Recording(name, tuple(vehicles), map_file=path, dt=dt, planning=_planning_problem(problems, dt, path.name))


def _polygons(shape: object) -> list[np.ndarray]:
    """The polygons (vertices, m) of a commonroad-io shape or occupancy (through its shapely geometry)."""
    geometry = getattr(shape, "shapely_object", None)
    if geometry is None:
        return []
    parts = getattr(geometry, "geoms", [geometry])
    return [np.asarray(g.exterior.coords, dtype=float)[:-1] for g in parts if hasattr(g, "exterior")]


def _planning_problem(problems: object, dt: float, name: str) -> PlanningProblem | None:
    """The planning problem with the lowest id of a commonroad-io ``PlanningProblemSet`` (``None``: none);
    its goal: the union of its goal states' positions and the hull of their time intervals."""
    table = getattr(problems, "planning_problem_dict", None) or {}
    if not table:
        return None
    pid = min(table)
    problem = table[pid]
    where = f"{name}: planning problem {pid}"
    start = problem.initial_state
    try:
        t, x, y = float(start.time_step) * dt, float(start.position[0]), float(start.position[1])
        yaw, v = float(start.orientation), float(getattr(start, "velocity", 0.0))
    except (AttributeError, TypeError, ValueError, IndexError) as exc:
        raise ValueError(f"{where}: its initial state lacks a position, orientation or time step ({exc})") from None
    goal: list[np.ndarray] = []
    lo, hi = math.inf, -math.inf
    for state in problem.goal.state_list:
        position = getattr(state, "position", None)
        if position is not None:
            goal.extend(_polygons(position))
        step = getattr(state, "time_step", None)
        if step is not None:
            lo = min(lo, float(getattr(step, "start", step)) * dt)
            hi = max(hi, float(getattr(step, "end", step)) * dt)
    if v < 0.0:  # reversing: heading turned round, as for the recorded vehicles
        yaw, v = yaw + math.pi, -v
    try:
        return PlanningProblem(int(pid), t, x, y, yaw, v, tuple(goal), (lo, hi) if math.isfinite(lo) else None)
    except ValueError as exc:
        raise ValueError(f"{name}: {exc}") from None


__all__ = ["EGO_MAX_LENGTH", "PRESENT_SLACK", "PlanningProblem", "RecordedVehicle", "Recording", "read_commonroad_recording"]
