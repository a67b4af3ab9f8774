"""Tests of tracker/update.py: the low-rank UKF update against the textbook one, and the single-target
filter (predict + update) on a car driving a radius-80 m curve, seen by a simulated scanning lidar."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import multivariate_normal

from tracker import Road
from tracker import jit as compiled_kernels
from tracker.config import MeasurementConfig, TrackerConfig
from tracker.measurement import prepare_cluster, rectangle_scan, to_vehicle
from tracker.motion import make_motion, predict
from tracker.track import cartesian_to_curvilinear, curvilinear_to_cartesian
from tracker.ukf import UnscentedTransform, Wrapping
from tracker.update import kalman_update, update, update_pairs

R80 = 80.0
DT = 0.1


@pytest.fixture(scope="module")
def circle80() -> Road:
    """Radius 80 m, turning left; two 3.5 m lanes at n = -1.75 (right) and +1.75 (left)."""
    return Road.from_curvature([(2 * np.pi * R80, 1 / R80, 1 / R80)], closed=True, lanes=2)


class CurveScenario:
    """A target (4.7 m x 1.9 m) in the left lane (n = 1.75) of the radius-80 curve; the ego follows in the
    right lane, 10 m behind in s at t = 0 and falling back 2 m/s (so the lidar's ray pattern on the target
    changes from frame to frame). Its speed is 15 m/s, or a random walk (white acceleration of density
    ``accel`` m/s^1.5) when ``accel > 0``. The lidar sits at the ego's centre: rays every ``res`` rad,
    Gaussian range noise ``noise`` m along the ray (as ``sim.sensors.lidar``)."""

    def __init__(self, road: Road, frames: int, accel: float = 0.0, seed: int = 0) -> None:
        self.road = road
        rng = np.random.default_rng(10_000 + seed)
        n = 1.75
        s, v = 30.0, 15.0
        self.states = []
        for _ in range(frames):
            self.states.append(np.array([s % road.length, n, v, 0.0, 0.0, 4.7, 1.9]))
            a = accel / np.sqrt(DT) * rng.standard_normal() if accel > 0 else 0.0
            s += (v * DT + 0.5 * a * DT * DT) / (1.0 - n / R80)
            v += a * DT

    def truth(self, k: int) -> np.ndarray:
        return self.states[k]

    def ego(self, k: int) -> tuple[float, float, float]:
        s_e = self.states[k][0] - (10.0 + 2.0 * k * DT)
        xy = self.road.to_cartesian(s_e, -1.75)
        return float(xy[0]), float(xy[1]), float(self.road.heading(self.road.wrap_s(s_e)))

    def scan(self, k: int, rng: np.random.Generator, noise: float, res: float = np.radians(0.2)) -> np.ndarray:
        corners = to_vehicle(self.truth(k), self.ego(k), self.road).corners()
        b = np.arctan2(corners[:, 1], corners[:, 0])
        rays = np.arange(np.ceil(b.min() / res), np.floor(b.max() / res) + 1) * res
        pts, _ = rectangle_scan(corners, rays)
        r = np.hypot(pts[:, 0], pts[:, 1])
        return pts * ((r + noise * rng.standard_normal(len(r))) / r)[:, None]

    def radar_velocity(self, k: int, rng: np.random.Generator, noise: float) -> np.ndarray:
        return to_vehicle(self.truth(k), self.ego(k), self.road).velocity() + noise * rng.standard_normal(2)


INIT_ERROR = np.array([1.0, 0.3, -3.0, 0.05, 0.0, -0.7, -0.3])
INIT_STD = np.array([1.0, 0.3, 3.0, 0.1, 0.05, 1.0, 0.3])


def run_filter(scn: CurveScenario, config: TrackerConfig, frames: int, noise: float, seed: int,
               radar_noise: float | None = None) -> list[np.ndarray]:
    """Predict/update over ``frames`` frames from a perturbed start; returns the curvilinear estimate
    after each update (a Cartesian-state filter is converted for comparison)."""
    road = scn.road
    ut = UnscentedTransform(config.ukf)
    motion = make_motion(config, road)
    rng = np.random.default_rng(seed)
    mean = scn.truth(0) + INIT_ERROR
    cov = np.diag(INIT_STD**2)
    if config.coordinates == "cartesian":
        mean = curvilinear_to_cartesian(road, mean)
        cov = np.diag(np.r_[1.0, 1.0, INIT_STD[2:]] ** 2)
    out = []
    for k in range(frames):
        if k:
            mean, cov = predict(ut, motion, mean, cov, DT)
        vel = None if radar_noise is None else scn.radar_velocity(k, rng, radar_noise)
        cluster = prepare_cluster(scn.scan(k, rng, noise), config.measurement, velocity=vel)
        mean, cov, _ = update(mean, cov, cluster, scn.ego(k), road, config, ut)
        est = mean if config.coordinates == "curvilinear" else cartesian_to_curvilinear(road, mean, scn.truth(k)[0])
        out.append(est)
    assert ut.repairs == 0
    return out


def position_error(road: Road, est: np.ndarray, truth: np.ndarray) -> float:
    return float(np.hypot(*(curvilinear_to_cartesian(road, est)[:2] - curvilinear_to_cartesian(road, truth)[:2])))


# -- the update's algebra ----------------------------------------------------------------------------
def _random_pairs(rng: np.random.Generator, p_count: int, d: int):
    """``p_count`` random Gaussians of a 7-state (yaw wrapped), their sigma points and a nonlinear
    ``d``-row measurement of them: ``(ut, wrap, mean, cov, sigma, z_sigma)``."""
    ut = UnscentedTransform()
    wrap = Wrapping(angles=(3,))
    mean = rng.standard_normal((p_count, 7))
    a = rng.standard_normal((p_count, 7, 7))
    cov = a @ np.swapaxes(a, 1, 2) / 7 + 0.1 * np.eye(7)
    sigma = ut.sigma_points(mean, cov, wrap)
    return ut, wrap, mean, cov, sigma, np.tanh(sigma @ rng.standard_normal((d, 7)).T)


def test_low_rank_update_equals_dense_textbook_update() -> None:
    """The matrix-inversion-lemma update equals K = T S^-1 with the full D x D innovation covariance,
    including the low-rank noise factors and masked padding rows; the log-likelihood equals scipy's."""
    rng = np.random.default_rng(0)
    p_count, d = 3, 12
    ut, wrap, mean, cov, sigma, z_sigma = _random_pairs(rng, p_count, d)
    z = rng.standard_normal((p_count, d))
    r = rng.uniform(0.01, 0.1, (p_count, d))
    factors = 0.1 * rng.standard_normal((p_count, 2, d))
    mask = np.ones((p_count, d), dtype=bool)
    mask[1, 8:] = False  # pair 1 has only 8 rows
    z_sigma = z_sigma * mask[:, None, :]
    factors = factors * mask[:, None, :]
    res = kalman_update(ut, sigma, mean, cov, z_sigma, z, r, mask, wrap, factors)
    for p in range(p_count):
        rows = mask[p]
        zs = z_sigma[p][:, rows]
        y = ut.wm @ zs
        dz = zs - y
        dx = ut.deviations(sigma[p], mean[p], wrap)
        f = factors[p][:, rows]
        s_mat = (ut.wc[:, None] * dz).T @ dz + np.diag(r[p, rows]) + f.T @ f
        t_mat = (ut.wc[:, None] * dx).T @ dz
        k_mat = t_mat @ np.linalg.inv(s_mat)
        np.testing.assert_allclose(res.mean[p], wrap.wrap(mean[p] + k_mat @ (z[p, rows] - y)), atol=1e-10)
        np.testing.assert_allclose(res.cov[p], cov[p] - k_mat @ s_mat @ k_mat.T, atol=1e-10)
        assert res.log_likelihood[p] == pytest.approx(multivariate_normal(y, s_mat).logpdf(z[p, rows]), rel=1e-10)
        assert res.dim[p] == rows.sum()


@pytest.mark.parametrize("compiled", [False, True], ids=["numpy", "compiled"])
def test_likelihood_variances_change_the_weights_not_the_posterior(compiled, monkeypatch) -> None:
    """``kalman_update(..., r_likelihood=...)`` (``MeasurementConfig.shadowed_lidar_sigma``: the update
    softened, the weights and the gate not): the posterior is the update with ``r``, the log-likelihood and NIS
    those of the update with ``r_likelihood`` (against scipy's density with the dense ``S``), for the
    pairs where they differ; a pair where they agree is untouched."""
    monkeypatch.setenv("EOT_NUMBA", "1" if compiled else "0")
    rng = np.random.default_rng(3)
    p_count, d = 3, 10
    ut, wrap, mean, cov, sigma, z_sigma = _random_pairs(rng, p_count, d)
    z = rng.standard_normal((p_count, d))
    factors = 0.1 * rng.standard_normal((p_count, 2, d))
    mask = np.ones((p_count, d), dtype=bool)
    soft = np.full((p_count, d), 0.15**2)
    nominal = np.full((p_count, d), 0.1**2)
    soft[2] = nominal[2]  # pair 2: the same variances
    got = kalman_update(ut, sigma, mean, cov, z_sigma, z, soft, mask, wrap, factors, r_likelihood=nominal)
    update = kalman_update(ut, sigma, mean, cov, z_sigma, z, soft, mask, wrap, factors)
    weight = kalman_update(ut, sigma, mean, cov, z_sigma, z, nominal, mask, wrap, factors)
    np.testing.assert_allclose(got.mean, update.mean, atol=1e-12)
    np.testing.assert_allclose(got.cov, update.cov, atol=1e-12)
    np.testing.assert_allclose(got.log_likelihood, weight.log_likelihood, rtol=1e-10)
    np.testing.assert_allclose(got.nis, weight.nis, rtol=1e-10)
    assert abs(update.log_likelihood[0] - weight.log_likelihood[0]) > 1.0  # what the option changes
    dz = z_sigma[0] - ut.wm @ z_sigma[0]
    s_mat = (ut.wc[:, None] * dz).T @ dz + np.diag(nominal[0]) + factors[0].T @ factors[0]
    assert got.log_likelihood[0] == pytest.approx(multivariate_normal(ut.wm @ z_sigma[0], s_mat).logpdf(z[0]), rel=1e-10)


def test_batched_pairs_equal_single_updates(circle80: Road) -> None:
    """Two components x two clusters of different sizes in one batch give the same posteriors and
    likelihoods as four separate updates; the right component explains the cluster better."""
    scn = CurveScenario(circle80, 2)
    rng = np.random.default_rng(3)
    cfg = TrackerConfig()
    clusters = [prepare_cluster(scn.scan(0, rng, 0.03), cfg.measurement),
                prepare_cluster(scn.scan(0, rng, 0.03)[::3], cfg.measurement, velocity=[14.0, 1.0])]
    means = np.stack([scn.truth(0), scn.truth(0) + np.array([2.0, 0.5, 0, 0.1, 0, 0, 0])])
    covs = np.stack([np.diag(INIT_STD**2)] * 2)
    comp, clu = np.array([0, 0, 1, 1]), np.array([0, 1, 0, 1])
    res = update_pairs(means, covs, clusters, comp, clu, scn.ego(0), circle80, cfg)
    for p in range(4):
        m, c, ll = update(means[comp[p]], covs[comp[p]], clusters[clu[p]], scn.ego(0), circle80, cfg)
        np.testing.assert_allclose(res.mean[p], m, atol=1e-9)
        np.testing.assert_allclose(res.cov[p], c, atol=1e-9)
        assert res.log_likelihood[p] == pytest.approx(ll, rel=1e-9)
    assert res.log_likelihood[0] > res.log_likelihood[2]


# -- the single-target filter on a curve -------------------------------------------------------------
def test_noise_free_points_converge_to_the_true_state(circle80: Road) -> None:
    """Noise-free scans (rays every 0.2 deg) for 3 s from an initial error of (1 m, 0.3 m, -3 m/s,
    0.05 rad, -, -0.7 m, -0.3 m): after 3 s |s| < 3 cm, |n| < 1 cm, |xi| < 0.005 rad, |L| < 5 cm,
    |W| < 3 cm, |v| < 0.05 m/s (measured: 0.8 cm, 0.1 cm, 0.002 rad, 1.6 cm, 0.9 cm, 0.0002 m/s; what
    remains is the ray-phase error of the far ends)."""
    scn = CurveScenario(circle80, 31)
    cfg = TrackerConfig(measurement=MeasurementConfig(lidar_sigma=0.03))
    est = run_filter(scn, cfg, 31, noise=0.0, seed=0)
    err = est[-1] - scn.truth(30)
    tol = np.array([0.03, 0.01, 0.05, 0.005, np.inf, 0.05, 0.03])
    assert np.all(np.abs(err) < tol), err


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_noisy_points_position_within_10cm_extent_within_20cm(circle80: Road, seed: int) -> None:
    """Range noise 0.03 m: after 3 s at 10 Hz the centre is within 0.1 m and L, W within 0.2 m."""
    scn = CurveScenario(circle80, 31)
    est = run_filter(scn, TrackerConfig(), 31, noise=0.03, seed=seed)
    truth = scn.truth(30)
    assert position_error(circle80, est[-1], truth) < 0.1
    assert abs(est[-1][5] - truth[5]) < 0.2
    assert abs(est[-1][6] - truth[6]) < 0.2


@pytest.mark.parametrize("seed", [0, 1])
def test_cartesian_state_converges_on_the_same_case(circle80: Road, seed: int) -> None:
    scn = CurveScenario(circle80, 31)
    est = run_filter(scn, TrackerConfig(coordinates="cartesian"), 31, noise=0.03, seed=seed)
    truth = scn.truth(30)
    assert position_error(circle80, est[-1], truth) < 0.1
    assert abs(est[-1][3] - truth[3]) < 0.02
    assert abs(est[-1][5] - truth[5]) < 0.2
    assert abs(est[-1][6] - truth[6]) < 0.2


def test_radar_velocity_rows_lower_the_speed_error(circle80: Road) -> None:
    """The target's speed is a random walk matching the filter's acceleration noise (a constant speed
    would favour the lidar-only filter, whose process noise then overstates the truth's). Radar velocity
    noise 0.2 m/s per axis. Over 10 seeds, the RMS speed error at t = 1 s with the radar rows is lower
    than without, and so is the RMS over 0.5 .. 1 s."""
    fused_cfg = TrackerConfig(measurement=MeasurementConfig(radar_velocity_sigma=0.2))
    lidar_cfg = TrackerConfig(use_radar=False)
    errors = {"fused": [], "lidar": []}
    for seed in range(10):
        scn = CurveScenario(circle80, 11, accel=fused_cfg.process_noise.accel, seed=seed)
        for name, cfg in (("fused", fused_cfg), ("lidar", lidar_cfg)):
            est = run_filter(scn, cfg, 11, noise=0.03, seed=seed, radar_noise=0.2)
            errors[name].append([e[2] - scn.truth(k)[2] for k, e in enumerate(est)])
    fused, lidar = np.array(errors["fused"]), np.array(errors["lidar"])
    rms = lambda e: float(np.sqrt(np.mean(e**2)))  # noqa: E731
    assert rms(fused[:, 10]) < rms(lidar[:, 10])
    assert rms(fused[:, 5:]) < rms(lidar[:, 5:])


def test_no_pairs_gives_an_empty_result(circle80: Road) -> None:
    scn = CurveScenario(circle80, 1)
    cluster = prepare_cluster(scn.scan(0, np.random.default_rng(0), 0.0))
    res = update_pairs(scn.truth(0)[None], np.eye(7)[None], [cluster], np.zeros(0, int), np.zeros(0, int),
                       scn.ego(0), circle80)
    assert res.mean.shape == (0, 7) and res.log_likelihood.shape == (0,) and res.radar_rejected.shape == (0,)
    with pytest.raises(ValueError, match="does not exist"):
        update_pairs(scn.truth(0)[None], np.eye(7)[None], [cluster], np.array([1]), np.array([0]), scn.ego(0), circle80)


def test_unobserved_length_is_held_observed_length_is_updated() -> None:
    """A car straight ahead shows only its rear: ``s - L/2`` is measured, ``L`` is not. With
    ``hold_unobserved_extent`` (default) the update keeps the prior's ``L`` mean and variance (the
    Schmidt update), while the plain update splits the along-track innovation between ``s`` and ``L``. A car ahead in the next lane shows its right side too: ``L`` is updated."""
    road = Road.from_curvature([(500.0, 0.0, 0.0)], lanes=2, lane_width=3.5)
    ego = (100.0, -1.75, 0.0)
    cfg = TrackerConfig()
    plain = TrackerConfig(measurement=MeasurementConfig(hold_unobserved_extent=False))
    res = np.radians(0.2)
    cov = np.diag(INIT_STD**2)
    for n_target, seen in ((-1.75, False), (1.75, True)):
        truth = np.array([130.0, n_target, 20.0, 0.0, 0.0, 4.8, 2.0])
        corners = to_vehicle(truth[None], ego, road).corners()[0]
        b = np.arctan2(corners[:, 1], corners[:, 0])
        pts, _ = rectangle_scan(corners, np.arange(np.ceil(b.min() / res), np.floor(b.max() / res) + 1) * res)
        cluster = prepare_cluster(pts, cfg.measurement)
        prior = truth + np.array([0.4, 0.0, 0.0, 0.0, 0.0, -0.8, 0.0])
        m, c, _ = update(prior, cov, cluster, ego, road, cfg)
        m0, c0, _ = update(prior, cov, cluster, ego, road, plain)
        assert np.linalg.eigvalsh(c).min() > 0.0 and np.allclose(c, c.T)
        if seen:
            assert abs(m[5] - 4.8) < abs(prior[5] - 4.8) - 0.1 and c[5, 5] < 0.8 * cov[5, 5]
        else:
            assert m[5] == prior[5] and c[5, 5] == cov[5, 5]
            assert abs(m0[5] - prior[5]) > 0.05  # the plain update moved the unobserved length
            # s - L/2 is measured: over a few frames s takes the whole correction, L keeps its prior
            mk, ck = m, c
            for _ in range(30):
                mk, ck, _ = update(mk, ck, cluster, ego, road, cfg)
            rear_before, rear_after = prior[0] - prior[5] / 2 - 127.6, mk[0] - mk[5] / 2 - 127.6
            assert abs(rear_after) < 0.25 * abs(rear_before) and mk[5] == prior[5]
            np.testing.assert_allclose(np.delete(np.delete(c, 5, 0), 5, 1), np.delete(np.delete(c0, 5, 0), 5, 1), atol=1e-12)


def test_a_truck_side_longer_than_the_prior_grows_the_length_and_passes_the_gate() -> None:
    """A 12 m truck tracked from its rear with a car's length prior (4.5 +- 1 m) shows its left side:
    its points run 7.5 m past the predicted rectangle. Without ``grow_extent`` the normalised innovation
    is in the far tail (p < 0.01; for an 18 m bus in the simulator it fails the gate and a newborn takes
    the cluster) and ``L`` creeps up by about a metre per update; with it the prior gets the excess as
    variance anchored at the rear, the innovation is ordinary, ``L`` is within 0.5 m of 12 m after one
    update and the rear stays where it was seen."""
    from scipy.stats import chi2

    road = Road.from_curvature([(500.0, 0.0, 0.0)], lanes=2, lane_width=3.5)
    ego = (100.0, 1.75, 0.0)
    truth = np.array([135.0, -1.75, 10.0, 0.0, 0.0, 12.0, 2.5])
    res = np.radians(0.2)
    corners = to_vehicle(truth[None], ego, road).corners()[0]
    b = np.arctan2(corners[:, 1], corners[:, 0])
    pts, _ = rectangle_scan(corners, np.arange(np.ceil(b.min() / res), np.floor(b.max() / res) + 1) * res)
    cluster = prepare_cluster(pts, MeasurementConfig())
    rear = truth[0] - truth[5] / 2
    prior = np.array([rear + 2.25, -1.75, 10.0, 0.0, 0.0, 4.5, 2.5])  # the rear in place, a car's length
    cov = np.diag([0.3, 0.1, 1.0, 0.05, 0.02, 1.0, 0.1]) ** 2
    grow = TrackerConfig()
    plain = TrackerConfig(measurement=MeasurementConfig(grow_extent=False))
    res_grow = update_pairs(prior, cov, [cluster], np.zeros(1, int), np.zeros(1, int), ego, road, grow)
    res_plain = update_pairs(prior, cov, [cluster], np.zeros(1, int), np.zeros(1, int), ego, road, plain)
    dim = int(res_grow.dim[0])
    assert res_plain.nis[0] > chi2.ppf(0.99, dim)
    assert res_grow.nis[0] < chi2.ppf(0.5, dim)
    m = res_grow.mean[0]
    assert abs(m[5] - 12.0) < 0.5 and abs(res_plain.mean[0, 5] - 12.0) > 3.0
    assert abs((m[0] - m[5] / 2) - rear) < 0.3
    assert np.linalg.eigvalsh(res_grow.cov[0]).min() > 0.0


@pytest.mark.parametrize("settled_width_std", [0.15, None], ids=["settled-width-kept", "off"])
def test_grow_extent_leaves_a_settled_width_alone(settled_width_std) -> None:
    """Three pairs whose short side runs 0.8 m past the predicted width, and one whose long side runs
    6 m past the predicted length: a width scanned for a while (sd 0.03 m) is not grown with
    ``settled_width_std`` (the excess is the heading lagging, the side joined the rear's chord), an
    unsettled one (sd 0.3 m, a new track) is; the length grows whatever the width's spread."""
    from types import SimpleNamespace

    from tracker.measurement import rectangle_corners
    from tracker.update import grow_extent

    means = np.array([[100.0, 0.0, 10.0, 0.0, 0.0, 4.5, 2.1]] * 4)
    sd_w = np.array([0.03, 0.3, 0.149, 0.03])
    covs = np.array([np.diag([0.1, 0.1, 0.1, 0.01, 0.01, 0.3**2, s**2]) for s in sd_w])
    structure = SimpleNamespace(sides=np.array([[0, 2], [0, 2], [0, 2], [1, 3]]),  # short sides, then long ones
                                excess=np.array([[0.8, np.nan], [0.8, np.nan], [0.8, np.nan], [6.0, np.nan]]))
    corners = rectangle_corners(np.array([[20.0, 0.0]] * 4), np.zeros(4), means[:, 5], means[:, 6])
    grown, out = grow_extent(means, covs, structure, corners, settled_width_std)
    expect_width = [settled_width_std is None, True, settled_width_std is None, False]
    np.testing.assert_array_equal(out[:, 6, 6] > covs[:, 6, 6], expect_width)
    np.testing.assert_array_equal(out[:, 5, 5] > covs[:, 5, 5], [False, False, False, True])
    np.testing.assert_array_equal(grown, np.array(expect_width) | [False, False, False, True])
    assert out[1, 6, 6] == pytest.approx(0.3**2 + 0.8**2)


def test_long_vehicle_prior_applies_once_to_an_unmeasured_car_length():
    """``long_vehicle_prior`` replaces a car's never-measured length by a long vehicle's (centre moved
    away from the sensor by half the change, variance added along that direction), and leaves alone a
    track that already carries it and one whose length was measured."""
    from tracker.config import BirthConfig
    from tracker.measurement import rectangle_corners
    from tracker.update import UpdateResult, long_vehicle_prior

    cfg = BirthConfig()
    mean = np.array([[100.0, 0.0, 10.0, 0.0, 0.0, 4.5, 2.5]] * 4)
    mean[1, 5] = 12.0  # already long
    mean[3, 6] = 2.0  # a car's width
    cov = np.tile(np.diag([0.1, 0.1, 0.1, 0.01, 0.01, cfg.length_std**2, 0.01]), (4, 1, 1))
    cov[2, 5, 5] = 0.05**2  # measured
    res = UpdateResult(mean.copy(), cov.copy(), np.zeros(4), np.zeros(4), np.zeros(4, dtype=int), np.zeros((4, 2)),
                       np.zeros((4, 2)))
    corners = rectangle_corners(np.array([[20.0, 0.0]] * 4), np.zeros(4), mean[:, 5], mean[:, 6])  # ahead, in E
    hit = long_vehicle_prior(res, np.ones(4, dtype=bool), corners, cfg)
    np.testing.assert_array_equal(hit, [True, False, False, False])
    e = cfg.long_length - 4.5
    assert res.mean[0, 5] == pytest.approx(cfg.long_length) and res.mean[0, 0] == pytest.approx(100.0 + 0.5 * e)
    assert res.cov[0, 5, 5] == pytest.approx(cfg.length_std**2 + cfg.long_length_std**2)
    assert res.cov[0, 0, 5] == pytest.approx(0.5 * cfg.long_length_std**2)
    np.testing.assert_array_equal(res.mean[1:], mean[1:])
    np.testing.assert_array_equal(res.cov[1:], cov[1:])
    behind = rectangle_corners(np.array([[-20.0, 0.0]] * 4), np.zeros(4), mean[:, 5], mean[:, 6])  # the rear is far
    res2 = UpdateResult(mean.copy(), cov.copy(), *(np.zeros(4),) * 2, np.zeros(4, dtype=int), *(np.zeros((4, 2)),) * 2)
    long_vehicle_prior(res2, np.ones(4, dtype=bool), behind, cfg)
    assert res2.mean[0, 0] == pytest.approx(100.0 - 0.5 * e)  # the front (nearest the sensor) stays put


def test_narrow_vehicle_prior_gives_a_measured_narrow_rear_a_motorcycles_length():
    """``narrow_vehicle_prior`` replaces a car's never-measured length by a motorcycle's where the width
    is measured narrow (centre moved towards the sensor by half the change: the rear stays put), and
    leaves alone a narrow width that is only a guess, a car's width, a length already short, and one
    that was measured."""
    from tracker.config import BirthConfig
    from tracker.measurement import rectangle_corners
    from tracker.update import UpdateResult, narrow_vehicle_prior

    cfg = BirthConfig()
    mean = np.array([[100.0, 0.0, 10.0, 0.0, 0.0, 4.5, 0.8]] * 5)
    cov = np.tile(np.diag([0.1, 0.1, 0.1, 0.01, 0.01, cfg.length_std**2, 0.03**2]), (5, 1, 1))
    cov[1, 6, 6] = 0.3**2  # the width not measured
    mean[2, 6] = 1.8  # a car's width
    mean[3, 5] = 2.3  # already a motorcycle's length
    cov[4, 5, 5] = 0.05**2  # the length measured (a side seen)
    res = UpdateResult(mean.copy(), cov.copy(), np.zeros(5), np.zeros(5), np.zeros(5, dtype=int), np.zeros((5, 2)),
                       np.zeros((5, 2)))
    corners = rectangle_corners(np.array([[20.0, 0.0]] * 5), np.zeros(5), mean[:, 5], mean[:, 6])  # ahead, in E
    hit = narrow_vehicle_prior(res, np.ones(5, dtype=bool), corners, cfg)
    np.testing.assert_array_equal(hit, [True, False, False, False, False])
    e = cfg.narrow_length - 4.5  # -2.3 m
    assert res.mean[0, 5] == pytest.approx(cfg.narrow_length)
    assert res.mean[0, 0] - 0.5 * res.mean[0, 5] == pytest.approx(100.0 - 0.5 * 4.5)  # the rear stays put
    assert res.mean[0, 0] == pytest.approx(100.0 + 0.5 * e)
    assert res.cov[0, 5, 5] == pytest.approx(cfg.length_std**2 + cfg.narrow_length_std**2)
    np.testing.assert_array_equal(res.mean[1:], mean[1:])
    np.testing.assert_array_equal(res.cov[1:], cov[1:])
    not_held = UpdateResult(mean.copy(), cov.copy(), *(np.zeros(5),) * 2, np.zeros(5, dtype=int), *(np.zeros((5, 2)),) * 2)
    assert not narrow_vehicle_prior(not_held, np.zeros(5, dtype=bool), corners, cfg).any()  # the length was updated


@pytest.mark.parametrize("max_width", [3.0, None], ids=["limited", "unlimited"])
def test_an_estimate_wider_than_any_vehicle_is_projected_back(max_width) -> None:
    """Two vehicles' rears side by side form one 8 m line; with a loose width prior the update alone
    makes the track ~8 m wide. With ``BirthConfig.max_width`` the width is projected back onto 3 m."""
    import dataclasses

    from tracker.config import BirthConfig

    road = Road.from_curvature([(500.0, 0.0, 0.0)], lanes=3)
    ego = (100.0, 0.0, 0.0)
    line = np.column_stack([np.full(41, 25.0), np.linspace(-4.0, 4.0, 41)])  # 8 m of rear, 25 m ahead
    cluster = prepare_cluster(line, MeasurementConfig())
    mean = np.array([126.0, 0.0, 10.0, 0.0, 0.0, 4.5, 2.5])
    cov = np.diag([0.5, 0.5, 1.0, 0.01, 0.01, 1.0, 9.0])
    base = TrackerConfig()
    config = dataclasses.replace(base, birth=BirthConfig(long_width=None, max_width=max_width))
    post, _, _ = update(mean, cov, cluster, ego, road, config)
    if max_width is None:
        assert post[6] > 6.0
    else:
        assert post[6] == pytest.approx(max_width)


@pytest.mark.parametrize("kernels", ["numpy", "compiled"])
@pytest.mark.parametrize("radar_rows", ["speed", "velocity"])
@pytest.mark.parametrize("off, gate, rejected", [(20.0, 25.0, True), (3.0, 25.0, False), (20.0, None, False)],
                         ids=["false-alarm", "braking", "gate-off"])
def test_a_radar_velocity_no_pair_explains_is_set_aside(circle80: Road, off: float, gate, rejected: bool,
                                                         radar_rows: str, kernels: str, monkeypatch) -> None:
    """``MeasurementConfig.radar_gate``: a cluster's radar velocity 20 m/s slower than the prediction
    (speed std 3 m/s: normalised innovation ~43 > 25) is a false alarm: set aside, the posterior is the
    lidar-only one. 3 m/s slower (~1) is a braking the prediction lags behind: kept, it pulls the speed
    down. Without the gate the false alarm pulls the speed down by metres per second. The same with the
    paper's two velocity rows. By numpy and by the compiled kernel (``measurement_update_kernel``)."""
    if kernels == "compiled" and not compiled_kernels.available():
        pytest.skip("numba is not installed")
    monkeypatch.setenv(compiled_kernels.ENV_SWITCH, "1" if kernels == "compiled" else "0")
    scn = CurveScenario(circle80, 1)
    cfg = TrackerConfig(measurement=MeasurementConfig(radar_gate=gate, radar_rows=radar_rows))
    pts = scn.scan(0, np.random.default_rng(4), 0.03)
    v_true = scn.radar_velocity(0, np.random.default_rng(0), 0.0)
    fused = prepare_cluster(pts, cfg.measurement, velocity=v_true * (1.0 - off / np.linalg.norm(v_true)))
    lidar = prepare_cluster(pts, cfg.measurement)
    mean, cov = scn.truth(0)[None], np.diag(INIT_STD**2)[None]
    pair = (np.zeros(1, dtype=int), np.zeros(1, dtype=int), scn.ego(0), circle80, cfg)
    res = update_pairs(mean, cov, [fused], *pair)
    ref = update_pairs(mean, cov, [lidar], *pair)
    assert bool(res.radar_rejected[0]) == rejected
    if rejected:
        np.testing.assert_allclose(res.mean, ref.mean, atol=1e-12)
        assert res.dim[0] == ref.dim[0]
    else:
        assert res.mean[0, 2] < ref.mean[0, 2] - 0.5 * min(off, 3.0)
        assert res.dim[0] == ref.dim[0] + (1 if radar_rows == "speed" else 2)
