"""Vehicles that do not follow their lane: a radar course across it, and the quarter turn it resolves.

A rectangle fitted to lidar points is ambiguous by quarter turns; the tracker resolves that by the
lane (vehicles drive along their lane). A vehicle crossing the lane (at an intersection, turning into
a side street) does not, and its outline alone cannot say so while only part of it is on the road. Its
radar velocity can: a vehicle moves along its heading, so a course that crosses the reference heading
(the lane's, at a birth; a track's, at an update) at 45-135 deg says the reference is a quarter turn
off (``crossing_courses``). A birth then takes that course as its reference (``tracker.birth``); a
component whose own cluster's radar course crosses its heading at nearly a right angle in consecutive
frames (``TURN_TOLERANCE``, ``TURN_FRAMES``), and whose speed agrees with that
velocity's part along its heading (``agrees_along``: a crossing car tracked along the road shows ~0 m/s
there; a detection not its own contradicts the speed the track knows), is turned by the quarter turn
nearer that course (``turn_to_course``), heading the way the radar says, the longer extent its length,
before the cluster updates it.
"""

from __future__ import annotations

import numpy as np

from tracker.angles import wrap_angle
from tracker.motion import LENGTH, V, WIDTH, XI
#: A track is turned only for a course within this of a right angle to its heading (rad; 30 deg): a
#: quarter turn off, not a vehicle turning (whose heading the updates follow) nor a stray detection.
TURN_TOLERANCE = np.pi / 6
#: ... shown by its own clusters in this many consecutive frames (one stray radar detection turns nothing).
TURN_FRAMES = 2
#: Standard deviations within which a radar velocity's part along a component's heading must agree with its speed (``agrees_along``).
AGREE_SIGMAS = 3.0


def crossing_courses(velocity: np.ndarray, heading: np.ndarray, min_speed: float,
                     tolerance: float = 0.25 * np.pi) -> np.ndarray:
    """The courses (rad, in E) of radar velocities ``velocity (N, 2)`` (E, m/s) at least ``min_speed``
    (m/s) fast that cross their reference ``heading (N,)`` (rad, in E: a lane's direction, or a track's
    heading) within ``tolerance`` (rad; default 45 deg: 45-135 deg) of a right angle: vehicles not
    following it, whose heading the reference does not give; NaN for the others (too slow for the
    course to be known to better than ~10 deg, along the reference, or against it: at a birth, the
    detection of a vehicle passing in the other direction, ``tracker.birth.BACKWARD_SPEED``)."""
    velocity = np.asarray(velocity, dtype=float).reshape(-1, 2)
    course = np.arctan2(velocity[:, 1], velocity[:, 0])
    off = np.abs(np.abs(wrap_angle(course - np.asarray(heading, dtype=float))) - 0.5 * np.pi)
    crossing = (np.hypot(velocity[:, 0], velocity[:, 1]) >= min_speed) & (off < tolerance)
    return np.where(crossing, course, np.nan)


def crossing_course(velocity: np.ndarray | None, heading: float, min_speed: float | None) -> float | None:
    """``crossing_courses`` of one radar ``velocity (vx, vy)`` and reference ``heading`` (45-135 deg);
    ``None`` where it gives NaN, without a velocity or with ``min_speed`` None (off)."""
    if velocity is None or min_speed is None:
        return None
    course = float(crossing_courses(np.asarray(velocity, dtype=float)[None, :], np.array([heading]), min_speed)[0])
    return None if np.isnan(course) else course


def agrees_along(speed: np.ndarray, speed_var: np.ndarray, heading: np.ndarray, velocity: np.ndarray,
                 radar_var: float, sigmas: float = AGREE_SIGMAS) -> np.ndarray:
    """Whether the parts of radar velocities ``velocity (N, 2)`` (E, m/s) along components' ``heading
    (N,)`` (rad, in E) agree with their ``speed (N,)`` within ``sigmas`` standard deviations (their
    ``speed_var (N,)`` plus the radar's ``radar_var``, m^2/s^2). A vehicle tracked a quarter turn off,
    crossing the road, shows its tracked speed near 0 and a course across it; a detection that is not
    the vehicle's (clutter, another vehicle's) contradicts a speed the track knows."""
    velocity = np.asarray(velocity, dtype=float).reshape(-1, 2)
    along = velocity[:, 0] * np.cos(heading) + velocity[:, 1] * np.sin(heading)
    return np.abs(along - speed) <= sigmas * np.sqrt(np.maximum(speed_var, 0.0) + radar_var)


def turn_to_course(mean: np.ndarray, cov: np.ndarray, heading: float, course: float, speed: float,
                   speed_var: float) -> None:
    """Turn one component, ``mean (D,)`` and ``cov (D, D)`` in place, by the quarter turn from its
    ``heading`` (rad, in E) nearer the radar ``course`` (rad, in E): the heading state moves by +-pi/2;
    the longer of its two extents is its length (a road vehicle is longer than it is wide): where the
    width was the longer (the crossing side read as a width: the track followed the vehicle's points
    turned a quarter off), length and width and their rows and columns of ``cov`` are exchanged and the
    rectangle stays where it was; otherwise (the vehicle turned under a track that kept its extent) the
    rectangle turns with the heading about its centre. The speed becomes the radar's ``speed`` (m/s)
    with variance ``speed_var`` (m^2/s^2), its correlations dropped (the old speed was along the wrong
    axis)."""
    turn = 0.5 * np.pi if float(wrap_angle(course - heading)) > 0.0 else -0.5 * np.pi
    mean[XI] = float(wrap_angle(mean[XI] + turn))  # xi, or psi in the Cartesian state: the same row
    if mean[WIDTH] > mean[LENGTH]:
        order = np.arange(len(mean))
        order[LENGTH], order[WIDTH] = WIDTH, LENGTH
        mean[:] = mean[order]
        cov[:] = cov[np.ix_(order, order)]
    mean[V] = speed
    cov[V, :] = 0.0
    cov[:, V] = 0.0
    cov[V, V] = speed_var
