"""Physical truth from noisy recordings: a Rauch-Tung-Striebel smoother on a vehicle model, and a width
bound for passenger cars.

Video-tracked trajectories (NGSIM) move in ways vehicles cannot: speed steps of 4-7 m/s^2 for one
sample, headings that jitter by a few degrees, and near standstill centres that drift sideways, across
the vehicle's heading. ``smooth_vehicle`` replaces each recorded vehicle by the maximum a-posteriori
path of a vehicle model given its samples: an extended Kalman filter forward, then the RTS pass
backward (Sarkka, *Bayesian Filtering and Smoothing*, 2013, sec. 9.1), on the constant turn rate and
acceleration model (CTRA)

.. math::
    x = [p_x, p_y, \\psi, v, \\omega, a], \\quad
    \\dot p = v (\\cos\\psi, \\sin\\psi), \\ \\dot\\psi = \\omega, \\ \\dot v = a,
    \\ \\dot a = j, \\ \\dot\\omega = \\alpha,

with white jerk ``j`` (``jerk_psd``), white yaw acceleration ``alpha`` (``yaw_accel_psd``) and a small
white lateral velocity (``lateral_psd``: a vehicle does not move sideways, so the model allows only
that much), observing the recorded centre (``position_std``) and heading (``yaw_std``). A centre that
drifts across a stopped car's heading is then read as noise, a speed step as a brief acceleration.
The recorded speeds only start the filter (NGSIM derives them from the same positions).

Widths: NGSIM overestimates them (cars 2.3-2.6 m wide are recorded; the widest passenger vehicles on
US roads, full-size pickups and SUVs, are about 2.1 m without mirrors). ``SmootherConfig.max_car_width``
bounds the width of a vehicle of class "car" up to ``car_max_length`` long; the lengths are kept.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from sim.world.recording import RecordedVehicle, Recording


@dataclass(frozen=True)
class SmootherConfig:
    """The smoother's model (module docstring); SI units."""

    position_std: float = 0.3  #: m, standard deviation of a recorded centre coordinate
    yaw_std: float = math.radians(2.0)  #: rad, standard deviation of a recorded heading
    jerk_psd: float = 2.0  #: m^2/s^5, spectral density of the white jerk
    yaw_accel_psd: float = 0.1  #: rad^2/s^3, spectral density of the white yaw acceleration
    lateral_psd: float = 0.01  #: m^2/s, spectral density of the white lateral velocity (side slip)
    max_car_width: float | None = 2.1  #: m, the widest a vehicle of class "car" is taken to be (None: no bound)
    car_max_length: float = 6.0  #: m, the longest vehicle the car width bound applies to

    def __post_init__(self) -> None:
        for name in ("position_std", "yaw_std", "jerk_psd", "yaw_accel_psd", "lateral_psd", "car_max_length"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"SmootherConfig.{name} must be a positive number; got {value!r}")
        width = self.max_car_width
        if width is not None and not (isinstance(width, (int, float)) and math.isfinite(width) and width > 0):
            raise ValueError(f"SmootherConfig.max_car_width must be a positive number of metres or None; got {self.max_car_width!r}")


def _transition(x: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """CTRA mean over ``dt`` (second order in ``dt``) and its Jacobian."""
    px, py, psi, v, w, a = x
    c, s = math.cos(psi + 0.5 * w * dt), math.sin(psi + 0.5 * w * dt)
    d = v * dt + 0.5 * a * dt * dt
    out = np.array([px + d * c, py + d * s, psi + w * dt, v + a * dt, w, a])
    jac = np.eye(6)
    jac[0, 2], jac[1, 2] = -d * s, d * c
    jac[0, 3], jac[1, 3] = dt * c, dt * s
    jac[0, 4], jac[1, 4] = -d * s * 0.5 * dt, d * c * 0.5 * dt
    jac[0, 5], jac[1, 5] = 0.5 * dt * dt * c, 0.5 * dt * dt * s
    jac[2, 4] = dt
    jac[3, 5] = dt
    return out, jac


def _noise(psi: float, dt: float, config: SmootherConfig) -> np.ndarray:
    """Process noise over ``dt``: white jerk on (along-track position, v, a), white yaw acceleration on
    (psi, omega), white lateral velocity across the heading."""
    q = np.zeros((6, 6))
    j = config.jerk_psd * np.array([[dt**5 / 20, dt**4 / 8, dt**3 / 6],
                                    [dt**4 / 8, dt**3 / 3, dt**2 / 2],
                                    [dt**3 / 6, dt**2 / 2, dt]])
    along = np.array([math.cos(psi), math.sin(psi)])
    across = np.array([-along[1], along[0]])
    lift = np.zeros((3, 6))  # (along-track position, v, a) -> state
    lift[0, :2] = along
    lift[1, 3] = 1.0
    lift[2, 5] = 1.0
    q += lift.T @ j @ lift
    y = config.yaw_accel_psd * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
    q[np.ix_([2, 4], [2, 4])] += y
    q[:2, :2] += config.lateral_psd * dt * np.outer(across, across)
    return q


def smooth_vehicle(vehicle: RecordedVehicle, config: SmootherConfig = SmootherConfig()) -> RecordedVehicle:
    """``vehicle`` with its centre, heading, speed and yaw rate replaced by the RTS smoother's (module
    docstring; a single sample is kept as it is) and its width bounded (``max_car_width``)."""
    width = vehicle.width
    if config.max_car_width is not None and vehicle.kind == "car" and vehicle.length <= config.car_max_length:
        width = min(width, config.max_car_width)
    count = len(vehicle)
    if count < 2:
        return replace(vehicle, width=width)
    t = vehicle.t
    z = np.column_stack([vehicle.xy, vehicle.yaw])
    r = np.diag([config.position_std**2, config.position_std**2, config.yaw_std**2])
    h = np.zeros((3, 6))
    h[0, 0] = h[1, 1] = h[2, 2] = 1.0
    x = np.array([z[0, 0], z[0, 1], z[0, 2], float(vehicle.v[0]), 0.0, 0.0])
    p = np.diag([config.position_std**2, config.position_std**2, config.yaw_std**2, 4.0, 0.05, 4.0])
    means = np.zeros((count, 6))
    covs = np.zeros((count, 6, 6))
    pred_means = np.zeros((count, 6))
    pred_covs = np.zeros((count, 6, 6))
    jacs = np.zeros((count, 6, 6))
    for k in range(count):
        if k > 0:
            dt = float(t[k] - t[k - 1])
            x, jac = _transition(x, dt)
            p = jac @ p @ jac.T + _noise(float(x[2]), dt, config)
            jacs[k] = jac
        pred_means[k], pred_covs[k] = x, p
        s = h @ p @ h.T + r
        gain = np.linalg.solve(s, h @ p).T
        x = x + gain @ (z[k] - h @ x)
        p = (np.eye(6) - gain @ h) @ p
        p = 0.5 * (p + p.T)
        means[k], covs[k] = x, p
    smoothed = means.copy()
    for k in range(count - 2, -1, -1):
        c = np.linalg.solve(pred_covs[k + 1], jacs[k + 1] @ covs[k]).T
        smoothed[k] = means[k] + c @ (smoothed[k + 1] - pred_means[k + 1])
    speed = smoothed[:, 3]
    yaw = smoothed[:, 2]
    # the model's speed is signed; below zero (a standing vehicle's noise) it is taken as 0
    return replace(vehicle, xy=smoothed[:, :2], yaw=yaw, v=np.maximum(speed, 0.0), yaw_rate=smoothed[:, 4], width=width)


@dataclass(frozen=True)
class SmoothingReport:
    """What smoothing changed: ``vehicles``; ``widths_bounded`` (vehicles whose width was bounded);
    ``position_change_rms_m`` (RMS distance between recorded and smoothed centres); the largest
    |acceleration| (m/s^2) of the recorded speeds (``raw_accel_max``; differences between samples) and
    of the smoothed ones (``smoothed_accel_max``)."""

    vehicles: int
    widths_bounded: int
    position_change_rms_m: float
    raw_accel_max: float
    smoothed_accel_max: float


def _accel_max(vehicles: tuple[RecordedVehicle, ...]) -> float:
    steps = [np.abs(np.diff(v.v) / np.diff(v.t)) for v in vehicles if len(v) > 1]
    return float(max((a.max() for a in steps), default=0.0))


def smooth_recording(recording: Recording, config: SmootherConfig = SmootherConfig()) -> tuple[Recording, SmoothingReport]:
    """Every vehicle of ``recording`` smoothed (``smooth_vehicle``), and what that changed."""
    out = tuple(smooth_vehicle(v, config) for v in recording.vehicles)
    moved = np.concatenate([np.hypot(*(a.xy - b.xy).T) for a, b in zip(recording.vehicles, out)])
    report = SmoothingReport(
        vehicles=len(out),
        widths_bounded=sum(int(b.width < a.width) for a, b in zip(recording.vehicles, out)),
        position_change_rms_m=float(np.sqrt(np.mean(moved**2))) if moved.size else 0.0,
        raw_accel_max=_accel_max(recording.vehicles),
        smoothed_accel_max=_accel_max(out),
    )
    return replace(recording, vehicles=out), report


__all__ = ["SmootherConfig", "SmoothingReport", "smooth_recording", "smooth_vehicle"]
