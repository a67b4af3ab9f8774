"""Optional compiled kernels (numba) for the tracker's per-frame fixed costs.

At the tracker's sizes (a few to a few dozen clusters and components per frame) numpy's cost is the
number of calls, not the arithmetic: preparing one cluster takes as long as preparing ten. The kernels
here do the same work as their numpy references in one compiled call each. They are an optional extra
(``pip install -e ".[fast]"``); without numba, or with the environment variable ``EOT_NUMBA=0``, the
tracker runs the numpy code, which stays the reference: ``tests/test_compiled.py`` checks every kernel
against it (the same discrete decisions, the numbers within 1e-9; sums run in another order).

``enabled()`` says whether the kernels are used; ``require()`` raises a clear error when they are asked
for and numba is missing; ``warm_up()`` compiles (or loads) them all at once. They compile on first
use and are cached next to this package (``cache=True``): a fresh checkout compiles once (~20 s on this
project's machines), later processes load them (~0.3 s). Numba's cache checks a kernel's own file only:
after editing a kernel that kernels of other files call (``pairs`` calls ``centerline``, ``structure``,
``extent``, ``kalman`` and ``preparation``; ``preparation`` and ``reduction`` call ``clustering``;
``centerline``, ``motion`` and ``kalman`` call ``ukf``; ``centerline`` and ``detection`` call ``geometry``;
``extraction`` calls ``centerline``; ``birth`` calls ``centerline`` and ``detection``; ``preprocess`` calls
``centerline`` and ``clustering``), delete ``tracker/compiled/__pycache__`` so that the callers compile
again with it.

Kernels: ``preparation`` (cluster preparation; with the ends' shadow flags), ``structure`` (the measurement structure),
``centerline`` (clothoid and Hermite frames, the projection and its seeding, states to rectangles, sigma
points with their rectangles), ``motion`` (Frenet RK4; the whole UKF prediction), ``clustering``
(bearing filter, distance partition, radar association, points in rectangles, overlap groups, ends
next to a shadow; the tracker's whole grouping of the points into clusters, its radar association),
``reduction`` (the reduce stage: the field-of-view and road test, prune, merge, cap and the closed
road's ``s`` in one call; the test of components inside an updated one's rectangle; the candidates of
overlapping labels and their overlap test), ``kalman`` (the UKF update of the
pairs; with the predicted measurements and the radar gate), ``extent`` (the extent rules before and after
the update), ``pairs`` (the whole update of the pairs in one call: the sigma points' rectangles through
the extent rules; with the pairs' clusters prepared first), ``preprocess`` (the lidar's road filter:
projection, road bounds, bearing filter), ``gating`` (the update's pre-gating of the pairs), ``birth``
(the road births and where a vehicle can enter the view), ``ukf`` (sigma points and their moments; a proof of positive definiteness before LAPACK), ``extraction`` (the report-range test's rectangle centres of the
components to report).
Where one kernel does the work of several numpy steps it repeats their operations in their order, so
that the numbers are the same bit for bit, except where numpy's sums run in another order (matrix
products, the Kalman update): there they agree to rounding (``tests/test_compiled.py`` says which).
``pinned()``: the switch read once for a block (one ``Tracker.step``).
"""

from __future__ import annotations

import os

try:  # pragma: no cover - exercised by whichever environment runs the tests
    import numba as _numba
except ImportError:  # pragma: no cover
    _numba = None

ENV_SWITCH = "EOT_NUMBA"
_WARM = False  # warm_up() has compiled or loaded every kernel in this process
_EXTRA_WARM_UPS: list = []  # callables registered by other packages' kernels (register_warm_up)


def available() -> bool:
    """Whether numba is installed."""
    return _numba is not None


_PINNED: bool | None = None  # enabled() inside a pinned block (pinned(): one Tracker.step)


def enabled() -> bool:
    """Whether the tracker uses the compiled kernels: numba installed and ``EOT_NUMBA`` not ``0``
    (inside a ``pinned()`` block: as it was when the block began)."""
    if _PINNED is not None:
        return _PINNED
    return _numba is not None and os.environ.get(ENV_SWITCH, "1").strip() not in ("0", "false", "no", "off")


class pinned:
    """``with pinned():`` reads the switch once and answers ``enabled()`` from it until the block ends
    (``Tracker.step`` asks ~25 times per frame; the environment lookup costs ~1 us each). Nested blocks
    keep the outermost value. Changing ``EOT_NUMBA`` inside a block takes effect after it."""

    __slots__ = ("_outer",)

    def __enter__(self) -> bool:
        global _PINNED
        self._outer = _PINNED is None
        if self._outer:
            _PINNED = enabled()
        return _PINNED

    def __exit__(self, *exc) -> None:
        global _PINNED
        if self._outer:
            _PINNED = None


def require() -> None:
    """Raise a clear error when numba is not installed."""
    if _numba is None:
        raise RuntimeError('the compiled kernels need numba: pip install -e ".[fast]" (or set EOT_NUMBA=0)')


def njit(*args, **kwargs):
    """``numba.njit(cache=True, ...)``; without numba a decorator that leaves the function as it is (the
    kernels are then never called by the tracker, but stay importable and testable as plain Python)."""
    kwargs.setdefault("cache", True)
    if _numba is None:
        if args and callable(args[0]):
            return args[0]
        return lambda f: f
    return _numba.njit(*args, **kwargs)


def register_warm_up(function) -> None:
    """Have ``warm_up()`` also call ``function()`` (no arguments): for kernels outside the tracker
    built with this ``njit`` (the simulator's ray caster), so that one call warms them all."""
    if function not in _EXTRA_WARM_UPS:
        _EXTRA_WARM_UPS.append(function)


def warm_up() -> bool:
    """Compile every kernel now (or load it from the cache): a few frames of a small tracked scene
    and one call of each kernel the scene may not reach. Call it before starting worker processes, so
    that they load the cache instead of each compiling (~20 s on a fresh checkout), and before timing.
    Returns whether the kernels are on (nothing is done when they are off). Once per process: later
    calls return at once."""
    global _WARM
    if not enabled():
        return False
    if _WARM:
        return True
    import numpy as np

    from tracker.clustering import points_in_rectangles
    from tracker.config import TrackerConfig
    from tracker.detection import occluded_fraction
    from tracker.frame import EgoState, Frame, RadarDetections
    from tracker.measurement import Rectangles, rectangle_corners, rectangle_scan
    from tracker.road import Road
    from tracker.tracker import Tracker, _duplicate_groups

    ring = Road.from_waypoints(np.array([[100.0, 0.0], [0.0, 100.0], [-100.0, 0.0], [0.0, -100.0]]), closed=True)
    ring.frame(np.array([1.0, 2.0]))
    road = Road.from_curvature([(300.0, 0.0, 0.0)], lanes=2, lane_width=3.5)
    road.to_frenet(np.array([[10.0, 1.0], [20.0, -1.0]]))  # Road._project's kernels (filter_points' fused call holds them)
    tracker = Tracker(road, TrackerConfig())
    bearings = np.arange(-np.pi, np.pi, np.radians(0.2))
    for k in range(4):
        t = 0.1 * k
        cars = np.array([[15.0 + 12.0 * t, 1.75], [22.0 + 10.0 * t, -1.75]])
        scan = [rectangle_scan(rectangle_corners(c, np.array(0.0), np.array(4.5), np.array(1.9)), bearings)[0]
                for c in cars]
        radar = RadarDetections(t=np.full(2, t), x=cars[:, 0], y=cars[:, 1], vx=np.array([12.0, 10.0]), vy=np.zeros(2))
        tracker.step(Frame(t, EgoState(100.0, 0.0, 0.0, 10.0, 0.0), np.concatenate(scan), radar))
    rect = Rectangles(np.array([[10.0, 0.0], [11.0, 0.5]]), np.zeros(2), np.zeros(2), np.full(2, 4.5), np.full(2, 1.9))
    _duplicate_groups(rect)
    occluded_fraction(rect, np.array([1, 2]), rect, np.array([3, 4]))  # the Cartesian births' occlusion test
    points_in_rectangles(np.array([[10.0, 0.0]]), rect.center, rect.psi, rect.length, rect.width, 1.0)
    # the grouping's second call (after a fragment's numpy step) and its hand-back's partition
    from tracker.clustering import SPLIT_MAX_CUTS, distance_partition
    from tracker.compiled.clustering import ordered_clusters_kernel

    pts = np.array([[10.0, 0.0], [10.5, 0.0]])
    distance_partition(pts, 1.0)
    ordered_clusters_kernel(pts, np.array([0, -1]), np.array([True, False]), np.zeros(2, dtype=np.int64), 1, np.zeros(2),
                            True, 3.0, 0.5, SPLIT_MAX_CUTS)
    # the staged kernels a frame takes where the fused ones hand back: a truck's 12 m side seen by a
    # component with a car's length prior (its prior is widened: tracker.update's staged path), and
    # clusters prepared alone, with and without their shadow flags (tracker.preparation)
    from tracker.preparation import prepare_batch, prepare_scanned_batch
    from tracker.update import update_pairs

    truck = rectangle_scan(rectangle_corners(np.array([30.0, 1.75]), np.array(0.0), np.array(12.0), np.array(2.5)),
                           bearings)[0]
    batch = prepare_batch([truck], tracker.config.measurement)
    prepare_scanned_batch([truck], tracker.config.measurement, None, truck, 0.01, 100.0)  # the two steps' first
    mean = np.zeros((1, tracker.dim))
    mean[0, :7] = [130.0, 1.75, 10.0, 0.0, 0.0, 4.5, 1.9]
    cov = np.diag(np.r_[1.0, 0.2, 1.0, 0.01, 0.01, 0.25, 0.04, np.ones(tracker.dim - 7)])[None]
    update_pairs(mean, cov, batch, np.zeros(1, dtype=int), np.zeros(1, dtype=int), EgoState(100.0, 0.0, 0.0, 10.0, 0.0),
                 road, tracker.config, tracker.ut)
    # the reduce stage's kernels, whatever the scene reached: the reduction in view, the test of the
    # components inside an updated one's rectangle, absorb_overlapping's screen (road and Cartesian axes)
    from tracker.compiled.reduction import inside_updated_kernel
    from tracker.reduction import Mixture, absorb_overlapping, reduce_in_view

    means = np.array([[130.0, 1.75, 10.0, 0.0, 0.0, 4.5, 1.9], [130.5, 1.75, 10.0, 0.0, 0.0, 4.5, 1.9]])
    mix = Mixture(np.array([0.9, 0.6]), means, np.broadcast_to(np.eye(7), (2, 7, 7)).copy(), np.array([1, 1]))
    reduce_in_view(mix, np.full(2, 30.0), 102.0, means[:, 1], (-5.0, 5.0), prune_threshold=1e-4, merge_gate=4.0,
                   max_components=100, wrapping=tracker.wrapping, same_label_distance=3.0, s_period=500.0)
    inside_updated_kernel(rect.center, np.ones(1), np.zeros(1), rect.length, rect.width, np.zeros(1, dtype=np.int64),
                          np.ones(1, dtype=np.int64))
    two = Mixture(mix.weights, mix.means, mix.covs, np.array([1, 2]))
    absorb_overlapping(two, 0.5, 0.5, tracker.wrapping)
    absorb_overlapping(two, 0.5, 0.5, tracker.wrapping, cartesian=True)
    # the extraction's report-range centres (tracker.compiled.extraction), whether or not the scene reported
    from tracker.tracker import _centres

    _centres(means, np.array([0, 1], dtype=np.intp), EgoState(100.0, 0.0, 0.0, 10.0, 0.0), road, "curvilinear")
    for function in _EXTRA_WARM_UPS:
        function()
    _WARM = True
    return True
