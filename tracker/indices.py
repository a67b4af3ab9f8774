"""Index bookkeeping of small non-negative integer arrays (component and cluster indices of a frame),
without ``numpy.unique``'s sort: a count over the index range does it in two passes."""

from __future__ import annotations

import numpy as np


def unique_indices(index: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
    """``numpy.unique(index, return_inverse=True)`` of indices ``0 <= index < count``: the sorted
    distinct indices and, per entry, its position among them."""
    index = np.asarray(index, dtype=np.intp).reshape(-1)
    present = np.bincount(index, minlength=count) > 0
    used = np.flatnonzero(present)
    slot = np.cumsum(present) - 1
    return used, slot[index]
