"""Kernels of the road, the UKF and the motion model against their numpy references (moving to tests/oracles)."""

from __future__ import annotations


import numpy as np
import pytest

from tracker import Road
from tracker import compiled
from tracker.config import MotionConfig
from tracker.motion import FrenetMotion

pytest.importorskip("numba")


def _roads():
    open_road = Road.from_curvature([(200.0, 0.0, 0.0), (300.0, 0.0, 1 / 150.0), (600.0, 1 / 150.0, -1 / 80.0)],
                                    lanes=3, lane_width=3.5)
    th = np.linspace(0.0, 2.0 * np.pi, 13)[:-1]
    ring = Road.from_waypoints(np.column_stack([300.0 * np.cos(th), 200.0 * np.sin(th)]), closed=True, lanes=2,
                               lane_width=3.5)
    return {"clothoid-open": open_road, "hermite-closed": ring}


@pytest.mark.parametrize("name", ["clothoid-open", "hermite-closed"])
def test_compiled_centerline_frame_equals_numpy(name, monkeypatch):
    curve = _roads()[name]._curve
    s = np.concatenate([np.random.default_rng(0).uniform(0.0, curve.length, 3000), [0.0, curve.length],
                        curve.starts[:-1], np.nextafter(curve.starts[1:], 0.0)])
    monkeypatch.setenv(compiled.ENV_SWITCH, "0")
    ref = curve.frame(s)
    monkeypatch.setenv(compiled.ENV_SWITCH, "1")
    got = curve.frame(s)
    for a, b in zip(ref, got):
        assert a.shape == b.shape
        np.testing.assert_allclose(b, a, rtol=0.0, atol=1e-9)


@pytest.mark.parametrize("name", ["clothoid-open", "hermite-closed"])
def test_compiled_projection_equals_numpy(name, monkeypatch):
    """``Road.to_frenet``'s Newton iterations compiled against numpy: points on and off the road,
    beyond an open road's ends (extrapolated), across a closed road's seam, near a centre of
    curvature (the fallback), with and without hints (good and bad ones)."""
    road = _roads()[name]
    rng = np.random.default_rng(1)
    s = np.concatenate([rng.uniform(0.0, road.length, 2000), [0.0, road.length, 1e-9, road.length - 1e-9]])
    n = rng.uniform(road.right_edge - 30.0, road.left_edge + 30.0, s.size)
    xy = road.to_cartesian(s, n)
    if not road.closed:  # beyond both ends, along and beside the end tangents
        x0, y0, c0, s0 = road._ends[0]
        x1, y1, c1, s1 = road._ends[1]
        xy = np.concatenate([xy, [[x0 - 25.0 * c0, y0 - 25.0 * s0], [x1 + 40.0 * c1 - 3.0 * s1, y1 + 40.0 * s1 + 3.0 * c1]]])
        s = np.concatenate([s, [0.0, road.length]])
    hints = [None, s + rng.normal(0.0, 2.0, s.size), (s + 0.5 * road.length) % road.length]  # good, then bad hints
    for hint in hints:
        monkeypatch.setenv(compiled.ENV_SWITCH, "0")
        ref = road.to_frenet(xy, s_hint=hint)
        monkeypatch.setenv(compiled.ENV_SWITCH, "1")
        got = road.to_frenet(xy, s_hint=hint)
        ds = got[0] - ref[0]
        if road.closed:  # s just below the length and just above 0 are the same place
            ds = (ds + 0.5 * road.length) % road.length - 0.5 * road.length
        np.testing.assert_allclose(ds, 0.0, rtol=0.0, atol=1e-9)
        np.testing.assert_allclose(got[1], ref[1], rtol=0.0, atol=1e-9)


@pytest.mark.parametrize("name", ["clothoid-open", "hermite-closed"])
@pytest.mark.parametrize("motion", [MotionConfig(), MotionConfig(acceleration=True), MotionConfig(slip_lever=0.0)],
                         ids=["default", "acceleration", "no-slip"])
def test_compiled_frenet_propagation_equals_numpy(name, motion, monkeypatch):
    """States on and beyond the road (open ends extrapolate straight), backwards and standing, over
    one frame and over several RK4 sub-steps."""
    road = _roads()[name]
    model = FrenetMotion(road, motion)
    rng = np.random.default_rng(1)
    count = 240
    cols = [rng.uniform(-30.0, road.length + 30.0, count), rng.uniform(-6.0, 6.0, count),
            rng.uniform(-3.0, 35.0, count), rng.normal(0.0, 0.4, count), rng.normal(0.0, 0.3, count),
            rng.uniform(3.0, 16.0, count), rng.uniform(1.5, 2.6, count)]
    if model.dim == 8:
        cols.append(rng.normal(0.0, 2.0, count))
    x = np.column_stack(cols).reshape(16, 15, -1)
    for dt in (0.1, 1.0 / 14.0, 1.3):
        monkeypatch.setenv(compiled.ENV_SWITCH, "0")
        ref = model.propagate(x, dt)
        monkeypatch.setenv(compiled.ENV_SWITCH, "1")
        got = model.propagate(x, dt)
        assert got.shape == ref.shape
        np.testing.assert_allclose(got, ref, rtol=0.0, atol=1e-9)


def test_compiled_curvature_interpolation_equals_numpy_interp():
    """The RK4 kernel's table lookup (the interval from ``s / step``, corrected at knots) gives
    ``numpy.interp``'s numbers exactly: random ``s``, every knot and its neighbouring floats."""
    from tracker.motion import _interp

    xp = np.linspace(0.0, 1234.567, 4939)
    fp = np.random.default_rng(0).normal(size=xp.size)
    knots = xp[::7]
    x = np.concatenate([np.random.default_rng(1).uniform(0.0, xp[-1], 3000), knots, np.nextafter(knots, -1.0),
                        np.nextafter(knots, 2000.0)])
    x = x[(x >= 0.0) & (x <= xp[-1])]
    assert np.array_equal(np.array([_interp(v, xp, fp) for v in x]), np.interp(x, xp, fp))


@pytest.mark.parametrize("name", ["clothoid-open", "hermite-closed"])
@pytest.mark.parametrize("motion", [MotionConfig(), MotionConfig(acceleration=True)], ids=["default", "acceleration"])
def test_compiled_ukf_prediction_equals_numpy(name, motion, monkeypatch):
    """``tracker.motion.predict`` with the compiled kernels (one fused call) against numpy: headings
    near +-pi (wrapped sigma points), ``s`` near a closed road's seam, wide and narrow covariances,
    per-state jerks, the acceleration relaxed and floored first (``relax``, ``floor``: the same as
    predicting the relaxed Gaussians); the fused call gives exactly the numbers of the compiled steps
    one by one; a NaN
    is refused; a covariance that is not positive definite takes the numpy path, which repairs and
    counts it."""
    from tracker.motion import predict, relax_acceleration
    from tracker.ukf import UnscentedTransform

    road = _roads()[name]
    model = FrenetMotion(road, motion)
    ut = UnscentedTransform(n=model.dim)
    rng = np.random.default_rng(3)
    count = 30
    cols = [rng.uniform(0.0, road.length, count), rng.uniform(-6.0, 6.0, count), rng.uniform(0.0, 30.0, count),
            rng.normal(0.0, 0.3, count), rng.normal(0.0, 0.2, count), rng.uniform(3.0, 16.0, count),
            rng.uniform(1.5, 2.6, count)]
    if model.dim == 8:
        cols.append(rng.normal(0.0, 1.0, count))
    mean = np.column_stack(cols)
    mean[:5, 3] = np.pi - 0.01  # sigma points across +-pi
    mean[5:10, 0] = [0.0, 0.05, road.length - 0.05, 1e-9, road.length - 1e-9]  # across the seam or the open ends
    root = rng.normal(0.0, 1.0, (count, model.dim, model.dim)) * rng.uniform(0.01, 2.0, (count, 1, 1))
    cov = root @ np.swapaxes(root, 1, 2) + 1e-3 * np.eye(model.dim)
    jerks = (None, rng.uniform(0.5, 3.0, count)) if model.dim == 8 else (None,)
    for dt in (0.1, 1.0 / 14.0):
        for jerk in jerks:
            monkeypatch.setenv(compiled.ENV_SWITCH, "0")
            ref_pts = ut.sigma_points(mean, cov, model.wrapping)
            ref = predict(ut, model, mean, cov, dt, jerk)
            monkeypatch.setenv(compiled.ENV_SWITCH, "1")
            np.testing.assert_allclose(ut.sigma_points(mean, cov, model.wrapping), ref_pts, rtol=0.0, atol=1e-12)
            got = predict(ut, model, mean, cov, dt, jerk)  # one fused call (FrenetMotion.predict_compiled)
            for a, b in zip(ref, got):
                assert a.shape == b.shape
                np.testing.assert_allclose(b, a, rtol=1e-10, atol=1e-10)
            with monkeypatch.context() as m:  # the compiled steps one by one: the very same numbers
                m.setattr(FrenetMotion, "predict_compiled", None)
                steps = predict(ut, model, mean, cov, dt, jerk)
            assert all(np.array_equal(a, b) for a, b in zip(steps, got))
            if model.dim == 8:  # the tracker's coasting relaxation and a manoeuvre onset's floor, first
                relax = np.where(rng.random(count) < 0.5, rng.uniform(0.5, 1.0, count), 1.0)
                floor = np.where(rng.random(count) < 0.3, rng.uniform(0.0, 3.0, count), -np.inf)
                got = predict(ut, model, mean, cov, dt, jerk, relax, floor)
                with monkeypatch.context() as m:
                    m.setattr(FrenetMotion, "predict_compiled", None)
                    steps = predict(ut, model, mean, cov, dt, jerk, relax, floor)
                assert all(np.array_equal(a, b) for a, b in zip(steps, got))
                m2, p2 = relax_acceleration(mean, cov, relax, floor)
                assert not np.array_equal(m2, mean) and np.array_equal(m2[relax == 1.0], mean[relax == 1.0])
                assert all(np.array_equal(a, b) for a, b in zip(predict(ut, model, m2, p2, dt, jerk), got))
    nan = mean.copy()
    nan[2, 1] = np.nan
    with pytest.raises(ValueError, match="must be finite"):
        predict(ut, model, nan, cov, 0.1)
    bad = cov.copy()
    bad[3] = -np.eye(model.dim)  # not positive definite
    before = ut.repairs
    got = predict(ut, model, mean, bad, 0.1)
    assert ut.repairs > before and np.isfinite(got[1]).all()


@pytest.mark.parametrize("bin_deg", [0.2, 0.37])
def test_compiled_bearing_filter_equals_numpy(bin_deg, monkeypatch):
    """``tracker.preprocess.bearing_filter`` by ``bearing_filter_kernel`` and by numpy: a scan of rays
    on the bins' centres, points sharing a bin at equal ranges (the first index wins), points across
    +-pi (one bin when the bins tile the circle, 0.2 deg; not for 0.37 deg); the same indices."""
    from tracker.preprocess import bearing_filter

    rng = np.random.default_rng(13)
    width = np.deg2rad(bin_deg)
    rays = np.arange(-np.pi, np.pi, width)
    ranges = rng.uniform(2.0, 90.0, len(rays))
    pts = [np.column_stack([ranges * np.cos(rays), ranges * np.sin(rays)])]
    pts.append(rng.normal(0.0, 30.0, (500, 2)))
    twin = pts[0][::7] * 1.0  # the same points again: equal ranges in one bin
    pts.append(twin)
    pts.append(np.array([[-10.0, 1e-12], [-10.0, -1e-12], [-12.0, 0.0]]))  # across +-pi
    pts = np.concatenate(pts)
    rng.shuffle(pts)
    out = {}
    for flag in ("0", "1"):
        monkeypatch.setenv(compiled.ENV_SWITCH, flag)
        out[flag] = bearing_filter(pts, width)
    assert np.array_equal(out["0"], out["1"]) and len(out["1"]) >= len(rays) // 2


@pytest.mark.parametrize("name", ["clothoid-open", "hermite-closed"])
def test_compiled_projection_seed_equals_numpy(name, monkeypatch):
    """``Road.to_frenet`` without a hint seeds its Newton iterations by ``seed_kernel`` when the
    kernels are on: on the seed grid exactly numpy's seed (``Road._nearest_node`` then ``Road._seed``),
    off it (points far from the road) left to the k-d tree; ``(s, n)`` within 1e-9 of numpy's for
    points on the road, far off it, and mixed."""
    from tracker.centerline import seed_kernel
    from tracker.road import PROJECTION_MIN_DENOMINATOR, SEED_GRID_RESOLUTION

    road = _roads()[name]
    rng = np.random.default_rng(17)
    near = road.to_cartesian(rng.uniform(0.0, road.length, 400), rng.uniform(-10.0, 10.0, 400))
    far = near + rng.normal(0.0, 200.0, (400, 2))
    pts = np.ascontiguousarray(np.concatenate([near, far]))
    got, missing = seed_kernel(pts, road._grid_origin, 1.0 / SEED_GRID_RESOLUTION, road._grid, road._node_frame,
                               road._nodes, PROJECTION_MIN_DENOMINATOR)
    assert missing.any() and (~missing).any()
    assert np.array_equal(got[~missing], road._seed(pts, road._nearest_node(pts))[~missing])
    for xy in (near, far, pts):
        out = {}
        for flag in ("1", "0"):
            monkeypatch.setenv(compiled.ENV_SWITCH, flag)
            out[flag] = road.to_frenet(xy)
        for a, b in zip(out["0"], out["1"]):
            np.testing.assert_allclose(b, a, rtol=0.0, atol=1e-9)
