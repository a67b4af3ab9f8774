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

from tracker.jit import njit
from tracker.geometry import corner_offset

TWO_PI = 2.0 * math.pi


@njit(error_model="numpy", inline="always")
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


@njit(error_model="numpy")
def scene_kernel(xy, yaw, length, width, static_edges, static_owner, static_mid, static_half, ox, oy, sensor_yaw,
                 max_range):  # pragma: no cover - compiled
    """``sim.sensors.scene.scene_segments`` in one call: the edges ``a (M, 2)``, ``b (M, 2)`` and
    owners ``(M,)`` of the vehicles' rectangles (rows ``0 .. V-1``, counter-clockwise from the front
    right corner) and the roadside edges (``static_*``: ``[ax, ay, bx, by]`` in G, owners, midpoints,
    half-lengths) within ``max_range`` of the sensor at ``(ox, oy)``, in the sensor frame (heading
    ``sensor_yaw``)."""
    count = xy.shape[0]
    n_static = static_edges.shape[0]
    a = np.empty((4 * count + n_static, 2))
    b = np.empty((4 * count + n_static, 2))
    owner = np.empty(4 * count + n_static, dtype=np.int64)
    c2 = np.cos(sensor_yaw)
    s2 = np.sin(sensor_yaw)
    m = 0
    cx = np.empty(4)
    cy = np.empty(4)
    for v in range(count):
        dx = xy[v, 0] - ox
        dy = xy[v, 1] - oy
        if np.sqrt(dx * dx + dy * dy) - 0.5 * np.sqrt(length[v] ** 2 + width[v] ** 2) > max_range:
            continue
        c = np.cos(yaw[v])
        s = np.sin(yaw[v])
        hl = 0.5 * length[v]
        hw = 0.5 * width[v]
        for k in range(4):
            lx, ly = corner_offset(k, hl, hw)
            cx[k] = xy[v, 0] + c * lx - s * ly - ox
            cy[k] = xy[v, 1] + s * lx + c * ly - oy
        for k in range(4):
            j = (k + 1) % 4
            a[m, 0] = cx[k] * c2 + cy[k] * s2
            a[m, 1] = -cx[k] * s2 + cy[k] * c2
            b[m, 0] = cx[j] * c2 + cy[j] * s2
            b[m, 1] = -cx[j] * s2 + cy[j] * c2
            owner[m] = v
            m += 1
    for e in range(n_static):
        dx = static_mid[e, 0] - ox
        dy = static_mid[e, 1] - oy
        if np.sqrt(dx * dx + dy * dy) - static_half[e] > max_range:
            continue
        ax = static_edges[e, 0] - ox
        ay = static_edges[e, 1] - oy
        bx = static_edges[e, 2] - ox
        by = static_edges[e, 3] - oy
        a[m, 0] = ax * c2 + ay * s2
        a[m, 1] = -ax * s2 + ay * c2
        b[m, 0] = bx * c2 + by * s2
        b[m, 1] = -bx * s2 + by * c2
        owner[m] = static_owner[e]
        m += 1
    return a[:m].copy(), b[:m].copy(), owner[:m].copy()


@njit(error_model="numpy")
def visible_kernel(xy, yaw, length, width, static_edges, static_owner, static_mid, static_half, ox, oy, sensor_yaw,
                   max_range, min_range, start, resolution, cos, sin):  # pragma: no cover - compiled
    """The radar's visibility test in one call (``sim.sensors.radar.RadarUnit.visible``): the scene of
    ``scene_kernel``, cast on the fan (culled, as ``cast_numpy``), then per vehicle the nearest ray
    that hits it at ``>= min_range``. Returns the vehicles' rows (ascending), their rays and ranges."""
    count = xy.shape[0]
    a, b, owner = scene_kernel(xy, yaw, length, width, static_edges, static_owner, static_mid, static_half, ox, oy,
                               sensor_yaw, max_range)
    ranges, owners = cast_kernel(a, b, owner, start, resolution, cos, sin, False, max_range, True)
    best = np.full(count, np.inf)
    best_ray = np.full(count, -1, dtype=np.int64)
    for r in range(ranges.shape[0]):  # rays ascending: the first of equal ranges wins (a stable sort's)
        o = owners[r]
        if 0 <= o < count and ranges[r] >= min_range and ranges[r] < best[o]:
            best[o] = ranges[r]
            best_ray[o] = r
    k = 0
    for v in range(count):
        if best_ray[v] >= 0:
            k += 1
    rows = np.empty(k, dtype=np.int64)
    rays = np.empty(k, dtype=np.int64)
    hit = np.empty(k)
    k = 0
    for v in range(count):
        if best_ray[v] >= 0:
            rows[k] = v
            rays[k] = best_ray[v]
            hit[k] = best[v]
            k += 1
    return rows, rays, hit
