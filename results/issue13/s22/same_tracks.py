"""Same tracks before and after a speed change (issue 13, session 22): every reported track's label,
weight, mean and covariance, and every ``Tracker.stats`` counter, of 11 fixed runs, compared bit for bit.

The runs: occlusion seed 1 (8 s), stop-and-go 0 (10 s), mixed-traffic 0 (10 s), curvy-multi 0 (10 s),
dense-highway 2 (8 s), truck-hairpin 0 (8 s), curve-single 11 (5 s), circuit 0 (10 s), cut-in 0 (8 s)
with each scenario's own tracker settings, and the bench's 10- and 50-target scenes (200 frames); since
session 23 also the 10-target scene's first 120 frames under the other tracker variants
(``VARIANT_RUNS``: lidar-only, Cartesian, the paper's motion, the paper's motion and Euler conversion).
A snapshot made before that holds only the first 11 runs and is checked on those. Their
sensor frames are made once and cached in ``FOLDER/frames.pkl`` (the simulator is not what is compared),
then fed to ``tracker.Tracker`` of the checkout in use::

    git checkout BEFORE && python results/issue13/s22/same_tracks.py make before FOLDER
    git checkout AFTER && python results/issue13/s22/same_tracks.py check before FOLDER
    EOT_NUMBA=0 python ... make before_numpy FOLDER   # the numpy code path: its own snapshot

``check`` prints OK and the largest relative difference of any number (0.0: bit for bit), or each run
that differs and how. Session 22's result is in ``README.md`` here.
"""

from __future__ import annotations

import argparse
import pickle
from pathlib import Path

import numpy as np

RUNS = [("occlusion", 1, 8.0), ("stop-and-go", 0, 10.0), ("mixed-traffic", 0, 10.0), ("curvy-multi", 0, 10.0),
        ("dense-highway", 2, 8.0), ("truck-hairpin", 0, 8.0), ("curve-single", 11, 5.0), ("circuit", 0, 10.0),
        ("cut-in", 0, 8.0)]
BENCH_TARGETS = (10, 50)
BENCH_FRAMES = 200
#: The other tracker variants (session 23), each on the 10-target bench scene's first 120 frames.
VARIANT_RUNS = ("curvilinear-lidar", "cartesian-fused", "paper-motion", "paper")
VARIANT_FRAMES = 120


def make_inputs() -> list[tuple]:
    """``(name, road, tracker config, frames)`` of every run."""
    from sim.benchmarks._tracking import bench_config, sensor_frames
    from sim.runner import run_scenario
    from sim.scenario import load_scenario
    from tracker import Tracker

    inputs = []
    for scenario, seed, duration in RUNS:
        made = {}

        def factory(road, config):
            made["road"], made["config"] = road, config
            return Tracker(road, config)

        result = run_scenario(load_scenario(scenario), seed, duration=duration, keep_sensor_data=True,
                              tracker_factory=factory)
        inputs.append((f"{scenario}-{seed}", made["road"], made["config"], [f.frame for f in result.frames]))
    for count in BENCH_TARGETS:
        scene, stream = sensor_frames(count, BENCH_FRAMES, seed=0)
        inputs.append((f"bench{count}", scene.road, bench_config("curvilinear-fused"), [sf.frame for sf in stream]))
    scene, stream = sensor_frames(10, VARIANT_FRAMES, seed=0)
    for variant in VARIANT_RUNS:
        inputs.append((f"bench10-{variant}", scene.road, bench_config(variant), [sf.frame for sf in stream]))
    return inputs


def track_rows(inputs: list[tuple]) -> tuple[dict[str, np.ndarray], dict[str, dict[str, float]]]:
    """Per run, one row per reported track and frame ``[frame, label, weight, mean (7), cov (49)]``, and
    the tracker's ``stats``."""
    from tracker import Tracker

    rows, stats = {}, {}
    for name, road, config, frames in inputs:
        tracker = Tracker(road, config)
        out = [np.concatenate([[k, tr.label, tr.weight], tr.mean, tr.cov.ravel()])
               for k, frame in enumerate(frames) for tr in tracker.step(frame)]
        rows[name] = np.array(out).reshape(-1, 3 + 7 + 49)
        stats[name] = {key: float(value) for key, value in tracker.stats.items()}
    return rows, stats


def compare(before: dict[str, np.ndarray], before_stats: dict, now: dict[str, np.ndarray], now_stats: dict) -> bool:
    """Print the differences; True when there are none beyond 1e-9 relative."""
    same, worst = True, 0.0
    for name, old in before.items():
        new = now[name]
        if old.shape != new.shape or not np.array_equal(old[:, :2], new[:, :2]):
            print(f"{name}: other tracks (rows {old.shape[0]} -> {new.shape[0]}, or other frames or labels)")
            same = False
            continue
        rel = float(np.max(np.abs(old - new) / (1e-9 + np.abs(old)))) if old.size else 0.0
        worst = max(worst, rel)
        if rel > 1e-9:
            print(f"{name}: numbers moved by up to {rel:.3g} (relative)")
            same = False
        if before_stats[name] != now_stats[name]:
            moved = {k: (before_stats[name].get(k), now_stats[name].get(k))
                     for k in set(before_stats[name]) | set(now_stats[name]) if before_stats[name].get(k) != now_stats[name].get(k)}
            print(f"{name}: stats differ: {moved}")
            same = False
    print(("OK" if same else "DIFFERENT") + f", largest relative difference {worst:.3g}")
    return same


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("mode", choices=("make", "check"))
    parser.add_argument("name", help="the snapshot's name (FOLDER/NAME.npz)")
    parser.add_argument("folder", nargs="?", default=".", help="where the frames and snapshots are kept")
    args = parser.parse_args()
    folder = Path(args.folder)
    folder.mkdir(parents=True, exist_ok=True)
    cache = folder / "frames.pkl"
    if not cache.exists():
        cache.write_bytes(pickle.dumps(make_inputs()))
    rows, stats = track_rows(pickle.loads(cache.read_bytes()))
    snapshot = folder / f"{args.name}.npz"
    if args.mode == "make":
        np.savez(snapshot, **rows)
        (folder / f"{args.name}.stats.pkl").write_bytes(pickle.dumps(stats))
        print(f"wrote {snapshot}: " + ", ".join(f"{k} {len(v)} rows" for k, v in rows.items()))
        return 0
    before = dict(np.load(snapshot))
    return 0 if compare(before, pickle.loads((folder / f"{args.name}.stats.pkl").read_bytes()), rows, stats) else 1


if __name__ == "__main__":
    raise SystemExit(main())
