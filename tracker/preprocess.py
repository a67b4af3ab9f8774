"""Lidar preprocessing before clustering (the paper's "sensor data preprocessing").

Three steps, each vectorised and each reporting what it removed so nothing is lost silently
(a frame whose lidar is a 3-D cloud first goes through ``tracker.cloud``: the mount transform, RANSAC
ground removal, the height ceiling and the projection to the road plane, ``lidar_points``):

1. ``drop_nonfinite``: NaN/inf points are dropped and counted (real drivers emit them).
2. ``road_bound_mask``: points outside the road bounds widened by a margin are discarded, using the
   Road's projection (roadside clutter: guard rails, trees, parked cars).
3. ``bearing_filter``: the paper's filter keeping the closest point per bearing bin, which removes
   points seen "through" an object (returns from inside a vehicle or from behind a gap).

``filter_points`` runs steps 2 and 3 on a frame's returns in one call of the compiled kernel
``road_filter_kernel`` (this module's), or one by one where it does not apply.
"""

from __future__ import annotations

import numpy as np

from tracker.cloud import CloudConfig, CloudResult, process_cloud
from tracker.config import ClusteringConfig
from tracker.frame import EgoState, Frame
from tracker.road import Road
from tracker.transforms import to_global
from tracker.jit import njit
from tracker.clustering import bearing_filter_kernel, nearest_in_bins_kernel
from tracker.centerline import project_kernel, seed_kernel
from tracker.lanes import edge_at


def drop_nonfinite(points: np.ndarray) -> tuple[np.ndarray, int]:
    """Rows of ``points`` (N, 2) with both coordinates finite, and the number dropped."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    with np.errstate(invalid="ignore", over="ignore"):  # +inf and -inf sum to NaN; huge returns overflow
        total = pts.sum()
    if np.isfinite(total):  # the usual scan: every return finite (one reduction, no mask)
        return pts.copy(), 0
    keep = np.isfinite(pts).all(axis=1)
    return pts[keep], int(len(pts) - keep.sum())


def lidar_points(frame: Frame, cloud: CloudConfig | None = None) -> tuple[np.ndarray, dict[str, int], CloudResult | None]:
    """The frame's lidar as finite 2-D points ``(M, 2)`` in E, what was removed, and the cloud result.

    ``(N, 2)`` points are taken as they are (non-finite rows dropped and counted as
    ``points_nonfinite``); an ``(N, 3)`` cloud in the lidar's frame goes through
    ``tracker.cloud.process_cloud`` with ``cloud`` (``CloudConfig()`` by default), whose points are
    the kept returns' projections less those seen over a nearer object (``CloudResult.outline_2d``),
    and which counts ``cloud_points``, ``cloud_ego_body`` (returns from the ego's own box),
    ``cloud_ground``, ``cloud_below_ground``, ``cloud_above_ceiling``, ``cloud_low_object`` (kerbs),
    ``cloud_seen_over`` and ``cloud_segments_fallback`` (its non-finite rows are ``points_nonfinite``)."""
    if frame.lidar.shape[1] == 2:
        pts, dropped = drop_nonfinite(frame.lidar)
        return pts, {"points_nonfinite": dropped}, None
    result = process_cloud(frame.lidar, cloud)
    st = result.stats
    counts = {"points_nonfinite": st.non_finite, "cloud_points": st.points_in, "cloud_ego_body": st.ego_body,
              "cloud_ground": st.ground,
              "cloud_below_ground": st.below_ground, "cloud_above_ceiling": st.above_ceiling,
              "cloud_low_object": st.low_object, "cloud_seen_over": st.seen_over,
              "cloud_segments_fallback": st.segments_fallback}
    return result.outline_2d, counts, result


def road_bound_mask(points_g: np.ndarray, road: Road, margin: float = 0.5) -> np.ndarray:
    """Which points (N, 2) in G lie within the road bounds widened by ``margin`` metres."""
    if len(points_g) == 0:
        return np.zeros(0, dtype=bool)
    return road.on_road(points_g, margin=margin)


def bearing_filter(points_e: np.ndarray, bin_width: float = np.deg2rad(0.2)) -> np.ndarray:
    """Indices of the closest point in each bearing bin of ``bin_width`` rad (seen from the E origin),
    in increasing bearing order. ``bin_width`` should be at least the lidar's azimuth resolution.

    Bin ``k`` is centred on the bearing ``k * bin_width`` (``k = floor(bearing / bin_width + 1/2)``,
    taken modulo the bin count when ``bin_width`` divides the circle), so a lidar whose rays sit at
    multiples of its resolution puts each ray in the middle of its own bin. (Bins with edges on the
    rays, ``floor((bearing + pi) / bin_width)``, let float rounding put two neighbouring rays into one
    bin, and the filter would drop one of them.)"""
    if not bin_width > 0:
        raise ValueError(f"bin_width must be > 0 rad; got {bin_width!r}")
    pts = np.asarray(points_e, dtype=float).reshape(-1, 2)
    if len(pts) == 0:
        return np.zeros(0, dtype=int)
    count = round(2.0 * np.pi / bin_width)
    tiles = abs(count * bin_width - 2.0 * np.pi) <= 1e-9  # the bins tile the circle: -pi and pi are one bin
    return bearing_filter_kernel(np.ascontiguousarray(pts), float(bin_width), int(max(count, 1)), bool(tiles))


def nearest_per_ray(points_e: np.ndarray, resolution: float) -> np.ndarray:
    """The nearest of the returns ``points_e (N, 2)`` in E of each ray, a bearing bin of ``resolution``
    rad (``floor(bearing / resolution + 1/2)`` modulo one turn; ties to the first by index), in the
    order of the bins: the occluders of a projected 3-D cloud. The detection model and the shadow tests
    ask, per ray, whether some return lies nearer than an object; the nearest one answers it where the
    ray's returns share its bearing (a spinning lidar fires its beams together), so the other beams'
    returns of the ray (up to 128) add nothing but time. One pass (``tracker.clustering.nearest_in_bins_kernel``,
    as the bearing filter's)."""
    if not resolution > 0:
        raise ValueError(f"resolution must be > 0 rad; got {resolution!r}")
    pts = np.ascontiguousarray(np.asarray(points_e, dtype=float).reshape(-1, 2))
    if len(pts) == 0:
        return pts
    count = max(round(2.0 * np.pi / resolution), 1)
    return pts[nearest_in_bins_kernel(pts, float(resolution), count, True)[0]]


def preprocess_frame(frame: Frame, road: Road, config: ClusteringConfig,
                     cloud: CloudConfig | None = None) -> tuple[np.ndarray, np.ndarray, dict[str, int]]:
    """The three steps on one frame's lidar points (E): returns ``(scan, points, counts)`` -- every
    finite return (occluders for the detection model; of a 3-D cloud, the points left after ground
    removal and the ceiling, projected: ``lidar_points``), the points kept for clustering, and how
    many each step removed (``points_nonfinite``, ``points_off_road``, ``points_bearing_filtered``,
    and the ``cloud_*`` counts of a 3-D cloud)."""
    scan, removed, _ = lidar_points(frame, cloud)
    points, counts, _ = filter_points(scan, frame.ego, road, config)
    return scan, points, {**removed, **counts}


def filter_points(scan: np.ndarray, ego: EgoState, road: Road,
                  config: ClusteringConfig) -> tuple[np.ndarray, dict[str, int], np.ndarray]:
    """Steps 2 and 3 on finite points ``scan (N, 2)`` in E seen from ``ego``: the points kept for
    clustering, the counts ``points_off_road``, ``points_bearing_filtered``, and the kept points'
    lateral road offsets ``n`` (m), which the road-bound test computes anyway."""
    counts = {"points_off_road": 0, "points_bearing_filtered": 0}
    if len(scan) == 0:
        return scan, counts, np.zeros(0)
    # one return takes the steps one by one: Road.to_frenet's pure-Python path for one point gives other numbers
    fused = _filter_compiled(scan, ego, road, config) if len(scan) > 1 else None
    if fused is not None:
        kept, n, on_road = fused
        counts["points_off_road"] = len(scan) - on_road
        counts["points_bearing_filtered"] = on_road - len(kept)
        return scan[kept], counts, n[kept]
    s, n = road.to_frenet(to_global(scan, (ego.x, ego.y), ego.yaw))
    on_road = road.within_bounds(s, n, config.road_margin)
    counts["points_off_road"] = int((~on_road).sum())
    pts = scan[on_road]
    keep = bearing_filter(pts, config.bearing_bin)
    counts["points_bearing_filtered"] = len(pts) - len(keep)
    return pts[keep], counts, n[on_road][keep]


def _filter_compiled(scan: np.ndarray, ego: EgoState, road: Road,
                     config: ClusteringConfig) -> tuple[np.ndarray, np.ndarray, int] | None:
    """``filter_points``' steps in one call of ``road_filter_kernel`` (the same kernels in the same
    order as the steps one by one: the same numbers): the kept returns' indices into ``scan`` (bearing
    order), the returns' lateral offsets ``n`` (m; NaN for those surely off the road, not projected) and
    how many lie on the road; None where the kernel
    does not apply (no seed grid, a bearing bin <= 0, a non-finite return, a projection that did not
    converge): ``filter_points`` then takes the steps one by one (``Road.to_frenet``, whose fallbacks
    handle the projection, ``Road.within_bounds``, ``bearing_filter``). Returns off the seed grid take
    their starts from the k-d tree (``Road.seed_missing``) and a second call."""
    args = road.projection_kernel_args()
    if args is None or not config.bearing_bin > 0:
        return None
    count = round(2.0 * np.pi / config.bearing_bin)
    tiles = abs(count * config.bearing_bin - 2.0 * np.pi) <= 1e-9
    margin = config.road_margin
    head = (np.ascontiguousarray(scan, dtype=float), float(np.cos(ego.yaw)), float(np.sin(ego.yaw)), float(ego.x),
            float(ego.y))
    clearance, offgrid, extent = road.clearance_kernel_args()
    tail = (*args, not road.closed, *road.edge_kernel_args(), float(margin), float(config.bearing_bin),
            int(max(count, 1)), bool(tiles), clearance, offgrid, extent + float(margin))
    status, kept, n, on_road, pts, s, missing = road_filter_kernel(*head, np.empty(0), False, *tail)
    if status == SEED:  # returns off the seed grid: their starts from the k-d tree, as Road._project's
        if not np.isfinite(pts[missing]).all():
            return None  # a non-finite return: Road.to_frenet's error names it
        road.seed_missing(pts, s, missing)
        status, kept, n, on_road, *_ = road_filter_kernel(*head, s, True, *tail)
    return (kept, n, int(on_road)) if status == DONE else None

# --------------------------------------------------------------------------------------------------
# The compiled kernels of this stage.
#
# Steps 2 and 3 of ``filter_points`` on a frame's returns in one call (``road_filter_kernel``): the
# returns to G (``tracker.transforms.to_global``'s formula), their projection on the centerline
# (``Road.to_frenet`` without a hint: ``seed_kernel``'s start, then the lock-step Newton iterations of
# ``project_kernel``), the road-bound test (``Road.within_bounds``) and the closest return per bearing
# bin (``bearing_filter_kernel``). Where a return is off the seed grid the caller seeds it from the k-d
# tree and calls again; where Newton does not converge the caller takes the steps one by one (the
# projection's bisection).
# --------------------------------------------------------------------------------------------------


#: ``road_filter_kernel``'s status: done; some returns off the seed grid (the caller seeds them from the
#: k-d tree and calls again with the seeds); a projection did not converge (the caller takes the steps
#: one by one).
DONE, SEED, STAGED = 0, 1, 2


@njit
def road_filter_kernel(scan, cos_yaw, sin_yaw, ego_x, ego_y, seeds, seeded, grid_origin, inv_resolution, grid,
                       node_frame, nodes, kind, closed, length, ends, table, bucket_cell, starts_next, inv_bucket, hops,
                       gl_nodes, gl_weights, max_iterations, tolerance, max_step, min_denominator, check_s,
                       edge_inv_step, edge_right, edge_left, margin, bin_width, bin_count, wrap, clearance,
                       offgrid_clearance, limit):  # pragma: no cover - compiled
    """The returns ``scan (N, 2)`` in E (finite) of an ego at ``(ego_x, ego_y)`` in G whose heading has
    cosine ``cos_yaw`` and sine ``sin_yaw``: their projections ``(s, n)`` on the road (Newton from
    ``seeds (N,)`` when ``seeded``, else from the seed grid's), those within the road's edges at their ``s``
    widened by ``margin`` (m; the edge tables ``edge_right``, ``edge_left`` read by ``tracker.lanes.edge_at``)
    (and ``0 <= s <= length`` when ``check_s``: an open road), and of those the closest per bearing bin.
    Returns whose clearance from the centerline (the seed grid's per-cell lower bound ``clearance``, or
    ``offgrid_clearance`` off it: ``Road.clearance_kernel_args``) exceeds ``limit`` (the largest ``|n|``
    of an edge plus ``margin``) lie off the road and are not projected (their ``lateral`` is NaN).
    Returns ``(status, kept, lateral, on_road_count, points, starts, missing)``: ``kept`` indices into
    ``scan`` in increasing bearing order (``bearing_filter_kernel`` of the on-road returns), the lateral
    offsets ``n (N,)`` of every return (NaN for those not projected). ``status`` ``SEED``: some returns
    are off the seed grid (``missing``) yet not surely off the road; ``points`` (G) and ``starts`` are
    then the caller's to complete. ``STAGED``: a projection did not converge. Neither leaves ``kept``
    or ``lateral`` valid."""
    count = scan.shape[0]
    pts = np.empty((count, 2))
    near = np.empty(count, dtype=np.int64)  # the returns within reach of the road, in order
    m = 0
    rows, cols = clearance.shape
    for i in range(count):  # to_global: rotate(points, yaw) + origin
        x, y = scan[i, 0], scan[i, 1]
        gx = (cos_yaw * x - sin_yaw * y) + ego_x
        gy = (sin_yaw * x + cos_yaw * y) + ego_y
        pts[i, 0] = gx
        pts[i, 1] = gy
        cx = np.floor((gx - grid_origin[0]) * inv_resolution)
        cy = np.floor((gy - grid_origin[1]) * inv_resolution)
        c = offgrid_clearance
        if cx >= 0.0 and cy >= 0.0 and cx < rows and cy < cols:
            c = clearance[int(cx), int(cy)]
        if not c > limit or not np.isfinite(gx + gy):  # a non-finite return goes on, to be named
            near[m] = i
            m += 1
    near = near[:m]
    sub = pts[near]
    empty = np.empty(0, dtype=np.int64)
    if seeded:
        s = seeds.copy()
        missing = np.zeros(count, dtype=np.bool_)
        s_sub = s[near]
    else:
        s_sub, missing_sub = seed_kernel(sub, grid_origin, inv_resolution, grid, node_frame, nodes, min_denominator)
        s = np.zeros(count)
        missing = np.zeros(count, dtype=np.bool_)
        s[near] = s_sub
        missing[near] = missing_sub
        if missing_sub.any():
            return SEED, empty, np.empty(0), 0, pts, s, missing
    s_sub, lateral_sub, pending = project_kernel(kind, sub, s_sub, closed, length, ends, table, bucket_cell,
                                                 starts_next, inv_bucket, hops, gl_nodes, gl_weights,
                                                 max_iterations, tolerance, max_step, min_denominator)
    if pending.any():
        return STAGED, empty, np.empty(0), 0, pts, s, missing
    lateral = np.full(count, np.nan)
    on_road = np.empty(m, dtype=np.int64)
    kept = 0
    for j in range(m):
        i = near[j]
        s_i = s_sub[j]
        lateral[i] = lateral_sub[j]
        n_low = edge_at(s_i, edge_inv_step, edge_right) - margin
        n_high = edge_at(s_i, edge_inv_step, edge_left) + margin
        if lateral_sub[j] >= n_low and lateral_sub[j] <= n_high and (not check_s or (s_i >= 0.0 and s_i <= length)):
            on_road[kept] = i
            kept += 1
    on_road = on_road[:kept]
    inside = scan[on_road]
    chosen = bearing_filter_kernel(inside, bin_width, bin_count, wrap)
    return DONE, on_road[chosen], lateral, kept, pts, s, missing
