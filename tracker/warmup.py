"""``warm_up()``: compile every kernel of the tracker now (or load it from the cache), and the calls
through which it does so, in shares that compile in parallel on a cold cache.

Call ``warm_up()`` before starting worker processes, so that they load the cache instead of each
compiling, and before timing. Where a kernel is missing from the cache it reports one line before
compiling (with the expected time, ``COMPILE_ESTIMATE_S``) and one after (``report_to``: stderr by
default), and a helper process (``python -P -m tracker.warmup``) compiles the update of the pairs
meanwhile into the same cache, so that two cores share the work.

The shares:

- ``update_share``: the update of the pairs (``tracker.update.update_clusters``: the fused kernel, then
  by hand-back the two steps and the staged kernels) and the cluster preparation alone (the helper's);
- ``first_frame`` (a tracker's first frame in which no cluster pairs with a component: the road filter,
  the grouping of the points, the radar association, the road births, the detection model, the
  reduction), ``other_calls`` (the kernels a small scene may not reach) and ``predict_share``;
- ``scene``: a few frames of a small tracked scene (two cars, lidar and radar) that reach the kernels
  of every stage, the update's included; after the shares it loads them from the cache.

The shares reach disjoint sets of kernels, so that the two processes do not compile the same one
(a kernel both reach is compiled by whichever comes first, and loaded by the other where the cache
already holds it). This module sits above every stage and imports them inside its functions; no stage
imports it.
"""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
import time

import numpy as np
from numba.core import event as _event

COMPILE_ESTIMATE_S = 40  # s: a cold warm_up() on a 2-core machine (the line warm_up() reports before compiling)
HELPER_TIMEOUT_S = 600.0  # s: warm_up() stops waiting for its helper process after this (and compiles its share)
_WARM = False  # warm_up() has compiled or loaded every kernel in this process
_EXTRA_WARM_UPS: list = []  # callables registered by other packages' kernels (register_warm_up)


def register_warm_up(function) -> None:
    """Have ``warm_up()`` also call ``function()`` (no arguments): for kernels outside the tracker
    built with this ``njit`` (the simulator's ray caster), so that one call warms them all."""
    if function not in _EXTRA_WARM_UPS:
        _EXTRA_WARM_UPS.append(function)


def _stderr_line(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


_REPORT = _stderr_line  # where warm_up() says that it compiles (report_to)


def report_to(function):
    """Send ``warm_up()``'s two lines about compiling (the start, with the expected time, and the
    time it took) to ``function(line)`` instead; the default prints them to stderr; None drops them.
    Returns the function that was in use. Nothing is reported when every kernel loads from the cache."""
    global _REPORT
    previous, _REPORT = _REPORT, function
    return previous


def _report(line: str) -> None:
    if _REPORT is not None:
        _REPORT(line)


class _Compiling(_event.Listener):
    """A listener of numba's compile events (``numba.core.event``) for one ``warm_up()``: the first
    compilation (a kernel missing from the cache) reports the start and, while the calling process's
    share runs, starts the helper process on the other share (``tracker.warmup``)."""

    def __init__(self, parallel: bool) -> None:
        self.parallel = parallel  # start the helper on a first compilation (before join())
        self.started: float | None = None  # perf_counter() of the first compilation
        self.helper: subprocess.Popen | None = None

    def on_start(self, event) -> None:
        if self.started is not None:
            return
        self.started = time.perf_counter()
        _report(f"compiling the tracker's kernels once (about {COMPILE_ESTIMATE_S} s on a 2-core machine; "
                "later runs load them from the cache)...")
        if self.parallel:
            self.helper = _start_helper()

    def on_end(self, event) -> None:
        pass

    def join(self) -> None:
        """Wait for the helper (if one runs; at most ``HELPER_TIMEOUT_S``) and start no other."""
        self.parallel = False
        if self.helper is not None:
            try:
                self.helper.wait(timeout=HELPER_TIMEOUT_S)
            except subprocess.TimeoutExpired:  # pragma: no cover - a helper that hangs: its share compiles here
                self.stop()

    def stop(self) -> None:
        if self.helper is not None and self.helper.poll() is None:
            self.helper.kill()
            self.helper.wait()


def _cores() -> int:
    """The CPUs this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - no affinity on this platform
        return os.cpu_count() or 1


def _start_helper() -> subprocess.Popen | None:
    """The helper process: ``python -P -m tracker.warmup`` (its share: the update of the pairs)
    by this interpreter with this process's environment, without the working directory on its path
    (``-P``); None where it cannot start or where this process has one CPU only. Where it fails (a
    package this process found only through a path it added itself) this process compiles that share."""
    if _cores() < 2:
        return None
    try:
        return subprocess.Popen([sys.executable, "-P", "-m", "tracker.warmup"], stdin=subprocess.DEVNULL,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    except OSError:  # pragma: no cover - no interpreter to start
        return None


def warm_up(parallel: bool = True) -> None:
    """Compile every kernel now, or load it from the cache: the calls of ``tracker.warmup`` (a
    tracker's first frame, a small tracked scene, the update of the pairs, the calls of the kernels a
    scene may not reach) and the functions of ``register_warm_up``. Call it before starting worker
    processes, so that they load the cache instead of each compiling, and before timing.

    Where a kernel is missing from the cache, one line says so (``report_to``; stderr by default)
    before the compilation and one after it with the seconds it took; with ``parallel`` a helper
    process compiles the update of the pairs meanwhile, into the same cache. Nothing is said when every
    kernel loads from the cache. Once per process: later calls return at once."""
    global _WARM
    if _WARM:
        return
    watch = _Compiling(parallel)
    with _event.install_listener("numba:compile", watch):
        try:
            # this process's share while the helper compiles the update of the pairs; then the rest
            first_frame()
            predict_share()
            other_calls()
            for function in _EXTRA_WARM_UPS:
                function()
            watch.join()
            update_share()
            scene()
        finally:
            watch.stop()
    if watch.started is not None:
        _report(f"compiled the tracker's kernels in {time.perf_counter() - watch.started:.0f} s")
    _WARM = True


EGO = (100.0, 0.0, 0.0, 10.0, 0.0)  # x, y (m), yaw (rad), speed (m/s), yaw rate (rad/s) of the scenes' ego
LIDAR_STEP_DEG = 0.2  # the scenes' lidar resolution (deg)


def _road():
    from tracker.road import Road

    return Road.from_curvature([(300.0, 0.0, 0.0)], lanes=2, lane_width=3.5)


def _tracker(first_scan: bool = True):
    from tracker.config import TrackerConfig
    from tracker.tracker import Tracker

    config = TrackerConfig()
    if not first_scan:
        config = dataclasses.replace(config, birth=dataclasses.replace(config.birth, first_scan=False))
    return Tracker(_road(), config)


def _bearings() -> np.ndarray:
    return np.arange(-np.pi, np.pi, np.radians(LIDAR_STEP_DEG))


def _scan(centres: np.ndarray, length: float = 4.5, width: float = 1.9) -> list[np.ndarray]:
    """Per vehicle (centres ``(V, 2)`` in the ego frame, heading 0) its lidar returns."""
    from tracker.measurement import rectangle_corners, rectangle_scan

    bearings = _bearings()
    return [rectangle_scan(rectangle_corners(c, np.array(0.0), np.array(length), np.array(width)), bearings)[0]
            for c in centres]


def _frame(k: int):
    """Frame ``k`` (0.1 s apart) of two cars ahead of the ego, 15 and 22 m away at first, in both lanes."""
    from tracker.frame import EgoState, Frame, RadarDetections

    t = 0.1 * k
    cars = np.array([[15.0 + 12.0 * t, 1.75], [22.0 + 10.0 * t, -1.75]])
    radar = RadarDetections(t=np.full(2, t), x=cars[:, 0], y=cars[:, 1], vx=np.array([12.0, 10.0]), vy=np.zeros(2))
    return Frame(t, EgoState(*EGO), np.concatenate(_scan(cars)), radar)


def first_frame() -> None:
    """One frame of a tracker without first-scan births: its road births lie at the lidar's range
    limit, far from the two cars, so no cluster pairs with a component and the update's kernels are
    not reached."""
    tracker = _tracker(first_scan=False)
    tracker.road.frame(np.array([1.0, 2.0]))
    tracker.road.to_frenet(np.array([[10.0, 1.0], [20.0, -1.0]]))  # Road._project's kernels
    tracker.step(_frame(0))


def update_share() -> None:
    """The update of the pairs as the tracker calls it (``update_clusters``): a truck's 12 m side seen by
    a component with a car's length prior, whose prior is widened, so that the fused kernel hands the
    pairs back to the two steps and the staged kernels; and the clusters prepared alone, with and
    without their shadow flags (``tracker.preparation``)."""
    from tracker.frame import EgoState
    from tracker.preparation import prepare_batch, prepare_scanned_batch
    from tracker.update import update_clusters, update_pairs

    tracker = _tracker()
    ego = EgoState(*EGO)
    truck = _scan(np.array([[30.0, 1.75]]), length=12.0, width=2.5)[0]
    scan = np.concatenate([truck, *_scan(np.array([[15.0, -1.75]]))])
    mean = np.zeros((1, tracker.dim))
    mean[0, :7] = [130.0, 1.75, 10.0, 0.0, 0.0, 4.5, 1.9]
    cov = np.diag(np.r_[1.0, 0.2, 1.0, 0.01, 0.01, 0.25, 0.04, np.ones(tracker.dim - 7)])[None]
    pair = np.zeros(1, dtype=np.intp)
    update_clusters(mean, cov, truck, np.array([0, len(truck)]), np.zeros((1, 2)), np.ones(1, dtype=bool), pair, pair,
                    scan, ego, tracker.road, tracker.config, tracker.ut)
    batch = prepare_batch([truck], tracker.config.measurement)
    prepare_scanned_batch([truck], tracker.config.measurement, None, truck, 0.01, 100.0)  # the two steps' first
    update_pairs(mean, cov, batch, np.zeros(1, dtype=int), np.zeros(1, dtype=int), ego, tracker.road, tracker.config,
                 tracker.ut)


def predict_share() -> None:
    """The UKF prediction of two components (``Tracker._predict`` as a frame calls it)."""
    from tracker.reduction import Mixture

    tracker = _tracker()
    means = np.zeros((2, tracker.dim))
    means[:, :7] = [[115.0, 1.75, 12.0, 0.0, 0.0, 4.5, 1.9], [122.0, -1.75, 10.0, 0.0, 0.0, 4.5, 1.9]]
    covs = np.broadcast_to(np.diag(np.r_[1.0, 0.2, 1.0, 0.01, 0.01, 0.25, 0.04, np.ones(tracker.dim - 7)]),
                           (2, tracker.dim, tracker.dim)).copy()
    tracker.mixture = Mixture(np.array([0.9, 0.8]), means, covs, np.array([1, 2]))
    tracker._predict(0.1, set())


def other_calls() -> None:
    """The kernels that a small scene may not reach: a closed road's frame, the Cartesian births'
    occlusion test, the points in rectangles, the grouping's second call and its hand-back's partition,
    the cuts along a track's cluster and the bounds they set, the reduce stage whatever the scene reached (the reduction in view, the test of the components
    inside an updated one's rectangle, ``absorb_overlapping``'s screen along the road and in Cartesian
    axes), the report-range centres of the extraction, the 3-D cloud's wall-feet pass, classification and
    seen-over pass, the partition's adaptive breakpoint joins."""
    from tracker.cloud import classify_kernel, seen_over_kernel, wall_feet_kernel
    from tracker.clustering import SPLIT_MAX_CUTS, distance_partition, points_in_rectangles, ray_partition
    from tracker.clustering import along_cuts_kernel, ordered_clusters_kernel
    from tracker.extent import bound_at_holes_kernel
    from tracker.reduction import inside_updated_kernel
    from tracker.detection import occluded_fraction
    from tracker.frame import EgoState
    from tracker.measurement import Rectangles
    from tracker.reduction import Mixture, absorb_overlapping, reduce_in_view
    from tracker.road import Road
    from tracker.tracker import _centres, _duplicate_groups

    ring = Road.from_waypoints(np.array([[100.0, 0.0], [0.0, 100.0], [-100.0, 0.0], [0.0, -100.0]]), closed=True)
    ring.frame(np.array([1.0, 2.0]))
    tracker = _tracker()
    road = tracker.road
    road.to_frenet(np.array([[10.0, 1.0], [150.0, 400.0]]))  # a point off the seed grid: its start from the k-d tree
    rect = Rectangles(np.array([[10.0, 0.0], [11.0, 0.5]]), np.zeros(2), np.zeros(2), np.full(2, 4.5), np.full(2, 1.9))
    _duplicate_groups(rect)
    occluded_fraction(rect, np.array([1, 2]), rect, np.array([3, 4]))
    points_in_rectangles(np.array([[10.0, 0.0]]), rect.center, rect.psi, rect.length, rect.width, 1.0)
    pts = np.array([[10.0, 0.0], [10.5, 0.0]])
    distance_partition(pts, 1.0)
    ray_partition(pts, 1.0, 0.07, 0.0035)  # the adaptive breakpoint rule's joins
    ordered_clusters_kernel(pts, np.array([0, -1]), np.array([True, False]), np.zeros(2, dtype=np.int64), 1, np.zeros(2),
                            True, 3.0, 0.5, SPLIT_MAX_CUTS)
    row = np.array([[10.0, -2.0], [11.0, -2.0], [12.0, -2.0], [16.0, -2.0], [17.0, -2.0], [18.0, -2.0]])
    _, _, _, _, bounds = along_cuts_kernel(row, np.array([0, 6]), np.array([0]), np.array([[14.0, -3.0]]), np.ones(1),
                                           np.zeros(1), np.full(1, 4.5), np.full(1, 1.0), row, 0.0035, 3.0, 1.0, 0.5, 3)
    car = np.array([[14.0, -3.0, 10.0, 0.0, 0.0, 9.0, 1.9]])
    bound_at_holes_kernel(car.copy(), np.eye(7)[None].copy(), rect.corners()[:1], np.zeros(1, dtype=np.int64),
                          np.array([[14.0, -3.0]]), np.ones(1), np.zeros(1), bounds, 1.0)
    means = np.array([[130.0, 1.75, 10.0, 0.0, 0.0, 4.5, 1.9], [130.5, 1.75, 10.0, 0.0, 0.0, 4.5, 1.9]])
    mix = Mixture(np.array([0.9, 0.6]), means, np.broadcast_to(np.eye(7), (2, 7, 7)).copy(), np.array([1, 1]))
    reduce_in_view(mix, np.full(2, 30.0), 102.0, means[:, 1], (-5.0, 5.0), prune_threshold=1e-4, merge_gate=4.0,
                   max_components=100, wrapping=tracker.wrapping, same_label_distance=3.0, s_period=500.0)
    inside_updated_kernel(rect.center, np.ones(1), np.zeros(1), rect.length, rect.width, np.zeros(1, dtype=np.int64),
                          np.ones(1, dtype=np.int64))
    two = Mixture(mix.weights, mix.means, mix.covs, np.array([1, 2]))
    absorb_overlapping(two, 0.5, 0.5, tracker.wrapping)
    absorb_overlapping(two, 0.5, 0.5, tracker.wrapping, cartesian=True)
    _centres(means, np.array([0, 1], dtype=np.intp), EgoState(*EGO), road, "curvilinear")
    wall_feet_kernel(np.zeros(2), np.array([5.0, 5.05]), np.array([0.0, 1.0]), 0.15)
    seen_over_kernel(np.arange(2), np.ones(2, dtype=np.bool_), np.zeros(2), np.array([5.0, 9.0]), np.array([0.5, 1.5]), 1.9,
                     0.5, 1e-3)
    classify_kernel(np.array([[5.0, 0.0, 0.2], [5.0, 0.0, 1.0]]), np.zeros(2, dtype=np.intp), np.array([[0.0, 0.0, 1.0]]),
                    np.zeros(1), 0.15, 4.0, 0.3, 0.5)


def scene(frames: int = 4) -> None:
    """``frames`` frames of the two cars tracked with the default configuration (first-scan births,
    then the update of the pairs, the prediction, the reduction, the extraction)."""
    tracker = _tracker()
    for k in range(frames):
        tracker.step(_frame(k))


if __name__ == "__main__":  # the helper process of warm_up
    update_share()
