"""Tests of tracker/update.py: the low-rank UKF update against the textbook one, and the single-target
filter (predict + update) on a car driving a radius-80 m curve, seen by a simulated scanning lidar."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scenes import Car, Scene, kernel_roads
from scipy.stats import multivariate_normal

from tracker import Road, Tracker
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


def test_likelihood_variances_change_the_weights_not_the_posterior() -> None:
    """``kalman_update(..., r_likelihood=...)`` (``MeasurementConfig.shadowed_lidar_sigma``: the update
    softened, the weights and the gate not): the posterior is the update with ``r``, the log-likelihood and NIS
    those of the update with ``r_likelihood`` (against scipy's density with the dense ``S``), for the
    pairs where they differ; a pair where they agree is untouched."""
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
    ``hold_unobserved_extent`` (default) the update keeps the prior's ``L`` mean and variance and, the
    rear face seen whole, the rear where the update put it: ``s`` takes the whole correction in one
    update, while the plain update splits the along-track innovation between ``s`` and ``L``. A car
    ahead in the next lane shows its right side too: ``L`` is updated."""
    from tracker.config import BirthConfig

    road = Road.from_curvature([(500.0, 0.0, 0.0)], lanes=2, lane_width=3.5)
    ego = (100.0, -1.75, 0.0)
    cfg = TrackerConfig(birth=BirthConfig(classes=None))  # the hold alone, not the vehicle classes' prior
    plain = TrackerConfig(measurement=MeasurementConfig(hold_unobserved_extent=False), birth=BirthConfig(classes=None))
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
            assert m[5] == pytest.approx(prior[5], abs=1e-12) and c[5, 5] == pytest.approx(cov[5, 5], abs=1e-12)
            assert abs(m0[5] - prior[5]) > 0.05  # the plain update moved the unobserved length
            # s - L/2 is measured: s takes the whole correction at once, L keeps its prior
            rear_before, rear_after = prior[0] - prior[5] / 2 - 127.6, m[0] - m[5] / 2 - 127.6
            assert abs(rear_before) == pytest.approx(0.8) and abs(rear_after) < 0.1 * abs(rear_before)
            # the plain update's rear: the same face, the split between s and L aside
            assert abs((m0[0] - m0[5] / 2) - (m[0] - m[5] / 2)) < 0.05


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


def _extent_rules(mean, cov, corners, birth, length_seen=False, width_seen=True):
    """``apply_extent_rules`` of posteriors ``mean``, ``cov`` equal to their priors (the Schmidt hold
    changes nothing) whose parts show the rear whole (the width measured) only with ``width_seen`` and
    the long side whole only with ``length_seen``; the largest vehicle off. Returns the result and the pairs whose length changed."""
    from tracker.measurement import FROM_A, FULL, Structure
    from tracker.update import UpdateResult, apply_extent_rules

    count = len(mean)
    structure = Structure(*([None] * 7), two_sided=None, sides=np.tile([1, 2], (count, 1)),
                          mode=np.tile([FULL if length_seen else FROM_A, FULL if width_seen else FROM_A], (count, 1)), radar=None, z=None, r=None,
                          mask=None, factors=None, excess=None)
    res = UpdateResult(mean.copy(), cov.copy(), np.zeros(count), np.zeros(count), np.zeros(count, dtype=int),
                       np.zeros((count, 2)), np.zeros((count, 2)))
    config = TrackerConfig(birth=dataclasses.replace(birth, max_length=None, max_width=None))
    res = apply_extent_rules(res, mean, cov, structure, corners, config)
    return res, res.mean[:, 5] != mean[:, 5]


def test_vehicle_classes_give_a_wide_rear_a_trucks_length_and_a_cars_rear_a_cars():
    """The vehicle classes' prior (``apply_extent_rules``, ``BirthConfig.classes``) replaces a never
    measured length seen from behind by the classes' length given the measured width: a 2.55 m rear a
    truck's or bus's (centre moved away from the sensor by half the change, the variance raised to the
    classes' along that direction), a 0.8 m rear a motorcycle's (the length's deviation scaled down to
    the motorcycle's spread), the end nearest the sensor kept with its variance in both;
    it leaves alone a 1.8 m rear (a car's length, within the held prior's spread), a length that was
    measured, a width not seen this update, and everything with the classes off. Applied again it
    changes nothing."""
    from oracles.update import class_length_prior as oracle_prior

    from tracker.config import BirthConfig
    from tracker.measurement import rectangle_corners

    cfg = BirthConfig()
    mean = np.array([[100.0, 0.0, 10.0, 0.0, 0.0, cfg.length, 2.55]] * 4)
    mean[1, 6] = 0.8  # a motorcycle's width
    mean[2, 6] = 1.8  # a car's width
    cov = np.tile(np.diag([0.1, 0.1, 0.1, 0.01, 0.01, cfg.length_std**2, 0.03**2]), (4, 1, 1))
    cov[3, 5, 5] = 0.05**2  # measured
    corners = rectangle_corners(np.array([[20.0, 0.0]] * 4), np.zeros(4), mean[:, 5], mean[:, 6])  # ahead, in E
    res, hit = _extent_rules(mean, cov, corners, cfg)
    np.testing.assert_array_equal(hit, [True, True, False, False])
    length, var = oracle_prior(mean[:3, 6], cov[:3, 6, 6], cfg.classes)
    assert 12.0 < length[0] < 14.0 and 3.0 < var[0] ** 0.5 < 5.0  # a truck's or a bus's
    assert abs(length[1] - 2.2) < 0.1 and var[1] < cfg.length_std**2  # a motorcycle's
    assert abs(length[2] - cfg.classes[0].length) < 0.1  # a car's
    e = length[0] - cfg.length
    assert res.mean[0, 5] == pytest.approx(length[0]) and res.mean[0, 0] == pytest.approx(100.0 + 0.5 * e)
    assert res.cov[0, 5, 5] == pytest.approx(var[0]) and res.cov[0, 0, 5] == pytest.approx(0.5 * (var[0] - 1.0))
    for p in (0, 1):  # the rear s - L/2 keeps its variance: a face seen later moves it, not the length
        near = np.array([1.0, 0, 0, 0, 0, -0.5, 0])
        assert near @ res.cov[p] @ near == pytest.approx(near @ cov[p] @ near)
    assert res.mean[1, 5] == pytest.approx(length[1]) and res.cov[1, 5, 5] == pytest.approx(var[1])
    assert res.mean[1, 0] - 0.5 * res.mean[1, 5] == pytest.approx(100.0 - 0.5 * cfg.length)  # the rear stays put
    np.testing.assert_array_equal(res.mean[2:], mean[2:])
    np.testing.assert_array_equal(res.cov[2:], cov[2:])
    again, _ = _extent_rules(res.mean, res.cov, corners, cfg)
    np.testing.assert_allclose(again.mean, res.mean, rtol=0, atol=1e-9)
    np.testing.assert_allclose(again.cov, res.cov, rtol=0, atol=1e-9)
    behind = rectangle_corners(np.array([[-20.0, 0.0]] * 4), np.zeros(4), mean[:, 5], mean[:, 6])  # the rear is far
    res2, _ = _extent_rules(mean, cov, behind, cfg)
    assert res2.mean[0, 0] == pytest.approx(100.0 - 0.5 * e)  # the front (nearest the sensor) stays put
    assert not _extent_rules(mean, cov, corners, cfg, length_seen=True)[1].any()  # the length was measured
    assert not _extent_rules(mean, cov, corners, cfg, width_seen=False)[1].any()  # the width not measured
    assert not _extent_rules(mean, cov, corners, dataclasses.replace(cfg, classes=None))[1].any()  # the rule off


def test_vehicle_classes_shorten_a_car_born_a_truck_but_not_a_grown_truck():
    """A length still at the classes' wide prior (a birth on an oblique or merged cluster 2.6 m wide
    took a truck's 12 ± 3.5 m) follows the width the updates measure: a rear now 2.0 m wide (a car's or
    van's, the classes' spread under ``length_std``) takes the classes' length, the end nearest the
    sensor staying put with its variance and the length's variance scaled down to the classes'; a
    truck whose length a side it showed grew to 15.6 m (still uncertain beyond ``1.5 length_std``) and
    whose rear is 2.5 m wide keeps it, and so does a length of a car's fitted spread (a lower bound).
    Checked against the independent oracle of ``tests/oracles/update.py``."""
    from oracles.update import class_length_prior as oracle_prior
    from oracles.update import vehicle_class_prior

    from tracker.config import BirthConfig
    from tracker.measurement import rectangle_corners
    from tracker.update import UpdateResult

    cfg = BirthConfig()
    mean = np.array([[100.0, 0.0, 10.0, 0.0, 0.0, 12.0, 2.0], [100.0, 0.0, 10.0, 0.0, 0.0, 15.6, 2.5],
                     [100.0, 0.0, 10.0, 0.0, 0.0, 6.0, 2.0]])
    cov = np.tile(np.diag([0.1, 0.1, 0.1, 0.01, 0.01, 3.5**2, 0.05**2]), (3, 1, 1))
    cov[1, 5, 5] = 2.0**2
    cov[2, 5, 5] = cfg.length_std**2  # a fitted length: a lower bound
    corners = rectangle_corners(np.array([[20.0, 0.0]] * 3), np.zeros(3), mean[:, 5], mean[:, 6])  # ahead, in E
    res, hit = _extent_rules(mean, cov, corners, cfg)
    np.testing.assert_array_equal(hit, [True, False, False])
    length, var = oracle_prior(mean[:1, 6], cov[:1, 6, 6], cfg.classes)
    assert 4.5 < length[0] < 5.5 and var[0] < cfg.length_std**2  # a car's or a van's
    assert res.mean[0, 5] == pytest.approx(length[0]) and res.cov[0, 5, 5] == pytest.approx(var[0])
    rear = np.array([1.0, 0, 0, 0, 0, -0.5, 0])  # the rear, nearest the sensor: kept, with its variance
    assert res.mean[0] @ rear == pytest.approx(mean[0] @ rear)
    assert rear @ res.cov[0] @ rear == pytest.approx(rear @ cov[0] @ rear)
    assert np.all(np.linalg.eigvalsh(res.cov[0]) > 0.0)
    np.testing.assert_array_equal(res.mean[1:], mean[1:])
    oracle = UpdateResult(mean.copy(), cov.copy(), *([None] * 5))
    vehicle_class_prior(oracle, np.ones(3, dtype=bool), np.zeros(3, dtype=bool), corners, cfg)
    np.testing.assert_allclose(res.mean, oracle.mean, rtol=0, atol=1e-9)
    np.testing.assert_allclose(res.cov, oracle.cov, rtol=0, atol=1e-9)


def test_vehicle_classes_weigh_an_ambiguous_width():
    """Between the classes the length is the mixture's: the prior of a measured width rises from a car's
    through a van's to a truck's as the width grows, its spread largest where the classes overlap, and a
    less certain width gives a wider spread between the modes."""
    from oracles.update import class_length_prior as oracle_prior

    from tracker.config import VEHICLE_CLASSES

    widths = np.array([0.8, 1.8, 2.0, 2.2, 2.3, 2.4, 2.55])
    length, var = oracle_prior(widths, np.full(len(widths), 0.05**2), VEHICLE_CLASSES)
    assert length[0] == pytest.approx(2.2, abs=0.05) and length[1] == pytest.approx(VEHICLE_CLASSES[0].length, abs=0.1)
    assert np.all(np.diff(length[1:]) > 0.0)  # longer with the width
    assert 5.0 < length[2] < 5.4 and 5.3 < length[3] < 5.6 and length[-1] > 12.0
    assert np.sqrt(var[4]) > 3.0  # 2.3 m: a van's or a truck's, its spread covers both
    _, var_loose = oracle_prior(widths, np.full(len(widths), 0.2**2), VEHICLE_CLASSES)
    assert var_loose[3] > var[3]
    # widths that stray from the body's (BirthConfig.width_error_std: mirrors, label boxes): 2.4 m is no
    # longer a truck's for sure, 2.55 m still mostly is
    loose, _ = oracle_prior(widths, np.full(len(widths), 0.05**2), VEHICLE_CLASSES, 0.25)
    assert loose[5] < 9.0 < loose[6] and loose[5] < length[5] - 3.5


@pytest.mark.parametrize("max_width", [3.0, None], ids=["limited", "unlimited"])
def test_an_estimate_wider_than_any_vehicle_is_projected_back(max_width) -> None:
    """Two vehicles' rears side by side form one 8 m line; with a loose width prior the update alone
    makes the track metres wider than any vehicle (the line's excess over the predicted 2.5 m widens
    the prior with the side nearest the sensor fixed: 5 m here, the sensor on the line's middle). With
    ``BirthConfig.max_width`` the width is projected back onto 3 m."""
    from tracker.config import BirthConfig

    road = Road.from_curvature([(500.0, 0.0, 0.0)], lanes=3)
    ego = (100.0, 0.0, 0.0)
    line = np.column_stack([np.full(41, 25.0), np.linspace(-4.0, 4.0, 41)])  # 8 m of rear, 25 m ahead
    cluster = prepare_cluster(line, MeasurementConfig())
    mean = np.array([126.0, 0.0, 10.0, 0.0, 0.0, 4.5, 2.5])
    cov = np.diag([0.5, 0.5, 1.0, 0.01, 0.01, 1.0, 9.0])
    base = TrackerConfig()
    config = dataclasses.replace(base, birth=BirthConfig(classes=None, max_width=max_width))
    post, _, _ = update(mean, cov, cluster, ego, road, config)
    if max_width is None:
        assert post[6] > 4.5
    else:
        assert post[6] == pytest.approx(max_width)


@pytest.mark.parametrize("radar_rows", ["speed", "velocity"])
@pytest.mark.parametrize("off, gate, rejected", [(20.0, 25.0, True), (3.0, 25.0, False), (20.0, None, False)],
                         ids=["false-alarm", "braking", "gate-off"])
def test_a_radar_velocity_no_pair_explains_is_set_aside(circle80: Road, off: float, gate, rejected: bool,
                                                         radar_rows: str) -> None:
    """``MeasurementConfig.radar_gate``: a cluster's radar velocity 20 m/s slower than the prediction
    (speed std 3 m/s: normalised innovation ~43 > 25) is a false alarm: set aside, the posterior is the
    lidar-only one. 3 m/s slower (~1) is a braking the prediction lags behind: kept, it pulls the speed
    down. Without the gate the false alarm pulls the speed down by metres per second. The same with the
    paper's two velocity rows."""
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


# -- the kernels against the numpy oracle, the fused calls against the staged ones --------------------
def track_scene(frames: int) -> Tracker:
    """The default tracker run ``frames`` frames (10 Hz, noise seed 0) on a curved three-lane road with
    three cars and an 11 m bus around the ego, with radar."""
    road = Road.from_curvature([(150.0, 0.0, 0.0), (300.0, 0.0, 1 / 120.0)], lanes=3, lane_width=3.5)
    scene = Scene(road, Car(60.0, -3.5, 14.0), [Car(80.0, -3.5, 14.0), Car(75.0, 0.0, 17.0, length=11.0, width=2.5),
                                                 Car(50.0, 3.5, 18.0)], radar=True)
    tracker = Tracker(road, TrackerConfig())
    rng = np.random.default_rng(0)
    for k in range(frames):
        tracker.step(scene.frame(0.1 * k, rng))
    return tracker


def tracked_update_calls(frames: int, monkeypatch) -> list[tuple]:
    """``track_scene(frames)``'s calls of the update (``tracker.update.update_clusters``) as the
    ``update_pairs`` calls they stand for: ``(means, covs, batch, comp, clu, ego, road, config, ut)``,
    the batch prepared by ``prepare_scanned_batch`` as the two-step path prepares it."""
    import tracker.tracker as tt
    from tracker.preparation import prepare_scanned_batch

    raw = []
    original = tt.update_clusters
    monkeypatch.setattr(tt, "update_clusters", lambda *args: raw.append(args) or original(*args))
    track_scene(frames)
    monkeypatch.setattr(tt, "update_clusters", original)
    calls = []
    for means, covs, points, offsets, velocity, has_velocity, comp, clu, scan, ego, road, config, ut in raw:
        used, slot = np.unique(clu, return_inverse=True)
        clusters = [points[offsets[k]:offsets[k + 1]] for k in used]
        velocities = [velocity[k] if has_velocity[k] else None for k in used]
        batch = prepare_scanned_batch(clusters, config.measurement, velocities, scan, config.detection.lidar_resolution,
                                      config.detection.lidar_range)
        calls.append((means, covs, batch, comp, slot, ego, road, config, ut))
    return calls


def _counting(function, taken: list):
    """``function`` that also records in ``taken`` whether each call gave a result (not None)."""
    def counting(*args):
        out = function(*args)
        taken.append(out is not None)
        return out
    return counting


def _lengths_cut(calls: list[tuple]) -> list[tuple]:
    """The update calls ``(means, covs, ...)`` with every prior's length cut to 2 m (sides longer than
    predicted: the fused kernels hand back for the widened prior)."""
    from tracker.motion import LENGTH

    out = []
    for means, covs, *rest in calls:
        short = means.copy()
        short[:, LENGTH] = 2.0
        out.append((short, covs, *rest))
    return out


def _kalman_inputs(rng, pairs, n, rows, extra, wrapping):
    """Random UKF update inputs of a realistic scale: states of road traffic, measurement sigma points
    a smooth nonlinear function of the state, innovations of a few standard deviations."""
    ut = UnscentedTransform(n=n)
    root = rng.normal(0.0, 1.0, (pairs, n, n)) * rng.uniform(0.05, 1.0, (pairs, 1, 1))
    cov = root @ np.swapaxes(root, 1, 2) + 1e-3 * np.eye(n)
    mean = rng.normal(0.0, 1.0, (pairs, n)) * np.r_[50.0, 3.0, 10.0, 0.3, 0.1, 4.0, 1.0, 1.0][:n]
    mean[: pairs // 3, 3] = np.pi - 0.02  # headings across +-pi
    sigma = ut.sigma_points(mean, cov, Wrapping(wrapping.angles, wrapping.periods[:1]))
    h = rng.normal(0.0, 1.0, (rows, n))
    z_sigma = np.sin(sigma @ h.T / 20.0) * 10.0 + sigma @ h.T
    r = rng.uniform(0.005, 0.3, (pairs, rows))
    mask = rng.random((pairs, rows)) < 0.7
    mask[:, :2] = True
    z = ut.wm @ z_sigma + rng.normal(0.0, 1.0, (pairs, rows)) * np.sqrt(r) * 3.0
    factors = rng.normal(0.0, 0.2, (pairs, extra, rows)) if extra else None
    return ut, sigma, mean, cov, z_sigma, z, r, mask, factors


def assert_results_close(got, ref, names=("mean", "cov", "log_likelihood", "nis", "dim", "predicted", "innovation"),
                         tol=1e-9) -> None:
    for name in names:
        a, b = getattr(ref, name), getattr(got, name)
        assert a.shape == b.shape, (name, a.shape, b.shape)
        np.testing.assert_allclose(b, a, rtol=tol, atol=tol, err_msg=name)


@pytest.mark.parametrize("extra", [0, 2])
@pytest.mark.parametrize("periods", [(), ((0, 180.0),)], ids=["open", "closed-road"])
def test_kalman_update_equals_the_textbook_oracle(extra, periods):
    """``kalman_update`` (``tracker.kalman.kalman_kernel``) against the textbook update of
    ``oracles.update`` within 1e-9:
    padded rows, with and without the low-rank noise factors, the heading wrapped across +-pi, ``s`` on
    a closed road; the 7- and 8-state filters; an empty batch."""
    from oracles.update import kalman_update as oracle_kalman_update

    wrapping = Wrapping(angles=(3,), periods=periods)
    rng = np.random.default_rng(5)
    for n, pairs, rows in ((7, 9, 40), (8, 12, 122), (7, 1, 2), (8, 0, 6)):
        ut, *inputs, factors = _kalman_inputs(rng, pairs, n, rows, extra, wrapping)
        got = kalman_update(ut, *inputs, wrapping=wrapping, factors=factors)
        ref = oracle_kalman_update(ut, *inputs, wrapping=wrapping, factors=factors)
        assert got.nis.size == pairs and got.dim.dtype.kind == "i"
        assert_results_close(got, ref)
        assert np.all(np.abs(got.mean[:, 3]) <= np.pi)
        for index, period in periods:
            assert np.all((got.mean[:, index] >= 0.0) & (got.mean[:, index] < period))


def test_kalman_update_refuses_two_periodic_coordinates():
    wrapping = Wrapping(angles=(3,), periods=((0, 180.0), (1, 40.0)))
    ut, *inputs, factors = _kalman_inputs(np.random.default_rng(5), 3, 7, 10, 0, Wrapping(angles=(3,)))
    with pytest.raises(ValueError, match="at most one periodic coordinate"):
        kalman_update(ut, *inputs, wrapping=wrapping, factors=factors)


def test_a_pair_whose_predicted_measurement_is_not_finite_has_no_posterior():
    """A NaN in one pair's measurement sigma points: that pair's posterior is NaN, every other pair's is
    the oracle's (and its predicted measurement and innovation are the oracle's too)."""
    from oracles.update import kalman_update as oracle_kalman_update

    wrapping = Wrapping(angles=(3,))
    ut, sigma, mean, cov, z_sigma, z, r, mask, factors = _kalman_inputs(np.random.default_rng(8), 6, 7, 20, 2, wrapping)
    z_sigma[2, 4, 0] = np.nan
    with np.errstate(invalid="ignore"):
        got = kalman_update(ut, sigma, mean, cov, z_sigma, z, r, mask, wrapping, factors)
    assert np.isnan(got.mean[2]).any()
    others = np.arange(6) != 2
    ref = oracle_kalman_update(ut, sigma[others], mean[others], cov[others], z_sigma[others], z[others], r[others],
                               mask[others], wrapping, factors[others])
    for name in ("mean", "cov", "log_likelihood", "nis", "predicted", "innovation"):
        np.testing.assert_allclose(getattr(got, name)[others], getattr(ref, name), rtol=1e-9, atol=1e-9, err_msg=name)
    assert np.isnan(got.mean[2]).all() and np.isnan(got.cov[2]).all() and np.isnan(got.nis[2])
    assert got.dim[2] == mask[2].sum()


def test_the_update_of_a_tracked_scene_equals_the_oracle(monkeypatch):
    """``update_pairs`` (one call of ``tracker.pairs.update_pairs_kernel``) on the tracker's own update
    batches (three cars and a bus with radar rows, ends in shadows), and the same batches with every
    prior's length cut to 2 m (the sides longer than predicted widen the priors: the staged kernels),
    against ``oracles.update.update_pairs``: the same radar decisions and dimensions, the numbers within
    1e-9 (1e-7 after a widened prior, whose variances of up to ~80 m^2 the update cancels)."""
    import tracker.update as tu
    from oracles.update import update_pairs as oracle_update_pairs

    calls = tracked_update_calls(12, monkeypatch)
    taken = []
    monkeypatch.setattr(tu, "_update_pairs_fused", _counting(tu._update_pairs_fused, taken))
    fused = 0
    for k, args in enumerate(calls + _lengths_cut(calls)):
        got = tu.update_pairs(*args)
        ref = oracle_update_pairs(*args)
        np.testing.assert_array_equal(got.radar_rejected, ref.radar_rejected)
        np.testing.assert_array_equal(got.dim, ref.dim)
        assert_results_close(got, ref, names=("mean", "cov", "log_likelihood", "nis", "predicted", "innovation"),
                             tol=1e-9 if k < len(calls) else 1e-7)
        fused += int(np.asarray(args[2].fused).sum())
    assert fused >= 20  # clusters with a radar velocity took part
    assert all(taken[: len(calls)]) and not all(taken[len(calls):])  # some widened priors: the staged kernels


@pytest.mark.parametrize("dim", [7, 8])
def test_the_extent_rules_equal_the_oracle(dim):
    """``apply_extent_rules`` (``tracker.extent.extent_rules_kernel``) against ``oracles.update`` on
    random pairs built to reach every rule: lengths and widths held or seen whole, trucks', cars' and
    motorcycles' widths with unmeasured lengths (the vehicle classes' prior), estimates beyond the
    largest vehicle, the sensor ahead of and behind the rectangles; the same numbers (to 1e-12: the
    mixture's sums run in another order) with the rules on and off."""
    from oracles.update import apply_extent_rules as oracle_extent_rules

    from tracker.config import VEHICLE_CLASSES, BirthConfig
    from tracker.measurement import FROM_A, FULL, Structure
    from tracker.update import UpdateResult, apply_extent_rules

    rng = np.random.default_rng(7)
    pairs = 400
    prior = np.zeros((pairs, dim))
    prior[:, 0], prior[:, 1], prior[:, 2] = rng.uniform(0, 200, pairs), rng.uniform(-5, 5, pairs), rng.uniform(0, 30, pairs)
    prior[:, 3] = rng.normal(0.0, 0.5, pairs)
    prior[:, 5] = rng.choice([2.0, 4.5, 13.0, 30.0], pairs) + rng.normal(0.0, 0.3, pairs)
    prior[:, 6] = rng.choice([0.8, 1.8, 2.5, 3.4], pairs) + rng.normal(0.0, 0.05, pairs)
    root = rng.normal(0.0, 1.0, (pairs, dim, dim)) * rng.uniform(0.02, 0.6, (pairs, 1, 1))
    prior_cov = root @ np.swapaxes(root, 1, 2) + 1e-3 * np.eye(dim)
    post = prior + rng.normal(0.0, 0.3, (pairs, dim))
    post_cov = prior_cov * rng.uniform(0.5, 1.0, (pairs, 1, 1))
    mode = rng.choice([FULL, FROM_A], (pairs, 2))
    sides = rng.integers(0, 4, (pairs, 2))
    centre = rng.normal(0.0, 30.0, (pairs, 1, 2))
    corners = centre + rng.normal(0.0, 2.0, (pairs, 4, 2))
    structure = Structure(*([None] * 7), two_sided=None, sides=sides, mode=mode, radar=None, z=None, r=None,
                          mask=None, factors=None, excess=None)
    for birth, hold in ((BirthConfig(), True), (BirthConfig(), False),
                        (BirthConfig(classes=None, max_length=None, max_width=None), True),
                        (BirthConfig(classes=VEHICLE_CLASSES[:3], length_std=0.2), True),
                        (BirthConfig(width_error_std=0.25), True)):
        config = TrackerConfig(birth=birth, measurement=MeasurementConfig(hold_unobserved_extent=hold))
        got = apply_extent_rules(UpdateResult(post.copy(), post_cov.copy(), *([None] * 5)), prior, prior_cov, structure,
                                 corners, config)
        ref = oracle_extent_rules(UpdateResult(post.copy(), post_cov.copy(), *([None] * 5)), prior, prior_cov, structure,
                                  corners, config)
        np.testing.assert_allclose(got.mean, ref.mean, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(got.cov, ref.cov, rtol=1e-12, atol=1e-12)
        changed = ~np.isclose(got.mean[:, 5], post[:, 5])
        assert changed.sum() >= 20  # the rules did something


def test_grow_extent_equals_the_oracle():
    """``grow_extent`` (``tracker.extent.grow_extent_kernel``) against ``oracles.update``: random
    excesses (some not finite) on long and short parts, narrow and wide extent spreads, the sensor on
    either side; the same mask and covariances, bit for bit, and both extents grown somewhere."""
    from oracles.update import grow_extent as oracle_grow_extent

    from tracker.measurement import Structure
    from tracker.update import grow_extent

    rng = np.random.default_rng(11)
    pairs, dim = 300, 8
    means = rng.normal(0.0, 1.0, (pairs, dim)) * np.r_[50.0, 3.0, 10.0, 0.5, 0.1, 3.0, 0.5, 1.0]
    root = rng.normal(0.0, 1.0, (pairs, dim, dim)) * rng.uniform(0.02, 0.8, (pairs, 1, 1))
    covs = root @ np.swapaxes(root, 1, 2) + 1e-4 * np.eye(dim)
    excess = rng.normal(0.0, 2.0, (pairs, 2))
    excess[rng.random((pairs, 2)) < 0.1] = np.nan
    excess[rng.random((pairs, 2)) < 0.05] = np.inf
    sides = rng.integers(0, 4, (pairs, 2))
    corners = rng.normal(0.0, 30.0, (pairs, 1, 2)) + rng.normal(0.0, 2.0, (pairs, 4, 2))
    structure = Structure(*([None] * 7), two_sided=None, sides=sides, mode=None, radar=None, z=None, r=None,
                          mask=None, factors=None, excess=excess)
    grown, out = grow_extent(means, covs, structure, corners)
    ref_grown, ref_out = oracle_grow_extent(means, covs, structure, corners)
    assert np.array_equal(grown, ref_grown) and np.array_equal(out, ref_out)
    for index in (5, 6):
        assert (grown & (out[:, index, index] > covs[:, index, index])).sum() >= 10
    empty = grow_extent(means[:0], covs[:0], dataclasses.replace(structure, sides=sides[:0], excess=excess[:0]),
                        corners[:0])
    assert empty[0].shape == (0,) and empty[1].shape == (0, dim, dim)


def test_a_side_past_its_prediction_by_a_quarter_metre_and_a_standard_deviation_widens_the_prior():
    """The chord is a lower bound of the side up to the range noise: a short side (a face) 0.3 m wider
    than predicted, the width's sd 0.2 m, widens the prior (``GROWTH_MIN_EXCESS`` 0.25 m,
    ``GROWTH_SIGMAS`` 1); 0.2 m does not. A long side with sd 1 m: 1.2 m does, 0.8 m does not."""
    from tracker.measurement import Structure
    from tracker.update import grow_extent

    means = np.tile([30.0, 0.0, 10.0, 0.0, 0.0, 4.7, 1.9, 0.0], (4, 1))
    covs = np.tile(np.diag([0.1, 0.1, 1.0, 0.01, 0.01, 1.0, 0.04, 0.1]), (4, 1, 1))
    excess = np.array([[0.3, -np.inf], [0.2, -np.inf], [1.2, -np.inf], [0.8, -np.inf]])
    sides = np.array([[2, 2], [2, 2], [1, 1], [1, 1]])  # the rear (a short side), then the right side (long)
    corners = np.array([[[32.35, -0.95], [32.35, 0.95], [27.65, 0.95], [27.65, -0.95]]] * 4)
    structure = Structure(*([None] * 7), two_sided=None, sides=sides, mode=None, radar=None, z=None, r=None,
                          mask=None, factors=None, excess=excess)
    grown, out = grow_extent(means, covs, structure, corners)
    assert grown.tolist() == [True, False, True, False]
    assert out[0, 6, 6] == pytest.approx(0.04 + 0.3**2) and out[2, 5, 5] == pytest.approx(1.0 + 1.2**2)


@pytest.mark.parametrize("name", ["clothoid-open", "hermite-closed"])
def test_sigma_rectangles_equal_the_two_steps(name):
    """``tracker.update.sigma_rectangles`` (sigma points and their rectangles in one compiled call)
    gives exactly ``sigma_points`` then ``to_vehicle``, and rectangles within 1e-9 of the road's frame
    in numpy (``oracles.measurement.to_vehicle``); 8-state Gaussians across the seam and beyond the
    ends; a NaN is refused, a covariance that is not positive definite is repaired and counted."""
    from oracles.measurement import to_vehicle as oracle_to_vehicle

    from tracker.frame import EgoState
    from tracker.motion import curvilinear_wrapping
    from tracker.update import sigma_rectangles

    road = kernel_roads()[name]
    wrapping = curvilinear_wrapping(road)
    ut = UnscentedTransform(n=8)
    rng = np.random.default_rng(5)
    ego = EgoState(120.0, -40.0, 0.7, 12.0, 0.05)
    mean = rng.normal(0.0, 1.0, (25, 8)) * np.r_[1.0, 3.0, 10.0, 0.3, 0.1, 1.0, 0.3, 1.0] + np.r_[0.0, 0, 0, 0, 0, 5.0, 2.0, 0]
    mean[:, 0] = rng.uniform(-20.0, road.length + 20.0, 25)
    if road.closed:
        mean[:, 0] %= road.length
    root = rng.normal(0.0, 1.0, (25, 8, 8)) * rng.uniform(0.02, 1.0, (25, 1, 1))
    cov = root @ np.swapaxes(root, 1, 2) + 1e-3 * np.eye(8)
    sigma, rect = sigma_rectangles(ut, mean, cov, wrapping, ego, road, "curvilinear")
    steps = ut.sigma_points(mean, cov, wrapping)
    ref = to_vehicle(steps, ego, road)
    assert np.array_equal(sigma, steps)
    for field in ("center", "psi", "v", "length", "width"):
        assert np.array_equal(getattr(rect, field), getattr(ref, field))
    assert np.array_equal(rect.corners(), ref.corners())
    np.testing.assert_allclose(rect.corners(), oracle_to_vehicle(steps, ego, road).corners(), rtol=0.0, atol=1e-9)
    bad = cov.copy()
    bad[4] = -np.eye(8)
    before = ut.repairs
    sigma_b, _ = sigma_rectangles(ut, mean, bad, wrapping, ego, road, "curvilinear")
    assert ut.repairs > before and np.isfinite(sigma_b).all()
    nan = mean.copy()
    nan[3, 2] = np.nan
    with pytest.raises(ValueError, match="finite"):
        sigma_rectangles(ut, nan, cov, wrapping, ego, road, "curvilinear")


def test_the_fused_update_of_the_pairs_equals_the_staged_kernels(monkeypatch):
    """``tracker.update.update_pairs`` by one compiled call (``tracker.pairs``) gives the staged
    kernels' numbers bit for bit: every call of a tracked scene (a bus, radar, shadows) replayed both
    ways, and the same calls with the priors' lengths cut to 2 m (sides longer than predicted: the
    kernel hands the pairs back for the widened prior, and the staged path runs)."""
    import tracker.update as tu

    calls = tracked_update_calls(15, monkeypatch)
    assert len(calls) >= 14
    taken = []
    counting = _counting(tu._update_pairs_fused, taken)
    for case in calls + _lengths_cut(calls):
        monkeypatch.setattr(tu, "_update_pairs_fused", counting)
        got = tu.update_pairs(*case)
        monkeypatch.setattr(tu, "_update_pairs_fused", lambda *args: None)
        ref = tu.update_pairs(*case)
        for name in ("mean", "cov", "log_likelihood", "nis", "dim", "predicted", "innovation", "radar_rejected"):
            np.testing.assert_array_equal(getattr(got, name), getattr(ref, name), err_msg=name)
    assert all(taken[: len(calls)])  # the scene's own calls: all by the fused kernel
    assert not all(taken[len(calls):])  # some shortened priors grew: handed back to the staged path


def test_the_fused_preparation_and_update_equal_the_two_steps(monkeypatch):
    """``tracker.update.update_clusters`` by one compiled call (``tracker.pairs.prepared_pairs_kernel``:
    the clusters prepared with their shadow flags, then the fused update) gives bit for bit what
    ``prepare_scanned_batch`` then ``update_pairs`` give, and the same counts of shadowed and continued
    ends: every call of a tracked scene (a bus, radar, ends in shadows), and the same calls with the priors'
    lengths cut to 2 m (the kernel hands back; the two steps run)."""
    import tracker.tracker as tt
    import tracker.update as tu

    raw = []
    original = tt.update_clusters
    monkeypatch.setattr(tt, "update_clusters", lambda *args: raw.append(args) or original(*args))
    road = Road.from_curvature([(150.0, 0.0, 0.0), (300.0, 0.0, 1 / 120.0)], lanes=3, lane_width=3.5)
    scene = Scene(road, Car(60.0, -3.5, 14.0),
                  [Car(80.0, -3.5, 14.0), Car(75.0, 0.0, 17.0, length=11.0, width=2.5), Car(50.0, 3.5, 18.0),
                   Car(95.0, 0.0, 12.0)], radar=True)  # the structure test's scene: shadows, a bus, radar
    tracker, rng = Tracker(road, TrackerConfig()), np.random.default_rng(3)
    for k in range(30):
        tracker.step(scene.frame(0.1 * k, rng))
    monkeypatch.setattr(tt, "update_clusters", original)
    assert len(raw) >= 28
    taken = []
    counting = _counting(tu._update_clusters_fused, taken)
    counts = []
    for case in raw + _lengths_cut(raw):
        monkeypatch.setattr(tu, "_update_clusters_fused", counting)
        got, occluded, continued = tu.update_clusters(*case)
        monkeypatch.setattr(tu, "_update_clusters_fused", lambda *args: None)
        ref, ref_occluded, ref_continued = tu.update_clusters(*case)
        assert (occluded, continued) == (ref_occluded, ref_continued)
        counts.append(occluded)
        for name in ("mean", "cov", "log_likelihood", "nis", "dim", "predicted", "innovation", "radar_rejected"):
            np.testing.assert_array_equal(getattr(got, name), getattr(ref, name), err_msg=name)
    assert sum(taken[: len(raw)]) >= 0.8 * len(raw)  # the scene's own calls: by the one kernel (a bus's side may grow)
    assert not all(taken[len(raw):])  # some shortened priors grew: handed back to the two steps
    assert any(c for c in counts), counts  # some ends in a shadow
    # a non-finite point in a cluster of some pair: the kernel hands back, the two steps take it
    means, covs, points, offsets, velocity, has_velocity, comp, clu, *rest = raw[-1]
    bad = points.copy()
    bad[offsets[clu[0]]] = np.nan
    assert tu._update_clusters_fused(means, covs, bad, offsets, velocity, has_velocity, comp, clu, *rest) is None
    # ... and in a cluster of no pair: the kernel still runs (only the pairs' clusters are prepared)
    idle = np.setdiff1d(np.arange(len(offsets) - 1), clu)
    if len(idle) and offsets[idle[0] + 1] > offsets[idle[0]]:
        bad = points.copy()
        bad[offsets[idle[0]]] = np.nan
        got = tu._update_clusters_fused(means, covs, bad, offsets, velocity, has_velocity, comp, clu, *rest)
        ref = tu._update_clusters_fused(means, covs, points, offsets, velocity, has_velocity, comp, clu, *rest)
        np.testing.assert_array_equal(got[0].mean, ref[0].mean)
    with pytest.raises(ValueError, match="does not exist"):
        tu.update_clusters(means, covs, points, offsets, velocity, has_velocity, comp, clu + len(offsets), *rest)
    with pytest.raises(ValueError, match="offsets must rise"):
        tu.update_clusters(means, covs, points, offsets[::-1], velocity, has_velocity, comp, clu, *rest)
    # a non-finite radar velocity: the fused call declines, the two steps raise their error
    bad_velocity = velocity.copy()
    bad_velocity[clu[0]] = np.nan
    has = has_velocity.copy()
    has[clu[0]] = True
    with pytest.raises(ValueError, match="finite"):
        tu.update_clusters(means, covs, points, offsets, bad_velocity, has, comp, clu, *rest)


def test_a_non_finite_prior_takes_the_staged_update_and_its_error(monkeypatch):
    """A NaN in a prior: the fused update hands the pairs back and the staged path's error is raised."""
    import tracker.update as tu

    calls = tracked_update_calls(4, monkeypatch)
    means, covs, *rest = calls[-1]
    bad = means.copy()
    bad[0, 2] = np.nan
    with pytest.raises(ValueError, match="finite"):
        tu.update_pairs(bad, covs, *rest)


def test_the_papers_euler_conversion_never_takes_the_fused_update(monkeypatch):
    """The ``paper`` variant converts states to E by the paper's Euler integration
    (``MeasurementConfig.conversion = "euler"``), which the fused kernels do not do: its tracker gives the
    same numbers with the fused calls as with the two steps, and the fused calls decline its updates."""
    import tracker.tracker as tt
    import tracker.update as tu
    from sim.evaluation.variants import variant_config

    config = variant_config("paper")
    assert config.measurement.conversion == "euler"
    road = Road.from_curvature([(80.0, 0.0, 0.0), (200.0, 0.0, 1 / 90.0)], lanes=3, lane_width=3.5)
    scene = Scene(road, Car(40.0, -3.5, 14.0), [Car(60.0, -3.5, 14.0), Car(55.0, 0.0, 17.0), Car(70.0, 3.5, 12.0)])

    def run() -> list:
        tracker, rng = Tracker(road, config), np.random.default_rng(2)
        return [(t.label, t.mean.copy()) for k in range(12) for t in tracker.step(scene.frame(0.1 * k, rng))]

    calls = []
    original = tt.update_clusters
    monkeypatch.setattr(tt, "update_clusters", lambda *args: calls.append(args) or original(*args))
    fused = run()
    monkeypatch.setattr(tt, "update_clusters", original)
    assert calls and all(tu._update_clusters_fused(*args) is None for args in calls)
    monkeypatch.setattr(tu, "_update_clusters_fused", lambda *args: None)
    monkeypatch.setattr(tu, "_update_pairs_fused", lambda *args: None)
    staged = run()
    assert len(fused) == len(staged) > 0
    for (label, mean), (ref_label, ref_mean) in zip(fused, staged):
        assert label == ref_label
        np.testing.assert_array_equal(mean, ref_mean)


def test_bound_at_holes_shortens_to_the_seen_free_space_keeping_the_near_end():
    """``tracker.extent.bound_at_holes_kernel``: E is the road frame (ego at the origin, heading along
    s), so a component's ``(s, n)`` is its centre in E; its group's heading is +x from ``(17.5, -3.9)``."""
    from tracker.extent import bound_at_holes_kernel
    from tracker.measurement import rectangle_corners

    # 0: an 11 m track over two parked cars ahead, its group cut 0.9 m past its first car's end (x = 16.6)
    # 1: the same, behind the sensor (its far end is the rear: the bound ahead is on its near side)
    # 2: a component of no group; 3: one turned 90 deg off its group's heading
    mean = np.array([[17.5, -3.9, 0.0, 0.0, 0.0, 11.0, 1.8]] * 4)
    mean[1, 0] = -17.5
    mean[3, 3] = np.pi / 2
    cov = np.broadcast_to(np.diag([0.25, 0.04, 1.0, 0.01, 0.01, 0.09, 0.01]), (4, 7, 7)).copy()
    corners = rectangle_corners(mean[:, :2], mean[:, 3], mean[:, 5], mean[:, 6])
    group = np.array([0, 0, -1, 0])
    bounds = np.array([[-np.inf, 16.6 - 17.5]])
    m, p = mean.copy(), cov.copy()
    count = bound_at_holes_kernel(m, p, corners, group, np.array([[17.5, -3.9]]), np.ones(1), np.zeros(1), bounds, 1.0)
    assert count == 1
    np.testing.assert_allclose(m[1:], mean[1:])
    np.testing.assert_allclose(p[1:], cov[1:])
    # the near end (x = 12) stays, the far end moves to the bound: L = 4.6, the centre at 14.3
    assert m[0, 5] == pytest.approx(4.6)
    assert m[0, 0] - 0.5 * m[0, 5] == pytest.approx(12.0)
    assert m[0, 0] == pytest.approx(14.3)
    np.testing.assert_allclose(m[0, [1, 2, 3, 4, 6]], mean[0, [1, 2, 3, 4, 6]])
    # the length's variance is raised to the floor along the growth direction d = (0.5, 0, ..., 1 at L):
    # the near end s - L / 2 keeps its variance, s and L gain 0.25 x and 1 x the added variance
    added = 1.0 - 0.09
    assert p[0, 5, 5] == pytest.approx(1.0)
    assert p[0, 0, 0] == pytest.approx(0.25 + 0.25 * added)
    assert p[0, 0, 5] == pytest.approx(0.5 * added)
    near = np.array([1.0, 0, 0, 0, 0, -0.5, 0])
    assert near @ p[0] @ near == pytest.approx(near @ cov[0] @ near)
    np.testing.assert_allclose(p[0], p[0].T)
    assert np.all(np.linalg.eigvalsh(p[0]) > 0)
    # a bound the rectangle does not reach changes nothing
    m, p = mean.copy(), cov.copy()
    assert bound_at_holes_kernel(m, p, corners, group, np.array([[17.5, -3.9]]), np.ones(1), np.zeros(1),
                                 np.array([[-np.inf, 6.0]]), 1.0) == 0
    np.testing.assert_allclose(m, mean)
