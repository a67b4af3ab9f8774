"""Monte Carlo throughput: simulated seconds per wall second per worker (world + sensors + tracker + scoring).

Runs ``--runs`` seeds of ``--scenario`` (curvy-multi) with the default variant on the local backend,
once with 1 worker and once with ``--workers`` workers, and reports for each the wall time and
``sim_s_per_wall_s_per_worker`` (total simulated seconds / (wall seconds x workers)), plus the
median tracker milliseconds per frame over the runs. Speed only; tests never assert it.
"""

from __future__ import annotations

import argparse
import statistics

from sim.studies.montecarlo import default_workers, plan, run_study


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--scenario", default="curvy-multi", help="scenario (default curvy-multi)")
    parser.add_argument("--runs", type=int, default=4, help="seeds (default 4)")
    parser.add_argument("--workers", type=int, default=min(2, default_workers()), help="parallel workers (default 2)")
    parser.add_argument("--duration", type=float, default=None, help="simulated seconds per run (default: the scenario's)")


def run(args: argparse.Namespace) -> dict:
    tasks = plan([args.scenario], args.runs, duration=args.duration)
    out: dict = {"scenario": args.scenario, "runs": args.runs, "cpus_available": default_workers()}
    for workers in dict.fromkeys([1, args.workers]):
        study = run_study(tasks, workers=workers)
        out[f"workers_{workers}"] = {
            "wall_s": round(study.wall_s, 2),
            "simulated_s": study.simulated_s,
            "sim_s_per_wall_s_per_worker": round(study.throughput, 3),
            "tracker_ms_median": round(statistics.median(r["tracker_ms_median"] for r in study.rows), 2),
        }
    return out
