"""The 3-D preprocessing's compiled steps (``tracker.cloud``) in plain numpy: the steep-rise and the
rho-bin tests of ``_wall_feet`` on returns sorted by azimuth column, then outwards."""

from __future__ import annotations

import numpy as np


def wall_feet_sorted(c: np.ndarray, r: np.ndarray, h: np.ndarray, tau: float) -> np.ndarray:
    """``tracker.cloud.wall_feet_kernel``: the feet (N,) among returns sorted by column ``c`` then
    ``rho`` ``r``, heights ``h``; ``tau`` the distance threshold (m)."""
    n = len(c)
    out = np.zeros(n, dtype=bool)
    if n < 2:
        return out
    rise = np.abs(h[1:] - h[:-1])
    steep = (c[1:] == c[:-1]) & (rise > tau) & (r[1:] - r[:-1] <= rise)
    lower = np.where(h[1:] < h[:-1], np.arange(1, n), np.arange(n - 1))
    out[lower[steep]] = True
    b = np.floor(r / tau)
    new = np.r_[True, (c[1:] != c[:-1]) | (b[1:] != b[:-1])]
    start = np.flatnonzero(new)
    top = np.maximum.reduceat(h, start)  # each (column, bin) group's highest return
    group = np.cumsum(new) - 1
    gc, gb = c[start], b[start]
    above = top.copy()
    nxt = (gc[1:] == gc[:-1]) & (gb[1:] == gb[:-1] + 1)  # the next group is the next bin out
    above[:-1] = np.where(nxt, np.maximum(above[:-1], top[1:]), above[:-1])
    above[1:] = np.where(nxt, np.maximum(above[1:], top[:-1]), above[1:])
    out[h < above[group] - tau] = True
    return out


def classify(pts: np.ndarray, patch: np.ndarray, normals: np.ndarray, offsets: np.ndarray, tau: float, ceiling: float,
             low_height: float | None, cell: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``tracker.cloud.classify_kernel``: heights, the masks ground, below ground, above the ceiling,
    low object and kept, and the kept points' projections ``(M, 2)``."""
    n = normals[patch]
    h = pts[:, 0] * n[:, 0]
    h += pts[:, 1] * n[:, 1]
    h += pts[:, 2] * n[:, 2]
    h += offsets[patch]
    ground = np.abs(h) <= tau
    below = h < -tau
    above = h > ceiling
    kept = ~(ground | below | above)
    low_object = np.zeros(len(pts), dtype=bool)
    rows = np.flatnonzero(kept)
    if low_height is not None and len(rows):
        low = h[rows] <= low_height
        cells = np.floor(pts[rows, :2] / cell).astype(np.intp)
        cells -= cells.min(axis=0)
        high = np.zeros(tuple(cells.max(axis=0) + 1), dtype=bool)
        high[cells[~low, 0], cells[~low, 1]] = True
        low_object[rows[low & ~high[cells[:, 0], cells[:, 1]]]] = True
    kept &= ~low_object
    xy = (pts[kept] - h[kept, None] * n[kept])[:, :2]
    return h, np.stack([ground, below, above, low_object, kept]), xy
