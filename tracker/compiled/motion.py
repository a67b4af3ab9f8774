"""Compiled Frenet motion: ``FrenetMotion.propagate``'s RK4 sub-steps of ``FrenetMotion.derivative``
(``tracker.motion``) over all states in one numba call: the curvature by linear interpolation of the
same table (wrapped on a closed road, 0 beyond an open road's ends), the kinematic slip, the
road-following prior's decays and the optional acceleration state. Wrapping stays with the caller."""

from __future__ import annotations

import math

import numpy as np

from tracker.compiled import njit


@njit(inline="always")
def _interp(x, xp, fp):
    """``numpy.interp`` at one ``x`` inside ``[xp[0], xp[-1]]`` (the same formula, no allocation).
    ``xp`` is the uniform table of ``FrenetMotion`` (from 0): the interval comes from ``x / step``,
    then moves to the one binary search finds (the last ``j`` with ``xp[j] <= x``) where rounding put
    the quotient across a knot."""
    last = len(xp) - 1
    if x >= xp[last]:
        return fp[last]
    if x < xp[0]:
        return fp[0]
    j = min(int(x * (last / xp[last])), last - 1)
    while j < last - 1 and xp[j + 1] <= x:
        j += 1
    while j > 0 and xp[j] > x:
        j -= 1
    return (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j]) * (x - xp[j]) + fp[j]


@njit(inline="always")
def _curvature(s, table_s, table_k, closed, length):
    if closed:
        return _interp(s % length, table_s, table_k)  # Python's float modulo: numpy's np.mod
    if s < table_s[0] or s > table_s[-1]:
        return 0.0
    return _interp(s, table_s, table_k)


@njit(inline="always")
def _derivative(x, out, params):
    """``FrenetMotion.derivative`` of one state ``x`` into ``out``; ``params`` as ``rk4_propagate``'s."""
    (table_s, table_k, closed, length, min_denominator, slip_lever, heading_decay, yaw_rate_decay,
     acceleration_time, max_sin_slip, slip_min_speed) = params
    s, n, v, xi, xi_dot = x[0], x[1], x[2], x[3], x[4]
    kappa = _curvature(s, table_s, table_k, closed, length)
    denom = max(1.0 - kappa * n, min_denominator)
    course = xi
    if slip_lever > 0.0:
        yaw_rate = kappa * v * math.cos(xi) / denom + xi_dot
        speed = (-1.0 if v < 0.0 else 1.0) * max(abs(v), slip_min_speed)
        sin_b = yaw_rate * slip_lever * max(x[5], 0.0) / speed
        course = course + math.asin(min(max(sin_b, -max_sin_slip), max_sin_slip))
    out[:] = 0.0
    out[0] = v * math.cos(course) / denom
    out[1] = v * math.sin(course)
    out[3] = xi_dot - heading_decay * course
    out[4] = -yaw_rate_decay * xi_dot
    if len(x) == 8:
        out[2] = x[7]
        out[7] = -x[7] / acceleration_time


@njit
def rk4_propagate(x, steps, h, table_s, table_k, closed, length, min_denominator, slip_lever, heading_decay,
                  yaw_rate_decay, acceleration_time, max_sin_slip, slip_min_speed):
    """States ``x (N, D)`` (D = 7 or 8) after ``steps`` RK4 steps of ``h`` seconds (a new array)."""
    params = (table_s, table_k, closed, length, min_denominator, slip_lever, heading_decay, yaw_rate_decay,
              acceleration_time, max_sin_slip, slip_min_speed)
    count, dim = x.shape
    out = x.copy()
    k1 = np.empty(dim)
    k2 = np.empty(dim)
    k3 = np.empty(dim)
    k4 = np.empty(dim)
    tmp = np.empty(dim)
    for i in range(count):
        xi = out[i]
        for _ in range(steps):
            _derivative(xi, k1, params)
            for j in range(dim):
                tmp[j] = xi[j] + 0.5 * h * k1[j]
            _derivative(tmp, k2, params)
            for j in range(dim):
                tmp[j] = xi[j] + 0.5 * h * k2[j]
            _derivative(tmp, k3, params)
            for j in range(dim):
                tmp[j] = xi[j] + h * k3[j]
            _derivative(tmp, k4, params)
            for j in range(dim):
                xi[j] = xi[j] + (h / 6.0) * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
    return out
