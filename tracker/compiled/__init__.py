"""Compiled kernels (numba) for the tracker's per-frame fixed costs.

At the tracker's sizes (a few to a few dozen clusters and components per frame) numpy's cost is the
number of calls, not the arithmetic: preparing one cluster takes as long as preparing ten. The kernels
here do the same work as their numpy references in one compiled call each. numba is a dependency of
the package and the kernels are the tracker's default path. With the environment variable
``EOT_NUMBA=0`` (or where numba cannot be imported) the tracker runs the numpy code, which stays the
reference: ``tests/test_compiled.py`` checks every kernel against it (the same discrete decisions, the
numbers within 1e-9; sums run in another order).

``enabled()`` says whether the kernels are used; ``require()`` raises a clear error when they are asked
for and numba is missing; ``pinned()`` reads the switch once for a block (one ``Tracker.step``).

Compilation and the cache. The kernels compile on first use and are cached (``cache=True``: next to
this package, or under ``NUMBA_CACHE_DIR``); later processes load them (about 0.6 s for all).
``warm_up()`` compiles or loads them all at once, through the calls of ``tracker.compiled._warm``.
Where a kernel is missing from the cache it reports one line before compiling (with the expected time,
``COMPILE_ESTIMATE_S``) and one after (``report_to``: stderr by default), and a helper process
compiles the update of the pairs meanwhile into the same cache, so that two cores share the work.
Kernels call kernels of other files (``pairs`` calls ``centerline``, ``structure``, ``extent``,
``kalman`` and ``preparation``; ``centerline``, ``detection`` and the simulator's
``sim.sensors.cast_kernel`` call ``geometry``; ...), and numba's cache checks a kernel's own file
only; so every kernel built with ``njit`` here is keyed by the contents of its own file and of every
file of this folder (``tracker.compiled._cache``): editing any kernel recompiles all of them on their
next call, with no manual step.

Kernels: ``preparation`` (cluster preparation; with the ends' shadow flags), ``structure`` (the
measurement structure), ``centerline`` (clothoid and Hermite frames, the projection and its seeding,
states to rectangles, sigma points with their rectangles), ``motion`` (Frenet RK4; the whole UKF
prediction), ``clustering`` (bearing filter, distance partition, radar association, points in
rectangles, overlap groups, ends next to a shadow; the tracker's whole grouping of the points into
clusters, its radar association), ``reduction`` (the reduce stage: the field-of-view and road test,
prune, merge, cap and the closed road's ``s`` in one call; the test of components inside an updated
one's rectangle; the candidates of overlapping labels and their overlap test), ``kalman`` (the UKF
update of the pairs; with the predicted measurements and the radar gate), ``extent`` (the extent rules
before and after the update), ``pairs`` (the whole update of the pairs in one call: the sigma points'
rectangles through the extent rules; with the pairs' clusters prepared first), ``preprocess`` (the
lidar's road filter: projection, road bounds, bearing filter), ``gating`` (the update's pre-gating of
the pairs), ``birth`` (the road births and where a vehicle can enter the view), ``ukf`` (sigma points
and their moments; a proof of positive definiteness before LAPACK), ``extraction`` (the report-range
test's rectangle centres of the components to report).
Where one kernel does the work of several numpy steps it repeats their operations in their order, so
that the numbers are the same bit for bit, except where numpy's sums run in another order (matrix
products, the Kalman update): there they agree to rounding (``tests/test_compiled.py`` says which).
Small helpers that only other kernels call are inlined into them (``inline="always"``), which
compiles faster than a kernel of their own. An inlined helper takes its caller's flags (fastmath, error
model): inlining a helper into a caller of other flags (the ``kalman`` kernels use fastmath) may change
the numbers.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time

try:  # pragma: no cover - exercised by whichever environment runs the tests
    import numba as _numba
    from numba.core import event as _event
except ImportError:  # pragma: no cover
    _numba = _event = None

from tracker.compiled import _cache  # noqa: E402 - needs nothing above; kept beside njit's use

ENV_SWITCH = "EOT_NUMBA"
COMPILE_ESTIMATE_S = 40  # s: a cold warm_up() on a 2-core machine (the line warm_up() reports before compiling)
HELPER_TIMEOUT_S = 600.0  # s: warm_up() stops waiting for its helper process after this (and compiles its share)
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
        raise RuntimeError("the compiled kernels need numba, a dependency of frenet-eot: pip install numba "
                           "(or reinstall the package); EOT_NUMBA=0 runs the numpy code")


def njit(*args, **kwargs):
    """``numba.njit(cache=True, no_cfunc_wrapper=True, ...)`` (no kernel is passed around as a C
    function pointer, so numba's C-callable wrapper is not built); without numba a decorator that leaves
    the function as it is (the kernels are then never called by the tracker, but stay importable and
    testable as plain Python)."""
    kwargs.setdefault("cache", True)
    kwargs.setdefault("no_cfunc_wrapper", True)
    if _numba is None:
        if args and callable(args[0]):
            return args[0]
        return lambda f: f
    if kwargs["cache"]:
        _cache.install()

        def decorate(function):
            _cache.register(function.__code__.co_filename)  # keyed by every kernel file (tracker.compiled._cache)
            return _numba.njit(**kwargs)(function)

        return decorate(args[0]) if args and callable(args[0]) else decorate
    return _numba.njit(*args, **kwargs)


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


class _Compiling(_event.Listener if _event is not None else object):
    """A listener of numba's compile events (``numba.core.event``) for one ``warm_up()``: the first
    compilation (a kernel missing from the cache) reports the start and, while the calling process's
    share runs, starts the helper process on the other share (``tracker.compiled._warm``)."""

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
    """The helper process: ``python -P -m tracker.compiled._warm`` (its share: the update of the pairs)
    by this interpreter with this process's environment, without the working directory on its path
    (``-P``); None where it cannot start or where this process has one CPU only. Where it fails (a
    package this process found only through a path it added itself) this process compiles that share."""
    if _cores() < 2:
        return None
    try:
        return subprocess.Popen([sys.executable, "-P", "-m", "tracker.compiled._warm"], stdin=subprocess.DEVNULL,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    except OSError:  # pragma: no cover - no interpreter to start
        return None


def warm_up(parallel: bool = True) -> bool:
    """Compile every kernel now, or load it from the cache: the calls of ``tracker.compiled._warm`` (a
    tracker's first frame, a small tracked scene, the update of the pairs, the calls of the kernels a
    scene may not reach) and the functions of ``register_warm_up``. Call it before starting worker
    processes, so that they load the cache instead of each compiling, and before timing.

    Where a kernel is missing from the cache, one line says so (``report_to``; stderr by default)
    before the compilation and one after it with the seconds it took; with ``parallel`` a helper
    process compiles the update of the pairs meanwhile, into the same cache. Nothing is said when every
    kernel loads from the cache. Returns whether the kernels are on (nothing is done when they are
    off). Once per process: later calls return at once."""
    global _WARM
    if not enabled():
        return False
    if _WARM:
        return True
    from tracker.compiled import _warm

    watch = _Compiling(parallel)
    with _event.install_listener("numba:compile", watch):
        try:
            # this process's share while the helper compiles the update of the pairs; then the rest
            _warm.first_frame()
            _warm.predict_share()
            _warm.other_calls()
            for function in _EXTRA_WARM_UPS:
                function()
            watch.join()
            _warm.update_share()
            _warm.scene()
        finally:
            watch.stop()
    if watch.started is not None:
        _report(f"compiled the tracker's kernels in {time.perf_counter() - watch.started:.0f} s")
    _WARM = True
    return True
