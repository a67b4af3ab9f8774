"""Compiled centerline evaluation: ``ClothoidCenterline.frame`` and ``HermiteCenterline.frame``
(``tracker.centerline``) as one numba call each, with the same bucket lookup of the cell, the same
per-cell closed forms (the clothoid's Taylor cos/sin and 4-point Gauss-Legendre position integral; the
Hermite cell's cubic ``tau(s)`` and the spline's derivatives)."""

from __future__ import annotations

import numpy as np

from tracker.compiled import njit
from tracker.compiled.geometry import corner_offset
from tracker.compiled.ukf import all_finite, sigma_kernel


@njit(inline="always")
def _locate(s, bucket_cell, starts_next, inv_bucket, hops, last):
    k = min(int(s * inv_bucket), len(bucket_cell) - 1)
    idx = bucket_cell[max(k, 0)]
    for _ in range(hops):
        if s >= starts_next[idx]:
            idx += 1
    return min(idx, last)


@njit(inline="always")
def _cos_sin_small(phi):
    p2 = phi * phi
    cos = 1.0 + p2 * (-1 / 2 + p2 * (1 / 24 + p2 * (-1 / 720 + p2 * (1 / 40320 - p2 / 3628800))))
    sin = phi * (1.0 + p2 * (-1 / 6 + p2 * (1 / 120 + p2 * (-1 / 5040 + p2 * (1 / 362880 - p2 / 39916800)))))
    return cos, sin


@njit(inline="always")
def _frame_arrays(count):
    """Empty outputs of a frame kernel: positions and unit tangents ``(count, 2)``, curvatures ``(count,)``."""
    return np.empty((count, 2)), np.empty((count, 2)), np.empty(count)


@njit(inline="always")
def clothoid_at(s, table, bucket_cell, starts_next, inv_bucket, hops, nodes, weights):
    """Position, unit tangent and curvature ``(x, y, tx, ty, kappa)`` at one ``s`` in [0, length];
    ``table`` rows ``(start, x, y, cos0, sin0, kappa0, rate)`` per cell."""
    row = table[_locate(s, bucket_cell, starts_next, inv_bucket, hops, len(table) - 1)]
    d = s - row[0]
    cos0, sin0, k0, kr = row[3], row[4], row[5], row[6]
    ic = 0.0
    is_ = 0.0
    for g in range(len(nodes)):
        dd = d * nodes[g]
        c, sn = _cos_sin_small((k0 + 0.5 * kr * dd) * dd)
        ic += c * weights[g]
        is_ += sn * weights[g]
    ce, se = _cos_sin_small((k0 + 0.5 * kr * d) * d)
    return (row[1] + d * (cos0 * ic - sin0 * is_), row[2] + d * (sin0 * ic + cos0 * is_),
            cos0 * ce - sin0 * se, sin0 * ce + cos0 * se, k0 + kr * d)


@njit(inline="always")
def hermite_at(s, table, bucket_cell, starts_next, inv_bucket, hops, nodes, weights):
    """As ``clothoid_at``; ``table`` rows ``(start, q0..q3, x0, y0, x1, y1, x2, y2, x3, y3)``
    (``nodes`` and ``weights`` unused: the same signature as ``clothoid_at``)."""
    row = table[_locate(s, bucket_cell, starts_next, inv_bucket, hops, len(table) - 1)]
    d = s - row[0]
    tau = ((row[4] * d + row[3]) * d + row[2]) * d + row[1]
    x0, y0, x1, y1, x2, y2, x3, y3 = row[5], row[6], row[7], row[8], row[9], row[10], row[11], row[12]
    dx = (3.0 * x3 * tau + 2.0 * x2) * tau + x1
    dy = (3.0 * y3 * tau + 2.0 * y2) * tau + y1
    ddx = 6.0 * x3 * tau + 2.0 * x2
    ddy = 6.0 * y3 * tau + 2.0 * y2
    speed = np.hypot(dx, dy)
    return (((x3 * tau + x2) * tau + x1) * tau + x0, ((y3 * tau + y2) * tau + y1) * tau + y0,
            dx / speed, dy / speed, (dx * ddy - dy * ddx) / speed**3)


#: curve kinds of the kernels' ``kind`` argument
CLOTHOID, HERMITE = 0, 1


@njit(inline="always")
def curve_at(kind, s, table, bucket_cell, starts_next, inv_bucket, hops, nodes, weights):
    """``clothoid_at`` or ``hermite_at`` by ``kind`` (``CLOTHOID`` or ``HERMITE``)."""
    if kind == CLOTHOID:
        return clothoid_at(s, table, bucket_cell, starts_next, inv_bucket, hops, nodes, weights)
    return hermite_at(s, table, bucket_cell, starts_next, inv_bucket, hops, nodes, weights)


@njit
def curve_frame(kind, s, table, bucket_cell, starts_next, inv_bucket, hops, nodes, weights):
    """Position ``(N, 2)``, unit tangent ``(N, 2)``, curvature ``(N,)`` at ``s (N,)`` in [0, length]."""
    count = len(s)
    p, tangent, kappa = _frame_arrays(count)
    for i in range(count):
        p[i, 0], p[i, 1], tangent[i, 0], tangent[i, 1], kappa[i] = curve_at(
            kind, s[i], table, bucket_cell, starts_next, inv_bucket, hops, nodes, weights)
    return p, tangent, kappa


@njit(inline="always")
def road_frame_at(kind, s, closed, length, ends, table, bucket_cell, starts_next, inv_bucket, hops, nodes, weights):
    """``Road._frame_flat(s, extrapolate=True)`` at one ``s``: wrapped on a closed road; on an open
    one the frame at ``s`` clipped to [0, length], its position moved along the end tangent
    (``ends`` rows ``(x, y, cos, sin)`` at 0 and at ``length``) and its curvature 0 beyond an end."""
    at = s % length if closed else min(max(s, 0.0), length)
    x, y, tx, ty, kappa = curve_at(kind, at, table, bucket_cell, starts_next, inv_bucket, hops, nodes, weights)
    if closed:
        return x, y, tx, ty, kappa
    if s < 0.0:
        return ends[0, 0] + s * ends[0, 2], ends[0, 1] + s * ends[0, 3], tx, ty, 0.0
    if s > length:
        d = s - length
        return ends[1, 0] + d * ends[1, 2], ends[1, 1] + d * ends[1, 3], tx, ty, 0.0
    return x, y, tx, ty, kappa


@njit
def project_kernel(kind, pts, s, closed, length, ends, table, bucket_cell, starts_next, inv_bucket, hops, nodes, weights,
                   max_iterations, tolerance, max_step, min_denominator):
    """``Road._project``'s Newton iterations from the starts ``s (N,)`` (changed in place), in its order:
    every point takes a step while any is pending (numpy's lock-step). Returns ``(s, lateral, pending)``;
    the pending points (not converged) go to the caller's fallback."""
    count = len(s)
    lateral = np.zeros(count)
    pending = np.ones(count, dtype=np.bool_)
    for _ in range(max_iterations):
        any_pending = False
        for i in range(count):
            x, y, tx, ty, kappa = road_frame_at(kind, s[i] % length if closed else s[i], closed, length, ends, table,
                                                bucket_cell, starts_next, inv_bucket, hops, nodes, weights)
            dx = pts[i, 0] - x
            dy = pts[i, 1] - y
            along = dx * tx + dy * ty
            lat = dy * tx - dx * ty
            denom = max(1.0 - kappa * lat, min_denominator)
            ds = min(max(along / denom, -max_step), max_step)
            s[i] = (s[i] + ds) % length if closed else s[i] + ds
            lateral[i] = lat
            pending[i] = abs(ds) >= tolerance
            any_pending = any_pending or pending[i]
        if not any_pending:
            break
    return s, lateral, pending


@njit
def to_vehicle_kernel(kind, states, ego_x, ego_y, ego_yaw, closed, length, ends, table, bucket_cell, starts_next,
                      inv_bucket, hops, nodes, weights, min_extent):
    """``tracker.measurement.to_vehicle``'s curvilinear exact conversion of ``states (N, 7 or 8)``:
    rectangle centres ``(N, 2)``, headings ``(N,)`` and corners ``(N, 4, 2)`` (of the extent floored
    at ``min_extent``) in E (the frame extrapolated beyond an open road's ends, as
    ``Road.frame(..., extrapolate=True)``)."""
    count = states.shape[0]
    center = np.empty((count, 2))
    psi = np.empty(count)
    corners = np.empty((count, 4, 2))
    c = np.cos(ego_yaw)
    sn = np.sin(ego_yaw)
    for i in range(count):
        x, y, tx, ty, _ = road_frame_at(kind, states[i, 0], closed, length, ends, table, bucket_cell, starts_next,
                                        inv_bucket, hops, nodes, weights)
        theta = np.arctan2(ty, tx)
        n = states[i, 1]
        gx = x - n * np.sin(theta) - ego_x
        gy = y + n * np.cos(theta) - ego_y
        center[i, 0] = c * gx + sn * gy
        center[i, 1] = -sn * gx + c * gy
        psi[i] = theta + states[i, 3] - ego_yaw
        # rectangle_corners of the floored extent
        cp, sp = np.cos(psi[i]), np.sin(psi[i])
        hl, hw = 0.5 * max(states[i, 5], min_extent), 0.5 * max(states[i, 6], min_extent)
        for k in range(4):
            lx, ly = corner_offset(k, hl, hw)
            corners[i, k, 0] = center[i, 0] + cp * lx - sp * ly
            corners[i, k, 1] = center[i, 1] + sp * lx + cp * ly
    return center, psi, corners


@njit
def rectangles_kernel(kind, states, ego_x, ego_y, ego_yaw, closed, length, ends, table, bucket_cell, starts_next,
                      inv_bucket, hops, nodes, weights, min_extent):  # pragma: no cover - compiled
    """``to_vehicle_kernel`` with the rest of ``tracker.measurement.to_vehicle``'s compiled path: the
    extent floored at ``min_extent`` (``numpy.maximum``: a NaN stays NaN) and whether every ``s`` is
    finite (checked first; nothing else computed when one is not). Returns ``(center, psi, corners,
    length, width, finite)``."""
    count = states.shape[0]
    for i in range(count):
        if not np.isfinite(states[i, 0]):
            return np.empty((0, 2)), np.empty(0), np.empty((0, 4, 2)), np.empty(0), np.empty(0), False
    center, psi, corners = to_vehicle_kernel(kind, states, ego_x, ego_y, ego_yaw, closed, length, ends, table,
                                             bucket_cell, starts_next, inv_bucket, hops, nodes, weights, min_extent)
    floored_length = np.empty(count)
    floored_width = np.empty(count)
    for i in range(count):
        a, b = states[i, 5], states[i, 6]
        floored_length[i] = a if (a >= min_extent or a != a) else min_extent
        floored_width[i] = b if (b >= min_extent or b != b) else min_extent
    return center, psi, corners, floored_length, floored_width, True


@njit
def sigma_rectangles_kernel(means, covs, scale, angles, period_index, period, kind, ego_x, ego_y, ego_yaw, closed,
                            length, ends, table, bucket_cell, starts_next, inv_bucket, hops, nodes, weights,
                            min_extent):  # pragma: no cover - compiled
    """The sigma points of ``N(means, covs)`` (``tracker.compiled.ukf.sigma_kernel``) and their
    rectangles in E (``to_vehicle_kernel``) in one call: ``tracker.update.update_pairs``' first step.
    Returns ``(sigma (C, S, D), center (C, S, 2), psi (C, S), corners (C, S, 4, 2), finite)``;
    ``finite`` False (nothing computed) when a mean or covariance holds a NaN or an infinity."""
    count, dim = means.shape
    if not all_finite(means, covs):
        return np.empty((0, 0, dim)), np.empty((0, 0, 2)), np.empty((0, 0)), np.empty((0, 0, 4, 2)), False
    sigma = sigma_kernel(means, covs, scale, angles, period_index, period)
    points = sigma.shape[1]
    center, psi, corners = to_vehicle_kernel(kind, sigma.reshape(count * points, dim), ego_x, ego_y, ego_yaw, closed,
                                             length, ends, table, bucket_cell, starts_next, inv_bucket, hops, nodes,
                                             weights, min_extent)
    return (sigma, center.reshape(count, points, 2), psi.reshape(count, points),
            corners.reshape(count, points, 4, 2), True)


@njit
def seed_kernel(pts, origin, inv_resolution, grid, node_frame, nodes, min_denominator):  # pragma: no cover - compiled
    """``Road._project``'s start without a hint: per point the curve sample its seed-grid cell stores
    (``Road._nearest_node``) and one Newton step from that sample's stored frame, ``s = s_node + (d . t)
    / max(1 - kappa (d x t), min_denominator)``. Returns ``(s, missing)``: ``missing`` where the point
    is off the grid or its cell holds no sample (the caller seeds those from the k-d tree)."""
    count = pts.shape[0]
    s = np.zeros(count)
    missing = np.zeros(count, dtype=np.bool_)
    for i in range(count):
        cx = np.floor((pts[i, 0] - origin[0]) * inv_resolution)
        cy = np.floor((pts[i, 1] - origin[1]) * inv_resolution)
        node = -1
        if cx >= 0.0 and cy >= 0.0 and cx < grid.shape[0] and cy < grid.shape[1]:
            node = grid[int(cx), int(cy)]
        if node < 0:
            missing[i] = True
            continue
        dx = pts[i, 0] - node_frame[node, 0]
        dy = pts[i, 1] - node_frame[node, 1]
        tx, ty, kappa = node_frame[node, 2], node_frame[node, 3], node_frame[node, 4]
        denom = max(1.0 - kappa * (dy * tx - dx * ty), min_denominator)
        s[i] = nodes[node] + (dx * tx + dy * ty) / denom
    return s, missing
