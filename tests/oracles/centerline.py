"""The frame of a road's centerline (``tracker.centerline``) at arc lengths ``s``, in numpy: each
``s``'s cell by binary search over the cell starts, then the cell's closed form with exact
trigonometry (no Taylor series) and an 8-point Gauss-Legendre rule (the kernels use 4 points)."""

from __future__ import annotations

import numpy as np

from tracker.centerline import GL_NODES, GL_WEIGHTS, ClothoidCenterline, HermiteCenterline


def cell_of(curve: HermiteCenterline | ClothoidCenterline, s: np.ndarray) -> np.ndarray:
    """Index of the cell holding each ``s`` in [0, length]: the last cell whose start is ``<= s``."""
    return np.clip(np.searchsorted(curve.starts, s, side="right") - 1, 0, len(curve.starts) - 2)


def hermite_frame(curve: HermiteCenterline, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position ``(N, 2)``, unit tangent ``(N, 2)`` and curvature ``(N,)``: the spline parameter is the
    cell's cubic ``tau(d)`` at ``d = s - start``; ``r(tau)`` the segment's cubic, the tangent ``r' / |r'|``
    and the curvature ``(r' x r'') / |r'|^3``."""
    cell = cell_of(curve, s)
    d = s - curve.starts[cell]
    q = curve.tau_poly[cell]  # (N, 4), lowest power first
    tau = q[:, 0] + q[:, 1] * d + q[:, 2] * d**2 + q[:, 3] * d**3
    c = curve.cell_coeffs[cell]  # (N, 4, 2): r(tau) = c0 + c1 tau + c2 tau^2 + c3 tau^3
    t = tau[:, None]
    r = c[:, 0] + c[:, 1] * t + c[:, 2] * t**2 + c[:, 3] * t**3
    r1 = c[:, 1] + 2.0 * c[:, 2] * t + 3.0 * c[:, 3] * t**2
    r2 = 2.0 * c[:, 2] + 6.0 * c[:, 3] * t
    speed = np.hypot(r1[:, 0], r1[:, 1])
    kappa = (r1[:, 0] * r2[:, 1] - r1[:, 1] * r2[:, 0]) / speed**3
    return r, r1 / speed[:, None], kappa


def clothoid_frame(curve: ClothoidCenterline, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position, unit tangent and curvature: at ``d = s - start`` into the cell the heading is
    ``theta(u) = theta0 + kappa0 u + rate u^2 / 2``, the curvature ``kappa0 + rate d`` and the position
    the cell's start plus ``int_0^d (cos theta(u), sin theta(u)) du``."""
    cell = cell_of(curve, s)
    d = s - curve.starts[cell]
    theta0, k0, rate = curve.cell_theta[cell], curve.cell_kappa[cell], curve.cell_rate[cell]

    def heading(u: np.ndarray) -> np.ndarray:
        return theta0[:, None] + k0[:, None] * u + 0.5 * rate[:, None] * u**2

    u = d[:, None] * GL_NODES[None, :]
    th = heading(u)
    position = curve.cell_xy[cell] + d[:, None] * np.column_stack([np.cos(th) @ GL_WEIGHTS, np.sin(th) @ GL_WEIGHTS])
    end = heading(d[:, None])[:, 0]
    return position, np.column_stack([np.cos(end), np.sin(end)]), k0 + rate * d


def frame(curve: HermiteCenterline | ClothoidCenterline, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``hermite_frame`` or ``clothoid_frame``, by the curve's kind."""
    s = np.asarray(s, dtype=float)
    return clothoid_frame(curve, s) if isinstance(curve, ClothoidCenterline) else hermite_frame(curve, s)
