"""The tracker's output ``Track`` and the state conversions between road and Cartesian coordinates.

Curvilinear state (index order fixed, docs/architecture.md): ``[s, n, v, xi, xi_dot, L, W]`` -- arc length (m) of
the rectangle centre's projection, lateral offset (m, positive left), absolute speed (m/s) along the
heading, heading relative to the road tangent ``xi`` (rad), its rate (rad/s), length and width (m).
Cartesian state in G: ``[x, y, v, psi, psi_dot, L, W]`` with ``psi = theta(s) + xi`` and the absolute yaw
rate ``psi_dot = xi_dot + kappa(s) s_dot``, ``s_dot = v cos(xi) / (1 - kappa n)`` (exact; the paper's
equation (MeasModel_eq4) drops the ``1 / (1 - kappa n)`` factor).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tracker.angles import wrap_angle
from tracker.road import Road
from tracker.ukf import UnscentedTransform, Wrapping

#: Floor of ``1 - kappa n`` in the yaw-rate conversion (a point at the centre of curvature has no
#: well-defined ``s_dot``).
MIN_METRIC = 0.1


def curvilinear_to_cartesian(road: Road, x: np.ndarray) -> np.ndarray:
    """Curvilinear states ``x (..., 7)`` to Cartesian states ``(..., 7)`` in G (module docstring).
    Open roads are extrapolated along their end tangents."""
    x = np.asarray(x, dtype=float)
    if x.shape[-1] != 7:
        raise ValueError(f"curvilinear states must have shape (..., 7); got {x.shape}")
    s, n, v, xi, xi_dot = (x[..., i] for i in range(5))
    xy, theta, kappa = road.frame(s, extrapolate=True)
    out = np.array(x, copy=True)
    out[..., 0] = xy[..., 0] - n * np.sin(theta)
    out[..., 1] = xy[..., 1] + n * np.cos(theta)
    out[..., 3] = wrap_angle(theta + xi)
    out[..., 4] = xi_dot + kappa * v * np.cos(xi) / np.maximum(1.0 - kappa * n, MIN_METRIC)
    return out


def cartesian_to_curvilinear(road: Road, x: np.ndarray, s_hint: np.ndarray | float | None = None) -> np.ndarray:
    """Cartesian states ``x (..., 7)`` in G to curvilinear states ``(..., 7)`` (nearest projection on
    the centerline, warm-started from ``s_hint`` where given; see ``Road.to_frenet``)."""
    x = np.asarray(x, dtype=float)
    if x.shape[-1] != 7:
        raise ValueError(f"Cartesian states must have shape (..., 7); got {x.shape}")
    flat = x.reshape(-1, 7)
    hint = None if s_hint is None else np.broadcast_to(np.asarray(s_hint, dtype=float), x.shape[:-1]).reshape(-1)
    s, n = road.to_frenet(flat[:, :2], s_hint=hint)
    s, n = np.asarray(s, dtype=float).reshape(-1), np.asarray(n, dtype=float).reshape(-1)
    _, theta, kappa = road.frame(s, extrapolate=True)
    out = flat.copy()
    out[:, 0], out[:, 1] = s, n
    xi = wrap_angle(flat[:, 3] - theta)
    out[:, 3] = xi
    out[:, 4] = flat[:, 4] - kappa * flat[:, 2] * np.cos(xi) / np.maximum(1.0 - kappa * n, MIN_METRIC)
    return out.reshape(x.shape)


def _readonly(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


@dataclass(frozen=True)
class Track:
    """One reported target: ``label`` (stable integer id), time ``t`` (s), curvilinear ``mean (7,)``
    ``[s, n, v, xi, xi_dot, L, W]`` and ``cov (7, 7)`` (SI units), and the GM-PHD ``weight``.
    Arrays are copied and read-only. ``cartesian(road)`` gives ``[x, y, v, psi, psi_dot, L, W]`` in G.
    ``extent`` is False for a point-object track (``tracker.point``): its ``L`` and ``W`` are the size the
    tracker assumes, not estimates, and evaluators must not score them."""

    label: int
    t: float
    mean: np.ndarray
    cov: np.ndarray
    weight: float = 1.0
    extent: bool = True

    def __post_init__(self) -> None:
        mean = np.array(self.mean, dtype=float).reshape(-1)
        cov = np.array(self.cov, dtype=float)
        if mean.shape != (7,):
            raise ValueError(f"Track.mean must have 7 entries [s, n, v, xi, xi_dot, L, W]; got shape {np.shape(self.mean)}")
        if cov.shape != (7, 7):
            raise ValueError(f"Track.cov must have shape (7, 7); got {cov.shape}")
        if not (np.isfinite(mean).all() and np.isfinite(cov).all()):
            raise ValueError("Track.mean and Track.cov must be finite")
        object.__setattr__(self, "label", int(self.label))
        object.__setattr__(self, "t", float(self.t))
        object.__setattr__(self, "weight", float(self.weight))
        object.__setattr__(self, "extent", bool(self.extent))
        object.__setattr__(self, "mean", _readonly(mean))
        object.__setattr__(self, "cov", _readonly(cov))

    @classmethod
    def checked_batch(cls, labels: np.ndarray | list[int], t: float, means: np.ndarray, covs: np.ndarray,
                      weights: np.ndarray | list[float]) -> list[Track]:
        """Tracks of ``means (K, 7)``, ``covs (K, 7, 7)`` checked at once (shapes, finiteness) instead of
        one by one: what ``Track(...)`` gives for each row, for the tracker's per-frame report."""
        means = np.array(means, dtype=float)
        covs = np.array(covs, dtype=float)
        if means.ndim != 2 or means.shape[1:] != (7,) or covs.shape != (len(means), 7, 7):
            raise ValueError(f"Track.checked_batch needs means (K, 7) and covs (K, 7, 7); got {means.shape}, {covs.shape}")
        if not (np.isfinite(means).all() and np.isfinite(covs).all()):
            raise ValueError("Track.mean and Track.cov must be finite")
        means.flags.writeable = False
        covs.flags.writeable = False
        labels = labels if isinstance(labels, list) else np.asarray(labels).tolist()
        weights = weights if isinstance(weights, list) else np.asarray(weights, dtype=float).tolist()
        t = float(t)
        new = object.__new__
        out = []
        for lab, m, p, w in zip(labels, means, covs, weights):
            track = new(cls)
            track.__dict__.update(label=int(lab), t=t, mean=m, cov=p, weight=float(w), extent=True)  # frozen: no __setattr__
            out.append(track)
        return out

    s = property(lambda self: float(self.mean[0]), doc="Arc length of the rectangle centre (m).")
    n = property(lambda self: float(self.mean[1]), doc="Lateral offset, positive left (m).")
    v = property(lambda self: float(self.mean[2]), doc="Speed along the heading (m/s).")
    xi = property(lambda self: float(self.mean[3]), doc="Heading relative to the road tangent (rad).")
    xi_dot = property(lambda self: float(self.mean[4]), doc="Rate of ``xi`` (rad/s).")
    length = property(lambda self: float(self.mean[5]), doc="Length (m).")
    width = property(lambda self: float(self.mean[6]), doc="Width (m).")

    def cartesian(self, road: Road) -> np.ndarray:
        """``[x, y, v, psi, psi_dot, L, W]`` in G (m, m/s, rad, rad/s)."""
        return curvilinear_to_cartesian(road, self.mean)

    def cartesian_cov(self, road: Road, ut: UnscentedTransform | None = None) -> np.ndarray:
        """Covariance ``(7, 7)`` of the Cartesian view, by the unscented transform."""
        ut = ut if ut is not None else UnscentedTransform()
        wrap_in = Wrapping(angles=(3,), periods=((0, road.length),) if road.closed else ())
        _, cov, _ = ut.transform(lambda x: curvilinear_to_cartesian(road, x), self.mean, self.cov, wrap_in,
                                 Wrapping(angles=(3,)))
        return cov

    def relative_s(self, road: Road, s_ego: float) -> float:
        """``s - s_ego`` (m), the paper's relative arc length; on a closed road the shortest way round."""
        d = self.s - float(s_ego)
        if road.closed:
            d -= road.length * np.floor(d / road.length + 0.5)
        return float(d)

    @classmethod
    def from_cartesian(
        cls,
        label: int,
        t: float,
        mean: np.ndarray,
        cov: np.ndarray,
        road: Road,
        weight: float = 1.0,
        ut: UnscentedTransform | None = None,
    ) -> Track:
        """A track from a Cartesian-state Gaussian (the Cartesian variant), converted to road
        coordinates by the unscented transform (mean and covariance)."""
        ut = ut if ut is not None else UnscentedTransform()
        mean = np.asarray(mean, dtype=float)
        hint = cartesian_to_curvilinear(road, mean)[0]
        wrap_out = Wrapping(angles=(3,), periods=((0, road.length),) if road.closed else ())
        m, c, _ = ut.transform(lambda x: cartesian_to_curvilinear(road, x, s_hint=hint), mean,
                               np.asarray(cov, dtype=float), Wrapping(angles=(3,)), wrap_out)
        return cls(label, t, m, c, weight)


__all__ = ["Track", "curvilinear_to_cartesian", "cartesian_to_curvilinear"]
