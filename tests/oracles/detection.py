"""The detection model (``tracker.detection``) in numpy: bearing spans, occlusion by the previous frame's
tracks and by the scan's returns, and the expected points ``gamma`` and ``P_D`` of each component,
vectorised over (component, occluder) and (component, return) pairs."""

from __future__ import annotations

import numpy as np

from tracker.angles import wrap_angle
from tracker.config import DetectionConfig
from tracker.detection import SCAN_OCCLUSION_MARGIN, VISIBLE_FOR_DETECTION
from tracker.measurement import Rectangles


def nearest_range(rect: Rectangles) -> np.ndarray:
    """Range (m) of each rectangle's nearest corner from the E origin."""
    corners = rect.corners()
    return np.hypot(corners[..., 0], corners[..., 1]).min(axis=-1)


def bearing_spans(rect: Rectangles) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Bearing interval ``(lo, hi)`` (rad; the corners' bearings about the centre's, so ``lo`` may lie
    below -pi) of each rectangle seen from the E origin, and the range (m) of its centre."""
    corners = rect.corners()  # (C, 4, 2)
    centre_bearing = np.arctan2(rect.center[:, 1], rect.center[:, 0])
    rel = wrap_angle(np.arctan2(corners[..., 1], corners[..., 0]) - centre_bearing[:, None])
    return centre_bearing + rel.min(axis=1), centre_bearing + rel.max(axis=1), np.hypot(rect.center[:, 0],
                                                                                           rect.center[:, 1])


def occluded_fraction(rect: Rectangles, labels: np.ndarray, occluders: Rectangles,
                      occluder_labels: np.ndarray) -> np.ndarray:
    """Fraction (C,) of each rectangle's span covered by the largest overlap with the span of a nearer
    occluder of another label (the occluder shifted by the whole turns nearest the spans' middles)."""
    if len(occluder_labels) == 0 or len(labels) == 0:
        return np.zeros(len(labels))
    lo, hi, rng = bearing_spans(rect)
    olo, ohi, orng = bearing_spans(occluders)
    turn = 2.0 * np.pi
    shift = turn * np.round((0.5 * (lo + hi))[:, None] / turn - (0.5 * (olo + ohi))[None, :] / turn)
    overlap = np.minimum(hi[:, None], ohi[None, :] + shift) - np.maximum(lo[:, None], olo[None, :] + shift)
    span = np.maximum(hi - lo, 1e-9)
    counts = (orng[None, :] < rng[:, None]) & (occluder_labels[None, :] != labels[:, None])
    frac = np.where(counts, np.clip(overlap, 0.0, None) / span[:, None], 0.0)
    return np.clip(frac.max(axis=1), 0.0, 1.0)


def ray_index(bearing: np.ndarray, resolution: float) -> np.ndarray:
    """The ray ``rint(bearing / resolution)`` modulo one turn of each bearing (rad)."""
    per_turn = max(int(round(2.0 * np.pi / resolution)), 1)
    return np.mod(np.rint(np.asarray(bearing, dtype=float) / resolution).astype(np.int64), per_turn)


def scan_occluded_fraction(rect: Rectangles, scan: np.ndarray, resolution: float) -> np.ndarray:
    """Fraction (C,) of each rectangle's span hidden by the returns of ``scan`` nearer than its nearest
    corner by more than ``SCAN_OCCLUSION_MARGIN``: the rays holding such a return within the span, times
    ``resolution``, over the span (at least one ray), at most 1."""
    count = len(rect.center)
    scan = np.asarray(scan, dtype=float).reshape(-1, 2)
    if count == 0 or len(scan) == 0:
        return np.zeros(count)
    lo, hi, _ = bearing_spans(rect)
    near = nearest_range(rect)
    r_scan = np.hypot(scan[:, 0], scan[:, 1])
    b_scan = np.arctan2(scan[:, 1], scan[:, 0])
    rel = wrap_angle(b_scan[None, :] - 0.5 * (lo + hi)[:, None])  # (C, N)
    hides = (np.abs(rel) <= 0.5 * (hi - lo)[:, None]) & (r_scan[None, :] < (near - SCAN_OCCLUSION_MARGIN)[:, None])
    ray = ray_index(b_scan, resolution)
    rays = np.array([len(np.unique(ray[row])) for row in hides])  # rays, not returns (a 3-D lidar's beams)
    return np.clip(rays * resolution / np.maximum(hi - lo, resolution), 0.0, 1.0)


def detection_model(rect: Rectangles, labels: np.ndarray, config: DetectionConfig, occluders: Rectangles | None = None,
                    occluder_labels: np.ndarray | None = None,
                    scan: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(gamma, p_d)`` per component: ``gamma`` the span in rays (at least 1), ``P_D`` the configured
    one within the lidar range (nearest corner), 0 beyond; with occlusion the larger hidden fraction
    ``f`` (tracks, scan) scales ``gamma`` by ``1 - f`` (at least 1) and ``P_D`` by
    ``min(1, (1 - f) / VISIBLE_FOR_DETECTION)``."""
    lo, hi, _ = bearing_spans(rect)
    near = nearest_range(rect)
    gamma = np.maximum((hi - lo) / config.lidar_resolution, 1.0)
    p_d = np.where(near <= config.lidar_range, config.p_detection, 0.0)
    if config.occlusion:
        hidden = np.zeros(len(labels))
        if occluders is not None and occluder_labels is not None:
            hidden = occluded_fraction(rect, labels, occluders, occluder_labels)
        if scan is not None:
            hidden = np.maximum(hidden, scan_occluded_fraction(rect, scan, config.lidar_resolution))
        visible = 1.0 - hidden
        p_d = p_d * np.clip(visible / VISIBLE_FOR_DETECTION, 0.0, 1.0)
        gamma = np.maximum(gamma * visible, 1.0)
    return gamma, p_d
