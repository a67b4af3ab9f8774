"""Soak test: one long run of a closed-road scenario, streamed (nothing kept per frame), recording
what must stay bounded over hours: the tracker's component count, the process's resident memory,
non-finite or non-PSD states, the tracker's time per frame and GOSPA.

``run_soak(SoakConfig(...))`` builds the ``World`` (traffic), the ``SensorRig`` and the ``Tracker``
exactly as ``sim.evaluation.runner.run_scenario`` does (same overrides, same seeds), then steps through the
frames without keeping them: every ``window_s`` simulated seconds it closes one ``SoakWindow`` of
aggregates (``on_window`` is called with it, e.g. to append a CSV row), so memory does not grow with
the run's length and a killed run leaves its finished windows behind. The default scenario,
``dense-highway-loop``, is dense-highway's IDM/MOBIL traffic on a closed oval: the traffic never ends.

Per window: frames; components (the tracker's GM-PHD mixture size, ``len(tracker.mixture)`` where
the tracker has one, else its track count) max and mean; tracks and truth (scored set) mean; the
resident set size (MB, ``/proc/self/statm``; the peak ``ru_maxrss`` where there is no ``/proc``);
``nonfinite`` (frames whose mixture or tracks hold a NaN or inf); ``bad_cov`` (tracks whose covariance
is asymmetric beyond 1e-9 relative or has an eigenvalue below ``-1e-9 x`` its largest); tracker ms per
frame (wall clock: median, p95, max; and the median of the process's CPU time in the step, which
other load on a shared machine disturbs less); GOSPA mean (alpha 2, p 2, c 5 m); labels born.
"""

from __future__ import annotations

import math
import os
import resource
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from sim.evaluation.metrics import GOSPA_C, GOSPA_P, gospa
from sim.evaluation.runner import (
    SENSOR_STREAM,
    build_rig,
    default_tracker_factory,
    rig_config_for,
    track_states,
    tracker_config_for,
    truth_set,
    truth_state,
)
from sim.evaluation.variants import DEFAULT_VARIANT, check_variant
from sim.world.scenario import ScenarioSpec
from sim.world.world import World

#: Scenario of the soak test (a closed road, so the traffic never ends).
SOAK_SCENARIO = "dense-highway-loop"
#: Relative tolerance for symmetric and positive semi-definite covariances.
COV_TOLERANCE = 1e-9


@dataclass(frozen=True)
class SoakConfig:
    """A soak run: ``duration_s`` simulated seconds (default: the scenario's, at most its own) of
    ``spec`` with ``seed`` and ``variant``, aggregated into windows of ``window_s`` simulated seconds
    (default 60 s); ``roadside`` forces roadside clutter on or off (``None``: the scenario's)."""

    spec: ScenarioSpec
    duration_s: float | None = None
    window_s: float = 60.0
    seed: int = 0
    variant: str = DEFAULT_VARIANT
    roadside: bool | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.spec, ScenarioSpec):
            raise ValueError(f"SoakConfig.spec must be a ScenarioSpec; got {type(self.spec).__name__}")
        check_variant(self.variant)
        if self.duration_s is not None and not (
            isinstance(self.duration_s, (int, float)) and 0.0 < self.duration_s <= self.spec.duration
        ):
            raise ValueError(f"duration must be in (0, {self.spec.duration:g}] s for {self.spec.name}; got {self.duration_s!r}")
        if not (isinstance(self.window_s, (int, float)) and math.isfinite(self.window_s) and self.window_s > 0):
            raise ValueError(f"window must be a positive number of seconds; got {self.window_s!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ValueError(f"seed must be a non-negative integer; got {self.seed!r}")

    @property
    def duration(self) -> float:
        """The simulated duration (s)."""
        return float(self.spec.duration if self.duration_s is None else self.duration_s)


@dataclass(frozen=True)
class SoakWindow:
    """Aggregates of the frames in ``(t_start, t_end]`` (s); see the module docstring for each field.
    ``wall_s``: wall-clock seconds since the run started, at the window's end."""

    t_start: float
    t_end: float
    frames: int
    components_max: int
    components_mean: float
    tracks_mean: float
    truth_mean: float
    rss_mb: float
    nonfinite: int
    bad_cov: int
    tracker_ms_median: float
    tracker_ms_p95: float
    tracker_ms_max: float
    tracker_cpu_ms_median: float
    gospa_mean: float
    labels_born: int
    wall_s: float


@dataclass
class SoakResult:
    """The windows of a soak run and its ``summary`` (``summarize_soak``)."""

    windows: list[SoakWindow] = field(default_factory=list)
    summary: dict[str, Any] = field(default_factory=dict)


def rss_mb() -> float:
    """The process's resident set size now (MB, 10^6 bytes), from ``/proc/self/statm``; where that is
    missing, the peak resident size (``resource.getrusage``)."""
    try:
        with open("/proc/self/statm", encoding="ascii") as fh:
            pages = int(fh.read().split()[1])
        return pages * os.sysconf("SC_PAGE_SIZE") / 1e6
    except (OSError, ValueError, IndexError):  # pragma: no cover (not Linux)
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 / 1e6


def bad_covariances(covs: np.ndarray) -> int:
    """How many of the (K, 7, 7) covariances are not symmetric positive semi-definite (within
    ``COV_TOLERANCE`` relative to their largest magnitude) or hold a non-finite entry."""
    covs = np.asarray(covs, dtype=float).reshape(-1, 7, 7)
    if covs.shape[0] == 0:
        return 0
    finite = np.isfinite(covs).all(axis=(1, 2))
    bad = ~finite
    good = covs[finite]
    if len(good):
        scale = np.maximum(np.abs(good).max(axis=(1, 2)), 1e-300)
        asym = np.abs(good - good.transpose(0, 2, 1)).max(axis=(1, 2)) > COV_TOLERANCE * scale
        eig = np.linalg.eigvalsh(0.5 * (good + good.transpose(0, 2, 1)))
        neg = eig[:, 0] < -COV_TOLERANCE * np.maximum(eig[:, -1], 1e-300)
        bad[np.flatnonzero(finite)] = asym | neg
    return int(bad.sum())


def _window(t_start: float, t_end: float, acc: dict[str, list], start_wall: float) -> SoakWindow:
    ms = np.asarray(acc["ms"], dtype=float)
    comps = np.asarray(acc["components"], dtype=float)
    return SoakWindow(
        t_start=t_start,
        t_end=t_end,
        frames=len(ms),
        components_max=int(comps.max()) if comps.size else 0,
        components_mean=float(comps.mean()) if comps.size else 0.0,
        tracks_mean=float(np.mean(acc["tracks"])) if acc["tracks"] else 0.0,
        truth_mean=float(np.mean(acc["truth"])) if acc["truth"] else 0.0,
        rss_mb=rss_mb(),
        nonfinite=int(sum(acc["nonfinite"])),
        bad_cov=int(sum(acc["bad_cov"])),
        tracker_ms_median=float(np.median(ms)) if ms.size else float("nan"),
        tracker_ms_p95=float(np.percentile(ms, 95)) if ms.size else float("nan"),
        tracker_ms_max=float(ms.max()) if ms.size else float("nan"),
        tracker_cpu_ms_median=float(np.median(acc["cpu_ms"])) if acc["cpu_ms"] else float("nan"),
        gospa_mean=float(np.mean(acc["gospa"])) if acc["gospa"] else float("nan"),
        labels_born=int(acc["born"][0]),
        wall_s=time.perf_counter() - start_wall,
    )


def summarize_soak(windows: list[SoakWindow], *, edge_fraction: float = 0.1) -> dict[str, Any]:
    """The soak's verdict numbers: frames and simulated seconds; component count max; resident
    memory at the end of the first window, at the end, and the growth in between (MB); non-finite
    frames and bad covariances in total; tracker ms median over the first and the last
    ``edge_fraction`` of the windows (at least one each) and their ratio; GOSPA mean."""
    if not windows:
        return {"windows": 0, "frames": 0}
    k = max(1, int(round(edge_fraction * len(windows))))
    first, last = windows[:k], windows[-k:]
    frames = sum(w.frames for w in windows)

    def weighted(ws: list[SoakWindow], name: str) -> float:
        n = sum(w.frames for w in ws)
        return float(sum(getattr(w, name) * w.frames for w in ws) / n) if n else float("nan")

    ms_first = float(np.median([w.tracker_ms_median for w in first]))
    ms_last = float(np.median([w.tracker_ms_median for w in last]))
    cpu_first = float(np.median([w.tracker_cpu_ms_median for w in first]))
    cpu_last = float(np.median([w.tracker_cpu_ms_median for w in last]))
    return {
        "windows": len(windows),
        "frames": frames,
        "simulated_s": windows[-1].t_end - windows[0].t_start,
        "wall_s": windows[-1].wall_s,
        "components_max": max(w.components_max for w in windows),
        "components_mean": weighted(windows, "components_mean"),
        "tracks_mean": weighted(windows, "tracks_mean"),
        "truth_mean": weighted(windows, "truth_mean"),
        "rss_first_window_mb": windows[0].rss_mb,
        "rss_end_mb": windows[-1].rss_mb,
        "rss_max_mb": max(w.rss_mb for w in windows),
        "rss_growth_mb": windows[-1].rss_mb - windows[0].rss_mb,
        "nonfinite_frames": sum(w.nonfinite for w in windows),
        "bad_covariances": sum(w.bad_cov for w in windows),
        "tracker_ms_median_first": ms_first,
        "tracker_ms_median_last": ms_last,
        "tracker_ms_last_over_first": ms_last / ms_first if ms_first > 0 else float("nan"),
        "tracker_ms_max": max(w.tracker_ms_max for w in windows),
        "tracker_cpu_ms_median_first": cpu_first,
        "tracker_cpu_ms_median_last": cpu_last,
        "gospa_mean": weighted(windows, "gospa_mean"),
        "labels_born": sum(w.labels_born for w in windows),
        "edge_windows": k,
    }


def run_soak(
    config: SoakConfig,
    *,
    on_window: Callable[[SoakWindow], None] | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> SoakResult:
    """Run the soak of ``config`` (module docstring); ``on_window(window)`` after each window,
    ``progress(frames_done, frames_total)`` after each frame."""
    spec = config.spec
    rig_cfg, clutter_cfg = rig_config_for(spec)
    tracker_cfg = tracker_config_for(spec, config.variant, rig_cfg)
    world = World(spec, config.seed)
    road = world.road
    rig = build_rig(rig_cfg, clutter_cfg, road, config.seed, config.roadside, world.ground)
    tracker = default_tracker_factory(road, tracker_cfg)
    max_range = rig_cfg.lidar.max_range
    duration = config.duration
    total = len(rig.frame_times(duration))
    sensor_seed = np.random.SeedSequence(config.seed, spawn_key=(SENSOR_STREAM,))

    result = SoakResult()
    start_wall = time.perf_counter()
    t_start = 0.0
    acc: dict[str, list] = {k: [] for k in ("ms", "cpu_ms", "components", "tracks", "truth", "nonfinite", "bad_cov", "gospa")}
    acc["born"] = [0]
    seen: set[int] = set()
    for k, sf in enumerate(rig.frames(world.truth_at, duration, seed=sensor_seed, poses_at=world.poses_at)):
        t0, c0 = time.perf_counter(), time.process_time()
        tracks = list(tracker.step(sf.frame))
        acc["ms"].append(1e3 * (time.perf_counter() - t0))
        acc["cpu_ms"].append(1e3 * (time.process_time() - c0))
        mixture = getattr(tracker, "mixture", None)
        acc["components"].append(len(mixture) if mixture is not None else len(tracks))
        finite = all(np.isfinite(tr.mean).all() and np.isfinite(tr.cov).all() for tr in tracks)
        if mixture is not None:
            finite = finite and bool(np.isfinite(mixture.means).all() and np.isfinite(mixture.covs).all()
                                     and np.isfinite(mixture.weights).all())
        acc["nonfinite"].append(0 if finite else 1)
        acc["bad_cov"].append(bad_covariances(np.stack([tr.cov for tr in tracks])) if tracks else 0)
        snap = sf.truth
        scored = truth_set(snap, road, max_range)
        est = track_states(tracks, road)
        acc["gospa"].append(gospa(truth_state(snap)[scored, :2], est[:, :2], GOSPA_C, GOSPA_P).gospa)
        acc["tracks"].append(len(tracks))
        acc["truth"].append(int(scored.sum()))
        for tr in tracks:
            if tr.label not in seen:
                seen.add(tr.label)
                acc["born"][0] += 1
        t = float(sf.frame.t)
        last = k + 1 == total
        if t >= t_start + config.window_s - 1e-9 or last:
            window = _window(t_start, t, acc, start_wall)
            result.windows.append(window)
            if on_window is not None:
                on_window(window)
            t_start = t
            for key in acc:
                acc[key] = [] if key != "born" else [0]
        if progress is not None:
            progress(k + 1, total)
    result.summary = summarize_soak(result.windows)
    return result


def window_row(window: SoakWindow) -> dict[str, Any]:
    """A window as a flat dict (CSV row)."""
    return asdict(window)


__all__ = [
    "COV_TOLERANCE",
    "SOAK_SCENARIO",
    "SoakConfig",
    "SoakResult",
    "SoakWindow",
    "bad_covariances",
    "rss_mb",
    "run_soak",
    "summarize_soak",
    "window_row",
]
