"""The unscented transform's steps (``tracker.ukf``), in numpy: sigma points from numpy's Cholesky
factor, weighted moments by matrix products, wrapped coordinates as ``tracker.ukf.Wrapping`` names
them, and the repair of covariances that are not positive semi-definite."""

from __future__ import annotations

import numpy as np

from tracker.ukf import Wrapping


def wrap(x: np.ndarray, wrapping: Wrapping) -> np.ndarray:
    """Angles to (-pi, pi], each periodic coordinate to ``[0, period)``."""
    out = np.array(x, dtype=float)
    for i in wrapping.angles:
        out[..., i] = np.pi - np.mod(np.pi - out[..., i], 2.0 * np.pi)
    for i, period in wrapping.periods:
        out[..., i] = np.mod(out[..., i], period)
    return out


def residual(d: np.ndarray, wrapping: Wrapping) -> np.ndarray:
    """Differences with angles to (-pi, pi] and periodic coordinates to ``[-period/2, period/2)``."""
    out = np.array(d, dtype=float)
    for i in wrapping.angles:
        out[..., i] = np.pi - np.mod(np.pi - out[..., i], 2.0 * np.pi)
    for i, period in wrapping.periods:
        out[..., i] -= period * np.floor(out[..., i] / period + 0.5)
    return out


def sigma_points(mean: np.ndarray, cov: np.ndarray, scale: float, wrapping: Wrapping) -> np.ndarray:
    """``(..., 2n + 1, n)``: the mean, then the mean plus and minus ``scale`` times each column of the
    lower Cholesky factor of ``cov``; wrapped."""
    spread = scale * np.swapaxes(np.linalg.cholesky(cov), -1, -2)  # rows: scaled columns of the factor
    mean = mean[..., None, :]
    return wrap(np.concatenate([mean, mean + spread, mean - spread], axis=-2), wrapping)


def moments(points: np.ndarray, wm: np.ndarray, wc: np.ndarray, wrapping: Wrapping) -> tuple[np.ndarray, np.ndarray]:
    """Weighted mean ``X_0 + sum_i wm_i res(X_i - X_0)`` (wrapped) and covariance ``sum_i wc_i d_i
    d_i^T``, ``d_i = res(X_i - mean)``, of points ``(..., S, n)``."""
    ref = points[..., 0, :]
    mean = wrap(ref + np.einsum("i,...ij->...j", wm, residual(points - ref[..., None, :], wrapping)), wrapping)
    d = residual(points - mean[..., None, :], wrapping)
    return mean, np.einsum("i,...ij,...ik->...jk", wc, d, d)


def ensure_spd(cov: np.ndarray, floor: float) -> tuple[np.ndarray, int]:
    """``cov (N, n, n)`` with every matrix whose symmetric part has an eigenvalue below 0 (LAPACK's
    eigenvalues alone, as the tracker decides) replaced by that part with its eigenvalues lifted to
    ``floor``, unless the whole batch has a Cholesky factorisation (then unchanged); and how many were
    replaced."""
    cov = np.asarray(cov, dtype=float)
    try:
        np.linalg.cholesky(cov)
        return cov, 0
    except np.linalg.LinAlgError:
        pass
    out = cov.copy()
    count = 0
    for k, matrix in enumerate(cov):
        sym = 0.5 * (matrix + matrix.T)
        if np.linalg.eigvalsh(sym)[0] < 0.0:
            vals, vecs = np.linalg.eigh(sym)
            out[k] = (vecs * np.maximum(vals, floor)) @ vecs.T
            count += 1
    return out, count
