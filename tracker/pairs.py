"""The update of the pairs as one numba call: ``tracker.update.update_pairs``' steps chained, so that
none of their intermediate arrays goes back to Python.

The steps are the staged path's kernels, called in its order with its arguments: the sigma points of
the components in some pair and their rectangles in E (``centerline.sigma_rectangles_kernel``), the
measurement structure of every pair (``structure.structure_kernel``, the predicted extent's standard
deviations from the pairs' priors), the extent growth (``extent.grow_extent_kernel``), the likelihood's
variances (``tracker.update.likelihood_variances``), the measurement update with the radar gate
(``kalman.measurement_update_kernel``) and the extent rules (``extent.extent_rules_kernel``): the same
numbers as the staged path. Where that path leaves the kernels or raises (a NaN or an infinity in a
mean or covariance, a pair whose prior the growth widened, a measurement variance that is not
positive), the kernel returns a status instead of a result; where a prior or an innovation covariance
is not positive definite a kernel it calls raises ``numpy.linalg.LinAlgError``. Either way the caller
(``tracker.update._update_pairs_fused``) takes the staged path, one kernel at a time, which handles
it."""

from __future__ import annotations

import numpy as np

from tracker.jit import njit
from tracker.centerline import sigma_rectangles_kernel
from tracker.extent import extent_rules_kernel, grow_extent_kernel
from tracker.kalman import measurement_update_kernel
from tracker.preparation import scanned_batch_kernel
from tracker.structure import structure_kernel
from tracker.motion import LENGTH, WIDTH

#: ``update_pairs_kernel`` statuses: done; the staged path is needed (see the module docstring).
DONE, NOT_FINITE, GROWN, BAD_NOISE = 0, 1, 2, 3


@njit
def _empty_result(pairs, dim, rows):  # pragma: no cover - compiled
    return (np.empty((0, dim)), np.empty((0, dim, dim)), np.empty(0), np.empty(0), np.empty(0, dtype=np.int64),
            np.empty((0, rows)), np.empty((0, rows)), np.zeros(0, dtype=np.bool_))


@njit
def update_pairs_kernel(means, covs, inverse, ci, scale, wm, wc, angles, period_index, period, kind, ego_x, ego_y,
                        ego_yaw, closed, length, ends, table, bucket_cell, starts_next, inv_bucket, hops, nodes, weights,
                        min_extent, points, valid, part, proj, chord_start, chord_end, chord_dir, chord_len, end_margin,
                        end_gap, two_sided, single, fused, velocity, centroid, occluded, not_free, min_apparent,
                        partial_visibility, free_gap, lidar_var, radar_var, use_radar, speed_row, min_chord,
                        shadows, min_points, gate_sigmas, gate_slack, missed_rays, shadowed_var, shadow_reach, grow,
                        growth_min,
                        growth_sigmas, gate, hold, classes_on, share, class_length, class_length_var,
                        class_width, class_width_var, unmeasured_var, class_prior_var, short_var, length_floor, min_length, min_width, max_length, max_width):  # pragma: no cover - compiled
    """The posteriors of the pairs ``(component used[inverse[p]], cluster ci[p])`` of the components
    ``means (U, D)``, ``covs (U, D, D)`` (the ones in some pair) and the prepared clusters (the
    ``tracker.measurement.ClusterBatch`` fields). Returns ``(status, mean, cov, log_likelihood, nis,
    dim, predicted, innovation, radar_rejected)``: ``measurement_update_kernel``'s outputs after the
    extent rules when ``status`` is ``DONE``, empty arrays otherwise. ``shadows``: the clusters have
    their shadow flags (``structure_kernel``)."""
    count, dim = means.shape
    pairs = len(ci)
    rows = 2 * points.shape[1] + 2
    sigma, center, psi, corners, finite = sigma_rectangles_kernel(
        means, covs, scale, angles, period_index, period, kind, ego_x, ego_y, ego_yaw, closed, length, ends, table,
        bucket_cell, starts_next, inv_bucket, hops, nodes, weights, min_extent)
    if not finite:
        return (NOT_FINITE,) + _empty_result(pairs, dim, rows)
    num_sigma = sigma.shape[1]
    # the pairs' priors, their mean rectangles' corners (the central sigma point is the mean) and the
    # sigma points' rectangles (Rectangles.of_states: the extent floored at min_extent)
    pair_means = np.empty((pairs, dim))
    pair_covs = np.empty((pairs, dim, dim))
    mean_corners = np.empty((pairs, 4, 2))
    extent_sd = np.empty((pairs, 2))
    pair_sigma = np.empty((pairs, num_sigma, dim))
    pair_center = np.empty((pairs, num_sigma, 2))
    pair_psi = np.empty((pairs, num_sigma))
    pair_v = np.empty((pairs, num_sigma))
    pair_length = np.empty((pairs, num_sigma))
    pair_width = np.empty((pairs, num_sigma))
    for p in range(pairs):
        u = inverse[p]
        pair_means[p] = means[u]
        pair_covs[p] = covs[u]
        mean_corners[p] = corners[u, 0]
        extent_sd[p, 0] = np.sqrt(max(covs[u, LENGTH, LENGTH], 0.0))
        extent_sd[p, 1] = np.sqrt(max(covs[u, WIDTH, WIDTH], 0.0))
        pair_sigma[p] = sigma[u]
        pair_center[p] = center[u]
        pair_psi[p] = psi[u]
        for i in range(num_sigma):
            pair_v[p, i] = sigma[u, i, 2]
            pair_length[p, i] = max(sigma[u, i, LENGTH], min_extent)
            pair_width[p, i] = max(sigma[u, i, WIDTH], min_extent)
    (_a, _b, _c1, _c2, _coef, matrix, _valid, _two, sides, mode, radar, z, r, mask, factors,
     excess) = structure_kernel(points, valid, part, proj, chord_start, chord_end, chord_dir, chord_len, end_margin,
                                end_gap, two_sided, single, fused, velocity, centroid, occluded, not_free, ci,
                                mean_corners, min_apparent, partial_visibility, free_gap, lidar_var, radar_var,
                                use_radar, speed_row, min_chord, shadows, True, extent_sd, min_points, gate_sigmas,
                                gate_slack, missed_rays, shadowed_var, shadow_reach)
    if grow:
        grown, _grown_covs = grow_extent_kernel(pair_means, pair_covs, excess, sides, mean_corners, growth_min,
                                                growth_sigmas)
        if grown.any():  # new sigma points for the widened pairs: the staged path (UnscentedTransform.sigma_points)
            return (GROWN,) + _empty_result(pairs, dim, rows)
    width = r.shape[1]
    softened = False
    for p in range(pairs):
        for d in range(width):
            if mask[p, d] and not r[p, d] > 0.0:
                return (BAD_NOISE,) + _empty_result(pairs, dim, rows)
        if shadowed_var >= 0.0 and mask[p, 0] and r[p, 0] != lidar_var:
            softened = True  # a pair's lidar rows share one variance: its first row, always a point, tells
    r_like = r
    if softened:  # tracker.update.likelihood_variances: the likelihood at the nominal lidar variance
        r_like = r.copy()
        for p in range(pairs):
            for d in range(width - 2):
                if mask[p, d]:
                    r_like[p, d] = lidar_var
    mean, cov, log_likelihood, nis, dims, predicted, innovation, rejected = measurement_update_kernel(
        pair_sigma, pair_means, pair_covs, pair_center, pair_psi, pair_v, pair_length, pair_width, matrix, z, r,
        r_like, mask, factors, radar, ci, gate, wm, wc, angles, period_index, period)
    extent_rules_kernel(mean, cov, pair_means, pair_covs, mode, sides, mean_corners, hold, classes_on, share,
                        class_length, class_length_var, class_width, class_width_var, unmeasured_var, class_prior_var, short_var, length_floor,
                        min_length, min_width, max_length, max_width)
    return DONE, mean, cov, log_likelihood, nis, dims, predicted, innovation, rejected


#: ``prepared_pairs_kernel``'s status where a cluster in some pair is empty or holds a non-finite point
#: (the two steps' preparation drops and counts such points): the caller takes the two steps.
IRREGULAR = 4


@njit
def _selected(points, offsets, has_velocity, velocity, means, covs, comp, clu):  # pragma: no cover - compiled
    """The pairs' clusters and components, as ``tracker.indices.unique_indices`` and fancy indexing select
    them: the distinct clusters of ``clu`` (ascending) concatenated, their offsets, radar flags and
    velocities, each pair's position among them; the distinct components of ``comp`` (ascending), their
    means and covariances, each pair's position among them. ``regular`` False where a selected cluster
    is empty or holds a non-finite point."""
    pairs = len(comp)
    clusters = len(offsets) - 1
    cluster_slot = np.full(clusters, -1, dtype=np.intp)
    for p in range(pairs):
        cluster_slot[clu[p]] = 0
    used = 0
    size = 0
    for k in range(clusters):
        if cluster_slot[k] >= 0:
            cluster_slot[k] = used
            used += 1
            size += offsets[k + 1] - offsets[k]
    flat = np.empty((size, 2))
    sub_offsets = np.zeros(used + 1, dtype=np.intp)
    sub_has = np.zeros(used, dtype=np.bool_)
    sub_velocity = np.zeros((used, 2))
    regular = True
    for k in range(clusters):
        j = cluster_slot[k]
        if j < 0:
            continue
        a, b = offsets[k], offsets[k + 1]
        start = sub_offsets[j]
        if b <= a:
            regular = False
        for i in range(a, b):
            x, y = points[i, 0], points[i, 1]
            if not (np.isfinite(x) and np.isfinite(y)):
                regular = False
            flat[start + i - a, 0] = x
            flat[start + i - a, 1] = y
        sub_offsets[j + 1] = start + b - a
        sub_has[j] = has_velocity[k]
        if has_velocity[k]:
            sub_velocity[j, 0] = velocity[k, 0]
            sub_velocity[j, 1] = velocity[k, 1]
    ci = np.empty(pairs, dtype=np.intp)
    for p in range(pairs):
        ci[p] = cluster_slot[clu[p]]
    count, dim = means.shape
    comp_slot = np.full(count, -1, dtype=np.intp)
    for p in range(pairs):
        comp_slot[comp[p]] = 0
    taken = 0
    for c in range(count):
        if comp_slot[c] >= 0:
            comp_slot[c] = taken
            taken += 1
    sub_means = np.empty((taken, dim))
    sub_covs = np.empty((taken, dim, dim))
    for c in range(count):
        j = comp_slot[c]
        if j >= 0:
            sub_means[j] = means[c]
            sub_covs[j] = covs[c]
    inverse = np.empty(pairs, dtype=np.intp)
    for p in range(pairs):
        inverse[p] = comp_slot[comp[p]]
    return flat, sub_offsets, sub_has, sub_velocity, ci, sub_means, sub_covs, inverse, regular


@njit
def prepared_pairs_kernel(points_all, offsets_all, has_velocity_all, velocity_all, means_all, covs_all, comp, clu, bound,
                          min_two, ratio_max, min_residual, line_residual, min_chord_prep, sin_min_angle, max_shift,
                          max_end_gap, scan, shadows, window, shadow_margin, max_range, range_margin, continuation,
                          rays, offset, scale, wm, wc,
                          angles, period_index, period, kind, ego_x, ego_y, ego_yaw, closed, length, ends, table,
                          bucket_cell, starts_next, inv_bucket, hops, nodes, weights, min_extent, min_apparent,
                          partial_visibility, free_gap, lidar_var, radar_var, use_radar, speed_row, min_chord,
                          min_points, gate_sigmas, gate_slack, missed_rays, shadowed_var, shadow_reach, grow, growth_min,
                          growth_sigmas, gate, hold, classes_on, share, class_length, class_length_var,
                          class_width, class_width_var, unmeasured_var, class_prior_var, short_var, length_floor, min_length, min_width, max_length, max_width):  # pragma: no cover - compiled
    """The pairs ``(component comp[p], cluster clu[p])`` of the components ``means_all``, ``covs_all``
    and the clusters ``points_all[offsets_all[k]:offsets_all[k + 1]]`` (E; radar velocity
    ``velocity_all[k]`` where ``has_velocity_all[k]``), updated as the two steps do it: the clusters in
    some pair (``_selected``) prepared by ``tracker.preparation.prepare_scanned_batch``'s compiled call
    (``scanned_batch_kernel``), the batch's centroids (``points.sum(axis=1) / max(kept, 1)``, summed
    point by point) and free ends (neither in a shadow nor continued: ``tracker.measurement._free_ends``)
    as ``ClusterBatch`` and ``structure_batch_args`` give them, then ``update_pairs_kernel`` of the
    components in some pair. Returns ``update_pairs_kernel``'s outputs (status ``IRREGULAR`` where a
    selected cluster is empty or not finite), then the numbers of occluded and of continued ends."""
    (flat, offsets, fused, velocity, ci, means, covs, inverse, regular) = _selected(
        points_all, offsets_all, has_velocity_all, velocity_all, means_all, covs_all, comp, clu)
    dim = means_all.shape[1]
    if not regular:
        return (IRREGULAR,) + _empty_result(len(comp), dim, 2) + (0, 0)
    (points, valid, part, proj, starts, chord_end, direction, chord_len, margin_out, half_gap, two, single, kept_count,
     occluded, continued) = scanned_batch_kernel(flat, offsets, bound, min_two, ratio_max, min_residual, line_residual,
                                                 min_chord_prep, sin_min_angle, max_shift, max_end_gap, scan, shadows,
                                                 window, shadow_margin, max_range, range_margin, continuation, rays, offset)
    count, width = points.shape[0], points.shape[1]
    centroid = np.empty((count, 2))
    not_free = np.zeros((count, 2), dtype=np.bool_)
    n_occluded = 0
    n_continued = 0
    for k in range(count):
        for d in range(2):
            acc = points[k, 0, d]
            for i in range(1, width):
                acc += points[k, i, d]
            centroid[k, d] = acc / max(kept_count[k], 1)
            if shadows:
                not_free[k, d] = occluded[k, d]
                n_occluded += occluded[k, d]
            if continuation:
                not_free[k, d] = not_free[k, d] or continued[k, d]
                n_continued += continued[k, d]
    result = update_pairs_kernel(
        means, covs, inverse, ci, scale, wm, wc, angles, period_index, period, kind, ego_x, ego_y, ego_yaw, closed,
        length, ends, table, bucket_cell, starts_next, inv_bucket, hops, nodes, weights, min_extent, points, valid,
        part, proj, starts, chord_end, direction, chord_len, margin_out, half_gap, two, single, fused, velocity,
        centroid, occluded, not_free, min_apparent, partial_visibility, free_gap, lidar_var, radar_var, use_radar,
        speed_row, min_chord, shadows, min_points, gate_sigmas, gate_slack, missed_rays, shadowed_var, shadow_reach, grow,
        growth_min, growth_sigmas, gate, hold, classes_on, share, class_length, class_length_var, class_width,
        class_width_var, unmeasured_var, class_prior_var, short_var, length_floor, min_length, min_width, max_length, max_width)
    return result + (n_occluded, n_continued)
