"""State-dependent detection model of the GM-PHD update: expected points ``gamma(x)`` and ``P_D(x)``.

For a component's predicted rectangle in E (the lidar at the origin):

- its bearing span ``[b_lo, b_hi]`` is that of its four corners (unwrapped around the centre's
  bearing); ``gamma = span / lidar_resolution`` points, at least 1;
- ``P_D = p_detection`` when the rectangle's nearest corner is inside the lidar range, 0 beyond it;
- occlusion: the fraction ``f`` of the span covered by a nearer *occluder* (the reported tracks of
  the previous frame, other than the component's own label) scales the expected points,
  ``gamma (1 - f)``, and the detection probability, ``P_D min(1, (1 - f) / VISIBLE_FOR_DETECTION)``: a
  partly hidden car is still detected; only a (nearly) hidden one is not. A fully hidden target then keeps its weight through the missed-detection term
  ``w (1 - (1 - e^-gamma) P_D)`` instead of fading, so it keeps its label when it reappears.

``f`` is the largest single overlap (not the union of several occluders) over the occluders.

Occlusion by the scan itself (``scan_occluded_fraction``): objects the tracker does not track (roadside
trees, posts, walls, a vehicle not yet confirmed) hide targets too. The fraction of a rectangle's bearing
span whose lidar returns lie nearer than its nearest corner by more than ``SCAN_OCCLUSION_MARGIN`` is
hidden: each ray (a bearing bin of ``lidar_resolution``, ``rint(bearing / resolution)``) with such a
return stands for one ray of the span. Rays, not returns, are counted: a 2-D scan has one return per
ray, but a 3-D lidar's projected cloud has one per beam and ray (up to 16 for a VLP-16), and counting
returns would take a half-hidden car for a wholly hidden one. The detection model uses the larger of
the two fractions. Without the scan's occlusion a target passing behind untracked objects (a row of
trees) would lose its weight at ``1 - P_D`` per frame, gone within two or three frames, and come back
under a new label.

The model is computed by the numba kernels at the end of the module: the spans and nearest corners
(``_spans``), the occluders' overlap (``_occluded``), the scan's hiding rays (``_scan_hidden``), and all
of it for a frame's components in one call (``detection_kernel``).
"""

from __future__ import annotations

import numpy as np

from tracker.config import DetectionConfig
from tracker.measurement import Rectangles
from tracker.jit import njit
from tracker.geometry import wrap_angle as wrap_angle_scalar

#: Visible fraction of a target's bearing span above which occlusion no longer lowers ``P_D``.
VISIBLE_FOR_DETECTION = 0.25
#: A lidar return hides a rectangle when it is nearer than the rectangle's nearest corner by this (m).
SCAN_OCCLUSION_MARGIN = 1.0


def nearest_range(rect: Rectangles) -> np.ndarray:
    """Range (m) of each rectangle's nearest corner from the E origin (the lidar)."""
    corners = rect.corners()
    return np.hypot(corners[..., 0], corners[..., 1]).min(axis=-1)


def _corners_and_centres(rect: Rectangles, caller: str) -> tuple[np.ndarray, np.ndarray]:
    """The corners ``(C, 4, 2)`` and centres ``(C, 2)`` of a batch of rectangles, as the kernels take
    them; a ``ValueError`` for rectangles that are not one batch ``(C, 2)``."""
    if rect.center.ndim != 2:
        raise ValueError(f"{caller} needs a batch of rectangles, centres (C, 2); got centres of shape {rect.center.shape}")
    return np.ascontiguousarray(rect.corners()), np.ascontiguousarray(rect.center, dtype=float)


def occluded_fraction(rect: Rectangles, labels: np.ndarray, occluders: Rectangles, occluder_labels: np.ndarray) -> np.ndarray:
    """Fraction (C,) of each rectangle's bearing span hidden by a nearer occluder of another label
    (one compiled call, ``occluded_kernel``)."""
    if len(occluder_labels) == 0 or len(labels) == 0:
        return np.zeros(len(labels))
    return occluded_kernel(*_corners_and_centres(rect, "occluded_fraction"), np.ascontiguousarray(labels, dtype=np.int64),
                           *_corners_and_centres(occluders, "occluded_fraction"),
                           np.ascontiguousarray(occluder_labels, dtype=np.int64))


def scan_occluded_fraction(rect: Rectangles, scan: np.ndarray, resolution: float) -> np.ndarray:
    """Fraction (C,) of each rectangle's bearing span hidden by lidar returns ``scan (N, 2)`` in E that
    lie nearer than its nearest corner by more than ``SCAN_OCCLUSION_MARGIN``; each ray (bearing bin of
    ``resolution`` rad) with such a return covers one ray of the span, however many returns it has (the
    beams of a 3-D lidar). One compiled call (``scan_occluded_kernel``)."""
    count = len(rect.center)
    scan = np.asarray(scan, dtype=float).reshape(-1, 2)
    if count == 0 or len(scan) == 0:
        return np.zeros(count)
    return scan_occluded_kernel(*_corners_and_centres(rect, "scan_occluded_fraction"), np.ascontiguousarray(scan),
                                float(resolution), SCAN_OCCLUSION_MARGIN)


def detection_model(
    rect: Rectangles,
    labels: np.ndarray,
    config: DetectionConfig,
    occluders: Rectangles | None = None,
    occluder_labels: np.ndarray | None = None,
    scan: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``(gamma, p_d)`` per component (C,) from its predicted rectangle in E (module docstring);
    ``scan`` (N, 2): the frame's lidar returns in E (all finite ones, on and off the road) for the
    scan-based occlusion. One compiled call (``detection_kernel``)."""
    with_occ = occluders is not None and occluder_labels is not None
    occ = occluders if with_occ else rect
    return detection_kernel(
        *_corners_and_centres(rect, "detection_model"), np.ascontiguousarray(labels, dtype=np.int64),
        *_corners_and_centres(occ, "detection_model"),
        np.ascontiguousarray(occluder_labels if with_occ else labels, dtype=np.int64), with_occ,
        np.zeros((0, 2)) if scan is None else np.ascontiguousarray(scan, dtype=float).reshape(-1, 2),
        scan is not None, float(config.lidar_resolution), float(config.lidar_range), float(config.p_detection),
        bool(config.occlusion), VISIBLE_FOR_DETECTION, SCAN_OCCLUSION_MARGIN,
    )


def cap_missed_weights(missed: np.ndarray, labels: np.ndarray, updated: np.ndarray, updated_labels: np.ndarray) -> np.ndarray:
    """The missed-detection weights ``missed`` (one per prior component, labels ``labels``) with each
    label's total capped at ``max(0, 1 - U)``, ``U`` the total weight of that label's updated components
    (``updated``, labels ``updated_labels``); the label's missed components are scaled down together.
    Labels without an updated component keep their weights. (``DetectionConfig.missed_weight_cap``: a
    label is one vehicle; once clusters explain it with weight ``U``, its "not detected" hypothesis can
    hold only the rest.)"""
    missed = np.asarray(missed, dtype=float)
    out = missed.copy()
    if not len(updated) or not len(missed):
        return out
    hit, where = np.unique(updated_labels, return_inverse=True)
    took = np.bincount(where.reshape(-1), weights=updated, minlength=len(hit))
    pos = np.searchsorted(hit, labels)
    mine = (pos < len(hit)) & (hit[np.minimum(pos, len(hit) - 1)] == labels)
    if not mine.any():
        return out
    idx = pos[mine]
    held = np.bincount(idx, weights=missed[mine], minlength=len(hit))  # each label's missed total
    room = np.maximum(0.0, 1.0 - took)
    scale = np.where(held > room, room / np.maximum(held, 1e-300), 1.0)
    out[mine] = missed[mine] * scale[idx]
    return out

# --------------------------------------------------------------------------------------------------
# The compiled kernels of this stage: the detection model (module docstring) per component, per
# (component, occluder) pair and per (component, return) pair.
# --------------------------------------------------------------------------------------------------


@njit
def _spans(corners, centers):
    """The bearing spans of rectangles ``corners (C, 4, 2)``, ``centers (C, 2)`` seen from the E origin:
    ``lo``, ``hi`` (rad: the corners' extreme bearings taken about the centre's, so ``hi - lo < pi`` and
    ``lo`` may lie below -pi), the centre's range and the nearest corner's range (m)."""
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
            rel = wrap_angle_scalar(np.arctan2(corners[c, k, 1], corners[c, k, 0]) - cb)
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
    """The fraction (C,) of each span ``[lo, hi]`` (centre range ``rng``, label ``labels``) covered by
    the largest overlap with the span of an occluder (``occ_corners (T, 4, 2)``, ``occ_centers``,
    ``occ_labels``) of another label whose centre is nearer, the occluder shifted by the whole turns
    that bring the two spans' middles closest; 0 without occluders."""
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
    """``occluded_fraction``: the fraction (C,) of each rectangle's bearing span hidden by a nearer
    occluder of another label (``_occluded``)."""
    lo, hi, rng, _ = _spans(corners, centers)
    return _occluded(lo, hi, rng, labels, occ_corners, occ_centers, occ_labels)


@njit(inline="always")
def _scan_hidden(lo, hi, near, scan, resolution, scan_margin):
    """The fraction (C,) of each bearing span ``[lo, hi]`` (rad) that returns of ``scan (N, 2)`` (N > 0)
    hide: those nearer than the span's rectangle's nearest corner ``near`` (m) by more than
    ``scan_margin``. Each ray (bearing bin of ``resolution``, ``rint(bearing / resolution)`` modulo one
    turn) holding such a return within the span counts once: the fraction is the rays times
    ``resolution`` over the span (at least one ray), at most 1."""
    count = lo.shape[0]
    hidden = np.zeros(count)
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
                if ray[i] != last and r_scan[i] < threshold and abs(wrap_angle_scalar(b_scan[i] - centre)) <= half:
                    hides += 1
                    last = ray[i]
        hidden[c] = min(max(hides * resolution / max(hi[c] - lo[c], resolution), 0.0), 1.0)
    return hidden


@njit
def scan_occluded_kernel(corners, centers, scan, resolution, scan_margin):
    """``scan_occluded_fraction``: the fraction (C,) of each rectangle's bearing span hidden by the
    returns of ``scan (N, 2)`` (N > 0) nearer than its nearest corner by more than ``scan_margin``."""
    lo, hi, _, near = _spans(corners, centers)
    return _scan_hidden(lo, hi, near, scan, resolution, scan_margin)


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
        by_scan = _scan_hidden(lo, hi, near, scan, resolution, scan_margin)
        for c in range(count):
            hidden[c] = max(hidden[c], by_scan[c])
    for c in range(count):
        visible = 1.0 - hidden[c]
        p_d[c] = p_d[c] * min(max(visible / visible_for_detection, 0.0), 1.0)
        gamma[c] = max(gamma[c] * visible, 1.0)
    return gamma, p_d
