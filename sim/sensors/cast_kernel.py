"""The compiled twin of ``sim.sensors.raycast.cast_numpy`` (numba, optional; see ``tracker.compiled``).

The same algorithm edge by edge: back-face culling, the angular broad phase (the rays between the
edge's end bearings, on a fan the interval and its copy one turn lower, each clipped to the fan) and
the narrow phase ``t = (a x b) / (cb - ca)`` with ``ca * cb <= 0`` and ``0 < t <= max_range``. The
pairs are visited in ``cast_numpy``'s order (on a fan: every edge's first interval, then every
edge's second), and a pair whose range ties the ray's best takes the owner, as the last write of
``cast_numpy``'s fancy assignment does. The ranges are the same floating-point expressions, so the
two casters agree bit for bit except where an end bearing's ``arctan2`` differs in its last bit
between numpy and libm, which moves only the broad phase's guard ray.

``cast_numpy`` is the reference; ``tests/test_sensors.py`` compares the two. A scene of a few dozen
edges costs numpy ~40 array calls (0.1-0.3 ms); the kernel needs ~5-20 us.
"""

from __future__ import annotations

import math

import numpy as np

from tracker.compiled import njit

TWO_PI = 2.0 * math.pi


@njit(error_model="numpy")
def _narrow(k_from, k_to, count, wrap, ax, ay, bx, by, cr, owner, cos, sin, max_range, ranges, owners):  # pragma: no cover - compiled
    for k in range(k_from, k_to + 1):
        ray = k % count if wrap else k
        dx, dy = cos[ray], sin[ray]
        ca = dx * ay - dy * ax
        cb = dx * by - dy * bx
        t = cr / (cb - ca)
        if ca * cb <= 0.0 and t > 0.0 and t <= max_range and t <= ranges[ray]:
            ranges[ray] = t
            owners[ray] = owner


@njit(error_model="numpy")
def cast_kernel(a, b, owner, start, resolution, cos, sin, full_circle, max_range, cull_back_faces):  # pragma: no cover - compiled
    """Per ray: range (count,) to the first hit (``inf`` for none) and the hit edge's owner (-1);
    arguments as ``cast_numpy``'s, the grid given by its (already wrapped) ``start``, ``resolution``
    and direction cosines and sines."""
    count = cos.shape[0]
    ranges = np.full(count, np.inf)
    owners = np.full(count, -1, dtype=np.int64)
    n = a.shape[0]
    inv_res = 1.0 / resolution
    keep = np.zeros(n, dtype=np.bool_)
    crs = np.empty(n)
    los = np.empty(n)
    spans = np.empty(n)
    for i in range(n):
        ax, ay, bx, by = a[i, 0], a[i, 1], b[i, 0], b[i, 1]
        cr = ax * by - ay * bx
        if cull_back_faces:
            if not cr < 0.0:
                continue
        elif cr == 0.0:
            continue
        rel_a = math.atan2(ay, ax) - start
        rel_b = math.atan2(by, bx) - start
        if cull_back_faces or not cr > 0.0:
            lo, hi = rel_b, rel_a
        else:
            lo, hi = rel_a, rel_b
        if hi < lo:
            hi += TWO_PI
        keep[i] = True
        crs[i] = cr
        los[i] = lo
        spans[i] = hi - lo
        if full_circle:
            k0 = int((lo + TWO_PI) * inv_res)
            k1 = int((hi + TWO_PI) * inv_res) + 1
            _narrow(k0, k1, count, True, ax, ay, bx, by, cr, owner[i], cos, sin, max_range, ranges, owners)
    if full_circle:
        return ranges, owners
    for turn in range(2):  # a fan: every edge's interval, then every edge's copy one turn lower
        for i in range(n):
            if not keep[i]:
                continue
            lo = los[i] % TWO_PI  # Python's float modulo, as np.mod: fmod, then the divisor's sign
            if turn == 1:
                lo -= TWO_PI
            hi = lo + spans[i]
            k0 = max(int(math.floor(lo * inv_res)), 0)
            k1 = min(math.floor(hi * inv_res) + 1.0, count - 1.0)
            _narrow(k0, int(k1), count, False, a[i, 0], a[i, 1], b[i, 0], b[i, 1], crs[i], owner[i], cos, sin,
                    max_range, ranges, owners)
    return ranges, owners
