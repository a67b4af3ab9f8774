"""The Frenet kinematics of ``tracker.motion.FrenetMotion`` and the UKF prediction, in numpy: the
state derivative, classic RK4 in equal sub-steps, and the prediction from ``oracles.ukf``'s steps."""

from __future__ import annotations

import math

import numpy as np

from oracles.ukf import moments, sigma_points, wrap
from tracker.motion import MAX_SIN_SLIP, SLIP_MIN_SPEED, FrenetMotion
from tracker.ukf import UnscentedTransform


def slip_angle(yaw_rate: np.ndarray, v: np.ndarray, length: np.ndarray, lever: float) -> np.ndarray:
    """Kinematic slip angle ``beta`` (rad) of a kinematic bicycle whose rear axle lies ``lever * L``
    behind the centre: ``sin beta = yaw_rate lever L / v``, ``|sin beta| <= MAX_SIN_SLIP``, ``|v|``
    floored at ``SLIP_MIN_SPEED``."""
    v = np.asarray(v, dtype=float)
    speed = np.where(v < 0.0, -1.0, 1.0) * np.maximum(np.abs(v), SLIP_MIN_SPEED)
    sin_b = yaw_rate * lever * np.maximum(length, 0.0) / speed
    return np.arcsin(np.clip(sin_b, -MAX_SIN_SLIP, MAX_SIN_SLIP))


def curvature(model: FrenetMotion, s: np.ndarray) -> np.ndarray:
    """The road's curvature from the model's table, interpolated linearly: wrapped on a closed road,
    0 beyond the ends of an open one."""
    road = model.road
    if road.closed:
        return np.interp(np.mod(s, road.length), model._table_s, model._table_k)
    return np.interp(s, model._table_s, model._table_k, left=0.0, right=0.0)


def derivative(model: FrenetMotion, x: np.ndarray) -> np.ndarray:
    """``dx/dt`` of states ``x (..., 7 or 8)``: ``[v cos(xi + beta) / (1 - kappa n), v sin(xi + beta),
    a, xi_dot - heading_decay (xi + beta - pi round((xi + beta) / pi)), -yaw_rate_decay xi_dot, 0, 0, -a / acceleration_time]``
    (``1 - kappa n`` floored at ``min_denominator``; ``a`` and ``v' = a`` with the acceleration state
    only; ``beta`` the slip angle of the yaw rate ``kappa v cos(xi) / (1 - kappa n) + xi_dot``)."""
    cfg = model.config
    s, n, v, xi, xi_dot, length = (x[..., i] for i in range(6))
    kappa = curvature(model, s)
    denom = np.maximum(1.0 - kappa * n, cfg.min_denominator)
    course = xi
    if cfg.slip_lever > 0.0:
        course = xi + slip_angle(kappa * v * np.cos(xi) / denom + xi_dot, v, length, cfg.slip_lever)
    d = np.zeros_like(x)
    d[..., 0] = v * np.cos(course) / denom
    d[..., 1] = v * np.sin(course)
    d[..., 3] = xi_dot - cfg.heading_decay * (course - np.pi * np.floor(course / np.pi + 0.5))
    d[..., 4] = -cfg.yaw_rate_decay * xi_dot
    if x.shape[-1] == 8:
        d[..., 2] = x[..., 7]
        d[..., 7] = -x[..., 7] / cfg.acceleration_time
    return d


def propagate(model: FrenetMotion, x: np.ndarray, dt: float) -> np.ndarray:
    """RK4 of ``derivative`` over ``dt`` in ``ceil(dt / step_limit)`` equal sub-steps, wrapped."""
    x = np.array(x, dtype=float)
    steps = max(1, math.ceil(dt / model.step_limit - 1e-9))
    h = dt / steps
    for _ in range(steps):
        k1 = derivative(model, x)
        k2 = derivative(model, x + 0.5 * h * k1)
        k3 = derivative(model, x + 0.5 * h * k2)
        k4 = derivative(model, x + h * k3)
        x = x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return wrap(x, model.wrapping)


def predict(ut: UnscentedTransform, model: FrenetMotion, mean: np.ndarray, cov: np.ndarray, dt: float,
            jerk: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The UKF prediction: the moments of the propagated sigma points plus the model's process noise
    about the predicted mean (``FrenetMotion.process_noise``, tested on its own), symmetrised."""
    moved = propagate(model, sigma_points(mean, cov, ut.scale, model.wrapping), dt)
    m, p = moments(moved, ut.wm, ut.wc, model.wrapping)
    p = p + (model.process_noise(m, dt) if jerk is None else model.process_noise(m, dt, jerk))
    return m, 0.5 * (p + np.swapaxes(p, -1, -2))
