"""A world that replays recorded traffic: the truth the sensors see and the tracker is scored against.

``ReplayWorld.from_spec(spec, seed)`` serves a scenario with a ``[replay]`` table (``sim.world.scenario.ReplaySpec``)
the way ``sim.world.world.World`` serves simulated traffic: ``truth_at(t)`` and ``poses_at(t)`` give a
``Snapshot`` at any time ``t`` (s) of the run, ``road`` is the scenario's road. The run's time 0 is the
ego's first sample; each vehicle is present between its first and last sample and linear between
samples (``RecordedVehicle.state_at``; the samples are 0.1 s apart in the CommonRoad recordings).
A vehicle whose recording ends while it is on the road (it drove out of the recorded area, which ends
before the lane map does, but not out of the world) is carried on at its last speed and heading until its
centre leaves the road (``MAX_CARRY`` at most): it does not vanish in front of the sensors (``info``
counts these vehicles). The
ego is one of the recorded vehicles (``ReplaySpec.ego``, default ``Recording.pick_ego`` with
``EGO_RANGE``); it is not among the snapshot's vehicles. Recorded vehicles do not react to anything.

The truth is the smoothed recording by default (``sim.world.smoothing``; ``truth = "raw"`` keeps the
recorded samples). The road is the route through the recording's lane map from the ego's first pose
to its last position, extended by ``EGO_RANGE`` ahead and behind where the map goes on
(``tracker.maps.route_road`` with ``onward`` and ``behind``): the road the ego's sensors see. A lane map
ends where the recorded area does (the US-101 maps end 10-30 m past some egos' last positions): beyond
it nothing is scored, and the recorded vehicles leave there. The seed does not change the traffic (it is
recorded); it seeds the sensors as in every run.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path
from typing import Any

import numpy as np

from sim.world.recording import RecordedVehicle, Recording, read_commonroad_recording
from sim.world.smoothing import SmoothingReport, smooth_recording
from sim.world.truth import CLASS_HEIGHTS, EgoPose, Snapshot, default_height
from tracker import Road
from tracker.angles import wrap_angle

#: Range (m) within which the default ego rule counts neighbours (the default lidar's range).
EGO_RANGE = 100.0
#: Longest time (s) a vehicle whose recording ends on the road is carried on (``ReplayWorld``).
MAX_CARRY = 20.0
#: Step (s) of the search for where a carried-on vehicle leaves the road.
CARRY_STEP = 0.1


@functools.lru_cache(maxsize=16)
def _recorded(path: str) -> Recording:
    """The recording of the CommonRoad file ``path``, read once per process."""
    return read_commonroad_recording(path)


@functools.lru_cache(maxsize=16)
def _smoothed(path: str) -> tuple[Recording, SmoothingReport]:
    """The recording of ``path`` smoothed, once per process."""
    return smooth_recording(_recorded(path))


def load_recording(path: str, truth: str = "smoothed") -> tuple[Recording, SmoothingReport | None]:
    """The recording of the CommonRoad file ``path`` (read once per process), smoothed (``truth =
    "smoothed"``, with what smoothing changed) or as recorded (``"raw"``, no report)."""
    if truth not in ("smoothed", "raw"):
        raise ValueError(f"truth must be 'smoothed' or 'raw'; got {truth!r}")
    return (_recorded(path), None) if truth == "raw" else _smoothed(path)


@functools.lru_cache(maxsize=16)
def _default_ego(path: str) -> int:
    return _recorded(path).pick_ego(EGO_RANGE)


def replay_ego(source: str | Recording, ego: int | None) -> int:
    """The ego's id in ``source`` (a CommonRoad file's path, or a recording): ``ego`` when it is one of the
    recording's vehicles (``ValueError`` naming the ids otherwise), else the default rule's
    (``Recording.pick_ego(EGO_RANGE)``), applied to the recording as recorded, so that smoothed and raw
    truth replay the same ego."""
    recording = _recorded(source) if isinstance(source, str) else source
    if ego is None:
        return _default_ego(source) if isinstance(source, str) else recording.pick_ego(EGO_RANGE)
    return recording.vehicle(int(ego)).id


@functools.lru_cache(maxsize=16)
def replay_road(path: str, truth: str, ego: int) -> Road:
    """The road of the ego's route through the recording's lane map (module docstring)."""
    recording, _ = load_recording(path, truth)
    return route_of(recording, ego, path)


def route_of(recording: Recording, ego: int, name: str = "") -> Road:
    """The road of vehicle ``ego``'s route through ``recording.map_file`` (module docstring); ``ValueError``
    naming the recording when it has no lane map or the route cannot be built."""
    car = recording.vehicle(ego)
    start = (float(car.xy[0, 0]), float(car.xy[0, 1]), float(car.yaw[0]))
    goal = (float(car.xy[-1, 0]), float(car.xy[-1, 1]))
    return route_between(recording, start, goal, f"ego {ego}'s route", name)


def route_between(recording: Recording, start: tuple[float, float, float], goal: tuple[float, float] | None,
                  what: str, name: str = "") -> Road:
    """The road of the route through ``recording.map_file`` from ``start`` (x m, y m, yaw rad) to ``goal``
    (x, y m; ``None`` or within 1 m of the start: on from the start's pose), ``EGO_RANGE`` ahead and behind
    where the map goes on; ``ValueError`` naming the recording and ``what`` when it cannot be built."""
    from tracker.maps import read_map, route_road

    path = recording.map_file
    if path is None:
        raise ValueError(f"recording {recording.name!r} has no lane map (map_file); give its road")
    if goal is not None and math.hypot(goal[0] - start[0], goal[1] - start[1]) < 1.0:
        goal = None  # a standing ego: the route goes on from its pose
    try:
        return route_road(read_map(path), start, goal, onward=EGO_RANGE, behind=EGO_RANGE)
    except ValueError as exc:
        raise ValueError(f"{Path(name or path).name}: no road along {what}: {exc}") from None


class ReplayWorld:
    """Recorded traffic as a world (module docstring): ``recording`` as the sensors are to see it (already
    smoothed or not; ``truth`` says which, ``smoothing`` what smoothing changed), on ``road``, with the
    vehicle ``ego`` (default: ``replay_ego``'s rule) carrying the sensors. ``from_spec`` builds it for a
    scenario with a ``[replay]`` table; ``spec`` is that scenario (``None`` when built from a recording
    in code, ``sim.evaluation.runner.run_recording``)."""

    def __init__(self, recording: Recording, road: Road, ego: int | None = None, *, truth: str = "raw",
                 smoothing: SmoothingReport | None = None, spec: Any = None, seed: int = 0) -> None:
        if truth not in ("smoothed", "raw"):
            raise ValueError(f"truth must be 'smoothed' or 'raw'; got {truth!r}")
        self.spec = spec
        self.seed = int(seed)
        self.recording, self.smoothing, self.truth = recording, smoothing, truth
        self.ego_id = replay_ego(recording, ego)
        self.road = road
        ego_car = self.recording.vehicle(self.ego_id)
        self._ego = ego_car
        self._set_traffic([v for v in self.recording.vehicles if v.id != self.ego_id], ego_car.start)

    def _set_traffic(self, others: list[RecordedVehicle], t0: float) -> None:
        """The recorded vehicles ``others`` are the truth; run time 0 is recording time ``t0`` (s)."""
        self.ground = None
        self.removed: dict[int, float] = {}
        self.collisions: list[tuple[float, int, int]] = []
        self.t0 = float(t0)
        self._others = others
        self._heights = {v.id: float(CLASS_HEIGHTS.get(v.kind, default_height(v.length))) for v in self._others}
        self._carry_until = {v.id: self._leaves_road(v) for v in self._others if v.end < self.t0 + self.duration}
        self.t = 0.0

    @classmethod
    def from_spec(cls, spec: Any, seed: int = 0) -> ReplayWorld:
        """The world of a scenario (``sim.world.scenario.ScenarioSpec``; it imports this module) with a
        ``[replay]`` table (its recording read once per process)."""
        if spec.replay is None:
            raise ValueError(f"ReplayWorld needs a scenario with a [replay] table; {spec.name!r} has none")
        replay = spec.replay
        recording, smoothing = load_recording(replay.file, replay.truth)
        return cls(recording, spec.build_road(), replay_ego(replay.file, replay.ego), truth=replay.truth,
                   smoothing=smoothing, spec=spec, seed=seed)

    def _carried(self, v: RecordedVehicle, when: float) -> tuple[float, float, float, float, float]:
        """``v`` carried on from its last sample to time ``when`` (s): its last speed along its last heading."""
        dt = when - v.end
        yaw, speed = float(v.yaw[-1]), float(v.v[-1])
        return (float(v.xy[-1, 0]) + speed * math.cos(yaw) * dt, float(v.xy[-1, 1]) + speed * math.sin(yaw) * dt,
                yaw, speed, 0.0)

    def _leaves_road(self, v: RecordedVehicle) -> float:
        """The recording time (s) until which ``v`` is carried on after its last sample: when its centre
        leaves the road (between the edges, ``0 <= s <= length`` on an open road), at most ``MAX_CARRY``."""
        if not bool(self.road.on_road(v.xy[-1:])[0]):
            return v.end  # it left the road before its recording ended
        times = v.end + CARRY_STEP * np.arange(1, int(round(MAX_CARRY / CARRY_STEP)) + 1)
        yaw, speed = float(v.yaw[-1]), float(v.v[-1])  # as _carried: the last speed along the last heading
        on = self.road.on_road(v.xy[-1] + np.outer(speed * (times - v.end), [math.cos(yaw), math.sin(yaw)]))
        off = np.flatnonzero(~on)
        if not off.size:
            return float(times[-1])
        return float(times[off[0] - 1]) if off[0] > 0 else v.end

    @property
    def duration(self) -> float:
        """The ego's recorded time (s): the longest run."""
        return self._ego.end - self._ego.start

    def info(self) -> dict[str, Any]:
        """What a run reports of the replay (``metrics.json``): ``replay_recording`` (name), ``replay_ego``
        (id), ``replay_truth`` ("smoothed" or "raw"), ``replay_vehicles`` (recorded vehicles besides the
        ego), ``replay_carried_on`` (of them, those carried on after their recording ends) and, for smoothed truth, ``replay_widths_bounded`` and ``replay_position_change_rms_m``
        (``sim.world.smoothing.SmoothingReport``)."""
        carried = sum(1 for v in self._others if self._carry_until.get(v.id, v.end) > v.end)
        out: dict[str, Any] = {"replay_recording": self.recording.name, "replay_ego": self.ego_id,
                               "replay_truth": self.truth, "replay_vehicles": len(self._others),
                               "replay_carried_on": carried}
        if self.smoothing is not None:
            out["replay_widths_bounded"] = self.smoothing.widths_bounded
            out["replay_position_change_rms_m"] = self.smoothing.position_change_rms_m
        return out

    def truth_at(self, t: float) -> Snapshot:
        """The truth ``Snapshot`` at run time ``t`` (s), with the vehicles' road coordinates."""
        return self._snapshot(t, road_coordinates=True)

    def poses_at(self, t: float) -> Snapshot:
        """The poses at ``t`` without road coordinates (NaN), as ``World.poses_at`` (what a radar needs)."""
        return self._snapshot(t, road_coordinates=False)

    def _snapshot(self, t: float, road_coordinates: bool) -> Snapshot:
        if not (isinstance(t, (int, float, np.floating)) and math.isfinite(t)):
            raise ValueError(f"{type(self).__name__}: t must be a finite number of seconds; got {t!r}")
        self.t = float(t)
        when = self.t0 + min(max(float(t), 0.0), self.duration)
        ids, cols = self._others_at(when)
        xy = np.ascontiguousarray(cols[:2].T)
        yaw = wrap_angle(cols[2])
        road: dict[str, np.ndarray] = {}
        if road_coordinates and len(ids):
            s, n = self.road.to_frenet(xy)
            s, n = np.asarray(s, dtype=float).reshape(-1), np.asarray(n, dtype=float).reshape(-1)
            along = s if self.road.closed else np.clip(s, 0.0, self.road.length)
            theta = self.road.heading(along)
            kappa = self.road.curvature(along)
            xi = wrap_angle(yaw - theta)
            s_dot = cols[3] * np.cos(xi) / np.maximum(1.0 - kappa * n, 1e-6)
            road = {"s": s, "n": n, "xi": xi, "xi_dot": cols[4] - kappa * s_dot}
        return Snapshot(t=self.t, ego=self._ego_pose(when), ids=ids, xy=xy, yaw=yaw, v=cols[3], yaw_rate=cols[4],
                        length=cols[5], width=cols[6], height=cols[7], **road)

    def _others_at(self, when: float) -> tuple[np.ndarray, np.ndarray]:
        """The recorded vehicles present at recording time ``when`` (s): their ids and the ``(8, k)`` rows
        x, y (m), yaw (rad), v (m/s), yaw rate (rad/s), length, width, height (m)."""
        rows, ids = [], []
        for v in self._others:
            state = v.state_at(when)
            if state is None and v.end < when <= self._carry_until.get(v.id, v.end):
                state = self._carried(v, when)
            if state is not None:
                rows.append((*state, v.length, v.width, self._heights[v.id]))
                ids.append(v.id)
        return np.array(ids, dtype=int), np.array(rows, dtype=float).reshape(-1, 8).T.copy()

    def _ego_pose(self, when: float) -> EgoPose:
        """The recorded ego's pose at recording time ``when`` (s)."""
        ego = self._ego.state_at(when)
        assert ego is not None
        return EgoPose(x=ego[0], y=ego[1], yaw=float(wrap_angle(ego[2])), v=ego[3], yaw_rate=ego[4],
                       length=self._ego.length, width=self._ego.width,
                       height=float(CLASS_HEIGHTS.get(self._ego.kind, default_height(self._ego.length))))


__all__ = ["EGO_RANGE", "ReplayWorld", "load_recording", "replay_ego", "replay_road", "route_between", "route_of"]
