"""Batched cluster preparation: ``prepare_clusters`` does for a list of clusters at once what
``tracker.measurement.prepare_cluster`` (the readable one-cluster reference) does for one, with numpy
over padded ``(K, N)`` arrays instead of a Python call per cluster. The tracker uses it every frame;
``tests/test_preparation.py`` checks it against the reference on random and real clusters.

Per cluster (all vectorised across clusters): centroid and scatter, points sorted by bearing about the
centroid's bearing, one/two-sided from the eigenvalue ratio, the corner split minimising the two line
fits' total-least-squares residuals (prefix sums over every split), even downsampling to
``max_cluster_points`` (the corner kept in both parts), the chords of slot 0 (all points) and slots 1, 2
(before / after the corner, the corner point in both), the corner as the intersection of the two
fitted lines when they meet at a useful angle near the corner point, the end-gap margins, and every
kept point's chord coordinates. Clusters with a non-finite point take the reference path (it drops and
counts them).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from tracker.config import MeasurementConfig
from tracker.measurement import (
    CORNER_MAX_SHIFT, CORNER_MIN_ANGLE, MAX_END_GAP, MIN_CHORD, Cluster, _lambda_min, prepare_cluster,
)


def _masked_scatter(pts: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Count, centroid ``(..., 2)`` and biased scatter ``sxx, syy, sxy`` of ``pts (..., N, 2)`` over the
    points where the mask ``w (..., N)`` is true."""
    wf = w.astype(float)
    count = wf.sum(axis=-1)
    safe = np.maximum(count, 1.0)
    c = np.einsum("...n,...nd->...d", wf, pts) / safe[..., None]
    d = (pts - c[..., None, :]) * wf[..., None]
    sxx = np.einsum("...n,...n->...", d[..., 0], d[..., 0]) / safe
    syy = np.einsum("...n,...n->...", d[..., 1], d[..., 1]) / safe
    sxy = np.einsum("...n,...n->...", d[..., 0], d[..., 1]) / safe
    return count, c, sxx, syy, sxy


def _corner_indices(pts: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Corner split ``k`` in ``1..n-2`` per row of bearing-sorted ``pts (K, N, 2)`` with ``n (K,)`` valid
    points each (``n >= 3``): ``tracker.measurement.corner_index`` for all rows at once."""
    count, width = pts.shape[0], pts.shape[1]
    valid = np.arange(width)[None, :] < n[:, None]
    _, centre, *_ = _masked_scatter(pts, valid)
    p = (pts - centre[:, None, :]) * valid[..., None]
    x, y = p[..., 0], p[..., 1]
    zero = np.zeros((count, 1))
    cs = [np.concatenate([zero, np.cumsum(v, axis=1)], axis=1) for v in (valid.astype(float), x, y, x * x, y * y, x * y)]
    k = np.arange(1, max(width - 1, 2))[None, :]  # candidate splits (K, N-2)
    rows = np.arange(count)[:, None]

    def residual(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:  # points lo..hi inclusive
        cnt, sx, sy, sxx, syy, sxy = (c[rows, hi + 1] - c[rows, lo] for c in cs)
        cnt = np.maximum(cnt, 1.0)
        return np.maximum(_lambda_min(sxx - sx * sx / cnt, syy - sy * sy / cnt, sxy - sx * sy / cnt), 0.0)

    kk = np.broadcast_to(k, (count, k.shape[1]))
    last = np.broadcast_to((n - 1)[:, None], kk.shape)
    hi = np.minimum(kk, last)
    cost = residual(np.zeros_like(kk), hi) + residual(hi, last)
    cost = np.where(kk <= (n - 2)[:, None], cost, np.inf)
    return k[0, np.argmin(cost, axis=1)]


def _even_mask(mask: np.ndarray, rows: np.ndarray, lo: np.ndarray, hi: np.ndarray, count: np.ndarray) -> None:
    """Set ``mask[row, i]`` for ``count`` indices evenly spread over ``lo..hi`` (both ends kept) per row,
    as ``tracker.measurement._even`` (duplicates collapse)."""
    if not len(rows):
        return
    count = np.maximum(count, 2)
    j = np.arange(int(count.max()))[None, :]
    step = (hi - lo) / (count - 1)  # as numpy.linspace: j * step + start, the last one exactly the stop
    pos = np.where(j == (count - 1)[:, None], hi[:, None], j * step[:, None] + lo[:, None])
    idx = np.round(pos).astype(int)
    take = j < count[:, None]
    r = np.broadcast_to(rows[:, None], idx.shape)
    mask[r[take], idx[take]] = True


def prepare_clusters(
    clusters: Sequence[np.ndarray], config: MeasurementConfig | None = None,
    velocities: Sequence[np.ndarray | None] | None = None,
) -> list[Cluster]:
    """``[prepare_cluster(points, config, velocity) for ...]`` for clusters ``(n_k, 2)`` in E (m),
    vectorised across clusters (module docstring). ``velocities`` per cluster or ``None``."""
    config = config if config is not None else MeasurementConfig()
    arrays = [np.asarray(c, dtype=float) for c in clusters]
    velocities = list(velocities) if velocities is not None else [None] * len(arrays)
    if len(velocities) != len(arrays):
        raise ValueError(f"prepare_clusters: {len(arrays)} clusters but {len(velocities)} velocities")
    out: list[Cluster | None] = [None] * len(arrays)
    fast = []
    for i, a in enumerate(arrays):
        if a.ndim != 2 or a.shape[1] != 2 or len(a) == 0 or not np.isfinite(a).all():
            out[i] = prepare_cluster(a, config, velocities[i])  # raises, or drops and counts non-finite points
        else:
            fast.append(i)
    if fast:
        for i, c in zip(fast, _prepare_finite([arrays[i] for i in fast], [velocities[i] for i in fast], config)):
            out[i] = c
    return out  # type: ignore[return-value]


def _prepare_finite(arrays: list[np.ndarray], velocities: list[np.ndarray | None], config: MeasurementConfig) -> list[Cluster]:
    n = np.array([len(a) for a in arrays])
    count, width = len(arrays), int(n.max())
    rows = np.arange(count)
    valid = np.arange(width)[None, :] < n[:, None]
    raw = np.zeros((count, width, 2))
    raw[valid] = np.concatenate(arrays)
    vel_out: list[np.ndarray | None] = []
    for v in velocities:
        if v is None:
            vel_out.append(None)
            continue
        v = np.asarray(v, dtype=float).reshape(-1)
        if v.shape != (2,) or not np.isfinite(v).all():
            raise ValueError(f"cluster velocity must be a finite (vx, vy) in m/s; got {v!r}")
        vel_out.append(v)
    # centroid, scatter, bearing order
    _, centroid, sxx, syy, sxy = _masked_scatter(raw, valid)
    cx, cy = centroid[:, 0], centroid[:, 1]
    ref = np.where(np.hypot(cx, cy) > 1e-9, np.arctan2(cy, cx), 0.0)
    rel = np.arctan2(raw[..., 1], raw[..., 0]) - ref[:, None]
    rel -= 2.0 * np.pi * np.round(rel / (2.0 * np.pi))
    rel = np.where(valid, rel, np.inf)
    order = np.argsort(rel, axis=1, kind="stable")
    pts = np.take_along_axis(raw, order[..., None], axis=1)
    rel = np.take_along_axis(rel, order, axis=1)
    # one or two sides
    root = np.sqrt(0.25 * (sxx - syy) ** 2 + sxy**2)
    lam_min, lam_max = 0.5 * (sxx + syy) - root, 0.5 * (sxx + syy) + root
    ratio = np.where(lam_min > 1e-15 * np.maximum(lam_max, 1e-300), lam_max / np.where(lam_min > 0, lam_min, 1.0), np.inf)
    ratio = np.where(n >= 2, ratio, np.inf)
    two = (n >= config.min_points_two_sided) & (ratio < config.two_side_eigen_ratio)
    k = np.full(count, -1)
    if two.any():
        k[two] = _corner_indices(pts[two], n[two])
    # downsampling: the kept points of the sorted cluster (the corner in both parts)
    bound = config.max_cluster_points
    keep = valid.copy()
    big = n > bound
    big_two, big_one = np.flatnonzero(big & two), np.flatnonzero(big & ~two)
    if len(big_two) or len(big_one):
        keep[big] = False
        kt, nt = k[big_two], n[big_two]
        m0 = np.minimum(np.maximum(2, np.round(bound * (kt + 1) / (nt + 1)).astype(int)), bound - 1)
        _even_mask(keep, big_two, np.zeros_like(kt), kt, m0)
        _even_mask(keep, big_two, kt, nt - 1, bound + 1 - m0)
        _even_mask(keep, big_one, np.zeros_like(big_one), n[big_one] - 1, np.full(len(big_one), bound))
    # chords from all the points: slot 0 whole, slot 1 = 0..k, slot 2 = k..n-1 (two-sided)
    j = np.arange(width)[None, :]
    members = np.stack([valid, valid & ((j <= k[:, None]) | ~two[:, None]), valid & ((j >= k[:, None]) | ~two[:, None])], axis=1)
    cnt, origin, mxx, myy, mxy = _masked_scatter(pts[:, None], members)  # (K, 3)
    first = np.stack([np.zeros(count, int), np.zeros(count, int), np.where(two, k, 0)], axis=1)
    last = np.stack([n - 1, np.where(two, k, n - 1), n - 1], axis=1)
    p_first = pts[rows[:, None], first]  # (K, 3, 2)
    p_last = pts[rows[:, None], last]
    norm = np.maximum(np.hypot(cx, cy), 1e-12)
    fallback = np.stack([-cy / norm, cx / norm], axis=1)  # the line-of-sight normal
    phi = 0.5 * np.arctan2(2.0 * mxy, mxx - myy)
    u = np.stack([np.cos(phi), np.sin(phi)], axis=-1)
    u = np.where((np.einsum("ksd,ksd->ks", u, p_last - p_first) >= 0.0)[..., None], u, -u)
    flat = (cnt < 2) | (mxx + myy <= MIN_CHORD**2)
    direction = np.where(flat[..., None], fallback[:, None, :], u)
    along = np.einsum("ksnd,ksd->ksn", pts[:, None] - origin[:, :, None, :], direction)
    lo = np.where(members, along, np.inf).min(axis=2)
    hi = np.where(members, along, -np.inf).max(axis=2)
    if two.any():  # the corner: where the two fitted lines meet, if they meet near the corner point
        t = np.flatnonzero(two)
        o1, u1, o2, u2 = origin[t, 1], direction[t, 1], origin[t, 2], direction[t, 2]
        den = u1[:, 0] * u2[:, 1] - u1[:, 1] * u2[:, 0]
        ok = np.abs(den) >= np.sin(CORNER_MIN_ANGLE)
        w = o2 - o1
        a = (w[:, 0] * u2[:, 1] - w[:, 1] * u2[:, 0]) / np.where(ok, den, 1.0)
        x = o1 + a[:, None] * u1
        corner_pt = pts[t, k[t]]
        ok &= np.hypot(*(x - corner_pt).T) <= CORNER_MAX_SHIFT
        x = np.where(ok[:, None], x, corner_pt)
        h1 = np.einsum("kd,kd->k", x - o1, u1)
        l2 = np.einsum("kd,kd->k", x - o2, u2)
        hi[t, 1] = np.maximum(h1, lo[t, 1])
        lo[t, 2] = np.minimum(l2, hi[t, 2])
    starts = origin + lo[..., None] * direction
    ends = origin + hi[..., None] * direction
    length = hi - lo
    margin = np.zeros((count, 3, 2))
    if config.end_gap_correction:
        db = np.zeros(count)  # the median bearing step (the upper one of an even count, as np.partition)
        if width > 1:
            gaps = np.sort(np.where(j[:, 1:] < n[:, None], np.diff(np.where(valid, rel, 0.0), axis=1), np.inf), axis=1)
            db = np.where(n >= 2, gaps[rows, np.maximum(n - 1, 1) // 2], 0.0)  # a lone point has no gap
        dist = np.abs(origin[..., 0] * direction[..., 1] - origin[..., 1] * direction[..., 0])
        r2 = np.stack([(starts * starts).sum(axis=-1), (ends * ends).sum(axis=-1)], axis=-1)
        gap = r2 * db[:, None, None] / np.maximum(dist, 1e-3)[..., None]
        margin = 0.5 * np.minimum(np.minimum(gap, MAX_END_GAP), length[..., None])
        margin = np.where((n >= 2)[:, None, None], margin, 0.0)
        margin[two, 1, 1] = 0.0  # the corner of a split is observed
        margin[two, 2, 0] = 0.0
    # the kept points, compacted, with their part and chord coordinates
    kept_count = keep.sum(axis=1)
    pick = np.argsort(~keep, axis=1, kind="stable")[:, : int(kept_count.max())]  # kept indices first, in order
    corner = np.where(two, (keep & (j < k[:, None])).sum(axis=1), -1)  # index of the corner among the kept
    kpts = pts[rows[:, None], pick]
    part = (two[:, None] & (np.arange(pick.shape[1])[None, :] > corner[:, None])).astype(np.intp)
    slot = 1 + part
    proj0 = np.einsum("kmd,kd->km", kpts - starts[:, None, 0], direction[:, 0])
    proj1 = np.einsum("kmd,kmd->km", kpts - starts[rows[:, None], slot], direction[rows[:, None], slot])
    src = np.take_along_axis(order, pick, axis=1)
    result = []
    for i in range(count):  # the Cluster records (no arithmetic here)
        m = int(kept_count[i])
        st, en, di, ln, mg = starts[i], ends[i], direction[i], length[i], margin[i]
        if not two[i]:  # one part: slots 1 and 2 repeat slot 0
            st, en, di, ln, mg = (np.repeat(a[:1], 3, axis=0) for a in (st, en, di, ln, mg))
        result.append(Cluster(
            points=kpts[i, :m], part=part[i, :m], proj=np.stack([proj0[i, :m], proj1[i, :m]]),
            chord_start=st, chord_end=en, chord_dir=di, chord_len=ln, two_sided=bool(two[i]), corner=int(corner[i]),
            eigen_ratio=float(ratio[i]), end_margin=mg, velocity=vel_out[i], raw_count=int(n[i]), dropped=0,
            order=src[i, :m],
        ))
    return result
