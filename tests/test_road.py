"""Tests of tracker/road.py and tracker/centerline.py: geometry against analytic curves and oracles."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scenes import kernel_roads
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad

from tracker import Road
from tracker.angles import wrap_angle

R = 80.0


def winding_segments() -> list[tuple[float, float, float]]:
    """Straights, arcs (radius down to 60 m, both directions) and clothoid ramps."""
    return [
        (40.0, 0.0, 0.0),
        (30.0, 0.0, 1 / 60),
        (60.0, 1 / 60, 1 / 60),
        (40.0, 1 / 60, -1 / 80),
        (70.0, -1 / 80, -1 / 80),
        (30.0, -1 / 80, 0.0),
        (50.0, 0.0, 0.0),
        (25.0, 0.0, 1 / 100),
        (45.0, 1 / 100, 1 / 100),
    ]


@pytest.fixture(scope="module")
def winding() -> Road:
    return Road.from_curvature(winding_segments(), start=(10.0, -5.0, 0.3), lanes=3, lane_width=3.5)


@pytest.fixture(scope="module")
def winding_waypoints(winding: Road) -> Road:
    s = np.linspace(0.0, winding.length, 41)
    return Road.from_waypoints(winding.position(s), lanes=3, lane_width=3.5)


def circle_waypoints(radius: float, count: int) -> np.ndarray:
    a = np.linspace(0.0, 2 * np.pi, count, endpoint=False)
    return np.column_stack([radius * np.sin(a), radius - radius * np.cos(a)])


def radius_error(xy: np.ndarray, radius: float) -> np.ndarray:
    return np.abs(np.hypot(xy[..., 0], xy[..., 1] - radius) - radius)


# -- circles --------------------------------------------------------------------------------------
def test_circle_from_curvature_matches_analytic_circle():
    road = Road.from_curvature([(2 * np.pi * R, 1 / R, 1 / R)], closed=True)
    assert road.length == pytest.approx(2 * np.pi * R, rel=1e-12)
    s = np.linspace(0.0, road.length, 997, endpoint=False)
    xy, theta, kappa = road.frame(s)
    phi = s / R
    exact = np.column_stack([R * np.sin(phi), R - R * np.cos(phi)])
    assert np.max(np.linalg.norm(xy - exact, axis=1)) < 1e-9
    assert np.max(np.abs(wrap_angle(theta - phi))) < 1e-12
    assert np.max(np.abs(kappa * R - 1.0)) < 1e-12


@pytest.mark.parametrize("closed", [True, False])
def test_circle_from_waypoints_has_curvature_one_over_r(closed):
    pts = circle_waypoints(R, 36)
    if not closed:
        pts = pts[:19]  # half circle
    road = Road.from_waypoints(pts, closed=closed)
    s = np.linspace(0.0, road.length, 2000, endpoint=False)
    xy, _, kappa = road.frame(s)
    assert np.max(radius_error(xy, R)) < 0.01
    # open arc: the end tangents are estimated ("not-a-knot"), so the first and last segments carry a
    # ~2 % curvature error at 10 deg waypoint spacing; everywhere else (and all round a closed circle)
    # the curvature is within 0.5 %
    inner = (s >= road.joins[1]) & (s <= road.joins[-2]) if not closed else np.ones_like(s, bool)
    assert np.max(np.abs(kappa[inner] * R - 1.0)) < 0.005
    assert np.max(np.abs(kappa * R - 1.0)) < 0.03
    if closed:
        assert road.length == pytest.approx(2 * np.pi * R, rel=1e-4)


def test_waypoints_with_given_headings_pass_through_them():
    a = np.linspace(0.0, np.pi, 10)
    pts = np.column_stack([R * np.sin(a), R - R * np.cos(a)])
    road = Road.from_waypoints(pts, headings=a)
    xy, theta, kappa = road.frame(road.joins)
    np.testing.assert_allclose(xy, pts, atol=1e-9)
    np.testing.assert_allclose(wrap_angle(theta - a), 0.0, atol=1e-9)
    s = np.linspace(0.0, road.length, 500)
    assert np.max(radius_error(road.position(s), R)) < 0.01
    assert np.max(np.abs(road.curvature(s) * R - 1.0)) < 0.04


# -- arc length -----------------------------------------------------------------------------------
def test_hermite_arc_length_parameterisation_better_than_1mm_per_km():
    rng = np.random.default_rng(3)
    pts = np.cumsum(np.column_stack([np.full(25, 45.0), rng.normal(0.0, 12.0, 25)]), axis=0)
    road = Road.from_waypoints(pts)
    assert road.length > 1000.0
    curve = road._curve
    s = np.sort(rng.uniform(0.0, road.length, 40))
    seg, tau = curve.parameter(s)
    c = curve.coeffs

    def speed(k: int, u: float) -> float:
        d1 = c[k, 1] + 2 * c[k, 2] * u + 3 * c[k, 3] * u * u
        return float(np.hypot(*d1))

    seg_len = [quad(lambda u, k=k: speed(k, u), 0.0, 1.0, epsabs=1e-12, limit=200)[0] for k in range(len(c))]
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    true_s = [cum[k] + quad(lambda u, k=k: speed(k, u), 0.0, t, epsabs=1e-12)[0] for k, t in zip(seg, tau)]
    err_per_km = np.max(np.abs(np.array(true_s) - s)) / (road.length / 1000.0)
    assert err_per_km < 1e-3
    assert road.length == pytest.approx(cum[-1], abs=1e-6)


# -- round trips ----------------------------------------------------------------------------------
@pytest.mark.parametrize("which", ["winding", "winding_waypoints"])
def test_round_trips_on_winding_road(which, request):
    road: Road = request.getfixturevalue(which)
    rng = np.random.default_rng(7)
    s = rng.uniform(0.0, road.length, 10_000)
    n = rng.uniform(road.right_edge, road.left_edge, 10_000)
    xy = road.to_cartesian(s, n)
    s2, n2 = road.to_frenet(xy)
    assert np.max(np.abs(s2 - s)) < 1e-3 and np.max(np.abs(n2 - n)) < 1e-3
    # random points of the plane that lie inside the road bounds
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    p = rng.uniform(lo, hi, size=(200_000, 2))
    p = p[road.on_road(p)][:10_000]
    assert len(p) == 10_000
    back = road.to_cartesian(*road.to_frenet(p))
    assert np.max(np.linalg.norm(back - p, axis=1)) < 1e-3


def test_projection_is_the_nearest_point_against_dense_sampling(winding):
    rng = np.random.default_rng(11)
    s_true = rng.uniform(5.0, winding.length - 5.0, 200)
    p = winding.to_cartesian(s_true, rng.uniform(-6.0, 6.0, 200))
    dense = np.linspace(0.0, winding.length, 200_001)  # 2.4 mm spacing
    curve = winding.position(dense)
    from scipy.spatial import cKDTree

    dist, idx = cKDTree(curve).query(p)
    s, n = winding.to_frenet(p)
    assert np.max(np.abs(s - dense[idx])) < 0.01
    assert np.all(np.abs(n) <= dist + 1e-9)  # never farther than any sample of the curve
    assert np.max(dist - np.abs(n)) < 1e-4


@settings(max_examples=200, deadline=None)
@given(st.floats(0.0, 1.0), st.floats(-5.25, 5.25))
def test_round_trip_property(frac, n):
    road = _HYPOTHESIS_ROAD
    s = frac * road.length
    xy = road.to_cartesian(s, n)
    s2, n2 = road.to_frenet(xy)
    assert abs(s2 - s) < 1e-6 and abs(n2 - n) < 1e-6


_HYPOTHESIS_ROAD = Road.from_curvature(winding_segments(), lanes=3)


def test_single_point_fast_path_matches_vectorised(winding, winding_waypoints):
    rng = np.random.default_rng(5)
    for road in (winding, winding_waypoints):
        s = rng.uniform(0.0, road.length, 50)
        n = rng.uniform(-5.0, 5.0, 50)
        xy = road.to_cartesian(s, n)
        for k in range(50):
            one = road.to_cartesian(float(s[k]), float(n[k]))
            np.testing.assert_allclose(one, xy[k], atol=1e-9)
            s1, n1 = road.to_frenet(xy[k])
            s2, n2 = road.to_frenet(tuple(xy[k]), s_hint=float(s[k]) + 0.7)
            assert isinstance(s1, float) and isinstance(n1, float)
            assert s1 == pytest.approx(s[k], abs=1e-7) and n1 == pytest.approx(n[k], abs=1e-7)
            assert s2 == pytest.approx(s[k], abs=1e-7) and n2 == pytest.approx(n[k], abs=1e-7)


# -- continuity and wrap-around ----------------------------------------------------------------
@pytest.mark.parametrize("which", ["winding", "winding_waypoints"])
def test_heading_and_curvature_continuous_across_joins(which, request):
    road: Road = request.getfixturevalue(which)
    joins = road.joins[1:-1] if which == "winding_waypoints" else road.joins[1:]
    eps = 1e-7
    _, th_l, k_l = road.frame(joins - eps)
    _, th_r, k_r = road.frame(joins + eps)
    assert np.max(np.abs(wrap_angle(th_r - th_l))) < 1e-6
    assert np.max(np.abs(k_r - k_l)) < 1e-6
    # the clothoid profile's curvature is the prescribed one at every join
    if which == "winding":
        prescribed = np.array([seg[1] for seg in winding_segments()])
        np.testing.assert_allclose(road.curvature(road.joins), prescribed, atol=1e-12)


def test_closed_road_wraps_s():
    segs = [(100.0, 0.0, 0.0), (np.pi * 50.0, 1 / 50, 1 / 50)] * 2  # a stadium
    road = Road.from_curvature(segs, closed=True, lanes=2)
    L = road.length
    assert L == pytest.approx(200.0 + 2 * np.pi * 50.0)
    s = np.array([0.0, 10.0, 123.4])
    np.testing.assert_allclose(road.position(s + L), road.position(s), atol=1e-9)
    np.testing.assert_allclose(road.position(s - 2 * L), road.position(s), atol=1e-9)
    np.testing.assert_allclose(road.position(L - 1e-9), road.position(0.0), atol=1e-6)
    th = road.heading(np.array([L - 1e-6, 1e-6]))
    assert abs(wrap_angle(th[1] - th[0])) < 1e-6
    # a point just before the start projects near L, one just after near 0; s stays in [0, L)
    before = road.to_cartesian(L - 0.5, 1.0)
    after = road.to_cartesian(0.5, 1.0)
    assert road.to_frenet(before)[0] == pytest.approx(L - 0.5, abs=1e-7)
    assert road.to_frenet(after, s_hint=L - 0.2)[0] == pytest.approx(0.5, abs=1e-7)
    assert road.on_road(np.vstack([before, after])).all()


def test_closed_waypoint_road_periodic_curvature():
    road = Road.from_waypoints(np.vstack([circle_waypoints(R, 24), [[0.0, 0.0]]]), closed=True)
    _, th, k = road.frame(np.array([road.length - 1e-7, 0.0, 1e-7]))
    assert abs(wrap_angle(th[2] - th[0])) < 1e-6 and abs(k[2] - k[0]) < 1e-6


def test_continuity_under_small_motion_on_a_hairpin():
    hairpin = Road.from_curvature([(50.0, 0, 0), (np.pi * 12.0, 1 / 12, 1 / 12), (50.0, 0, 0)], lanes=1, lane_width=3.0)
    # drive along the lane centre with warm starts; s must increase smoothly even where the two
    # straights are 24 m apart and the other branch is far closer than the distance driven
    s_true = np.linspace(0.0, hairpin.length, 400)
    xy = hairpin.to_cartesian(s_true, np.zeros_like(s_true))
    s_prev = 0.0
    for k, p in enumerate(xy):
        s_prev, _ = hairpin.to_frenet(p, s_hint=s_prev)
        assert s_prev == pytest.approx(s_true[k], abs=1e-6)


# -- the paper's polynomials and Euler conversion -----------------------------------------------
def test_local_polynomials_exact_on_a_clothoid_ramp():
    k0, k1, length = 0.002, 0.022, 100.0
    road = Road.from_curvature([(length, k0, k1)], start=(0.0, 0.0, 0.5))
    rate = (k1 - k0) / length
    s0 = 20.0
    a, b, c, d = road.heading_poly(s0)
    kappa_s0 = k0 + rate * s0
    assert (a, b, c) == pytest.approx((0.0, rate / 2, kappa_s0), abs=1e-9)
    assert d == pytest.approx(0.5 + k0 * s0 + rate * s0**2 / 2, abs=1e-9)
    np.testing.assert_allclose(road.curvature_poly(s0), [0.0, 0.0, rate, kappa_s0], atol=1e-9)


def test_euler_conversion_converges_to_exact():
    # a clothoid ramp: the heading is exactly quadratic, so the cubic fit is exact and what is left
    # is the Euler step's error, about step * kappa * |s - s0| / 2 for right-Riemann sums
    road = Road.from_curvature([(200.0, 0.0, 1 / 50)], start=(0.0, 0.0, 0.2))
    s0 = 100.0
    rng = np.random.default_rng(2)
    s = s0 + rng.uniform(-30.0, 30.0, 200)
    n = rng.uniform(-5.0, 5.0, 200)
    exact = road.to_cartesian(s, n)
    kappa_max = 130.0 / 200.0 / 50.0
    errors = []
    for step in (2.0, 1.0, 0.5, 0.25):
        euler = road.to_cartesian(s, n, method="euler", s0=s0, step=step)
        err = np.linalg.norm(euler - exact, axis=1)
        assert np.all(err <= 0.5 * step * kappa_max * np.abs(s - s0) * 1.05 + 1e-9)
        errors.append(err.max())
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    np.testing.assert_allclose(ratios, 2.0, rtol=0.1)  # first order
    fine = road.to_cartesian(s, n, method="euler", s0=s0, step=0.001)
    assert np.max(np.linalg.norm(fine - exact, axis=1)) < 1e-3


def test_euler_conversion_floor_is_the_cubic_fit(winding):
    # across arc/ramp joins the heading is not a cubic: the paper's conversion keeps the fit's error
    s0 = 120.0
    s = s0 + np.linspace(-30.0, 30.0, 61)
    exact = winding.to_cartesian(s, np.zeros_like(s))
    fine = winding.to_cartesian(s, np.zeros_like(s), method="euler", s0=s0, step=0.005)
    coarse = winding.to_cartesian(s, np.zeros_like(s), method="euler", s0=s0, step=2.0)
    err_fine = np.linalg.norm(fine - exact, axis=1).max()
    assert 1e-3 < err_fine < 0.1
    assert np.linalg.norm(coarse - exact, axis=1).max() > 2 * err_fine


# -- lanes and bounds ----------------------------------------------------------------------------
def test_lanes_and_bounds(winding):
    np.testing.assert_allclose(winding.lane_centers, [-3.5, 0.0, 3.5])
    assert (winding.right_edge, winding.left_edge) == (-5.25, 5.25)
    assert winding.lane_center(0) == -3.5
    np.testing.assert_array_equal(winding.lane_index([-6.0, -5.0, -1.0, 1.0, 5.0, 6.0]), [-1, 0, 1, 1, 2, 3])
    s = np.array([50.0, 50.0, 150.0, 150.0])
    n = np.array([5.0, 5.5, -5.0, -5.5])
    np.testing.assert_array_equal(winding.on_road(winding.to_cartesian(s, n)), [True, False, True, False])
    shifted = Road.from_curvature([(100.0, 0.0, 0.0)], lanes=2, lane_width=3.0, right_edge=-1.5)
    np.testing.assert_allclose(shifted.lane_centers, [0.0, 3.0])
    right, left = shifted.boundaries(step=10.0)
    np.testing.assert_allclose(right[:, 1], -1.5) and np.testing.assert_allclose(left[:, 1], 4.5)
    with pytest.raises(ValueError, match="lane 3 does not exist"):
        winding.lane_center(3)


def test_open_road_ends_raise_or_extrapolate(winding):
    with pytest.raises(ValueError, match="off the open road"):
        winding.position(np.array([10.0, winding.length + 1.0]))
    with pytest.raises(ValueError, match="off the open road"):
        winding.to_cartesian(-2.0, 0.0)
    end_xy, end_th, _ = winding.frame(winding.length)
    ext = winding.position(winding.length + 5.0, extrapolate=True)
    np.testing.assert_allclose(ext, end_xy + 5.0 * np.array([np.cos(end_th), np.sin(end_th)]), atol=1e-9)
    s, n = winding.to_frenet(ext + np.array([-np.sin(end_th), np.cos(end_th)]))
    assert s == pytest.approx(winding.length + 5.0, abs=1e-7) and n == pytest.approx(1.0, abs=1e-7)
    assert not winding.on_road(ext[None, :])[0]


# -- bad input ------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "build, match",
    [
        (lambda: Road.from_waypoints([[0, 0], [np.nan, 1.0], [2, 0]]), "waypoints xy must be finite"),
        (lambda: Road.from_waypoints([[0.0, 0.0]]), "at least 2 waypoints"),
        (lambda: Road.from_waypoints([[0, 0], [5, 0]], closed=True), "at least 3 waypoints"),
        (lambda: Road.from_waypoints([[0, 0], [5, 0], [5, 0], [9, 1]]), "waypoints 1 and 2 coincide"),
        (lambda: Road.from_waypoints([[0, 0, 0], [5, 0, 0]]), r"shape \(M, 2\)"),
        (lambda: Road.from_waypoints([[0, 0], [5, 0]], headings=[0.0]), "headings must have shape"),
        (lambda: Road.from_waypoints([[0, 0], [5, 0]], headings=[0.0, np.inf]), "headings must be finite"),
        (lambda: Road.from_waypoints([[0, 0], [5, 0]], lane_width=0.0), "lane_width must be a positive"),
        (lambda: Road.from_waypoints([[0, 0], [5, 0]], lane_width=-3.5), "lane_width must be a positive"),
        (lambda: Road.from_waypoints([[0, 0], [5, 0]], lanes=0), "lanes must be a positive integer"),
        (lambda: Road.from_curvature([(0.0, 0.0, 0.0)]), "segment 0 has non-positive length"),
        (lambda: Road.from_curvature([(10.0, np.nan, 0.0)]), "segments must be finite"),
        (lambda: Road.from_curvature([(10.0, 0.0)]), "rows of"),
        (lambda: Road.from_curvature([(100.0, 0.01, 0.01)], closed=True), "does not close"),
    ],
)
def test_bad_construction_raises_clear_errors(build, match):
    with pytest.raises(ValueError, match=match):
        build()


def test_bad_query_input_raises_clear_errors(winding):
    with pytest.raises(ValueError, match="s and n must have the same shape"):
        winding.to_cartesian(np.array([1.0, 2.0, 3.0]), np.array([0.0, 1.0]))
    with pytest.raises(ValueError, match=r"xy must have shape \(\.\.\., 2\)"):
        winding.to_frenet(np.zeros((4, 3)))
    with pytest.raises(ValueError, match="xy must be finite"):
        winding.to_frenet(np.array([[1.0, 2.0], [np.nan, 0.0]]))
    with pytest.raises(ValueError, match="xy must be finite"):
        winding.to_frenet(np.array([np.nan, 0.0]))
    with pytest.raises(ValueError, match="s must be finite"):
        winding.position(np.array([1.0, np.nan]))
    with pytest.raises(ValueError, match="s_hint must be a scalar or have shape"):
        winding.to_frenet(np.zeros((3, 2)), s_hint=np.zeros(2))
    with pytest.raises(ValueError, match="method='euler' needs s0"):
        winding.to_cartesian(1.0, 0.0, method="euler")
    with pytest.raises(ValueError, match="method must be"):
        winding.to_cartesian(1.0, 0.0, method="rk4")


def test_vectorised_shapes(winding):
    s = np.full((3, 4), 20.0)
    xy = winding.to_cartesian(s, np.zeros((3, 4)))
    assert xy.shape == (3, 4, 2)
    s2, n2 = winding.to_frenet(xy)
    assert s2.shape == (3, 4) and n2.shape == (3, 4)
    assert winding.heading(s).shape == (3, 4)
    assert math.isclose(float(winding.to_cartesian(s, 0.0)[1, 2, 0]), float(xy[0, 0, 0]))


def test_one_point_in_any_shape_takes_the_fast_path_and_agrees_with_the_batch():
    road = Road.from_curvature([(200.0, 0.0, 0.0), (300.0, 0.0, 1 / 150), (600, 1 / 150, 1 / 150)], lanes=3)
    rng = np.random.default_rng(4)
    pts = np.column_stack([rng.uniform(0.0, 700.0, 50), rng.uniform(-10.0, 150.0, 50)])
    s_batch, n_batch = road.to_frenet(pts)  # the vectorised Newton projection
    for k, p in enumerate(pts):
        s1, n1 = road.to_frenet(p[None, :])
        assert s1.shape == (1,) and n1.shape == (1,)
        assert abs(s1[0] - s_batch[k]) < 1e-9 and abs(n1[0] - n_batch[k]) < 1e-9
        s2, n2 = road.to_frenet(p.reshape(1, 1, 2), s_hint=np.array([s_batch[k]]))
        assert s2.shape == (1, 1) and abs(s2[0, 0] - s_batch[k]) < 1e-9
        st, nt = road.to_frenet(tuple(p))
        assert isinstance(st, float) and abs(st - s_batch[k]) < 1e-9 and abs(nt - n_batch[k]) < 1e-9
    with pytest.raises(ValueError, match="scalar"):
        road.to_frenet(pts[:1], s_hint=np.array([1.0, 2.0]))
    s_int, _ = road.to_frenet(np.array([[300, 20]]))  # integers take the same path
    assert s_int.shape == (1,) and abs(s_int[0] - road.to_frenet((300.0, 20.0))[0]) < 1e-12
    with pytest.raises(ValueError, match="xy must be finite"):
        road.to_frenet(np.array([[np.nan, 1.0]]))
    with pytest.raises(ValueError, match="xy must be finite"):
        road.to_frenet((np.inf, 1.0))


# -- the curve and projection kernels against the numpy oracles ---------------------------------------
KERNEL_ROADS = kernel_roads()


def _seam_difference(road: Road, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a - b`` of arc lengths; on a closed road the shortest (just below the length and just above 0
    are the same place)."""
    d = a - b
    return (d + 0.5 * road.length) % road.length - 0.5 * road.length if road.closed else d


@pytest.mark.parametrize("name", ["clothoid-open", "hermite-closed"])
def test_curve_frame_kernel_against_the_oracle(name):
    """``frame`` (``curve_frame``: bucket lookup, Taylor cos/sin, 4-point rule) against the oracle's
    binary search, exact trigonometry and 8-point rule: random ``s``, both ends, every cell start and
    the float just below it."""
    from oracles.centerline import frame

    curve = KERNEL_ROADS[name]._curve
    s = np.concatenate([np.random.default_rng(0).uniform(0.0, curve.length, 3000), [0.0, curve.length],
                        curve.starts[:-1], np.nextafter(curve.starts[1:], 0.0)])
    for got, ref in zip(curve.frame(s), frame(curve, s)):
        assert got.shape == ref.shape
        np.testing.assert_allclose(got, ref, rtol=0.0, atol=1e-9)


def _projection_points(road: Road, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Points on and off the road (up to 30 m beyond its edges) with their true ``s``; on an open road
    also beyond both ends, along and beside the end tangents."""
    s = np.concatenate([rng.uniform(0.0, road.length, 2000), [0.0, road.length, 1e-9, road.length - 1e-9]])
    n = rng.uniform(road.right_edge - 30.0, road.left_edge + 30.0, s.size)
    xy = road.to_cartesian(s, n)
    if not road.closed:
        x0, y0, c0, s0 = road._ends[0]
        x1, y1, c1, s1 = road._ends[1]
        xy = np.concatenate([xy, [[x0 - 25.0 * c0, y0 - 25.0 * s0], [x1 + 40.0 * c1 - 3.0 * s1, y1 + 40.0 * s1 + 3.0 * c1]]])
        s = np.concatenate([s, [0.0, road.length]])
    return xy, s


@pytest.mark.parametrize("name", ["clothoid-open", "hermite-closed"])
def test_projection_kernels_against_the_oracle(name):
    """``project_kernel``'s Newton iterations against the oracle's from the same starts (good hints and
    bad ones, half a road away): the same points left pending, ``(s, n)`` of the others within 1e-9. ``to_frenet``
    (seeded by the kernels, its fallbacks for what Newton leaves) against the oracle's projection where
    that converges, and elsewhere a true foot of the perpendicular at distance ``|n|``."""
    from oracles.road import newton, road_frame, to_frenet
    from tracker.centerline import project_kernel
    from tracker.road import PROJECTION_MAX_ITERATIONS, PROJECTION_MAX_STEP, PROJECTION_MIN_DENOMINATOR, PROJECTION_TOLERANCE

    road = KERNEL_ROADS[name]
    rng = np.random.default_rng(1)
    xy, s = _projection_points(road, rng)
    kind, *curve = road._curve.kernel_args()
    for start in (s + rng.normal(0.0, 2.0, s.size), (s + 0.5 * road.length) % road.length):
        got = project_kernel(kind, np.ascontiguousarray(xy), start.copy(), road.closed, road.length, road._ends_array,
                             *curve, PROJECTION_MAX_ITERATIONS, PROJECTION_TOLERANCE, PROJECTION_MAX_STEP,
                             PROJECTION_MIN_DENOMINATOR)
        ref = newton(road, xy, start)
        np.testing.assert_array_equal(got[2], ref[2])
        done = ~ref[2]  # (a pending point's last iterate is discarded: near the far side's distance maximum
        # its steps amplify rounding)
        np.testing.assert_allclose(_seam_difference(road, got[0][done], ref[0][done]), 0.0, rtol=0.0, atol=1e-9)
        np.testing.assert_allclose(got[1][done], ref[1][done], rtol=0.0, atol=1e-9)
    assert ref[2].any()  # the bad hints exercise to_frenet's retry from the global search
    for hint in (None, s + rng.normal(0.0, 2.0, s.size), (s + 0.5 * road.length) % road.length):
        got_s, got_n = road.to_frenet(xy, s_hint=hint)
        ref_s, ref_n, pending = to_frenet(road, xy, hint)
        done = ~pending
        np.testing.assert_allclose(_seam_difference(road, got_s[done], ref_s[done]), 0.0, rtol=0.0, atol=1e-9)
        np.testing.assert_allclose(got_n[done], ref_n[done], rtol=0.0, atol=1e-9)
        foot, tangent, _ = road_frame(road, got_s)
        d = xy - foot
        np.testing.assert_allclose(d[:, 0] * tangent[:, 0] + d[:, 1] * tangent[:, 1], 0.0, atol=1e-6)
        np.testing.assert_allclose(d[:, 1] * tangent[:, 0] - d[:, 0] * tangent[:, 1], got_n, atol=1e-9)


@pytest.mark.parametrize("name", ["clothoid-open", "hermite-closed"])
def test_projection_seed_kernels_against_the_oracle(name):
    """The projection's starts without a hint: ``seed_kernel`` (the seed grid's curve sample, one Newton
    step) exactly the oracle's for points on the grid and ``missing`` off it (points far from the road);
    ``node_seed_kernel`` exactly the oracle's step from the nearest sample of all (brute force)."""
    from oracles.road import nearest_node, node_start
    from tracker.centerline import node_seed_kernel, seed_kernel
    from tracker.road import PROJECTION_MIN_DENOMINATOR, SEED_GRID_RESOLUTION

    road = KERNEL_ROADS[name]
    rng = np.random.default_rng(17)
    near = road.to_cartesian(rng.uniform(0.0, road.length, 400), rng.uniform(-10.0, 10.0, 400))
    far = near + rng.normal(0.0, 200.0, (400, 2))
    pts = np.ascontiguousarray(np.concatenate([near, far]))
    got, missing = seed_kernel(pts, road._grid_origin, 1.0 / SEED_GRID_RESOLUTION, road._grid, road._node_frame,
                               road._nodes, PROJECTION_MIN_DENOMINATOR)
    assert missing.any() and (~missing).any()
    node = nearest_node(road, pts)
    assert np.array_equal(got[~missing], node_start(road, pts, node)[~missing])
    off = np.ascontiguousarray(pts[missing])
    tree_node = road._tree.query(off)[1]
    np.testing.assert_array_equal(tree_node, node[missing])  # the k-d tree's nearest sample: brute force's
    assert np.array_equal(node_seed_kernel(off, tree_node, road._node_frame, road._nodes, PROJECTION_MIN_DENOMINATOR),
                          node_start(road, off, tree_node))


@pytest.mark.parametrize("closed", [False, True])
def test_the_seed_grid_clearance_is_a_lower_bound_of_the_distance_to_the_centerline(closed):
    """``Road.clearance_kernel_args``: no point lies nearer the centerline than its seed-grid cell's
    clearance (or the off-grid one, off the grid and in cells beyond its reach), against the distance
    to 20,000 samples of the curve; and the bound is tight within the cell's half diagonal plus half the
    longest arc between the grid's samples."""
    if closed:
        road = Road.from_waypoints(np.array([[100.0, 0.0], [0.0, 100.0], [-100.0, 0.0], [0.0, -100.0]]), closed=True,
                                   lanes=3, lane_width=3.5)
    else:
        road = Road.from_curvature([(80.0, 0.0, 0.0), (120.0, 0.0, 0.02), (60.0, 0.02, -0.03)], lanes=3, lane_width=3.5)
    clearance, offgrid, extent = road.clearance_kernel_args()
    s = np.linspace(0.0, road.length, 20_000)
    curve = np.asarray(road.to_cartesian(s, np.zeros_like(s)))
    from scipy.spatial import cKDTree
    lo, hi = curve.min(axis=0) - 40.0, curve.max(axis=0) + 40.0
    pts = np.random.default_rng(5).uniform(lo, hi, size=(20_000, 2))
    dist = cKDTree(curve).query(pts)[0]
    origin, inv_res = road.projection_kernel_args()[:2]
    cell = np.floor((pts - origin) * inv_res).astype(int)
    inside = (cell >= 0).all(axis=1) & (cell[:, 0] < clearance.shape[0]) & (cell[:, 1] < clearance.shape[1])
    bound = np.full(len(pts), offgrid)
    bound[inside] = clearance[cell[inside, 0], cell[inside, 1]]
    step = float(road.length) / len(s)  # the samples' own spacing
    assert (bound <= dist + step).all()
    near = inside & (bound < offgrid)
    assert (dist[near] - bound[near]).max() < 2.0 * (math.sqrt(2.0) + 1.0)
    assert offgrid > extent + 15.0  # a return 15 m beyond the edges needs no projection


def test_s_difference_is_the_short_way_round_on_a_closed_road_only():
    ring = Road.from_curvature([(2 * np.pi * 100.0, 0.01, 0.01)], closed=True, lanes=2)
    length = ring.length
    np.testing.assert_allclose(ring.s_difference([10.0, length - 5.0, 400.0, 300.0], [length - 5.0, 10.0, 10.0, 10.0]),
                               [15.0, -15.0, 390.0 - length, 290.0])
    line = Road.from_curvature([(500.0, 0.0, 0.0)], lanes=2)
    np.testing.assert_allclose(line.s_difference([10.0, 495.0], [495.0, 10.0]), [-485.0, 485.0])
    # broadcast (T, 1) against (1, S), as tracker.flow uses it
    assert ring.s_difference(np.zeros((3, 1)), np.zeros((1, 4))).shape == (3, 4)
