"""Compiled centerline evaluation: ``ClothoidCenterline.frame`` and ``HermiteCenterline.frame``
(``tracker.centerline``) as one numba call each, with the same bucket lookup of the cell, the same
per-cell closed forms (the clothoid's Taylor cos/sin and 4-point Gauss-Legendre position integral; the
Hermite cell's cubic ``tau(s)`` and the spline's derivatives)."""

from __future__ import annotations

import numpy as np

from tracker.compiled import njit


@njit
def _locate(s, bucket_cell, starts_next, inv_bucket, hops, last):
    k = min(int(s * inv_bucket), len(bucket_cell) - 1)
    idx = bucket_cell[max(k, 0)]
    for _ in range(hops):
        if s >= starts_next[idx]:
            idx += 1
    return min(idx, last)


@njit
def _cos_sin_small(phi):
    p2 = phi * phi
    cos = 1.0 + p2 * (-1 / 2 + p2 * (1 / 24 + p2 * (-1 / 720 + p2 * (1 / 40320 - p2 / 3628800))))
    sin = phi * (1.0 + p2 * (-1 / 6 + p2 * (1 / 120 + p2 * (-1 / 5040 + p2 * (1 / 362880 - p2 / 39916800)))))
    return cos, sin


@njit
def _frame_arrays(count):
    """Empty outputs of a frame kernel: positions and unit tangents ``(count, 2)``, curvatures ``(count,)``."""
    return np.empty((count, 2)), np.empty((count, 2)), np.empty(count)


@njit
def clothoid_frame(s, table, bucket_cell, starts_next, inv_bucket, hops, nodes, weights):
    """Position ``(N, 2)``, unit tangent ``(N, 2)``, curvature ``(N,)`` at ``s (N,)`` in [0, length];
    ``table`` rows ``(start, x, y, cos0, sin0, kappa0, rate)`` per cell."""
    count = len(s)
    last = len(table) - 1
    p, tangent, kappa = _frame_arrays(count)
    for i in range(count):
        row = table[_locate(s[i], bucket_cell, starts_next, inv_bucket, hops, last)]
        d = s[i] - row[0]
        cos0, sin0, k0, kr = row[3], row[4], row[5], row[6]
        ic = 0.0
        is_ = 0.0
        for g in range(len(nodes)):
            dd = d * nodes[g]
            c, sn = _cos_sin_small((k0 + 0.5 * kr * dd) * dd)
            ic += c * weights[g]
            is_ += sn * weights[g]
        p[i, 0] = row[1] + d * (cos0 * ic - sin0 * is_)
        p[i, 1] = row[2] + d * (sin0 * ic + cos0 * is_)
        ce, se = _cos_sin_small((k0 + 0.5 * kr * d) * d)
        tangent[i, 0] = cos0 * ce - sin0 * se
        tangent[i, 1] = sin0 * ce + cos0 * se
        kappa[i] = k0 + kr * d
    return p, tangent, kappa


@njit
def hermite_frame(s, table, bucket_cell, starts_next, inv_bucket, hops):
    """As ``clothoid_frame``; ``table`` rows ``(start, q0..q3, x0, y0, x1, y1, x2, y2, x3, y3)``."""
    count = len(s)
    last = len(table) - 1
    p, tangent, kappa = _frame_arrays(count)
    for i in range(count):
        row = table[_locate(s[i], bucket_cell, starts_next, inv_bucket, hops, last)]
        d = s[i] - row[0]
        tau = ((row[4] * d + row[3]) * d + row[2]) * d + row[1]
        x0, y0, x1, y1, x2, y2, x3, y3 = row[5], row[6], row[7], row[8], row[9], row[10], row[11], row[12]
        p[i, 0] = ((x3 * tau + x2) * tau + x1) * tau + x0
        p[i, 1] = ((y3 * tau + y2) * tau + y1) * tau + y0
        dx = (3.0 * x3 * tau + 2.0 * x2) * tau + x1
        dy = (3.0 * y3 * tau + 2.0 * y2) * tau + y1
        ddx = 6.0 * x3 * tau + 2.0 * x2
        ddy = 6.0 * y3 * tau + 2.0 * y2
        speed = np.hypot(dx, dy)
        kappa[i] = (dx * ddy - dy * ddx) / speed**3
        tangent[i, 0] = dx / speed
        tangent[i, 1] = dy / speed
    return p, tangent, kappa
