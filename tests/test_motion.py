"""Tests of tracker/motion.py: the exact Frenet kinematics, the paper's flat model, the Cartesian model."""

from __future__ import annotations

import numpy as np
import pytest
from scenes import kernel_roads

from tracker import Road
from tracker.config import MotionConfig, ProcessNoise, TrackerConfig
from oracles.motion import slip_angle
from tracker.motion import (
    CartesianMotion,
    FrenetMotion,
    PaperMotion,
    heading_noise_block,
    make_motion,
    predict,
    process_noise,
)
from tracker.track import curvilinear_to_cartesian
from tracker.ukf import UnscentedTransform

R50 = 50.0


@pytest.fixture(scope="module")
def circle50() -> Road:
    """Circle of radius 50 m turning left from (0, 0) heading +x; centre (0, 50); lanes at n = 0, 3.5."""
    return Road.from_curvature([(2 * np.pi * R50, 1 / R50, 1 / R50)], closed=True, lanes=2, right_edge=-1.75)


NO_SLIP = MotionConfig(slip_lever=0.0)
#: The constant turn of ``xi`` (no road-following prior), for the tests of the kinematics themselves.
CONSTANT_TURN = dict(heading_decay=0.0, yaw_rate_decay=0.0)


def lane_following_error(road: Road, model, v: float = 15.0, n: float = 3.5, steps: int = 100, dt: float = 0.1,
                         xi: float = 0.0):
    """Propagate a lane-following car (body at ``xi`` to the road, xi_dot = 0) for steps * dt seconds;
    return the largest distance (m) from the analytic position on the lane circle (radius 50 - n about
    (0, 50)) and the largest |n - 3.5|."""
    x = np.array([0.0, n, v, xi, 0.0, 4.5, 1.8])
    radius = R50 - n
    worst, worst_n = 0.0, 0.0
    for k in range(1, steps + 1):
        x = model.propagate(x, dt)
        phi = v * k * dt / radius
        truth = np.array([radius * np.sin(phi), R50 - radius * np.cos(phi)])
        pos = road.to_cartesian(x[0], x[1])
        worst = max(worst, float(np.hypot(*(pos - truth))))
        worst_n = max(worst_n, abs(float(x[1]) - n))
    return worst, worst_n


def test_exact_model_keeps_lane_on_tight_circle_paper_model_drifts(circle50: Road) -> None:
    """Radius 50 m, n = 3.5 m, 15 m/s for 10 s at 10 Hz: the exact model stays within 1 cm of the true
    lane position; the paper's flat model advances s at v instead of v / (1 - kappa n), lagging by
    v t kappa n / (1 - kappa n) ~ 11 m of arc."""
    exact_err, exact_dn = lane_following_error(circle50, FrenetMotion(circle50, NO_SLIP))
    paper_err, paper_dn = lane_following_error(circle50, PaperMotion(circle50))
    assert exact_err < 0.01
    assert exact_dn < 1e-9
    assert paper_err > 5.0
    assert exact_err < paper_err


def test_slip_lane_follower_has_its_body_turned_into_the_curve(circle50: Road) -> None:
    """With slip (``slip_lever`` 0.5, the simulator's kinematic bicycle), a car holding its lane on the
    R 46.5 m lane circle has its body at ``xi = -beta``, ``sin beta = psi_dot 0.5 L / v`` with
    ``psi_dot = v / 46.5``: propagated with that ``xi`` it stays on its lane; with ``xi = 0`` (what the
    no-slip model takes for lane keeping) it drifts outward by metres."""
    length, v = 4.5, 15.0
    beta = float(slip_angle(np.array(v / (R50 - 3.5)), np.array(v), np.array(length), 0.5))
    assert beta == pytest.approx(np.arcsin(0.5 * length / (R50 - 3.5)), rel=1e-12)
    slip = FrenetMotion(circle50, MotionConfig(slip_lever=0.5, **CONSTANT_TURN))
    err, dn = lane_following_error(circle50, slip, v=v, xi=-beta)
    assert err < 0.05 and dn < 0.01
    _, drift = lane_following_error(circle50, slip, v=v, xi=0.0)
    assert drift > 1.0


def test_frenet_equals_constant_turn_on_a_straight_road() -> None:
    """On a straight road (kappa = 0) the exact kinematics are the constant-turn model: RK4 with sub-steps
    matches the closed form for a turning car to 1e-7 m."""
    road = Road.from_curvature([(500.0, 0.0, 0.0)], lanes=2)
    x = np.array([[50.0, -1.0, 20.0, 0.1, 0.3, 4.5, 1.8], [60.0, 1.0, 10.0, -0.2, -0.5, 4.0, 1.7]])
    exact = FrenetMotion(road, MotionConfig(max_step=0.01, slip_lever=0.0, **CONSTANT_TURN)).propagate(x, 1.0)
    flat = PaperMotion(road).propagate(x, 1.0)
    np.testing.assert_allclose(exact, flat, atol=1e-7)


def test_small_turn_rate_limit_has_no_division_by_zero(circle50: Road) -> None:
    x0 = np.array([10.0, 0.5, 12.0, 0.2, 0.0, 4.5, 1.8])
    x1 = x0.copy()
    x1[4] = 1e-12
    for model in (PaperMotion(circle50), CartesianMotion()):
        a, b = model.propagate(x0, 0.1), model.propagate(x1, 0.1)
        assert np.isfinite(a).all()
        np.testing.assert_allclose(a, b, atol=1e-9)
    # straight line when xi_dot = 0
    a = CartesianMotion().propagate(x0, 0.5)
    np.testing.assert_allclose(a[:2], x0[:2] + 12.0 * 0.5 * np.array([np.cos(0.2), np.sin(0.2)]), atol=1e-12)


def test_cartesian_constant_turn_follows_a_circle() -> None:
    """psi_dot = v / r: after a quarter period the car is a quarter turn round its circle."""
    v, r = 10.0, 40.0
    x = np.array([0.0, 0.0, v, 0.0, v / r, 4.5, 1.8])
    t = 0.5 * np.pi * r / v
    out = CartesianMotion().propagate(x, t)
    np.testing.assert_allclose(out[:2], [r, r], atol=1e-9)
    assert out[3] == pytest.approx(np.pi / 2)


def test_rk4_substeps_converged_on_a_clothoid() -> None:
    """A lane change on a clothoid ramp: default sub-steps (0.1 s) agree with 1 ms steps to 1e-5 m."""
    road = Road.from_curvature([(100.0, 0.0, 1 / 60), (200.0, 1 / 60, 1 / 60)], lanes=3)
    x = np.array([40.0, -2.0, 25.0, 0.05, -0.05, 4.5, 1.8])
    coarse = FrenetMotion(road, MotionConfig(**CONSTANT_TURN)).propagate(x, 1.0)
    fine = FrenetMotion(road, MotionConfig(max_step=0.001, **CONSTANT_TURN)).propagate(x, 1.0)
    np.testing.assert_allclose(coarse, fine, atol=1e-5)
    # the exact model keeps L, W and v; xi advances by xi_dot dt
    np.testing.assert_allclose(coarse[[2, 4, 5, 6]], x[[2, 4, 5, 6]])
    assert coarse[3] == pytest.approx(x[3] + x[4] * 1.0)


def test_closed_road_wraps_s(circle50: Road) -> None:
    x = np.array([circle50.length - 1.0, 0.0, 20.0, 0.0, 0.0, 4.5, 1.8])
    out = FrenetMotion(circle50, NO_SLIP).propagate(x, 0.1)
    assert 0.0 <= out[0] < 2.0
    assert out[0] == pytest.approx(1.0)


def test_process_noise_structure() -> None:
    noise = ProcessNoise()
    mean = np.array([[0, 0, 10, 0.3, 0, 4.5, 1.8], [0, 0, 10, -1.0, 0, 4.5, 1.8]], dtype=float)
    q = process_noise(mean, 0.1, noise)
    assert q.shape == (2, 7, 7)
    np.testing.assert_allclose(q, np.swapaxes(q, 1, 2))
    assert np.linalg.eigvalsh(q).min() > -1e-15
    assert q[0, 2, 2] == pytest.approx(noise.accel**2 * 0.1)
    assert q[0, 5, 5] == pytest.approx(noise.length**2 * 0.1)
    # the acceleration noise acts along the heading: its position part is rank one along (cos, sin)
    h = mean[0, 3]
    along = np.array([np.cos(h), np.sin(h)])
    across = np.array([-np.sin(h), np.cos(h)])
    assert across @ q[0, :2, :2] @ across == pytest.approx(noise.lateral**2 * 0.1)
    assert along @ q[0, :2, :2] @ along == pytest.approx(noise.accel**2 * 0.1**3 / 3 + noise.along**2 * 0.1)
    np.testing.assert_allclose(process_noise(mean, 0.0, noise), 0.0)
    with pytest.raises(ValueError, match="dt"):
        process_noise(mean, -0.1, noise)


def test_predict_moves_the_mean_and_grows_the_covariance(circle50: Road) -> None:
    ut = UnscentedTransform()
    model = FrenetMotion(circle50)
    mean = np.array([[100.0, 1.75, 15.0, 0.0, 0.0, 4.5, 1.8]] * 3)
    cov = np.broadcast_to(np.diag([1e-8] * 7), (3, 7, 7)).copy()
    m, p = predict(ut, model, mean, cov, 0.1)
    np.testing.assert_allclose(m, model.propagate(mean, 0.1), atol=1e-6)
    q = model.process_noise(m, 0.1)
    assert np.linalg.eigvalsh(p - q).min() > -1e-12
    assert p[0, 0, 0] > cov[0, 0, 0]


def test_make_motion_picks_the_configured_model(circle50: Road) -> None:
    assert isinstance(make_motion(TrackerConfig(), circle50), FrenetMotion)
    assert isinstance(make_motion(TrackerConfig(motion=MotionConfig(model="paper")), circle50), PaperMotion)
    assert isinstance(make_motion(TrackerConfig(coordinates="cartesian"), circle50), CartesianMotion)


def test_curvilinear_and_cartesian_models_agree_for_a_lane_follower(circle50: Road) -> None:
    """The exact Frenet model and the Cartesian constant turn (with psi_dot = v / (R - n)) predict the
    same position for a lane-following car on a circle."""
    x = np.array([30.0, 3.5, 15.0, 0.0, 0.0, 4.5, 1.8])
    xc = curvilinear_to_cartesian(circle50, x)
    a = curvilinear_to_cartesian(circle50, FrenetMotion(circle50, NO_SLIP).propagate(x, 2.0))
    b = CartesianMotion().propagate(xc, 2.0)
    np.testing.assert_allclose(a[:4], b[:4], atol=1e-6)


def test_road_following_prior_keeps_the_slip_lane_follower_on_its_lane(circle50: Road) -> None:
    """With the default prior (heading_decay 1/s, yaw_rate_decay 2/s) lane keeping on a curve with slip,
    ``xi = -beta``, is a fixed point: the car stays on its lane as with the constant turn."""
    beta = float(slip_angle(np.array(15.0 / (R50 - 3.5)), np.array(15.0), np.array(4.5), 0.5))
    err, dn = lane_following_error(circle50, FrenetMotion(circle50, MotionConfig(slip_lever=0.5)), xi=-beta)
    assert err < 0.05 and dn < 0.01


def test_road_following_prior_ends_a_coasting_lane_change() -> None:
    """Coasting 2 s through a lane change (xi 0.1 rad, xi_dot 0.1 rad/s at 20 m/s on a straight road):
    xi and xi_dot decay as the linear system ``xi' = xi_dot - a xi``, ``xi_dot' = -b xi_dot`` says, and
    the lateral move is bounded by ``v int xi`` instead of the constant turn's ``v (xi t + xi_dot t^2/2)``."""
    road = Road.from_curvature([(500.0, 0.0, 0.0)], lanes=3)
    x = np.array([50.0, 0.0, 20.0, 0.1, 0.1, 4.5, 1.8])
    a, b, t = 1.0, 2.0, 2.0
    out = FrenetMotion(road, MotionConfig(slip_lever=0.0, max_step=0.01)).propagate(x, t)
    xi_dot = 0.1 * np.exp(-b * t)
    xi = 0.1 * np.exp(-a * t) + 0.1 * (np.exp(-b * t) - np.exp(-a * t)) / (a - b)
    assert out[4] == pytest.approx(xi_dot, rel=1e-6)
    assert out[3] == pytest.approx(xi, rel=1e-5)
    assert out[1] < 20.0 * (0.1 / a + 0.1 / (a * b))  # int_0^inf xi dt, times v (small angles)
    turn = FrenetMotion(road, MotionConfig(slip_lever=0.0, **CONSTANT_TURN)).propagate(x, t)
    assert turn[1] > 2.0 * out[1]


@pytest.mark.parametrize("dt", [0.05, 0.1, 1.0, 7.3, 60.0])
def test_heading_noise_block_against_the_constant_turn_and_the_lyapunov_solution(dt: float) -> None:
    """``heading_noise_block``: with no decay it is ``process_noise``'s integrated white yaw acceleration;
    with decay it tends to the stationary covariance that solves ``A Q + Q A^T + G G^T = 0``
    (scipy's Lyapunov solver, an independent oracle), and ``Q(dt)`` matches a fine numerical integral."""
    from scipy.integrate import quad_vec
    from scipy.linalg import expm, solve_continuous_lyapunov

    noise = ProcessNoise()
    np.testing.assert_allclose(heading_noise_block(dt, 0.0, 0.0, noise), process_noise(np.zeros(7), dt, noise)[3:5, 3:5],
                               rtol=1e-9, atol=1e-15)
    a, b = 1.0, 2.0
    a_mat = np.array([[-a, 1.0], [0.0, -b]])
    gg = np.diag([noise.heading**2, noise.yaw_accel**2])
    q = heading_noise_block(dt, a, b, noise)
    integral, _ = quad_vec(lambda s: expm(a_mat * s) @ gg @ expm(a_mat * s).T, 0.0, dt, epsabs=1e-14, epsrel=1e-10)
    np.testing.assert_allclose(q, integral, rtol=1e-7, atol=1e-14)
    stationary = solve_continuous_lyapunov(a_mat, -gg)
    assert np.linalg.eigvalsh(stationary - q).min() >= -1e-12  # Q(dt) grows to the stationary covariance
    if dt >= 60.0:
        np.testing.assert_allclose(q, stationary, rtol=1e-9)


def test_rk4_sub_steps_shrink_for_fast_decay_rates() -> None:
    """Large decay rates with a long ``max_step`` would make RK4 diverge (rate x step > 2.8); the
    sub-step is capped at 0.5 / rate, so xi_dot decays as exp(-b t)."""
    road = Road.from_curvature([(500.0, 0.0, 0.0)], lanes=3)
    x = np.array([50.0, 0.0, 20.0, 0.1, 0.1, 4.5, 1.8])
    for step, rate in ((0.5, 10.0), (1.0, 3.0)):
        motion = FrenetMotion(road, MotionConfig(max_step=step, heading_decay=rate, yaw_rate_decay=rate, slip_lever=0.0))
        assert motion.step_limit == pytest.approx(0.5 / rate)
        out = motion.propagate(x, 5.0)
        assert out[4] == pytest.approx(0.1 * np.exp(-rate * 5.0), abs=1e-6)
    assert FrenetMotion(road, MotionConfig()).step_limit == MotionConfig().max_step  # defaults unchanged


def test_acceleration_state_follows_the_singer_mean_and_noise() -> None:
    # straight road, lane keeping: v(t) = v0 + a0 tau (1 - e^{-t/tau}), s(t) = v0 t + a0 tau (t - tau (1 - e^{-t/tau}))
    road = Road.from_curvature([(2000.0, 0.0, 0.0)], lanes=2, lane_width=3.5)
    tau, a0, v0, t = 3.0, 2.0, 10.0, 2.5
    model = FrenetMotion(road, MotionConfig(acceleration=True, acceleration_time=tau, jerk=0.7, residual_accel=0.3))
    assert model.dim == 8 and FrenetMotion(road, MotionConfig(acceleration=False)).dim == 7
    x = np.array([100.0, 1.0, v0, 0.0, 0.0, 4.5, 1.8, a0])
    out = model.propagate(x, t)
    decay = 1.0 - np.exp(-t / tau)
    np.testing.assert_allclose(out[2], v0 + a0 * tau * decay, atol=1e-6)
    np.testing.assert_allclose(out[0], 100.0 + v0 * t + a0 * tau * (t - tau * decay), atol=1e-5)
    np.testing.assert_allclose(out[7], a0 * np.exp(-t / tau), atol=1e-7)
    np.testing.assert_allclose(out[[1, 3, 4, 5, 6]], x[[1, 3, 4, 5, 6]], atol=1e-12)
    # the noise: the 7-state block without the acceleration state and with the white acceleration
    # residual_accel, plus the Singer (v, a) block, whose acceleration variance tends to its stationary
    # value jerk^2 tau / 2
    q8 = model.process_noise(x, 0.1)
    q7 = FrenetMotion(road, MotionConfig(acceleration=False), ProcessNoise(accel=0.3)).process_noise(x[:7], 0.1)
    assert q8.shape == (8, 8)
    extra = q8[:7, :7] - q7
    extra[2, 2] = 0.0
    np.testing.assert_allclose(extra, 0.0, atol=1e-15)
    assert q8[2, 2] > q7[2, 2] and q8[2, 7] > 0.0
    assert np.all(np.linalg.eigvalsh(q8) > -1e-12)
    np.testing.assert_allclose(model.process_noise(x, 200.0)[7, 7], 0.7**2 * tau / 2.0, rtol=1e-6)


def test_a_jerk_per_state_gives_each_state_the_noise_of_a_model_with_that_jerk() -> None:
    # the tracker's manoeuvre-gated jerk (MotionConfig.quiet_jerk) asks process_noise for one jerk per
    # component: each row must equal the noise of a model configured with that jerk, and predict must
    # pass it through
    road = Road.from_curvature([(2000.0, 0.0, 0.0)], lanes=2, lane_width=3.5)
    x = np.array([[100.0, 1.0, 10.0, 0.01, 0.0, 4.5, 1.8, 0.5], [130.0, -1.0, 20.0, 0.0, 0.02, 4.8, 2.0, -2.0]])
    jerks = np.array([0.3, 0.7])
    model = FrenetMotion(road, MotionConfig(jerk=0.7))
    q = model.process_noise(x, 0.1, jerks)
    for i, j in enumerate(jerks):
        alone = FrenetMotion(road, MotionConfig(jerk=float(j))).process_noise(x[i], 0.1)
        np.testing.assert_allclose(q[i], alone, rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(model.process_noise(x, 0.1, np.full(2, 0.7)), model.process_noise(x, 0.1), rtol=1e-12)
    ut = UnscentedTransform(TrackerConfig().ukf, n=8)
    cov = np.broadcast_to(np.diag([0.2, 0.1, 0.3, 0.01, 0.01, 0.5, 0.1, 1.0]), (2, 8, 8)).copy()
    _, p_gated = predict(ut, model, x, cov, 0.1, jerks)
    _, p_full = predict(ut, model, x, cov, 0.1)
    q_quiet = FrenetMotion(road, MotionConfig(jerk=0.3)).process_noise(x[0], 0.1)
    np.testing.assert_allclose(p_full[0] - p_gated[0], model.process_noise(x[0], 0.1) - q_quiet, atol=1e-12)
    np.testing.assert_allclose(p_gated[1], p_full[1], atol=1e-12)


def test_predict_refuses_relax_and_floor_of_the_wrong_shape():
    """``predict``'s ``relax`` and ``floor`` (the tracker's coasting relaxation and a manoeuvre's onset)
    act on the acceleration state: other states, or one value too few, are refused by name."""
    from tracker.config import MotionConfig
    from tracker.motion import FrenetMotion, predict
    from tracker.ukf import UnscentedTransform

    road = Road.from_curvature([(200.0, 0.0, 0.0)], lanes=2, lane_width=3.5)
    for motion, dim, relax in ((MotionConfig(), 7, np.ones(2)), (MotionConfig(acceleration=True), 8, np.ones(1))):
        model = FrenetMotion(road, motion)
        mean = np.tile(np.r_[50.0, 0.0, 10.0, 0.0, 0.0, 4.5, 1.9, 0.0][:dim], (2, 1))
        cov = np.tile(np.eye(dim) * 0.1, (2, 1, 1))
        with pytest.raises(ValueError, match="relax and floor"):
            predict(UnscentedTransform(n=dim), model, mean, cov, 0.1, relax=relax)


# -- the Frenet motion and UKF prediction kernels against the numpy oracles -----------------------------
KERNEL_ROADS = kernel_roads()


@pytest.mark.parametrize("name", ["clothoid-open", "hermite-closed"])
@pytest.mark.parametrize("motion", [MotionConfig(), MotionConfig(acceleration=True), MotionConfig(slip_lever=0.0)],
                         ids=["default", "acceleration", "no-slip"])
def test_frenet_propagation_kernel_against_the_oracle(name, motion):
    """``FrenetMotion.propagate`` (``rk4_propagate``) against the oracle's numpy RK4: states on and
    beyond the road (open ends extrapolate straight), backwards and standing, over one frame and over
    several RK4 sub-steps, in a (16, 15) batch; within 1e-9."""
    from oracles.motion import propagate

    road = KERNEL_ROADS[name]
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
        got = model.propagate(x, dt)
        assert got.shape == x.shape
        np.testing.assert_allclose(got, propagate(model, x, dt), rtol=0.0, atol=1e-9)
    np.testing.assert_array_equal(model.propagate(x[0, 0], 0.1), model.propagate(x[:1, :1], 0.1)[0, 0])  # one state
    with pytest.raises(ValueError, match="7\\) or"):
        model.propagate(np.zeros((3, 6)), 0.1)


def test_curvature_interpolation_kernel_equals_numpy_interp():
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
def test_ukf_prediction_kernel_against_the_oracle(name, motion, monkeypatch):
    """``predict`` with ``FrenetMotion`` (one call of ``ukf_predict_kernel``) against the oracle's numpy
    prediction: headings near +-pi (wrapped sigma points), ``s`` near a closed road's seam or an open
    road's ends, wide and narrow covariances, per-state jerks; the sigma points within 1e-12, the moments
    within 1e-10. The one call gives exactly the numbers of its steps one by one (``sigma_kernel``,
    ``rk4_propagate``, ``moments_kernel``), also with the acceleration relaxed and floored first
    (``relax``, ``floor``: the same as predicting the relaxed Gaussians); a NaN is refused; a
    covariance that is not positive definite is repaired and counted."""
    from oracles.motion import predict as oracle_predict
    from oracles.ukf import sigma_points
    from tracker.motion import relax_acceleration

    road = KERNEL_ROADS[name]
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
    np.testing.assert_allclose(ut.sigma_points(mean, cov, model.wrapping),
                               sigma_points(mean, cov, ut.scale, model.wrapping), rtol=0.0, atol=1e-12)
    jerks = (None, rng.uniform(0.5, 3.0, count)) if model.dim == 8 else (None,)
    for dt in (0.1, 1.0 / 14.0):
        for jerk in jerks:
            got = predict(ut, model, mean, cov, dt, jerk)  # one call (FrenetMotion.predict_compiled)
            ref = oracle_predict(ut, model, mean, cov, dt, jerk)
            assert got[0].shape == ref[0].shape and got[1].shape == ref[1].shape
            d = got[0] - ref[0]
            if road.closed:  # s across the seam: the shortest difference
                d[:, 0] = (d[:, 0] + 0.5 * road.length) % road.length - 0.5 * road.length
            assert np.all(np.abs(d) <= 1e-10 + 1e-10 * np.abs(ref[0]))
            np.testing.assert_allclose(got[1], ref[1], rtol=1e-10, atol=1e-10)
            with monkeypatch.context() as m:  # the steps one by one: the very same numbers
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


def test_oncoming_vehicle_keeps_its_lane_and_heading():
    """A vehicle driving against ``s`` (``xi = pi``) in its lane on a curve: the road-following prior
    relaxes its course toward pi (the axis it drives along), never toward 0; it holds its lateral offset
    as the road curves under it, and its heading in G turns with the road's (pi from it)."""
    road = Road.from_curvature([(400.0, 0.01, 0.01)], lanes=2, oncoming=1)
    motion = FrenetMotion(road, MotionConfig(slip_lever=0.0))
    x = np.array([[300.0, 1.75, 15.0, np.pi, 0.0, 4.5, 1.8],
                  [300.0, 1.75, 15.0, -np.pi + 0.1, 0.0, 4.5, 1.8]])  # on course, and 0.1 rad off it
    out = motion.propagate(x, 4.0)
    # on course: s falls at v / (1 - kappa n) (the road's metric), n and xi unchanged
    assert out[0, 0] == pytest.approx(300.0 - 4.0 * 15.0 / (1.0 - 0.01 * 1.75), abs=1e-6)
    assert out[0, 1] == pytest.approx(1.75, abs=1e-9)
    assert abs(np.mod(out[0, 3], 2 * np.pi) - np.pi) < 1e-9
    # off course by 0.1 rad: the prior brings it back toward pi (not across to 0)
    assert abs(np.mod(out[1, 3], 2 * np.pi) - np.pi) < 0.1 * np.exp(-1.0 * 4.0) * 3.0
    assert out[1, 0] < 260.0

