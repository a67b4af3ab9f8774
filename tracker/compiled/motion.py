"""Compiled Frenet motion: ``FrenetMotion.propagate``'s RK4 sub-steps of ``FrenetMotion.derivative``
(``tracker.motion``) over all states in one numba call: the curvature by linear interpolation of the
same table (wrapped on a closed road, 0 beyond an open road's ends), the kinematic slip, the
road-following prior's decays and the optional acceleration state (``rk4_propagate``; wrapping stays
with the caller). ``ukf_predict_kernel``: the whole UKF prediction of a batch (sigma points, RK4,
moments, process noise) in one call, the same steps as ``tracker.motion.predict``'s compiled path."""

from __future__ import annotations

import math

import numpy as np

from tracker.compiled import njit
from tracker.compiled.ukf import _wrap, all_finite, moments_kernel, sigma_kernel


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
    if not closed and (s < table_s[0] or s > table_s[-1]):
        return 0.0
    return _interp(s % length if closed else s, table_s, table_k)  # Python's float modulo: numpy's np.mod


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
    k = np.empty((4, dim))  # the four stages' slopes
    tmp = np.empty(dim)
    half = 0.5 * h
    for i in range(count):
        xi = out[i]
        for _ in range(steps):
            # one call site of the (inlined) derivative for the four stages: the state of stage q is
            # x + c_q k_{q-1} with c = (0, h/2, h/2, h), the first stage's the state itself
            for q in range(4):
                if q == 0:
                    tmp[:] = xi
                else:
                    c = h if q == 3 else half
                    for j in range(dim):
                        tmp[j] = xi[j] + c * k[q - 1, j]
                _derivative(tmp, k[q], params)
            for j in range(dim):
                xi[j] = xi[j] + (h / 6.0) * (k[0, j] + 2.0 * k[1, j] + 2.0 * k[2, j] + k[3, j])
    return out


@njit(inline="always")
def _relaxed(means, covs, relax, floor):  # pragma: no cover - compiled
    """Copies of ``means (C, 8)``, ``covs (C, 8, 8)`` with each acceleration (state 7) scaled by
    ``relax[c]`` (the mean, then the covariance's row, then its column: ``tracker.motion.predict``'s
    numpy order) and its variance then raised to at least ``floor[c]`` (``numpy.maximum``'s rule: a NaN
    stays)."""
    means = means.copy()
    covs = covs.copy()
    dim = means.shape[1]
    for c in range(means.shape[0]):
        f = relax[c]
        means[c, 7] *= f
        for j in range(dim):
            covs[c, 7, j] *= f
        for j in range(dim):
            covs[c, j, 7] *= f
        if floor[c] > covs[c, 7, 7]:
            covs[c, 7, 7] = floor[c]
    return means, covs


@njit
def ukf_predict_kernel(means, covs, relax, floor, scale, wm, wc, angles, period_index, period, steps, h, table_s,
                       table_k, closed, length, min_denominator, slip_lever, heading_decay, yaw_rate_decay,
                       acceleration_time, max_sin_slip, slip_min_speed, q_const, k_u, k_p, a2d2, jerk_scale,
                       singer):  # pragma: no cover - compiled
    """``tracker.motion.predict`` with ``FrenetMotion`` in one call: the sigma points of ``N(means,
    covs)`` (``sigma_kernel``), ``steps`` RK4 steps of ``h`` s (``rk4_propagate``), wrapped, their
    weighted moments (``moments_kernel``), plus ``FrenetMotion.process_noise`` about the predicted
    mean, symmetrised. The noise's direction-free entries come as ``q_const (D, D)``; per state the
    position block ``k_u u u^T + k_p u_perp u_perp^T`` and ``Q[pos, v] = a2d2 u`` (``u`` the heading's
    direction), and with the acceleration state (``D = 8``) ``jerk_scale[c]`` times the unit jerk's
    Singer block ``singer (2, 2)`` on ``(v, a)``. With the acceleration state the Gaussians are first
    ``_relaxed`` by ``relax`` and ``floor`` (one each per Gaussian; empty: not). Returns ``(mean, cov,
    finite)``; ``finite`` False (and nothing computed) when a mean or covariance holds a NaN or an
    infinity."""
    count, dim = means.shape
    if len(relax):
        means, covs = _relaxed(means, covs, relax, floor)
    if not all_finite(means, covs):
        return means.copy(), covs.copy(), False
    pts = sigma_kernel(means, covs, scale, angles, period_index, period)
    sigma = pts.shape[1]
    moved = rk4_propagate(pts.reshape(count * sigma, dim), steps, h, table_s, table_k, closed, length,
                          min_denominator, slip_lever, heading_decay, yaw_rate_decay, acceleration_time,
                          max_sin_slip, slip_min_speed)
    for i in range(count * sigma):
        _wrap(moved[i], angles, period_index, period)
    mean, cov = moments_kernel(moved.reshape(count, sigma, dim), wm, wc, angles, period_index, period)
    q = np.empty((dim, dim))
    out = np.empty((count, dim, dim))
    for c in range(count):
        q[:, :] = q_const
        co, si = math.cos(mean[c, 3]), math.sin(mean[c, 3])
        cc, cs, ss = co * co, co * si, si * si
        q[0, 0] = k_u * cc + k_p * ss
        q[0, 1] = k_u * cs + k_p * -cs
        q[1, 0] = q[0, 1]
        q[1, 1] = k_u * ss + k_p * cc
        q[0, 2] = a2d2 * co
        q[2, 0] = q[0, 2]
        q[1, 2] = a2d2 * si
        q[2, 1] = q[1, 2]
        if dim == 8:
            q[2, 2] += jerk_scale[c] * singer[0, 0]
            q[2, 7] += jerk_scale[c] * singer[0, 1]
            q[7, 2] += jerk_scale[c] * singer[1, 0]
            q[7, 7] += jerk_scale[c] * singer[1, 1]
        for j in range(dim):
            for k in range(dim):
                cov[c, j, k] += q[j, k]
        for j in range(dim):
            for k in range(dim):
                out[c, j, k] = 0.5 * (cov[c, j, k] + cov[c, k, j])
    return mean, out, True
