"""Compiled lidar preprocessing: ``tracker.preprocess.filter_points``' steps 2 and 3 on a frame's
returns in one numba call (``road_filter_kernel``): the returns to G (``tracker.transforms.to_global``'s
formula), their projection on the centerline (``Road._project`` without a hint: the seed grid's start,
then the lock-step Newton iterations of ``project_kernel``), the road-bound test (``Road.within_bounds``)
and the closest return per bearing bin (``bearing_filter_kernel``). The same kernels and formulas in
the same order: the same numbers. Where a return is off the seed grid the caller seeds it from the
k-d tree and calls again; where Newton does not converge it takes the staged path (the bracketed search)."""

from __future__ import annotations

import numpy as np

from tracker.compiled import njit
from tracker.compiled.centerline import project_kernel, seed_kernel
from tracker.compiled.clustering import bearing_filter_kernel

#: ``road_filter_kernel``'s status: done; some returns off the seed grid (the caller seeds them from the
#: k-d tree and calls again with the seeds); hand back to the staged path.
DONE, SEED, STAGED = 0, 1, 2


@njit
def road_filter_kernel(scan, cos_yaw, sin_yaw, ego_x, ego_y, seeds, seeded, grid_origin, inv_resolution, grid,
                       node_frame, nodes, kind, closed, length, ends, table, bucket_cell, starts_next, inv_bucket, hops,
                       gl_nodes, gl_weights, max_iterations, tolerance, max_step, min_denominator, check_s, n_low,
                       n_high, bin_width, bin_count, wrap):  # pragma: no cover - compiled
    """The returns ``scan (N, 2)`` in E (finite) of an ego at ``(ego_x, ego_y)`` in G whose heading has
    cosine ``cos_yaw`` and sine ``sin_yaw``: their projections ``(s, n)`` on the road (Newton from
    ``seeds (N,)`` when ``seeded``, else from the seed grid's), those within ``n_low <= n <= n_high``
    (and ``0 <= s <= length`` when ``check_s``: an open road), and of those the closest per bearing bin.
    Returns ``(status, kept, lateral, on_road_count, points, starts, missing)``: ``kept`` indices into
    ``scan`` in increasing bearing order (``bearing_filter_kernel`` of the on-road returns), the lateral
    offsets ``n (N,)`` of every return. ``status`` ``SEED``: some returns are off the seed grid
    (``missing``); ``points`` (G) and ``starts`` are then the caller's to complete. ``STAGED``: a
    projection did not converge. Neither leaves ``kept`` or ``lateral`` valid."""
    count = scan.shape[0]
    pts = np.empty((count, 2))
    for i in range(count):  # to_global: rotate(points, yaw) + origin
        x, y = scan[i, 0], scan[i, 1]
        pts[i, 0] = (cos_yaw * x - sin_yaw * y) + ego_x
        pts[i, 1] = (sin_yaw * x + cos_yaw * y) + ego_y
    empty = np.empty(0, dtype=np.int64)
    if seeded:
        s = seeds.copy()
        missing = np.zeros(count, dtype=np.bool_)
    else:
        s, missing = seed_kernel(pts, grid_origin, inv_resolution, grid, node_frame, nodes, min_denominator)
        if missing.any():
            return SEED, empty, np.empty(0), 0, pts, s, missing
    s, lateral, pending = project_kernel(kind, pts, s, closed, length, ends, table, bucket_cell, starts_next,
                                         inv_bucket, hops, gl_nodes, gl_weights, max_iterations, tolerance, max_step,
                                         min_denominator)
    if pending.any():
        return STAGED, empty, np.empty(0), 0, pts, s, missing
    on_road = np.empty(count, dtype=np.int64)
    kept = 0
    for i in range(count):
        if lateral[i] >= n_low and lateral[i] <= n_high and (not check_s or (s[i] >= 0.0 and s[i] <= length)):
            on_road[kept] = i
            kept += 1
    on_road = on_road[:kept]
    inside = np.empty((kept, 2))
    for j in range(kept):
        inside[j, 0] = scan[on_road[j], 0]
        inside[j, 1] = scan[on_road[j], 1]
    chosen = bearing_filter_kernel(inside, bin_width, bin_count, wrap)
    return DONE, on_road[chosen], lateral, kept, pts, s, missing
