"""Tests of tracker/detection.py: expected points, P_D and occlusion (by tracks and by the scan)."""

from __future__ import annotations

import numpy as np

from tracker.config import DetectionConfig
from tracker.detection import SCAN_OCCLUSION_MARGIN, bearing_spans, detection_model, scan_occluded_fraction
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
