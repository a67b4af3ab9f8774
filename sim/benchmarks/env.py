"""Environment speed: eot/TrackedRoad-v0 steps per second with the tracker in the loop (10 vehicles).

``env_steps_per_second(...)`` is the measurement (also for other benchmarks/reports): one process, the
env at its defaults (5 Hz policy, 0.05 s world grid, lidar 10 Hz, radars 14 Hz, roadside clutter),
the meta-action IDLE every step, on ``dense-highway`` cut down to the ego and the ``vehicles - 1``
vehicles nearest to it along the road (written to a temporary scenario file). Reported per
perception: steps per wall second, the real-time factor (simulated s per wall s = steps/s x 0.2 s),
and for ``tracks`` the share of the wall time spent in ``Tracker.step``. Run it on one core
(``OMP_NUM_THREADS=1 taskset -c 0 eot bench env``) to compare with the issue's target (20x real time).
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
import tomllib
from pathlib import Path
from typing import Any

from sim.world.scenario import resolve_scenario_path

BASE_SCENARIO = "dense-highway"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--vehicles", type=int, default=10, help="vehicles including the ego (default 10)")
    parser.add_argument("--steps", type=int, default=75, help="env steps per measurement (default 75 = 15 s)")
    parser.add_argument("--repeat", type=int, default=3, help="measurements (the median is reported)")
    parser.add_argument("--variant", default="curvilinear-fused", help="tracker variant")


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return '"' + value.replace('"', '\\"') + '"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    return repr(value)


def scenario_with(vehicles: int, folder: Path) -> Path:
    """A copy of ``dense-highway`` with the ego and its ``vehicles - 1`` nearest vehicles (by ``s``)."""
    if vehicles < 1:
        raise ValueError(f"vehicles must be >= 1 (the ego); got {vehicles}")
    with open(resolve_scenario_path(BASE_SCENARIO), "rb") as fh:
        data = tomllib.load(fh)
    others = sorted(data["vehicles"], key=lambda v: abs(v["s"] - data["ego"]["s"]))
    if vehicles - 1 > len(others):
        raise ValueError(f"{BASE_SCENARIO} has {len(others) + 1} vehicles; asked for {vehicles}")
    lines = [f'name = "bench-{vehicles}"', f'description = "{BASE_SCENARIO} with {vehicles} vehicles"',
             f"duration = {float(data['duration'])!r}", "", "[road]"]
    lines += [f"{k} = {_toml_value(v)}" for k, v in data["road"].items()]
    lines += ["", "[ego]"] + [f"{k} = {_toml_value(v)}" for k, v in data["ego"].items()]
    for v in others[: vehicles - 1]:
        lines += ["", "[[vehicles]]"] + [f"{k} = {_toml_value(x)}" for k, x in v.items()]
    path = folder / f"bench-{vehicles}.toml"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def env_steps_per_second(vehicles: int = 10, steps: int = 75, *, perception: str = "tracks",
                         variant: str = "curvilinear-fused", repeat: int = 3, seed: int = 0) -> dict[str, float]:
    """Median over ``repeat`` measurements of ``steps`` env steps (after ``reset``, not timed):
    ``steps_per_s``, ``real_time_factor`` and ``tracker_share`` (fraction of the wall time in
    ``Tracker.step``; 0 for truth); the fastest measurement as ``best_steps_per_s`` and
    ``best_real_time_factor`` (on a shared machine the same work varies by up to ~1.5x between
    measurements: the median is the typical figure, the best the closest to the code's own cost)."""
    from sim.env import TrackedRoadEnv

    with tempfile.TemporaryDirectory() as tmp:
        path = scenario_with(vehicles, Path(tmp))
        env = TrackedRoadEnv({"scenario": str(path), "perception": perception, "variant": variant})
        results = []
        for _ in range(max(1, repeat)):
            env.reset(seed=seed)
            spent = [0.0]
            if env.tracker is not None:
                inner = env.tracker.step

                def timed(frame: Any, inner: Any = inner) -> Any:
                    t0 = time.perf_counter()
                    out = inner(frame)
                    spent[0] += time.perf_counter() - t0
                    return out

                env.tracker.step = timed  # type: ignore[method-assign]
            start = time.perf_counter()
            done = 0
            for _ in range(steps):
                _, _, terminated, truncated, _ = env.step(1)
                done += 1
                if terminated or truncated:
                    break
            wall = time.perf_counter() - start
            results.append((done / wall, spent[0] / wall))
        env.close()
    rate = statistics.median(r[0] for r in results)
    best = max(r[0] for r in results)
    return {
        "steps_per_s": round(rate, 1),
        "real_time_factor": round(rate / env.settings.policy_frequency, 1),
        "best_steps_per_s": round(best, 1),
        "best_real_time_factor": round(best / env.settings.policy_frequency, 1),
        "tracker_share": round(statistics.median(r[1] for r in results), 3),
    }


def run(args: argparse.Namespace) -> dict:
    out: dict[str, Any] = {"scenario": f"{BASE_SCENARIO} cut to {args.vehicles} vehicles", "policy_hz": 5.0,
                           "steps_per_measurement": args.steps}
    for perception in ("tracks", "truth"):
        out[perception] = env_steps_per_second(args.vehicles, args.steps, perception=perception,
                                               variant=args.variant, repeat=args.repeat)
    return out
