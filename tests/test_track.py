"""Tests of tracker/track.py: Track and the road <-> Cartesian state conversions."""

from __future__ import annotations

import numpy as np
import pytest

from tracker import Road
from tracker.track import Track, cartesian_to_curvilinear, curvilinear_to_cartesian
from tracker.ukf import UnscentedTransform

R = 80.0


@pytest.fixture(scope="module")
def circle() -> Road:
    """Circle of radius 80 m from (0, 0) heading +x, turning left: centre (0, 80)."""
    return Road.from_curvature([(2 * np.pi * R, 1 / R, 1 / R)], closed=True, lanes=2)


def test_accessors_and_read_only_arrays() -> None:
    t = Track(7, 1.5, [1, 2, 3, 0.1, 0.01, 4.5, 1.8], np.eye(7), 0.8)
    assert (t.label, t.t, t.weight) == (7, 1.5, 0.8)
    assert (t.s, t.n, t.v, t.xi, t.xi_dot, t.length, t.width) == (1, 2, 3, 0.1, 0.01, 4.5, 1.8)
    with pytest.raises(ValueError):
        t.mean[0] = 5.0
    with pytest.raises(ValueError, match="7 entries"):
        Track(1, 0.0, np.zeros(6), np.eye(7))
    with pytest.raises(ValueError, match=r"\(7, 7\)"):
        Track(1, 0.0, np.zeros(7), np.eye(6))
    with pytest.raises(ValueError, match="finite"):
        Track(1, 0.0, np.full(7, np.nan), np.eye(7))


def test_cartesian_view_on_a_circle(circle: Road) -> None:
    """A lane follower at s = R pi/2 (a quarter turn), n = 1.75: position on the radius R - n circle,
    heading pi/2 + xi, absolute yaw rate v cos(xi) / (R - n) + xi_dot."""
    s, n, v, xi, xi_dot = R * np.pi / 2, 1.75, 20.0, 0.05, 0.01
    t = Track(1, 0.0, [s, n, v, xi, xi_dot, 4.5, 1.8], np.eye(7))
    x = t.cartesian(circle)
    np.testing.assert_allclose(x[:2], [R - n, R], atol=1e-9)
    assert x[3] == pytest.approx(np.pi / 2 + xi)
    assert x[4] == pytest.approx(xi_dot + v * np.cos(xi) / (R - n))
    np.testing.assert_allclose(x[[2, 5, 6]], [v, 4.5, 1.8])


def test_round_trip_curvilinear_cartesian(circle: Road) -> None:
    rng = np.random.default_rng(0)
    x = np.column_stack([rng.uniform(0, circle.length, 50), rng.uniform(-3, 3, 50), rng.uniform(0, 30, 50),
                         rng.uniform(-0.5, 0.5, 50), rng.uniform(-0.2, 0.2, 50), np.full(50, 4.5), np.full(50, 1.8)])
    back = cartesian_to_curvilinear(circle, curvilinear_to_cartesian(circle, x))
    diff = back - x
    diff[:, 0] = (diff[:, 0] + circle.length / 2) % circle.length - circle.length / 2
    np.testing.assert_allclose(diff, 0.0, atol=1e-7)


def test_from_cartesian_and_cartesian_cov(circle: Road) -> None:
    """A Cartesian Gaussian converted to road coordinates by the unscented transform: the mean is the
    converted mean (small covariance), and converting back gives the covariance we started from."""
    x = curvilinear_to_cartesian(circle, np.array([100.0, -1.75, 15.0, 0.02, 0.0, 4.5, 1.8]))
    cov = np.diag([0.04, 0.09, 0.25, 1e-4, 1e-4, 0.01, 0.01])
    ut = UnscentedTransform()
    t = Track.from_cartesian(3, 2.0, x, cov, circle, weight=0.9, ut=ut)
    np.testing.assert_allclose(t.mean, cartesian_to_curvilinear(circle, x), atol=1e-3)
    np.testing.assert_allclose(t.cartesian_cov(circle, ut), cov, atol=2e-3 * cov.max())
    assert t.label == 3 and t.weight == 0.9


def test_relative_s_wraps_on_a_closed_road(circle: Road) -> None:
    t = Track(1, 0.0, [2.0, 0, 10, 0, 0, 4.5, 1.8], np.eye(7))
    assert t.relative_s(circle, circle.length - 3.0) == pytest.approx(5.0)
    assert t.relative_s(circle, 10.0) == pytest.approx(-8.0)


def test_checked_batch_equals_one_by_one() -> None:
    rng = np.random.default_rng(0)
    means = rng.normal(size=(4, 7))
    a = rng.normal(size=(4, 7, 7))
    covs = a @ np.swapaxes(a, 1, 2)
    labels, weights = np.array([3, 9, 1, 4]), rng.uniform(0.5, 1.0, 4)
    batch = Track.checked_batch(labels, 2.5, means, covs, weights)
    for k, tr in enumerate(batch):
        one = Track(int(labels[k]), 2.5, means[k], covs[k], float(weights[k]))
        assert (tr.label, tr.t, tr.weight, tr.extent) == (one.label, one.t, one.weight, one.extent)
        assert type(tr.label) is int and type(tr.weight) is float
        np.testing.assert_array_equal(tr.mean, one.mean)
        np.testing.assert_array_equal(tr.cov, one.cov)
        assert not tr.mean.flags.writeable and not tr.cov.flags.writeable
    means[0, 0] = 1e9  # copied: the caller's arrays stay the caller's
    assert batch[0].s != 1e9
    bad = means.copy()
    bad[2, 4] = np.nan
    with pytest.raises(ValueError, match="finite"):
        Track.checked_batch(labels, 0.0, bad, covs, weights)
    with pytest.raises(ValueError, match=r"\(K, 7\)"):
        Track.checked_batch(labels, 0.0, means[:, :6], covs, weights)
