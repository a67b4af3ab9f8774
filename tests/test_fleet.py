"""Tests of tracker/fleet.py: the width error learned from the vehicles measured whole (its likelihood
against scipy's densities, its estimate on body widths and on label boxes, which tracks it takes), and
the renewal of the classes' length prior when it changes (tracker/extent.py)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import norm

from tracker import Road, Tracker, TrackerConfig
from tracker.config import VEHICLE_CLASSES, BirthConfig
from tracker.extent import class_arrays, class_length_prior, class_prior_lengths_kernel
from tracker.fleet import EVIDENCE, GRID, MEASURED_LENGTH_STD, MEASURED_WIDTH_STD, WidthError
from tracker.frame import EgoState
from tracker.motion import LENGTH, WIDTH
from tracker.reduction import Mixture

DIM = 8


def _tracks(widths, lengths, var_w=0.02**2, var_l=0.1**2):
    """States and covariances of tracks of the given sizes (diagonal covariances)."""
    k = len(widths)
    means = np.zeros((k, DIM))
    means[:, WIDTH], means[:, LENGTH] = widths, lengths
    covs = np.tile(np.eye(DIM), (k, 1, 1))
    covs[:, WIDTH, WIDTH], covs[:, LENGTH, LENGTH] = var_w, var_l
    return means, covs


def _fleet(n, width_error, seed):
    """``n`` vehicles drawn from the default classes, their widths off the body's by ``N(0, width_error^2)``."""
    rng = np.random.default_rng(seed)
    share = np.array([c.share for c in VEHICLE_CLASSES])
    pick = rng.choice(len(VEHICLE_CLASSES), size=n, p=share / share.sum())
    widths = np.array([rng.normal(VEHICLE_CLASSES[c].width, VEHICLE_CLASSES[c].width_std) for c in pick])
    lengths = np.array([rng.normal(VEHICLE_CLASSES[c].length, VEHICLE_CLASSES[c].length_std) for c in pick])
    return widths + rng.normal(0.0, width_error, n) if width_error else widths, lengths


def test_the_log_likelihood_is_the_classes_joint_density_of_the_pairs():
    learner = WidthError(BirthConfig())
    widths, lengths = np.array([2.25, 2.20, 2.55]), np.array([4.6, 4.5, 6.6])
    means, covs = _tracks(widths, lengths)
    learner.observe(np.array([1, 2, 3]), means, covs)
    expected = []
    for error in GRID:
        total = 0.0
        for w, l in zip(widths, lengths):
            total += np.log(sum(c.share * norm.pdf(w, c.width, np.sqrt(c.width_std**2 + error**2 + 0.02**2))
                                * norm.pdf(l, c.length, np.sqrt(c.length_std**2 + 0.1**2)) for c in VEHICLE_CLASSES))
        expected.append(total)
    np.testing.assert_allclose(learner.log_likelihood(), expected, rtol=1e-10)
    # cars 2.2-2.25 m wide and 4.5-4.6 m long, a pickup 2.55 m wide and 6.6 m long: not bodies' widths
    assert learner.value == GRID[int(np.argmax(expected))] > 0.1


def test_body_widths_give_no_error_and_label_boxes_their_spread():
    bodies = WidthError(BirthConfig())
    widths, lengths = _fleet(60, 0.0, seed=1)
    bodies.observe(np.arange(60), *_tracks(widths, lengths))
    assert bodies.value <= 0.05
    boxes = WidthError(BirthConfig())
    widths, lengths = _fleet(60, 0.25, seed=1)
    boxes.observe(np.arange(60), *_tracks(widths, lengths))
    assert 0.15 <= boxes.value <= 0.35


def test_only_vehicles_measured_whole_count_and_a_label_keeps_its_latest_pair():
    learner = WidthError(BirthConfig(width_error_vehicles=3))
    means, covs = _tracks([2.25, 2.25, 2.25], [4.6, 4.6, 4.6])
    covs[1, WIDTH, WIDTH] = (MEASURED_WIDTH_STD + 0.01) ** 2  # its width not yet measured
    covs[2, LENGTH, LENGTH] = (MEASURED_LENGTH_STD + 0.01) ** 2  # its length not yet measured
    learner.observe(np.array([1, 2, 3]), means, covs)
    assert learner.vehicles == 1
    learner.observe(np.array([1, 4]), *_tracks([2.2, 2.2], [4.5, 4.5]))  # label 1 again, and a second vehicle
    assert learner.vehicles == 2
    assert learner.value == 0.0  # the configured one until three are measured
    learner.observe(np.array([5]), *_tracks([2.55], [6.6]))
    assert learner.vehicles == 3 and learner.value > 0.1
    never = WidthError(BirthConfig(width_error_vehicles=None))
    never.observe(np.arange(10), *_tracks(np.full(10, 2.25), np.full(10, 4.6)))
    assert never.vehicles == 0 and never.value == 0.0


def test_weak_evidence_keeps_the_configured_width_error():
    # three vehicles near the classes' bodies: their likelihood barely prefers another error
    learner = WidthError(BirthConfig(width_error_vehicles=3))
    means, covs = _tracks([1.95, 1.95, 2.12], [4.6, 4.6, 5.4])
    learner.observe(np.array([1, 2, 3]), means, covs)
    ll = learner.log_likelihood()
    assert 0.0 < ll.max() - ll[0] < EVIDENCE
    assert learner.value == 0.0


def test_the_config_rejects_a_count_below_one():
    with pytest.raises(ValueError, match="width_error_vehicles must be an integer >= 1"):
        BirthConfig(width_error_vehicles=0)


def test_a_class_prior_length_is_renewed_with_the_near_end_kept():
    # a vehicle ahead of the sensor along +x, 2.55 m wide, holding the classes' length for that width
    # read as a body (a truck's); the width error learned, its prior is renewed from the same width
    share, length, length_var, width, width_var = class_arrays(VEHICLE_CLASSES, 0.0)
    old, old_var = class_length_prior(2.55, 0.02**2, share, length, length_var, width, width_var)
    means, covs = _tracks([2.55], [old], var_l=old_var)
    means[0, 0] = 30.0  # centre 30 m ahead in E (the state's x, heading 0)
    corners = np.array([[[30.0 + old / 2, 1.275], [30.0 + old / 2, -1.275], [30.0 - old / 2, -1.275],
                         [30.0 - old / 2, 1.275]]])
    arrays = class_arrays(VEHICLE_CLASSES, 0.25)
    new, new_var = class_length_prior(2.55, 0.02**2, *arrays)
    class_prior_lengths_kernel(means, covs, corners, np.array([0]), *arrays, 4.7, 1.0)
    assert new < old - 1.0
    assert means[0, LENGTH] == pytest.approx(new)
    assert covs[0, LENGTH, LENGTH] == pytest.approx(max(new_var, 1.0))
    assert means[0, 0] - means[0, LENGTH] / 2 == pytest.approx(30.0 - old / 2)  # the rear, facing the sensor
    # a width the classes read as a car's: the car's prior, as a cluster birth takes it
    means, covs = _tracks([1.8], [9.0], var_l=9.0)
    class_prior_lengths_kernel(means, covs, corners, np.array([0]), *arrays, 4.7, 1.0)
    assert means[0, LENGTH] == pytest.approx(4.7) and covs[0, LENGTH, LENGTH] == pytest.approx(1.0)


def test_the_tracker_learns_the_error_and_renews_only_class_prior_lengths_on_measured_widths():
    road = Road.from_curvature([(500.0, 0.0, 0.0)], lanes=2)
    tracker = Tracker(road, TrackerConfig())
    widths = [2.25, 2.20, 2.55, 2.55, 2.55, 2.25]
    lengths = [4.6, 4.5, 6.6, 12.0, 12.0, 4.6]
    means, covs = _tracks(widths, lengths)
    means[:, 0] = [20.0, 40.0, 60.0, 80.0, 100.0, 120.0]  # s along the road ahead of the ego
    covs[3, LENGTH, LENGTH] = covs[4, LENGTH, LENGTH] = 3.5**2  # the classes' prior (a truck's spread)
    covs[4, WIDTH, WIDTH] = 0.3**2  # ... on a width not measured
    covs[5, LENGTH, LENGTH] = 1.0  # a fitted length held (a car's prior spread)
    tracker.mixture = Mixture(np.ones(6), means, covs, np.arange(1, 7))
    tracker._reported = np.array([0, 1, 2])  # three vehicles measured whole, their widths label boxes
    before = tracker.mixture.means.copy(), tracker.mixture.covs.copy()
    tracker._learn_width_error(EgoState(0.0, 0.0, 0.0))
    error = tracker.width_error.value
    assert error > 0.1 and tracker._sized.birth.width_error_std == error
    assert tracker.config.birth.width_error_std == 0.0  # the user's config is not changed
    mix = tracker.mixture
    arrays = class_arrays(VEHICLE_CLASSES, error)
    expected, variance = class_length_prior(2.55, 0.02**2, *arrays)
    assert expected < 12.0 - 1.0
    assert mix.means[3, LENGTH] == pytest.approx(expected)
    assert mix.covs[3, LENGTH, LENGTH] == pytest.approx(max(variance, 1.0))
    assert mix.means[3, 0] - mix.means[3, LENGTH] / 2 == pytest.approx(80.0 - 6.0)  # the rear, facing the ego
    for row in (0, 1, 2, 4, 5):  # measured lengths, an unmeasured width, a fitted length: as they were
        np.testing.assert_array_equal(mix.means[row], before[0][row])
        np.testing.assert_array_equal(mix.covs[row], before[1][row])
    assert tracker.stats["class_lengths_renewed"] == 1
    # the same error again changes nothing
    tracker._learn_width_error(EgoState(0.0, 0.0, 0.0))
    assert tracker.stats["width_error_changes"] == 1 and tracker.stats["class_lengths_renewed"] == 1
