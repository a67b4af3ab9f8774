"""Cluster preparation (``tracker.measurement.prepare_cluster``, ``tracker.preparation``) for one
cluster in plain numpy: drop non-finite points, sort by bearing about the centroid's bearing, decide
one/two-sided from the eigenvalue ratio of the points' scatter, find the corner split minimising the
two line fits' total-least-squares residuals, downsample evenly (the corner in both parts), fit the
chords of slot 0 (all points) and slots 1, 2 (before / after the corner), put the corner where the two
fitted lines meet, add the end-gap margins and give every kept point its chord coordinates
(``tracker.measurement``'s module docstring)."""

from __future__ import annotations

import math

import numpy as np

from tracker.config import MeasurementConfig
from tracker.measurement import (CORNER_MAX_SHIFT, CORNER_MIN_ANGLE, MAX_END_GAP, MIN_CHORD, SPLIT_MAX_SPACING,
                                 SPLIT_MIN_SIN, Cluster, finite_cluster_points)


def _lambda_min(sxx: np.ndarray, syy: np.ndarray, sxy: np.ndarray) -> np.ndarray:
    """Smallest eigenvalue of symmetric 2x2 matrices ``[[sxx, sxy], [sxy, syy]]``."""
    return 0.5 * (sxx + syy) - np.sqrt(0.25 * (sxx - syy) ** 2 + sxy**2)


def corner_index(points: np.ndarray) -> int:
    """Corner index of bearing-sorted points ``(N, 2)``, ``N >= 3``: the split ``k`` in ``1..N-2``
    minimising the summed total-least-squares residuals of lines fitted to ``points[:k+1]`` and
    ``points[k:]`` (the corner point in both). All splits at once from prefix sums: O(N)."""
    p = np.asarray(points, dtype=float)
    n = len(p)
    if n < 3:
        raise ValueError(f"corner_index needs at least 3 points; got {n}")
    p = p - p.mean(axis=0)
    x, y = p[:, 0], p[:, 1]
    cs = [np.concatenate([[0.0], np.cumsum(v)]) for v in (np.ones(n), x, y, x * x, y * y, x * y)]
    k = np.arange(1, n - 1)

    def residual(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:  # points lo..hi inclusive
        cnt, sx, sy, sxx, syy, sxy = (c[hi + 1] - c[lo] for c in cs)
        return np.maximum(_lambda_min(sxx - sx * sx / cnt, syy - sy * sy / cnt, sxy - sx * sy / cnt), 0.0)

    cost = residual(np.zeros_like(k), k) + residual(k, np.full_like(k, n - 1))
    return int(k[np.argmin(cost)])


def _even(lo: int, hi: int, count: int) -> np.ndarray:
    """``count`` indices evenly spread over ``lo..hi`` inclusive (both ends kept)."""
    return np.unique(np.round(np.linspace(lo, hi, max(count, 2))).astype(int))


def _scatter(pts: np.ndarray) -> tuple[np.ndarray, float, float, float]:
    """Centroid and the (biased) covariance entries ``sxx, syy, sxy`` of ``pts (K, 2)``."""
    c = pts.mean(axis=0)
    d = pts - c
    return c, float(d[:, 0] @ d[:, 0]) / len(pts), float(d[:, 1] @ d[:, 1]) / len(pts), float(d[:, 0] @ d[:, 1]) / len(pts)


def _line_fit(pts: np.ndarray, fallback: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # noqa: D401
    """Total-least-squares line through ``pts (K, 2)``: a point on it (the centroid) and its unit
    direction (the major axis of the scatter, angle ``atan2(2 sxy, sxx - syy) / 2``), oriented from the
    first point towards the last; ``fallback`` direction if the points have no extent."""
    c, sxx, syy, sxy = _scatter(pts)
    if len(pts) < 2 or sxx + syy <= MIN_CHORD**2:
        return c, fallback
    phi = 0.5 * np.arctan2(2.0 * sxy, sxx - syy)
    u = np.array([np.cos(phi), np.sin(phi)])
    return c, (u if float(u @ (pts[-1] - pts[0])) >= 0.0 else -u)


def _intersect(o1: np.ndarray, u1: np.ndarray, o2: np.ndarray, u2: np.ndarray) -> np.ndarray | None:
    """Intersection of the lines ``o1 + a u1`` and ``o2 + b u2``; ``None`` if they meet at less than
    ``CORNER_MIN_ANGLE``."""
    den = u1[0] * u2[1] - u1[1] * u2[0]
    if abs(den) < np.sin(CORNER_MIN_ANGLE):
        return None
    w = o2 - o1
    a = (w[0] * u2[1] - w[1] * u2[0]) / den
    return o1 + a * u1


def prepare_cluster(
    points: np.ndarray, config: MeasurementConfig | None = None, velocity: np.ndarray | None = None
) -> Cluster:
    """Prepare lidar ``points (N, 2)`` in E (m) for the rectangle model: drop non-finite points
    (counted in ``dropped``), sort by bearing, decide one/two-sided from the eigenvalue ratio, find the
    corner, downsample to ``config.max_cluster_points`` and compute each point's chord coordinates.
    ``velocity`` is an associated radar detection's absolute velocity ``(vx, vy)`` in E (m/s)."""
    config = config if config is not None else MeasurementConfig()
    pts, index, dropped, velocity = finite_cluster_points(points, velocity)
    centroid, sxx, syy, sxy = _scatter(pts)
    cx, cy = float(centroid[0]), float(centroid[1])
    ref = math.atan2(cy, cx) if math.hypot(cx, cy) > 1e-9 else 0.0
    rel = np.arctan2(pts[:, 1], pts[:, 0]) - ref
    rel -= 2.0 * np.pi * np.round(rel / (2.0 * np.pi))
    order = np.argsort(rel, kind="stable")
    pts, index, rel = pts[order], index[order], rel[order]
    n = len(pts)
    ratio = math.inf
    if n >= 2:
        root = math.sqrt(0.25 * (sxx - syy) ** 2 + sxy**2)
        lam_min, lam_max = 0.5 * (sxx + syy) - root, 0.5 * (sxx + syy) + root
        ratio = lam_max / lam_min if lam_min > 1e-15 * max(lam_max, 1e-300) else math.inf
    db = 0.0  # the median bearing step between neighbouring points (rad)
    if n >= 2:
        gaps = np.diff(rel)
        db = float(np.partition(gaps, len(gaps) // 2)[len(gaps) // 2])
    two = n >= config.min_points_two_sided and lam_min > config.two_side_min_residual**2
    if two and ratio >= config.two_side_eigen_ratio:  # a line by the ratio: a corner if no line fits, split at one
        line = math.inf if config.two_side_line_residual is None else config.two_side_line_residual
        two = lam_min > line**2
        if two:
            k = corner_index(pts)
            (_, u), (_, v) = _line_fit(pts[: k + 1], np.array([1.0, 0.0])), _line_fit(pts[k:], np.array([1.0, 0.0]))
            two = (abs(u[0] * v[1] - u[1] * v[0]) >= SPLIT_MIN_SIN
                   and float(np.hypot(*pts[k])) * db <= SPLIT_MAX_SPACING)
    keep = np.arange(n)
    corner = -1
    if two:
        k = corner_index(pts)
        if n > config.max_cluster_points:
            bound = config.max_cluster_points  # the corner is shared: m0 + m1 - 1 = bound points
            m0 = min(max(2, int(round(bound * (k + 1) / (n + 1)))), bound - 1)
            m1 = bound + 1 - m0
            keep = np.unique(np.concatenate([_even(0, k, m0), _even(k, n - 1, m1)]))
        corner = int(np.searchsorted(keep, k))
    elif n > config.max_cluster_points:
        keep = _even(0, n - 1, config.max_cluster_points)
    # lines and extents from all the points, before downsampling
    norm = max(math.hypot(cx, cy), 1e-12)
    fallback = np.array([-cy / norm, cx / norm])  # no extent: the line-of-sight normal
    corner_full = int(keep[corner]) if two else -1
    # slot 0: the whole cluster; slots 1, 2: before / after the corner (the corner point in both fits)
    members = [pts, pts[: corner_full + 1], pts[corner_full:]] if two else [pts]
    fits = [_line_fit(q, fallback) for q in members]
    lo, hi = np.zeros(len(fits)), np.zeros(len(fits))
    for i, (q, (o, u)) in enumerate(zip(members, fits)):
        a = (q - o) @ u
        lo[i], hi[i] = a.min(), a.max()
    if not two:  # one part: slots 1 and 2 repeat slot 0
        fits, lo, hi = fits * 3, np.repeat(lo, 3), np.repeat(hi, 3)
    if two:  # the corner: where the two fitted lines meet, if they meet near the corner point
        x = _intersect(fits[1][0], fits[1][1], fits[2][0], fits[2][1])
        if x is None or np.hypot(*(x - pts[corner_full])) > CORNER_MAX_SHIFT:
            x = pts[corner_full]
        hi[1] = (x - fits[1][0]) @ fits[1][1]
        lo[2] = (x - fits[2][0]) @ fits[2][1]
        hi[1], lo[2] = max(hi[1], lo[1]), min(lo[2], hi[2])
    origin = np.stack([o for o, _ in fits])
    direction = np.stack([u for _, u in fits])
    starts = origin + lo[:, None] * direction
    ends = origin + hi[:, None] * direction
    length = hi - lo
    margin, half_gap = np.zeros((3, 2)), np.zeros((3, 2))
    if n >= 2:
        # half the gap between rays at each free end: along a line at distance d from the sensor a
        # bearing step db moves the hit point by r^2 db / d (r: range of the end point)
        dist = np.abs(origin[:, 0] * direction[:, 1] - origin[:, 1] * direction[:, 0])  # (3,) line to sensor
        r2 = np.column_stack([(starts * starts).sum(axis=1), (ends * ends).sum(axis=1)])
        gap = r2 * db / np.maximum(dist, 1e-3)[:, None]
        half_gap = 0.5 * np.minimum(gap, MAX_END_GAP)
        margin = np.minimum(half_gap, 0.5 * length[:, None])
        if two:
            margin[1, 1] = margin[2, 0] = 0.0  # the corner of a split is observed
            half_gap[1, 1] = half_gap[2, 0] = 0.0
    pts, index = pts[keep], index[keep]
    m = len(pts)
    part = np.zeros(m, dtype=np.intp)
    if two:
        part[corner + 1:] = 1
    proj = np.stack([
        (pts - starts[0]) @ direction[0],
        np.einsum("md,md->m", pts - starts[1 + part], direction[1 + part]),
    ])
    return Cluster(
        points=pts, part=part, proj=proj, chord_start=starts, chord_end=ends, chord_dir=direction,
        chord_len=length, two_sided=bool(two), corner=corner, eigen_ratio=ratio, end_margin=margin, velocity=velocity,
        raw_count=n, dropped=dropped, order=index, end_gap=half_gap,
    )

