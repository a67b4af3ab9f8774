"""Synthetic frames for tracker tests: vehicles as rectangles on a Road, an exact 2-D ray cast from
the ego (first hit wins, so occlusion is real), range noise, and optional radar detections.
No simulator: tracker tests must not depend on ``sim``."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tracker import EgoState, Frame, RadarDetections, Road
from tracker.measurement import rectangle_corners
from tracker.transforms import rotate, to_local


@dataclass
class Car:
    """A lane-following car: arc length ``s0 + v t + accel u^2 / 2`` (m) with ``u = max(t - accel_from,
    0)`` (the acceleration starts at ``accel_from`` s), lateral offset ``n`` (m), size (m).
    ``lane_change = (t0, duration, dn)`` (s, s, m) moves it by ``dn`` on a half-cosine
    profile from ``t0`` (``n_at``); its heading then turns by ``atan(n' / s')`` off the road's."""

    s0: float
    n: float
    v: float
    length: float = 4.8
    width: float = 2.0
    accel: float = 0.0
    lane_change: tuple[float, float, float] | None = None
    accel_from: float = 0.0

    def s_at(self, t: float) -> float:
        """Arc length (m) of the centre at time ``t``."""
        u = max(t - self.accel_from, 0.0)
        return self.s0 + self.v * t + 0.5 * self.accel * u * u

    def speed_at(self, t: float) -> float:
        """``ds/dt`` (m/s) at time ``t``."""
        return self.v + self.accel * max(t - self.accel_from, 0.0)

    def n_at(self, t: float) -> tuple[float, float]:
        """Lateral offset (m) and its rate (m/s) at time ``t``."""
        if self.lane_change is None:
            return self.n, 0.0
        t0, duration, dn = self.lane_change
        u = min(max((t - t0) / duration, 0.0), 1.0)
        rate = 0.5 * dn * np.pi / duration * np.sin(np.pi * u) if 0.0 < u < 1.0 else 0.0
        return self.n + 0.5 * dn * (1.0 - np.cos(np.pi * u)), float(rate)

    def pose(self, road: Road, t: float) -> tuple[np.ndarray, float]:
        """Centre (2,) in G and heading (rad) at time ``t``."""
        s = road.wrap_s(self.s_at(t))
        xy, theta, _ = road.frame(np.array([float(s)]))
        n, n_rate = self.n_at(t)
        centre = xy[0] + n * np.array([-np.sin(theta[0]), np.cos(theta[0])])
        kappa = float(road.curvature(np.array([float(s)]))[0])
        along = self.speed_at(t) * (1.0 - kappa * n)
        return centre, float(theta[0] + np.arctan2(n_rate, along))


def cast(ego_xy: np.ndarray, ego_yaw: float, rects: list[tuple[np.ndarray, float, float, float]],
         resolution: float, max_range: float) -> np.ndarray:
    """Ranges (R,) of a full-circle scan at ``resolution`` rad (inf where nothing is hit)."""
    bearings = np.arange(-np.pi, np.pi, resolution)
    d = np.stack([np.cos(bearings), np.sin(bearings)], axis=1)
    best = np.full(len(bearings), np.inf)
    for centre, psi, length, width in rects:
        c = to_local(rectangle_corners(centre, np.array(psi), np.array(length), np.array(width)), ego_xy, ego_yaw)
        e = np.roll(c, -1, axis=0) - c
        de = d[:, None, 0] * e[None, :, 1] - d[:, None, 1] * e[None, :, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            r = (c[:, 0] * e[:, 1] - c[:, 1] * e[:, 0])[None, :] / de
            u = (c[None, :, 0] * d[:, None, 1] - c[None, :, 1] * d[:, None, 0]) / de
        ok = (np.abs(de) > 1e-12) & (r > 0) & (u >= 0) & (u <= 1)
        best = np.minimum(best, np.where(ok, r, np.inf).min(axis=1))
    best[best > max_range] = np.inf
    return best


@dataclass
class Scene:
    """Ego (a ``Car``) and other cars on ``road``; ``frame(t, rng)`` makes a ``tracker.Frame``."""

    road: Road
    ego: Car
    cars: list[Car]
    resolution: float = np.radians(0.2)
    max_range: float = 100.0
    sigma: float = 0.03
    radar: bool = False
    radar_sigma: float = 0.2

    def truth(self, t: float) -> np.ndarray:
        """Rows ``[x, y, psi, speed]`` of the other cars in G at ``t``. A car's ``s`` advances at
        ``s_dot = Car.speed_at(t)``, so its own speed at lateral offset ``n`` is ``s_dot (1 - kappa n)``."""
        rows = []
        for car in self.cars:
            centre, psi = car.pose(self.road, t)
            kappa = float(self.road.curvature(np.array([float(self.road.wrap_s(car.s_at(t)))]))[0])
            n, n_rate = car.n_at(t)
            rows.append([centre[0], centre[1], psi, float(np.hypot(car.speed_at(t) * (1.0 - kappa * n), n_rate))])
        return np.array(rows).reshape(-1, 4)

    def frame(self, t: float, rng: np.random.Generator, extra_points_g: np.ndarray | None = None) -> Frame:
        ego_xy, ego_yaw = self.ego.pose(self.road, t)
        rects = [(row[:2], row[2], car.length, car.width) for row, car in zip(self.truth(t), self.cars)]
        ranges = cast(ego_xy, ego_yaw, rects, self.resolution, self.max_range)
        bearings = np.arange(-np.pi, np.pi, self.resolution)
        hit = np.isfinite(ranges)
        r = ranges[hit] + rng.normal(0.0, self.sigma, hit.sum())
        pts = r[:, None] * np.stack([np.cos(bearings[hit]), np.sin(bearings[hit])], axis=1)
        if extra_points_g is not None and len(extra_points_g):
            pts = np.vstack([pts, to_local(extra_points_g, ego_xy, ego_yaw)])
        radar = RadarDetections()
        if self.radar and self.cars:
            truth = self.truth(t)
            local = to_local(truth[:, :2], ego_xy, ego_yaw)
            vel = rotate(truth[:, 3:4] * np.stack([np.cos(truth[:, 2]), np.sin(truth[:, 2])], axis=1), -ego_yaw)
            seen = np.linalg.norm(local, axis=1) < self.max_range
            k = int(seen.sum())
            radar = RadarDetections(
                t=np.full(k, t), x=local[seen, 0] + rng.normal(0, 0.5, k), y=local[seen, 1] + rng.normal(0, 0.5, k),
                vx=vel[seen, 0] + rng.normal(0, self.radar_sigma, k), vy=vel[seen, 1] + rng.normal(0, self.radar_sigma, k),
            )
        curvature = float(self.road.curvature(np.array([float(self.road.wrap_s(self.ego.s0 + self.ego.v * t))]))[0])
        speed = self.ego.v * (1.0 - curvature * self.ego.n)
        return Frame(t, EgoState(ego_xy[0], ego_xy[1], ego_yaw, speed, self.ego.v * curvature), pts, radar)


def kernel_roads() -> dict[str, Road]:
    """The kernels' test roads by name: an open clothoid road (straight, arc, ramp to the other side) and a
    closed Hermite ellipse."""
    open_road = Road.from_curvature([(200.0, 0.0, 0.0), (300.0, 0.0, 1 / 150.0), (600.0, 1 / 150.0, -1 / 80.0)],
                                    lanes=3, lane_width=3.5)
    th = np.linspace(0.0, 2.0 * np.pi, 13)[:-1]
    ring = Road.from_waypoints(np.column_stack([300.0 * np.cos(th), 200.0 * np.sin(th)]), closed=True, lanes=2,
                               lane_width=3.5)
    return {"clothoid-open": open_road, "hermite-closed": ring}
