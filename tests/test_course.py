"""tracker.course: a radar course across a reference heading, and the quarter turn it resolves."""

from __future__ import annotations

import numpy as np
import pytest

from tracker.course import TURN_TOLERANCE, agrees_along, crossing_course, crossing_courses, turn_to_course
from tracker.measurement import rectangle_corners


def test_crossing_course_only_for_a_fast_course_off_the_reference():
    assert crossing_course(np.array([0.0, 8.0]), 0.0, 3.0) == pytest.approx(np.pi / 2)
    assert crossing_course(np.array([8.0, 7.0]), 0.0, 3.0) is None  # 41 deg off: following it
    assert crossing_course(np.array([8.0, 8.5]), 0.0, 3.0) == pytest.approx(np.arctan2(8.5, 8.0))
    assert crossing_course(np.array([-8.0, 0.0]), np.pi, 3.0) is None  # an oncoming lane's own traffic
    assert crossing_course(np.array([8.0, -1.0]), np.pi, 3.0) is None  # against it: another vehicle's detection
    assert crossing_course(np.array([-8.0, 9.0]), 0.0, 3.0) == pytest.approx(np.arctan2(9.0, -8.0))  # 132 deg
    assert crossing_course(np.array([0.0, 2.9]), 0.0, 3.0) is None  # too slow for a course
    assert crossing_course(None, 0.0, 3.0) is None and crossing_course(np.array([0.0, 8.0]), 0.0, None) is None


def test_crossing_courses_of_a_track_need_nearly_a_right_angle():
    """At an update the course must lie within 30 deg of a right angle to the track's heading (0.3 rad
    here): 65 and 115 deg off cross it, 55 and 125 deg do not; headings per row."""
    angles = np.radians([65.0, 115.0, 55.0, 125.0, -70.0])
    heading = np.array([0.3, 0.3, 0.3, 0.3, 0.3])
    velocity = 8.0 * np.column_stack([np.cos(heading + angles), np.sin(heading + angles)])
    out = crossing_courses(velocity, heading, 3.0, TURN_TOLERANCE)
    np.testing.assert_allclose(out[[0, 1, 4]], np.arctan2(velocity[[0, 1, 4], 1], velocity[[0, 1, 4], 0]))
    assert np.isnan(out[[2, 3]]).all()


def test_a_radar_velocity_agrees_along_a_heading_within_three_sigmas():
    """A track heading 0 at 0.2 m/s (variance 0.5): a radar velocity (0.5, 8) agrees (0.3 m/s off, the
    bound 3 sqrt(0.5 + 0.25) = 2.6 m/s); (4, 8) does not (3.8 m/s off); nor does any crossing
    detection on a track known to move at 11 m/s (a stray detection)."""
    velocity = np.array([[0.5, 8.0], [4.0, 8.0], [0.5, 8.0]])
    ok = agrees_along(np.array([0.2, 0.2, 11.0]), np.array([0.5, 0.5, 0.5]), np.zeros(3), velocity, 0.25)
    assert ok.tolist() == [True, False, False]


@pytest.mark.parametrize("course", [np.pi / 2 + 0.1, -np.pi / 2 - 0.1])
def test_a_quarter_turn_keeps_the_rectangle_and_heads_along_the_course(course):
    """A component heading 0.05 rad, 2.2 x 4.6 m (its crossing side read as its width), turned to a radar
    course of about +-pi/2: the same four corners, heading +-pi/2 from before (the turn nearer the
    course), length and width exchanged with their variances and covariance, the radar's speed with no
    correlation left to the speed."""
    rng = np.random.default_rng(3)
    mean = np.array([10.0, 1.0, 0.5, 0.05, 0.01, 2.2, 4.6])
    a = rng.normal(size=(7, 7))
    cov = a @ a.T + 7 * np.eye(7)
    before_mean, before_cov = mean.copy(), cov.copy()
    turn_to_course(mean, cov, 0.05, course, 8.0, 4.0)
    assert mean[3] == pytest.approx(0.05 + np.sign(course) * np.pi / 2)
    assert (mean[5], mean[6]) == (before_mean[6], before_mean[5])
    assert mean[2] == 8.0 and cov[2, 2] == 4.0 and not cov[2, [0, 1, 3, 4, 5, 6]].any()
    assert cov[5, 5] == before_cov[6, 6] and cov[6, 6] == before_cov[5, 5] and cov[5, 6] == before_cov[6, 5]
    assert cov[0, 5] == before_cov[0, 6] and cov[3, 6] == before_cov[3, 5]
    np.testing.assert_allclose(cov, cov.T)
    corners = rectangle_corners(mean[:2], np.array(mean[3]), np.array(mean[5]), np.array(mean[6]))
    before = rectangle_corners(before_mean[:2], np.array(before_mean[3]), np.array(before_mean[5]), np.array(before_mean[6]))
    assert {tuple(np.round(c, 9)) for c in corners} == {tuple(np.round(c, 9)) for c in before}


def test_a_quarter_turn_of_a_track_that_kept_its_length_turns_the_rectangle():
    """A component 4.8 x 2 m heading 0 (a vehicle that turned under a track keeping its extent): turned
    to a course of pi/2, its length stays the longer extent and the rectangle turns about its centre."""
    mean = np.array([10.0, 1.0, 0.5, 0.0, 0.0, 4.8, 2.0])
    cov = np.diag([0.1, 0.1, 1.0, 0.01, 0.01, 0.3, 0.05])
    before = cov.copy()
    turn_to_course(mean, cov, 0.0, np.pi / 2, 8.0, 4.0)
    assert mean[3] == pytest.approx(np.pi / 2) and (mean[5], mean[6]) == (4.8, 2.0)
    assert cov[5, 5] == before[5, 5] and cov[6, 6] == before[6, 6] and mean[2] == 8.0
