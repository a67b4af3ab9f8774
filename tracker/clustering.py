"""Clustering of lidar points and radar-to-cluster association (the paper's fusion and clustering).

- ``points_in_rectangles``: points inside a predicted target's rectangle (plus a margin) form that
  target's cluster (vectorised over points x rectangles);
- ``distance_partition``: the remaining points are split into connected components of the graph
  linking points closer than a threshold (``scipy.spatial.cKDTree`` + ``scipy.sparse.csgraph``), the
  distance partitioning of Granstrom et al. at one threshold;
- ``split_across``: a cluster wider across the road than one vehicle can be (two long vehicles side by
  side in adjacent lanes, whose points the lidar sees as one line, or a drifted track's rectangle owning
  both) is cut at its largest gap in the lateral offset ``n``;
- ``associate_radar``: greedy nearest-neighbour association of radar detections to clusters within
  a gate; a cluster with a detection is "fused" and carries its absolute velocity. Radar positions
  are used only for this association, as in the paper.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from tracker import compiled as compiled_kernels
from tracker.angles import wrap_angle
from tracker.frame import RadarDetections
from tracker.compiled.clustering import cluster_radar_kernel

#: Up to this many runs of consecutive linked points, their graph's components are found densely.
MAX_DENSE_RUNS = 64


def points_in_rectangles(
    points: np.ndarray,
    centres: np.ndarray,
    yaw: np.ndarray,
    length: np.ndarray,
    width: np.ndarray,
    margin: float = 1.0,
) -> np.ndarray:
    """Index of the rectangle containing each point (-1 for none), all in one frame (m, rad).

    Rectangles are widened by ``margin`` on every side. A point inside several (overlapping
    predictions) goes to the one whose centre is nearest in normalised rectangle coordinates.
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    ctr = np.asarray(centres, dtype=float).reshape(-1, 2)
    if len(pts) == 0 or len(ctr) == 0:
        return np.full(len(pts), -1, dtype=int)
    c, s = np.cos(yaw), np.sin(yaw)
    if compiled_kernels.enabled():
        from tracker.compiled.clustering import points_in_rectangles_kernel

        half_l = np.broadcast_to(0.5 * np.asarray(length, dtype=float) + margin, (len(ctr),))
        half_w = np.broadcast_to(0.5 * np.asarray(width, dtype=float) + margin, (len(ctr),))
        return points_in_rectangles_kernel(np.ascontiguousarray(pts), np.ascontiguousarray(ctr),
                                           np.ascontiguousarray(np.broadcast_to(c, (len(ctr),)), dtype=float),
                                           np.ascontiguousarray(np.broadcast_to(s, (len(ctr),)), dtype=float),
                                           np.ascontiguousarray(half_l), np.ascontiguousarray(half_w))
    d = pts[:, None, :] - ctr[None, :, :]  # (N, M, 2)
    u = (d[..., 0] * c + d[..., 1] * s) / (0.5 * np.asarray(length) + margin)
    v = (-d[..., 0] * s + d[..., 1] * c) / (0.5 * np.asarray(width) + margin)
    score = np.maximum(np.abs(u), np.abs(v))  # <= 1 inside the widened rectangle
    best = np.argmin(score, axis=1)
    inside = score[np.arange(len(pts)), best] <= 1.0
    return np.where(inside, best, -1)


def distance_partition(points: np.ndarray, threshold: float) -> np.ndarray:
    """Cluster label (0..K-1) of each point: connected components of the graph whose edges join
    points closer than ``threshold`` metres. Labels are ordered by each cluster's first point.

    The edges come from ``cKDTree.query_pairs``. A lidar scan lists its points in scan order, so most
    edges join consecutive points: those first cut the points into runs (connected by construction),
    and only the few edges between runs go into a graph over the runs, whose components
    (``dense_components``, or ``scipy.sparse.csgraph`` for many runs) are the clusters; any order of
    the points gives the same partition, only more runs. The compiled kernel
    (``tracker.compiled.clustering``, when on) finds the same components by union-find on a grid."""
    if not threshold > 0:
        raise ValueError(f"distance threshold must be > 0 m; got {threshold!r}")
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    n = len(pts)
    if n == 0:
        return np.zeros(0, dtype=int)
    if compiled_kernels.enabled():
        # cells of side threshold / sqrt(2) from 2 (the neighbours two cells away have keys >= 0); a
        # non-finite point, or keys that could overflow, take the numpy path
        from tracker.compiled.clustering import partition_points_kernel

        labels, ok = partition_points_kernel(np.ascontiguousarray(pts), float(threshold))
        if ok:
            return labels
    pairs = cKDTree(pts).query_pairs(threshold, output_type="ndarray")  # i < j
    linked = np.zeros(n, dtype=bool)  # linked[i]: an edge joins point i - 1 and point i
    linked[pairs[pairs[:, 1] - pairs[:, 0] == 1, 1]] = True
    run = np.cumsum(~linked) - 1  # run index of every point (0..R-1)
    a, b = run[pairs[:, 0]], run[pairs[:, 1]]
    across = a != b
    a, b, runs = a[across], b[across], int(run[-1]) + 1
    if runs <= MAX_DENSE_RUNS:
        adjacency = np.zeros((runs, runs), dtype=bool)
        adjacency[a, b] = True
        component = dense_components(adjacency)
    else:
        graph = coo_matrix((np.ones(len(a)), (a, b)), shape=(runs, runs))
        component = connected_components(graph, directed=False)[1]
    labels = component[run]
    # relabel in order of first appearance so labels are deterministic and readable
    _, first = np.unique(labels, return_index=True)
    rank = np.empty(len(first), dtype=int)
    rank[np.argsort(first)] = np.arange(len(first))
    return rank[labels]


def fragment_owners(points: np.ndarray, component: np.ndarray, free: np.ndarray, centres: np.ndarray, yaw: np.ndarray,
                    length: np.ndarray, width: np.ndarray, length_sd: np.ndarray, margin: float, max_points: int,
                    sigmas: float, seen: np.ndarray | None = None, side_tolerance: float | None = None) -> np.ndarray:
    """The rectangle each small fragment continues at its far end: per point ``(N,)`` a rectangle index,
    or -1.

    The side of a truck seen at grazing incidence far away returns one point every 2-3 m (the ray
    spacing ``r delta / sin(incidence)``), beyond the clustering distance: while its track's length is
    still a car's, the points past the predicted front are one-point clusters, each updating the track
    into a posterior of its own (a split label) or seeding a newborn. So a connected component
    (``component (N,)``) of at most ``max_points`` points, all of them ``free`` (owned by no rectangle),
    gets the index of the rectangle (``centres``, ``yaw``, ``length``, ``width``, E, m and rad) whose
    stretched version holds all its points, when

    - the stretch: the rectangle grows at its end away from the sensor (the E origin; the near end is
      where the returns start) by ``sigmas`` times its length's standard deviation ``length_sd``, plus
      ``margin`` on every side; a length known to within ``margin`` (``sigmas`` sd at most ``margin``)
      is not stretched (a lone return past a measured car is noise: lidar spikes grew such a car, and the
      grown uncertainty reached for the next spike);
    - with ``seen (T,)``: the rectangle holds points of its own this frame (a fragment continues a side
      being seen; a coasting track does not reach for the first lone return of its vehicle coming back
      into view, which may lie anywhere about it);
    - with ``side_tolerance`` (m): the point lies within that distance of the line of the rectangle's
      long side facing the sensor (a side going on; a spurious return lands anywhere across);
    - the rectangle itself, shrunk by ``OCCLUSION_SHRINK``, does not hide the point from the sensor (a
      lidar spike along a ray that hit the vehicle lands behind it; a side going on is seen past it)."""
    out = np.full(len(component), -1)
    free = np.asarray(free, dtype=bool)
    if not free.any() or len(centres) == 0:
        return out
    size = np.bincount(component)
    free_size = np.bincount(component, weights=free, minlength=len(size))
    small = np.flatnonzero(free & (size[component] <= max_points) & (free_size[component] == size[component]))
    if not len(small):
        return out
    stretch = sigmas * np.asarray(length_sd, dtype=float)
    stretch = np.where(stretch > margin, stretch, 0.0)  # a length known to within the margin: not stretched
    if seen is not None:
        stretch = np.where(seen, stretch, 0.0)
    axis = np.stack([np.cos(yaw), np.sin(yaw)], axis=-1)
    far = np.where(np.einsum("td,td->t", centres, axis) >= 0.0, 1.0, -1.0)  # the sensor behind: the front is far
    hit = points_in_rectangles(points[small], centres + (0.5 * stretch * far)[:, None] * axis, yaw, length + stretch,
                               width, margin)
    k = np.maximum(hit, 0)
    normal = np.stack([-axis[k, 1], axis[k, 0]], axis=-1)
    rel = points[small] - centres[k]
    along, across = np.einsum("pd,pd->p", rel, axis[k]), np.einsum("pd,pd->p", rel, normal)
    sensor_along, sensor_across = np.einsum("pd,pd->p", -centres[k], axis[k]), np.einsum("pd,pd->p", -centres[k], normal)
    if side_tolerance is not None:  # on the line of the long side facing the sensor
        side = np.where(sensor_across >= 0.0, 0.5, -0.5) * np.asarray(width, dtype=float)[k]
        hit = np.where(np.abs(across - side) <= side_tolerance, hit, -1)
    # not behind the vehicle's own body: the ray to a real return does not cross the rectangle (shrunk by
    # ``OCCLUSION_SHRINK`` against its uncertainty); a spurious one along a ray that hit the vehicle does
    half_l = 0.5 * np.asarray(length, dtype=float)[k] - OCCLUSION_SHRINK
    half_w = 0.5 * np.asarray(width, dtype=float)[k] - OCCLUSION_SHRINK
    hidden = segment_crosses_box(np.stack([sensor_along, sensor_across], -1), np.stack([along, across], -1),
                                 half_l, half_w)
    hit = np.where(hidden, -1, hit)
    _, which = np.unique(component[small], return_inverse=True)
    lo = np.full(which.max() + 1, np.iinfo(np.int64).max)
    hi = np.full(which.max() + 1, -1)
    np.minimum.at(lo, which, hit)
    np.maximum.at(hi, which, hit)
    whole = (lo >= 0) & (lo == hi)  # every point of the fragment in one and the same rectangle
    whole &= stretch[np.maximum(lo, 0)] > 0.0  # (seen, and a length still uncertain)
    take = whole[which]
    out[small[take]] = lo[which][take]
    return out


#: Metres by which ``fragment_owners`` shrinks a rectangle before asking whether it hides a fragment.
OCCLUSION_SHRINK = 0.2


def segment_crosses_box(start: np.ndarray, end: np.ndarray, half_length: np.ndarray, half_width: np.ndarray) -> np.ndarray:
    """Whether each segment ``start (P, 2)`` -> ``end (P, 2)`` (in the box's own axes) passes through the
    open box ``|x| < half_length``, ``|y| < half_width`` (``P,`` boxes; an empty box, a half-extent
    not above 0, is crossed by nothing). The slab test: the parameter intervals in which the segment
    lies inside each slab must overlap within ``[0, 1]``."""
    start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    d = end - start
    lo, hi = np.zeros(len(start)), np.ones(len(start))
    ok = (np.asarray(half_length) > 0.0) & (np.asarray(half_width) > 0.0)
    for axis, half in ((0, np.asarray(half_length, dtype=float)), (1, np.asarray(half_width, dtype=float))):
        with np.errstate(divide="ignore", invalid="ignore"):
            t0 = (-half - start[:, axis]) / d[:, axis]
            t1 = (half - start[:, axis]) / d[:, axis]
        parallel = d[:, axis] == 0.0
        inside = np.abs(start[:, axis]) < half
        ok &= ~parallel | inside  # parallel to the slab and outside it: never in
        enter = np.where(parallel, -np.inf, np.minimum(t0, t1))
        leave = np.where(parallel, np.inf, np.maximum(t0, t1))
        lo, hi = np.maximum(lo, enter), np.minimum(hi, leave)
    return ok & (lo < hi)


#: Rounds of cuts ``split_across`` makes at most (a part still too wide after them stays whole).
SPLIT_MAX_CUTS = 8


def split_across(n: np.ndarray, group: np.ndarray, width: float, gap: float, max_cuts: int = SPLIT_MAX_CUTS) -> np.ndarray:
    """Part index (0..P-1) of each point: the points of each ``group`` (integer labels, any values)
    whose extent in ``n`` (the lateral road offset, m) exceeds ``width`` are cut at their largest gap
    between consecutive ``n`` values, if that gap is at least ``gap``; parts still wider are cut again
    (up to ``max_cuts`` rounds). Groups narrower than ``width``, or without such a gap (one vehicle at
    an angle to the road shows a continuous side), stay whole. Parts are numbered by group in sorted
    order, then by ``n``. Vectorised: each round is a few sorts and ``reduceat``s over all points."""
    n = np.asarray(n, dtype=float).reshape(-1)
    group = np.asarray(group).reshape(-1)
    if len(n) != len(group):
        raise ValueError(f"split_across needs one group per point; got {len(n)} offsets and {len(group)} groups")
    part = np.unique(group, return_inverse=True)[1].reshape(-1)
    if len(n) == 0:
        return part
    order = np.lexsort((n, part))  # by part, then by n: fixed from here, as cuts keep that order
    ns = n[order]
    ps = part[order]
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
        index = np.cumsum(first) - 1  # part (0..P-1, in sorted order) of each sorted point
        cut = wide[index] & (step == largest[index]) & (step >= gap)
        if not cut.any():
            break
        # one cut per part: the first point at its largest gap
        hits = np.flatnonzero(cut)
        _, keep = np.unique(index[hits], return_index=True)
        cut[:] = False
        cut[hits[keep]] = True
        ps = np.cumsum(first | cut) - 1
    out = np.empty(len(n), dtype=int)
    out[order] = ps
    return out


def dense_components(adjacency: np.ndarray) -> np.ndarray:
    """Connected components of the small undirected graph given by a boolean ``adjacency (T, T)``:
    component index per node, numbered in order of each component's first node (as scipy's
    ``connected_components``). By boolean squaring of the reachability matrix (``log2 T`` products),
    which for the tens of tracks of a frame is cheaper than building a sparse graph."""
    adj = np.asarray(adjacency, dtype=bool)
    count = len(adj)
    if count == 0:
        return np.zeros(0, dtype=int)
    reach = (adj | adj.T | np.eye(count, dtype=bool)).astype(np.float32)
    while True:
        nxt = ((reach @ reach) > 0).astype(np.float32)
        if np.array_equal(nxt, reach):
            break
        reach = nxt
    first = np.argmax(reach > 0, axis=1)  # the lowest node of each node's component
    return np.unique(first, return_inverse=True)[1].reshape(-1)


def associate_radar(cluster_points: list[np.ndarray], radar_xy: np.ndarray, gate: float = 3.0) -> np.ndarray:
    """Greedy nearest-neighbour association of radar detections (R, 2) to clusters.

    The distance from a detection to a cluster is the distance to the cluster's nearest point (the
    radar reports a point near the target's visible surface). Pairs are taken in increasing distance;
    each cluster and each detection is used at most once; pairs farther than ``gate`` metres are
    never taken. Returns, per cluster, the index of its detection or -1. (By
    ``tracker.compiled.clustering`` when the compiled kernels are on.)
    """
    radar = np.asarray(radar_xy, dtype=float).reshape(-1, 2)
    out = np.full(len(cluster_points), -1, dtype=int)
    if len(radar) == 0 or len(cluster_points) == 0:
        return out
    sizes = np.array([len(p) for p in cluster_points])
    if compiled_kernels.enabled():
        from tracker.compiled.clustering import radar_association_kernel

        offsets = np.zeros(len(sizes) + 1, dtype=np.int64)
        np.cumsum(sizes, out=offsets[1:])
        if all(type(p) is np.ndarray and p.ndim == 2 and p.shape[1] == 2 and p.dtype == np.float64 for p in cluster_points):
            pts = np.concatenate(cluster_points)  # the tracker's clusters: (n, 2) float arrays already
        else:
            pts = np.concatenate([np.asarray(p, dtype=float).reshape(-1, 2) for p in cluster_points])
        return radar_association_kernel(pts, offsets, np.ascontiguousarray(radar), float(gate))
    dist = np.full((len(cluster_points), len(radar)), np.inf)
    if sizes.sum():
        pts = np.concatenate([p for p in cluster_points if len(p)])
        d = np.linalg.norm(pts[:, None, :] - radar[None, :, :], axis=2)  # (points, detections)
        starts = np.concatenate([[0], np.cumsum(sizes[sizes > 0])[:-1]])
        dist[sizes > 0] = np.minimum.reduceat(d, starts, axis=0)
    flat = np.argsort(dist, axis=None)
    rows, cols = np.unravel_index(flat, dist.shape)
    ok = dist[rows, cols] <= gate
    used_r = np.zeros(len(radar), dtype=bool)
    for r, c in zip(rows[ok].tolist(), cols[ok].tolist()):  # greedy over gated pairs only
        if out[r] < 0 and not used_r[c]:
            out[r] = c
            used_r[c] = True
    return out


def cluster_velocities(clusters: list[np.ndarray], radar: RadarDetections, t: float, gate: float) -> list[np.ndarray | None]:
    """Per cluster, the absolute velocity ``(vx, vy)`` (m/s, E axes) of its associated radar detection,
    or None (``cluster_radar``)."""
    return cluster_radar(clusters, radar, t, gate)[0]


def cluster_radar(clusters: list[np.ndarray], radar: RadarDetections, t: float,
                  gate: float) -> tuple[list[np.ndarray | None], np.ndarray]:
    """Per cluster, the absolute velocity ``(vx, vy)`` (m/s, E axes) of its associated radar detection
    or None, and the index of that detection (-1: none). Each detection is first moved to the frame
    time ``t`` with its own velocity (a radar scan is up to one lidar period old), then
    ``associate_radar`` pairs them within ``gate`` metres."""
    velocities: list[np.ndarray | None] = [None] * len(clusters)
    if len(radar) == 0 or not clusters:
        return velocities, np.full(len(clusters), -1, dtype=int)
    index = np.asarray(associate_radar(clusters, radar.positions_at(t), gate), dtype=int)
    velocity = np.column_stack([radar.vx, radar.vy]).astype(float, copy=False)  # one (vx, vy) row per detection
    velocity.flags.writeable = False  # the clusters' velocities are rows of it: read-only, not aliased edits
    for k, r in enumerate(index.tolist()):
        if r >= 0:
            velocities[k] = velocity[r]
    return velocities, index


def cluster_radar_ranges(points: np.ndarray, lo: np.ndarray, hi: np.ndarray, radar: RadarDetections, t: float,
                         gate: float) -> tuple[list[np.ndarray | None], np.ndarray]:
    """``cluster_radar`` for the clusters ``points[lo[k]:hi[k]]`` (``points (N, 2)`` in E ordered by
    cluster, as the tracker groups them): per cluster the velocity ``(vx, vy)`` of its detection (a
    row of one read-only ``(R, 2)`` array) or None, and the indices of the detections that joined no
    cluster. One compiled call (``tracker.compiled.clustering.cluster_radar_kernel``: the detections
    moved to ``t`` as ``RadarDetections.positions_at``, then the association) when the kernels are on."""
    lo = np.asarray(lo, dtype=np.int64).reshape(-1)
    hi = np.asarray(hi, dtype=np.int64).reshape(-1)
    if len(lo) != len(hi):
        raise ValueError(f"cluster_radar_ranges needs one end per start; got {len(lo)} starts and {len(hi)} ends")
    if len(lo) and (lo.min() < 0 or (hi < lo).any() or hi.max() > len(points)):
        raise ValueError(f"cluster_radar_ranges: every range must lie within the {len(points)} points, 0 <= lo <= hi")
    if len(radar) == 0 or len(lo) == 0 or not compiled_kernels.enabled():
        velocities, index = cluster_radar([points[a:b] for a, b in zip(lo.tolist(), hi.tolist())], radar, t, gate)
        free = np.ones(len(radar), dtype=bool)
        free[index[index >= 0]] = False
        return velocities, np.flatnonzero(free)
    index, velocity, free = cluster_radar_kernel(np.ascontiguousarray(points, dtype=float), lo, hi, radar.t, radar.x,
                                                 radar.y, radar.vx, radar.vy, float(t), float(gate))
    velocity.flags.writeable = False  # the clusters' velocities are rows of it: read-only, not aliased edits
    velocities: list[np.ndarray | None] = [None] * len(lo)
    for k, r in enumerate(index.tolist()):
        if r >= 0:
            velocities[k] = velocity[r]
    return velocities, free


def bearing_extremes(clusters: list[np.ndarray]) -> np.ndarray:
    """Each cluster's first and last point in bearing from the lidar at E's origin: ``(K, 2, 2)`` for
    ``clusters`` of points ``(N, 2)`` in E (bearings taken about each cluster's centroid bearing, so a
    cluster across the -x axis is not split by the +-pi wrap), the input of ``occluded_ends``."""
    out = np.zeros((len(clusters), 2, 2))
    if not clusters:
        return out
    size = np.array([len(c) for c in clusters])
    pts = np.concatenate(clusters)
    start = np.cumsum(size) - size
    centroid = np.add.reduceat(pts, start) / size[:, None]
    owner = np.repeat(np.arange(len(clusters)), size)
    rel = wrap_angle(np.arctan2(pts[:, 1], pts[:, 0]) - np.arctan2(centroid[owner, 1], centroid[owner, 0]))
    order = np.lexsort((rel, owner))  # by cluster, then by bearing
    out[:, 0] = pts[order[start]]
    out[:, 1] = pts[order[start + size - 1]]
    return out


def occluded_ends(ends: np.ndarray, scan: np.ndarray, window: float, margin: float,
                  max_range: float = np.inf, range_margin: float = 0.0) -> np.ndarray:
    """Whether each end of each cluster borders a shadow: ``(K, 2)`` bool for ``ends (K, 2, 2)``, each
    cluster's first and last point in bearing order in E, the lidar at the origin
    (``tracker.measurement.ClusterBatch.bearing_ends``). An end is occluded when a return of
    ``scan (R, 2)`` (the frame's lidar points) lies within ``window`` rad beyond it in bearing and more
    than ``margin`` m nearer than the end point: the side continues behind another object, so the
    extreme point is not the side's end. An end whose neighbouring rays return nothing or something
    farther is the object's own boundary, unless it lies within ``range_margin`` of the lidar's
    ``max_range`` (m): there the side may go on beyond the range, and the end counts as occluded too.
    One compiled call (``tracker.compiled.clustering.occluded_ends_kernel``) when the kernels are on."""
    ends = np.asarray(ends, dtype=float).reshape(-1, 2, 2)
    if len(ends) == 0 or len(scan) == 0:
        return np.zeros((len(ends), 2), dtype=bool)
    if compiled_kernels.enabled():
        from tracker.compiled.clustering import occluded_ends_kernel

        compiled_kernels.require()
        return occluded_ends_kernel(np.ascontiguousarray(ends), np.ascontiguousarray(scan, dtype=float), float(window),
                                    float(margin), float(max_range), float(range_margin))
    bearing = np.arctan2(ends[..., 1], ends[..., 0]).ravel()  # (2K,) first and last end of each cluster
    reach = np.hypot(ends[..., 0], ends[..., 1]).ravel()
    scan_r = np.hypot(scan[:, 0], scan[:, 1])
    near = scan_r < reach.max() - margin  # only returns nearer than some end can occlude it
    scan_b, scan_r = np.arctan2(scan[near, 1], scan[near, 0]), scan_r[near]
    beyond = np.tile([-1.0, 1.0], len(ends))  # the first end looks below its bearing, the last above
    d = scan_b[None, :] - bearing[:, None]
    d = beyond[:, None] * (d - 2.0 * np.pi * np.round(d / (2.0 * np.pi)))  # > 0: beyond the end
    nearer = (d > 0.0) & (d <= window) & (scan_r[None, :] < reach[:, None] - margin)
    return (nearer.any(axis=1) | (reach >= max_range - range_margin)).reshape(len(ends), 2)


def continued_ends(ends: np.ndarray, outward: np.ndarray, half_gap: np.ndarray, scan: np.ndarray, rays: float,
                   offset: float) -> np.ndarray:
    """Whether the side goes on beyond each end of each cluster: ``(K, 2)`` bool for ``ends (K, 2, 2)``
    (where each cluster's side ends at its first and last point in bearing, in E), ``outward (K, 2, 2)``
    (unit directions pointing on beyond them) and ``half_gap (K, 2)`` (half the expected ray gap there,
    m; ``tracker.measurement.ClusterBatch.side_ends``). An end continues when a return of ``scan (R, 2)``
    lies beyond it along its line, more than half a ray gap (the next ray's return is a whole gap
    beyond; the cluster's own points lie at or before the end) and within ``rays`` ray gaps
    (``2 half_gap`` each), and at most ``offset`` m from that line: the next ray or two along the side
    found it again in another cluster (a dropped return split the side), so the extreme point is not
    the side's end. One compiled call
    (``tracker.compiled.clustering.continued_ends_kernel``) when the kernels are on."""
    ends = np.asarray(ends, dtype=float).reshape(-1, 2, 2)
    outward = np.asarray(outward, dtype=float).reshape(-1, 2, 2)
    half_gap = np.asarray(half_gap, dtype=float).reshape(-1, 2)
    reach = 2.0 * float(rays) * half_gap
    if len(ends) == 0 or len(scan) == 0:
        return np.zeros((len(ends), 2), dtype=bool)
    if compiled_kernels.enabled():
        from tracker.compiled.clustering import continued_ends_kernel

        compiled_kernels.require()
        return continued_ends_kernel(np.ascontiguousarray(ends), np.ascontiguousarray(outward), np.ascontiguousarray(half_gap),
                                     np.ascontiguousarray(reach), np.ascontiguousarray(scan, dtype=float), float(offset))
    d = scan[None, None, :, :] - ends[:, :, None, :]  # (K, 2, R, 2)
    along = np.einsum("kerd,ked->ker", d, outward)
    across = np.abs(d[..., 0] * outward[..., None, 1] - d[..., 1] * outward[..., None, 0])
    return ((along > half_gap[..., None]) & (along <= reach[..., None]) & (across <= offset)).any(axis=2)
