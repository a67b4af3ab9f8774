"""Tests of tracker/flow.py: the lane-flow speed of a coasting track and its pseudo-measurement, and the
tracker's use of them (which components take it, from which sources)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.linalg import solve

from tracker import Road, Tracker, TrackerConfig
from tracker.flow import SPEED, flow_speeds, pull_to_flow
from tracker.reduction import Mixture


@pytest.fixture(scope="module")
def straight() -> Road:
    """A straight three-lane road, lanes 3.5 m wide centred at n = -3.5, 0, 3.5."""
    return Road.from_curvature([(1000.0, 0.0, 0.0)], lanes=3, lane_width=3.5)


def test_the_flow_is_the_mean_of_the_nearest_seen_vehicles_ahead_and_behind_in_the_lane(straight):
    source = np.array([
        [140.0, 3.4, 10.0],  # lane 2, 10 m ahead of the first target
        [160.0, 3.6, 5.0],  # lane 2, farther ahead: not the nearest
        [110.0, 3.5, 14.0],  # lane 2, 20 m behind
        [131.0, 0.0, 30.0],  # lane 1, beside the target: another lane
    ])
    target = np.array([
        [130.0, 3.5],  # between 140 (ahead) and 110 (behind): (10 + 14) / 2
        [170.0, 3.5],  # only 160 within the window (ahead: none): 5 m/s from behind
        [300.0, 3.5],  # nothing within 50 m
        [125.0, 0.2],  # lane 1: the vehicle at 131
        [125.0, -3.5],  # lane 0: nobody
    ])
    flow = flow_speeds(straight, source, target, 50.0)
    np.testing.assert_allclose(flow[[0, 1, 3]], [12.0, 5.0, 30.0])
    assert np.isnan(flow[2]) and np.isnan(flow[4])
    # a narrower window leaves the first target only the vehicle ahead
    assert flow_speeds(straight, source, target[:1], 15.0)[0] == 10.0
    assert np.isnan(flow_speeds(straight, source[:0], target, 50.0)).all()


def test_on_a_closed_road_the_flow_reaches_across_the_seam():
    ring = Road.from_curvature([(2 * np.pi * 100.0, 0.01, 0.01)], closed=True, lanes=2, right_edge=-3.5)
    length = ring.length
    source = np.array([[length - 3.0, -1.75, 8.0], [12.0, -1.75, 12.0]])
    flow = flow_speeds(ring, source, np.array([[2.0, -1.75]]), 50.0)
    assert flow[0] == pytest.approx(10.0)  # 5 m behind across the seam, 10 m ahead


def test_the_pull_is_the_kalman_update_of_a_speed_measurement():
    rng = np.random.default_rng(3)
    a = rng.normal(size=(3, 8, 8))
    covs = a @ a.transpose(0, 2, 1) + 0.5 * np.eye(8)
    means = rng.normal(size=(3, 8))
    rows, flow, variance = np.array([0, 2]), np.array([4.0, -1.0]), 2.5
    expect_m, expect_p = means.copy(), covs.copy()
    h = np.zeros((1, 8))
    h[0, SPEED] = 1.0
    for r, z in zip(rows, flow):  # the textbook form: K = P H^T (H P H^T + R)^-1
        s = h @ covs[r] @ h.T + variance
        gain = solve(s, h @ covs[r]).T
        expect_m[r] = means[r] + (gain @ (np.array([z]) - h @ means[r])).ravel()
        expect_p[r] = (np.eye(8) - gain @ h) @ covs[r]
    pull_to_flow(means, covs, rows, flow, variance)
    np.testing.assert_allclose(means, expect_m, atol=1e-12)
    np.testing.assert_allclose(covs, expect_p, atol=1e-12)
    prior = a @ a.transpose(0, 2, 1) + 0.5 * np.eye(8)
    for r in rows:  # the information form: 1 / P_vv+ = 1 / P_vv + 1 / R
        assert covs[r, SPEED, SPEED] == pytest.approx(1.0 / (1.0 / prior[r, SPEED, SPEED] + 1.0 / variance))
        assert np.all(np.linalg.eigvalsh(covs[r]) > 0.0)
        np.testing.assert_allclose(covs[r], covs[r].T, atol=1e-12)
    # a row not pulled is untouched
    np.testing.assert_array_equal(means[1], expect_m[1])


def _tracker(road: Road, **motion) -> Tracker:
    """A tracker whose mixture holds four labels in the left lane (n = 3.5): 1 at s = 150 (14 m/s),
    2 at 135 (10 m/s), 3 at 120 (12 m/s), 4 at 128 (9 m/s, never reported); all reported before but 4."""
    cfg = TrackerConfig()
    tracker = Tracker(road, dataclasses.replace(cfg, motion=dataclasses.replace(cfg.motion, **motion)))
    means = np.zeros((4, 8))
    means[:, 0] = [150.0, 135.0, 120.0, 128.0]
    means[:, 1] = 3.5
    means[:, 2] = [14.0, 10.0, 12.0, 9.0]
    means[:, 5], means[:, 6] = 4.5, 1.8
    covs = np.repeat(np.eye(8)[None] * 0.5, 4, axis=0)
    covs[:, 0, 2] = covs[:, 2, 0] = 0.2  # s and v correlated: the pull moves s too
    tracker.mixture = Mixture(np.ones(4), means, covs, np.array([1, 2, 3, 4]))
    tracker._reported = np.array([0, 1, 2])
    tracker._ever_reported = {1, 2, 3}
    return tracker


def test_the_tracker_pulls_only_coasting_tracks_towards_their_seen_neighbours(straight):
    tracker = _tracker(straight)
    before = tracker.mixture.means.copy(), tracker.mixture.covs.copy()
    # 1 and 3 were updated last frame, 2 coasted; the ego drives in the right lane
    tracker._ego_road = (100.0, -3.5, 20.0)
    tracker._pull_to_flow(0.1, {1, 3})
    mix = tracker.mixture
    motion = tracker.config.motion
    variance = motion.flow_speed_std**2 * motion.flow_time / 0.1
    gain = 0.5 / (0.5 + variance)
    flow = (14.0 + 12.0) / 2.0  # the seen neighbours ahead (label 1) and behind (label 3)
    assert mix.means[1, 2] == pytest.approx(10.0 + gain * (flow - 10.0))
    assert mix.means[1, 0] == pytest.approx(135.0 + 0.2 / (0.5 + variance) * (flow - 10.0))
    assert mix.covs[1, 2, 2] == pytest.approx(0.5 - gain * 0.5)
    for row in (0, 2, 3):  # the updated tracks, and a label never reported
        np.testing.assert_array_equal(mix.means[row], before[0][row])
        np.testing.assert_array_equal(mix.covs[row], before[1][row])
    assert tracker.stats["flow_pulls"] == 1


def test_the_ego_is_a_seen_vehicle_and_nothing_is_pulled_when_the_prior_is_off(straight):
    tracker = _tracker(straight)
    # nothing updated last frame (a blackout): only the ego, 10 m behind label 3 in its lane, sets a flow;
    # label 2 has it 25 m behind, at the default window's edge; label 1, 40 m ahead of it, is beyond it
    assert tracker.config.motion.flow_window == 25.0
    tracker._ego_road = (110.0, 3.5, 20.0)
    tracker._pull_to_flow(0.1, set())
    assert tracker.stats["flow_pulls"] == 2
    assert np.all(tracker.mixture.means[1:3, 2] > [10.0, 12.0])
    assert tracker.mixture.means[0, 2] == 14.0 and tracker.mixture.means[3, 2] == 9.0
    off = _tracker(straight, flow_speed_std=None)
    off._ego_road = (110.0, 3.5, 20.0)
    off._pull_to_flow(0.1, set())
    np.testing.assert_array_equal(off.mixture.means[:, 2], [14.0, 10.0, 12.0, 9.0])
    assert off.stats["flow_pulls"] == 0


@pytest.mark.parametrize("section, field, value", [("MotionConfig", "flow_speed_std", 0.0), ("MotionConfig", "flow_time", -1.0),
                                                    ("MotionConfig", "flow_window", 0.0), ("BirthConfig", "flow_speed_std", -2.0)])
def test_bad_flow_settings_are_refused(section, field, value):
    from tracker import config

    with pytest.raises(ValueError, match=f"{section}.{field}"):
        getattr(config, section)(**{field: value})


def test_a_birth_without_radar_takes_its_lanes_flow(straight):
    # labels 1 (s = 150, 14 m/s) and 3 (s = 120, 12 m/s) were updated this frame; a cluster at s = 135 in
    # their lane gets their mean speed as its prior, one in the ego's lane (right, ego at s = 100 doing
    # 20 m/s) 10 m ahead of the ego gets the ego's speed, one in the middle lane nobody's (None: the
    # ego's speed with BirthConfig.speed_std, tracker.birth)
    from tracker import EgoState
    from tracker.transforms import to_local

    tracker = _tracker(straight)
    tracker._updated_labels = {1, 3}
    tracker._ego_road = (100.0, -3.5, 20.0)  # as Tracker.step sets it
    ego_xy = straight.to_cartesian(100.0, -3.5)
    ego = EgoState(ego_xy[0], ego_xy[1], 0.0, 20.0)
    clusters = [to_local(np.array([straight.to_cartesian(s - 0.5, n), straight.to_cartesian(s + 0.5, n)]), ego_xy, 0.0)
                for s, n in ((135.0, 3.5), (110.0, -3.5), (115.0, 0.0))]
    priors = tracker._birth_flow(ego, clusters)
    std = tracker.config.birth.flow_speed_std
    assert priors[0] == (pytest.approx(13.0), std)
    assert priors[1] == (pytest.approx(20.0), std)
    assert priors[2] is None
    cfg = tracker.config
    off = Tracker(straight, dataclasses.replace(cfg, birth=dataclasses.replace(cfg.birth, flow_speed_std=None)))
    assert off._birth_flow(ego, clusters) is None
