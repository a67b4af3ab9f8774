"""Compiled detection model: ``tracker.detection.detection_model`` (bearing spans, nearest range,
occlusion by the previous frame's tracks and by the scan's own returns) in one numba call, the same
formulas per component, per (component, occluder) pair and per (component, return) pair."""

from __future__ import annotations

import numpy as np

from tracker.compiled import njit
from tracker.compiled.geometry import wrap_angle


@njit
def _spans(corners, centers):
    """``bearing_spans`` and ``nearest_range`` of rectangles ``corners (C, 4, 2)``, ``centers (C, 2)``:
    ``lo``, ``hi`` (rad), centre range and nearest-corner range (m)."""
    count = corners.shape[0]
    lo = np.empty(count)
    hi = np.empty(count)
    rng = np.empty(count)
    near = np.empty(count)
    for c in range(count):
        cb = np.arctan2(centers[c, 1], centers[c, 0])
        r_min = np.inf
        r_max = -np.inf
        d_min = np.inf
        for k in range(4):
            rel = wrap_angle(np.arctan2(corners[c, k, 1], corners[c, k, 0]) - cb)
            r_min = min(r_min, rel)
            r_max = max(r_max, rel)
            d_min = min(d_min, np.hypot(corners[c, k, 0], corners[c, k, 1]))
        lo[c] = cb + r_min
        hi[c] = cb + r_max
        rng[c] = np.hypot(centers[c, 0], centers[c, 1])
        near[c] = d_min
    return lo, hi, rng, near


@njit
def _occluded(lo, hi, rng, labels, occ_corners, occ_centers, occ_labels):
    """``occluded_fraction`` from the components' spans and ranges."""
    count = lo.shape[0]
    hidden = np.zeros(count)
    if occ_corners.shape[0] == 0:
        return hidden
    olo, ohi, orng, _ = _spans(occ_corners, occ_centers)
    for c in range(count):
        span = max(hi[c] - lo[c], 1e-9)
        best = 0.0
        for t in range(occ_corners.shape[0]):
            if not (orng[t] < rng[c] and occ_labels[t] != labels[c]):
                continue
            shift = 2.0 * np.pi * np.rint((0.5 * (lo[c] + hi[c])) / (2.0 * np.pi) - (0.5 * (olo[t] + ohi[t])) / (2.0 * np.pi))
            overlap = min(hi[c], ohi[t] + shift) - max(lo[c], olo[t] + shift)
            best = max(best, max(overlap, 0.0) / span)
        hidden[c] = min(max(best, 0.0), 1.0)
    return hidden


@njit
def occluded_kernel(corners, centers, labels, occ_corners, occ_centers, occ_labels):
    """``tracker.detection.occluded_fraction``: the fraction (C,) of each rectangle's bearing span
    hidden by a nearer occluder of another label."""
    lo, hi, rng, _ = _spans(corners, centers)
    return _occluded(lo, hi, rng, labels, occ_corners, occ_centers, occ_labels)


@njit
def detection_kernel(corners, centers, labels, occ_corners, occ_centers, occ_labels, use_occluders, scan, use_scan,
                     resolution, lidar_range, p_detection, occlusion, visible_for_detection, scan_margin):
    """``(gamma, p_d)`` per component, as ``detection_model`` (``use_occluders``: the previous frame's
    tracks are given; ``use_scan``: the scan is)."""
    count = corners.shape[0]
    lo, hi, rng, near = _spans(corners, centers)
    gamma = np.empty(count)
    p_d = np.empty(count)
    for c in range(count):
        gamma[c] = max((hi[c] - lo[c]) / resolution, 1.0)
        p_d[c] = p_detection if near[c] <= lidar_range else 0.0
    if not occlusion:
        return gamma, p_d
    if use_occluders:
        hidden = _occluded(lo, hi, rng, labels, occ_corners, occ_centers, occ_labels)
    else:
        hidden = np.zeros(count)
    if use_scan and scan.shape[0] > 0 and count > 0:
        limit = -np.inf
        for c in range(count):
            limit = max(limit, near[c])
        limit -= scan_margin
        m = scan.shape[0]
        r_all = np.empty(m)
        b_all = np.empty(m)
        ray_all = np.empty(m, dtype=np.int64)
        per_turn = max(int(np.rint(2.0 * np.pi / resolution)), 1)
        k = 0
        for i in range(m):
            r = np.hypot(scan[i, 0], scan[i, 1])
            if r < limit:  # only returns that can hide anything
                r_all[k] = r
                b_all[k] = np.arctan2(scan[i, 1], scan[i, 0])
                ray_all[k] = np.int64(np.rint(b_all[k] / resolution)) % per_turn  # its ray (bearing bin)
                k += 1
        order = np.argsort(ray_all[:k], kind="mergesort")  # the returns of one ray together
        r_scan = r_all[:k][order]
        b_scan = b_all[:k][order]
        ray = ray_all[:k][order]
        for c in range(count):
            centre = 0.5 * (lo[c] + hi[c])
            half = 0.5 * (hi[c] - lo[c])
            threshold = near[c] - scan_margin
            # the returns sorted by ray whose ray can lie in the span: the rays of its bearings, two
            # rays more on either side (rounding, and 2 pi / resolution not a whole number); as two
            # ranges where the window crosses ray 0. The count of rays with a hiding return does not
            # depend on the order the rays are visited in, so the window gives the whole scan's count.
            first = np.int64(np.floor((centre - half) / resolution)) - 2
            final = np.int64(np.ceil((centre + half) / resolution)) + 2
            if final - first + 1 >= per_turn:
                ranges = ((0, k), (0, 0))
            else:
                a = first % per_turn
                b = final % per_turn
                if a <= b:
                    ranges = ((np.searchsorted(ray, a), np.searchsorted(ray, b, side="right")), (0, 0))
                else:
                    ranges = ((np.searchsorted(ray, a), k), (0, np.searchsorted(ray, b, side="right")))
            hides = 0  # rays with a hiding return (a 3-D lidar's beams share a ray)
            for start, stop in ranges:
                last = -1
                for i in range(start, stop):
                    if ray[i] != last and r_scan[i] < threshold and abs(wrap_angle(b_scan[i] - centre)) <= half:
                        hides += 1
                        last = ray[i]
            frac = min(max(hides * resolution / max(hi[c] - lo[c], resolution), 0.0), 1.0)
            hidden[c] = max(hidden[c], frac)
    for c in range(count):
        visible = 1.0 - hidden[c]
        p_d[c] = p_d[c] * min(max(visible / visible_for_detection, 0.0), 1.0)
        gamma[c] = max(gamma[c] * visible, 1.0)
    return gamma, p_d
