"""Motion models of a target, vectorised over any leading axes (sigma points, components).

Three models share one interface (``MotionModel``: ``propagate(x, dt)``, ``process_noise(mean, dt)``,
``wrapping``), so the UKF prediction ``predict`` is the same for all:

- ``FrenetMotion`` (default): the exact Frenet kinematics of a rigid body moving at speed ``v`` with
  heading ``psi = theta(s) + xi`` along a road of curvature ``kappa(s)``::

      s' = v cos(xi) / (1 - kappa(s) n),   n' = v sin(xi),   v' = 0,   xi' = xi_dot,   xi_dot' = 0

  with the acceleration state (``MotionConfig.acceleration``, on by default) an eighth, internal state ``a``:
  ``v' = a``, ``a' = -a / acceleration_time`` (Singer);
  plus the road-following prior (``MotionConfig.heading_decay``, ``yaw_rate_decay``): ``xi' = xi_dot -
  heading_decay (xi + beta - pi round((xi + beta) / pi))``, ``xi_dot' = -yaw_rate_decay xi_dot`` (0 and 0
  give the constant turn above): the course relaxes toward the road's axis in the direction the vehicle
  drives, 0 along ``s`` and pi against it (an oncoming vehicle's lane, or one parked facing the other
  way), so no prior ever turns a vehicle around,
  integrated with classic RK4 in ``ceil(dt / max_step)`` sub-steps (with ``MotionConfig.slip_lever > 0``
  the centre moves along ``xi + beta`` instead of ``xi``, ``beta`` the kinematic slip angle of a
  kinematic bicycle whose rear axle lies ``slip_lever * L`` behind the centre, ``sin beta = yaw_rate
  slip_lever L / v`` (``|sin beta| <= MAX_SIN_SLIP``, ``|v|`` floored at ``SLIP_MIN_SPEED``): ``psi``
  is the body axis, the rectangle's, and a car holding its lane on a curve has ``xi = -beta``),
  evaluating the road's
  ``kappa(s)`` at every stage -- from a table of the road's curvature every ``CURVATURE_TABLE_STEP``
  metres, interpolated linearly (exact on a curvature profile's straights, arcs and clothoid ramps
  between joints; error ``<= h^2/8 max|kappa''|`` on a spline road; a table lookup costs microseconds
  where a curve evaluation costs ~100 us of numpy overhead per call). Lane keeping is ``xi = xi_dot = 0``: ``n`` stays constant exactly.
  ``1 - kappa n`` is floored at ``MotionConfig.min_denominator`` (only a point beyond the centre of
  curvature reaches it).
- ``PaperMotion``: the paper's constant turn in ``(s, n)``, which treats the road frame as flat::

      s += 2 v / xi_dot sin(xi_dot dt / 2) cos(xi + xi_dot dt / 2),   n += ... sin(xi + xi_dot dt / 2)

  written as ``v dt sinc(xi_dot dt / 2) cos(...)`` so ``xi_dot -> 0`` needs no division. On a curve it
  advances ``s`` at ``v`` instead of ``v / (1 - kappa n)``: off the centerline it drifts along the lane.
- ``CartesianMotion``: the constant-turn model of the Cartesian state ``[x, y, v, psi, psi_dot, L, W]``
  in G (the same closed form with ``x, y, psi``; exact for a constant turn).

``L`` and ``W`` are constant in all three. The additive process noise (``process_noise``) is the same
construction in both coordinate systems (see ``process_noise``).
"""

from __future__ import annotations

import dataclasses
import math
from functools import lru_cache
from typing import Protocol

import numpy as np
from scipy.linalg import expm

from tracker.angles import wrap_angle
from tracker.config import MotionConfig, ProcessNoise, TrackerConfig
from tracker.road import Road
from tracker.jit import njit
from tracker.ukf import UnscentedTransform, Wrapping, _wrap, all_finite, moments_kernel, sigma_kernel

# state indices (curvilinear names; the Cartesian state uses the same slots for x, y, psi, psi_dot);
# ACCEL: the internal acceleration state of ``FrenetMotion`` with ``MotionConfig.acceleration``
S, N, V, XI, XI_DOT, LENGTH, WIDTH, ACCEL = range(8)


#: Largest ``rate * h`` of an RK4 sub-step ``h`` on the road-following prior's decay (``FrenetMotion.step_limit``).
MAX_DECAY_STEP = 0.5

#: ``ukf_predict_kernel``'s ``relax`` and ``floor`` where the acceleration is left as it is.
_NO_RELAX = np.zeros(0)

#: Spacing (m) of the curvature table ``FrenetMotion`` interpolates.
CURVATURE_TABLE_STEP = 0.25


def curvilinear_wrapping(road: Road) -> Wrapping:
    """Wrapped coordinates of the curvilinear state: ``xi`` always, ``s`` on a closed road."""
    return Wrapping(angles=(XI,), periods=((S, road.length),) if road.closed else ())


CARTESIAN_WRAPPING = Wrapping(angles=(XI,))


def _check_dt(dt: float) -> float:
    dt = float(dt)
    if not math.isfinite(dt) or dt < 0:
        raise ValueError(f"dt must be a finite time step >= 0 s; got {dt!r}")
    return dt


def _constant_turn(x: np.ndarray, dt: float) -> np.ndarray:
    """Closed-form constant turn on slots (0, 1, 2, 3, 4) = (position a, position b, v, heading, rate)."""
    out = np.array(x, dtype=float, copy=True)
    v, h, w = x[..., V], x[..., XI], x[..., XI_DOT]
    half = 0.5 * w * dt
    chord = v * dt * np.sinc(half / np.pi)  # 2 v / w sin(w dt / 2), finite as w -> 0
    out[..., S] += chord * np.cos(h + half)
    out[..., N] += chord * np.sin(h + half)
    out[..., XI] = h + w * dt
    return out


#: Largest slip angle (rad) the motion model assumes (|sin beta| <= 0.5); speeds below ``SLIP_MIN_SPEED``
#: (m/s) count as that speed in the slip angle (a standing vehicle has no defined slip).
MAX_SIN_SLIP = 0.5
SLIP_MIN_SPEED = 1.0


def process_noise(mean: np.ndarray, dt: float, noise: ProcessNoise) -> np.ndarray:
    """Process noise covariance ``Q (..., 7, 7)`` over ``dt`` (s) about ``mean (..., 7)``.

    With ``u = (cos h, sin h)`` the direction of motion in the position slots (``h = xi`` in road
    coordinates, ``psi`` in Cartesian ones; the road metric ``1 - kappa n`` is ignored here) and ``u_perp``
    its left normal::

        Q[pos, pos] = accel^2 dt^3/3 u u^T + (along^2 u u^T + lateral^2 u_perp u_perp^T) dt
        Q[pos, v]   = accel^2 dt^2/2 u,              Q[v, v] = accel^2 dt
        Q[h, h]     = yaw_accel^2 dt^3/3 + heading^2 dt,  Q[h, h_dot] = yaw_accel^2 dt^2/2,
        Q[h_dot, h_dot] = yaw_accel^2 dt,   Q[L, L] = length^2 dt,   Q[W, W] = width^2 dt

    i.e. white acceleration and yaw acceleration integrated exactly over the step, plus direct random
    walks. Units follow ``ProcessNoise``.
    """
    dt = _check_dt(dt)
    mean = np.asarray(mean, dtype=float)
    c, s = np.cos(mean[..., XI]), np.sin(mean[..., XI])
    q0, k_u, k_p, a2d2 = noise_coefficients(dt, noise)
    q = np.broadcast_to(q0, mean.shape[:-1] + (7, 7)).copy()
    # the direction's entries (the same products as k_u u u^T + k_p u_perp u_perp^T element by element)
    cc, cs, ss = c * c, c * s, s * s
    q[..., 0, 0] = k_u * cc + k_p * ss
    q[..., 0, 1] = q[..., 1, 0] = k_u * cs + k_p * -cs
    q[..., 1, 1] = k_u * ss + k_p * cc
    q[..., 0, V] = q[..., V, 0] = a2d2 * c
    q[..., 1, V] = q[..., V, 1] = a2d2 * s
    return q


def noise_coefficients(dt: float, noise: ProcessNoise) -> tuple[np.ndarray, float, float, float]:
    """``process_noise``'s parts over ``dt`` (s): the entries that do not depend on the direction of
    motion ``q0 (7, 7)`` (zero in the position block and its ``v`` column), and the coefficients
    ``k_u = accel^2 dt^3/3 + along^2 dt``, ``k_p = lateral^2 dt`` and ``accel^2 dt^2/2`` of
    ``Q[pos, pos] = k_u u u^T + k_p u_perp u_perp^T`` and ``Q[pos, v] = accel^2 dt^2/2 u``."""
    a2, y2 = noise.accel**2, noise.yaw_accel**2
    d1, d2, d3 = dt, dt * dt / 2.0, dt**3 / 3.0
    q0 = np.zeros((7, 7))
    q0[V, V] = a2 * d1
    q0[XI, XI] = y2 * d3 + noise.heading**2 * d1
    q0[XI, XI_DOT] = q0[XI_DOT, XI] = y2 * d2
    q0[XI_DOT, XI_DOT] = y2 * d1
    q0[LENGTH, LENGTH] = noise.length**2 * d1
    q0[WIDTH, WIDTH] = noise.width**2 * d1
    return q0, a2 * d3 + noise.along**2 * d1, noise.lateral**2 * d1, a2 * d2


class MotionModel(Protocol):
    """What ``predict`` needs from a motion model."""

    wrapping: Wrapping
    noise: ProcessNoise
    dim: int  # state dimension (7, or 8 with FrenetMotion's acceleration state)

    def propagate(self, x: np.ndarray, dt: float) -> np.ndarray:
        """States ``x (..., 7)`` moved forward by ``dt`` seconds."""
        ...

    def process_noise(self, mean: np.ndarray, dt: float) -> np.ndarray:
        """Additive noise covariance ``(..., 7, 7)`` over ``dt``."""
        ...


class FrenetMotion:
    """Exact Frenet kinematics on ``road`` (see the module docstring), RK4 with sub-steps of at most
    ``config.max_step`` seconds."""

    def __init__(self, road: Road, config: MotionConfig | None = None, noise: ProcessNoise | None = None) -> None:
        self.road = road
        self.config = config if config is not None else MotionConfig()
        self.noise = noise if noise is not None else ProcessNoise()
        self.wrapping = curvilinear_wrapping(road)
        count = max(2, int(math.ceil(road.length / CURVATURE_TABLE_STEP)) + 1)
        self._table_s = np.linspace(0.0, road.length, count)
        if road.closed:
            self._table_s[-1] = 0.0  # the road's own wrap; restored below
        self._table_k = road.curvature(self._table_s)
        self._table_s[-1] = road.length
        #: the tracker's state dimension: 8 with the acceleration state (``MotionConfig.acceleration``),
        #: else 7; ``propagate`` and ``process_noise`` take either (seven states: constant speed)
        self.dim = 8 if self.config.acceleration else 7
        # the white acceleration on v: lower with the acceleration state (MotionConfig.residual_accel)
        self._noise7 = (dataclasses.replace(self.noise, accel=self.config.residual_accel) if self.dim == 8
                        else self.noise)
        self._noise_cache: dict[float, tuple] = {}  # _noise_parts by dt
        self._step_cache: dict[float, tuple] = {}  # _step_args by dt

    @property
    def step_limit(self) -> float:
        """Largest RK4 sub-step (s): ``max_step``, and at most ``MAX_DECAY_STEP / rate`` for the
        road-following prior's rates (RK4 on ``x' = -rate x`` is accurate for ``rate h <= 0.5`` and
        unstable beyond ``rate h ~ 2.8``; the defaults, 2/s at 0.1 s, are 0.2)."""
        rate = max(self.config.heading_decay, self.config.yaw_rate_decay,
                   1.0 / self.config.acceleration_time if self.dim == 8 else 0.0)
        return min(self.config.max_step, MAX_DECAY_STEP / rate) if rate > 0.0 else self.config.max_step

    def propagate(self, x: np.ndarray, dt: float) -> np.ndarray:
        """States ``x (..., 7 or 8)`` after ``dt`` seconds: classic RK4 of the Frenet kinematics (the
        module docstring; ``rk4_propagate``) in ``ceil(dt / step_limit)`` equal sub-steps; ``s`` wrapped
        on a closed road and ``xi`` to (-pi, pi]."""
        dt = _check_dt(dt)
        x = np.array(x, dtype=float, copy=True)
        if dt == 0.0:
            return x
        if x.ndim == 0 or x.shape[-1] not in (7, 8):
            raise ValueError(f"FrenetMotion.propagate needs states (..., 7) or (..., 8); got shape {x.shape}")
        steps, h, motion_args = self._step_args(dt)
        flat = rk4_propagate(np.ascontiguousarray(x.reshape(-1, x.shape[-1])), steps, h, *motion_args)
        return self.wrapping.wrap(flat.reshape(x.shape))

    def process_noise(self, mean: np.ndarray, dt: float, jerk: np.ndarray | None = None) -> np.ndarray:
        """See ``process_noise``; with the road-following prior (``heading_decay`` or
        ``yaw_rate_decay`` > 0) the ``(xi, xi_dot)`` block is ``heading_noise_block``'s exact one; with
        the acceleration state ``(8, 8)``: the white acceleration ``residual_accel`` instead of
        ``ProcessNoise.accel``, plus the Singer block of ``(v, a)`` for white jerk ``jerk`` (m s^-2.5):
        ``MotionConfig.jerk``, or one value per state (shape ``mean.shape[:-1]``: the tracker's
        manoeuvre-gated jerk, ``MotionConfig.quiet_jerk``). The block is ``jerk^2`` times the unit
        jerk's."""
        mean = np.asarray(mean, dtype=float)
        with_accel = mean.shape[-1] == 8
        q = process_noise(mean[..., :7], dt, self._noise7 if with_accel else self.noise)
        if self.config.heading_decay > 0.0 or self.config.yaw_rate_decay > 0.0:
            q[..., XI:XI_DOT + 1, XI:XI_DOT + 1] = heading_noise_block(
                dt, self.config.heading_decay, self.config.yaw_rate_decay, self.noise)
        if with_accel:  # (v, a): the Singer block of white jerk, on top of the white acceleration on v
            q8 = np.zeros(q.shape[:-2] + (8, 8))
            q8[..., :7, :7] = q
            block = _heading_noise_block(float(_check_dt(dt)), 0.0, 1.0 / self.config.acceleration_time, 0.0, 1.0)
            scale = (self.config.jerk**2 if jerk is None
                     else np.broadcast_to(np.asarray(jerk, dtype=float) ** 2, mean.shape[:-1]))
            q8[..., V, V] += scale * block[0, 0]
            q8[..., V, ACCEL] += scale * block[0, 1]
            q8[..., ACCEL, V] += scale * block[1, 0]
            q8[..., ACCEL, ACCEL] += scale * block[1, 1]
            q = q8
        return q

    def predict_compiled(self, ut: UnscentedTransform, mean: np.ndarray, cov: np.ndarray, dt: float,
                         jerk: np.ndarray | None = None, relax: np.ndarray | None = None,
                         floor: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray] | None:
        """``predict`` of a batch ``mean (C, D)``, ``cov (C, D, D)`` in one call of
        ``ukf_predict_kernel`` (the same numbers as ``predict``'s steps one by one); ``None`` where it
        does not apply (``dt = 0``, another shape, or a covariance that is not positive definite:
        ``predict`` then takes its steps one by one, and the sigma points' repair counts it)."""
        if mean.ndim != 2 or mean.shape[1] != self.dim or cov.shape != mean.shape + (self.dim,) or len(mean) == 0:
            return None
        dt = _check_dt(dt)
        if dt == 0.0:
            return None
        if relax is None and floor is None:
            relax = floor = _NO_RELAX
        else:
            relax = np.ones(len(mean)) if relax is None else np.ascontiguousarray(relax, dtype=float)
            floor = np.full(len(mean), -np.inf) if floor is None else np.ascontiguousarray(floor, dtype=float)

        if self.dim == 8:
            if jerk is None:
                scale = np.full(len(mean), self.config.jerk**2)
            elif type(jerk) is np.ndarray and jerk.dtype == np.float64 and jerk.shape == (len(mean),):
                scale = jerk**2
            else:
                scale = np.ascontiguousarray(np.broadcast_to(np.asarray(jerk, dtype=float) ** 2, mean.shape[:-1]))
        else:
            scale = np.zeros(len(mean))
        (steps, h, motion_args), (q_const, k_u, k_p, a2d2, singer) = self._step_args(dt), self._noise_parts(dt)
        try:
            m, p, finite = ukf_predict_kernel(
                np.ascontiguousarray(mean, dtype=float), np.ascontiguousarray(cov, dtype=float), relax, floor,
                ut.scale, ut.wm, ut.wc, *self.wrapping.kernel_args(), steps, h, *motion_args, q_const, k_u, k_p, a2d2,
                scale, singer)
        except np.linalg.LinAlgError:
            return None
        if not finite:
            raise ValueError("sigma_points: mean and cov must be finite (a NaN/inf entered the filter)")
        return m, p

    def _step_args(self, dt: float) -> tuple[int, float, tuple]:
        """The RK4 sub-steps over ``dt`` (their count and length, s) and the model's arguments of
        ``ukf_predict_kernel`` after them (the curvature table, the road, ``MotionConfig``'s numbers);
        cached by ``dt`` with ``_noise_parts``."""
        hit = self._step_cache.get(dt)
        if hit is None:
            steps = max(1, int(math.ceil(dt / self.step_limit - 1e-9)))
            cfg = self.config
            if len(self._step_cache) >= 64:
                self._step_cache.clear()
            self._step_cache[dt] = hit = (steps, dt / steps, (
                self._table_s, self._table_k, bool(self.road.closed), float(self.road.length), float(cfg.min_denominator),
                float(cfg.slip_lever), float(cfg.heading_decay), float(cfg.yaw_rate_decay), float(cfg.acceleration_time),
                MAX_SIN_SLIP, SLIP_MIN_SPEED))
        return hit

    def _noise_parts(self, dt: float) -> tuple[np.ndarray, float, float, float, np.ndarray]:
        """``process_noise``'s parts for ``ukf_predict_kernel`` over ``dt`` (cached: a tracker's frames
        mostly share one ``dt``): the direction-free entries ``(D, D)`` (the road-following prior's
        heading block in place; without the jerk's Singer block), ``k_u``, ``k_p``, ``accel^2 dt^2/2``
        (``noise_coefficients``), and the unit jerk's Singer block ``(2, 2)`` of ``(v, a)`` (zeros
        without the acceleration state)."""
        hit = self._noise_cache.get(dt)
        if hit is not None:
            return hit
        q0, k_u, k_p, a2d2 = noise_coefficients(dt, self._noise7 if self.dim == 8 else self.noise)
        if self.config.heading_decay > 0.0 or self.config.yaw_rate_decay > 0.0:
            q0[XI:XI_DOT + 1, XI:XI_DOT + 1] = heading_noise_block(
                dt, self.config.heading_decay, self.config.yaw_rate_decay, self.noise)
        q = np.zeros((self.dim, self.dim))
        q[:7, :7] = q0
        singer = (_heading_noise_block(dt, 0.0, 1.0 / self.config.acceleration_time, 0.0, 1.0).copy() if self.dim == 8
                  else np.zeros((2, 2)))
        if len(self._noise_cache) >= 64:
            self._noise_cache.clear()
        self._noise_cache[dt] = hit = (q, float(k_u), float(k_p), float(a2d2), singer)
        return hit


def heading_noise_block(dt: float, heading_decay: float, yaw_rate_decay: float, noise: ProcessNoise) -> np.ndarray:
    """See ``_heading_noise_block``; cached by its arguments (a tracker's frames mostly share one ``dt``:
    the matrix exponential costs ~100 us, a cache hit ~1 us). Returns a new array."""
    return _heading_noise_block(float(dt), float(heading_decay), float(yaw_rate_decay),
                                float(noise.heading), float(noise.yaw_accel)).copy()


@lru_cache(maxsize=256)
def _heading_noise_block(dt: float, heading_decay: float, yaw_rate_decay: float, heading: float, yaw_accel: float) -> np.ndarray:
    """Covariance ``(2, 2)`` of ``(xi, xi_dot)`` added over ``dt`` by the mean-reverting heading model
    (also the Singer block of ``(v, a)``: ``a = 0``, ``b = 1 / acceleration_time``, ``heading = 0``,
    ``yaw_accel = jerk``)

        d xi = (xi_dot - a xi) dt + heading dW_1,     d xi_dot = -b xi_dot dt + yaw_accel dW_2

    (``a = heading_decay``, ``b = yaw_rate_decay``): ``Q = int_0^dt e^{At} G G^T e^{A^T t} dt`` with
    ``A = [[-a, 1], [0, -b]]``, computed exactly by Van Loan's matrix exponential. With ``a = b = 0`` it
    is ``process_noise``'s block (``yaw_accel^2 [[dt^3/3, dt^2/2], [dt^2/2, dt]] + heading^2 dt``); with
    ``a, b > 0`` it stays bounded as ``dt`` grows (the stationary covariance). Van Loan's exponential
    holds ``e^{-At}``, which overflows for long gaps: it is taken over ``dt / 2^k`` with
    ``max(a, b, 1) dt / 2^k <= 1`` and doubled ``k`` times (``Q(2t) = F Q(t) F^T + Q(t)``, ``F = e^{At}``)."""
    dt = _check_dt(dt)
    a_mat = np.array([[-heading_decay, 1.0], [0.0, -yaw_rate_decay]])
    gg = np.diag([heading**2, yaw_accel**2])
    doublings = max(0, int(math.ceil(math.log2(max(heading_decay, yaw_rate_decay, 1.0) * dt + 1e-300))))
    step = dt / 2.0**doublings
    van_loan = np.zeros((4, 4))
    van_loan[:2, :2] = -a_mat
    van_loan[:2, 2:] = gg
    van_loan[2:, 2:] = a_mat.T
    e = expm(van_loan * step)
    f = e[2:, 2:].T  # e^{A step}
    q = f @ e[:2, 2:]
    for _ in range(doublings):
        q = f @ q @ f.T + q
        f = f @ f
    return 0.5 * (q + q.T)


class PaperMotion:
    """The paper's flat constant-turn model in ``(s, n)`` (module docstring); ``road`` only sets the
    wrapping of ``s`` on a closed road."""

    dim = 7

    def __init__(self, road: Road, noise: ProcessNoise | None = None) -> None:
        self.road = road
        self.noise = noise if noise is not None else ProcessNoise()
        self.wrapping = curvilinear_wrapping(road)

    def propagate(self, x: np.ndarray, dt: float) -> np.ndarray:
        """Closed-form constant turn in ``(s, n, xi)`` over ``dt`` seconds."""
        return self.wrapping.wrap(_constant_turn(np.asarray(x, dtype=float), _check_dt(dt)))

    def process_noise(self, mean: np.ndarray, dt: float) -> np.ndarray:
        """See ``process_noise``."""
        return process_noise(mean, dt, self.noise)


class CartesianMotion:
    """Constant turn of the Cartesian state ``[x, y, v, psi, psi_dot, L, W]`` in G::

        x += 2 v / psi_dot sin(psi_dot dt / 2) cos(psi + psi_dot dt / 2),  y += ... sin(...),  psi += psi_dot dt
    """

    dim = 7

    def __init__(self, noise: ProcessNoise | None = None) -> None:
        self.noise = noise if noise is not None else ProcessNoise()
        self.wrapping = CARTESIAN_WRAPPING

    def propagate(self, x: np.ndarray, dt: float) -> np.ndarray:
        """Closed-form constant turn over ``dt`` seconds; ``psi`` wrapped to (-pi, pi]."""
        return self.wrapping.wrap(_constant_turn(np.asarray(x, dtype=float), _check_dt(dt)))

    def process_noise(self, mean: np.ndarray, dt: float) -> np.ndarray:
        """See ``process_noise``."""
        return process_noise(mean, dt, self.noise)


def make_motion(config: TrackerConfig, road: Road) -> FrenetMotion | PaperMotion | CartesianMotion:
    """The motion model a ``TrackerConfig`` asks for: Cartesian constant turn for a Cartesian state,
    else ``FrenetMotion`` (``motion.model = "frenet"``) or ``PaperMotion`` (``"paper"``)."""
    if config.coordinates == "cartesian":
        return CartesianMotion(config.process_noise)
    if config.motion.model == "paper":
        return PaperMotion(road, config.process_noise)
    return FrenetMotion(road, config.motion, config.process_noise)


def relax_acceleration(mean: np.ndarray, cov: np.ndarray, relax: np.ndarray | None,
                       floor: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """Gaussians ``mean (C, 8)``, ``cov (C, 8, 8)`` with each one's acceleration (state 7) scaled by
    ``relax[c]`` (the linear map ``a -> f a``: the mean, the covariance's row and column) and then its
    variance raised to at least ``floor[c]``; None: not. New arrays where changed."""
    if relax is not None:
        mean, cov = mean.copy(), cov.copy()
        mean[:, ACCEL] *= relax
        cov[:, ACCEL, :] *= relax[:, None]
        cov[:, :, ACCEL] *= relax[:, None]
    if floor is not None:
        cov = cov.copy()
        cov[:, ACCEL, ACCEL] = np.maximum(cov[:, ACCEL, ACCEL], floor)
    return mean, cov


def predict(
    ut: UnscentedTransform, model: MotionModel, mean: np.ndarray, cov: np.ndarray, dt: float,
    jerk: np.ndarray | None = None, relax: np.ndarray | None = None, floor: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """UKF prediction of Gaussians ``mean (..., 7)``, ``cov (..., 7, 7)`` over ``dt`` seconds:
    ``m' = sum Wm f(X_i)``, ``P' = sum Wc (f(X_i) - m')(f(X_i) - m')^T + Q(m', dt)`` (wrapped residuals).
    ``jerk`` (one per Gaussian; ``FrenetMotion`` with the acceleration state only) replaces
    ``MotionConfig.jerk`` in ``Q``. ``relax`` and ``floor`` (one per Gaussian, ``(C, 8)`` states only:
    ``relax_acceleration``) change the acceleration first (the tracker's coasting relaxation and a
    manoeuvre's onset)."""
    if (relax is not None or floor is not None) and (np.ndim(mean) != 2 or np.shape(mean)[1] != 8 or any(
            x is not None and np.shape(x) != (len(mean),) for x in (relax, floor))):
        raise ValueError(f"predict: relax and floor need Gaussians of the acceleration state (C, 8), one value per "
                         f"Gaussian; got means {np.shape(mean)}, relax {np.shape(relax)}, floor {np.shape(floor)}")
    fused = getattr(model, "predict_compiled", None)
    if fused is not None and np.ndim(mean) == 2:
        out = fused(ut, np.asarray(mean, dtype=float), np.asarray(cov, dtype=float), dt, jerk, relax, floor)
        if out is not None:
            return out
    if relax is not None or floor is not None:
        mean, cov = relax_acceleration(np.asarray(mean, dtype=float), np.asarray(cov, dtype=float), relax, floor)
    pts = ut.sigma_points(mean, cov, model.wrapping)
    moved = model.propagate(pts, dt)
    noise = (lambda m: model.process_noise(m, dt)) if jerk is None else (lambda m: model.process_noise(m, dt, jerk))
    if moved.ndim == 3:  # a batch: the moments in one call
        m, p = moments_kernel(np.ascontiguousarray(moved), ut.wm, ut.wc, *model.wrapping.kernel_args())
        p += noise(m)
        return m, 0.5 * (p + np.swapaxes(p, -1, -2))
    # one Gaussian (or another batch shape): the unscented transform's own moments (numpy's sums, whose
    # order can differ from the kernel's in the last bits)
    m = ut.mean(moved, model.wrapping)
    dev = ut.deviations(moved, m, model.wrapping)
    p = ut.covariance(dev) + noise(m)
    return m, 0.5 * (p + np.swapaxes(p, -1, -2))

# --------------------------------------------------------------------------------------------------
# The compiled kernels of this stage.
#
# The Frenet kinematics (the module docstring) integrated by classic RK4 over all states in one call
# (``rk4_propagate``, for ``FrenetMotion.propagate``; the wrapping stays with the caller): the road's
# curvature by linear interpolation of ``FrenetMotion``'s table (wrapped on a closed road, 0 beyond an
# open road's ends), the kinematic slip, the road-following prior's decays and the optional
# acceleration state. ``ukf_predict_kernel``: the whole UKF prediction of a batch (sigma points, RK4,
# moments, process noise) in one call, ``predict``'s steps for ``FrenetMotion``.
# --------------------------------------------------------------------------------------------------


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
    """The road's curvature (1/m) at ``s`` from ``FrenetMotion``'s table ``(table_s, table_k)``,
    interpolated linearly: wrapped on a closed road, 0 beyond the ends of an open one (the road's
    straight extrapolation)."""
    if not closed and (s < table_s[0] or s > table_s[-1]):
        return 0.0
    return _interp(s % length if closed else s, table_s, table_k)  # Python's float modulo: numpy's np.mod


@njit(inline="always")
def _derivative(x, out, params):
    """``dx/dt`` of one state ``x`` into ``out`` (``params`` as ``rk4_propagate``'s)::

        [v cos(xi + beta) / max(1 - kappa(s) n, min_denominator), v sin(xi + beta), a,
         xi_dot - heading_decay (xi + beta - pi round((xi + beta) / pi)), -yaw_rate_decay xi_dot, 0, 0,
         -a / acceleration_time]

    with ``a`` the acceleration state (8 coordinates; else ``v`` constant) and the kinematic slip angle
    ``beta`` (0 when ``slip_lever = 0``): ``sin beta = yaw_rate slip_lever L / v``, clipped to
    ``+-max_sin_slip``, ``|v|`` floored at ``slip_min_speed``, for the yaw rate ``kappa v cos(xi) / (1 -
    kappa n) + xi_dot``. The curvature ``kappa(s)`` is ``_curvature``'s."""
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
    out[3] = xi_dot - heading_decay * (course - math.pi * math.floor(course / math.pi + 0.5))
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
    ``relax[c]`` (the mean, then the covariance's row, then its column, in ``relax_acceleration``'s
    order) and its variance then raised to at least ``floor[c]`` (``numpy.maximum``'s rule: a NaN
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
