"""``eot closed-loop``: the planner (``sim.env.planner``) driving ``eot/TrackedRoad-v0`` on truth and on
tracks, over seeds and scenarios; per-run safety, comfort and progress metrics, every event traced to
the track behind it, differences to truth paired per seed, a table with 95 % intervals and figures.

Modes (``variant`` column): ``truth`` (``perception = "truth"``) and one ``perception = "tracks"`` mode
per tracker variant (``sim.evaluation.variants``: ``curvilinear-fused``, ``curvilinear-lidar`` by
default; every registered one with ``--variant all``), optionally with a sensor fault as
``VARIANT+FAULT`` (``FAULT_MODES``): ``+radar-missing`` (no radar detections in the run) or
``+lidar-dropout`` (no lidar returns for ``DROPOUT_S`` s centred on the scenario's ``hazard_t``, the
family's critical moment; on the middle of the run when the scenario names none). Everything else --
world, sensors, seeds, planner -- is the same, so differences are the tracker's (and the fault's).

**Real traffic.** A replay scenario (a ``[replay]`` table: the ``real`` suite's recordings) runs as a
driven replay (``sim.world.driven``): the recorded vehicles drive as recorded and do not react; the ego
starts at the recording's planning problem's initial state and the planner drives it along the route to
the goal region, cruising at ``max(v0, d_goal / t_goal)`` (``set_speed_for``: the initial speed, or
the speed that covers the route distance to the goal's centre by the middle of the goal's time
interval, whichever is higher) and changing lanes toward the goal's lane (``goal_lane_for``; the
planner's ``goal_lane``) when the gap allows. The seeds vary only the sensor noise; the truth runs
are the same in every seed. A collision there may be the replay's (a recorded vehicle drives into the ego, which the
recorded driver's different path avoided): pair it with truth's run of the same recording.

Per run (one row of ``runs.csv``; the ego's truth, sampled at every lidar frame, 10 Hz):

- ``collision``: 1 if the ego's rectangle overlapped another vehicle's (the episode ends), else 0;
  ``collision_ahead``: 1 if that vehicle's centre was more than half the ego's length ahead of the ego's
  along the road (the ego drove into it; a vehicle behind or beside drove into the ego, or cut across
  it), else 0;
- ``min_time_headway_s``: minimum of ``gap / v_ego`` (``v_ego > 1 m/s``) to the true in-path lead, the
  nearest vehicle ahead whose lateral extent overlaps the ego's (``|n - n_ego| < (W + W_ego) / 2``);
  ``gap`` is bumper to bumper along the road; capped at ``HEADWAY_CAP`` s (also when there was no lead);
- ``min_ttc_s``: minimum of ``gap / (v_ego - v_lead)`` while closing in, capped at ``TTC_CAP`` s;
- ``min_rear_ttc_s``: the same for the nearest in-path vehicle behind closing in on the ego (a lane
  change in front of fast traffic shows here), capped at ``TTC_CAP`` s;
- ``mean_speed_mps``; ``progress_m``: distance driven along the road in the episode (shorter when a
  collision ends it); ``rms_jerk_mps3``: RMS of the second difference of the ego's speed at 10 Hz;
  ``max_decel_mps2``: the hardest deceleration (first difference of the speed at 10 Hz, >= 0);
  ``hard_brake_events``: runs of frames decelerating harder than ``HARD_BRAKE_MPS2``;
- ``goal_reached`` (driven replays; empty elsewhere): 1 if the ego's centre entered the planning problem's
  goal region in the episode, else 0; ``time_to_goal_s``: when it did (empty when it did not);
- track-caused events, judged at every planner decision against the truth at that time (an event is
  a run of consecutive decisions; ``*_events`` count the runs):
  ``phantom_brake_events`` -- the planner brakes (command < ``-BRAKE_MPS2``) for a lead with no true
  vehicle within ``GATE_S`` m + half its length along the road and ``GATE_N`` m across;
  ``lateral_brake_events`` -- it brakes for a lead that is a true vehicle outside the ego's lanes
  (its lane and target lane) and off the ego's own path (more than the planner's ``path_margin``
  beside the ego's body): misplaced across; ``late_brake_events`` -- the true in-path lead needs a reaction
  (``TTC < LATE_TTC_S`` or headway < ``LATE_HEADWAY_S``) but the planner's lead is not that vehicle
  (the tracker has not confirmed it, or put it elsewhere); ``unconfirmed_lead_s`` -- the time spent so.

``events.csv`` lists every event (the ones above, hard brakes and collisions) with what the tracker
reported against the truth at that moment: the track (``track_label``, ``track_ds``, ``track_n``,
``track_v``: the planner's lead for brakes; the nearest track to the vehicle for late brakes and
collisions) and the true vehicle (``truth_id``, ``truth_ds``, ``truth_n``, ``truth_v``), their distance
``track_error_m`` and the lidar points on the vehicle. Summaries: ``summary.csv`` / ``summary.json``
(``sim.studies.montecarlo.summarize_runs``: mean, Student-t 95 % interval per scenario, mode and
metric), ``paired.csv`` (per scenario, mode and metric the mean difference mode - truth over the same
seeds with its 95 % interval, and for collisions the seeds where only one of the two collided),
``table.md`` (with Wilson 95 % intervals for the collision rate, and the paired differences),
``closed_loop.png`` and ``family_<scenario>.png`` (per scenario, each outcome per mode with intervals).
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sim.evaluation.variants import check_variant, probe_variant
from sim.world.scenario import load_scenario, resolve_scenario_path
from tracker.warmup import warm_up

#: Mode name of the ground-truth perception.
TRUTH = "truth"
#: Default tracker variants compared with truth.
DEFAULT_VARIANTS = ("curvilinear-fused", "curvilinear-lidar")
#: Sensor faults a mode may add (``VARIANT+FAULT``): what each does to the episode.
FAULT_MODES = {
    "radar-missing": "no radar detections in the whole run",
    "lidar-dropout": "no lidar returns for DROPOUT_S s centred on the scenario's hazard_t",
}
#: Length (s) of the lidar dropout of ``+lidar-dropout``.
DROPOUT_S = 2.0
#: Caps (s) of the minimum headway and TTC (no lead / never closing in).
HEADWAY_CAP = 10.0
TTC_CAP = 20.0
#: A planner command below -BRAKE_MPS2 (m/s^2) is a brake.
BRAKE_MPS2 = 1.0
#: The ego decelerating harder than this (m/s^2) is a hard brake.
HARD_BRAKE_MPS2 = 4.0
#: Gate (m) for matching a planner lead to a true vehicle: along the road GATE_S + L / 2, across GATE_N.
GATE_S = 4.0
GATE_N = 1.5
#: A true in-path lead needs a reaction below this TTC (s) or time headway (s).
LATE_TTC_S = 4.0
LATE_HEADWAY_S = 0.8
#: Metrics of a run, in ``runs.csv`` order.
METRICS = ("collision", "collision_ahead", "min_time_headway_s", "min_ttc_s", "min_rear_ttc_s", "mean_speed_mps", "progress_m",
           "rms_jerk_mps3", "max_decel_mps2", "hard_brake_events", "phantom_brake_events", "lateral_brake_events",
           "late_brake_events", "unconfirmed_lead_s", "goal_reached", "time_to_goal_s")
EVENT_COLUMNS = ("scenario", "variant", "seed", "t", "kind", "lead_label", "track_label", "track_ds", "track_n",
                 "track_v", "truth_id", "truth_ds", "truth_n", "truth_v", "track_error_m", "gap_m", "ttc_s",
                 "lidar_points", "detail")


def parse_mode(mode: str) -> tuple[str, str | None]:
    """``(variant or "truth", fault or None)`` of a mode name ``VARIANT[+FAULT]``; ``ValueError`` naming
    the choices for an unknown variant or fault."""
    name, _, fault = mode.partition("+")
    if fault and fault not in FAULT_MODES:
        raise ValueError(f"mode {mode!r}: unknown fault {fault!r}; choose one of: {', '.join(FAULT_MODES)}")
    if name == TRUTH:
        if fault:
            raise ValueError(f"mode {mode!r}: the truth mode has no sensors to fail")
        return TRUTH, None
    return check_variant(name), (fault or None)


def fault_config(fault: str | None, duration: float, hazard_t: float | None) -> dict[str, Any] | None:
    """The env's ``faults`` dict of a fault mode (None: the scenario's own faults)."""
    if fault is None:
        return None
    if fault == "radar-missing":
        return {"radar_missing": True}
    centre = 0.5 * duration if hazard_t is None else hazard_t
    start = min(max(centre - 0.5 * DROPOUT_S, 0.0), max(duration - DROPOUT_S, 0.0))
    return {"lidar_dropout": [[round(start, 3), round(min(start + DROPOUT_S, duration), 3)]]}


@dataclass(frozen=True)
class Task:
    """One closed-loop run: scenario file ``source`` (name ``scenario``), ``mode`` ("truth", a tracker
    variant, or ``VARIANT+FAULT``), ``seed``, an optional shorter ``duration`` (s) and the env's
    ``faults`` (set by ``plan`` for a fault mode)."""

    scenario: str
    source: str
    mode: str
    seed: int
    duration: float | None = None
    faults: dict[str, Any] | None = field(default=None, hash=False)


def make_env(source: str, mode: str, duration: float | None = None, faults: dict[str, Any] | None = None) -> Any:
    """The env of one mode: ``ContinuousAction``, unnormalised observation, 5 Hz."""
    from sim.env import TrackedRoadEnv

    variant, _ = parse_mode(mode)
    config: dict[str, Any] = {"scenario": source, "action": "ContinuousAction", "duration": duration}
    if variant == TRUTH:
        config["perception"] = "truth"
    else:
        config.update(perception="tracks", variant=variant)
    if faults is not None:
        config["faults"] = faults
    return TrackedRoadEnv(config)


def _lead_truth(snap: Any, ego_s: float, ego_n: float, ego_v: float, ego_l: float, ego_w: float, wrap: Callable,
                behind: bool = False) -> tuple[int, float, float, float]:
    """(index, gap m, time headway s, TTC s) of the true in-path lead (``behind``: the in-path follower,
    its TTC closing in on the ego), index -1 when none."""
    if len(snap) == 0:
        return -1, math.inf, math.inf, math.inf
    ds = wrap(snap.s - ego_s)
    if behind:
        ds = -ds
    path = (np.abs(snap.n - ego_n) < 0.5 * (snap.width + ego_w)) & (ds > 0.0)
    if not path.any():
        return -1, math.inf, math.inf, math.inf
    i = int(np.flatnonzero(path)[np.argmin(ds[path])])
    gap = float(ds[i] - 0.5 * (snap.length[i] + ego_l))
    headway = gap / ego_v if ego_v > 1.0 else math.inf
    closing = (float(snap.v[i]) - ego_v) if behind else (ego_v - float(snap.v[i]))
    ttc = max(gap, 0.0) / closing if closing > 0.1 else math.inf
    return i, gap, headway, ttc


class _Episode:
    """The bookkeeping of one run: metrics sampled at every lidar frame, events with their traces."""

    def __init__(self, task: Task, env: Any, planner: Any) -> None:
        self.task, self.env, self.planner = task, env, planner
        road = env.world.road
        self.road = road
        self.half = 0.5 * road.length
        self.ego_l, self.ego_w = float(env.vehicle.LENGTH), float(env.vehicle.WIDTH)
        self.lane_reach = 0.5 * road.lane_width
        self.speeds: list[float] = []
        self.min_headway = HEADWAY_CAP
        self.min_ttc = TTC_CAP
        self.min_rear_ttc = TTC_CAP
        self.progress = 0.0
        self.counts = {"phantom_brake": 0, "lateral_brake": 0, "late_brake": 0, "hard_brake": 0}
        self.active = {k: False for k in self.counts}
        self.unconfirmed_steps = 0
        self.events: list[dict[str, Any]] = []
        self.s_hint: float | None = None
        self.last_s: float | None = None
        self.dt = 1.0 / env.rig.config.lidar.rate_hz
        #: (frame, ego s) of the planner's last decision
        self.decided: tuple[Any, float] | None = None

    def wrap(self, ds: Any) -> Any:
        return (ds + self.half) % self.road.length - self.half if self.road.closed else ds

    # -- tracing ------------------------------------------------------------------------------
    def _tracks(self) -> tuple[np.ndarray, np.ndarray]:
        tracks = self.env.tracks
        if not tracks:
            return np.zeros(0, dtype=np.int64), np.zeros((0, 3))
        return (np.array([tr.label for tr in tracks], dtype=np.int64),
                np.array([[tr.s, tr.n, tr.v] for tr in tracks], dtype=float))

    def trace_vehicle(self, snap: Any, sf: Any, j: int, ego_s: float) -> dict[str, Any]:
        """What the tracker had for true vehicle ``j``: the nearest track, its error and the lidar points."""
        out = {"truth_id": int(snap.ids[j]), "truth_ds": float(self.wrap(snap.s[j] - ego_s)), "truth_n": float(snap.n[j]),
               "truth_v": float(snap.v[j]), "lidar_points": int(np.count_nonzero(sf.lidar.vehicle_id == snap.ids[j]))}
        labels, states = self._tracks()
        if len(labels):
            err = np.hypot(self.wrap(states[:, 0] - snap.s[j]), states[:, 1] - snap.n[j])
            k = int(np.argmin(err))
            out.update(track_label=int(labels[k]), track_ds=float(self.wrap(states[k, 0] - ego_s)),
                       track_n=float(states[k, 1]), track_v=float(states[k, 2]), track_error_m=float(err[k]))
        return out

    def trace_lead(self, snap: Any, sf: Any, decision: Any, ego_s: float) -> dict[str, Any]:
        """The planner's lead row (as the planner saw it) and the nearest true vehicle to it."""
        out: dict[str, Any] = {"track_label": decision.lead_label, "track_ds": decision.lead_ds,
                               "track_n": decision.lead_n, "track_v": decision.lead_v}
        if len(snap) and decision.lead_label is not None:
            ds = self.wrap(snap.s - ego_s)
            err = np.hypot(ds - decision.lead_ds, snap.n - decision.lead_n)
            j = int(np.argmin(err))
            out.update(truth_id=int(snap.ids[j]), truth_ds=float(ds[j]), truth_n=float(snap.n[j]), truth_v=float(snap.v[j]),
                       track_error_m=float(err[j]),
                       lidar_points=int(np.count_nonzero(sf.lidar.vehicle_id == snap.ids[j])))
        return out

    def event(self, kind: str, t: float, detail: str, **values: Any) -> None:
        row = {c: "" for c in EVENT_COLUMNS}
        row.update(scenario=self.task.scenario, variant=self.task.mode, seed=self.task.seed, t=round(t, 3), kind=kind,
                   detail=detail)
        for k, v in values.items():
            if v is None or (isinstance(v, float) and not math.isfinite(v)):
                continue
            row[k] = round(v, 3) if isinstance(v, float) else v
        self.events.append(row)

    # -- per lidar frame ----------------------------------------------------------------------
    def frames(self, frames: list) -> None:
        for sf, _ in frames:
            snap = sf.truth
            e = snap.ego
            s, n = self.road.to_frenet((e.x, e.y), s_hint=self.s_hint)
            s, n = float(np.asarray(s).reshape(-1)[0]), float(np.asarray(n).reshape(-1)[0])
            self.s_hint = s
            if self.last_s is not None:
                self.progress += float(self.wrap(s - self.last_s))
            self.last_s = s
            if self.speeds:
                decel = (self.speeds[-1] - e.v) / self.dt
                hard = decel > HARD_BRAKE_MPS2
                if hard and not self.active["hard_brake"]:
                    self.counts["hard_brake"] += 1
                    d = self.planner.decision
                    # the lead as the planner saw it, against the truth of the frame it decided on
                    seen_sf, seen_s = self.decided if self.decided is not None else (sf, s)
                    self.event("hard_brake", float(snap.t), f"ego decelerates {decel:.1f} m/s^2; planner lead "
                               f"{d.lead_label}/{d.lead_source}, command {d.accel:.2f} m/s^2",
                               lead_label=d.lead_label, **self.trace_lead(seen_sf.truth, seen_sf, d, seen_s))
                self.active["hard_brake"] = hard
            self.speeds.append(e.v)
            _, _, headway, ttc = _lead_truth(snap, s, n, e.v, self.ego_l, self.ego_w, self.wrap)
            _, _, _, rear_ttc = _lead_truth(snap, s, n, e.v, self.ego_l, self.ego_w, self.wrap, behind=True)
            self.min_headway = min(self.min_headway, headway)
            self.min_ttc = min(self.min_ttc, ttc)
            self.min_rear_ttc = min(self.min_rear_ttc, rear_ttc)

    # -- per planner decision -----------------------------------------------------------------
    def decision(self) -> None:
        env, planner = self.env, self.planner
        d = planner.decision
        sf = env.last_frame
        snap = sf.truth
        ego = env.world.ego_state()
        t = env.sim_time
        self.decided = (sf, float(ego.s))
        ds = self.wrap(snap.s - ego.s) if len(snap) else np.zeros(0)
        lead_id, matched_in_lane = None, False
        if d.lead_label is not None and len(snap):
            near = (np.abs(ds - d.lead_ds) < GATE_S + 0.5 * snap.length) & (np.abs(snap.n - d.lead_n) < GATE_N)
            if near.any():
                j = int(np.flatnonzero(near)[np.argmin(np.abs(ds[near] - d.lead_ds))])
                lead_id = int(snap.ids[j])
                lanes = [float(planner.centers[k]) for k in {planner.lane_of(ego.n), d.target_lane}]
                matched_in_lane = (any(abs(snap.n[j] - c) < self.lane_reach + 0.5 * snap.width[j] for c in lanes)
                                   or bool(planner.on_path(snap.n[j], snap.width[j], ego.n, self.ego_w)))
        braking = d.accel < -BRAKE_MPS2 and d.lead_label is not None
        now = {"phantom_brake": braking and lead_id is None,
               "lateral_brake": braking and lead_id is not None and not matched_in_lane}
        i, gap, headway, ttc = _lead_truth(snap, ego.s, ego.n, ego.v, self.ego_l, self.ego_w, self.wrap)
        needs = i >= 0 and (ttc < LATE_TTC_S or headway < LATE_HEADWAY_S)
        now["late_brake"] = bool(needs and lead_id != int(snap.ids[i]))
        if now["late_brake"]:
            self.unconfirmed_steps += 1
        for kind, on in now.items():
            if on and not self.active[kind]:
                self.counts[kind] += 1
                what = {"phantom_brake": "brake for a lead with no vehicle there",
                        "lateral_brake": "brake for a vehicle outside the ego's lanes",
                        "late_brake": "in-path lead needs braking but the planner's lead is not it"}[kind]
                trace = self.trace_vehicle(snap, sf, i, ego.s) if kind == "late_brake" else self.trace_lead(snap, sf, d, ego.s)
                detail = f"{what} (planner lead {d.lead_label}/{d.lead_source}, command {d.accel:.2f} m/s^2)"
                if kind == "late_brake" and d.lead_label is not None:
                    lead = self.trace_lead(snap, sf, d, ego.s)  # what the planner followed instead, and where it truly was
                    if "truth_id" in lead:
                        detail += (f"; its lead is vehicle {lead['truth_id']}, reported at ds {d.lead_ds:.1f} m, n {d.lead_n:.2f} m, "
                                   f"truly at ds {lead['truth_ds']:.1f} m, n {lead['truth_n']:.2f} m")
                self.event(kind, t, detail, lead_label=d.lead_label, gap_m=gap, ttc_s=ttc, **trace)
            self.active[kind] = on

    def finish(self) -> dict[str, Any]:
        env, task = self.env, self.task
        collisions = [c for c in env.world.collisions if 0 in c[1:]]
        sf = env.last_frame
        snap = sf.truth
        ego = env.world.ego_state()
        ahead = False
        for t_c, a, b in collisions:
            other = b if a == 0 else a
            d = self.planner.decision
            hit = np.flatnonzero(snap.ids == other)
            trace = self.trace_vehicle(snap, sf, int(hit[0]), ego.s) if len(hit) else {"truth_id": other}
            ds = trace.get("truth_ds")
            where = "" if ds is None else ("ahead of" if ds > 0.5 * self.ego_l else "behind" if ds < -0.5 * self.ego_l else "beside")
            ahead = ahead or where == "ahead of"
            self.event("collision", t_c, f"collision with vehicle {other}" + (f" ({where} the ego)" if where else "")
                       + f"; planner lead {d.lead_label}/{d.lead_source}, command {d.accel:.2f} m/s^2, {len(env.tracks)} tracks",
                       lead_label=d.lead_label, **trace)
        v = np.asarray(self.speeds)
        jerk = np.diff(v, n=2) / self.dt**2 if len(v) > 2 else np.zeros(0)
        decel = -np.diff(v) / self.dt if len(v) > 1 else np.zeros(0)
        row: dict[str, Any] = {"scenario": task.scenario, "variant": task.mode, "seed": task.seed, "sim_s": env.sim_time}
        row.update({
            "collision": int(bool(collisions)),
            "collision_ahead": int(ahead),
            "min_time_headway_s": float(self.min_headway),
            "min_ttc_s": float(self.min_ttc),
            "min_rear_ttc_s": float(self.min_rear_ttc),
            "mean_speed_mps": float(v.mean()) if len(v) else None,
            "progress_m": float(self.progress),
            "rms_jerk_mps3": float(np.sqrt(np.mean(jerk**2))) if len(jerk) else None,
            "max_decel_mps2": max(float(decel.max()), 0.0) + 0.0 if len(decel) else 0.0,  # (+ 0.0: no -0.0)
            "hard_brake_events": self.counts["hard_brake"],
            "phantom_brake_events": self.counts["phantom_brake"],
            "lateral_brake_events": self.counts["lateral_brake"],
            "late_brake_events": self.counts["late_brake"],
            "unconfirmed_lead_s": self.unconfirmed_steps * env.period,
        })
        planning = getattr(env.world, "planning", None)  # a driven replay's planning problem
        reached = getattr(env.world, "goal_reached_at", None)
        row["goal_reached"] = None if planning is None else int(reached is not None)
        row["time_to_goal_s"] = None if reached is None else float(reached)
        return row


def set_speed_for(env: Any) -> float | None:
    """The planner's cruise speed (m/s) in a driven replay (module docstring): ``max(v0, d / t)`` with ``d``
    the distance along the route from the ego to the goal region's centre and ``t`` the middle of the
    goal's time interval (run clock); ``None`` (the planner's default, its first observed speed) elsewhere
    or without a goal region and time."""
    world = env.world
    planning = getattr(world, "planning", None)
    if planning is None or planning.goal_center is None or planning.goal_time is None:
        return None
    ego = world.ego_state()
    s_goal, _ = world.road.to_frenet(planning.goal_center)
    t_mid = 0.5 * (planning.goal_time[0] + planning.goal_time[1]) - planning.t
    if t_mid <= 0.0:
        return None
    return max(float(ego.v), float(np.asarray(s_goal).reshape(-1)[0] - ego.s) / t_mid)


def goal_lane_for(env: Any) -> int | None:
    """The lane (index on the route's road) holding the goal region's centre in a driven replay: the
    planner's ``goal_lane`` (module docstring); ``None`` elsewhere, without a goal region, or when the
    centre lies off the lanes."""
    world = env.world
    planning = getattr(world, "planning", None)
    if planning is None or planning.goal_center is None:
        return None
    s, n = world.road.to_frenet(planning.goal_center)
    lane = int(world.road.lane_index(np.asarray(n).reshape(-1), np.asarray(s).reshape(-1))[0])
    return lane if 0 <= lane < world.road.lanes else None


def run_task(task: Task) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """Run one episode with the planner; the row (``METRICS``) and its events (``EVENT_COLUMNS``)."""
    from sim.env.planner import planner_for

    env = make_env(task.source, task.mode, task.duration, task.faults)
    obs, info = env.reset(seed=task.seed)
    planner = planner_for(env.settings, info["lane_centers"], lane_directions=info["lane_directions"],
                          lane_kinds=info["lane_kinds"], set_speed=set_speed_for(env), goal_lane=goal_lane_for(env))
    episode = _Episode(task, env, planner)
    episode.frames(env.step_frames)
    terminated = truncated = False
    while not (terminated or truncated):
        action = planner.act(obs, info["labels"], info["lane_centers"])
        episode.decision()
        obs, _, terminated, truncated, info = env.step(action)
        episode.frames(env.step_frames)
    row = episode.finish()
    env.close()
    return row, episode.events


def plan(scenarios: Sequence[str], runs: int, variants: Sequence[str] = DEFAULT_VARIANTS, *, seed0: int = 0,
         truth: bool = True, duration: float | None = None) -> list[Task]:
    """Tasks: every scenario x mode (truth first, then ``variants``: variant names or ``VARIANT+FAULT``)
    x seed ``seed0 .. seed0 + runs - 1``. A ``+lidar-dropout`` mode's interval is placed on each seed's
    drawn ``hazard_t`` (``fault_config``)."""
    from sim.world.generator import realize

    if isinstance(runs, bool) or not isinstance(runs, int) or runs < 1:
        raise ValueError(f"runs must be an integer >= 1; got {runs!r}")
    modes = ([TRUTH] if truth else []) + list(variants)
    for m in modes:
        variant = parse_mode(m)[0]
        reason = None if variant == TRUTH else probe_variant(variant)
        if reason is not None:
            raise ValueError(f"mode {m!r}: variant {variant} is not available here: {reason}")
    if not modes:
        raise ValueError("nothing to run: no tracker variant and no truth mode")
    tasks = []
    for name in scenarios:
        path = resolve_scenario_path(name)
        spec = load_scenario(path)
        full = spec.duration
        if spec.replay is not None:  # a driven replay runs to the end of its goal's time interval
            from sim.world.driven import planned_run

            full = planned_run(spec.replay.file, spec.replay.truth)[0]
        if duration is not None and not 0.0 < duration <= full:
            raise ValueError(f"duration must be in (0, {full:g}] s for {spec.name}; got {duration!r}")
        length = full if duration is None else duration
        hazards: dict[int, float | None] = {}
        for mode in modes:
            fault = parse_mode(mode)[1]
            for k in range(runs):
                seed = seed0 + k
                if fault == "lidar-dropout" and seed not in hazards:
                    hazards[seed] = None if spec.replay is not None else realize(spec, seed).hazard_t
                faults = fault_config(fault, length, hazards.get(seed))
                tasks.append(Task(spec.name, str(path), mode, seed, duration, faults))
    return tasks


def run_tasks(tasks: Sequence[Task], *, workers: int = 1,
              progress: Callable[[int, int], None] | None = None) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """Run the tasks (``workers`` processes; rows in task order) -> (rows, events)."""
    results: list[tuple[dict[str, Any], list[dict[str, Any]]] | None] = [None] * len(tasks)
    if workers <= 1:
        for i, task in enumerate(tasks):
            results[i] = run_task(task)
            if progress is not None:
                progress(i + 1, len(tasks))
    else:
        warm_up()  # the tracker's compiled kernels, once, before the workers load them from the cache
        with ProcessPoolExecutor(max_workers=workers) as pool:
            futures = {pool.submit(run_task, task): i for i, task in enumerate(tasks)}
            for done, future in enumerate(as_completed(futures), start=1):
                results[futures[future]] = future.result()
                if progress is not None:
                    progress(done, len(tasks))
    rows = [r[0] for r in results if r is not None]
    events = [e for r in results if r is not None for e in r[1]]
    return rows, events


# -- outputs ---------------------------------------------------------------------------------------
def wilson(successes: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """Wilson score 95 % interval of a proportion."""
    if n == 0:
        return 0.0, 1.0
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


_TABLE = (("collision", "collisions (rate)", 2), ("collision_ahead", "collisions ahead (rate)", 2), ("min_time_headway_s", "min headway (s)", 2),
          ("min_ttc_s", "min TTC (s)", 1), ("min_rear_ttc_s", "min rear TTC (s)", 1),
          ("progress_m", "progress (m)", 1), ("rms_jerk_mps3", "RMS jerk (m/s^3)", 2),
          ("max_decel_mps2", "max decel (m/s^2)", 2), ("hard_brake_events", "hard brakes", 2),
          ("phantom_brake_events", "phantom brakes", 2), ("lateral_brake_events", "brakes for misplaced tracks", 2),
          ("late_brake_events", "late brakes", 2), ("unconfirmed_lead_s", "unconfirmed lead (s)", 2),
          ("goal_reached", "goal reached (rate)", 2), ("time_to_goal_s", "time to goal (s)", 2))
#: Metrics of the paired table (difference mode - truth), in order.
_PAIRED = ("min_ttc_s", "min_rear_ttc_s", "min_time_headway_s", "progress_m", "max_decel_mps2", "hard_brake_events",
           "rms_jerk_mps3")
#: Outcomes drawn per scenario in ``family_<scenario>.png``.
_FAMILY_PANELS = ("collision", "min_ttc_s", "min_rear_ttc_s", "min_time_headway_s", "progress_m", "max_decel_mps2",
                  "hard_brake_events", "rms_jerk_mps3")


def _order(rows: Sequence[dict[str, Any]], key: str) -> list[str]:
    return list(dict.fromkeys(r[key] for r in rows))


def paired_rows(rows: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per scenario, mode (not truth) and metric: the mean difference mode - truth over the seeds both
    ran (``sim.studies.study.paired_difference``) with its 95 % interval; for ``collision`` also
    ``only_mode`` / ``only_truth``, the seeds where only that one collided."""
    from sim.studies.study import paired_difference

    out: list[dict[str, Any]] = []
    for scenario in _order(rows, "scenario"):
        members = [r for r in rows if r["scenario"] == scenario]
        modes = _order(members, "variant")
        if TRUTH not in modes:
            continue
        truth = {int(r["seed"]): r for r in members if r["variant"] == TRUTH}
        for mode in modes:
            if mode == TRUTH:
                continue
            for metric in METRICS:
                p = paired_difference(members, metric, mode, TRUTH)
                item = {"scenario": scenario, "mode": mode, "metric": metric, "n": p.diff.n, "mode_mean": p.a_mean,
                        "truth_mean": p.b_mean, "diff": p.diff.mean, "ci95_low": p.diff.low, "ci95_high": p.diff.high,
                        "only_mode": "", "only_truth": ""}
                if metric == "collision":
                    mine = {int(r["seed"]): int(r["collision"]) for r in members if r["variant"] == mode}
                    both = sorted(set(mine) & set(truth))
                    item["only_mode"] = sum(1 for k in both if mine[k] and not int(truth[k]["collision"]))
                    item["only_truth"] = sum(1 for k in both if int(truth[k]["collision"]) and not mine[k])
                out.append(item)
    return out


def _cell(item: dict[str, Any] | None, digits: int) -> str:
    if item is None or item["mean"] is None:
        return "-"
    if item["ci95_low"] is None:
        return f"{item['mean']:.{digits}f}"
    return f"{item['mean']:.{digits}f} [{item['ci95_low']:.{digits}f}, {item['ci95_high']:.{digits}f}]"


def table_markdown(rows: Sequence[dict[str, Any]], summary: Sequence[dict[str, Any]], command: str,
                   paired: Sequence[dict[str, Any]] | None = None, events: Sequence[dict[str, Any]] | None = None) -> str:
    """The Markdown tables: per scenario and mode, mean [95 % interval] of each metric; then the
    differences to truth paired per seed (``paired_rows``; ``*`` where the interval excludes 0); then the
    events and what the tracker reported for them (``event_causes``)."""
    by = {(s["scenario"], s["variant"], s["metric"]): s for s in summary}
    scenarios = _order(rows, "scenario")
    modes = _order(rows, "variant")
    runs = {(sc, m): [r for r in rows if r["scenario"] == sc and r["variant"] == m] for sc in scenarios for m in modes}
    lines = [
        "# Closed loop: the planner on truth vs tracks",
        "",
        f"Made by `{command}`. Mean and 95 % interval over seeds (Student t; collisions: the Wilson interval of",
        f"the rate). Headway capped at {HEADWAY_CAP:g} s and TTC at {TTC_CAP:g} s (no lead / never closing in).",
        "Definitions: `sim/studies/closed_loop.py`; every event is listed in `events.csv`, traced to its track.",
        "",
        "## Outcomes",
        "",
        "| scenario | mode | runs | " + " | ".join(label for _, label, _ in _TABLE) + " |",
        "|---|---|---:|" + "---:|" * len(_TABLE),
    ]
    for sc in scenarios:
        for m in modes:
            members = runs[(sc, m)]
            if not members:
                continue
            cells = []
            for metric, _, digits in _TABLE:
                if metric == "collision":
                    hits = sum(int(r["collision"]) for r in members)
                    lo, hi = wilson(hits, len(members))
                    cells.append(f"{hits}/{len(members)} [{lo:.2f}, {hi:.2f}]")
                else:
                    cells.append(_cell(by.get((sc, m, metric)), digits))
            lines.append(f"| {sc} | {m} | {len(members)} | " + " | ".join(cells) + " |")
    if paired:
        labels = {k: label for k, label, _ in _TABLE}
        digits = {k: d for k, _, d in _TABLE}
        pb = {(p["scenario"], p["mode"], p["metric"]): p for p in paired}
        lines += [
            "",
            "## Differences to truth, paired per seed",
            "",
            "Mode - truth over the same seeds (the same traffic): mean [95 % interval]; `*` where the interval",
            "excludes 0. Collisions: seeds where only the mode collided / only truth did.",
            "",
            "| scenario | mode | collisions only mode / only truth | " + " | ".join(labels[k] for k in _PAIRED) + " |",
            "|---|---|---:|" + "---:|" * len(_PAIRED),
        ]
        for sc in scenarios:
            for m in modes:
                c = pb.get((sc, m, "collision"))
                if c is None:
                    continue
                cells = [f"{c['only_mode']} / {c['only_truth']}"]
                for metric in _PAIRED:
                    p = pb.get((sc, m, metric))
                    if p is None or p["diff"] is None:
                        cells.append("-")
                        continue
                    d = digits[metric] + (1 if metric == "min_ttc_s" or metric == "min_rear_ttc_s" else 0)
                    star = "*" if p["ci95_low"] is not None and (p["ci95_low"] > 0 or p["ci95_high"] < 0) else ""
                    text = f"{p['diff']:+.{d}f}" if p["ci95_low"] is None else \
                        f"{p['diff']:+.{d}f} [{p['ci95_low']:+.{d}f}, {p['ci95_high']:+.{d}f}]{star}"
                    cells.append(text)
                lines.append(f"| {sc} | {m} | " + " | ".join(cells) + " |")
    if events is not None:
        causes = event_causes(events)
        order = {k: i for i, k in enumerate(("collision", "late_brake", "phantom_brake", "lateral_brake", "hard_brake"))}
        rank = {sc: i for i, sc in enumerate(scenarios)}
        mode_rank = {m: i for i, m in enumerate(modes)}
        causes.sort(key=lambda c: (rank.get(c["scenario"], 99), mode_rank.get(c["mode"], 99), order.get(c["kind"], 9)))

        def num(value: float | None, digits: int) -> str:
            return "-" if value is None else f"{value:.{digits}f}"

        lines += [
            "",
            "## Events and what the tracker reported",
            "",
            f"Per scenario, mode and kind (`events.csv` has every one): events; with a track within {GATE_S:g} m of the",
            "true vehicle (for a late brake: the in-path lead; for a brake: the vehicle nearest to the planner's",
            "lead); the median distance and lateral offset between that track and the vehicle; the median lidar",
            "points on the vehicle.",
            "",
            "| scenario | mode | kind | events | with a track | track error (m) | lateral error (m) | lidar points |",
            "|---|---|---|---:|---:|---:|---:|---:|",
        ]
        for c in causes:
            lines.append(f"| {c['scenario']} | {c['mode']} | {c['kind']} | {c['events']} | {c['with_track']} | "
                         f"{num(c['median_track_error_m'], 2)} | {num(c['median_n_error_m'], 2)} | "
                         f"{num(c['median_lidar_points'], 0)} |")
    return "\n".join(lines) + "\n"


def event_causes(events: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per scenario, mode and event kind: ``events``, how many had a track within ``GATE_S`` m of the true
    vehicle (``with_track``; for a late brake, without one the tracker had not confirmed the vehicle),
    the median distance between the reported track and the true vehicle (``median_track_error_m``), the
    median lateral offset between them (``median_n_error_m``) and the median lidar points on the vehicle."""
    groups: dict[tuple[str, str, str], list[dict[str, Any]]] = {}
    for e in events:
        groups.setdefault((e["scenario"], e["variant"], e["kind"]), []).append(e)

    def numbers(members: list[dict[str, Any]], key: str) -> np.ndarray:
        return np.array([float(e[key]) for e in members if e.get(key) not in ("", None)], dtype=float)

    out = []
    for (scenario, mode, kind), members in groups.items():
        err = numbers(members, "track_error_m")
        n_err = np.array([abs(float(e["track_n"]) - float(e["truth_n"])) for e in members
                          if e.get("track_n") not in ("", None) and e.get("truth_n") not in ("", None)], dtype=float)
        points = numbers(members, "lidar_points")
        out.append({"scenario": scenario, "mode": mode, "kind": kind, "events": len(members),
                    "with_track": int(np.count_nonzero(err < GATE_S)),
                    "median_track_error_m": float(np.median(err)) if len(err) else None,
                    "median_n_error_m": float(np.median(n_err)) if len(n_err) else None,
                    "median_lidar_points": float(np.median(points)) if len(points) else None})
    return out


def _estimate(rows: Sequence[dict[str, Any]], by: dict, scenario: str, mode: str, metric: str) -> tuple[float, float, float]:
    """(mean, low, high) of one metric of one scenario and mode: Wilson for the collision rate."""
    members = [r for r in rows if r["scenario"] == scenario and r["variant"] == mode]
    if metric == "collision":
        hits = sum(int(r["collision"]) for r in members)
        lo, hi = wilson(hits, len(members))
        return (hits / len(members) if members else math.nan), lo, hi
    item = by.get((scenario, mode, metric))
    m = math.nan if item is None or item["mean"] is None else item["mean"]
    lo = m if item is None or item["ci95_low"] is None else item["ci95_low"]
    hi = m if item is None or item["ci95_high"] is None else item["ci95_high"]
    return m, lo, hi


_COLORS = ["0.25", "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22",
           "#17becf"]


def plot_summary(summary: Sequence[dict[str, Any]], rows: Sequence[dict[str, Any]], path: str | Path) -> Path:
    """Per metric a panel: mean and 95 % interval per scenario (groups) and mode (colours)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    scenarios = _order(rows, "scenario")
    modes = _order(rows, "variant")
    by = {(s["scenario"], s["variant"], s["metric"]): s for s in summary}
    panels = [m for m in _TABLE if m[0] in _FAMILY_PANELS]
    fig = Figure(figsize=(16, 8.5), dpi=100)
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, 4).ravel()
    width = 0.8 / max(len(modes), 1)
    x = np.arange(len(scenarios))
    for ax, (metric, label, _) in zip(axes, panels):
        for k, mode in enumerate(modes):
            est = [_estimate(rows, by, sc, mode, metric) for sc in scenarios]
            mean = np.array([e[0] for e in est])
            err = np.array([[max(e[0] - e[1], 0.0), max(e[2] - e[0], 0.0)] for e in est]).T
            ax.bar(x + (k - 0.5 * (len(modes) - 1)) * width, mean, width, yerr=np.nan_to_num(err), capsize=1.5,
                   color=_COLORS[k % len(_COLORS)], label=mode)
        ax.set_title(label, fontsize=10)
        ax.set_xticks(x)
        ax.set_xticklabels(scenarios, rotation=25, ha="right", fontsize=7)
        ax.grid(axis="y", alpha=0.3)
    axes[0].legend(fontsize=7, ncol=2)
    fig.suptitle("Closed loop: planner on truth vs tracks (mean, 95 % interval over seeds)", fontsize=11)
    fig.tight_layout()
    fig.savefig(path)
    return Path(path)


def plot_family(summary: Sequence[dict[str, Any]], rows: Sequence[dict[str, Any]], scenario: str, path: str | Path) -> Path:
    """One scenario (family): per outcome a panel with each mode's mean and 95 % interval (horizontal
    bars, truth first), the truth's mean as a dashed line."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    members = [r for r in rows if r["scenario"] == scenario]
    modes = _order(members, "variant")
    by = {(s["scenario"], s["variant"], s["metric"]): s for s in summary}
    labels = {k: label for k, label, _ in _TABLE}
    fig = Figure(figsize=(15, 7.5), dpi=100)
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, 4).ravel()
    y = np.arange(len(modes))[::-1]
    for ax, metric in zip(axes, _FAMILY_PANELS):
        est = [_estimate(rows, by, scenario, mode, metric) for mode in modes]
        mean = np.array([e[0] for e in est])
        err = np.array([[max(e[0] - e[1], 0.0), max(e[2] - e[0], 0.0)] for e in est]).T
        ax.barh(y, mean, xerr=np.nan_to_num(err), capsize=2, color=[_COLORS[k % len(_COLORS)] for k in range(len(modes))])
        if TRUTH in modes:
            ax.axvline(mean[modes.index(TRUTH)], color="0.25", ls="--", lw=1)
        ax.set_yticks(y)
        ax.set_yticklabels(modes if ax in (axes[0], axes[4]) else [], fontsize=8)
        ax.set_title(labels[metric] + (" (Wilson)" if metric == "collision" else ""), fontsize=10)
        ax.grid(axis="x", alpha=0.3)
    runs = len(members) // max(len(modes), 1)
    fig.suptitle(f"{scenario}: outcome per mode, mean and 95 % interval over {runs} seeds (dashed: truth)", fontsize=11)
    fig.tight_layout()
    fig.savefig(path)
    return Path(path)


def write_outputs(rows: list[dict[str, Any]], events: list[dict[str, Any]], out: str | Path, *, command: str,
                  wall_s: float, workers: int) -> dict[str, Path]:
    """``runs.csv``, ``summary.csv``, ``summary.json`` (``sim.studies.montecarlo.write_study``), ``events.csv``,
    ``paired.csv``, ``table.md``, ``closed_loop.png`` and one ``family_<scenario>.png`` per scenario in ``out``."""
    from sim.studies.montecarlo import Study, summarize_runs, write_study

    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    paths = write_study(Study(rows, "local", workers, wall_s), folder)
    summary = summarize_runs(rows)
    with open(folder / "summary.json", encoding="utf-8") as fh:
        doc = json.load(fh)
    doc["command"] = command
    doc["note"] = ("mean and 95 % CI of the mean (Student t) per scenario, mode (variant column: 'truth', the "
                   "tracker variant, or VARIANT+FAULT) and metric; definitions in sim/studies/closed_loop.py")
    with open(folder / "summary.json", "w", encoding="utf-8") as fh:
        json.dump(doc, fh, indent=2)
        fh.write("\n")
    paths["events"] = folder / "events.csv"
    with open(paths["events"], "w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(EVENT_COLUMNS))
        writer.writeheader()
        writer.writerows(events)
    paired = paired_rows(rows)
    paths["paired"] = folder / "paired.csv"
    with open(paths["paired"], "w", newline="", encoding="utf-8") as fh:
        columns = ["scenario", "mode", "metric", "n", "mode_mean", "truth_mean", "diff", "ci95_low", "ci95_high",
                   "only_mode", "only_truth"]
        writer = csv.DictWriter(fh, fieldnames=columns)
        writer.writeheader()
        writer.writerows({k: ("" if v is None else v) for k, v in p.items()} for p in paired)
    paths["table"] = folder / "table.md"
    paths["table"].write_text(table_markdown(rows, summary, command, paired, events), encoding="utf-8")
    paths["figure"] = plot_summary(summary, rows, folder / "closed_loop.png")
    for scenario in _order(rows, "scenario"):
        paths[f"figure_{scenario}"] = plot_family(summary, rows, scenario, folder / f"family_{scenario}.png")
    return paths


__all__ = [
    "DEFAULT_VARIANTS",
    "FAULT_MODES",
    "METRICS",
    "TRUTH",
    "Task",
    "goal_lane_for",
    "set_speed_for",
    "event_causes",
    "fault_config",
    "make_env",
    "paired_rows",
    "parse_mode",
    "plan",
    "plot_family",
    "run_task",
    "run_tasks",
    "table_markdown",
    "wilson",
    "write_outputs",
]
