"""The clustering's steps (``tracker.clustering``) in numpy: points in rectangles, the distance partition,
the greedy radar association, the shadowed and continued ends of clusters, and the cuts across the road."""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree


def points_in_rectangles(points: np.ndarray, centres: np.ndarray, yaw: np.ndarray, length: np.ndarray,
                         width: np.ndarray, margin: float = 1.0) -> np.ndarray:
    """Index of the rectangle (widened by ``margin`` on every side) containing each point, -1 for none;
    a point inside several goes to the one whose normalised score ``max(|u|, |v|)`` is smallest (the
    first on a tie)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    ctr = np.asarray(centres, dtype=float).reshape(-1, 2)
    if len(pts) == 0 or len(ctr) == 0:
        return np.full(len(pts), -1, dtype=int)
    c, s = np.cos(yaw), np.sin(yaw)
    d = pts[:, None, :] - ctr[None, :, :]  # (N, M, 2)
    u = (d[..., 0] * c + d[..., 1] * s) / (0.5 * np.asarray(length) + margin)
    v = (-d[..., 0] * s + d[..., 1] * c) / (0.5 * np.asarray(width) + margin)
    score = np.maximum(np.abs(u), np.abs(v))  # <= 1 inside the widened rectangle
    best = np.argmin(score, axis=1)
    inside = score[np.arange(len(pts)), best] <= 1.0
    return np.where(inside, best, -1)


def distance_partition(points: np.ndarray, threshold: float) -> np.ndarray:
    """Connected components of the whole graph joining points at most ``threshold`` apart (scipy),
    labelled in order of each component's first point."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    n = len(pts)
    pairs = cKDTree(pts).query_pairs(threshold, output_type="ndarray")
    labels = connected_components(coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n)),
                                  directed=False)[1]
    return first_appearance(labels)


def first_appearance(labels: np.ndarray) -> np.ndarray:
    """``labels`` renumbered 0, 1, ... in order of each value's first occurrence."""
    _, first = np.unique(labels, return_index=True)
    rank = np.empty(len(first), dtype=int)
    rank[np.argsort(first)] = np.arange(len(first))
    return rank[labels]


def associate_radar(cluster_points: list[np.ndarray], radar_xy: np.ndarray, gate: float = 3.0) -> np.ndarray:
    """Greedy nearest-neighbour association: the distance of a detection to a cluster is that to its
    nearest point; pairs within ``gate`` are taken in increasing distance (ties in row-major order),
    each cluster and each detection at most once. Per cluster its detection, or -1."""
    radar = np.asarray(radar_xy, dtype=float).reshape(-1, 2)
    out = np.full(len(cluster_points), -1, dtype=int)
    if len(radar) == 0 or len(cluster_points) == 0:
        return out
    dist = np.full((len(cluster_points), len(radar)), np.inf)
    for k, pts in enumerate(cluster_points):
        if len(pts):
            dist[k] = np.linalg.norm(np.asarray(pts)[:, None, :] - radar[None, :, :], axis=2).min(axis=0)
    rows, cols = np.unravel_index(np.argsort(dist, axis=None, kind="stable"), dist.shape)
    used = np.zeros(len(radar), dtype=bool)
    for r, c in zip(rows.tolist(), cols.tolist()):
        if dist[r, c] > gate:
            break
        if out[r] < 0 and not used[c]:
            out[r] = c
            used[c] = True
    return out


def occluded_ends(ends: np.ndarray, scan: np.ndarray, window: float, margin: float, max_range: float = np.inf,
                  range_margin: float = 0.0) -> np.ndarray:
    """``(K, 2)``: a return of ``scan`` lies within ``window`` rad beyond each end in bearing (below the
    first end's bearing, above the last's) and more than ``margin`` m nearer than the end, or the end
    lies within ``range_margin`` of ``max_range``."""
    ends = np.asarray(ends, dtype=float).reshape(-1, 2, 2)
    if len(ends) == 0 or len(scan) == 0:
        return np.zeros((len(ends), 2), dtype=bool)
    bearing = np.arctan2(ends[..., 1], ends[..., 0]).ravel()  # (2K,) first and last end of each cluster
    reach = np.hypot(ends[..., 0], ends[..., 1]).ravel()
    scan_b, scan_r = np.arctan2(scan[:, 1], scan[:, 0]), np.hypot(scan[:, 0], scan[:, 1])
    beyond = np.tile([-1.0, 1.0], len(ends))  # the first end looks below its bearing, the last above
    d = scan_b[None, :] - bearing[:, None]
    d = beyond[:, None] * (d - 2.0 * np.pi * np.round(d / (2.0 * np.pi)))  # > 0: beyond the end
    nearer = (d > 0.0) & (d <= window) & (scan_r[None, :] < reach[:, None] - margin)
    return (nearer.any(axis=1) | (reach >= max_range - range_margin)).reshape(len(ends), 2)


def continued_ends(ends: np.ndarray, outward: np.ndarray, half_gap: np.ndarray, scan: np.ndarray, rays: float,
                   offset: float) -> np.ndarray:
    """``(K, 2)``: a return of ``scan`` lies beyond each end along ``outward``, more than ``half_gap``
    and at most ``2 rays half_gap`` along it, and at most ``offset`` m from the line."""
    ends = np.asarray(ends, dtype=float).reshape(-1, 2, 2)
    outward = np.asarray(outward, dtype=float).reshape(-1, 2, 2)
    half_gap = np.asarray(half_gap, dtype=float).reshape(-1, 2)
    if len(ends) == 0 or len(scan) == 0:
        return np.zeros((len(ends), 2), dtype=bool)
    reach = 2.0 * float(rays) * half_gap
    d = scan[None, None, :, :] - ends[:, :, None, :]  # (K, 2, R, 2)
    along = np.einsum("kerd,ked->ker", d, outward)
    across = np.abs(d[..., 0] * outward[..., None, 1] - d[..., 1] * outward[..., None, 0])
    return ((along > half_gap[..., None]) & (along <= reach[..., None]) & (across <= offset)).any(axis=2)


def split_across(n: np.ndarray, group: np.ndarray, width: float, gap: float, max_cuts: int = 8) -> np.ndarray:
    """Part index of each point: the points of each ``group`` whose offsets ``n`` span more than
    ``width`` are cut at their largest gap between consecutive offsets (the first such gap), if at least
    ``gap``; parts still wider are cut again, up to ``max_cuts`` rounds. Parts are numbered by group in
    sorted order, then by ``n``."""
    n = np.asarray(n, dtype=float).reshape(-1)
    part = np.unique(np.asarray(group).reshape(-1), return_inverse=True)[1].reshape(-1)
    if len(n) == 0:
        return part
    order = np.lexsort((n, part))  # by part, then by n
    ns, ps = n[order], part[order]
    with np.errstate(invalid="ignore"):  # inf - inf: a NaN gap, which is no part's largest
        for _ in range(max_cuts):
            first = np.ones(len(ns), dtype=bool)
            first[1:] = ps[1:] != ps[:-1]
            starts = np.flatnonzero(first)
            ends = np.append(starts[1:], len(ns)) - 1
            wide = (ns[ends] - ns[starts]) > width  # per part
            step = np.empty(len(ns))
            step[0] = -np.inf
            step[1:] = ns[1:] - ns[:-1]
            step[first] = -np.inf  # no gap across parts
            largest = np.maximum.reduceat(step, starts)
            index = np.cumsum(first) - 1
            cut = wide[index] & (step == largest[index]) & (step >= gap)
            if not cut.any():
                break
            hits = np.flatnonzero(cut)
            _, keep = np.unique(index[hits], return_index=True)  # one cut per part: the first at its largest gap
            cut[:] = False
            cut[hits[keep]] = True
            ps = np.cumsum(first | cut) - 1
    out = np.empty(len(n), dtype=int)
    out[order] = ps
    return out


def ray_partition(points: np.ndarray, threshold: float, grazing_angle: float, bearing_step: float,
                  max_gap: float) -> np.ndarray:
    """The distance partition's graph plus an edge from each point to its successor counter-clockwise
    (the point at the least positive bearing difference, around the circle), when that difference is at
    most ``1.5 bearing_step`` and the two lie at most ``min(max_gap, min(r) dtheta / sin(grazing_angle))``
    apart; its components in order of first point."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    n = len(pts)
    bearing = np.arctan2(pts[:, 1], pts[:, 0])
    rng = np.hypot(pts[:, 0], pts[:, 1])
    edges = cKDTree(pts).query_pairs(threshold, output_type="ndarray").reshape(-1, 2)
    if n > 1:
        ahead = (bearing[None, :] - bearing[:, None]) % (2.0 * np.pi)  # (i, j): j counter-clockwise of i
        np.fill_diagonal(ahead, np.inf)
        nxt = np.argmin(ahead, axis=1)
        step = ahead[np.arange(n), nxt]
        reach = np.minimum(max_gap, np.minimum(rng, rng[nxt]) * step / np.sin(grazing_angle))
        ok = (step <= 1.5 * bearing_step) & (np.linalg.norm(pts - pts[nxt], axis=1) <= reach)
        edges = np.vstack([edges, np.column_stack([np.arange(n), nxt])[ok]])
    labels = connected_components(coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n)),
                                  directed=False)[1]
    return first_appearance(labels)
