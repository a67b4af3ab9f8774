"""Tests of tracker/detection.py: expected points, P_D and occlusion (by tracks and by the scan)."""

from __future__ import annotations

import numpy as np

from tracker.config import DetectionConfig
from tracker.detection import SCAN_OCCLUSION_MARGIN, bearing_spans, cap_missed_weights, detection_model, scan_occluded_fraction
from tracker.measurement import Rectangles

RES = np.radians(0.2)


def car_ahead(x: float = 40.0, y: float = 0.0) -> Rectangles:
    """A 4.8 x 2 m car at (x, y) in E, heading +x."""
    one = np.ones(1)
    return Rectangles(np.array([[x, y]]), 0.0 * one, 20.0 * one, 4.8 * one, 2.0 * one)


def wall(x: float, bearings: np.ndarray) -> np.ndarray:
    """Returns of a wall at distance x straight ahead, one per bearing."""
    return np.stack([np.full(len(bearings), x), x * np.tan(bearings)], axis=1)


def test_scan_returns_nearer_than_the_car_hide_it_farther_ones_do_not() -> None:
    rect = car_ahead()
    lo, hi, _ = bearing_spans(rect)
    rays = np.arange(lo[0], hi[0], RES)
    assert scan_occluded_fraction(rect, wall(20.0, rays), RES)[0] > 0.95  # a wall between: hidden
    half = rays[: len(rays) // 2]
    assert scan_occluded_fraction(rect, wall(20.0, half), RES)[0] == np.clip(len(half) * RES / (hi[0] - lo[0]), 0, 1)
    # returns on the car itself (its rear face, 37.6 m) and beyond it hide nothing
    assert scan_occluded_fraction(rect, wall(37.6 + 0.5 - SCAN_OCCLUSION_MARGIN + 0.1, rays), RES)[0] == 0.0
    assert scan_occluded_fraction(rect, wall(60.0, rays), RES)[0] == 0.0
    # returns outside the car's bearing span hide nothing
    assert scan_occluded_fraction(rect, wall(20.0, rays + 0.2), RES)[0] == 0.0


def test_a_3d_lidars_beams_on_one_ray_hide_one_ray() -> None:
    """A VLP-16's projected cloud has a return per beam on each ray: a wall hiding half of a car's rays
    with 16 returns on each (ranges 19.5-20.5 m, bearings within a hundredth of a ray) hides half of its
    span, as one return per ray does, not all of it (counting returns took a half-hidden car 12 m ahead
    for a hidden one)."""
    rect = car_ahead()
    lo, hi, _ = bearing_spans(rect)
    rays = np.arange(lo[0], hi[0], RES)
    half = rays[: len(rays) // 2]
    one = scan_occluded_fraction(rect, wall(20.0, half), RES)[0]
    beams = np.concatenate([wall(x, half + 0.01 * RES * (k - 8) / 8) for k, x in enumerate(np.linspace(19.5, 20.5, 16))])
    assert len(beams) == 16 * len(half)
    assert 0.45 < one < 0.55
    assert scan_occluded_fraction(rect, beams, RES)[0] == one
    config = DetectionConfig()
    _, p_d = detection_model(rect, np.array([1]), config, scan=beams)
    assert p_d[0] == config.p_detection  # half visible: detected


def test_a_car_hidden_by_the_scan_keeps_its_detection_probability_low() -> None:
    """Behind an untracked occluder (a tree, a wall) P_D drops to 0, so a missed detection does not
    erase the track's weight; in the open it is ``p_detection``."""
    rect = car_ahead()
    lo, hi, _ = bearing_spans(rect)
    cfg = DetectionConfig()
    labels = np.array([7])
    _, p_open = detection_model(rect, labels, cfg, scan=wall(60.0, np.arange(lo[0], hi[0], RES)))
    gamma, p_hidden = detection_model(rect, labels, cfg, scan=wall(20.0, np.arange(lo[0], hi[0], RES)))
    assert p_open[0] == cfg.p_detection
    assert p_hidden[0] == 0.0 and gamma[0] == 1.0
    _, p_off = detection_model(rect, labels, DetectionConfig(occlusion=False), scan=wall(20.0, np.arange(lo[0], hi[0], RES)))
    assert p_off[0] == cfg.p_detection


def test_cap_missed_weights_leaves_each_updated_label_at_most_the_rest_of_one() -> None:
    """Label 7: missed 0.9 + 0.3, updated 0.8 in all -> its missed components share 0.2 in proportion
    (0.15, 0.05). Label 8: updated 1.3 -> nothing left. Label 9: missed 0.1, updated 0.5 -> under the
    cap, kept. Label 4: not updated -> kept whatever its weight."""
    missed = np.array([0.9, 0.3, 0.6, 0.1, 2.5])
    labels = np.array([7, 7, 8, 9, 4])
    updated = np.array([0.5, 0.3, 1.0, 0.3, 0.5])
    updated_labels = np.array([7, 7, 8, 8, 9])
    out = cap_missed_weights(missed, labels, updated, updated_labels)
    np.testing.assert_allclose(out, [0.15, 0.05, 0.0, 0.1, 2.5], atol=1e-12)
    np.testing.assert_array_equal(cap_missed_weights(missed, labels, np.zeros(0), np.zeros(0, dtype=int)), missed)
