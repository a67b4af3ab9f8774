"""``eot bench`` with no target: every benchmark in one run, one JSON file and a printed table.

Sections (the keys of the JSON, in the order they run):

- ``tracker``: ms per frame (median, p95) at 1, 5, 10, 20 and 50 targets in view, fused and
  lidar-only, with the mean number in view (``sim.benchmarks.tracker``; 50 on a 10-lane road; the
  fastest of ``Settings.tracker_repeat`` rounds, every round's median beside it), and
  where the frame goes: ``stage_ms``, the mean ms per frame of each stage of ``Tracker.step``
  (``tracker.tracker.STAGES``), beside ``ms_mean``;
- ``stonesoup``: Stone Soup's GM-PHD (UKF, 10 point targets, 200 frames) and ours on the same frames,
  and the ratio (``sim.benchmarks._stonesoup``; each the fastest of the same rounds);
  ``{"skipped": reason}`` when Stone Soup is missing;
- ``lidar``: one ``Lidar.scan`` (1800 rays, 20 vehicles, 300 roadside objects) and one radar cycle, ms;
- ``lidar3d``: per 3-D lidar model (VLP-16, VLP-32C, HDL-64E, OS1-128), one scan (28,800 to 131,072
  rays, a sloped road, 20 vehicles, 300 roadside objects), the tracker's 3-D preprocessing of it and
  its whole step on it, ms, with the ground removal's recall and precision, and the same for a two-lidar
  rig's merged cloud (``rig``; ``sim.benchmarks.lidar3d``);
- ``world``: ms of wall time per simulated second, traffic only (``sim.benchmarks.world``);
- ``end_to_end``: ``run_scenario`` (world + sensors + tracker + scoring) of ``curvy-multi`` and
  ``dense-highway``, simulated seconds per wall second on one core: the median over ``e2e_repeat``
  runs of seed 0 after a first run, which is reported apart (``first_sim_s_per_wall_s``: it also pays
  the scenario's one-time set-up, as the first run of a Monte Carlo worker does), and the fastest of
  them (``best_sim_s_per_wall_s``: this 2-core machine's speed for the same run varies by up to ~1.5x
  between runs);
- ``montecarlo``: ``curvy-multi`` runs through ``sim.studies.montecarlo.run_study`` with 1, 2 (and 4, 8, ...
  up to the usable CPUs) worker processes: runs per minute and simulated seconds per wall second;
- ``env``: ``eot/TrackedRoad-v0`` steps per second with tracks and with truth (``sim.benchmarks.env``);
- ``memory``: peak resident memory of this process and of its largest worker (``getrusage``);

plus ``machine`` (cores, CPU model, Python, numpy, scipy, Stone Soup, git commit and modified
files, load average), ``settings``, ``pinned_cpu`` and each section's wall time. Every part but the
Monte Carlo runs pinned to one CPU (``--no-pin`` leaves the affinity alone). ``--quick`` shrinks every
part (2 target counts, 10 frames, 1 s runs, a 0.5 s Monte Carlo) so the whole path runs in seconds;
its numbers are not benchmarks.

Commands::

    eot bench                                  # everything (a few minutes), eot-output/bench.json
    OMP_NUM_THREADS=1 eot bench --out results/bench.json   # re-make the committed reference
    eot bench --quick --out /tmp/bench.json    # the whole path in seconds
    eot bench --only tracker stonesoup         # some sections
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import json
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from sim.benchmarks._machine import machine, one_core, peak_memory_mb, usable_cpus

SECTIONS = ("tracker", "stonesoup", "lidar", "lidar3d", "world", "end_to_end", "montecarlo", "env")
E2E_SCENARIOS = ("curvy-multi", "dense-highway")
MC_SCENARIO = "curvy-multi"
DEFAULT_OUT = "eot-output/bench.json"


@dataclasses.dataclass(frozen=True)
class Settings:
    """Sizes of every part (``None`` durations: the scenario's own, 20 s). ``tracker_repeat``: rounds of
    the tracker and Stone Soup timings, each row its fastest round (``sim.benchmarks._tracking.best_of``:
    this shared machine's speed moves by up to 1.5 x from minute to minute)."""

    quick: bool = False
    tracker_counts: tuple[int, ...] = (1, 5, 10, 20, 50)
    tracker_frames: int = 100
    tracker_repeat: int = 3
    stonesoup_frames: int = 200
    lidar_repeats: int = 100
    world_duration: float | None = None
    world_repeat: int = 3
    e2e_duration: float | None = None
    e2e_repeat: int = 5
    mc_runs_per_worker: int = 2
    mc_duration: float | None = None
    env_steps: int = 75
    env_repeat: int = 5

    @classmethod
    def make(cls, quick: bool) -> Settings:
        """The full settings, or the ``--quick`` ones."""
        if not quick:
            return cls()
        return cls(quick=True, tracker_counts=(1, 5), tracker_frames=10, tracker_repeat=1, stonesoup_frames=10,
                   lidar_repeats=5,
                   world_duration=1.0, world_repeat=1, e2e_duration=1.0, e2e_repeat=1, mc_runs_per_worker=1, mc_duration=0.5,
                   env_steps=5, env_repeat=1)


def mc_worker_counts(cpus: int) -> list[int]:
    """1 and 2 workers, then every power of two below ``cpus``, then ``cpus``."""
    counts = {1, 2}
    k = 4
    while k < cpus:
        counts.add(k)
        k *= 2
    counts.add(max(1, cpus))
    return sorted(counts)


# -- the sections ---------------------------------------------------------------------------------
def tracker_section(s: Settings) -> dict[str, Any]:
    from sim.benchmarks.tracker import VARIANTS, measure

    return {"frames": s.tracker_frames, "repeat": s.tracker_repeat,
            "results": measure(s.tracker_counts, VARIANTS, s.tracker_frames, repeat=s.tracker_repeat)}


def stonesoup_section(s: Settings) -> dict[str, Any]:
    from sim.baselines.stonesoup_gmphd import MissingBaselineError
    from sim.benchmarks._stonesoup import compare

    try:
        return compare(s.stonesoup_frames, repeat=s.tracker_repeat)
    except MissingBaselineError as exc:
        return {"skipped": str(exc)}


def lidar_section(s: Settings) -> dict[str, Any]:
    import numpy as np

    from sim.benchmarks._timing import median_seconds
    from sim.benchmarks.sensors import scene
    from sim.sensors.lidar import Lidar, LidarConfig
    from sim.sensors.radar import FRONT_RADAR, RadarUnit

    snapshot, objects = scene()
    lidar, radar = Lidar(LidarConfig()), RadarUnit(FRONT_RADAR)
    rng = np.random.default_rng(0)
    return {
        "scene": f"{len(snapshot)} vehicles, {len(objects)} roadside objects, straight 4-lane road (sim.benchmarks.sensors)",
        "rays": int(lidar.scan(snapshot, objects, rng=rng).rays),
        "scan_ms": round(1e3 * median_seconds(lambda: lidar.scan(snapshot, objects, rng=rng), s.lidar_repeats), 3),
        "radar_cycle_ms": round(1e3 * median_seconds(lambda: radar.detect(snapshot, objects, rng=rng), s.lidar_repeats), 3),
    }


def lidar3d_section(s: Settings) -> dict[str, Any]:
    from sim.benchmarks.lidar3d import bench_all

    return bench_all(s.lidar_repeats if not s.quick else 3, pin=False, verbose=False)  # run_all pins


def world_section(s: Settings) -> dict[str, Any]:
    from sim.benchmarks import world

    return world.run(argparse.Namespace(repeat=s.world_repeat, duration=s.world_duration, query_hz=10.0))


def end_to_end_section(s: Settings) -> dict[str, Any]:
    from sim.evaluation.runner import run_scenario
    from sim.world.scenario import load_scenario

    out: dict[str, Any] = {}
    for name in E2E_SCENARIOS:
        spec = load_scenario(name)
        walls, shares = [], []
        for _ in range(1 + max(1, s.e2e_repeat)):
            start = time.perf_counter()
            result = run_scenario(spec, seed=0, duration=s.e2e_duration)
            walls.append(time.perf_counter() - start)
            shares.append(1e-3 * sum(f.tracker_ms for f in result.frames) / walls[-1])
        median = sorted(range(1, len(walls)), key=lambda k: walls[k])[(len(walls) - 1) // 2]
        out[name] = {
            "simulated_s": result.duration,
            "wall_s": round(walls[median], 3),
            "sim_s_per_wall_s": round(result.duration / walls[median], 3),
            "first_sim_s_per_wall_s": round(result.duration / walls[0], 3),
            "best_sim_s_per_wall_s": round(result.duration / min(walls[1:]), 3),
            "repeats": len(walls) - 1,
            "frames": len(result.frames),
            "tracker_ms_median": round(float(result.metrics["tracker_ms_median"]), 3),
            "tracker_share": round(shares[median], 3),
        }
    return out


def montecarlo_section(s: Settings) -> dict[str, Any]:
    from sim.studies.montecarlo import plan, run_study

    out: dict[str, Any] = {"scenario": MC_SCENARIO, "duration_s": s.mc_duration, "runs_per_worker": s.mc_runs_per_worker,
                           "workers": {}}
    base: float | None = None
    for workers in mc_worker_counts(usable_cpus()):
        tasks = plan([MC_SCENARIO], s.mc_runs_per_worker * workers, duration=s.mc_duration)
        study = run_study(tasks, workers=workers)
        rate = study.simulated_s / study.wall_s
        base = rate if base is None else base
        out["workers"][str(workers)] = {
            "runs": len(tasks),
            "wall_s": round(study.wall_s, 3),
            "runs_per_min": round(60.0 * len(tasks) / study.wall_s, 2),
            "sim_s_per_wall_s": round(rate, 3),
            "sim_s_per_wall_s_per_worker": round(study.throughput, 3),
            "speedup_over_1": round(rate / base, 2),
        }
    return out


def env_section(s: Settings) -> dict[str, Any]:
    from sim.benchmarks.env import env_steps_per_second

    out: dict[str, Any] = {"vehicles": 10, "steps": s.env_steps}
    for perception in ("tracks", "truth"):
        out[perception] = env_steps_per_second(10, s.env_steps, perception=perception, repeat=s.env_repeat)
    return out


RUNNERS: dict[str, Callable[[Settings], dict[str, Any]]] = {
    "tracker": tracker_section,
    "stonesoup": stonesoup_section,
    "lidar": lidar_section,
    "world": world_section,
    "end_to_end": end_to_end_section,
    "montecarlo": montecarlo_section,
    "env": env_section,
    "lidar3d": lidar3d_section,
}
#: Sections that run with the process's own affinity (they start worker processes).
UNPINNED = ("montecarlo",)


def run_all(settings: Settings, sections: tuple[str, ...] = SECTIONS, *, pin: bool = True, command: str = "eot bench",
            log: Callable[[str], None] | None = None) -> dict[str, Any]:
    """Run ``sections`` with ``settings``; the JSON-ready result (module docstring)."""
    from tracker.warmup import warm_up

    unknown = [x for x in sections if x not in RUNNERS]
    if unknown:
        raise ValueError(f"unknown bench section(s) {', '.join(unknown)}; choose from: {', '.join(SECTIONS)}")
    started = datetime.datetime.now(datetime.timezone.utc)
    result: dict[str, Any] = {
        "schema": 1,
        "command": command,
        "quick": settings.quick,
        "started_utc": started.isoformat(timespec="seconds"),
        "machine": machine(),
        "settings": dataclasses.asdict(settings),
        "pinned_cpu": None,
        "section_wall_s": {},
    }
    total = time.perf_counter()
    t0 = time.perf_counter()  # compile (or load) the tracker's kernels before anything is timed
    warm_up()
    result["kernels"] = {"warm_up_s": round(time.perf_counter() - t0, 2)}
    for name in (x for x in SECTIONS if x in sections):
        if log is not None:
            log(f"eot bench: {name} ...")
        t0 = time.perf_counter()
        with one_core(pin and name not in UNPINNED) as cpu:
            result[name] = RUNNERS[name](settings)
        if cpu is not None:
            result["pinned_cpu"] = cpu
        result["section_wall_s"][name] = round(time.perf_counter() - t0, 2)
    result["memory"] = peak_memory_mb()
    result["wall_s"] = round(time.perf_counter() - total, 2)
    return result


def write(result: dict[str, Any], path: str | Path) -> Path:
    """Write ``result`` as indented JSON to ``path`` (folders made as needed)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    return path


def stderr_log(line: str) -> None:
    """Progress lines go to stderr (the table goes to stdout)."""
    print(line, file=sys.stderr, flush=True)
