"""Tests of tracker/identity.py: the store of lost tracks and the re-identification of newcomers."""

from __future__ import annotations

import numpy as np
import pytest

from tracker import Road, TrackerConfig
from tracker.config import MotionConfig
from tracker.identity import LostTracks
from tracker.motion import make_motion
from tracker.ukf import UnscentedTransform

STRAIGHT = Road.from_curvature([(1000.0, 0.0, 0.0)], lanes=2, lane_width=3.5)
RING = Road.from_curvature([(2 * np.pi * 100.0, 0.01, 0.01)], closed=True, lanes=2, lane_width=3.5)


def state(s: float, n: float = 0.0, v: float = 10.0) -> np.ndarray:
    return np.array([s, n, v, 0.0, 0.0, 4.5, 1.8])


def cov(pos_std: float = 0.3) -> np.ndarray:
    return np.diag([pos_std**2, pos_std**2, 0.3**2, 0.02**2, 0.01**2, 0.2**2, 0.1**2])


def store(road: Road = STRAIGHT, window: float = 5.0, period: float | None = None, accel: float = 0.0,
          cartesian: bool = False, brake: float | None = None, lane_following: bool = False) -> LostTracks:
    config = TrackerConfig(coordinates="cartesian" if cartesian else "curvilinear", motion=MotionConfig(acceleration=False))
    return LostTracks(window, 0.99, UnscentedTransform(config.ukf), make_motion(config, road), period, accel, cartesian,
                      brake, lane_following)


def lose(lt: LostTracks, label: int, x: np.ndarray, t: float = 0.0) -> None:
    """Report ``label`` at ``t`` and not in the next frame (0.1 s later)."""
    lt.observe(t, np.array([label]), x[None], cov()[None])
    lt.observe(t + 0.1, np.zeros(0, dtype=int), np.zeros((0, 7)), np.zeros((0, 7, 7)))


def test_a_track_no_longer_reported_is_lost_until_reported_again_or_expired():
    lt = store()
    lose(lt, 4, state(10.0))
    assert list(lt.lost) == [4]
    np.testing.assert_array_equal(lt.lost[4].mean, state(10.0))  # the last reported state
    lt.observe(0.2, np.array([4]), state(12.0)[None], cov()[None])  # reported again by itself
    assert lt.lost == {}
    lose(lt, 5, state(10.0), t=1.0)
    lt.observe(6.0, np.zeros(0, dtype=int), np.zeros((0, 7)), np.zeros((0, 7, 7)))  # 4.9 s later: kept
    assert list(lt.lost) == [5]
    lt.observe(6.2, np.zeros(0, dtype=int), np.zeros((0, 7)), np.zeros((0, 7, 7)))  # 5.1 s: expired
    assert lt.lost == {}


def test_last_reported_is_last_frames_state_of_a_reported_track():
    lt = store()
    assert lt.last_reported(4) is None
    lt.observe(0.0, np.array([4, 6]), np.stack([state(10.0), state(30.0)]), np.stack([cov(), cov(0.5)]))
    mean, c = lt.last_reported(6)
    np.testing.assert_array_equal(mean, state(30.0))
    np.testing.assert_array_equal(c, cov(0.5))
    lt.observe(0.1, np.array([6]), state(31.0)[None], cov()[None])
    assert lt.last_reported(4) is None  # lost in this frame
    np.testing.assert_array_equal(lt.last_reported(6)[0], state(31.0))


def test_a_newcomer_at_the_predicted_position_takes_the_label_a_far_one_does_not():
    lt = store()
    lose(lt, 4, state(10.0, v=10.0))
    # 2 s later the lost car is predicted at s = 30 m: a newcomer there takes label 4 (once)
    far = lt.match(2.0, np.stack([state(60.0)]), cov()[None])
    assert far.tolist() == [-1] and list(lt.lost) == [4]
    near = lt.match(2.0, np.stack([state(30.5, 0.2)]), cov()[None])
    assert near.tolist() == [4] and lt.lost == {}
    # the gate grows with the time lost: 2.5 m off is outside it after 0.2 s, inside after 3 s
    lt = store()
    lose(lt, 4, state(10.0, v=10.0))
    assert lt.match(0.3, state(12.0 + 2.5)[None], cov()[None]).tolist() == [-1]
    assert lt.match(3.1, state(40.0 + 2.5)[None], cov()[None]).tolist() == [4]


def test_newcomers_are_assigned_one_to_one_to_the_nearest_predictions():
    lt = store()
    lt.observe(0.0, np.array([1, 2]), np.stack([state(10.0, -1.75), state(10.0, 1.75)]), np.stack([cov(), cov()]))
    lt.observe(0.1, np.zeros(0, dtype=int), np.zeros((0, 7)), np.zeros((0, 7, 7)))
    got = lt.match(1.0, np.stack([state(20.0, 1.6), state(20.2, -1.9)]), np.stack([cov(), cov()]))
    assert got.tolist() == [2, 1]


def test_on_a_closed_road_the_position_difference_is_taken_the_short_way_round():
    length = RING.length
    for period, expected in ((length, [7]), (None, [-1])):
        lt = store(RING, period=period)
        lose(lt, 7, state(length - 4.0, v=10.0))
        # 0.35 s later the lost car is predicted 0.5 m before the seam; the newcomer is 0.2 m past it
        assert lt.match(0.35, state(0.2)[None], cov()[None]).tolist() == expected


def test_a_coasting_track_is_a_candidate_at_its_current_state():
    lt = store()
    coasting = (np.array([9]), state(50.0)[None], cov()[None])
    assert lt.match(1.0, state(50.4)[None], cov()[None], coasting).tolist() == [9]
    assert lt.match(1.0, state(56.0)[None], cov()[None], coasting).tolist() == [-1]


def test_the_gate_allows_for_acceleration_since_the_last_update_along_the_heading():
    # lost after 2.4 s without an update (reported, coasting, from t = -2.4 s): a car accelerating at
    # 2 m/s^2 meanwhile is 5.8 m ahead of the constant-speed prediction
    for accel, expected in ((0.0, [-1]), (2.0, [4])):
        lt = store(accel=accel)
        lt.observe(-2.4, np.array([4]), state(-14.0)[None], cov()[None])
        lt.observe(0.0, np.array([4]), state(10.0)[None], cov()[None], updated=np.array([False]))
        lt.observe(0.1, np.zeros(0, dtype=int), np.zeros((0, 7)), np.zeros((0, 7, 7)))
        assert lt.lost[4].updated == -2.4
        assert lt.match(0.5, state(15.0 + 5.8)[None], cov()[None]).tolist() == expected
    # only along the heading: 5.8 m across the road is not allowed for
    lt = store(accel=2.0)
    lose(lt, 4, state(10.0))
    assert lt.match(2.5, state(35.0, 5.8)[None], cov()[None]).tolist() == [-1]
    # Cartesian states: along psi (here +y)
    north = np.array([0.0, 10.0, 10.0, np.pi / 2, 0.0, 4.5, 1.8])
    for offset, expected in (((0.0, 2.0 * 0.5 * 2.4**2), [4]), ((2.0 * 0.5 * 2.4**2, 0.0), [-1])):
        lt = store(accel=2.0, cartesian=True)
        lose(lt, 4, north)
        moved = north + np.array([offset[0], 24.0 + offset[1], 0, 0, 0, 0, 0])  # 2.4 s at 10 m/s, then off
        assert lt.match(2.4, moved[None], cov()[None]).tolist() == expected


def lose_after_coasting(lt: LostTracks, label: int, x: np.ndarray, updated: float, lost: float) -> None:
    """``label`` last updated at ``updated`` (state ``x`` then), reported coasting until ``lost``."""
    lt.observe(updated, np.array([label]), x[None], cov()[None])
    coasted = x + np.array([x[2] * (lost - updated), 0, 0, 0, 0, 0, 0])
    lt.observe(lost, np.array([label]), coasted[None], cov()[None], updated=np.array([False]))
    lt.observe(lost + 0.1, np.zeros(0, dtype=int), np.zeros((0, 7)), np.zeros((0, 7, 7)))


def test_the_reach_behind_the_prediction_is_what_braking_loses_and_ends_at_standstill():
    # a car at 9 m/s unseen for 1.9 s: 12 m behind its constant-speed prediction needs 6.6 m/s^2 of
    # braking (allowed with brake 8: up to 14.4 m); 12 m ahead needs that much acceleration (not with accel 2)
    for brake, behind, ahead in ((8.0, [4], [-1]), (None, [-1], [-1])):
        lt = store(accel=2.0, brake=brake)
        lose_after_coasting(lt, 4, state(100.0, v=9.0), updated=0.0, lost=1.0)
        at = 100.0 + 9.0 * 1.9
        assert lt.match(1.9, state(at - 12.0, v=3.0)[None], cov()[None]).tolist() == behind
        assert lt.match(1.9, state(at + 12.0, v=14.0)[None], cov()[None]).tolist() == ahead
    # a car at 2 m/s braking at 8 m/s^2 stops after 0.25 m: after 3 s it lies at most 5.75 m behind the
    # prediction (not 0.5 * 8 * 3^2 = 36 m: it does not drive backwards)
    for gap, expected in ((5.5, [4]), (12.0, [-1])):
        lt = store(accel=2.0, brake=8.0)
        lose_after_coasting(lt, 4, state(100.0, v=2.0), updated=0.0, lost=0.5)
        assert lt.match(3.0, state(106.0 - gap, v=0.0)[None], cov()[None]).tolist() == expected


def test_a_car_that_braked_while_hidden_keeps_its_label_not_the_bus_behind_it():
    # stop-and-go (seed 17): a car (label 5, last updated at 4.3 s) and, behind it in the same lane, a
    # bus (label 8, last updated at 2.8 s), both hidden and coasting until lost; the car braked from 9 to
    # 3 m/s and re-appears at 6.2 s 12 m behind its prediction and 25 m ahead of the bus's. The reach
    # behind the car's prediction is what braking loses (14 m), the bus's ahead what 2 m/s^2 gains
    # (12 m): the car's own label. With a symmetric 2 m/s^2 reach neither (and with a Gaussian spread
    # as the allowance, the bus's, grown for longer, would take the car).
    bus, car = state(112.0, 3.9, 7.5), state(158.0, 3.9, 9.0)
    at = lambda x, t0, t: x + np.array([x[2] * (t - t0), 0, 0, 0, 0, 0, 0])  # noqa: E731 (coasting)
    for brake, expected in ((8.0, [5]), (None, [-1])):
        lt = store(accel=2.0, brake=brake)
        lt.observe(2.8, np.array([8]), bus[None], cov()[None])
        lt.observe(4.3, np.array([8, 5]), np.stack([at(bus, 2.8, 4.3), car]), np.stack([cov(), cov()]),
                   updated=np.array([False, True]))
        lt.observe(5.6, np.array([8, 5]), np.stack([at(bus, 2.8, 5.6), at(car, 4.3, 5.6)]), np.stack([cov(), cov()]),
                   updated=np.array([False, False]))
        lt.observe(5.8, np.array([8]), at(bus, 2.8, 5.8)[None], cov()[None], updated=np.array([False]))
        lt.observe(5.9, np.zeros(0, dtype=int), np.zeros((0, 7)), np.zeros((0, 7, 7)))
        assert sorted(lt.lost) == [5, 8] and lt.lost[8].updated == 2.8 and lt.lost[5].updated == 4.3
        assert lt.match(6.2, state(162.9, 3.8, 2.8)[None], cov()[None]).tolist() == expected


@pytest.mark.parametrize("window", [0.0])
def test_window_zero_never_reidentifies(window):
    lt = store(window=window)
    lose(lt, 4, state(10.0))
    assert lt.lost == {}
    assert lt.match(0.5, state(15.0)[None], cov()[None]).tolist() == [-1]


def test_a_track_that_stops_being_reported_in_the_newcomers_frame_is_a_candidate():
    """The track drops out of the report in the same frame as the newcomer appears (before ``observe``
    stores it as lost): given this frame's reported labels, it is a candidate like a stored one; without
    them (the old behaviour) the newcomer found no candidate (curvy-multi seed 1, 8.9 s)."""
    for reported, expected in ((np.array([9]), [6]), (None, [-1])):
        lt = store()
        lt.observe(0.0, np.array([6]), state(10.0, v=10.0)[None], cov()[None])
        lt.observe(0.1, np.array([6]), state(11.0, v=10.0)[None], cov()[None])
        newcomer = np.stack([state(12.2, 0.1)])  # where label 6 is predicted at 0.2 s
        assert lt.match(0.2, newcomer, cov()[None], reported=reported).tolist() == expected
        if reported is not None:
            lt.observe(0.2, np.array([6]), newcomer, cov()[None])  # the newcomer now reports label 6
            assert lt.lost == {}
    lt = store()  # a label still reported this frame is not a candidate
    lt.observe(0.0, np.array([6]), state(10.0)[None], cov()[None])
    assert lt.match(0.1, np.stack([state(11.0)]), cov()[None], reported=np.array([6, 9])).tolist() == [-1]


def test_observe_keeps_the_records_the_per_track_store_kept():
    """``observe`` keeps the frame's arrays and makes a lost track's record only when it is lost: over
    random frames (labels coming, going, coming back, repeated in a frame; some not updated; the
    window expiring) the store holds what a record per reported track gave: the same lost labels in
    the same order, each with the state it was last reported with and when it was last updated, and
    the same ``last_updated``; a length mismatch is refused."""
    rng = np.random.default_rng(3)
    lt = store(window=0.35)
    last: dict[int, tuple] = {}  # the reference: label -> (t, mean, cov, updated) of last frame's tracks
    lost: dict[int, tuple] = {}
    for k in range(60):
        t = 0.1 * k
        labels = rng.choice(8, rng.integers(0, 6)).tolist()  # repeats possible: the last row counts
        means = rng.normal(size=(len(labels), 7))
        covs = rng.normal(size=(len(labels), 7, 7))
        updated = (rng.random(len(labels)) < 0.6).tolist()
        lt.observe(t, np.array(labels, dtype=int) if k % 2 else labels, means, covs,
                   None if k % 7 == 0 else (updated if k % 3 else np.array(updated)))
        if k % 7 == 0:
            updated = [True] * len(labels)
        now = {}
        for lab, m, p, up in zip(labels, means, covs, updated):
            now[lab] = (t, m, p, t if up or lab not in last else last[lab][3])
        for lab, entry in last.items():
            if lab not in now:
                lost[lab] = entry
        lost = {lab: e for lab, e in lost.items() if lab not in now and t - e[0] <= lt.window}
        last = now
        assert list(lt.lost) == list(lost)
        for lab, (t0, m, p, up) in lost.items():
            e = lt.lost[lab]
            assert e.t == t0 and e.updated == up and np.array_equal(e.mean, m) and np.array_equal(e.cov, p)
        for lab in range(9):
            assert lt.last_updated(lab, -1.0) == (last[lab][3] if lab in last else -1.0)
    with pytest.raises(ValueError, match="as many"):
        lt.observe(9.0, [1, 2], np.zeros((1, 7)), np.zeros((2, 7, 7)))


@pytest.mark.parametrize("against", [False, True], ids=["along", "against"])
def test_a_track_lost_while_turning_matches_where_it_followed_its_lane(against):
    """A car lost while it turned 20 deg off its lane at 0.5 rad/s (cutting an intersection's corner)
    comes back 2 s later where following its lane puts it: its own prediction lies metres to the side
    (the road-following prior relaxes the turn only over seconds), so only the lane-following
    prediction matches it. The same for a car driving against ``s`` (course pi + 20 deg)."""
    sign = -1.0 if against else 1.0
    lost = np.array([100.0, 0.0, 10.0, (np.pi if against else 0.0) + 0.35, 0.5, 4.5, 1.8])
    back = state(100.0 + sign * 20.0)[None]
    for lane_following, label in ((False, -1), (True, 4)):
        lt = store(lane_following=lane_following)
        lose(lt, 4, lost)
        predicted, _ = lt._predicted(2.1, [4])
        assert abs(predicted[0, 1]) > 3.0  # the turning prediction: metres off the lane
        assert lt.match(2.1, back, cov()[None])[0] == label
    # a car in the other lane, 3.5 m to the side of the lane-following prediction, is not the lost one
    lt = store(lane_following=True)
    lose(lt, 4, np.array([100.0, 0.0, 10.0, (np.pi if against else 0.0), 0.0, 4.5, 1.8]))
    assert lt.match(2.1, state(100.0 + sign * 20.0, 3.5)[None], cov()[None])[0] == -1
