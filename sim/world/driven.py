"""Recorded traffic with an ego of one's own: the closed loop's world on real traffic.

``DrivenReplayWorld`` replays a recording as ``sim.world.replay.ReplayWorld`` does (the recorded vehicles,
smoothed by default, carried on past the end of their recording while on the road) and adds an ego that a
driver outside the world drives (the environment's agent, e.g. ``sim.env.planner``): it starts at the
recording's planning problem's initial state (``sim.world.recording.PlanningProblem``: in the NGSIM files a
recorded vehicle taken out of the traffic), as a car of ``EGO_LENGTH`` x ``EGO_WIDTH`` m (a planning
problem gives no size; the scenarios' default ego), and moves as the simulated world's vehicles do:
highway-env's kinematic bicycle model with the action held over each step of the internal 0.05 s grid
(``sim.world.world``; ``truth_at`` between grid times evaluates the held action without moving it).

**The recorded vehicles do not react to the ego.** They drive as recorded, into the ego too. Every
overlap of the ego's rectangle with a recorded vehicle's that starts at a grid time is a collision
``(t, 0, id)`` in ``collisions``, whoever caused it (``sim.studies.closed_loop`` pairs each with the
truth planner's run of the same recording to tell the tracker's from the replay's).

The road is the route through the recording's lane map from the initial state to the goal region's
centre, ``EGO_RANGE`` beyond either end (``sim.world.replay.route_between``). Run time 0 is the planning
problem's initial time; the duration is the end of the goal's time interval (the time the recorded
driver had), at most the recording's last sample. ``goal_reached_at`` is the first grid time the ego's
centre lay in the goal region (``None``: not yet).
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from sim.world.lanes import build_network, lane_index
from sim.world.recording import PlanningProblem, Recording
from sim.world.replay import ReplayWorld, load_recording, route_between
from sim.world.scenario import EgoSpec, polygons_overlap
from sim.world.traffic import ConstantCar, TrafficRoad
from sim.world.truth import EgoPose, default_height, rectangle_corners
from sim.world.world import (
    DEFAULT_STEP,
    TIME_TOLERANCE,
    WORLD_STREAM,
    VehicleState,
    forward_time,
    held_pose,
    held_state,
)
from tracker import Road

#: Length and width (m) of the driven ego: the scenarios' default ego (``sim.world.scenario.EgoSpec``).
EGO_LENGTH = float(EgoSpec.model_fields["length"].default)
EGO_WIDTH = float(EgoSpec.model_fields["width"].default)


def planning_of(recording: Recording) -> PlanningProblem:
    """The recording's planning problem; ``ValueError`` naming the recording when it has none."""
    if recording.planning is None:
        raise ValueError(f"recording {recording.name!r} has no planning problem: its ego cannot be driven "
                         "(the closed loop starts the ego at a planning problem's initial state)")
    return recording.planning


def planned_road(recording: Recording, name: str = "") -> Road:
    """The road of the planning problem's route (module docstring)."""
    p = planning_of(recording)
    return route_between(recording, (p.x, p.y, p.yaw), p.goal_center, f"planning problem {p.id}'s route", name)


def planned_duration(recording: Recording) -> float:
    """The run's duration (s): from the planning problem's initial time to the end of its goal's time
    interval, at most to the recording's last sample."""
    p = planning_of(recording)
    end = recording.span[1] if p.goal_time is None else min(p.goal_time[1], recording.span[1])
    if end <= p.t + 1e-9:
        raise ValueError(f"recording {recording.name!r}: planning problem {p.id} starts at {p.t:g} s, when the "
                         f"recording ends ({recording.span[1]:g} s); nothing to drive")
    return end - p.t


@functools.lru_cache(maxsize=16)
def _planned_road(path: str, truth: str) -> Road:
    recording, _ = load_recording(path, truth)
    return planned_road(recording, path)


def planned_run(path: str, truth: str = "smoothed") -> tuple[float, Road]:
    """``(duration s, road)`` of a driven replay of the CommonRoad file ``path`` (read once per process)."""
    recording, _ = load_recording(path, truth)
    return planned_duration(recording), _planned_road(path, truth)


class DrivenReplayWorld(ReplayWorld):
    """Recorded traffic and a driven ego (module docstring). ``recording`` (smoothed or not: ``truth`` says
    which) must have a planning problem; ``road`` is the route (default ``planned_road``); ``step`` the
    internal grid (s). ``ego`` is the highway-env vehicle (id 0) the driver replaces or acts on (as
    ``World.ego``), ``traffic`` the ``TrafficRoad`` it drives on (it alone: the recorded vehicles are not
    highway-env vehicles). ``from_spec`` builds it for a scenario with a ``[replay]`` table."""

    def __init__(self, recording: Recording, road: Road | None = None, *, truth: str = "raw",
                 smoothing: Any = None, spec: Any = None, seed: int = 0, step: float = DEFAULT_STEP) -> None:
        if truth not in ("smoothed", "raw"):
            raise ValueError(f"truth must be 'smoothed' or 'raw'; got {truth!r}")
        if not (isinstance(step, (int, float)) and 0.0 < step <= 0.1):
            raise ValueError(f"DrivenReplayWorld step must be in (0, 0.1] s; got {step!r}")
        self.spec = spec
        self.seed = int(seed)
        self.step = float(step)
        self.recording, self.smoothing, self.truth = recording, smoothing, truth
        self.planning = planning_of(recording)
        self._duration = planned_duration(recording)
        self.road = planned_road(recording) if road is None else road
        self.ego_id = 0
        self._set_traffic(list(recording.vehicles), self.planning.t)
        network, projector = build_network(self.road)
        rng = np.random.default_rng(np.random.SeedSequence(self.seed, spawn_key=(WORLD_STREAM,)))
        self.traffic = TrafficRoad(network, projector, self.road, np_random=rng, dt=self.step)
        p = self.planning
        s, n = self.road.to_frenet((p.x, p.y))
        lane = int(np.clip(self.road.lane_index(n, s).reshape(-1)[0], 0, self.road.lanes - 1))
        ego = ConstantCar(self.traffic, np.array([p.x, p.y], dtype=float), p.yaw, p.v, target_lane_index=lane_index(lane),
                          target_speed=p.v)
        ego._setup(0, EGO_LENGTH, EGO_WIDTH)
        self.traffic.vehicles = [ego]
        self.ego = ego
        self.heights = {0: default_height(EGO_LENGTH)}
        self.goal_reached_at: float | None = None
        self._k = 0
        self._overlapping: set[int] = set()
        self._check(0.0)
        self.traffic.time = 0.0
        self.traffic.act()

    @classmethod
    def from_spec(cls, spec: Any, seed: int = 0) -> DrivenReplayWorld:
        """The driven world of a scenario with a ``[replay]`` table (its ``ego`` must be unset: the driven
        ego is the planning problem's, not a recorded vehicle)."""
        if spec.replay is None:
            raise ValueError(f"DrivenReplayWorld needs a scenario with a [replay] table; {spec.name!r} has none")
        replay = spec.replay
        if replay.ego is not None:
            raise ValueError(f"{spec.name}: replay.ego = {replay.ego} names a recorded vehicle to carry the sensors; a "
                             "driven replay's ego is the recording's planning problem (leave replay.ego out)")
        recording, smoothing = load_recording(replay.file, replay.truth)
        return cls(recording, planned_run(replay.file, replay.truth)[1], truth=replay.truth, smoothing=smoothing,
                   spec=spec, seed=seed)

    # -- time -----------------------------------------------------------------------------------
    @property
    def duration(self) -> float:
        """The run's duration (s): ``planned_duration``."""
        return self._duration

    @property
    def grid_time(self) -> float:
        """Time (s) of the last internal grid state."""
        return self._k * self.step

    def advance(self, t: float) -> None:
        """Drive the ego forward to time ``t`` (s; not earlier than the last one), checking collisions and
        the goal at every grid time."""
        t = forward_time(t, self.t, "DrivenReplayWorld.advance")
        while (self._k + 1) * self.step <= t + TIME_TOLERANCE:
            self.traffic.step(self.step)
            self._k += 1
            self.traffic.time = self.grid_time
            self._check(self.grid_time)
            self.traffic.act()
        self.t = max(t, self.t)

    def _check(self, now: float) -> None:
        """Record the collisions that start at grid time ``now`` (s) and whether the goal is reached."""
        ego = self.ego
        xy = np.array([ego.position], dtype=float)
        if self.goal_reached_at is None and bool(self.planning.reached(xy)[0]):
            self.goal_reached_at = now
        when = self.t0 + min(now, self.duration)
        ids, cols = self._others_at(when)
        overlapping: set[int] = set()
        if len(ids):
            near = np.hypot(cols[0] - xy[0, 0], cols[1] - xy[0, 1]) < 0.5 * (np.hypot(cols[5], cols[6]) + ego.diagonal)
            if near.any():
                corners = rectangle_corners(np.concatenate([xy, cols[:2, near].T]), np.concatenate([[ego.heading], cols[2, near]]),
                                            np.concatenate([[ego.LENGTH], cols[5, near]]), np.concatenate([[ego.WIDTH], cols[6, near]]))
                for j, vid in enumerate(ids[near]):
                    if polygons_overlap(corners[0], corners[j + 1]):
                        overlapping.add(int(vid))
                        if int(vid) not in self._overlapping:
                            self.collisions.append((now, 0, int(vid)))
        self._overlapping = overlapping

    # -- truth ----------------------------------------------------------------------------------
    def truth_at(self, t: float) -> Any:
        """Drive to ``t`` (s), then the truth ``Snapshot`` there (the recorded vehicles with road coordinates)."""
        self.advance(t)
        return self._snapshot(t, road_coordinates=True)

    def poses_at(self, t: float) -> Any:
        """Drive to ``t`` (s), then the poses there without road coordinates (``World.poses_at``)."""
        self.advance(t)
        return self._snapshot(t, road_coordinates=False)

    def _ego_pose(self, when: float) -> EgoPose:
        _, x, y, yaw, v, yaw_rate, length, width, _, _ = held_pose(self.ego, max(self.t - self.grid_time, 0.0))
        return EgoPose(x=x, y=y, yaw=yaw, v=v, yaw_rate=yaw_rate, length=length, width=width, height=self.heights[0])

    def ego_state(self) -> VehicleState:
        """The ego's truth at the current time, with its road coordinates (``World.ego_state``)."""
        return VehicleState(*held_state(self.ego, max(self.t - self.grid_time, 0.0), self.road, self.traffic))

    def info(self) -> dict[str, Any]:
        """``ReplayWorld.info`` with ``replay_ego`` "planned" and the planning problem: ``replay_planning_problem``
        (id), ``goal_reached_s`` (run time the ego's centre entered the goal region; None: not reached) and
        ``goal_time_s`` (the goal's interval on the run's clock)."""
        out = super().info()
        p = self.planning
        out.update(replay_ego="planned", replay_vehicles=len(self._others), replay_planning_problem=p.id,
                   goal_reached_s=self.goal_reached_at,
                   goal_time_s=None if p.goal_time is None else [p.goal_time[0] - p.t, p.goal_time[1] - p.t])
        return out


__all__ = ["EGO_LENGTH", "EGO_WIDTH", "DrivenReplayWorld", "planned_duration", "planned_road", "planned_run", "planning_of"]
