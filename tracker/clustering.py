"""Clustering of lidar points and radar-to-cluster association (the paper's fusion and clustering).

- ``points_in_rectangles``: points inside a predicted target's rectangle (plus a margin) form that
  target's cluster;
- ``distance_partition``: the remaining points are split into connected components of the graph
  linking points at most a threshold apart, the distance partitioning of Granstrom et al. at one
  threshold;
- the tracker's grouping of a frame's points (``cluster_points_kernel``): overlapping track
  rectangles are one group, a connected component a group owns in part joins it, lone fragments may
  continue a track's side (``fragment_owners``), and a cluster wider across the road than one vehicle
  can be (two long vehicles side by side in adjacent lanes, whose points the lidar sees as one line,
  or a drifted track's rectangle owning both) is cut at its largest gap in the lateral offset ``n``;
- ``associate_radar``: greedy nearest-neighbour association of radar detections to clusters within
  a gate; a cluster with a detection is "fused" and carries its absolute velocity. Radar positions
  are used only for this association, as in the paper;
- ``occluded_ends``, ``continued_ends``: whether a cluster's ends border another object's shadow, or
  whether its side goes on in another cluster.

The stage's numba kernels are at the end of the module.
"""

from __future__ import annotations

import math
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from tracker.angles import wrap_angle
from tracker.frame import RadarDetections
from tracker.jit import njit

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
    half_l = np.broadcast_to(0.5 * np.asarray(length, dtype=float) + margin, (len(ctr),))
    half_w = np.broadcast_to(0.5 * np.asarray(width, dtype=float) + margin, (len(ctr),))
    return points_in_rectangles_kernel(np.ascontiguousarray(pts), np.ascontiguousarray(ctr),
                                       np.ascontiguousarray(np.broadcast_to(c, (len(ctr),)), dtype=float),
                                       np.ascontiguousarray(np.broadcast_to(s, (len(ctr),)), dtype=float),
                                       np.ascontiguousarray(half_l), np.ascontiguousarray(half_w))


def distance_partition(points: np.ndarray, threshold: float) -> np.ndarray:
    """Cluster label (0..K-1) of each point: connected components of the graph whose edges join
    points at most ``threshold`` metres apart. Labels are ordered by each cluster's first point.

    One compiled call (``partition_points_kernel``: union-find on a grid of square cells of side
    ``threshold / sqrt(2)``). Points the grid cannot hold (a non-finite point, or a spread so wide
    that the cells' keys could overflow) take the whole graph instead: its edges from
    ``cKDTree.query_pairs`` (which rejects a non-finite point with a ``ValueError``), its components
    from ``scipy.sparse.csgraph``."""
    if not threshold > 0:
        raise ValueError(f"distance threshold must be > 0 m; got {threshold!r}")
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    n = len(pts)
    if n == 0:
        return np.zeros(0, dtype=int)
    labels, ok = partition_points_kernel(np.ascontiguousarray(pts), float(threshold))
    if ok:
        return labels
    pairs = cKDTree(pts).query_pairs(threshold, output_type="ndarray")  # i < j
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    labels = connected_components(graph, directed=False)[1]
    # relabel in order of first appearance so labels are deterministic and readable
    _, first = np.unique(labels, return_index=True)
    rank = np.empty(len(first), dtype=int)
    rank[np.argsort(first)] = np.arange(len(first))
    return rank[labels]


def ray_partition(points: np.ndarray, threshold: float, grazing_angle: float | None = None,
                  bearing_step: float = math.radians(0.2), max_gap: float = 4.0) -> np.ndarray:
    """``distance_partition`` at ``threshold`` (m), and with ``grazing_angle`` (rad) the adaptive
    breakpoint rule of Borges and Aldon (2004) on top: two points on neighbouring rays (bearings from
    the E origin at most ``1.5 bearing_step`` apart, no ray between them) also join when

        |p_i - p_j| <= min(max_gap, min(r_i, r_j) dtheta / sin(lambda)),

    the spacing of consecutive returns on a surface seen at incidence ``lambda`` (the ray meets it at
    ``lambda`` or more). A far vehicle's side seen at a grazing angle has returns ``r dtheta / sin alpha``
    apart (1.9 m at 52 m for a car 5 m to the side with a 0.2 deg step), more than any fixed threshold
    that keeps neighbours in a queue apart; one fixed threshold leaves it one-point clusters that seed
    no birth. A gap between two vehicles that some ray passes through leaves a ray between their
    returns (or a return far behind), so it is never joined. Labels as ``distance_partition``'s: by
    each cluster's first point."""
    labels = distance_partition(points, threshold)
    if grazing_angle is None or len(labels) < 2:
        return labels
    if not 0.0 < grazing_angle < 0.5 * math.pi:
        raise ValueError(f"grazing_angle must be in (0, pi/2) rad; got {grazing_angle!r}")
    if not bearing_step > 0 or not max_gap > 0:
        raise ValueError(f"bearing_step and max_gap must be > 0; got {bearing_step!r}, {max_gap!r}")
    pts = np.ascontiguousarray(np.asarray(points, dtype=float).reshape(-1, 2))
    return ray_links_kernel(pts, np.ascontiguousarray(labels, dtype=np.int64), 1.5 * float(bearing_step),
                            1.0 / math.sin(grazing_angle), float(max_gap))


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


#: Rounds of cuts across the road the clustering makes at most (``_split_keys``: a part still too wide
#: after them stays whole).
SPLIT_MAX_CUTS = 8


def associate_radar(cluster_points: list[np.ndarray], radar_xy: np.ndarray, gate: float = 3.0) -> np.ndarray:
    """Greedy nearest-neighbour association of radar detections (R, 2) to clusters.

    The distance from a detection to a cluster is the distance to the cluster's nearest point (the
    radar reports a point near the target's visible surface). Pairs are taken in increasing distance;
    each cluster and each detection is used at most once; pairs farther than ``gate`` metres are
    never taken. Returns, per cluster, the index of its detection or -1 (one compiled call,
    ``radar_association_kernel``).
    """
    radar = np.asarray(radar_xy, dtype=float).reshape(-1, 2)
    out = np.full(len(cluster_points), -1, dtype=int)
    if len(radar) == 0 or len(cluster_points) == 0:
        return out
    sizes = np.array([len(p) for p in cluster_points])
    offsets = np.zeros(len(sizes) + 1, dtype=np.int64)
    np.cumsum(sizes, out=offsets[1:])
    if all(type(p) is np.ndarray and p.ndim == 2 and p.shape[1] == 2 and p.dtype == np.float64 for p in cluster_points):
        pts = np.concatenate(cluster_points)  # the tracker's clusters: (n, 2) float arrays already
    else:
        pts = np.concatenate([np.asarray(p, dtype=float).reshape(-1, 2) for p in cluster_points])
    return radar_association_kernel(pts, offsets, np.ascontiguousarray(radar), float(gate))


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
    cluster. One compiled call (``cluster_radar_kernel``: the detections moved to ``t`` as
    ``RadarDetections.positions_at``, then the association)."""
    lo = np.asarray(lo, dtype=np.int64).reshape(-1)
    hi = np.asarray(hi, dtype=np.int64).reshape(-1)
    if len(lo) != len(hi):
        raise ValueError(f"cluster_radar_ranges needs one end per start; got {len(lo)} starts and {len(hi)} ends")
    if len(lo) and (lo.min() < 0 or (hi < lo).any() or hi.max() > len(points)):
        raise ValueError(f"cluster_radar_ranges: every range must lie within the {len(points)} points, 0 <= lo <= hi")
    if len(radar) == 0 or len(lo) == 0:  # nothing to associate: every detection is free
        return [None] * len(lo), np.arange(len(radar))
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
    One compiled call (``occluded_ends_kernel``)."""
    ends = np.asarray(ends, dtype=float).reshape(-1, 2, 2)
    if len(ends) == 0 or len(scan) == 0:
        return np.zeros((len(ends), 2), dtype=bool)
    return occluded_ends_kernel(np.ascontiguousarray(ends), np.ascontiguousarray(scan, dtype=float), float(window),
                                float(margin), float(max_range), float(range_margin))


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
    the side's end. One compiled call (``continued_ends_kernel``)."""
    ends = np.asarray(ends, dtype=float).reshape(-1, 2, 2)
    outward = np.asarray(outward, dtype=float).reshape(-1, 2, 2)
    half_gap = np.asarray(half_gap, dtype=float).reshape(-1, 2)
    reach = 2.0 * float(rays) * half_gap
    if len(ends) == 0 or len(scan) == 0:
        return np.zeros((len(ends), 2), dtype=bool)
    return continued_ends_kernel(np.ascontiguousarray(ends), np.ascontiguousarray(outward), np.ascontiguousarray(half_gap),
                                 np.ascontiguousarray(reach), np.ascontiguousarray(scan, dtype=float), float(offset))


# --------------------------------------------------------------------------------------------------
# The compiled kernels of this stage.
#
# The distance partition (``partition_points_kernel``): the graph of points joined when at most
# ``threshold`` apart and its connected components, found on a grid of square cells of side
# ``threshold / sqrt(2)``: the points of one cell are all within ``threshold`` of each other (one
# component), and two cells at most two apart along each axis are joined as soon as one pair of their
# points is close enough (union-find; a pair of cells already in one component is skipped). Components
# are labelled in order of their first point (so any order of the unions gives the same labels).
#
# The tracker's grouping of a frame's points into clusters (``cluster_points_kernel``: the track
# rectangles' overlap groups, the points in rectangles, the partition, strays adopted, clusters cut
# across the road, the points ordered by cluster; ``ordered_clusters_kernel`` for its second half), the
# radar association (``associate_ranges``, ``cluster_radar_kernel``), and the scan's bearing searches
# (``occluded_ends_kernel``, ``continued_ends_kernel``, ``nearest_in_bins_kernel``, ``bearing_filter_kernel``).
# --------------------------------------------------------------------------------------------------


@njit
def _root(parent, i):
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@njit
def _union(parent, a, b):
    a = _root(parent, a)
    b = _root(parent, b)
    if a != b:
        parent[max(a, b)] = min(a, b)


@njit(inline="always")
def _labels_in_order(parent):
    """Component label per node of a union-find forest, numbered in order of each component's first node."""
    n = len(parent)
    labels = np.empty(n, dtype=np.int64)
    rank = np.full(n, -1, dtype=np.int64)
    count = 0
    for i in range(n):
        r = _root(parent, i)
        if rank[r] < 0:
            rank[r] = count
            count += 1
        labels[i] = rank[r]
    return labels


@njit
def partition_points_kernel(pts, threshold):
    """The distance partition of ``pts (N, 2)`` at ``threshold`` (m): ``partition_kernel`` on the cells
    ``floor(p sqrt(2) / threshold)``, shifted to start at 2. Returns ``(labels, ok)``; ``ok`` False
    (nothing computed) when a point is not finite or the cell keys could overflow (``distance_partition``
    then takes the whole graph)."""
    n = len(pts)
    scale = np.sqrt(2.0) / threshold
    cx = np.empty(n, dtype=np.int64)
    cy = np.empty(n, dtype=np.int64)
    for i in range(n):
        if not (np.isfinite(pts[i, 0]) and np.isfinite(pts[i, 1])):
            return np.empty(0, dtype=np.int64), False
        cx[i] = np.int64(np.floor(pts[i, 0] * scale))
        cy[i] = np.int64(np.floor(pts[i, 1] * scale))
    shift_x = cx.min() - 2
    shift_y = cy.min() - 2
    cx -= shift_x
    cy -= shift_y
    span_x = cx.max() + 4
    span_y = cy.max() + 4
    if float(span_x) * float(span_y) >= 2.0**62:
        return np.empty(0, dtype=np.int64), False
    return partition_kernel(pts, threshold, cx, cy, span_y), True


@njit(inline="always")
def _counting_order(value, within):  # pragma: no cover - compiled
    """``within`` (indices) stably reordered by ``value[within]`` (non-negative integers): a counting sort."""
    size = 0
    for i in within:
        size = max(size, value[i] + 1)
    start = np.zeros(size + 1, dtype=np.int64)
    for i in within:
        start[value[i] + 1] += 1
    for k in range(size):
        start[k + 1] += start[k]
    order = np.empty(len(within), dtype=np.int64)
    for i in within:
        order[start[value[i]]] = i
        start[value[i]] += 1
    return order


@njit(inline="always")
def _cell_order(cx, cy):  # pragma: no cover - compiled
    """Point indices ordered by cell: by ``cx``, then ``cy`` (non-negative cells; the order of the points
    of one cell is any). Two counting sorts (by ``cy``, then stably by ``cx``); with more rows and
    columns than ``4 n + 1024``, ``numpy.argsort`` of the keys (a merge sort: the one sort routine the
    kernels compile for integer keys)."""
    n = len(cx)
    if n == 0:
        return np.empty(0, dtype=np.int64)
    if cx.max() + cy.max() + 2 > 4 * n + 1024:
        return np.argsort(cx * (cy.max() + 1) + cy, kind="mergesort")
    return _counting_order(cx, _counting_order(cy, np.arange(n)))


@njit(inline="always")
def partition_kernel(pts, threshold, cx, cy, span_y):
    """Component label per point; ``cx``, ``cy`` the points' cells (side ``threshold / sqrt(2)``)
    shifted to start at 2 and ``span_y`` the number of cell rows plus 4 (the keys ``cx * span_y + cy`` of
    every cell and of its neighbours two cells away are then distinct and non-negative)."""
    n = len(pts)
    key = cx * span_y + cy
    order = _cell_order(cx, cy)
    sorted_key = key[order]
    parent = np.arange(n)
    # the cells: unique keys with the range of their points in ``order``
    cell_key = np.empty(n, dtype=np.int64)
    cell_start = np.empty(n + 1, dtype=np.int64)
    cells = 0
    for j in range(n):
        if j == 0 or sorted_key[j] != sorted_key[j - 1]:
            cell_key[cells] = sorted_key[j]
            cell_start[cells] = j
            cells += 1
        else:
            _union(parent, order[j], order[cell_start[cells - 1]])  # one cell: one component
    cell_start[cells] = n
    cell_key = cell_key[:cells]
    r2 = threshold * threshold
    # the 12 neighbours' key offsets (each pair of cells once), all positive; the cells are sorted by key,
    # so the neighbour at each offset is found by a pointer that only moves forward
    offsets = np.empty(12, dtype=np.int64)
    m = 0
    for dx in range(0, 3):
        for dy in range(-2, 3):
            if dx == 0 and dy <= 0:
                continue
            offsets[m] = dx * span_y + dy
            m += 1
    pointer = np.zeros(12, dtype=np.int64)
    for a in range(cells):
        pa = order[cell_start[a]]
        ka = cell_key[a]
        for m in range(12):
            target = ka + offsets[m]
            b = pointer[m]
            while b < cells and cell_key[b] < target:
                b += 1
            pointer[m] = b
            if b >= cells or cell_key[b] != target:
                continue
            pb = order[cell_start[b]]
            if _root(parent, pa) == _root(parent, pb):
                continue
            joined = False
            for u in range(cell_start[a], cell_start[a + 1]):
                i = order[u]
                for w in range(cell_start[b], cell_start[b + 1]):
                    q = order[w]
                    ddx = pts[q, 0] - pts[i, 0]
                    ddy = pts[q, 1] - pts[i, 1]
                    if ddx * ddx + ddy * ddy <= r2:
                        _union(parent, pa, pb)
                        joined = True
                        break
                if joined:
                    break
    return _labels_in_order(parent)


@njit
def ray_links_kernel(pts, labels, max_step, inv_sin, max_gap):  # pragma: no cover - compiled
    """``ray_partition``'s joins on top of the component ``labels`` of ``pts (N, 2)`` (E, finite): the
    points sorted by bearing, each with the next (and the last with the first, across -pi / pi) joined
    when their bearings differ by at most ``max_step`` (rad) and their distance is at most
    ``min(max_gap, min(r) dtheta inv_sin)`` (m). Returns the labels of the joined components, in order of
    each one's first point."""
    n = len(pts)
    bearing = np.empty(n)
    rng = np.empty(n)
    for i in range(n):
        bearing[i] = np.arctan2(pts[i, 1], pts[i, 0])
        rng[i] = np.hypot(pts[i, 0], pts[i, 1])
    order = np.argsort(bearing, kind="mergesort")
    first = np.full(labels.max() + 1, -1, dtype=np.int64)
    parent = np.arange(n)
    for i in range(n):
        if first[labels[i]] < 0:
            first[labels[i]] = i
        else:
            _union(parent, i, first[labels[i]])
    for j in range(n):
        a = order[j]
        b = order[j + 1] if j + 1 < n else order[0]
        if a == b:
            continue
        step = bearing[b] - bearing[a]
        if j + 1 == n:
            step += 2.0 * np.pi  # the last bearing and the first, across -pi / pi
        if not step <= max_step:
            continue
        dx = pts[b, 0] - pts[a, 0]
        dy = pts[b, 1] - pts[a, 1]
        reach = min(max_gap, min(rng[a], rng[b]) * step * inv_sin)
        if dx * dx + dy * dy <= reach * reach:
            _union(parent, a, b)
    return _labels_in_order(parent)


@njit
def radar_association_kernel(points, offsets, radar, gate):
    """``tracker.clustering.associate_radar`` for clusters ``points[offsets[k]:offsets[k + 1]]``
    (``associate_ranges``)."""
    return associate_ranges(points, offsets[:-1], offsets[1:], radar, gate)


@njit(inline="always")
def associate_ranges(points, lo, hi, radar, gate):
    """``tracker.clustering.associate_radar`` for clusters ``points[lo[k]:hi[k]]``: the distance of a
    detection to a cluster is that to its nearest point; gated pairs are taken greedily in increasing
    distance (ties in row-major order, as a stable sort of the flattened matrix), each cluster and each
    detection at most once. Returns the detection index per cluster, or -1. A pair whose detection lies
    beyond the gate from the cluster's bounding box keeps an infinite distance (it can never be taken);
    only the pairs within the gate are sorted."""
    count = len(lo)
    n_radar = len(radar)
    dist = np.full(count * n_radar, np.inf)
    reach = gate * gate * (1.0 + 1e-9)  # beyond it a pair is never taken: its distance is not needed
    for k in range(count):
        lo_x = hi_x = points[lo[k], 0] if hi[k] > lo[k] else 0.0
        lo_y = hi_y = points[lo[k], 1] if hi[k] > lo[k] else 0.0
        for i in range(lo[k], hi[k]):
            lo_x, hi_x = min(lo_x, points[i, 0]), max(hi_x, points[i, 0])
            lo_y, hi_y = min(lo_y, points[i, 1]), max(hi_y, points[i, 1])
        for r in range(n_radar):
            bx = max(lo_x - radar[r, 0], 0.0, radar[r, 0] - hi_x)  # to the cluster's bounding box
            by = max(lo_y - radar[r, 1], 0.0, radar[r, 1] - hi_y)
            if bx * bx + by * by > reach:
                continue  # every point is farther than the gate: the distance stays inf
            best = np.inf  # the nearest point's squared distance, then its root (sqrt is monotonic)
            for i in range(lo[k], hi[k]):
                dx = points[i, 0] - radar[r, 0]
                dy = points[i, 1] - radar[r, 1]
                d2 = dx * dx + dy * dy
                if d2 < best:
                    best = d2
            dist[k * n_radar + r] = np.sqrt(best)
    # the gated pairs in row-major order, then stably by distance: the prefix of a stable sort of all
    # pairs that the greedy pass reads (it stops at the first distance beyond the gate)
    gated = 0
    for f in range(count * n_radar):
        if dist[f] <= gate:
            gated += 1
    flat = np.empty(gated, dtype=np.int64)
    gated = 0
    for f in range(count * n_radar):
        if dist[f] <= gate:
            flat[gated] = f
            gated += 1
    order = flat[np.argsort(dist[flat], kind="mergesort")]
    out = np.full(count, -1, dtype=np.int64)
    used = np.zeros(n_radar, dtype=np.bool_)
    for f in order:
        k = f // n_radar
        r = f % n_radar
        if out[k] < 0 and not used[r]:
            out[k] = r
            used[r] = True
    return out


@njit
def cluster_radar_kernel(points, lo, hi, t_radar, x, y, vx, vy, t, gate):  # pragma: no cover - compiled
    """``tracker.clustering.cluster_radar`` for clusters ``points[lo[k]:hi[k]]`` and the detections'
    fields (``RadarDetections``): each detection moved to ``t`` (``x + vx (t - t_radar)``, as
    ``RadarDetections.positions_at``), then ``associate_ranges``. Returns the detection per cluster (or
    -1), the detections' velocities ``(R, 2)`` and the indices of the detections that joined no cluster."""
    n_radar = len(t_radar)
    radar = np.empty((n_radar, 2))
    velocity = np.empty((n_radar, 2))
    for r in range(n_radar):
        lag = t - t_radar[r]
        radar[r, 0] = x[r] + vx[r] * lag
        radar[r, 1] = y[r] + vy[r] * lag
        velocity[r, 0] = vx[r]
        velocity[r, 1] = vy[r]
    index = associate_ranges(points, lo, hi, radar, gate)
    used = np.zeros(n_radar, dtype=np.bool_)
    for k in range(len(index)):
        if index[k] >= 0:
            used[index[k]] = True
    free = np.empty(n_radar - used.sum(), dtype=np.int64)
    m = 0
    for r in range(n_radar):
        if not used[r]:
            free[m] = r
            m += 1
    return index, velocity, free


@njit
def points_in_rectangles_kernel(pts, ctr, c, s, half_l, half_w):
    """``tracker.clustering.points_in_rectangles``: per point the rectangle (widened: ``half_l``,
    ``half_w`` include the margin) whose normalised score ``max(|u|, |v|)`` is smallest, if <= 1."""
    n = len(pts)
    m = len(ctr)
    out = np.full(n, -1, dtype=np.int64)
    # beyond a widened rectangle's circumscribed circle (with a margin far above rounding) the score
    # exceeds 1: that rectangle cannot be the point's, so its score is not needed
    reach = np.empty(m)
    for k in range(m):
        reach[k] = (half_l[k] * half_l[k] + half_w[k] * half_w[k]) * (1.0 + 1e-9)
    for i in range(n):
        best = np.inf
        arg = 0
        for k in range(m):
            dx = pts[i, 0] - ctr[k, 0]
            dy = pts[i, 1] - ctr[k, 1]
            if dx * dx + dy * dy > reach[k]:
                continue
            u = abs((dx * c[k] + dy * s[k]) / half_l[k])
            v = abs((-dx * s[k] + dy * c[k]) / half_w[k])
            score = max(u, v)
            if score < best:
                best = score
                arg = k
        if best <= 1.0:
            out[i] = arg
    return out


@njit
def overlap_groups_kernel(corners, c, s, depth):
    """Group per rectangle: two rectangles that overlap by more than ``min(depth_i, depth_j)`` (m; ``depth``
    (T,) per rectangle) on each of their own four axes (``(c, s)`` and ``(-s, c)`` of each, ``c``, ``s``
    the cosine and sine of its heading: the separating-axis test, a smaller overlap of the projections
    counting as separated) are one group; groups numbered in order of their first rectangle
    (``tracker.tracker._duplicate_groups``)."""
    t = len(corners)
    parent = np.arange(t)
    for i in range(t):
        for j in range(i + 1, t):
            tol = min(depth[i], depth[j])
            separated = False
            for owner in (i, j):
                for turn in range(2):
                    ax = c[owner] if turn == 0 else -s[owner]
                    ay = s[owner] if turn == 0 else c[owner]
                    lo_i = np.inf
                    hi_i = -np.inf
                    lo_j = np.inf
                    hi_j = -np.inf
                    for k in range(4):
                        pi_ = corners[i, k, 0] * ax + corners[i, k, 1] * ay
                        pj = corners[j, k, 0] * ax + corners[j, k, 1] * ay
                        lo_i = min(lo_i, pi_)
                        hi_i = max(hi_i, pi_)
                        lo_j = min(lo_j, pj)
                        hi_j = max(hi_j, pj)
                    if hi_i - lo_j < tol or hi_j - lo_i < tol:
                        separated = True
            if not separated:
                _union(parent, i, j)
    return _labels_in_order(parent)


@njit(inline="always")
def _grouped(key):  # pragma: no cover - compiled
    """A stable counting sort of the non-negative integer ``key``: the point indices ordered by key
    (ties by index, as ``numpy.argsort(key, kind="stable")``) and the edges ``(G + 1,)`` of the runs of
    equal keys in that order."""
    count = len(key)
    size = key.max() + 1 if count else 0
    start = np.zeros(size + 1, dtype=np.int64)
    for i in range(count):
        start[key[i] + 1] += 1
    groups = 0
    for k in range(size):
        if start[k + 1] > 0:
            groups += 1
        start[k + 1] += start[k]
    edges = np.empty(groups + 1, dtype=np.int64)
    g = 0
    for k in range(size):
        if start[k + 1] > start[k]:
            edges[g] = start[k]
            g += 1
    edges[groups] = count
    order = np.empty(count, dtype=np.int64)
    for i in range(count):
        order[start[key[i]]] = i
        start[key[i]] += 1
    return order, edges


@njit(inline="always")
def track_owners_kernel(pts, ctr, c, s, length, width, margin, margin_across, corners, depth, labels, track_labels, threshold,
                        component, max_points):  # pragma: no cover - compiled
    """The first half of the tracker's grouping of a frame's points: per point the track group owning
    it (``points_in_rectangles_kernel`` for the rectangles at ``ctr`` with ``c``, ``s`` the cosine and
    sine of their headings, widened by ``margin`` along and ``margin_across`` across: half extents
    ``0.5 length + margin`` and ``0.5 width + margin_across``; mapped to the
    rectangles' groups, ``overlap_groups_kernel`` of their ``corners`` at ``depth`` (T,); a point outside every rectangle
    then joins the group owning most points of its connected component, the first such group on a
    tie), whether it lay inside a rectangle, its connected component (``component`` where the caller
    has them, ``(N,)``; else, empty, ``partition_points_kernel`` at ``threshold``), per mixture component
    the group of the first track carrying its label (``labels`` against ``track_labels``; -1), and
    whether some component of at most ``max_points`` points is wholly free (``fragment_owners`` has
    work; -1: never). Returns ``(ok, groups, owner, inside, component, component_group, fragments)``;
    ``ok`` False when the partition's grid does not hold the points (the caller then passes the
    components of ``distance_partition``)."""
    count = len(pts)
    owner = np.full(count, -1, dtype=np.int64)
    inside = np.zeros(count, dtype=np.bool_)
    component_group = np.full(len(labels), -1, dtype=np.int64)
    groups = overlap_groups_kernel(corners, c, s, depth) if len(ctr) > 1 else np.zeros(len(ctr), dtype=np.int64)
    if len(component) != count:
        component, ok = partition_points_kernel(pts, threshold)
        if not ok:
            return False, groups, owner, inside, owner, component_group, False
    for c_ in range(len(labels)):
        for t in range(len(track_labels)):
            if labels[c_] == track_labels[t]:
                component_group[c_] = groups[t]
                break
    if len(ctr):
        half_l = np.empty(len(ctr))
        half_w = np.empty(len(ctr))
        for k in range(len(ctr)):
            half_l[k] = 0.5 * length[k] + margin
            half_w[k] = 0.5 * width[k] + margin_across
        box = points_in_rectangles_kernel(pts, ctr, c, s, half_l, half_w)
        for i in range(count):
            if box[i] >= 0:
                owner[i] = groups[box[i]]
                inside[i] = True
    n_comp = component.max() + 1 if count else 0
    owned = 0
    n_own = 0
    for i in range(count):
        if owner[i] >= 0:
            owned += 1
            n_own = max(n_own, owner[i] + 1)
    if owned > 0 and owned < count:  # strays join their component's majority group
        votes = np.zeros((n_comp, n_own), dtype=np.int64)
        for i in range(count):
            if owner[i] >= 0:
                votes[component[i], owner[i]] += 1
        majority = np.full(n_comp, -1, dtype=np.int64)
        for k in range(n_comp):
            best = 0
            for g in range(n_own):
                if votes[k, g] > best:
                    best = votes[k, g]
                    majority[k] = g
        for i in range(count):
            if owner[i] < 0:
                owner[i] = majority[component[i]]
    fragments = False
    if max_points >= 0 and owned < count:
        size = np.zeros(n_comp, dtype=np.int64)
        taken = np.zeros(n_comp, dtype=np.bool_)
        for i in range(count):
            size[component[i]] += 1
            if owner[i] >= 0:
                taken[component[i]] = True
        for k in range(n_comp):
            if size[k] <= max_points and not taken[k]:
                fragments = True
                break
    return True, groups, owner, inside, component, component_group, fragments


@njit(inline="always")
def _split_keys(key, owner, inside, n, width, gap, max_cuts):  # pragma: no cover - compiled
    """The cuts across the road, on ``key`` and ``owner`` in place: a cluster (run of equal keys) whose
    lateral offsets ``n`` (m) span more than ``width`` is cut at its largest gap between consecutive
    offsets (the first point after it, in ``n`` order; ties by index) if that gap is at least ``gap``;
    parts still wider are cut again, for up to ``max_cuts`` rounds. The parts of a cut cluster take
    the keys ``max(key) + 1 + part`` (parts numbered by cluster, then ``n``), and of a track's cluster
    only the parts with most points ``inside`` (plus 1e-6 per point: ties to the larger part) stay
    owned. A cluster with a NaN offset has no span and is never cut; a NaN gap (two infinite offsets)
    is no part's largest. Returns the number of parts added."""
    order, edges = _grouped(key)
    clusters = len(edges) - 1
    wide = np.zeros(clusters, dtype=np.bool_)
    total = 0
    for g in range(clusters):
        lo = hi = n[order[edges[g]]]
        unknown = False
        for j in range(edges[g], edges[g + 1]):
            v = n[order[j]]
            unknown |= v != v
            lo = min(lo, v)
            hi = max(hi, v)
        wide[g] = not unknown and hi - lo > width
        if wide[g]:
            total += edges[g + 1] - edges[g]
    if total == 0:
        return 0
    # the candidates, by cluster then n (ties by index): src (point index), ns (offset), ps (part)
    src = np.empty(total, dtype=np.int64)
    ns = np.empty(total)
    ps = np.empty(total, dtype=np.int64)
    cluster_of = np.empty(total, dtype=np.int64)  # the original cluster (run index) of each candidate
    m = 0
    rank = 0
    for g in range(clusters):
        if not wide[g]:
            continue
        idx = order[edges[g]:edges[g + 1]]
        sub = n[idx]
        within = np.argsort(sub, kind="mergesort")
        for j in range(len(idx)):
            src[m] = idx[within[j]]
            ns[m] = sub[within[j]]
            ps[m] = rank
            cluster_of[m] = g
            m += 1
        rank += 1
    first = np.empty(total, dtype=np.bool_)
    cut = np.empty(total, dtype=np.bool_)
    for _ in range(max_cuts):
        for j in range(total):
            first[j] = j == 0 or ps[j] != ps[j - 1]
            cut[j] = False
        any_cut = False
        a = 0
        while a < total:
            b = a + 1
            while b < total and not first[b]:
                b += 1
            if ns[b - 1] - ns[a] > width:
                largest = -np.inf
                for j in range(a + 1, b):
                    step = ns[j] - ns[j - 1]
                    if not step <= largest:  # a larger gap, or NaN: then no gap equals the largest
                        largest = step
                        if step != step:
                            break
                for j in range(a + 1, b):
                    step = ns[j] - ns[j - 1]
                    if step == largest and step >= gap:
                        cut[j] = True
                        any_cut = True
                        break
            a = b
        if not any_cut:
            break
        part = -1
        for j in range(total):
            if first[j] or cut[j]:
                part += 1
            ps[j] = part
    # clusters in more than one part are cut; the others keep their key and owner
    top = key.max()
    added = 0
    a = 0
    while a < total:
        b = a + 1
        while b < total and cluster_of[b] == cluster_of[a]:
            b += 1
        pieces = ps[b - 1] - ps[a] + 1
        if pieces > 1:
            added += pieces - 1
            g_owner = owner[src[a]]
            if g_owner >= 0:  # the part(s) with most points inside the rectangle stay owned
                votes = np.zeros(pieces)
                points = np.zeros(pieces, dtype=np.int64)
                for j in range(a, b):
                    if inside[src[j]]:
                        votes[ps[j] - ps[a]] += 1.0
                    points[ps[j] - ps[a]] += 1
                best = -1.0
                for p in range(pieces):
                    votes[p] = votes[p] + 1e-6 * points[p]
                    best = max(best, votes[p])
                for j in range(a, b):
                    if not votes[ps[j] - ps[a]] >= best:
                        owner[src[j]] = -1
            for j in range(a, b):
                key[src[j]] = top + 1 + ps[j]
        a = b
    return added


@njit
def ordered_clusters_kernel(pts, owner, inside, component, n_tracks, n, split, width, gap,
                            max_cuts):  # pragma: no cover - compiled
    """The second half of the tracker's grouping of a frame's points: the key of each point (its
    owner group, else ``n_tracks`` plus its connected component), with ``split`` the clusters cut
    across the road (``_split_keys``), then the points ordered by key (ties by index): returns the
    ordered points, the clusters' edges ``(K + 1,)`` in them, each cluster's owner group (or -1) and
    the number of parts the cuts added."""
    count = len(pts)
    key = np.empty(count, dtype=np.int64)
    owner = owner.copy()
    for i in range(count):
        key[i] = owner[i] if owner[i] >= 0 else n_tracks + component[i]
    added = _split_keys(key, owner, inside, n, width, gap, max_cuts) if split else 0
    order, edges = _grouped(key)
    ordered = np.empty((count, 2))
    for j in range(count):
        ordered[j, 0] = pts[order[j], 0]
        ordered[j, 1] = pts[order[j], 1]
    owned = np.empty(len(edges) - 1, dtype=np.int64)
    for g in range(len(owned)):
        owned[g] = owner[order[edges[g]]]
    return ordered, edges, owned, added


@njit
def cluster_points_kernel(pts, ctr, c, s, length, width, margin, margin_across, corners, depth, labels, track_labels, threshold,
                          component, n, max_points, split, split_width, gap, max_cuts):  # pragma: no cover - compiled
    """The tracker's grouping of a frame's points into clusters: ``track_owners_kernel`` then, unless a
    fragment needs ``fragment_owners`` (in Python, in between) or the partition's grid did not hold
    the points, ``ordered_clusters_kernel``: returns ``(ok, done, groups, owner, inside, component,
    component_group, ordered, edges, owned, added)`` (``done`` False: the last four are empty and the
    caller finishes the grouping)."""
    ok, groups, owner, inside, component, component_group, fragments = track_owners_kernel(
        pts, ctr, c, s, length, width, margin, margin_across, corners, depth, labels, track_labels, threshold, component,
        max_points)
    if not ok or fragments:
        return (ok, False, groups, owner, inside, component, component_group, np.empty((0, 2)),
                np.zeros(1, dtype=np.int64), np.empty(0, dtype=np.int64), 0)
    ordered, edges, owned, added = ordered_clusters_kernel(pts, owner, inside, component, len(track_labels), n, split,
                                                           split_width, gap, max_cuts)
    return ok, True, groups, owner, inside, component, component_group, ordered, edges, owned, added


@njit(inline="always")
def bearing_sorted_scan(scan):  # pragma: no cover - compiled
    """The returns of ``scan (R, 2)`` sorted by bearing from the E origin: their bearings (rad, (-pi, pi]),
    ranges (m) and coordinates, for the ends' searches in a bearing window (``occluded_ends_kernel``,
    ``continued_ends_kernel``)."""
    count = len(scan)
    bearing = np.empty(count)
    for j in range(count):
        bearing[j] = np.arctan2(scan[j, 1], scan[j, 0])
    order = np.argsort(bearing, kind="mergesort")  # any order of equal bearings serves the searches
    b = bearing[order]
    r = np.empty(count)
    xy = np.empty((count, 2))
    for i in range(count):
        xy[i, 0] = scan[order[i], 0]
        xy[i, 1] = scan[order[i], 1]
        r[i] = np.hypot(xy[i, 0], xy[i, 1])
    return b, r, xy


@njit(inline="always")
def _window(b, lo, hi):  # pragma: no cover - compiled
    """Index ranges of the sorted bearings ``b`` in ``[lo, hi]`` read modulo 2 pi (``lo`` may be below
    -pi, ``hi`` above pi): up to three ``(start, stop)`` pairs (empty ones ``(0, 0)``)."""
    two_pi = 2.0 * np.pi
    if hi - lo >= two_pi:
        return (0, len(b)), (0, 0), (0, 0)
    main = (np.searchsorted(b, lo), np.searchsorted(b, hi, side="right"))
    below = (0, 0)
    above = (0, 0)
    if lo < -np.pi:
        below = (np.searchsorted(b, lo + two_pi), len(b))
    if hi > np.pi:
        above = (0, np.searchsorted(b, hi - two_pi, side="right"))
    return main, below, above


#: Padding (rad) of the bearing windows the ends' searches look in (far above the rounding of a bearing).
WINDOW_PAD = 1e-6


@njit
def occluded_ends_kernel(ends, scan, window, margin, max_range, range_margin):  # pragma: no cover - compiled
    """``tracker.clustering.occluded_ends`` for ``ends (K, 2, 2)``: whether a nearer return of ``scan``
    lies within ``window`` beyond each end, or the end lies within ``range_margin`` of ``max_range``."""
    if len(ends) == 0 or len(scan) == 0:
        return np.zeros((len(ends), 2), dtype=np.bool_)
    b, r, _ = bearing_sorted_scan(scan)
    return occluded_ends_sorted(ends, b, r, window, margin, max_range, range_margin)


@njit(inline="always")
def occluded_ends_sorted(ends, b, r, window, margin, max_range, range_margin):  # pragma: no cover - compiled
    """``occluded_ends_kernel`` with the scan sorted by bearing (``bearing_sorted_scan``): per end only
    the returns within ``window`` of its bearing (padded) are tested, with the same test; an end is
    occluded when any return passes it, whatever the order they are visited in."""
    count = len(ends)
    out = np.zeros((count, 2), dtype=np.bool_)
    two_pi = 2.0 * np.pi
    for k in range(count):
        for e in range(2):
            bearing = np.arctan2(ends[k, e, 1], ends[k, e, 0])
            reach = np.hypot(ends[k, e, 0], ends[k, e, 1])
            if reach >= max_range - range_margin:
                out[k, e] = True
                continue
            lo = bearing - window - WINDOW_PAD if e == 0 else bearing - WINDOW_PAD
            hi = bearing + WINDOW_PAD if e == 0 else bearing + window + WINDOW_PAD
            for start, stop in _window(b, lo, hi):
                for i in range(start, stop):
                    if not r[i] < reach - margin:
                        continue
                    d = b[i] - bearing
                    d = d - two_pi * np.round(d / two_pi)
                    if e == 0:
                        d = -d
                    if d > 0.0 and d <= window:
                        out[k, e] = True
                        break
                if out[k, e]:
                    break
    return out


@njit
def continued_ends_kernel(ends, outward, start, reach, scan, offset):  # pragma: no cover - compiled
    """``tracker.clustering.continued_ends`` for ``ends``, ``outward (K, 2, 2)``, ``start``, ``reach (K, 2)``
    (m): whether a return of ``scan`` lies beyond each end along its line, past ``start`` and within
    ``reach``, and within ``offset`` of the line."""
    if len(ends) == 0 or len(scan) == 0:
        return np.zeros((len(ends), 2), dtype=np.bool_)
    b, _, xy = bearing_sorted_scan(scan)
    return continued_ends_sorted(ends, outward, start, reach, b, xy, offset)


@njit(inline="always")
def continued_ends_sorted(ends, outward, start, reach, b, xy, offset):  # pragma: no cover - compiled
    """``continued_ends_kernel`` with the scan sorted by bearing (``bearing_sorted_scan``): a return that
    passes an end's test lies within ``sqrt(reach^2 + offset^2)`` of the end, so within that disc's
    bearing window seen from the lidar (padded; the whole scan where the disc holds the lidar); only
    those are tested, with the same test."""
    count = len(ends)
    out = np.zeros((count, 2), dtype=np.bool_)
    for k in range(count):
        for e in range(2):
            ex = ends[k, e, 0]
            ey = ends[k, e, 1]
            radius = np.sqrt(reach[k, e] * reach[k, e] + offset * offset) * (1.0 + 1e-9)
            distance = np.hypot(ex, ey)
            bearing = np.arctan2(ey, ex)
            if distance > radius:
                spread = np.arcsin(min(radius / distance, 1.0)) + WINDOW_PAD
                ranges = _window(b, bearing - spread, bearing + spread)
            else:
                ranges = ((0, len(b)), (0, 0), (0, 0))
            for first, stop in ranges:
                for i in range(first, stop):
                    dx = xy[i, 0] - ex
                    dy = xy[i, 1] - ey
                    along = dx * outward[k, e, 0] + dy * outward[k, e, 1]
                    if along > start[k, e] and along <= reach[k, e]:
                        if abs(dx * outward[k, e, 1] - dy * outward[k, e, 0]) <= offset:
                            out[k, e] = True
                            break
                if out[k, e]:
                    break
    return out


@njit
def nearest_in_bins_kernel(pts, bin_width, count, wrap):  # pragma: no cover - compiled
    """The nearest of the points ``pts (N, 2)`` (seen from the origin) in each bearing bin ``floor(bearing
    / bin_width + 1/2)``, taken modulo ``count`` when ``wrap``: the indices of the occupied bins' nearest
    points (the first by index among equal ranges) in ascending bin order, and every point's bearing
    (rad). One pass over the points and one over the bins."""
    size = pts.shape[0]
    lo = np.int64(0) if wrap else np.int64(np.floor(-np.pi / bin_width + 0.5))
    bins = np.int64(count) if wrap else np.int64(np.floor(np.pi / bin_width + 0.5)) - lo + 1
    best = np.full(bins, -1, dtype=np.int64)
    best_r = np.full(bins, np.inf)
    bearing = np.empty(size)
    for i in range(size):
        bearing[i] = np.arctan2(pts[i, 1], pts[i, 0])
        r = np.hypot(pts[i, 0], pts[i, 1])
        b = np.int64(np.floor(bearing[i] / bin_width + 0.5))
        k = b % count if wrap else b - lo
        if r < best_r[k]:
            best_r[k] = r
            best[k] = i
    kept = 0
    for k in range(bins):
        if best[k] >= 0:
            best[kept] = best[k]
            kept += 1
    return best[:kept].copy(), bearing


@njit
def bearing_filter_kernel(pts, bin_width, count, wrap):  # pragma: no cover - compiled
    """``tracker.preprocess.bearing_filter``: indices of the closest point of each bearing bin (the
    first by index among equal ranges), in increasing bearing order (ties by bin). Bins ``floor(bearing
    / bin_width + 1/2)``, taken modulo ``count`` when ``wrap`` (``nearest_in_bins_kernel``)."""
    kept, bearing = nearest_in_bins_kernel(pts, bin_width, count, wrap)
    return kept[np.argsort(bearing[kept], kind="mergesort")]


@njit(inline="always")
def _ray_gap(points, i, k, c, s, step):  # pragma: no cover - compiled
    """The spacing of a scan's returns (bearing step ``step``, rad) at point ``k`` along a side through
    it: ``r^2 step / d`` with ``r`` its range and ``d`` the line's distance from the sensor; the line
    runs from point ``i`` to ``k`` (of ``points``), or along ``(c, s)`` where they coincide. 0 where
    the line is across the heading ``(c, s)`` by more than 45 deg (no side along it)."""
    x = points[k, 0]
    y = points[k, 1]
    ux = x - points[i, 0]
    uy = y - points[i, 1]
    norm = math.sqrt(ux * ux + uy * uy)
    if norm > 0.0:
        ux /= norm
        uy /= norm
        if abs(ux * c + uy * s) < SQRT_HALF:
            return 0.0
    else:
        ux = c
        uy = s
    d = abs(x * uy - y * ux)
    return (x * x + y * y) * step / d if d > 0.0 else np.inf


#: cos 45 deg.
SQRT_HALF = math.sqrt(0.5)


@njit
def along_cuts_kernel(ordered, edges, owned, ctr, c, s, half_l, half_w, scan, step, rays, min_gap, margin,
                      min_part):  # pragma: no cover - compiled
    """The cuts along a track's length (``tracker.Tracker._grouped_points``): per cluster a track group
    owns (``owned[k] >= 0``; ``ordered`` the points in cluster order, ``edges (K + 1,)``), its points
    sorted by their offset ``t`` along the group's heading (cosine ``c[g]``, sine ``s[g]``, centre
    ``ctr[g]``) are cut between two consecutive points whose gap in ``t`` is a hole a solid side cannot
    have:

    - at least ``min_gap`` (m), and at least ``rays`` ray gaps ``r^2 step / d`` at either point (range
      ``r``, lidar bearing step ``step`` in rad, distance ``d`` of the line along the heading through the
      point from the sensor: the spacing of a scan's returns along such a side);
    - no return of ``scan`` in the bearings strictly between the two points lies nearer than the nearer
      of them less ``margin`` (then the gap is another object's shadow on one side, not a hole), or
      within the gap along the heading, more than ``min_gap / 2`` from both points (the side goes on
      there in returns another cluster holds, or that the road filter dropped);
    - both parts hold at least ``min_part`` points (a lone far return is more likely the end of a side
      seen at a grazing angle, whose ray gap the heading's error hides, than a vehicle of its own).

    Of a cut cluster the part with most points inside the group's rectangle (half extents ``half_l``,
    ``half_w``; ties: the larger part, then the first) stays the group's; the other parts become
    free clusters, appended after the others. A cut is seen free space beyond the kept part: per group,
    the bounds ``(lo, hi)`` in ``t`` its vehicle cannot reach past (``+-inf`` where nothing was cut),
    half the ray gap beyond the kept part's extreme point on each cut side (where the next ray along
    a side would have found it: ``tracker.extent.bound_at_holes``). Returns ``(ordered, edges, owned,
    added, bounds (G, 2))``, the inputs themselves when nothing was cut."""
    groups = len(ctr)
    bounds = np.empty((groups, 2))
    bounds[:, 0] = -np.inf
    bounds[:, 1] = np.inf
    clusters = len(edges) - 1
    count = len(ordered)
    part = np.zeros(count, dtype=np.int64)  # per point, its part within its cluster
    parts = np.ones(clusters, dtype=np.int64)
    keep = np.zeros(clusters, dtype=np.int64)  # the part that stays owned
    sorted_scan = False
    b = np.empty(0)
    r = np.empty(0)
    xy = np.empty((0, 2))
    added = 0
    for k in range(clusters):
        g = owned[k]
        lo = edges[k]
        hi = edges[k + 1]
        if g < 0 or hi - lo < 2 * min_part:
            continue
        n = hi - lo
        t = np.empty(n)
        for j in range(n):
            t[j] = (ordered[lo + j, 0] - ctr[g, 0]) * c[g] + (ordered[lo + j, 1] - ctr[g, 1]) * s[g]
        order = np.argsort(t, kind="mergesort")
        cuts = 0
        last = 0  # the first point of the current part
        for j in range(min_part, n - min_part + 1):
            if j - last < min_part:
                continue
            a = lo + order[j - 1]
            z = lo + order[j]
            gap = t[order[j]] - t[order[j - 1]]
            if not gap >= min_gap:
                continue
            # the ray gap at either point along the heading, and along the line through it and its
            # neighbour on its own side of the gap (the side's own direction, where the heading errs)
            spacing = max(_ray_gap(ordered, a, a, c[g], s[g], step), _ray_gap(ordered, z, z, c[g], s[g], step))
            if j >= 2:
                spacing = max(spacing, _ray_gap(ordered, lo + order[j - 2], a, c[g], s[g], step))
            if j + 1 < n:
                spacing = max(spacing, _ray_gap(ordered, lo + order[j + 1], z, c[g], s[g], step))
            if not gap >= rays * spacing:
                continue
            if not sorted_scan:
                b, r, xy = bearing_sorted_scan(scan)
                sorted_scan = True
            ba = np.arctan2(ordered[a, 1], ordered[a, 0])
            bz = np.arctan2(ordered[z, 1], ordered[z, 0])
            d = bz - ba
            d = d - 2.0 * np.pi * np.round(d / (2.0 * np.pi))
            first = ba if d >= 0.0 else bz
            width = abs(d)
            nearer = min(np.hypot(ordered[a, 0], ordered[a, 1]), np.hypot(ordered[z, 0], ordered[z, 1])) - margin
            shadow = False
            inner_lo = t[order[j - 1]] + 0.5 * min_gap
            inner_hi = t[order[j]] - 0.5 * min_gap
            for start, stop in _window(b, first + WINDOW_PAD, first + width - WINDOW_PAD):
                for i in range(start, stop):
                    if r[i] < nearer:
                        shadow = True
                        break
                    ti = (xy[i, 0] - ctr[g, 0]) * c[g] + (xy[i, 1] - ctr[g, 1]) * s[g]
                    if ti > inner_lo and ti < inner_hi:  # the gap holds a return of another cluster
                        shadow = True
                        break
                if shadow:
                    break
            if shadow:
                continue
            cuts += 1
            last = j
            for i in range(j, n):
                part[lo + order[i]] += 1
        if cuts == 0:
            continue
        parts[k] = cuts + 1
        added += cuts
        inside = np.zeros(cuts + 1, dtype=np.int64)
        size = np.zeros(cuts + 1, dtype=np.int64)
        for i in range(lo, hi):
            dx = ordered[i, 0] - ctr[g, 0]
            dy = ordered[i, 1] - ctr[g, 1]
            size[part[i]] += 1
            if abs(dx * c[g] + dy * s[g]) <= half_l[g] and abs(-dx * s[g] + dy * c[g]) <= half_w[g]:
                inside[part[i]] += 1
        best = 0  # most points inside; ties: the larger part, then the first (counted, not summed in floats)
        for p in range(1, cuts + 1):
            if inside[p] > inside[best] or (inside[p] == inside[best] and size[p] > size[best]):
                best = p
        keep[k] = best
        # the kept part's extreme points toward the cut-off parts bound the vehicle
        lo_t = np.inf
        hi_t = -np.inf
        lo_i = hi_i = -1
        for i in range(lo, hi):
            if part[i] == keep[k]:
                ti = (ordered[i, 0] - ctr[g, 0]) * c[g] + (ordered[i, 1] - ctr[g, 1]) * s[g]
                if ti < lo_t:
                    lo_t = ti
                    lo_i = i
                if ti > hi_t:
                    hi_t = ti
                    hi_i = i
        for side in range(2):
            if (side == 0 and keep[k] == 0) or (side == 1 and keep[k] == cuts):
                continue  # nothing was cut off on that side
            i = lo_i if side == 0 else hi_i
            half = 0.5 * _ray_gap(ordered, i, i, c[g], s[g], step)
            if side == 0:
                bounds[g, 0] = max(bounds[g, 0], lo_t - half)
            else:
                bounds[g, 1] = min(bounds[g, 1], hi_t + half)
    if added == 0:
        return ordered, edges, owned, 0, bounds
    out = np.empty((count, 2))
    new_edges = np.empty(clusters + added + 1, dtype=np.int64)
    new_owned = np.empty(clusters + added, dtype=np.int64)
    m = 0
    for k in range(clusters):  # the clusters in their order, a cut one by its kept part
        new_edges[k] = m
        new_owned[k] = owned[k]
        for i in range(edges[k], edges[k + 1]):
            if parts[k] == 1 or part[i] == keep[k]:
                out[m, 0] = ordered[i, 0]
                out[m, 1] = ordered[i, 1]
                m += 1
    q = clusters
    for k in range(clusters):  # then the cut-off parts, by cluster and part
        for p in range(parts[k]):
            if parts[k] == 1 or p == keep[k]:
                continue
            new_edges[q] = m
            new_owned[q] = -1
            for i in range(edges[k], edges[k + 1]):
                if part[i] == p:
                    out[m, 0] = ordered[i, 0]
                    out[m, 1] = ordered[i, 1]
                    m += 1
            q += 1
    new_edges[q] = m
    return out, new_edges, new_owned, added, bounds
