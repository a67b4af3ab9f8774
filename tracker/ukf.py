"""The unscented transform, vectorised over a batch of Gaussians, with angle- and period-aware maths.

Sigma points (Wan & van der Merwe scaling, ``n`` = state dimension, ``lambda = alpha^2 (n + kappa) - n``)::

    X_0 = m,   X_i = m + sqrt(n + lambda) * col_i(chol(P)),   X_{n+i} = m - sqrt(n + lambda) * col_i(chol(P))
    Wm_0 = lambda / (n + lambda),  Wc_0 = Wm_0 + 1 - alpha^2 + beta,  Wm_i = Wc_i = 1 / (2 (n + lambda))

Every array carries leading batch axes: ``mean (..., n)``, ``cov (..., n, n)`` give sigma points
``(..., 2n + 1, n)``. Wrapped coordinates (``Wrapping``): angles (the heading ``xi`` or ``psi``) live in
(-pi, pi] and the arc length ``s`` of a closed road in [0, length). Their means are taken about the
central sigma point, ``m = X_0 + sum_i Wm_i wrap(X_i - X_0)``, and their residuals are wrapped, so a
spread across the +-pi cut (or across ``s = 0``) averages correctly.

A covariance that is not numerically positive definite (a failed Cholesky factorisation) is repaired:
symmetrised and its eigenvalues lifted to ``UKFParams.min_eigenvalue``; ``UnscentedTransform.repairs``
counts the repaired matrices.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from tracker.angles import wrap_angle
from tracker.config import STATE_DIM, UKFParams
from tracker.jit import njit
from tracker.geometry import wrap_angle as wrap_angle_scalar


@dataclass(frozen=True)
class Wrapping:
    """Which coordinates of a vector wrap: ``angles`` (indices, wrapped to (-pi, pi]) and ``periods``
    (``(index, period)`` pairs, wrapped to ``[0, period)``, e.g. ``s`` on a closed road)."""

    angles: tuple[int, ...] = ()
    periods: tuple[tuple[int, float], ...] = ()

    @property
    def empty(self) -> bool:
        """Whether nothing wraps."""
        return not self.angles and not self.periods

    def kernel_args(self) -> tuple[np.ndarray, int, float]:
        """``(angles, period_index, period)``, the wrapping arguments of the kernels (``sigma_kernel``,
        ``moments_kernel``, ...): the angle indices as an array, and the one periodic coordinate (index
        -1 when there is none)."""
        if len(self.periods) > 1:
            raise ValueError("the kernels handle at most one periodic coordinate")
        index, period = self.periods[0] if self.periods else (-1, 1.0)
        return np.array(self.angles, dtype=np.int64), int(index), float(period)

    def residual(self, x: np.ndarray) -> np.ndarray:
        """Differences ``x`` with wrapped coordinates brought to the shortest representative
        (angles to (-pi, pi], periodic ``d`` to ``[-P/2, P/2)``). Returns a new array."""
        out = np.array(x, dtype=float, copy=True)
        for i in self.angles:
            out[..., i] = wrap_angle(out[..., i])
        for i, period in self.periods:
            out[..., i] -= period * np.floor(out[..., i] / period + 0.5)
        return out

    def coordinate_residual(self, d: np.ndarray, index: int) -> np.ndarray:
        """Differences ``d`` (any shape) of state coordinate ``index`` alone, brought to their shortest
        representative as ``residual`` brings that coordinate. Returns a new array."""
        out = np.array(d, dtype=float, copy=True)
        if index in self.angles:
            out = wrap_angle(out)
        for i, period in self.periods:
            if i == index:
                out -= period * np.floor(out / period + 0.5)
        return out

    def wrap(self, x: np.ndarray) -> np.ndarray:
        """Values ``x`` with wrapped coordinates brought into their range. Returns a new array."""
        out = np.array(x, dtype=float, copy=True)
        for i in self.angles:
            out[..., i] = wrap_angle(out[..., i])
        for i, period in self.periods:
            out[..., i] = np.mod(out[..., i], period)
        return out


NO_WRAP = Wrapping()


def make_spd(cov: np.ndarray, floor: float) -> tuple[np.ndarray, int]:
    """``cov`` (..., n, n) symmetrised, with the matrices whose smallest eigenvalue is below ``floor``
    repaired by lifting their eigenvalues to ``floor`` (units of ``cov``). Returns the matrices and how
    many were repaired."""
    sym = 0.5 * (cov + np.swapaxes(cov, -1, -2))
    flat = sym.reshape((-1,) + sym.shape[-2:])
    vals, vecs = np.linalg.eigh(flat)
    bad = vals[:, 0] < floor
    count = int(bad.sum())
    if count:
        fixed_vals = np.maximum(vals[bad], floor)
        flat = flat.copy()
        flat[bad] = np.einsum("bij,bj,bkj->bik", vecs[bad], fixed_vals, vecs[bad])
    return flat.reshape(sym.shape), count


#: Shift of the unit-diagonal scaled matrix for which ``ensure_spd``'s first test
#: (``certainly_positive_definite``) still finds a Cholesky factorisation before it
#: takes a matrix as positive definite without LAPACK: far above the ~1e-14 at which rounding could make
#: any Cholesky factorisation of an 8 x 8 matrix fail.
CERTAIN_SHIFT = 1e-8


def ensure_spd(cov: np.ndarray, floor: float) -> tuple[np.ndarray, int]:
    """``cov`` (..., n, n) with the matrices that are not positive semi-definite (smallest eigenvalue
    below 0) repaired: symmetrised, eigenvalues lifted to ``floor``. Whether a matrix is repaired does
    not depend on the others in the batch. The common case (all positive definite: returned unchanged)
    is decided by a test that proves it with room to spare (``certainly_positive_definite``,
    ``CERTAIN_SHIFT``) for a batch ``(N, n, n)``, else by one batched Cholesky factorisation; only when
    that fails are the eigenvalues computed.
    Non-finite entries are not repaired here (``UnscentedTransform.sigma_points`` refuses them).
    Returns the matrices and how many were repaired."""
    cov = np.asarray(cov, dtype=float)
    if cov.size == 0:
        return cov, 0
    if (cov.ndim == 3 and cov.shape[1] == cov.shape[2]
            and certainly_positive_definite(np.ascontiguousarray(cov), CERTAIN_SHIFT)):
        return cov, 0  # the usual batch: positive definite beyond doubt, no LAPACK call
    try:
        np.linalg.cholesky(cov)
        return cov, 0
    except np.linalg.LinAlgError:
        pass
    out = cov.reshape((-1,) + cov.shape[-2:]).copy()
    bad = np.linalg.eigvalsh(0.5 * (out + np.swapaxes(out, -1, -2)))[:, 0] < 0.0
    if bad.any():
        out[bad] = make_spd(out[bad], floor)[0]  # every one of them is below the floor: all lifted
    return out.reshape(cov.shape), int(bad.sum())


class UnscentedTransform:
    """Sigma points and weights for an ``n``-dimensional state (default 7) with ``UKFParams``.

    ``repairs`` counts covariances repaired before a Cholesky factorisation (see ``make_spd``).
    All methods take leading batch axes.
    """

    def __init__(self, params: UKFParams | None = None, n: int = STATE_DIM) -> None:
        self.params = params if params is not None else UKFParams()
        if n < 1:
            raise ValueError(f"state dimension n must be >= 1; got {n}")
        self.n = n
        a, b, k = self.params.alpha, self.params.beta, self.params.kappa
        lam = a * a * (n + k) - n
        if n + lam <= 0:
            raise ValueError(f"UKF: n + lambda = {n + lam!r} must be > 0 for n = {n}; raise alpha or kappa")
        self.scale = float(np.sqrt(n + lam))
        self.wm = np.full(2 * n + 1, 0.5 / (n + lam))
        self.wc = self.wm.copy()
        self.wm[0] = lam / (n + lam)
        self.wc[0] = self.wm[0] + 1.0 - a * a + b
        if self.wc[0] < 0:
            raise ValueError(f"UKF: central covariance weight Wc0 = {self.wc[0]!r} < 0; use alpha near 1")
        self.repairs = 0

    @property
    def num_sigma(self) -> int:
        """Number of sigma points, ``2n + 1``."""
        return 2 * self.n + 1

    def cholesky(self, cov: np.ndarray) -> np.ndarray:
        """Lower Cholesky factors of ``cov`` (..., n, n); non-SPD matrices are repaired and counted."""
        cov = np.asarray(cov, dtype=float)
        try:
            return np.linalg.cholesky(cov)
        except np.linalg.LinAlgError:
            fixed, count = make_spd(cov, self.params.min_eigenvalue)
            self.repairs += max(count, 1)
            try:
                return np.linalg.cholesky(fixed)
            except np.linalg.LinAlgError:  # eigenvalues at the floor but rounding defeats Cholesky
                bump = 10.0 * self.params.min_eigenvalue * np.eye(cov.shape[-1])
                return np.linalg.cholesky(fixed + bump)

    def sigma_points(self, mean: np.ndarray, cov: np.ndarray, wrapping: Wrapping = NO_WRAP) -> np.ndarray:
        """Sigma points ``(..., 2n + 1, n)`` of ``N(mean (..., n), cov (..., n, n))``; wrapped
        coordinates of the result are brought into range.

        A batch ``(C, n)`` takes ``sigma_kernel``. A covariance that is not positive definite is
        repaired and counted (``cholesky``), and the points are built from numpy's Cholesky factor,
        as they are for a single Gaussian or a batch of other shape: numba's LAPACK call (the kernel's)
        and numpy's give factors that can differ in their last bits, and these callers' numbers stay
        numpy's."""
        mean = np.asarray(mean, dtype=float)
        cov = np.asarray(cov, dtype=float)
        if mean.shape[-1] != self.n or cov.shape[-2:] != (self.n, self.n) or cov.shape[:-2] != mean.shape[:-1]:
            raise ValueError(
                f"sigma_points needs mean (..., {self.n}) and cov (..., {self.n}, {self.n}) with equal batch "
                f"shapes; got mean {mean.shape} and cov {cov.shape}"
            )
        if not (np.isfinite(mean).all() and np.isfinite(cov).all()):
            raise ValueError("sigma_points: mean and cov must be finite (a NaN/inf entered the filter)")
        if mean.ndim == 2:
            try:
                return sigma_kernel(np.ascontiguousarray(mean), np.ascontiguousarray(cov), self.scale,
                                    *wrapping.kernel_args())
            except np.linalg.LinAlgError:  # not positive definite: repaired and counted below
                pass
        chol = self.cholesky(cov)
        spread = self.scale * np.swapaxes(chol, -1, -2)  # rows = scaled columns of chol
        pts = np.concatenate([mean[..., None, :], mean[..., None, :] + spread, mean[..., None, :] - spread], axis=-2)
        return pts if wrapping.empty else wrapping.wrap(pts)

    def mean(self, points: np.ndarray, wrapping: Wrapping = NO_WRAP) -> np.ndarray:
        """Weighted mean ``sum_i Wm_i X_i`` of points ``(..., 2n + 1, d)``; wrapped coordinates are
        averaged as residuals about the central point ``X_0``."""
        if wrapping.empty:
            return self.wm @ points
        ref = points[..., 0, :]
        dev = wrapping.residual(points - ref[..., None, :])
        return wrapping.wrap(ref + self.wm @ dev)

    def deviations(self, points: np.ndarray, mean: np.ndarray, wrapping: Wrapping = NO_WRAP) -> np.ndarray:
        """Residuals ``X_i - m`` ``(..., 2n + 1, d)`` (wrapped coordinates wrapped)."""
        dev = points - mean[..., None, :]
        return dev if wrapping.empty else wrapping.residual(dev)

    def covariance(self, dev_a: np.ndarray, dev_b: np.ndarray | None = None) -> np.ndarray:
        """``sum_i Wc_i a_i b_i^T`` for deviations ``(..., 2n + 1, da)`` and ``(..., 2n + 1, db)``."""
        dev_b = dev_a if dev_b is None else dev_b
        return np.swapaxes(dev_a * self.wc[:, None], -1, -2) @ dev_b

    def transform(
        self,
        fn: Callable[[np.ndarray], np.ndarray],
        mean: np.ndarray,
        cov: np.ndarray,
        wrapping_in: Wrapping = NO_WRAP,
        wrapping_out: Wrapping = NO_WRAP,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Unscented transform of ``N(mean, cov)`` through ``fn`` (maps ``(..., 2n+1, n)`` sigma points
        to ``(..., 2n+1, d)``). Returns the mean ``(..., d)``, the covariance ``(..., d, d)`` and the
        cross covariance ``(..., n, d)`` between input and output."""
        pts = self.sigma_points(mean, cov, wrapping_in)
        out = np.asarray(fn(pts), dtype=float)
        m_out = self.mean(out, wrapping_out)
        dev_out = self.deviations(out, m_out, wrapping_out)
        dev_in = self.deviations(pts, np.asarray(mean, dtype=float), wrapping_in)
        cov_out = self.covariance(dev_out)
        return m_out, 0.5 * (cov_out + np.swapaxes(cov_out, -1, -2)), self.covariance(dev_in, dev_out)

# --------------------------------------------------------------------------------------------------
# The compiled kernels of this stage.
#
# The unscented transform of a batch of Gaussians: their sigma points (``sigma_kernel``) and the
# weighted mean and covariance of propagated points (``moments_kernel``), with the state's wrapped
# coordinates (angles wrapped to (-pi, pi], one periodic ``s`` to ``[0, period)``) as ``Wrapping``
# defines them. The Cholesky factor is LAPACK's (through numba); sums over sigma points run in index
# order. A matrix that is not positive definite raises ``numpy.linalg.LinAlgError``: the caller repairs
# and counts it (``UnscentedTransform.sigma_points``). Whether a batch is positive definite beyond doubt
# (``certainly_positive_definite``, ``ensure_spd``'s first test).
# --------------------------------------------------------------------------------------------------


@njit(inline="always")
def _wrap(x, angles, period_index, period):  # pragma: no cover - compiled
    """One vector's wrapped coordinates brought into range, in place: ``angles`` to (-pi, pi], the
    coordinate ``period_index`` (none when -1) to ``[0, period)``."""
    for a in angles:
        x[a] = wrap_angle_scalar(x[a])
    if period_index >= 0:
        x[period_index] = x[period_index] % period


@njit(inline="always")
def _residual(x, angles, period_index, period):  # pragma: no cover - compiled
    """One difference vector's wrapped coordinates brought to their shortest representative, in place:
    ``angles`` to (-pi, pi], the coordinate ``period_index`` (none when -1) to ``[-period/2, period/2)``."""
    for a in angles:
        x[a] = wrap_angle_scalar(x[a])
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
