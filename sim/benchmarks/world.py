"""World speed: ms of wall time per simulated second (traffic only, no sensors), dense-highway and curvy-multi."""

from __future__ import annotations

import argparse
import statistics
import time

from sim.world.scenario import load_scenario
from sim.world.world import World

SCENARIOS = ("dense-highway", "curvy-multi")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--repeat", type=int, default=3, help="runs per scenario (the median is reported)")
    parser.add_argument("--duration", type=float, default=None, help="simulated seconds per run (default: the scenario's)")
    parser.add_argument("--query-hz", type=float, default=10.0, help="truth_at calls per simulated second (0: advance only)")


def _one_run(name: str, duration: float, query_hz: float) -> float:
    spec = load_scenario(name)
    world = World(spec)
    start = time.perf_counter()
    if query_hz > 0:
        k = 1
        while k / query_hz <= duration + 1e-9:
            world.truth_at(k / query_hz)
            k += 1
    else:
        world.advance(duration)
    return time.perf_counter() - start


def run(args: argparse.Namespace) -> dict:
    out: dict[str, dict[str, float]] = {}
    for name in SCENARIOS:
        spec = load_scenario(name)
        duration = float(args.duration or spec.duration)
        times = [_one_run(name, duration, args.query_hz) for _ in range(max(1, args.repeat))]
        per_second = 1e3 * statistics.median(times) / duration
        out[name] = {
            "vehicles": len(spec.vehicles) + 1,
            "simulated_s": duration,
            "truth_queries_hz": args.query_hz,
            "ms_per_simulated_s": round(per_second, 2),
            "real_time_factor": round(1e3 / per_second, 1),
        }
    return out
