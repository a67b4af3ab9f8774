"""The paper's bearing filter (``tracker.preprocess.bearing_filter``), in numpy: the closest point of
each bearing bin, by sorting."""

from __future__ import annotations

import numpy as np


def bearing_filter(points: np.ndarray, bin_width: float) -> np.ndarray:
    """Indices of the closest point (the first index among equals) of each bin ``k = floor(bearing /
    bin_width + 1/2)`` (modulo the bin count when the bins tile the circle), in increasing bearing
    order (stable)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    count = round(2.0 * np.pi / bin_width)
    bearing = np.arctan2(pts[:, 1], pts[:, 0])
    rng = np.hypot(pts[:, 0], pts[:, 1])
    bins = np.floor(bearing / bin_width + 0.5).astype(np.int64)
    if abs(count * bin_width - 2.0 * np.pi) <= 1e-9:
        bins = np.mod(bins, count)
    order = np.lexsort((rng, bins))  # by bin, then by range, then by index
    first = np.ones(len(order), dtype=bool)
    first[1:] = bins[order][1:] != bins[order][:-1]
    kept = order[first]
    return kept[np.argsort(bearing[kept], kind="stable")]
