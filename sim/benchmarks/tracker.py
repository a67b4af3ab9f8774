"""Multi-target tracker speed: median ms per frame at 1, 5, 10 and 20 targets with fused input."""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from sim.sensors import SensorRig
from sim.truth import EgoPose, Snapshot
from tracker import Road, Tracker, TrackerConfig

#: Road of the benchmark: a 4-lane circle of radius 500 m (lanes 3.5 m).
RADIUS = 500.0
LANES = 4
EGO_SPEED = 20.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--targets", type=int, nargs="+", default=[1, 5, 10, 20], help="target counts")
    parser.add_argument("--seconds", type=float, default=6.0, help="simulated seconds per count")
    parser.add_argument("--variant", default="curvilinear-fused", help="TrackerConfig.for_variant name")


def traffic(road: Road, count: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lane-following cars around the ego: initial ``s`` offsets (m) spread over +-80 m without overlap,
    lanes, and speeds (m/s)."""
    rng = np.random.default_rng(seed)
    slots = [(lane, ds) for ds in np.arange(-80.0, 81.0, 12.0) for lane in range(LANES) if not (lane == 1 and abs(ds) < 10)]
    pick = rng.choice(len(slots), size=count, replace=False)
    lanes = np.array([slots[k][0] for k in pick])
    offsets = np.array([slots[k][1] for k in pick]) + rng.uniform(-1.0, 1.0, count)
    speeds = EGO_SPEED + rng.uniform(-1.0, 1.0, count)
    return offsets, lanes, speeds


def truth_function(road: Road, offsets: np.ndarray, lanes: np.ndarray, speeds: np.ndarray):
    """``truth_at(t) -> Snapshot`` of the ego (lane 1) and the lane-following cars."""
    n_lane = road.lane_centers

    def truth_at(t: float) -> Snapshot:
        s_ego = EGO_SPEED * t
        xy_e, th_e, _ = road.frame(np.array([s_ego]))
        ego_xy = xy_e[0] + n_lane[1] * np.array([-np.sin(th_e[0]), np.cos(th_e[0])])
        s = road.wrap_s(offsets + speeds * t)
        n = n_lane[lanes]
        xy = road.to_cartesian(s, n)
        yaw = road.heading(s)
        count = len(offsets)
        return Snapshot(
            t, EgoPose(ego_xy[0], ego_xy[1], float(th_e[0]), EGO_SPEED, EGO_SPEED / RADIUS),
            np.arange(1, count + 1), xy, yaw, speeds, speeds / RADIUS, np.full(count, 4.8), np.full(count, 2.0),
            s, n, np.zeros(count), np.zeros(count),
        )

    return truth_at


def run(args: argparse.Namespace) -> dict:
    road = Road.from_curvature([(2 * np.pi * RADIUS, 1 / RADIUS, 1 / RADIUS)], closed=True, lanes=LANES)
    out: dict[str, dict] = {}
    for count in args.targets:
        frames = list(SensorRig().frames(truth_function(road, *traffic(road, count)), args.seconds, seed=0))
        tracker = Tracker(road, TrackerConfig.for_variant(args.variant))
        times, counts = [], []
        for sf in frames:
            t0 = time.perf_counter()
            tracks = tracker.step(sf.frame)
            times.append(time.perf_counter() - t0)
            counts.append(len(tracks))
        steady = times[10:] if len(times) > 20 else times
        out[f"{count}_targets"] = {
            "ms_median": round(1e3 * statistics.median(steady), 2),
            "ms_p95": round(1e3 * float(np.percentile(steady, 95)), 2),
            "frames": len(frames),
            "mean_tracks_after_1s": round(float(np.mean(counts[10:])), 2),
            "lidar_points_median": int(statistics.median(len(sf.frame.lidar) for sf in frames)),
        }
    return {"variant": args.variant, "road": f"circle R {RADIUS:.0f} m, {LANES} lanes", **out}
