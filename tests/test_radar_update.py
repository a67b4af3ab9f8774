"""Tests of tracker/radar_update.py: the nearest point of a rectangle against a dense sampling of its
boundary, the radar-only update of coasting tracks (its gates, the ambiguity rule), and the tracker
following a car that stops while hidden from the lidar but not from the radar."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scenes import Car, Scene

from tracker import Road, Tracker, TrackerConfig
from tracker.frame import EgoState, Frame, RadarDetections
from tracker.measurement import Rectangles, rectangle_corners, to_vehicle
from tracker.radar_update import nearest_points, radar_measurement, update_coasting
from tracker.ukf import UnscentedTransform

EGO = EgoState(0.0, 0.0, 0.0, 20.0, 0.0)


def boundary_oracle(center, psi, length, width, samples=4000):
    """The boundary point nearest the origin, by sampling each side densely (m)."""
    corners = rectangle_corners(np.asarray(center, float), np.array(psi), np.array(length), np.array(width))
    u = np.linspace(0.0, 1.0, samples)[:, None]
    pts = np.concatenate([corners[k] + u * (corners[(k + 1) % 4] - corners[k]) for k in range(4)])
    return pts[np.argmin(np.hypot(pts[:, 0], pts[:, 1]))]


@pytest.mark.parametrize("center, psi", [((20.0, 3.0), 0.2), ((-15.0, -4.0), 2.5), ((5.0, 12.0), -1.1),
                                         ((30.0, 0.0), 0.0), ((0.0, -8.0), np.pi / 2)])
def test_nearest_point_is_the_boundary_point_nearest_the_sensor(center, psi):
    rect = Rectangles(np.array([center]), np.array([psi]), np.array([10.0]), np.array([4.6]), np.array([1.9]))
    got = nearest_points(rect)[0]
    np.testing.assert_allclose(got, boundary_oracle(center, psi, 4.6, 1.9), atol=5e-3)
    v = radar_measurement(rect)[0, 2:]
    np.testing.assert_allclose(v, 10.0 * np.array([np.cos(psi), np.sin(psi)]), atol=1e-12)


def test_the_sensor_inside_a_rectangle_is_its_own_nearest_point():
    rect = Rectangles(np.array([[0.5, -0.2]]), np.array([0.3]), np.array([0.0]), np.array([4.6]), np.array([1.9]))
    np.testing.assert_allclose(nearest_points(rect)[0], [0.0, 0.0], atol=1e-12)


@pytest.fixture(scope="module")
def straight() -> Road:
    return Road.from_curvature([(600.0, 0.0, 0.0)], lanes=3)


def coasting(road: Road, s: float, n: float, v: float, sd_s: float = 3.0):
    """One coasting component (8-D with the acceleration state) at ``(s, n)``, speed ``v``."""
    mean = np.array([s, n, v, 0.0, 0.0, 4.6, 1.9, 0.0])
    cov = np.diag([sd_s**2, 0.3**2, 1.5**2, 0.05**2, 0.02**2, 0.3**2, 0.1**2, 1.0])
    return mean[None], cov[None]


def detection_of(road: Road, s: float, n: float, v: float, dt: float = 0.0) -> RadarDetections:
    """A noise-free detection of a car (4.6 x 1.9 m) at ``(s, n)``, speed ``v`` along the straight road:
    its nearest point from the sensor and its velocity, in E (the ego at the origin, heading along x)."""
    rect = to_vehicle(np.array([[s, n, v, 0.0, 0.0, 4.6, 1.9]]), EGO, road)
    z = radar_measurement(rect)[0]
    return RadarDetections(np.array([-dt]), z[:1], z[1:2], z[2:3], z[3:4])


def test_a_detection_stops_a_coasting_track(straight):
    # the track coasts 2 m beyond the car at 6 m/s; the car has stopped: one detection pulls the speed
    # down by most of the 6 m/s and the position back towards the car
    config, ut = TrackerConfig(), UnscentedTransform(TrackerConfig().ukf, n=8)
    mean, cov = coasting(straight, 52.0, 0.0, 6.0)
    radar = detection_of(straight, 50.0, 0.0, 0.0)
    res = update_coasting(mean, cov, np.array([0]), radar, np.array([0]), 0.0, EGO, straight, config, ut)
    assert list(res.component) == [0] and list(res.detection) == [0]
    assert res.mean[0, 2] < 1.5 and abs(res.mean[0, 0] - 50.0) < 0.8, res.mean[0, :3]
    assert np.all(np.linalg.eigvalsh(res.cov[0]) > 0)
    assert res.cov[0, 2, 2] < cov[0, 2, 2]


@pytest.mark.parametrize("offset, reason", [((0.0, 2.5, 0.0), "next lane"), ((0.0, 0.0, -15.0), "velocity"),
                                            ((12.0, 0.0, 0.0), "too far beyond the front")])
def test_a_detection_that_does_not_fit_updates_nothing(straight, offset, reason):
    config, ut = TrackerConfig(), UnscentedTransform(TrackerConfig().ukf, n=8)
    mean, cov = coasting(straight, 50.0, 0.0, 8.0)
    ds, dn, dv = offset
    radar = detection_of(straight, 50.0 + ds, dn, 8.0 + dv)
    res = update_coasting(mean, cov, np.array([0]), radar, np.array([0]), 0.0, EGO, straight, config, ut)
    assert len(res.component) == 0, reason


def test_a_detection_two_tracks_could_take_goes_to_the_nearer_alone(straight):
    # two hidden cars queueing in one lane, their tracks' spreads along the road grown to 3 m: a detection
    # 2 m ahead of the first gates with both and updates only the first (the assignment); two
    # hypotheses of one track (one label) are both refined by it
    config, ut = TrackerConfig(), UnscentedTransform(TrackerConfig().ukf, n=8)
    m1, p1 = coasting(straight, 50.0, 0.0, 5.0)
    m2, p2 = coasting(straight, 56.0, 0.0, 5.0)
    means, covs = np.concatenate([m1, m2]), np.concatenate([p1, p2])
    radar = detection_of(straight, 52.0, 0.0, 5.0)
    loose = update_coasting(means, covs, np.array([0, 1]), radar, np.array([0]), 0.0, EGO, straight, config, ut)
    assert sorted(loose.component) == [0, 1]  # without labels: every gated component
    both = update_coasting(means, covs, np.array([0, 1]), radar, np.array([0]), 0.0, EGO, straight, config, ut,
                           labels=np.array([7, 8]))
    assert list(both.component) == [0]
    one_label = update_coasting(means, covs, np.array([0, 1]), radar, np.array([0]), 0.0, EGO, straight, config, ut,
                                labels=np.array([7, 7]))
    assert sorted(one_label.component) == [0, 1]
    two = RadarDetections(*(np.concatenate([getattr(radar, f), getattr(detection_of(straight, 57.0, 0.0, 5.0), f)])
                            for f in ("t", "x", "y", "vx", "vy")))
    each = update_coasting(means, covs, np.array([0, 1]), two, np.array([0, 1]), 0.0, EGO, straight, config, ut,
                           labels=np.array([7, 8]))
    assert dict(zip(each.component, each.detection)) == {0: 0, 1: 1}


@pytest.mark.parametrize("n_car", [0.0, 3.0])
def test_a_detection_moves_the_vehicle_not_its_length(straight, n_car):
    # a coasting car of unmeasured length (4.6 +- 1.0 m) whose rear lies 1 m short of the prediction: the
    # free update lengthens the car (its far end moves less than its rear); the held update keeps the
    # length and width and their block of the covariance, and puts the point nearest the detection
    # where the free update put it (the whole car moved): a point shows no side whole
    ut = UnscentedTransform(TrackerConfig().ukf, n=8)
    mean, cov = coasting(straight, 40.0, n_car, 10.0, sd_s=0.4)
    cov[0, 5, 5] = 1.0
    radar = detection_of(straight, 39.0, n_car, 10.0)
    held_cfg = TrackerConfig()
    free_cfg = dataclasses.replace(held_cfg, measurement=dataclasses.replace(held_cfg.measurement,
                                                                            hold_unobserved_extent=False))
    free = update_coasting(mean, cov, np.array([0]), radar, np.array([0]), 0.0, EGO, straight, free_cfg, ut)
    held = update_coasting(mean, cov, np.array([0]), radar, np.array([0]), 0.0, EGO, straight, held_cfg, ut)
    assert free.mean[0, 5] > 4.6 + 0.1  # without the hold, one point measures the length
    np.testing.assert_allclose(held.mean[0, 5:7], mean[0, 5:7], atol=0.0)
    np.testing.assert_allclose(held.cov[0, 5:7, 5:7], cov[0, 5:7, 5:7], atol=0.0)
    np.testing.assert_allclose(held.cov[0, :5, :5], free.cov[0, :5, :5], atol=0.0)
    z = np.array([radar.x[0], radar.y[0]])
    on = [nearest_points(to_vehicle(r.mean[:, :7], EGO, straight), z)[0] for r in (free, held)]
    np.testing.assert_allclose(on[1], on[0], atol=1e-9)
    far = [r.mean[0, 0] + 0.5 * r.mean[0, 5] for r in (free, held)]
    assert far[0] - far[1] > 0.05  # the far end moves with the car
    assert np.all(np.linalg.eigvalsh(held.cov[0]) > 0)


def test_a_detection_on_the_vehicle_does_not_move_it(straight):
    # the radar reports the nearest *visible* point: of a car half hidden behind another, a point on its
    # side, metres beyond its rear; inside the predicted rectangle it tells nothing of where the car is
    # (taken for its point nearest the sensor it would pull the car 0.4 m forward), while its velocity still counts
    config, ut = TrackerConfig(), UnscentedTransform(TrackerConfig().ukf, n=8)
    mean, cov = coasting(straight, 40.0, 3.0, 10.0, sd_s=1.0)
    side = to_vehicle(mean[:, :7], EGO, straight)
    point = side.center[0] + np.array([-0.8, -0.95])  # on its right side, 1.5 m ahead of its rear
    radar = RadarDetections(np.zeros(1), point[:1], point[1:], np.array([8.0]), np.array([0.0]))
    res = update_coasting(mean, cov, np.array([0]), radar, np.array([0]), 0.0, EGO, straight, config, ut)
    assert list(res.component) == [0]
    assert abs(res.mean[0, 0] - 40.0) < 0.05 and abs(res.mean[0, 1] - 3.0) < 0.05, res.mean[0, :2]
    assert res.mean[0, 2] < 9.5  # the velocity rows pull the speed towards the detection's 8 m/s


def test_an_old_detection_is_moved_to_the_frame_time(straight):
    # a detection 0.07 s old of a car at 20 m/s lies 1.4 m behind where the car is at the frame time
    config, ut = TrackerConfig(), UnscentedTransform(TrackerConfig().ukf, n=8)
    mean, cov = coasting(straight, 50.0, 0.0, 20.0, sd_s=0.5)
    radar = detection_of(straight, 50.0 - 1.4, 0.0, 20.0, dt=0.07)
    res = update_coasting(mean, cov, np.array([0]), radar, np.array([0]), 0.0, EGO, straight, config, ut)
    assert abs(res.mean[0, 0] - 50.0) < 0.05


class NearestPointRadar(Scene):
    """``Scene`` whose radar reports each car's boundary point nearest the ego (as the simulator's
    radar does), instead of its centre, and its velocity from its motion (``Car.s_at`` by central
    differences; noise 0.5 m and 0.2 m/s per axis); it sees every car (through the van)."""

    def frame(self, t, rng, extra_points_g=None):
        frame = super().frame(t, rng, extra_points_g)
        ego_xy, ego_yaw = self.ego.pose(self.road, t)
        c, s = np.cos(ego_yaw), np.sin(ego_yaw)
        rows = []
        for row, car in zip(self.truth(t), self.cars):
            d = row[:2] - ego_xy
            local = np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])
            p = boundary_oracle(local, row[2] - ego_yaw, car.length, car.width, samples=400)
            vel = (car.pose(self.road, t + 1e-3)[0] - car.pose(self.road, t - 1e-3)[0]) / 2e-3
            v = np.array([c * vel[0] + s * vel[1], -s * vel[0] + c * vel[1]])
            rows.append(np.concatenate([p + rng.normal(0.0, 0.5, 2), v + rng.normal(0.0, 0.2, 2)]))
        z = np.array(rows)
        return Frame(frame.t, frame.ego, frame.lidar, RadarDetections(np.full(len(z), t), *z.T))


@dataclasses.dataclass
class Braking(Car):
    """A car at ``v`` that brakes at ``decel`` (m/s^2) from ``t_brake`` (s) for ``brake_s`` (s), then
    holds its speed."""

    t_brake: float = 0.0
    decel: float = 0.0
    brake_s: float = 0.0

    def s_at(self, t: float) -> float:
        tau = min(max(t - self.t_brake, 0.0), self.brake_s)
        after = max(t - self.t_brake - self.brake_s, 0.0)
        return self.s0 + self.v * t - 0.5 * self.decel * tau * tau - self.decel * self.brake_s * after


def follow(scene: Scene, car: Car, radar_only: bool, frames: int, seed: int, dark=None):
    """Track ``scene`` for ``frames`` frames at 10 Hz (lidar empty in ``dark = (t0, t1)``); per frame the
    along-road error (m) of the nearest track in ``car``'s lane (inf: none), and the tracker."""
    cfg = TrackerConfig()
    tracker = Tracker(scene.road, dataclasses.replace(cfg, measurement=dataclasses.replace(
        cfg.measurement, radar_only_update=radar_only)))
    rng = np.random.default_rng(seed)
    errors = []
    for k in range(frames):
        t = 0.1 * k
        frame = scene.frame(t, rng)
        if dark is not None and dark[0] <= t < dark[1]:
            frame = Frame(frame.t, frame.ego, np.zeros((0, 2)), frame.radar)
        tracks = tracker.step(frame)
        errors.append(min((abs(tr.s - car.s_at(t)) for tr in tracks if abs(tr.n - car.n) < 2.0), default=np.inf))
    return np.array(errors), tracker


@pytest.mark.parametrize("radar_only", [True, False], ids=["radar-only-update", "clusters-only"])
def test_a_car_stopping_while_hidden_from_the_lidar_is_followed_by_the_radar(radar_only):
    # B drives at 3 m/s in the left lane, 32 m ahead of the ego (5 m/s, right lane); a van beside the ego
    # in the middle lane hides B from the lidar from about 5 s to 7.2 s, while B brakes at 2 m/s^2 from
    # 4.5 s to a stop at 6 s; the radar (reporting B's nearest point) sees it throughout. With the
    # radar-only update the coasting track stops with B; without, it drives on and is metres beyond B
    road = Road.from_curvature([(3000.0, 0.0, 0.0)], lanes=3, lane_width=3.5)
    car_b = Braking(132.0, 3.5, 3.0, t_brake=4.5, decel=2.0, brake_s=1.5)
    scene = NearestPointRadar(road, Car(100.0, -3.5, 5.0),
                              [Car(106.0, 0.0, 5.0, length=6.0, width=2.2), car_b], radar=True)
    errors, tracker = follow(scene, car_b, radar_only, 71, seed=0)
    late = errors[62:]  # 6.2-7 s: B hidden and stopped
    assert np.all(np.isfinite(late))  # a track throughout, either way
    if radar_only:
        assert tracker.stats["radar_only_updates"] > 10
        assert np.all(late < 1.0), late
    else:
        assert tracker.stats["radar_only_updates"] == 0
        assert np.all(late > 1.4) and late[-1] > 2.5, late  # 1.5 m at 6.2 s, 2.9 m at 7 s


@pytest.mark.parametrize("radar_only", [True, False], ids=["radar-only-update", "clusters-only"])
def test_the_radar_carries_the_tracks_through_a_lidar_blackout(radar_only):
    # the lidar returns nothing for 1.5 s (2-3.5 s) while the car 30 m ahead brakes at 4 m/s^2 from
    # 20 to 14 m/s; the radar keeps delivering. With radar-only updates its track follows the braking
    # (within 1 m at the end of the blackout); coasting, it is metres ahead of the car
    road = Road.from_curvature([(3000.0, 0.0, 0.0)], lanes=3, lane_width=3.5)
    car = Braking(130.0, 0.0, 20.0, t_brake=2.0, decel=4.0, brake_s=1.5)
    scene = NearestPointRadar(road, Car(100.0, 0.0, 20.0), [car], radar=True)
    errors, tracker = follow(scene, car, radar_only, 36, seed=1, dark=(2.0, 3.5))
    assert tracker.stats["predict_only_frames"] == 15
    end = errors[34]  # 3.4 s, the last dark frame
    if radar_only:
        assert tracker.stats["radar_only_updates"] >= 14 and end < 1.0, end
    else:
        assert tracker.stats["radar_only_updates"] == 0 and 2.5 < end < np.inf, end
