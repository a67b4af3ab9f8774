"""Tests of tracker/detection.py: expected points, P_D and occlusion (by tracks and by the scan)."""

from __future__ import annotations

import numpy as np

import pytest

from oracles import detection as oracle
from oracles.detection import bearing_spans
from tracker.config import DetectionConfig
from tracker.detection import (SCAN_OCCLUSION_MARGIN, cap_missed_weights, detection_model, occluded_fraction,
                               scan_occluded_fraction)
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


@pytest.mark.parametrize("seed", range(3))
def test_detection_model_equals_the_oracle(seed):
    """``detection_model`` (one compiled call) against the oracle's vectorised model: rectangles all
    around the sensor (across the +-pi seam behind it), near and beyond the lidar range, hidden by nearer
    tracks of other labels and by scan returns (several beams on one ray); without occluders, without a
    scan, with occlusion off, and for no components; ``occluded_fraction`` and ``scan_occluded_fraction``
    on their own."""
    rng = np.random.default_rng(seed)

    def rects(count):
        r, b = rng.uniform(3.0, 110.0, count), rng.uniform(-np.pi, np.pi, count)
        b[:3] = np.pi - rng.uniform(0.0, 0.02, 3)  # straddling the seam behind the sensor
        return Rectangles(np.column_stack([r * np.cos(b), r * np.sin(b)]), rng.uniform(-np.pi, np.pi, count),
                          rng.uniform(0.0, 30.0, count), rng.uniform(2.0, 14.0, count), rng.uniform(1.5, 2.6, count))

    comps, tracks = rects(60), rects(12)
    labels = rng.integers(0, 15, 60)
    track_labels = rng.integers(0, 15, 12)
    scan = np.concatenate([tracks.corners().reshape(-1, 2), rng.uniform(-60.0, 60.0, (400, 2))])
    scan = np.concatenate([scan, scan[:200] * rng.uniform(0.97, 1.03, (200, 1))])  # several beams on one ray
    cases = [(DetectionConfig(), tracks, track_labels, scan), (DetectionConfig(), None, None, scan),
             (DetectionConfig(), tracks, track_labels, None), (DetectionConfig(occlusion=False), tracks, track_labels, scan),
             (DetectionConfig(), tracks.take(np.arange(0)), track_labels[:0], scan[:0])]
    for config, occ, occ_labels, sc in cases:
        got = detection_model(comps, labels, config, occ, occ_labels, scan=sc)
        for a, b in zip(got, oracle.detection_model(comps, labels, config, occ, occ_labels, scan=sc)):
            np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12)
    hidden = occluded_fraction(comps, labels, tracks, track_labels)
    np.testing.assert_allclose(hidden, oracle.occluded_fraction(comps, labels, tracks, track_labels), rtol=1e-12, atol=1e-12)
    assert (hidden > 0.0).any()
    by_scan = scan_occluded_fraction(comps, scan, RES)
    np.testing.assert_allclose(by_scan, oracle.scan_occluded_fraction(comps, scan, RES), rtol=1e-12, atol=1e-12)
    assert (by_scan > 0.0).any()
    p_d = detection_model(comps, labels, DetectionConfig(), tracks, track_labels, scan=scan)[1]
    # occlusion lowers some P_D part-way, range cuts others to 0
    assert ((p_d > 0.0) & (p_d < DetectionConfig().p_detection)).any() and (p_d == 0.0).any()
    empty = detection_model(comps.take(np.arange(0)), labels[:0], DetectionConfig(), tracks, track_labels, scan=scan)
    assert empty[0].shape == (0,) and empty[1].shape == (0,)


def test_the_detection_model_takes_one_batch_of_rectangles():
    """One rectangle's fields without the batch axis (centre ``(2,)``) are no batch: a ValueError."""
    one = Rectangles(np.array([40.0, 0.0]), np.array(0.0), np.array(20.0), np.array(4.8), np.array(2.0))
    with pytest.raises(ValueError, match="batch of rectangles"):
        detection_model(one, np.array(1), DetectionConfig())
    with pytest.raises(ValueError, match="batch of rectangles"):
        occluded_fraction(one, np.array([1]), car_ahead(20.0), np.array([2]))
