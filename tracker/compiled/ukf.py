"""Compiled unscented-transform steps of the UKF prediction (``tracker.motion.predict``): the sigma
points of a batch of Gaussians and the weighted mean and covariance of propagated points, with the
state's wrapped coordinates (an angle wrapped to (-pi, pi], a periodic ``s`` to ``[0, period)``)
handled as ``tracker.ukf.Wrapping`` does. The Cholesky factors are LAPACK's, as numpy's; sums over
sigma points run in index order (numpy's matmul may sum in another order: the results agree to
rounding). A matrix that is not positive definite raises ``numpy.linalg.LinAlgError``; the caller
then takes the numpy path, which repairs and counts it."""

from __future__ import annotations

import math

import numpy as np

from tracker.compiled import njit
from tracker.compiled.geometry import wrap_angle


@njit(inline="always")
def _wrap(x, angles, period_index, period):  # pragma: no cover - compiled
    """``Wrapping.wrap`` of one vector in place."""
    for a in angles:
        x[a] = wrap_angle(x[a])
    if period_index >= 0:
        x[period_index] = x[period_index] % period


@njit(inline="always")
def _residual(x, angles, period_index, period):  # pragma: no cover - compiled
    """``Wrapping.residual`` of one difference vector in place."""
    for a in angles:
        x[a] = wrap_angle(x[a])
    if period_index >= 0:
        x[period_index] -= period * math.floor(x[period_index] / period + 0.5)


@njit(inline="always")
def all_finite(means, covs):  # pragma: no cover - compiled
    """Whether every entry of the means ``(C, D)`` and covariances ``(C, D, D)`` is finite (the
    kernels that start from ``sigma_kernel`` refuse a NaN or an infinity before any work)."""
    count, dim = means.shape
    for c in range(count):
        for j in range(dim):
            if not math.isfinite(means[c, j]):
                return False
            for k in range(dim):
                if not math.isfinite(covs[c, j, k]):
                    return False
    return True


@njit
def sigma_kernel(means, covs, scale, angles, period_index, period):  # pragma: no cover - compiled
    """Sigma points ``(C, 2n + 1, n)`` of ``N(means[c], covs[c])``: the mean, then the mean plus and
    minus ``scale`` times each column of the lower Cholesky factor, wrapped."""
    count, dim = means.shape
    pts = np.empty((count, 2 * dim + 1, dim))
    for c in range(count):
        chol = np.linalg.cholesky(covs[c])
        pts[c, 0] = means[c]
        _wrap(pts[c, 0], angles, period_index, period)
        for i in range(dim):
            for j in range(dim):
                spread = scale * chol[j, i]
                pts[c, 1 + i, j] = means[c, j] + spread
                pts[c, 1 + dim + i, j] = means[c, j] - spread
            _wrap(pts[c, 1 + i], angles, period_index, period)
            _wrap(pts[c, 1 + dim + i], angles, period_index, period)
    return pts


@njit
def moments_kernel(points, wm, wc, angles, period_index, period):  # pragma: no cover - compiled
    """Weighted mean ``(C, n)`` (wrapped coordinates averaged as residuals about the central point)
    and covariance ``sum_i Wc_i d_i d_i^T`` ``(C, n, n)`` of ``points (C, S, n)``."""
    count, sigma, dim = points.shape
    mean = np.empty((count, dim))
    cov = np.zeros((count, dim, dim))
    dev = np.empty((sigma, dim))
    for c in range(count):
        for i in range(sigma):
            for j in range(dim):
                dev[i, j] = points[c, i, j] - points[c, 0, j]
            _residual(dev[i], angles, period_index, period)
        for j in range(dim):
            acc = 0.0
            for i in range(sigma):
                acc += wm[i] * dev[i, j]
            mean[c, j] = points[c, 0, j] + acc
        _wrap(mean[c], angles, period_index, period)
        for i in range(sigma):
            for j in range(dim):
                dev[i, j] = points[c, i, j] - mean[c, j]
            _residual(dev[i], angles, period_index, period)
        for j in range(dim):
            for k in range(dim):
                acc = 0.0
                for i in range(sigma):
                    acc += dev[i, j] * wc[i] * dev[i, k]
                cov[c, j, k] = acc
    return mean, cov



@njit
def certainly_positive_definite(covs, shift):  # pragma: no cover - compiled
    """Whether every matrix of ``covs (N, n, n)`` is positive definite with room to spare: its
    unit-diagonal scaling ``H = D^-1/2 A D^-1/2`` (``D`` the diagonal, which must be positive) less
    ``shift`` times the identity has a Cholesky factorisation (of its lower triangle). Its success bounds
    ``lambda_min(H)`` below by ``shift`` less a rounding error of order ``n^2 eps`` (``||H|| <= n``), and
    every Cholesky factorisation of ``A`` in floating point runs to completion once ``lambda_min(H)``
    exceeds a small multiple of ``n^1.5 eps`` (Higham, Accuracy and Stability of Numerical Algorithms,
    Thm 10.7): with ``shift`` far above both, LAPACK's factorisation of ``A`` succeeds. False says only
    that this test is not sure (the caller asks LAPACK)."""
    count, dim = covs.shape[0], covs.shape[1]
    scaled = np.empty((dim, dim))
    root = np.empty(dim)
    chol = np.zeros((dim, dim))
    for c in range(count):
        for j in range(dim):
            diag = covs[c, j, j]
            if not (diag > 0.0 and diag < np.inf):
                return False
            root[j] = np.sqrt(diag)
        for i in range(dim):
            for j in range(i + 1):
                value = covs[c, i, j] / (root[i] * root[j])
                if not np.isfinite(value):
                    return False
                scaled[i, j] = value
            scaled[i, i] -= shift
        if not cholesky_into(scaled, chol):
            return False
    return True


@njit
def cholesky_into(a, low):  # pragma: no cover - compiled
    """The lower Cholesky factor of the symmetric matrix ``a`` (its lower triangle) into ``low`` (its
    upper triangle left as it is); False (``low`` partly written) at the first pivot that is not
    positive."""
    size = a.shape[0]
    for j in range(size):
        acc = a[j, j]
        for k in range(j):
            acc -= low[j, k] * low[j, k]
        if not acc > 0.0:
            return False
        low[j, j] = math.sqrt(acc)
        for i in range(j + 1, size):
            acc = a[i, j]
            for k in range(j):
                acc -= low[i, k] * low[j, k]
            low[i, j] = acc / low[j, j]
    return True
