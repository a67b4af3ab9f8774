"""``eot closed-loop``: the planner (``sim.env.planner``) driving ``eot/TrackedRoad-v0`` on truth and on
tracks, over seeds and scenarios; per-run safety and comfort metrics, track-caused events, a table
with 95 % intervals and a figure.

Modes (``variant`` column): ``truth`` (``perception = "truth"``) and one ``perception = "tracks"`` mode
per tracker variant (``curvilinear-fused``, ``curvilinear-lidar`` by default). Everything else -- world,
sensors, seeds, planner -- is the same, so differences are the tracker's.

Per run (one row of ``runs.csv``; the ego's truth, sampled at every lidar frame, 10 Hz):

- ``collision``: 1 if the ego's rectangle overlapped another vehicle's (the episode ends), else 0;
- ``min_time_headway_s``: minimum of ``gap / v_ego`` (``v_ego > 1 m/s``) to the true in-path lead, the
  nearest vehicle ahead whose lateral extent overlaps the ego's (``|n - n_ego| < (W + W_ego) / 2``);
  ``gap`` is bumper to bumper along the road; capped at ``HEADWAY_CAP`` s (also when there was no lead);
- ``min_ttc_s``: minimum of ``gap / (v_ego - v_lead)`` while closing in, capped at ``TTC_CAP`` s;
- ``mean_speed_mps``; ``rms_jerk_mps3``: RMS of the second difference of the ego's speed at 10 Hz;
- track-caused events, judged at every planner decision against the truth at that time (an event is
  a run of consecutive decisions; ``*_events`` count the runs):
  ``phantom_brake_events`` -- the planner brakes (command < ``-BRAKE_MPS2``) for a lead with no true
  vehicle within ``GATE_S`` m + half its length along the road and ``GATE_N`` m across;
  ``lateral_brake_events`` -- it brakes for a lead that is a true vehicle outside the ego's lanes
  (misplaced across); ``late_brake_events`` -- the true in-path lead needs a reaction
  (``TTC < LATE_TTC_S`` or headway < ``LATE_HEADWAY_S``) but the planner's lead is not that vehicle
  (the tracker has not confirmed it, or put it elsewhere); ``unconfirmed_lead_s`` -- the time spent so.

``events.csv`` lists every event and collision with what the tracker had near the vehicle (nearest
track distance, lidar points on the vehicle) for tracing failures back to the tracker.
Summaries: ``summary.csv`` / ``summary.json`` (``sim.studies.montecarlo.summarize_runs``: mean, Student-t 95 %
interval per scenario, mode and metric), ``table.md`` (with Wilson 95 % intervals for the collision
rate), ``closed_loop.png``.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sim.evaluation.variants import check_variant
from sim.world.scenario import load_scenario, resolve_scenario_path
from tracker.warmup import warm_up

#: Mode name of the ground-truth perception.
TRUTH = "truth"
#: Default tracker variants compared with truth.
DEFAULT_VARIANTS = ("curvilinear-fused", "curvilinear-lidar")
#: Caps (s) of the minimum headway and TTC (no lead / never closing in).
HEADWAY_CAP = 10.0
TTC_CAP = 20.0
#: A planner command below -BRAKE_MPS2 (m/s^2) is a brake.
BRAKE_MPS2 = 1.0
#: Gate (m) for matching a planner lead to a true vehicle: along the road GATE_S + L / 2, across GATE_N.
GATE_S = 4.0
GATE_N = 1.5
#: A true in-path lead needs a reaction below this TTC (s) or time headway (s).
LATE_TTC_S = 4.0
LATE_HEADWAY_S = 0.8
#: Metrics of a run, in ``runs.csv`` order.
METRICS = ("collision", "min_time_headway_s", "min_ttc_s", "mean_speed_mps", "rms_jerk_mps3", "phantom_brake_events",
           "lateral_brake_events", "late_brake_events", "unconfirmed_lead_s")
EVENT_COLUMNS = ("scenario", "variant", "seed", "t", "kind", "lead_label", "truth_id", "gap_m", "ttc_s", "nearest_track_m",
                 "lidar_points", "detail")


@dataclass(frozen=True)
class Task:
    """One closed-loop run: scenario file ``source`` (name ``scenario``), ``mode`` ("truth" or a tracker
    variant), ``seed`` and an optional shorter ``duration`` (s)."""

    scenario: str
    source: str
    mode: str
    seed: int
    duration: float | None = None


def make_env(source: str, mode: str, duration: float | None = None) -> Any:
    """The env of one mode: ``ContinuousAction``, unnormalised observation, 5 Hz."""
    from sim.env import TrackedRoadEnv

    config: dict[str, Any] = {"scenario": source, "action": "ContinuousAction", "duration": duration}
    if mode == TRUTH:
        config["perception"] = "truth"
    else:
        config.update(perception="tracks", variant=check_variant(mode))
    return TrackedRoadEnv(config)


def _lead_truth(snap: Any, ego_s: float, ego_n: float, ego_v: float, ego_l: float, ego_w: float, wrap: Callable) -> tuple[int, float, float, float]:
    """(index, gap m, time headway s, TTC s) of the true in-path lead, index -1 when none."""
    if len(snap) == 0:
        return -1, math.inf, math.inf, math.inf
    ds = wrap(snap.s - ego_s)
    path = (np.abs(snap.n - ego_n) < 0.5 * (snap.width + ego_w)) & (ds > 0.0)
    if not path.any():
        return -1, math.inf, math.inf, math.inf
    i = int(np.flatnonzero(path)[np.argmin(ds[path])])
    gap = float(ds[i] - 0.5 * (snap.length[i] + ego_l))
    headway = gap / ego_v if ego_v > 1.0 else math.inf
    closing = ego_v - float(snap.v[i])
    ttc = max(gap, 0.0) / closing if closing > 0.1 else math.inf
    return i, gap, headway, ttc


def run_task(task: Task) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """Run one episode with the planner; the row (``METRICS``) and its events (``EVENT_COLUMNS``)."""
    from sim.env.planner import planner_for

    env = make_env(task.source, task.mode, task.duration)
    obs, info = env.reset(seed=task.seed)
    planner = planner_for(env.settings, info["lane_centers"], lane_directions=info["lane_directions"],
                          lane_kinds=info["lane_kinds"])
    road = env.world.road
    half = 0.5 * road.length

    def wrap(ds: np.ndarray) -> np.ndarray:
        return (ds + half) % road.length - half if road.closed else ds

    ego_spec = env.world.spec.ego
    ego_l, ego_w = float(ego_spec.length), float(ego_spec.width)
    lane_reach = 0.5 * road.lane_width
    speeds: list[float] = []
    min_headway, min_ttc = HEADWAY_CAP, TTC_CAP
    counts = {"phantom_brake": 0, "lateral_brake": 0, "late_brake": 0}
    active = {k: False for k in counts}
    unconfirmed_steps = 0
    events: list[dict[str, Any]] = []
    ego_s_hint: float | None = None

    def event(kind: str, t: float, **values: Any) -> None:
        row = {c: "" for c in EVENT_COLUMNS}
        row.update(scenario=task.scenario, variant=task.mode, seed=task.seed, t=round(t, 3), kind=kind)
        row.update({k: (round(v, 3) if isinstance(v, float) and math.isfinite(v) else v) for k, v in values.items()})
        events.append(row)

    def frame_metrics(frames: list) -> None:
        nonlocal min_headway, min_ttc, ego_s_hint
        for sf, _ in frames:
            snap = sf.truth
            e = snap.ego
            s, n = road.to_frenet((e.x, e.y), s_hint=ego_s_hint)
            s, n = float(np.asarray(s).reshape(-1)[0]), float(np.asarray(n).reshape(-1)[0])
            ego_s_hint = s
            speeds.append(e.v)
            _, gap, headway, ttc = _lead_truth(snap, s, n, e.v, ego_l, ego_w, wrap)
            min_headway = min(min_headway, headway)
            min_ttc = min(min_ttc, ttc)

    frame_metrics(env.step_frames)
    terminated = truncated = False
    while not (terminated or truncated):
        action = planner.act(obs, info["labels"])
        d = planner.decision
        sf = env.last_frame
        snap = sf.truth
        ego = env.world.ego_state()
        t = env.sim_time
        ds = wrap(snap.s - ego.s) if len(snap) else np.zeros(0)
        # what the planner's lead is in truth
        lead_id, matched_in_lane = None, False
        if d.lead_label is not None and len(snap):
            near = (np.abs(ds - d.lead_ds) < GATE_S + 0.5 * snap.length) & (np.abs(snap.n - d.lead_n) < GATE_N)
            if near.any():
                j = int(np.flatnonzero(near)[np.argmin(np.abs(ds[near] - d.lead_ds))])
                lead_id = int(snap.ids[j])
                lanes = [planner.config.lane_centers[k] for k in {planner.lane_of(ego.n), d.target_lane}]
                matched_in_lane = any(abs(snap.n[j] - c) < lane_reach + 0.5 * snap.width[j] for c in lanes)
        braking = d.accel < -BRAKE_MPS2 and d.lead_label is not None
        now = {"phantom_brake": braking and lead_id is None, "lateral_brake": braking and lead_id is not None and not matched_in_lane}
        i, gap, headway, ttc = _lead_truth(snap, ego.s, ego.n, ego.v, ego_l, ego_w, wrap)
        needs = i >= 0 and (ttc < LATE_TTC_S or headway < LATE_HEADWAY_S)
        now["late_brake"] = bool(needs and lead_id != int(snap.ids[i]))
        if now["late_brake"]:
            unconfirmed_steps += 1
        for kind, on in now.items():
            if on and not active[kind]:
                counts[kind] += 1
                detail = {"phantom_brake": "brake for a lead with no vehicle there",
                          "lateral_brake": "brake for a vehicle outside the ego's lanes",
                          "late_brake": "in-path lead needs braking but the planner's lead is not it"}[kind]
                truth_j = i if kind == "late_brake" else None
                tracks = env.tracks
                nearest = math.inf
                points = ""
                if truth_j is not None:
                    if tracks:
                        tr = np.array([[tr.s, tr.n] for tr in tracks])
                        nearest = float(np.min(np.hypot(wrap(tr[:, 0] - snap.s[truth_j]), tr[:, 1] - snap.n[truth_j])))
                    points = int(np.count_nonzero(sf.lidar.vehicle_id == snap.ids[truth_j]))
                event(kind, t, lead_label="" if d.lead_label is None else d.lead_label,
                      truth_id=int(snap.ids[truth_j]) if truth_j is not None else ("" if lead_id is None else lead_id),
                      gap_m=gap, ttc_s=ttc, nearest_track_m=nearest if truth_j is not None else "", lidar_points=points,
                      detail=f"{detail} (planner lead {d.lead_label}/{d.lead_source}, command {d.accel:.2f} m/s^2)")
            active[kind] = on
        obs, _, terminated, truncated, info = env.step(action)
        frame_metrics(env.step_frames)
    collisions = [c for c in env.world.collisions if 0 in c[1:]]
    for t_c, a, b in collisions:
        other = b if a == 0 else a
        d = planner.decision
        event("collision", t_c, lead_label="" if d.lead_label is None else d.lead_label, truth_id=other,
              detail=f"ego hit vehicle {other}; planner lead {d.lead_label}/{d.lead_source}, command {d.accel:.2f} m/s^2, "
                     f"{len(env.tracks)} tracks")
    v = np.asarray(speeds)
    dt = 1.0 / env.rig.config.lidar.rate_hz
    jerk = np.diff(v, n=2) / dt**2 if len(v) > 2 else np.zeros(0)
    row: dict[str, Any] = {"scenario": task.scenario, "variant": task.mode, "seed": task.seed, "sim_s": env.sim_time}
    row.update({
        "collision": int(bool(collisions)),
        "min_time_headway_s": float(min_headway),
        "min_ttc_s": float(min_ttc),
        "mean_speed_mps": float(v.mean()) if len(v) else None,
        "rms_jerk_mps3": float(np.sqrt(np.mean(jerk**2))) if len(jerk) else None,
        "phantom_brake_events": counts["phantom_brake"],
        "lateral_brake_events": counts["lateral_brake"],
        "late_brake_events": counts["late_brake"],
        "unconfirmed_lead_s": unconfirmed_steps * env.period,
    })
    env.close()
    return row, events


def plan(scenarios: Sequence[str], runs: int, variants: Sequence[str] = DEFAULT_VARIANTS, *, seed0: int = 0,
         truth: bool = True, duration: float | None = None) -> list[Task]:
    """Tasks: every scenario x mode (truth first, then the variants) x seed ``seed0 .. seed0 + runs - 1``."""
    if isinstance(runs, bool) or not isinstance(runs, int) or runs < 1:
        raise ValueError(f"runs must be an integer >= 1; got {runs!r}")
    modes = ([TRUTH] if truth else []) + [check_variant(v) for v in variants]
    if not modes:
        raise ValueError("nothing to run: no tracker variant and no truth mode")
    tasks = []
    for name in scenarios:
        path = resolve_scenario_path(name)
        spec = load_scenario(path)
        if duration is not None and not 0.0 < duration <= spec.duration:
            raise ValueError(f"duration must be in (0, {spec.duration:g}] s for {spec.name}; got {duration!r}")
        tasks += [Task(spec.name, str(path), mode, seed0 + k, duration) for mode in modes for k in range(runs)]
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


_TABLE = (("collision", "collisions (rate)", 2), ("min_time_headway_s", "min headway (s)", 2),
          ("min_ttc_s", "min TTC (s)", 1), ("mean_speed_mps", "mean speed (m/s)", 2),
          ("rms_jerk_mps3", "RMS jerk (m/s^3)", 2), ("phantom_brake_events", "phantom brakes", 2),
          ("lateral_brake_events", "brakes for misplaced tracks", 2), ("late_brake_events", "late brakes", 2),
          ("unconfirmed_lead_s", "unconfirmed lead (s)", 2))


def table_markdown(rows: Sequence[dict[str, Any]], summary: Sequence[dict[str, Any]], command: str) -> str:
    """The Markdown table: per scenario and mode, mean [95 % interval] of each metric."""
    by = {(s["scenario"], s["variant"], s["metric"]): s for s in summary}
    scenarios = list(dict.fromkeys(r["scenario"] for r in rows))
    modes = list(dict.fromkeys(r["variant"] for r in rows))
    runs = {(sc, m): [r for r in rows if r["scenario"] == sc and r["variant"] == m] for sc in scenarios for m in modes}
    lines = [
        "# Closed loop: the planner on truth vs tracks",
        "",
        f"Made by `{command}`. Mean and 95 % interval over seeds (Student t; collisions: the Wilson interval of",
        f"the rate). Headway capped at {HEADWAY_CAP:g} s and TTC at {TTC_CAP:g} s (no lead / never closing in).",
        "Definitions: `sim/studies/closed_loop.py`; every event is listed in `events.csv`.",
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
                item = by.get((sc, m, metric))
                if metric == "collision":
                    hits = sum(int(r["collision"]) for r in members)
                    lo, hi = wilson(hits, len(members))
                    cells.append(f"{hits}/{len(members)} [{lo:.2f}, {hi:.2f}]")
                elif item is None or item["mean"] is None:
                    cells.append("-")
                elif item["ci95_low"] is None:
                    cells.append(f"{item['mean']:.{digits}f}")
                else:
                    cells.append(f"{item['mean']:.{digits}f} [{item['ci95_low']:.{digits}f}, {item['ci95_high']:.{digits}f}]")
            lines.append(f"| {sc} | {m} | {len(members)} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def plot_summary(summary: Sequence[dict[str, Any]], rows: Sequence[dict[str, Any]], path: str | Path) -> Path:
    """Per metric a panel: mean and 95 % interval per scenario (groups) and mode (colours)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    scenarios = list(dict.fromkeys(r["scenario"] for r in rows))
    modes = list(dict.fromkeys(r["variant"] for r in rows))
    by = {(s["scenario"], s["variant"], s["metric"]): s for s in summary}
    panels = [m for m in _TABLE if m[0] != "unconfirmed_lead_s"]
    fig = Figure(figsize=(14, 7.5), dpi=100)
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, 4).ravel()
    colors = ["0.25", "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728"]
    width = 0.8 / max(len(modes), 1)
    x = np.arange(len(scenarios))
    for ax, (metric, label, _) in zip(axes, panels):
        for k, mode in enumerate(modes):
            mean, low, high = [], [], []
            for sc in scenarios:
                members = [r for r in rows if r["scenario"] == sc and r["variant"] == mode]
                if metric == "collision":
                    hits = sum(int(r["collision"]) for r in members)
                    m = hits / len(members) if members else math.nan
                    lo, hi = wilson(hits, len(members))
                else:
                    item = by.get((sc, mode, metric))
                    m = math.nan if item is None or item["mean"] is None else item["mean"]
                    lo = m if item is None or item["ci95_low"] is None else item["ci95_low"]
                    hi = m if item is None or item["ci95_high"] is None else item["ci95_high"]
                mean.append(m)
                low.append(m - lo)
                high.append(hi - m)
            ax.bar(x + (k - 0.5 * (len(modes) - 1)) * width, mean, width, yerr=[low, high], capsize=2,
                   color=colors[k % len(colors)], label=mode)
        ax.set_title(label, fontsize=10)
        ax.set_xticks(x)
        ax.set_xticklabels(scenarios, rotation=25, ha="right", fontsize=8)
        ax.grid(axis="y", alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle("Closed loop: planner on truth vs tracks (mean, 95 % interval over seeds)", fontsize=11)
    fig.tight_layout()
    fig.savefig(path)
    return Path(path)


def write_outputs(rows: list[dict[str, Any]], events: list[dict[str, Any]], out: str | Path, *, command: str,
                  wall_s: float, workers: int) -> dict[str, Path]:
    """``runs.csv``, ``summary.csv``, ``summary.json`` (``sim.studies.montecarlo.write_study``), ``events.csv``,
    ``table.md`` and ``closed_loop.png`` in ``out``."""
    from sim.studies.montecarlo import Study, summarize_runs, write_study

    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    paths = write_study(Study(rows, "local", workers, wall_s), folder)
    summary = summarize_runs(rows)
    with open(folder / "summary.json", encoding="utf-8") as fh:
        doc = json.load(fh)
    doc["command"] = command
    doc["note"] = ("mean and 95 % CI of the mean (Student t) per scenario, mode (variant column: 'truth' or the "
                   "tracker variant) and metric; definitions in sim/studies/closed_loop.py")
    with open(folder / "summary.json", "w", encoding="utf-8") as fh:
        json.dump(doc, fh, indent=2)
        fh.write("\n")
    paths["events"] = folder / "events.csv"
    with open(paths["events"], "w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(EVENT_COLUMNS))
        writer.writeheader()
        writer.writerows(events)
    paths["table"] = folder / "table.md"
    paths["table"].write_text(table_markdown(rows, summary, command), encoding="utf-8")
    paths["figure"] = plot_summary(summary, rows, folder / "closed_loop.png")
    return paths


__all__ = ["DEFAULT_VARIANTS", "METRICS", "TRUTH", "Task", "make_env", "plan", "run_task", "run_tasks",
           "table_markdown", "wilson", "write_outputs"]
