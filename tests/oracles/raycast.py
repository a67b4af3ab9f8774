"""The 2-D ray caster (``sim.sensors.raycast.cast``) in vectorised numpy: the same culling, angular
broad phase and narrow phase, batched over all (ray, edge) pairs, so the ranges are the same
floating-point expressions and the owners the same, bit for bit.

1. cull: drop edges facing away from the origin (``a x b >= 0`` for counter-clockwise polygons), or
   only the edges on a line through the origin (``a x b == 0``) without culling;
2. broad phase: each edge subtends the bearing interval between its end points (rad, relative to the
   grid's start wrapped to ``[-pi, pi]``); its rays are a contiguous index range, modulo the ray count
   on a full circle; on a fan, the interval and its copy one turn lower, each clipped to the fan; one
   extra ray on each side;
3. narrow phase: with ``d`` the ray direction, ``ca = d x a``, ``cb = d x b``: a hit iff
   ``ca * cb <= 0`` and ``0 < t <= max_range`` for ``t = (a x b) / (cb - ca)``;
4. per ray the smallest ``t`` wins (``np.minimum.at``); of equal ones, the pair written last (in the
   order of step 2) gives the owner.
"""

from __future__ import annotations

import math

import numpy as np

from sim.sensors.raycast import CastResult, RayGrid, Segments

TWO_PI = 2.0 * math.pi


def cast_numpy(segments: Segments, grid: RayGrid, max_range: float, *, cull_back_faces: bool = True) -> CastResult:
    """First hit of every ray of ``grid`` on ``segments`` within ``max_range`` (m) (module docstring)."""
    count = grid.count
    ranges = np.full(count, np.inf)
    owners = np.full(count, -1, dtype=np.int64)
    if len(segments) == 0:
        return CastResult(ranges, owners)
    a, b = segments.a, segments.b
    cr = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]  # a x b: < 0 when the edge faces the origin (CCW polygon)
    idx = np.flatnonzero(cr < 0.0 if cull_back_faces else cr != 0.0)
    if idx.size == 0:
        return CastResult(ranges, owners)
    a, b, cr = a[idx], b[idx], cr[idx]
    ax, ay, bx, by = a[:, 0], a[:, 1], b[:, 0], b[:, 1]
    # the edge subtends [lo, hi] (rad, relative to the grid start), < pi wide; with cr < 0 the end b
    # is clockwise of a, so the interval runs from b to a
    start = math.remainder(grid.start, TWO_PI)
    rel_a = np.arctan2(ay, ax) - start  # in (-2 pi, 2 pi]
    rel_b = np.arctan2(by, bx) - start
    if cull_back_faces:
        lo, hi = rel_b, rel_a
    else:
        ccw = cr > 0.0
        lo, hi = np.where(ccw, rel_a, rel_b), np.where(ccw, rel_b, rel_a)
    hi[hi < lo] += TWO_PI
    inv_res = 1.0 / grid.resolution
    if grid.is_full_circle:  # lo + 2 pi > 0: truncation is floor; the extra turn goes with the modulo
        k0 = ((lo + TWO_PI) * inv_res).astype(np.int64)
        k1 = ((hi + TWO_PI) * inv_res).astype(np.int64) + 1
        edge_of_range = np.arange(idx.size)
    else:  # a fan: the interval as is and one turn lower, each clipped to the fan's rays
        span = hi - lo
        lo = np.mod(lo, TWO_PI)
        lo = np.concatenate([lo, lo - TWO_PI])
        hi = lo + np.concatenate([span, span])
        k0 = np.maximum(np.floor(lo * inv_res), 0.0).astype(np.int64)
        k1 = np.minimum(np.floor(hi * inv_res) + 1.0, count - 1.0).astype(np.int64)
        edge_of_range = np.tile(np.arange(idx.size), 2)
    sizes = np.maximum(k1 - k0 + 1, 0)
    seg = np.repeat(edge_of_range, sizes)
    if seg.size == 0:
        return CastResult(ranges, owners)
    ray = np.arange(seg.size) + np.repeat(k0 - (np.cumsum(sizes) - sizes), sizes)
    if grid.is_full_circle:
        ray %= count
    dx, dy = grid.cos[ray], grid.sin[ray]
    sax, say, sbx, sby = ax[seg], ay[seg], bx[seg], by[seg]
    ca = dx * say - dy * sax
    cb = dx * sby - dy * sbx
    with np.errstate(divide="ignore", invalid="ignore"):
        t = cr[seg] / (cb - ca)
    t[~((ca * cb <= 0.0) & (t > 0.0) & (t <= max_range))] = np.inf
    np.minimum.at(ranges, ray, t)
    win = np.flatnonzero((t == ranges[ray]) & (t < np.inf))
    owners[ray[win]] = segments.owner[idx[seg[win]]]  # fancy assignment: the last write wins
    return CastResult(ranges, owners)
