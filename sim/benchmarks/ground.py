"""Ground removal over a scenario suite, per 3-D lidar model: ours beside Patchwork++ on the same clouds.

For each model of ``sim.sensors.lidar3d.LIDAR3D_MODELS``, each scenario of the suite (``standard`` by
default) and each seed, the scenario's world and sensor rig with that lidar; every ``every``-th scan
(from the first) goes through the tracker's cloud pipeline (``tracker.cloud.process_cloud`` with the
run's mount) and through Patchwork++ (``pypatchworkpp``, Lee et al. 2022, C++; the ``baselines``
extra; its default parameters but the sensor's height and range), and both are scored against the
simulator's labels of that scan:

- ``ground_removed``: ground returns removed / all ground returns;
- ``precision``: removed returns that were ground / all removed;
- ``vehicle_kept``: vehicle returns kept / all vehicle returns;
- ``roadside_kept``: returns of roadside objects (posts, trees, parked cars) kept / all of them: what
  a ground removal must leave for the road filter, not take for ground;
- ``median_ms``: the median time per cloud.

Scores pool the returns of every scan of the model (not a mean of per-scan ratios). ``eot bench
ground`` runs it (``--models``, ``--suite``, ``--seeds``, ``--every``). The targets of the real-lidar
work: vehicle returns kept >= 99.5 %, ground returns removed >= 99 %.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from sim.benchmarks._patchwork import MISSING, Patchwork
from sim.evaluation.runner import (
    build_rig,
    rig_config_for,
    tracker_config_for,
    with_lidar_model,
)
from sim.sensors.lidar3d import LIDAR3D_MODELS
from sim.world.scenario import load_suite
from sim.world.world import World
from tracker.cloud import process_cloud

#: The targets (shares) of the real-lidar work: vehicle returns kept, ground returns removed.
VEHICLE_KEPT_TARGET = 0.995
GROUND_REMOVED_TARGET = 0.99


class _Tally:
    """Pooled counts of one method over the scans: removed ground, removed, ground, vehicle kept,
    vehicle, roadside kept, roadside; and the times (ms)."""

    def __init__(self) -> None:
        self.counts = np.zeros(7, dtype=np.int64)
        self.times: list[float] = []

    def add(self, removed: np.ndarray, scan, ms: float) -> None:
        ground, vehicle, roadside = scan.ground, scan.vehicle_id >= 0, scan.roadside_index >= 0
        self.counts += [int((removed & ground).sum()), int(removed.sum()), int(ground.sum()),
                        int((~removed & vehicle).sum()), int(vehicle.sum()), int((~removed & roadside).sum()),
                        int(roadside.sum())]
        self.times.append(ms)

    def result(self) -> dict:
        rg, r, g, vk, v, sk, s = (int(c) for c in self.counts)
        return {"ground_removed": round(rg / max(g, 1), 5), "precision": round(rg / max(r, 1), 5),
                "vehicle_kept": round(vk / max(v, 1), 5), "roadside_kept": round(sk / max(s, 1), 5),
                "median_ms": round(statistics.median(self.times), 3) if self.times else None,
                "scans": len(self.times), "ground_points": g, "vehicle_points": v}


def bench_ground(models: list[str] | None = None, suite: str = "standard", seeds: int = 5, every: int = 10,
                 verbose: bool = True) -> dict:
    """Ground removal of ours and of Patchwork++ on the same clouds (module docstring), per model."""
    names = list(LIDAR3D_MODELS) if models is None else list(models)
    if not names or any(m not in LIDAR3D_MODELS for m in names):
        raise ValueError(f"bench_ground: models must be some of {list(LIDAR3D_MODELS)}; got {models!r}")
    for name, value in (("seeds", seeds), ("every", every)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ValueError(f"bench_ground: {name} must be a positive integer; got {value!r}")
    specs = load_suite(suite).load()
    out: dict = {"suite": suite, "seeds": seeds, "every": every, "scenarios": [s.name for s in specs], "models": {}}
    for model in names:
        ours, theirs = _Tally(), _Tally()
        segmenter = None
        for spec in specs:
            spec3 = with_lidar_model(spec, model)
            rig_config, clutter = rig_config_for(spec3)
            cloud_config = tracker_config_for(spec3, "curvilinear-fused", rig_config).cloud
            lidar = rig_config.lidar
            segmenter = segmenter or Patchwork.create(lidar.mount_z, lidar.max_range)
            for seed in range(seeds):
                world = World(spec3, seed)
                rig = build_rig(rig_config, clutter, world.road, seed=seed, ground=world.ground)
                for k, sensor_frame in enumerate(rig.frames(world.truth_at, float(spec3.duration), seed=seed)):
                    if k % every:
                        continue
                    scan = sensor_frame.lidar
                    t0 = time.perf_counter()
                    result = process_cloud(scan.points, cloud_config)
                    ours.add(result.ground | result.below_ground, scan, 1e3 * (time.perf_counter() - t0))
                    if segmenter is not None:
                        t0 = time.perf_counter()
                        removed = segmenter.ground(scan.points)
                        theirs.add(removed, scan, 1e3 * (time.perf_counter() - t0))
        row = {"ours": ours.result(),
               "patchworkpp": theirs.result() if segmenter is not None
               else {"skipped": MISSING}}
        out["models"][model] = row
        if verbose:
            print(_line(model, row))
    return out


def _line(model: str, row: dict) -> str:
    o, p = row["ours"], row["patchworkpp"]
    text = (f"{model}: ours ground removed {o['ground_removed']:.4f}, precision {o['precision']:.4f}, vehicle kept "
            f"{o['vehicle_kept']:.4f}, roadside kept {o['roadside_kept']:.4f}, {o['median_ms']} ms ({o['scans']} scans)")
    if "skipped" in p:
        return text + f"; Patchwork++ skipped ({p['skipped']})"
    return text + (f"; Patchwork++ {p['ground_removed']:.4f}, {p['precision']:.4f}, {p['vehicle_kept']:.4f}, "
                   f"{p['roadside_kept']:.4f}, {p['median_ms']} ms")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``eot bench ground``."""
    parser.add_argument("--model", action="append", choices=list(LIDAR3D_MODELS),
                        help="3-D lidar model, repeatable (default: every one)")
    parser.add_argument("--suite", default="standard", help="scenario suite (default standard)")
    parser.add_argument("--seeds", type=int, default=5, help="seeds 0..N-1 per scenario (default 5)")
    parser.add_argument("--every", type=int, default=10, help="score every N-th scan of a run (default 10: 1 Hz)")


def run(args: argparse.Namespace) -> dict:
    """``bench_ground`` with the command line's options (the JSON is printed by ``eot bench``)."""
    return bench_ground(getattr(args, "model", None), str(getattr(args, "suite", "standard")),
                        int(getattr(args, "seeds", 5)), int(getattr(args, "every", 10)), verbose=False)


def summary(result: dict) -> str:
    """One line per model after the JSON."""
    return "\n".join(_line(model, row) for model, row in result["models"].items())
