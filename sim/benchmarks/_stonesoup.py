"""Stone Soup's GM-PHD (UKF, point targets) timed against our tracker on the same frames, in one process.

``compare(frames=200)``: the benchmark scene with 10 cars in view (``sim.benchmarks._traffic``), one
sensor stream of ``frames`` frames, fed to the ``stonesoup-gmphd`` variant
(``sim.baselines.stonesoup_gmphd``: Stone Soup's ``PHDUpdater`` + ``UnscentedKalmanUpdater`` +
``GaussianMixtureReducer`` on our lidar cluster centroids, i.e. 10 point targets) and to our tracker
(fused and lidar-only), one after the other. Reported: each one's ms per frame (median, p95, over the
frames after the warm-up), tracks and in-view means, Stone Soup's mean mixture size, the share of its
step spent making the centroids (our preprocessing and clustering), and the ratios
``stonesoup ms / our ms`` (medians). Used by ``eot bench tracker --compare-stonesoup`` and ``eot bench``.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from sim.baselines.stonesoup_gmphd import INSTALL_HINT, MissingBaselineError
from sim.benchmarks._tracking import (bench_config, best_of, frame_stats, in_view, sensor_frames, steady, time_steps,
                                      time_variant)

TARGETS = 10
STONESOUP_VARIANT = "stonesoup-gmphd"
OUR_VARIANTS = ("curvilinear-fused", "curvilinear-lidar")


def require_stonesoup() -> str:
    """Stone Soup's version; ``MissingBaselineError`` (saying how to install it) when it is missing."""
    try:
        import stonesoup
    except ImportError:
        raise MissingBaselineError(
            f"the Stone Soup comparison needs Stone Soup, the optional extra 'baselines': {INSTALL_HINT}"
        ) from None
    return str(getattr(stonesoup, "__version__", "unknown"))


def compare(frames: int = 200, *, seed: int = 0, variants: tuple[str, ...] = OUR_VARIANTS,
            repeat: int = 1) -> dict[str, Any]:
    """Stone Soup's GM-PHD and ours on the same 10-target frames (module docstring); with ``repeat`` > 1
    each of them is timed that many times, in rounds (ours, then Stone Soup's, per round), and each
    keeps its fastest round (``best_of``), so a busy minute of the machine slows both alike."""
    version = require_stonesoup()
    from sim.evaluation.variants import make_tracker

    if isinstance(repeat, bool) or not isinstance(repeat, int) or repeat < 1:
        raise ValueError(f"repeat must be an integer >= 1; got {repeat!r}")
    scene, stream = sensor_frames(TARGETS, frames, seed=seed)
    visible = in_view(stream)
    our_rounds: dict[str, list[dict[str, Any]]] = {v: [] for v in variants}
    their_rounds = []
    for _ in range(repeat):
        for v in variants:
            our_rounds[v].append(time_variant(v, scene, stream, visible))
        baseline = make_tracker(STONESOUP_VARIANT, scene.road, bench_config(STONESOUP_VARIANT))
        seconds, tracks = time_steps(baseline, stream)
        their_rounds.append((frame_stats(seconds, tracks, visible), baseline))
    ours = {v: best_of(rows) if repeat > 1 else rows[0] for v, rows in our_rounds.items()}
    stats, baseline = min(their_rounds, key=lambda pair: pair[0]["ms_median"])
    if repeat > 1:
        stats = {**stats, "rounds": repeat, "ms_median_rounds": [row["ms_median"] for row, _ in their_rounds]}
    frames_run = max(1, int(baseline.stats["frames"]))
    centroid_s = np.empty(len(stream))
    for k, sf in enumerate(stream):  # the input side alone (after the timed run: changes only its counters)
        t0 = time.perf_counter()
        baseline.centroids(sf.frame)
        centroid_s[k] = time.perf_counter() - t0
    stonesoup: dict[str, Any] = {
        "version": version,
        **stats,
        "components_mean": round(float(baseline.stats["components"]) / frames_run, 2),
        "centroids_ms_median": round(1e3 * float(np.median(steady(centroid_s))), 3),
    }
    ratios = {v: round(stonesoup["ms_median"] / row["ms_median"], 2) for v, row in ours.items() if row["ms_median"] > 0}
    return {
        "targets": TARGETS,
        "frames": len(stream),
        "lanes": scene.lanes,
        "stonesoup": stonesoup,
        "ours": ours,
        "ratio_stonesoup_over_ours": ratios,
    }


def summary(result: dict[str, Any]) -> str:
    """One line per variant: Stone Soup's ms per frame, ours, and the ratio."""
    ss = result["stonesoup"]
    head = (f"Stone Soup {ss['version']} GM-PHD (UKF, {result['targets']} point targets, {result['frames']} frames): "
            f"{ss['ms_median']:.2f} ms/frame median, {ss['ms_p95']:.2f} p95")
    lines = [head]
    for v, row in result["ours"].items():
        ratio = result["ratio_stonesoup_over_ours"].get(v)
        lines.append(f"  ours {v}: {row['ms_median']:.2f} ms/frame median -> Stone Soup / ours = "
                     f"{ratio if ratio is not None else 'n/a'}x")
    return "\n".join(lines)
