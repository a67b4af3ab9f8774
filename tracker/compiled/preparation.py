"""Compiled cluster preparation: ``tracker.preparation._prepare_finite`` as one numba call.

The numpy reference pads all clusters to the largest and runs ~150 array operations whatever their
number; this kernel walks each cluster once (the same steps, in the same order, see the reference's
module docstring): centroid and scatter, bearing sort (stable), one/two-sided from the eigenvalue
ratio, the corner split from prefix sums, even downsampling (numpy's round half to even), the chords of
slots 0, 1, 2, the fitted corner, the end-gap margins and the kept points' chord coordinates.
"""

from __future__ import annotations

import math

import numpy as np

from tracker.compiled import njit
from tracker.compiled.clustering import bearing_sorted_scan, continued_ends_sorted, occluded_ends_sorted


@njit(inline="always")
def _lambda_min(sxx: float, syy: float, sxy: float) -> float:
    return 0.5 * (sxx + syy) - math.sqrt(0.25 * (sxx - syy) ** 2 + sxy * sxy)


@njit(inline="always")
def _residual(cnt: float, sx: float, sy: float, sxx: float, syy: float, sxy: float) -> float:
    cnt = max(cnt, 1.0)
    return max(_lambda_min(sxx - sx * sx / cnt, syy - sy * sy / cnt, sxy - sx * sy / cnt), 0.0)


@njit(inline="always")
def _even(keep: np.ndarray, lo: int, hi: int, count: int) -> None:
    count = max(count, 2)
    step = (hi - lo) / (count - 1)
    for j in range(count):
        pos = float(hi) if j == count - 1 else j * step + lo
        keep[int(np.rint(pos))] = True


@njit(inline="always")
def _mean_scatter(pts, j0, j1):
    """Centroid and biased scatter ``(cx, cy, sxx, syy, sxy)`` of ``pts[j0:j1 + 1]``."""
    cnt = j1 - j0 + 1
    cx = 0.0
    cy = 0.0
    for j in range(j0, j1 + 1):
        cx += pts[j, 0]
        cy += pts[j, 1]
    cx /= cnt
    cy /= cnt
    sxx = 0.0
    syy = 0.0
    sxy = 0.0
    for j in range(j0, j1 + 1):
        dx = pts[j, 0] - cx
        dy = pts[j, 1] - cy
        sxx += dx * dx
        syy += dy * dy
        sxy += dx * dy
    return cx, cy, sxx / cnt, syy / cnt, sxy / cnt


@njit(inline="always")
def _corner_split(pts: np.ndarray, n: int) -> int:
    cx, cy, _, _, _ = _mean_scatter(pts, 0, n - 1)
    c = np.zeros((n + 1, 6))
    for j in range(n):
        x = pts[j, 0] - cx
        y = pts[j, 1] - cy
        c[j + 1, 0] = c[j, 0] + 1.0
        c[j + 1, 1] = c[j, 1] + x
        c[j + 1, 2] = c[j, 2] + y
        c[j + 1, 3] = c[j, 3] + x * x
        c[j + 1, 4] = c[j, 4] + y * y
        c[j + 1, 5] = c[j, 5] + x * y
    best = np.inf
    k_best = 1
    for k in range(1, n - 1):
        head = _residual(c[k + 1, 0], c[k + 1, 1], c[k + 1, 2], c[k + 1, 3], c[k + 1, 4], c[k + 1, 5])
        tail = _residual(c[n, 0] - c[k, 0], c[n, 1] - c[k, 1], c[n, 2] - c[k, 2],
                         c[n, 3] - c[k, 3], c[n, 4] - c[k, 4], c[n, 5] - c[k, 5])
        if head + tail < best:
            best = head + tail
            k_best = k
    return k_best


@njit
def prepare_kernel(flat, offsets, bound, min_two, ratio_max, gap_correction, min_chord, sin_min_angle, max_shift,
                   max_end_gap):
    """Padded per-cluster arrays (``tracker.preparation._Prepared``'s fields, kept points padded to the
    largest possible count) of the clusters ``flat[offsets[i]:offsets[i + 1]]`` (finite, non-empty)."""
    count = len(offsets) - 1
    width = 0
    for i in range(count):
        width = max(width, min(offsets[i + 1] - offsets[i], bound + 2))
    points = np.zeros((count, width, 2))
    valid = np.zeros((count, width), dtype=np.bool_)
    part = np.zeros((count, width), dtype=np.intp)
    proj = np.zeros((count, 2, width))
    order_out = np.zeros((count, width), dtype=np.intp)
    chord_start = np.zeros((count, 3, 2))
    chord_end = np.zeros((count, 3, 2))
    chord_dir = np.zeros((count, 3, 2))
    chord_len = np.zeros((count, 3))
    end_margin = np.zeros((count, 3, 2))
    end_gap = np.zeros((count, 3, 2))
    two_sided = np.zeros(count, dtype=np.bool_)
    corner_out = np.full(count, -1, dtype=np.intp)
    eigen_ratio = np.zeros(count)
    kept_count = np.zeros(count, dtype=np.intp)
    for i in range(count):
        o = offsets[i]
        n = offsets[i + 1] - o
        raw = flat[o : o + n]
        cx, cy, sxx, syy, sxy = _mean_scatter(raw, 0, n - 1)  # centroid, biased scatter
        # bearing order about the centroid's bearing
        ref = math.atan2(cy, cx) if math.hypot(cx, cy) > 1e-9 else 0.0
        rel0 = np.empty(n)
        for j in range(n):
            a = math.atan2(raw[j, 1], raw[j, 0]) - ref
            rel0[j] = a - 2.0 * np.pi * np.rint(a / (2.0 * np.pi))
        order = np.argsort(rel0, kind="mergesort")
        pts = np.empty((n, 2))
        rel = np.empty(n)
        for j in range(n):
            pts[j, 0] = raw[order[j], 0]
            pts[j, 1] = raw[order[j], 1]
            rel[j] = rel0[order[j]]
        # one or two sides
        root = math.sqrt(0.25 * (sxx - syy) ** 2 + sxy * sxy)
        lam_min = 0.5 * (sxx + syy) - root
        lam_max = 0.5 * (sxx + syy) + root
        ratio = np.inf
        if n >= 2 and lam_min > 1e-15 * max(lam_max, 1e-300):
            ratio = lam_max / lam_min
        two = n >= min_two and ratio < ratio_max
        k = _corner_split(pts, n) if two else -1
        # downsampling
        keep = np.zeros(n, dtype=np.bool_)
        if n > bound:
            if two:
                m0 = min(max(2, int(np.rint(bound * (k + 1) / (n + 1)))), bound - 1)
                _even(keep, 0, k, m0)
                _even(keep, k, n - 1, bound + 1 - m0)
            else:
                _even(keep, 0, n - 1, bound)
        else:
            keep[:] = True
        # chords: slot 0 all points, slot 1 = 0..k, slot 2 = k..n-1 (two-sided)
        norm = max(math.hypot(cx, cy), 1e-12)
        origin = np.zeros((3, 2))
        direction = np.zeros((3, 2))
        lo = np.zeros(3)
        hi = np.zeros(3)
        for s in range(3):
            j0 = 0
            j1 = n - 1
            if two and s == 1:
                j1 = k
            if two and s == 2:
                j0 = k
            cnt = j1 - j0 + 1
            ox, oy, mxx, myy, mxy = _mean_scatter(pts, j0, j1)
            if cnt < 2 or mxx + myy <= min_chord * min_chord:
                ux = -cy / norm
                uy = cx / norm
            else:
                phi = 0.5 * math.atan2(2.0 * mxy, mxx - myy)
                ux = math.cos(phi)
                uy = math.sin(phi)
                if ux * (pts[j1, 0] - pts[j0, 0]) + uy * (pts[j1, 1] - pts[j0, 1]) < 0.0:
                    ux = -ux
                    uy = -uy
            low = np.inf
            high = -np.inf
            for j in range(j0, j1 + 1):
                t = (pts[j, 0] - ox) * ux + (pts[j, 1] - oy) * uy
                low = min(low, t)
                high = max(high, t)
            origin[s, 0] = ox
            origin[s, 1] = oy
            direction[s, 0] = ux
            direction[s, 1] = uy
            lo[s] = low
            hi[s] = high
        if two:  # the corner: where the two fitted lines meet, if they meet near the corner point
            u1x, u1y, u2x, u2y = direction[1, 0], direction[1, 1], direction[2, 0], direction[2, 1]
            den = u1x * u2y - u1y * u2x
            ok = abs(den) >= sin_min_angle
            wx = origin[2, 0] - origin[1, 0]
            wy = origin[2, 1] - origin[1, 1]
            a = (wx * u2y - wy * u2x) / (den if ok else 1.0)
            xx = origin[1, 0] + a * u1x
            xy = origin[1, 1] + a * u1y
            ok = ok and math.hypot(xx - pts[k, 0], xy - pts[k, 1]) <= max_shift
            if not ok:
                xx = pts[k, 0]
                xy = pts[k, 1]
            h1 = (xx - origin[1, 0]) * u1x + (xy - origin[1, 1]) * u1y
            l2 = (xx - origin[2, 0]) * u2x + (xy - origin[2, 1]) * u2y
            hi[1] = max(h1, lo[1])
            lo[2] = min(l2, hi[2])
        starts = np.empty((3, 2))
        ends = np.empty((3, 2))
        length = np.empty(3)
        for s in range(3):
            for d in range(2):
                starts[s, d] = origin[s, d] + lo[s] * direction[s, d]
                ends[s, d] = origin[s, d] + hi[s] * direction[s, d]
            length[s] = hi[s] - lo[s]
        margin = np.zeros((3, 2))
        half_gap = np.zeros((3, 2))
        if gap_correction and n >= 2:
            gaps = rel[1:] - rel[:-1]
            gaps = gaps[np.argsort(gaps, kind="mergesort")]  # numpy.sort's values
            db = gaps[(n - 1) // 2]
            for s in range(3):
                dist = abs(origin[s, 0] * direction[s, 1] - origin[s, 1] * direction[s, 0])
                r2s = starts[s, 0] * starts[s, 0] + starts[s, 1] * starts[s, 1]
                r2e = ends[s, 0] * ends[s, 0] + ends[s, 1] * ends[s, 1]
                half_gap[s, 0] = 0.5 * min(r2s * db / max(dist, 1e-3), max_end_gap)
                half_gap[s, 1] = 0.5 * min(r2e * db / max(dist, 1e-3), max_end_gap)
                margin[s, 0] = min(half_gap[s, 0], 0.5 * length[s])
                margin[s, 1] = min(half_gap[s, 1], 0.5 * length[s])
            if two:
                margin[1, 1] = 0.0  # the corner of a split is observed
                margin[2, 0] = 0.0
                half_gap[1, 1] = 0.0
                half_gap[2, 0] = 0.0
        # the kept points, compacted, with their part and chord coordinates
        corner = -1
        if two:
            corner = 0
            for j in range(k):
                if keep[j]:
                    corner += 1
        m = 0
        for j in range(n):
            if not keep[j]:
                continue
            points[i, m, 0] = pts[j, 0]
            points[i, m, 1] = pts[j, 1]
            valid[i, m] = True
            p = 1 if (two and m > corner) else 0
            part[i, m] = p
            proj[i, 0, m] = (pts[j, 0] - starts[0, 0]) * direction[0, 0] + (pts[j, 1] - starts[0, 1]) * direction[0, 1]
            proj[i, 1, m] = ((pts[j, 0] - starts[1 + p, 0]) * direction[1 + p, 0]
                             + (pts[j, 1] - starts[1 + p, 1]) * direction[1 + p, 1])
            order_out[i, m] = order[j]
            m += 1
        for s in range(3):
            src = s if two else 0  # one part: slots 1 and 2 repeat slot 0
            for d in range(2):
                chord_start[i, s, d] = starts[src, d]
                chord_end[i, s, d] = ends[src, d]
                chord_dir[i, s, d] = direction[src, d]
                end_margin[i, s, d] = margin[src, d]
                end_gap[i, s, d] = half_gap[src, d]
            chord_len[i, s] = length[src]
        two_sided[i] = two
        corner_out[i] = corner
        eigen_ratio[i] = ratio
        kept_count[i] = m
    return (points, valid, part, proj, chord_start, chord_end, chord_dir, chord_len, end_margin, end_gap, two_sided,
            corner_out, eigen_ratio, order_out, kept_count)


@njit
def scanned_batch_kernel(flat, offsets, bound, min_two, ratio_max, gap_correction, min_chord, sin_min_angle, max_shift,
                         max_end_gap, scan, shadows, window, margin, max_range, range_margin, continuation, rays,
                         offset):  # pragma: no cover - compiled
    """``prepare_kernel``'s arrays cut to the most points kept (``tracker.preparation._prepare_compiled``),
    whether each cluster's chord is a single point, and the shadow flags of the clusters' ends in
    ``scan`` (``shadows``: ``occluded_ends`` of the bearing ends with ``window``, ``margin``,
    ``max_range``, ``range_margin``; ``continuation``: ``continued_ends`` of the side ends with
    ``rays`` ray gaps and ``offset``), all False where a flag is off (the caller leaves it out).
    Returns ``(points, valid, part, proj, chord_start, chord_end, chord_dir, chord_len, end_margin,
    end_gap, two_sided, single, kept_count, occluded, continued)``."""
    (points, valid, part, proj, starts, ends, direction, length, margin_out, half_gap, two, _corner, _ratio, _order,
     kept_count) = prepare_kernel(flat, offsets, bound, min_two, ratio_max, gap_correction, min_chord, sin_min_angle,
                                  max_shift, max_end_gap)
    count = len(kept_count)
    m = kept_count.max()
    points = points[:, :m].copy()
    valid = valid[:, :m].copy()
    part = part[:, :m].copy()
    proj = proj[:, :, :m].copy()
    single = np.empty(count, dtype=np.bool_)
    for k in range(count):
        single[k] = length[k, 0] <= min_chord
    occluded = np.zeros((count, 2), dtype=np.bool_)
    continued = np.zeros((count, 2), dtype=np.bool_)
    if shadows and len(scan) and count:
        bearing_ends = np.empty((count, 2, 2))  # ClusterBatch.bearing_ends: first and last kept point
        for k in range(count):
            last = max(int(valid[k].sum()) - 1, 0)
            bearing_ends[k, 0] = points[k, 0]
            bearing_ends[k, 1] = points[k, last]
        scan_b, scan_r, scan_xy = bearing_sorted_scan(scan)  # one sort for both searches
        occluded = occluded_ends_sorted(bearing_ends, scan_b, scan_r, window, margin, max_range, range_margin)
        if continuation:
            side = np.empty((count, 2, 2))  # ClusterBatch.side_ends
            outward = np.empty((count, 2, 2))
            start = np.empty((count, 2))
            reach = np.empty((count, 2))
            for k in range(count):
                side[k, 0] = starts[k, 1]
                side[k, 1] = ends[k, 2]
                outward[k, 0, 0] = -direction[k, 1, 0]
                outward[k, 0, 1] = -direction[k, 1, 1]
                outward[k, 1] = direction[k, 2]
                start[k, 0] = half_gap[k, 1, 0]
                start[k, 1] = half_gap[k, 2, 1]
                reach[k, 0] = 2.0 * rays * start[k, 0]
                reach[k, 1] = 2.0 * rays * start[k, 1]
            continued = continued_ends_sorted(side, outward, start, reach, scan_b, scan_xy, offset)
    return (points, valid, part, proj, starts, ends, direction, length, margin_out, half_gap, two, single, kept_count,
            occluded, continued)
