"""Point-object tracking on cluster centroids: global nearest neighbour (GNN) with a UKF in curvilinear
coordinates -- the paper's earlier tracker (its reference "2021_Integrated") and the study's
``point-gnn`` baseline. No extent, no yaw of its own beyond the direction of motion.

Per frame (``PointTracker.step``):

1. **predict** every track with the same exact Frenet motion model as the extended tracker
   (``tracker.motion``; ``L`` and ``W`` are carried as constants, the birth prior's car size, and only
   feed the kinematic slip);
2. **preprocess and cluster** exactly as the extended tracker does (``tracker.preprocess.
   preprocess_frame``, ``tracker.clustering.ray_partition``), radar detections associated to
   clusters by ``tracker.clustering.cluster_velocities``;
3. **measure** each cluster by its centroid ``z = mean(points)`` in E (``R = centroid_sigma^2 I2``)
   and, for a fused cluster, the radar velocity ``(vx, vy)`` against ``v (cos psi_E, sin psi_E)``
   (``R = radar_velocity_sigma^2 I2``); the predicted measurement of a state is the centre of its
   rectangle in E (``tracker.measurement.to_vehicle``);
4. **associate** by GNN: for every (track, cluster) pair within the pre-gate distance, the UKF update
   (``tracker.update.kalman_update``) gives the normalised innovation squared ``d^2``; pairs with
   ``d^2`` above the chi-square gate (``GatingConfig.probability``, measurement dimension) are
   excluded, and ``scipy.optimize.linear_sum_assignment`` picks the one-to-one assignment of least
   total ``d^2``; an assigned track takes its pair's posterior;
5. **manage** tracks with M-of-N logic: an unassigned cluster with at least
   ``PointConfig.min_cluster_points`` points starts a tentative track (centroid, radar speed along
   the road or the ego's speed, the birth prior's spreads); it is confirmed (reported) after
   ``PointConfig.confirm_hits`` associations within ``confirm_window`` frames; a track is deleted
   after ``max_misses`` consecutive misses (``tentative_max_misses`` before confirmation), or when it
   leaves the lidar's range or the road.

Reported tracks carry ``Track.extent = False``: their ``L`` and ``W`` are the assumed size, not an
estimate, and their position is the centroid of the visible points, which lies between the centre and
the sensor (for a car seen from behind about half its length short).
"""

from __future__ import annotations

import dataclasses

from collections import Counter

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.stats import chi2

from tracker.angles import wrap_angle
from tracker.birth import birth_covariance
from tracker.clustering import cluster_velocities, ray_partition
from tracker.config import TrackerConfig
from tracker.frame import Frame
from tracker.measurement import to_vehicle
from tracker.motion import make_motion, predict
from tracker.preprocess import preprocess_frame
from tracker.road import Road
from tracker.track import Track
from tracker.transforms import to_global
from tracker.ukf import UnscentedTransform
from tracker.update import kalman_update, state_wrapping

#: Variance (m^2) of the pinned ``L`` and ``W`` (tiny; the sigma points need a positive definite covariance).
PINNED_VARIANCE = 1e-6

#: Cost of an excluded (gated-out) pair in the assignment; any real ``d^2`` is far below it.
EXCLUDED = 1e12


class PointTracker:
    """GNN point-object tracker on ``road`` (module docstring); the same ``step(frame) -> list[Track]``,
    ``stats`` and ``last_events`` as ``tracker.Tracker``. ``Tracker(road, config)`` returns one when
    ``config.object_model == "point"``."""

    def __init__(self, road: Road, config: TrackerConfig | None = None) -> None:
        if not isinstance(road, Road):
            raise ValueError(f"PointTracker needs a tracker.Road; got {type(road).__name__}")
        config = TrackerConfig(object_model="point") if config is None else config
        if not isinstance(config, TrackerConfig):
            raise ValueError(f"PointTracker config must be a TrackerConfig; got {type(config).__name__}")
        if config.coordinates != "curvilinear":
            raise ValueError("PointTracker tracks in curvilinear coordinates only; set coordinates='curvilinear'")
        self.road = road
        self.config = config
        self.ut = UnscentedTransform(config.ukf)
        # the point tracker keeps the seven states of docs/architecture.md (no internal acceleration state)
        self.motion = make_motion(dataclasses.replace(config, motion=dataclasses.replace(config.motion, acceleration=False)), road)
        self.wrapping = state_wrapping(road, "curvilinear")
        self.means = np.zeros((0, 7))
        self.covs = np.zeros((0, 7, 7))
        self.labels = np.zeros(0, dtype=int)
        self.hits = np.zeros((0, config.point.confirm_window), dtype=bool)  # last N frames, newest last
        self.misses = np.zeros(0, dtype=int)
        self.confirmed = np.zeros(0, dtype=bool)
        self.t: float | None = None
        self.stats: Counter[str] = Counter()
        self.last_events: dict[str, list] = {"born": [], "updated": [], "missed": [], "dropped": [], "merged": []}
        self._next_label = 1
        self._s_ego: float | None = None
        self._reported: list[int] = []
        self._ever_reported: set[int] = set()
        self._gate = {d: float(chi2.ppf(config.gating.probability, d)) for d in (2, 4)}

    def __len__(self) -> int:
        return len(self.labels)

    # -- public -----------------------------------------------------------------------------------
    def step(self, frame: Frame) -> list[Track]:
        """Process one frame; returns the confirmed tracks (``Track.extent`` False)."""
        if not isinstance(frame, Frame):
            raise ValueError(f"PointTracker.step needs a tracker.Frame; got {type(frame).__name__}")
        if self.t is not None and frame.t < self.t - 1e-9:
            raise ValueError(f"frame at t={frame.t!r} s is older than the last one (t={self.t!r} s); frames must not go back in time")
        dt = 0.0 if self.t is None else max(frame.t - self.t, 0.0)
        self.t = frame.t
        self.stats["frames"] += 1
        ego = frame.ego
        s_ego, _ = self.road.to_frenet((ego.x, ego.y), s_hint=self._s_ego)
        self._s_ego = float(s_ego)
        previous = list(self._reported)
        if len(self.labels) and dt > 0.0:
            self.means, self.covs = predict(self.ut, self.motion, self.means, self.covs, dt)
            self._pin_extent()
        scan, points, counts = preprocess_frame(frame, self.road, self.config.clustering, self.config.cloud)
        self.stats.update(counts)
        clusters = self._clusters(points)
        velocities = cluster_velocities(clusters, frame.radar, frame.t, self.config.clustering.radar_gate) \
            if self.config.use_radar else [None] * len(clusters)
        assigned_track, assigned_cluster = self._associate(frame, clusters, velocities)
        updated = set(int(self.labels[i]) for i in assigned_track)
        hit = np.zeros(len(self.labels), dtype=bool)
        hit[assigned_track] = True
        self.hits = np.concatenate([self.hits[:, 1:], hit[:, None]], axis=1)
        self.misses = np.where(hit, 0, self.misses + 1)
        self.confirmed |= self.hits.sum(axis=1) >= self.config.point.confirm_hits
        free = np.ones(len(clusters), dtype=bool)
        free[assigned_cluster] = False
        self._delete(frame)
        self._birth(frame, [c for c, f in zip(clusters, free) if f], [v for v, f in zip(velocities, free) if f])
        tracks = [Track(int(self.labels[i]), frame.t, self.means[i], self.covs[i], 1.0, extent=False)
                  for i in np.flatnonzero(self.confirmed)]
        self._reported = [tr.label for tr in tracks]
        alive = set(int(lab) for lab in self.labels)
        self.last_events = {
            "born": [lab for lab in self._reported if lab not in self._ever_reported],
            "updated": [lab for lab in self._reported if lab in updated],
            "missed": [lab for lab in previous if lab not in updated],
            "dropped": [lab for lab in previous if lab not in alive],
            "merged": [],
        }
        self._ever_reported.update(self._reported)
        return tracks

    # -- steps ------------------------------------------------------------------------------------
    def _clusters(self, points: np.ndarray) -> list[np.ndarray]:
        cfg = self.config.clustering
        if len(points) == 0:
            return []
        label = ray_partition(points, cfg.distance, cfg.grazing_angle, cfg.bearing_bin, cfg.grazing_max_gap)
        order = np.argsort(label, kind="stable")
        bounds = np.flatnonzero(np.diff(label[order])) + 1
        clusters = [c for c in np.split(points[order], bounds) if len(c) >= cfg.min_points]
        self.stats["clusters"] += len(clusters)
        return clusters

    def _associate(self, frame: Frame, clusters: list[np.ndarray], velocities: list[np.ndarray | None]
                   ) -> tuple[np.ndarray, np.ndarray]:
        """GNN assignment; updates the assigned tracks in place and returns (track, cluster) indices."""
        none = np.zeros(0, dtype=int)
        if not len(self.labels) or not clusters:
            return none, none
        cfg = self.config
        centroid = np.stack([c.mean(axis=0) for c in clusters])  # (K, 2) in E
        fused = np.array([v is not None for v in velocities])
        vel = np.stack([v if v is not None else np.zeros(2) for v in velocities])
        centre = to_vehicle(self.means, frame.ego, self.road).center  # (T, 2)
        near = np.linalg.norm(centre[:, None, :] - centroid[None, :, :], axis=2) <= cfg.gating.distance
        track, clu = np.nonzero(near)
        self.stats["pairs_pre_gated"] += len(track)
        if not len(track):
            return none, none
        sigma = self.ut.sigma_points(self.means[track], self.covs[track], self.wrapping)  # (P, S, 7)
        rect = to_vehicle(sigma, frame.ego, self.road)
        z_sigma = np.concatenate([rect.center, rect.velocity()], axis=-1)  # (P, S, 4)
        z = np.concatenate([centroid[clu], vel[clu]], axis=1)
        r = np.concatenate([np.full((len(track), 2), cfg.point.centroid_sigma**2),
                            np.full((len(track), 2), cfg.measurement.radar_velocity_sigma**2)], axis=1)
        mask = np.ones((len(track), 4), dtype=bool)
        mask[:, 2:] = fused[clu, None]
        res = kalman_update(self.ut, sigma, self.means[track], self.covs[track], z_sigma, np.where(mask, z, 0.0),
                            r, mask, self.wrapping)
        gate = np.where(res.dim == 4, self._gate[4], self._gate[2])
        inside = res.nis <= gate
        cost = np.full((len(self.labels), len(clusters)), EXCLUDED)
        cost[track[inside], clu[inside]] = res.nis[inside]
        rows, cols = linear_sum_assignment(cost)
        ok = cost[rows, cols] < EXCLUDED
        rows, cols = rows[ok], cols[ok]
        pair = np.full((len(self.labels), len(clusters)), -1)
        pair[track, clu] = np.arange(len(track))
        chosen = pair[rows, cols]
        self.means[rows] = res.mean[chosen]
        self.covs[rows] = res.cov[chosen]
        self._pin_extent()
        self.stats["pairs_updated"] += len(rows)
        return rows, cols

    def _delete(self, frame: Frame) -> None:
        cfg = self.config
        limit = np.where(self.confirmed, cfg.point.max_misses, cfg.point.tentative_max_misses)
        keep = self.misses < limit
        if len(self.labels):
            centre = to_vehicle(self.means, frame.ego, self.road).center
            in_range = np.linalg.norm(centre, axis=1) <= cfg.detection.lidar_range + cfg.reduction.fov_margin
            n = self.means[:, 1]
            right, left = self.road.edges(self.means[:, 0])
            on_road = (n >= right - cfg.reduction.road_margin) & (n <= left + cfg.reduction.road_margin)
            self.stats["tracks_left_view"] += int((keep & ~in_range).sum())
            self.stats["tracks_off_road"] += int((keep & in_range & ~on_road).sum())
            keep &= in_range & on_road
        self.stats["tracks_deleted"] += int((~keep).sum())
        self._take(keep)

    def _birth(self, frame: Frame, clusters: list[np.ndarray], velocities: list[np.ndarray | None]) -> None:
        cfg = self.config.birth
        ego = frame.ego
        rows = [(c, v) for c, v in zip(clusters, velocities) if len(c) >= self.config.point.min_cluster_points]
        if not rows:
            return
        centroid_g = to_global(np.stack([c.mean(axis=0) for c, _ in rows]), (ego.x, ego.y), ego.yaw)
        s, n = self.road.to_frenet(centroid_g, s_hint=np.full(len(rows), self._s_ego))
        s, n = np.atleast_1d(np.asarray(s, dtype=float)), np.atleast_1d(np.asarray(n, dtype=float))
        _, theta, _ = self.road.frame(s, extrapolate=True)
        means = np.zeros((len(rows), 7))
        covs = birth_covariance(cfg, len(rows))
        means[:, 0], means[:, 1] = s, n
        means[:, 5], means[:, 6] = cfg.length, cfg.width
        default_speed = ego.v if cfg.speed is None else cfg.speed
        fused = np.array([vel is not None for _, vel in rows])
        vel = np.stack([vel if vel is not None else np.zeros(2) for _, vel in rows])  # (B, 2) in E
        road_e = theta - ego.yaw  # the road tangent's direction in E
        along = vel[:, 0] * np.cos(road_e) + vel[:, 1] * np.sin(road_e)
        moving = fused & (np.hypot(vel[:, 0], vel[:, 1]) > 1.0)  # a heading from the radar only when moving
        means[:, 2] = np.where(fused, along, default_speed)
        means[:, 3] = np.where(moving, wrap_angle(np.arctan2(vel[:, 1], vel[:, 0]) - road_e), 0.0)
        covs[fused, 2, 2] = self.config.measurement.radar_velocity_sigma**2
        covs[:, 0, 0] = covs[:, 1, 1] = self.config.point.centroid_sigma**2
        covs[:, 5, 5] = covs[:, 6, 6] = PINNED_VARIANCE
        labels = np.arange(self._next_label, self._next_label + len(rows))
        self._next_label += len(rows)
        self.means = np.concatenate([self.means, means])
        self.covs = np.concatenate([self.covs, covs])
        self.labels = np.concatenate([self.labels, labels])
        first = np.zeros((len(rows), self.config.point.confirm_window), dtype=bool)
        first[:, -1] = True  # the cluster that started the track counts as its first hit
        self.hits = np.concatenate([self.hits, first])
        self.misses = np.concatenate([self.misses, np.zeros(len(rows), dtype=int)])
        self.confirmed = np.concatenate([self.confirmed, np.zeros(len(rows), dtype=bool)])
        self.stats["births_cluster"] += len(rows)

    def _pin_extent(self) -> None:
        """Keep ``L``, ``W`` at the assumed size with no uncertainty and no correlation (a point object
        has no extent; only the slip uses it)."""
        cfg = self.config.birth
        self.means[:, 5], self.means[:, 6] = cfg.length, cfg.width
        self.covs[:, 5:, :] = 0.0
        self.covs[:, :, 5:] = 0.0
        self.covs[:, 5, 5] = self.covs[:, 6, 6] = PINNED_VARIANCE

    def _take(self, keep: np.ndarray) -> None:
        for name in ("means", "covs", "labels", "hits", "misses", "confirmed"):
            setattr(self, name, getattr(self, name)[keep])


__all__ = ["PointTracker"]
