"""Compiled road births: ``tracker.birth.road_births`` with the tracker's acceleration state and its
test of where a vehicle can enter the view (``tracker.tracker.Tracker._add_births``) in one numba call
(``road_births_kernel``): the same components, the same rectangles (``to_vehicle_kernel``), the same
occlusion (``detection._spans`` and ``_occluded``, as ``occluded_kernel``) and the same distance to the
nearest track (``sqrt(dx^2 + dy^2)``, as ``numpy.linalg.norm``)."""

from __future__ import annotations

import math

import numpy as np

from tracker.compiled import njit
from tracker.compiled.centerline import to_vehicle_kernel
from tracker.compiled.detection import _occluded, _spans


@njit
def road_births_kernel(s, lanes, speed, length_prior, width_prior, cov7, accel_var, dim, kind, ego_x, ego_y, ego_yaw,
                       closed, length, ends, table, bucket_cell, starts_next, inv_bucket, hops, nodes, weights,
                       min_extent, track_corners, track_centers, track_labels, gate_distance):  # pragma: no cover - compiled
    """Birth components ``(means (B, dim), covs (B, dim, dim))`` at the arc lengths ``s`` (m) on every lane
    centre ``lanes`` (row ``i * len(lanes) + j``), speed ``speed``, extent ``length_prior`` x
    ``width_prior``, covariance ``cov7 (7, 7)`` (and ``accel_var`` for the acceleration state when ``dim``
    is 8); where tracks are given (``track_labels`` not empty: their rectangles' corners and centres in
    E), only those whose rectangle in E (the ego at ``ego_x, ego_y, ego_yaw`` in G) is less than half
    hidden by the tracks (``occluded_fraction``) and lies farther than ``gate_distance`` (m) from every
    track's centre."""
    count = len(s) * len(lanes)
    means = np.zeros((count, dim))
    for i in range(len(s)):
        for j in range(len(lanes)):
            row = i * len(lanes) + j
            means[row, 0] = s[i]
            means[row, 1] = lanes[j]
            means[row, 2] = speed
            means[row, 5] = length_prior
            means[row, 6] = width_prior
    keep = np.ones(count, dtype=np.bool_)
    if count and len(track_labels):
        center, _psi, corners = to_vehicle_kernel(kind, means, ego_x, ego_y, ego_yaw, closed, length, ends, table,
                                                  bucket_cell, starts_next, inv_bucket, hops, nodes, weights, min_extent)
        lo, hi, rng, _near = _spans(corners, center)
        hidden = _occluded(lo, hi, rng, np.full(count, -1, dtype=np.int64), track_corners, track_centers, track_labels)
        for b in range(count):
            gap = np.inf
            for t in range(len(track_labels)):
                dx = center[b, 0] - track_centers[t, 0]
                dy = center[b, 1] - track_centers[t, 1]
                gap = min(gap, math.sqrt(dx * dx + dy * dy))
            keep[b] = hidden[b] < 0.5 and gap > gate_distance
    kept = 0
    for b in range(count):
        kept += keep[b]
    out_means = np.empty((kept, dim))
    out_covs = np.zeros((kept, dim, dim))
    k = 0
    for b in range(count):
        if not keep[b]:
            continue
        out_means[k] = means[b]
        for r in range(7):
            for c in range(7):
                out_covs[k, r, c] = cov7[r, c]
        if dim == 8:
            out_covs[k, 7, 7] = accel_var
        k += 1
    return out_means, out_covs
