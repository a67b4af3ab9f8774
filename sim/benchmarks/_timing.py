"""Timing helper shared by the benchmark modules (not a benchmark target: its name starts with ``_``)."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable


def median_seconds(fn: Callable[[], object], repeat: int, inner: int = 1) -> float:
    """Median wall time (s) of one call of ``fn`` over ``repeat`` measurements of ``inner`` calls
    each, after one warm-up call."""
    fn()  # warm up
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(inner):
            fn()
        times.append((time.perf_counter() - t0) / inner)
    return statistics.median(times)
