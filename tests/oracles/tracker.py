"""The tracker's own steps (``tracker.tracker``) in numpy: the grouping of a frame's points into clusters
(``Tracker._cluster``), the update's pre-gating, the overlap groups of track rectangles and the test of
``Tracker._drop_inside_updated``."""

from __future__ import annotations

from collections import Counter

import numpy as np
from scipy.sparse.csgraph import connected_components

from oracles.clustering import associate_radar, distance_partition, points_in_rectangles, ray_partition, split_across
from tracker.clustering import fragment_owners
from tracker.config import ClusteringConfig
from tracker.frame import RadarDetections
from tracker.measurement import Rectangles


def candidate_pairs(center: np.ndarray, reach: np.ndarray, points: np.ndarray, offsets: np.ndarray, p_d: np.ndarray,
                    owned: np.ndarray, group: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The (component, cluster) pairs in row-major order: the rectangle centre within ``reach`` of the
    cluster's centroid, ``p_d > 0``, and the cluster free (``owned < 0``) or the component's group's."""
    centroid = np.add.reduceat(points, offsets[:-1]) / np.diff(offsets)[:, None]
    dist = np.linalg.norm(center[:, None, :] - centroid[None, :, :], axis=2)
    allowed = (owned[None, :] < 0) | (owned[None, :] == group[:, None])
    return np.nonzero((dist <= reach[:, None]) & (p_d[:, None] > 0.0) & allowed)


def duplicate_groups(rect: Rectangles, depth=0.0) -> np.ndarray:
    """Group per rectangle: two rectangles that overlap by more than the smaller of their ``depth`` (m;
    per rectangle, or one for all) on each of the two rectangles' own edge directions are one group,
    groups numbered in order of their first rectangle."""
    count = len(rect.center)
    depth = np.broadcast_to(np.asarray(depth, dtype=float), (count,))
    corners = rect.corners()  # (T, 4, 2)
    axes = np.stack([np.cos(rect.psi), np.sin(rect.psi), -np.sin(rect.psi), np.cos(rect.psi)], -1).reshape(-1, 2, 2)
    overlap = np.eye(count, dtype=bool)
    for i in range(count):
        for j in range(i + 1, count):
            separated = False
            tol = min(depth[i], depth[j])
            for axis in np.concatenate([axes[i], axes[j]]):
                a, b = corners[i] @ axis, corners[j] @ axis
                separated |= a.max() - b.min() < tol or b.max() - a.min() < tol
            overlap[i, j] = overlap[j, i] = not separated
    return first_of_components(overlap)


def first_of_components(adjacency: np.ndarray) -> np.ndarray:
    """Connected components of a boolean adjacency, numbered in order of each one's first node."""
    labels = connected_components(adjacency, directed=False)[1]
    _, first = np.unique(labels, return_index=True)
    rank = np.empty(len(first), dtype=int)
    rank[np.argsort(first)] = np.arange(len(first))
    return rank[labels]


def adopt_strays(component: np.ndarray, owner: np.ndarray) -> np.ndarray:
    """Points owned by no group (-1) join the group owning most points of their connected component (the
    first such group on a tie; -1 when none owns any)."""
    owned = owner >= 0
    if not owned.any() or owned.all():
        return owner
    votes = np.zeros((int(component.max()) + 1, int(owner.max()) + 1), dtype=int)
    np.add.at(votes, (component[owned], owner[owned]), 1)
    majority = np.where(votes.any(axis=1), votes.argmax(axis=1), -1)
    out = owner.copy()
    out[~owned] = majority[component[~owned]]
    return out


def split_clusters(key: np.ndarray, owner: np.ndarray, inside: np.ndarray, n: np.ndarray, width: float,
                   gap: float) -> tuple[np.ndarray, np.ndarray, int]:
    """The clusters (equal ``key``) whose lateral offsets ``n`` span more than ``width`` cut by
    ``split_across``; the parts of a cut cluster take the keys ``max(key) + 1 + part``, and of an owned
    cluster only the part(s) with most points ``inside`` (plus 1e-6 per point) stay owned. Returns the
    keys, the owners and the number of parts added."""
    with np.errstate(invalid="ignore"):  # inf - inf: a NaN span, never wide
        span = {k: np.max(n[key == k]) - np.min(n[key == k]) for k in np.unique(key).tolist()}
    candidate = np.array([span[k] > width for k in key.tolist()], dtype=bool)
    if not candidate.any():
        return key, owner, 0
    cand = np.flatnonzero(candidate)
    part = split_across(n[cand], key[cand], width, gap)
    cut = np.array([len(np.unique(part[key[cand] == k])) > 1 for k in key[cand].tolist()], dtype=bool)
    if not cut.any():
        return key, owner, 0
    added = len(np.unique(part[cut])) - len(np.unique(key[cand][cut]))
    new_key, new_owner = key.copy(), owner.copy()
    new_key[cand[cut]] = key.max() + 1 + part[cut]
    for k in np.unique(key[cand][cut]).tolist():  # the cut clusters
        rows = cand[key[cand] == k]
        if owner[rows[0]] < 0:
            continue
        parts = part[key[cand] == k]
        votes = {p: inside[rows[parts == p]].sum() + 1e-6 * (parts == p).sum() for p in np.unique(parts).tolist()}
        best = max(votes.values())
        new_owner[rows] = [owner[r] if votes[p] >= best else -1 for r, p in zip(rows.tolist(), parts.tolist())]
    return new_key, new_owner, added


def grouped_points(points: np.ndarray, rect: Rectangles, labels: np.ndarray, tracks: np.ndarray,
                   length_sd: np.ndarray, n: np.ndarray, config: ClusteringConfig, depths=0.0) -> dict:
    """The tracker's grouping of a frame's points: the points in a track's rectangle (plus
    ``track_margin`` along and ``across_margin`` across it) go to its group (``duplicate_groups`` at the
    tracks' ``depths``); strays join their component's majority
    group; small free fragments may continue a track's side (``fragment_owners``, with the length's sd
    ``length_sd`` per track); the clusters too wide across the road are cut (``split_clusters``).
    Returns the points ordered by key (ties by index), the clusters' edges, each cluster's owner group,
    each mixture component's group (``labels`` against those of ``tracks``), and the counts
    ``clusters_split`` and ``fragment_points_adopted``."""
    owner = np.full(len(points), -1)
    groups = np.zeros(0, dtype=int)
    component_group = np.full(len(labels), -1)
    if len(tracks):
        groups = duplicate_groups(rect, depths)
        same = labels[:, None] == labels[tracks][None, :]  # (C, T)
        component_group = np.where(same.any(axis=1), groups[same.argmax(axis=1)], -1)
        # grown by track_margin along the length and across_margin across it
        box = points_in_rectangles(points, rect.center, rect.psi, rect.length,
                                   rect.width + 2.0 * (config.across_margin - config.track_margin), config.track_margin)
        owner = np.where(box >= 0, groups[np.maximum(box, 0)], -1)
    component = (distance_partition(points, config.distance) if config.grazing_angle is None else
                 ray_partition(points, config.distance, config.grazing_angle, config.bearing_bin, config.grazing_max_gap))
    inside = owner >= 0
    owner = adopt_strays(component, owner)
    adopted = 0
    if config.fragment_points is not None and len(tracks):
        held = np.zeros(int(groups.max()) + 1, dtype=bool)
        held[owner[owner >= 0]] = True
        taken = fragment_owners(points, component, owner < 0, rect.center, rect.psi, rect.length, rect.width,
                                length_sd, config.track_margin, config.fragment_points, config.fragment_sigmas,
                                held[groups], config.fragment_side_tolerance)
        adopted = int((taken >= 0).sum())
        owner = np.where(taken >= 0, groups[np.maximum(taken, 0)], owner)
    key = np.where(owner >= 0, owner, len(tracks) + component)
    split = 0
    if config.split_width is not None:
        key, owner, split = split_clusters(key, owner, inside, n, config.split_width, config.split_gap)
    order = np.argsort(key, kind="stable")
    edges = np.concatenate([[0], np.flatnonzero(np.diff(key[order])) + 1, [len(points)]])
    return {"ordered": points[order], "edges": edges, "owned": owner[order][edges[:-1]],
            "component_group": component_group, "clusters_split": split, "fragment_points_adopted": adopted}


def _ray_gap(point: np.ndarray, other: np.ndarray | None, heading: np.ndarray, step: float) -> float:
    """The spacing of a scan's returns (bearing step ``step``) at ``point`` along a side through it:
    ``r^2 step / d``, the side along the line from ``other`` to ``point`` (None: along ``heading``, as
    where the two coincide), 0 for a line more than 45 deg across ``heading``."""
    direction = heading if other is None or not np.any(point != other) else (point - other) / np.linalg.norm(point - other)
    if abs(direction @ heading) < np.sqrt(0.5):
        return 0.0
    d = abs(point[0] * direction[1] - point[1] * direction[0])
    return float(point @ point) * step / d if d > 0.0 else np.inf


def along_cuts(ordered: np.ndarray, edges: np.ndarray, owned: np.ndarray, rect: Rectangles, groups: np.ndarray,
               scan: np.ndarray, step: float, rays: float, min_gap: float, margin: float, min_part: int) -> tuple:
    """The cuts along a track group's cluster, from their definition: its points sorted by ``t`` along the
    heading of the group's first track are cut between neighbours at least ``min_gap`` and ``rays`` ray
    gaps apart (``_ray_gap`` at both, along the heading and along the line to the next point outward),
    with no ``scan`` return strictly inside the bearings between them that is nearer than the nearer one
    less ``margin`` or lies inside the gap along the heading (``min_gap / 2`` from both), each part at
    least ``min_part`` points (cuts taken in order of ``t``). The part with most points inside the
    rectangle (ties: the larger, then the first) stays owned, in place; the others follow all clusters.
    Returns the ordered points, edges, owners and the number of parts added."""
    kept, extra, added = [], [], 0
    first_track = {int(g): int(np.flatnonzero(groups == g)[0]) for g in np.unique(groups)} if len(groups) else {}
    for k in range(len(edges) - 1):
        pts, g = ordered[edges[k]:edges[k + 1]], int(owned[k])
        if g < 0 or len(pts) < 2 * min_part:
            kept.append((pts, g))
            continue
        tr = first_track[g]
        u = np.array([np.cos(rect.psi[tr]), np.sin(rect.psi[tr])])
        t = (pts - rect.center[tr]) @ u
        order = np.argsort(t, kind="stable")
        part = np.zeros(len(pts), dtype=int)
        last, cuts = 0, 0
        for j in range(min_part, len(pts) - min_part + 1):
            a, z = pts[order[j - 1]], pts[order[j]]
            gap = t[order[j]] - t[order[j - 1]]
            if j - last < min_part or not gap >= min_gap:
                continue
            spacing = max(_ray_gap(a, None, u, step), _ray_gap(z, None, u, step),
                          _ray_gap(a, pts[order[j - 2]], u, step) if j >= 2 else 0.0,
                          _ray_gap(z, pts[order[j + 1]], u, step) if j + 1 < len(pts) else 0.0)
            if not gap >= rays * spacing:
                continue
            ba, bz = np.arctan2(a[1], a[0]), np.arctan2(z[1], z[0])
            width = (bz - ba + np.pi) % (2 * np.pi) - np.pi
            start = ba if width >= 0 else bz
            offset = (np.arctan2(scan[:, 1], scan[:, 0]) - start) % (2 * np.pi)
            between = (offset > 1e-6) & (offset < abs(width) - 1e-6)
            ts = (scan - rect.center[tr]) @ u
            nearer = np.hypot(*scan.T) < min(np.hypot(*a), np.hypot(*z)) - margin
            inside = (ts > t[order[j - 1]] + 0.5 * min_gap) & (ts < t[order[j]] - 0.5 * min_gap)
            if (between & (nearer | inside)).any():
                continue
            part[order[j:]] += 1
            last, cuts = j, cuts + 1
        if cuts == 0:
            kept.append((pts, g))
            continue
        added += cuts
        d = pts - rect.center[tr]
        inside = (np.abs(d @ u) <= 0.5 * rect.length[tr]) & (np.abs(d @ np.array([-u[1], u[0]])) <= 0.5 * rect.width[tr])
        counts = list(zip(np.bincount(part[inside], minlength=cuts + 1), np.bincount(part, minlength=cuts + 1)))
        keep = max(range(cuts + 1), key=lambda p: (counts[p], -p))
        kept.append((pts[part == keep], g))
        extra += [(pts[part == p], -1) for p in range(cuts + 1) if p != keep]
    parts = kept + extra
    sizes = [len(p) for p, _ in parts]
    return (np.concatenate([p for p, _ in parts]) if parts else ordered, np.concatenate([[0], np.cumsum(sizes)]),
            np.array([g for _, g in parts], dtype=int), added)


def cluster(points: np.ndarray, rect: Rectangles, labels: np.ndarray, tracks: np.ndarray, length_sd: np.ndarray,
            n: np.ndarray, radar: RadarDetections, t: float, config: ClusteringConfig, use_radar: bool = True,
            scan: np.ndarray | None = None, step: float = 0.0, margin: float = 0.0, min_part: int = 1,
            depths=0.0) -> tuple:
    """``Tracker._cluster``: the clusters (``grouped_points`` with the tracks' duplicate ``depths``, then ``along_cuts`` in the lidar returns
    ``scan`` of bearing step ``step`` with the shadow ``margin`` and parts of ``min_part`` points; those
    of fewer than ``min_points`` points dropped), each one's radar velocity (``associate_radar`` of the
    detections moved to ``t``) or None, each cluster's owner group, each component's group, the free
    detections and the counts."""
    grouped = grouped_points(points, rect, labels, tracks, length_sd, n, config, depths)
    edges = grouped["edges"]
    ordered, owned, cut = grouped["ordered"], grouped["owned"], 0
    if config.along_gap is not None and len(tracks) and (owned >= 0).any():
        ordered, edges, owned, cut = along_cuts(ordered, edges, owned, rect, duplicate_groups(rect, depths),
                                                np.zeros((0, 2)) if scan is None else scan, step,
                                                config.along_gap_rays, config.along_gap, margin, min_part)
    clusters = [ordered[a:b] for a, b in zip(edges[:-1], edges[1:])]
    big = np.diff(edges) >= config.min_points
    stats = Counter(clusters_too_small=int((~big).sum()) if config.min_points > 1 else 0,
                    clusters_split=grouped["clusters_split"], fragment_points_adopted=grouped["fragment_points_adopted"],
                    clusters_cut_along=cut)
    if config.min_points > 1:
        clusters = [c for c, keep in zip(clusters, big) if keep]
        owned = owned[big]
    velocities: list = [None] * len(clusters)
    free = np.arange(len(radar))
    if use_radar and clusters and len(radar):
        index = associate_radar(clusters, radar.positions_at(t), config.radar_gate)
        velocities = [None if r < 0 else np.array([radar.vx[r], radar.vy[r]]) for r in index.tolist()]
        free = np.setdiff1d(free, index[index >= 0])
    stats.update(clusters=len(clusters), clusters_fused=sum(v is not None for v in velocities))
    return clusters, velocities, owned, grouped["component_group"], free, stats


def inside_updated(center: np.ndarray, psi: np.ndarray, length: np.ndarray, width: np.ndarray, seen: np.ndarray,
                   idle: np.ndarray) -> np.ndarray:
    """Which of the components ``idle`` have their centre inside the rectangle (margin 0) of one of the
    components ``seen``."""
    return points_in_rectangles(center[idle], center[seen], psi[seen], length[seen], width[seen], margin=0.0) >= 0
