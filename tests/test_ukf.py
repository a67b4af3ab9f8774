"""Tests of tracker/ukf.py: the unscented transform against exact answers."""

from __future__ import annotations

import numpy as np
import pytest

from tracker.config import UKFParams
from tracker.ukf import UnscentedTransform, Wrapping, make_spd


def random_spd(rng: np.random.Generator, n: int, batch: tuple[int, ...] = ()) -> np.ndarray:
    a = rng.standard_normal(batch + (n, n))
    return a @ np.swapaxes(a, -1, -2) + 0.1 * np.eye(n)


@pytest.mark.parametrize("params", [UKFParams(), UKFParams(alpha=0.5, beta=2.0, kappa=3.0), UKFParams(alpha=1.0, beta=0.0)])
def test_linear_function_exact_mean_and_covariance(params: UKFParams) -> None:
    """For f(x) = A x + b the unscented transform is exact: mean A m + b, covariance A P A^T, cross
    covariance P A^T; batched over a (4, 3) batch of Gaussians."""
    rng = np.random.default_rng(0)
    ut = UnscentedTransform(params)
    mean = rng.standard_normal((4, 3, 7))
    cov = random_spd(rng, 7, (4, 3))
    a = rng.standard_normal((5, 7))
    b = rng.standard_normal(5)
    m, c, cross = ut.transform(lambda x: x @ a.T + b, mean, cov)
    np.testing.assert_allclose(m, mean @ a.T + b, atol=1e-12)
    np.testing.assert_allclose(c, a @ cov @ a.T, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(cross, cov @ a.T, rtol=1e-10, atol=1e-10)


def test_weights_and_sigma_points_reproduce_the_gaussian() -> None:
    rng = np.random.default_rng(1)
    ut = UnscentedTransform()
    assert ut.wm.sum() == pytest.approx(1.0)
    assert np.all(ut.wc >= 0)
    mean, cov = rng.standard_normal(7), random_spd(rng, 7)
    pts = ut.sigma_points(mean, cov)
    assert pts.shape == (15, 7)
    np.testing.assert_allclose(ut.mean(pts), mean, atol=1e-12)
    np.testing.assert_allclose(ut.covariance(ut.deviations(pts, mean)), cov, atol=1e-10)


def test_angle_mean_across_the_cut() -> None:
    """A heading spread across +-pi averages to a value near pi, with a small covariance."""
    ut = UnscentedTransform()
    wrap = Wrapping(angles=(3,))
    mean = np.array([0, 0, 10, np.pi - 0.02, 0, 4.5, 1.8])
    cov = np.diag([1, 1, 1, 0.1**2, 0.01, 0.1, 0.1])
    m, c, _ = ut.transform(lambda x: x, mean, cov, wrap, wrap)
    assert abs(np.angle(np.exp(1j * (m[3] - (np.pi - 0.02))))) < 1e-9
    assert -np.pi < m[3] <= np.pi
    assert c[3, 3] == pytest.approx(0.01, rel=1e-9)


def test_period_mean_across_the_start_of_a_closed_road() -> None:
    """s on a closed road of length 500 m: a Gaussian at s = 0.1 m with 1 m std keeps mean 0.1 m."""
    ut = UnscentedTransform()
    wrap = Wrapping(angles=(3,), periods=((0, 500.0),))
    mean = np.array([0.1, 0, 10, 0, 0, 4.5, 1.8])
    cov = np.diag([1.0, 1, 1, 0.01, 0.01, 0.1, 0.1])
    pts = ut.sigma_points(mean, cov, wrap)
    assert pts[:, 0].max() > 490.0  # a sigma point wrapped to the end of the road
    m = ut.mean(pts, wrap)
    assert m[0] == pytest.approx(0.1, abs=1e-9)
    dev = ut.deviations(pts, m, wrap)
    assert ut.covariance(dev)[0, 0] == pytest.approx(1.0, rel=1e-9)


def test_failed_cholesky_is_repaired_and_counted() -> None:
    ut = UnscentedTransform()
    cov = np.diag([1.0, 1, 1, 1, 1, 1, 1])
    bad = cov.copy()
    bad[0, 1] = bad[1, 0] = 1.5  # indefinite: eigenvalues -0.5 and 2.5
    pts = ut.sigma_points(np.zeros((2, 7)), np.stack([cov, bad]))
    assert np.isfinite(pts).all()
    assert ut.repairs == 1
    fixed, count = make_spd(bad, 1e-9)
    assert count == 1
    assert np.linalg.eigvalsh(fixed).min() >= 1e-9 * 0.999
    # the repair only lifts the negative eigen-direction
    np.testing.assert_allclose(np.linalg.eigvalsh(fixed)[-1], 2.5)


def test_bad_inputs_raise_clear_errors() -> None:
    ut = UnscentedTransform()
    with pytest.raises(ValueError, match="mean"):
        ut.sigma_points(np.zeros(6), np.eye(7))
    with pytest.raises(ValueError, match="finite"):
        ut.sigma_points(np.full(7, np.nan), np.eye(7))
    with pytest.raises(ValueError, match="Wc0"):
        UKFParams(alpha=1e-3)
    with pytest.raises(ValueError, match="alpha"):
        UKFParams(alpha=-1.0)


def test_ensure_spd_repairs_only_indefinite_matrices_whatever_the_batch():
    from tracker.ukf import ensure_spd

    rng = np.random.default_rng(1)
    a = rng.normal(size=(7, 7))
    good = a @ a.T + np.eye(7)
    tiny = np.diag([1e-12, 1, 1, 1, 1, 1, 1.0])  # positive definite, below the floor
    bad = good.copy()
    bad[0, 0] = -0.5  # indefinite
    out, count = ensure_spd(np.stack([good, tiny]), 1e-9)
    assert count == 0 and np.array_equal(out, np.stack([good, tiny]))
    out, count = ensure_spd(np.stack([good, tiny, bad]), 1e-9)
    assert count == 1
    np.testing.assert_array_equal(out[0], good)
    np.testing.assert_array_equal(out[1], tiny)  # not touched because another matrix failed
    assert np.linalg.eigvalsh(out[2]).min() >= 1e-9 * 0.999
    np.testing.assert_allclose(out[2], out[2].T)
    assert ensure_spd(np.zeros((0, 7, 7)), 1e-9)[1] == 0


def test_coordinate_residual_is_residuals_column():
    """``Wrapping.coordinate_residual`` of one coordinate's differences equals that column of
    ``residual`` bit for bit: an angle, a periodic coordinate, and a plain one."""
    wrapping = Wrapping(angles=(3,), periods=((0, 500.0),))
    rng = np.random.default_rng(2)
    x = rng.uniform(-1200.0, 1200.0, (50, 8))
    x[:, 3] = rng.uniform(-20.0, 20.0, 50)
    full = wrapping.residual(x)
    for index in (0, 1, 3):
        np.testing.assert_array_equal(wrapping.coordinate_residual(x[:, index], index), full[:, index])
    assert wrapping.coordinate_residual(x[:, 1], 1) is not x[:, 1]


def test_certainly_positive_definite_never_disagrees_with_lapack():
    """``ensure_spd``'s first test (``tracker.ukf.certainly_positive_definite``, the scaled matrix less
    ``CERTAIN_SHIFT`` I factorised): True only for matrices LAPACK's Cholesky factorises -- near-singular
    ones (eigenvalues down to 1e-16 of the rest) with diagonals spread over eight orders of magnitude,
    indefinite ones, NaN -- and ``ensure_spd`` gives the oracle's matrices and counts (numpy's
    Cholesky factorisation and eigenvalues alone)."""
    from oracles.ukf import ensure_spd as oracle_ensure_spd
    from tracker.ukf import CERTAIN_SHIFT, certainly_positive_definite, ensure_spd

    rng = np.random.default_rng(4)
    answers = []
    for trial in range(3000):
        n = int(rng.integers(1, 9))
        u, _ = np.linalg.qr(rng.normal(size=(n, n)))
        vals = rng.uniform(0.5, 2.0, n)
        vals[: int(rng.integers(0, n + 1))] *= 10.0 ** -rng.uniform(4, 16)
        if trial % 7 == 0:
            vals[0] = -vals[0]  # indefinite
        scale = 10.0 ** rng.uniform(-4, 4, n)
        cov = (u * vals) @ u.T
        cov = 0.5 * (cov + cov.T) * scale[:, None] * scale[None, :]
        sure = certainly_positive_definite(cov[None], CERTAIN_SHIFT)
        answers.append(sure)
        if sure:
            np.linalg.cholesky(cov)  # never raises where the test is sure
        if trial % 10 == 0:
            got = ensure_spd(cov[None], 1e-9)
            ref = oracle_ensure_spd(cov[None], 1e-9)
            assert got[1] == ref[1]
            if ref[1]:
                np.testing.assert_allclose(got[0], ref[0], rtol=1e-9, atol=1e-12 * np.abs(cov).max())
            else:
                np.testing.assert_array_equal(got[0], cov[None])
    assert 0.1 < np.mean(answers) < 0.9  # both answers, often
    assert not certainly_positive_definite(np.full((1, 2, 2), np.nan), CERTAIN_SHIFT)
    assert not certainly_positive_definite(np.array([[[1.0, 1.0 - 1e-10], [1.0 - 1e-10, 1.0]]]), CERTAIN_SHIFT)
    assert certainly_positive_definite(np.diag([1.0, 1e-12])[None], CERTAIN_SHIFT)  # scale alone is no doubt
