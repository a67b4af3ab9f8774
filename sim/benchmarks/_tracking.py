"""Timing trackers frame by frame on the benchmark scene (``sim.benchmarks._traffic``).

``sensor_frames`` makes one sensor stream (the default ``SensorRig``: 10 Hz lidar, 14 Hz front/rear
radars, no roadside clutter); ``time_steps`` feeds it to a tracker and keeps the wall time of every
``step``; ``frame_stats`` turns the times into the reported numbers. The first ``WARMUP_FRAMES`` frames
(births, no tracks yet) are left out when at least ``2 * WARMUP_FRAMES`` frames were timed.
"""

from __future__ import annotations

import itertools
import math
import time
from typing import Any

import numpy as np

from sim.benchmarks._traffic import Layout, layout, truth_function
from sim.evaluation.runner import MIN_VISIBLE_POINTS, told_lidar
from sim.evaluation.variants import make_tracker, variant_config
from sim.sensors import SensorRig
from sim.sensors.rig import RigConfig, SensorFrame
from tracker import TrackerConfig

WARMUP_FRAMES = 10


def sensor_frames(count: int, frames: int, *, seed: int = 0, lanes: int | None = None) -> tuple[Layout, list[SensorFrame]]:
    """The scene with ``count`` cars in view and its first ``frames`` sensor frames (seeded)."""
    if isinstance(frames, bool) or not isinstance(frames, int) or frames < 1:
        raise ValueError(f"frames must be an integer >= 1; got {frames!r}")
    scene = layout(count, seed=seed, lanes=lanes)
    stream = SensorRig().frames(truth_function(scene), None, seed=seed)
    return scene, list(itertools.islice(stream, frames))


def in_view(frames: list[SensorFrame]) -> np.ndarray:
    """Per frame, the number of cars hit by at least ``MIN_VISIBLE_POINTS`` lidar points (the
    runner's "visible")."""
    out = np.empty(len(frames), dtype=int)
    for k, sf in enumerate(frames):
        ids = sf.lidar.vehicle_id
        _, hits = np.unique(ids[ids >= 0], return_counts=True)
        out[k] = int(np.count_nonzero(hits >= MIN_VISIBLE_POINTS))
    return out


def bench_config(variant: str) -> TrackerConfig:
    """The variant's configuration told the default lidar's range and resolution (as ``sim.evaluation.runner``
    does for a scenario)."""
    lidar = RigConfig().lidar
    return told_lidar(variant_config(variant), float(lidar.max_range), math.radians(lidar.azimuth_step_deg))


def time_steps(tracker: Any, frames: list[SensorFrame], *,
               stages_at_warm_up: dict[str, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Wall seconds of ``tracker.step`` per frame and the number of tracks it reported;
    ``stages_at_warm_up`` (a dict, filled in): the tracker's ``stage_seconds`` when the warm-up frames
    are done."""
    seconds = np.empty(len(frames))
    tracks = np.empty(len(frames), dtype=int)
    for k, sf in enumerate(frames):
        if k == WARMUP_FRAMES and stages_at_warm_up is not None:
            stages_at_warm_up.update(tracker.stage_seconds)
        t0 = time.perf_counter()
        out = tracker.step(sf.frame)
        seconds[k] = time.perf_counter() - t0
        tracks[k] = len(out)
    return seconds, tracks


def stage_ms(total: dict[str, float], at_warm_up: dict[str, float], frames: int) -> dict[str, float]:
    """Mean ms per frame of each stage of ``Tracker.step`` (``tracker.Tracker.stage_seconds``: ``total``
    after a ``time_steps`` run of ``frames`` frames, ``at_warm_up`` after its warm-up) over the steady
    frames (all of them when fewer than ``2 * WARMUP_FRAMES``, as ``steady``)."""
    if frames >= 2 * WARMUP_FRAMES:
        return {name: round(1e3 * (sec - at_warm_up.get(name, 0.0)) / (frames - WARMUP_FRAMES), 4)
                for name, sec in total.items()}
    return {name: round(1e3 * sec / max(frames, 1), 4) for name, sec in total.items()}


def steady(values: np.ndarray) -> np.ndarray:
    """``values`` without the warm-up frames (kept whole when fewer than ``2 * WARMUP_FRAMES``)."""
    return values[WARMUP_FRAMES:] if len(values) >= 2 * WARMUP_FRAMES else values


def frame_stats(seconds: np.ndarray, tracks: np.ndarray, visible: np.ndarray) -> dict[str, float | int]:
    """``ms_median``, ``ms_p95``, ``frames_timed``, ``in_view_mean`` and ``tracks_mean`` over the
    steady frames."""
    ms = 1e3 * steady(seconds)
    return {
        "ms_median": round(float(np.median(ms)), 3),
        "ms_p95": round(float(np.percentile(ms, 95)), 3),
        "frames_timed": int(len(ms)),
        "in_view_mean": round(float(np.mean(steady(visible))), 2),
        "tracks_mean": round(float(np.mean(steady(tracks))), 2),
    }


def best_of(rounds: list[dict[str, Any]]) -> dict[str, Any]:
    """Of the rows of repeated timings of one tracker on the same frames, the one with the lowest
    ``ms_median`` (on a shared machine a round can fall into a minute of another job's load; the
    fastest round is the machine's speed for the code), with ``rounds`` and every round's
    ``ms_median_rounds`` beside it."""
    best = min(rounds, key=lambda row: row["ms_median"])
    return {**best, "rounds": len(rounds), "ms_median_rounds": [row["ms_median"] for row in rounds]}


def time_variant(variant: str, scene: Layout, frames: list[SensorFrame], visible: np.ndarray) -> dict[str, Any]:
    """``frame_stats`` of a fresh tracker of ``variant`` on ``frames`` of ``scene``; for a tracker that
    times its stages also ``ms_mean`` (the steady frames' mean) and ``stage_ms`` (``stage_ms``)."""
    tracker = make_tracker(variant, scene.road, bench_config(variant))
    at_warm_up: dict[str, float] = {}
    timed = hasattr(tracker, "stage_seconds")
    seconds, tracks = time_steps(tracker, frames, stages_at_warm_up=at_warm_up if timed else None)
    out: dict[str, Any] = dict(frame_stats(seconds, tracks, visible))
    if timed:  # where the frame goes: mean ms per stage (their sum is about the mean frame, ms_mean)
        out["ms_mean"] = round(float(np.mean(1e3 * steady(seconds))), 3)
        out["stage_ms"] = stage_ms(tracker.stage_seconds, at_warm_up, len(frames))
    return out
