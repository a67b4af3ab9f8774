"""Stone Soup's GM-PHD filter with its UKF on our lidar cluster centroids: an external point-object
baseline (the ``stonesoup-gmphd`` study variant).

Input side, shared with ``tracker.Tracker``: the same lidar preprocessing (``tracker.preprocess``:
non-finite points dropped, the road-bound filter, the bearing filter) and the same distance
partitioning (``tracker.clustering.distance_partition``) with the settings of the variant's
``TrackerConfig.clustering``. Each cluster of at least ``clustering.min_points`` points gives one
detection: its centroid in the global frame G. Radar is not used (Stone Soup's GM-PHD here is a
position-only point tracker; the ``point-gnn`` variant is the fused point tracker).

Filter, all Stone Soup components, assembled as in Stone Soup's GM-PHD tutorial:

- state ``[x, vx, y, vy, omega]`` in G, ``stonesoup.models.transition.nonlinear.ConstantTurn``
  (``accel_noise`` m^2/s^3 on both axes, ``turn_noise`` rad^2/s^3);
- ``LinearGaussian`` position measurement (``centroid_sigma`` m per axis: a centroid of the visible
  sides lies up to half a car length from the rectangle centre, so this is much larger than the
  lidar noise);
- ``UnscentedKalmanPredictor`` / ``UnscentedKalmanUpdater``;
- ``DistanceHypothesiser`` (Mahalanobis, ``gate``) inside ``GaussianMixtureHypothesiser``;
- ``PHDUpdater`` with ``prob_detection`` and ``prob_survival`` from ``TrackerConfig.detection`` and
  the clutter intensity ``clutter_rate * clutter_density`` (1/m^2) of the same configuration;
- ``GaussianMixtureReducer`` (prune at ``reduction.prune_threshold``, merge at ``merge_threshold``
  squared Mahalanobis, cap at ``reduction.max_components``);
- one birth component per frame (Stone Soup's ``BIRTH`` tag) centred on the ego with the ego's
  velocity and a broad covariance (``birth_position_std`` m, ``birth_speed_std`` m/s,
  ``birth_turn_std`` rad/s) of weight ``birth_weight``, as in the tutorial.

Output: per Stone Soup tag (a track identity), the heaviest component whose weight exceeds
``reduction.extraction_threshold`` becomes a ``tracker.Track`` with a stable integer label. Its
Cartesian view is ``[x, y, v, psi, omega, 0, 0]`` (``psi`` the velocity's direction: a point tracker
has no yaw of its own; no extent: ``estimates_extent = False``, so the runner reports length and
width errors as missing), converted to road coordinates by ``Track.from_cartesian``.
"""

from __future__ import annotations

import datetime
from collections import Counter
from dataclasses import dataclass
from typing import Any

import numpy as np

from tracker import Frame, Road, Track, TrackerConfig
from tracker.clustering import distance_partition
from tracker.preprocess import bearing_filter, lidar_points, road_bound_mask
from tracker.transforms import to_global

#: How to install Stone Soup when it is missing.
INSTALL_HINT = 'pip install -e ".[baselines]"  (or: pip install "stonesoup>=1.4")'
#: Speed (m/s) below which the heading's covariance is computed at this speed (atan2 is singular at 0).
MIN_SPEED_FOR_HEADING = 0.5
#: Variance (m^2) given to the placeholder extent in the reported covariance (a point has none).
POINT_EXTENT_VARIANCE = 1e-6
_EPOCH = datetime.datetime(2000, 1, 1)


class MissingBaselineError(RuntimeError):
    """An optional dependency of a baseline is not installed; the message says how to install it."""


def import_stonesoup() -> dict[str, Any]:
    """The Stone Soup classes the baseline uses, by name; ``MissingBaselineError`` when Stone Soup is
    not installed."""
    try:
        from stonesoup.hypothesiser.distance import DistanceHypothesiser
        from stonesoup.hypothesiser.gaussianmixture import GaussianMixtureHypothesiser
        from stonesoup.measures import Mahalanobis
        from stonesoup.mixturereducer.gaussianmixture import GaussianMixtureReducer
        from stonesoup.models.measurement.linear import LinearGaussian
        from stonesoup.models.transition.nonlinear import ConstantTurn
        from stonesoup.predictor.kalman import UnscentedKalmanPredictor
        from stonesoup.types.detection import Detection
        from stonesoup.types.state import TaggedWeightedGaussianState
        from stonesoup.updater.kalman import UnscentedKalmanUpdater
        from stonesoup.updater.pointprocess import PHDUpdater
    except ImportError:
        raise MissingBaselineError(
            f"the stonesoup-gmphd variant needs Stone Soup, an optional extra: {INSTALL_HINT}"
        ) from None
    return dict(locals())


@dataclass(frozen=True)
class StoneSoupGMPHDConfig:
    """Settings of the baseline that ``TrackerConfig`` has no counterpart for (SI units).

    - ``centroid_sigma`` (m): std of a cluster centroid about the target centre, per axis;
    - ``accel_noise`` (m^2/s^3): ``ConstantTurn.linear_noise_coeffs`` on x and y;
    - ``turn_noise`` (rad^2/s^3): ``ConstantTurn.turn_noise_coeff``;
    - ``gate``: Mahalanobis distance beyond which a component-detection pair is not hypothesised;
    - ``merge_threshold``: squared Mahalanobis distance for merging (Stone Soup's default 16);
    - ``birth_weight``: weight of the per-frame birth component (expected births per frame);
    - ``birth_position_std`` (m), ``birth_speed_std`` (m/s), ``birth_turn_std`` (rad/s): its spread
      about the ego's position, velocity and zero turn rate.
    """

    centroid_sigma: float = 1.0
    accel_noise: float = 1.0
    turn_noise: float = 0.01
    gate: float = 4.0
    merge_threshold: float = 16.0
    birth_weight: float = 0.1
    birth_position_std: float = 60.0
    birth_speed_std: float = 10.0
    birth_turn_std: float = 0.1

    def __post_init__(self) -> None:
        for name in ("centroid_sigma", "accel_noise", "turn_noise", "gate", "merge_threshold", "birth_weight",
                     "birth_position_std", "birth_speed_std", "birth_turn_std"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and np.isfinite(value) and value > 0):
                raise ValueError(f"StoneSoupGMPHDConfig.{name} must be a finite number > 0; got {value!r}")


def _cartesian_view(mean: np.ndarray, cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``[x, vx, y, vy, omega]`` Gaussian -> ``[x, y, v, psi, psi_dot, L, W]`` Gaussian (linearised
    at the mean; the extent is a zero placeholder with ``POINT_EXTENT_VARIANCE``)."""
    x, vx, y, vy, omega = mean
    v = float(np.hypot(vx, vy))
    psi = float(np.arctan2(vy, vx))
    r = max(v, MIN_SPEED_FOR_HEADING)
    c, s = vx / r if v > 0 else 1.0, vy / r if v > 0 else 0.0
    jac = np.zeros((7, 5))
    jac[0, 0] = jac[1, 2] = jac[4, 4] = 1.0
    jac[2, 1], jac[2, 3] = c, s
    jac[3, 1], jac[3, 3] = -s / r, c / r
    out_cov = jac @ cov @ jac.T
    out_cov[5, 5] = out_cov[6, 6] = POINT_EXTENT_VARIANCE
    return np.array([x, y, v, psi, omega, 0.0, 0.0]), 0.5 * (out_cov + out_cov.T)


class StoneSoupGMPHD:
    """Stone Soup's GM-PHD + UKF on cluster centroids (module docstring), with the runner's tracker
    interface: ``step(frame) -> list[tracker.Track]``, ``stats`` (counters), ``estimates_extent``."""

    #: A point tracker: the runner reports length/width errors as missing.
    estimates_extent = False

    def __init__(self, road: Road, config: TrackerConfig | None = None,
                 baseline: StoneSoupGMPHDConfig | None = None) -> None:
        if not isinstance(road, Road):
            raise ValueError(f"StoneSoupGMPHD needs a tracker.Road; got {type(road).__name__}")
        self.road = road
        self.config = TrackerConfig() if config is None else config
        self.baseline = StoneSoupGMPHDConfig() if baseline is None else baseline
        ss = import_stonesoup()
        self._ss = ss
        b, det, red = self.baseline, self.config.detection, self.config.reduction
        transition = ss["ConstantTurn"](linear_noise_coeffs=np.array([b.accel_noise, b.accel_noise]),
                                        turn_noise_coeff=b.turn_noise)
        self._measurement_model = ss["LinearGaussian"](ndim_state=5, mapping=(0, 2),
                                                       noise_covar=np.eye(2) * b.centroid_sigma**2)
        predictor = ss["UnscentedKalmanPredictor"](transition)
        updater = ss["UnscentedKalmanUpdater"](self._measurement_model)
        self._hypothesiser = ss["GaussianMixtureHypothesiser"](
            ss["DistanceHypothesiser"](predictor, updater, measure=ss["Mahalanobis"](), missed_distance=b.gate),
            order_by_detection=True)
        self._updater = ss["PHDUpdater"](updater, clutter_spatial_density=det.clutter_rate * det.clutter_density,
                                         prob_detection=det.p_detection, prob_survival=det.p_survival)
        self._reducer = ss["GaussianMixtureReducer"](prune_threshold=red.prune_threshold,
                                                     merge_threshold=b.merge_threshold,
                                                     max_number_components=red.max_components)
        self.components: list[Any] = []
        self.t: float | None = None
        self.stats: Counter[str] = Counter()
        self._labels: dict[Any, int] = {}

    # -- input ----------------------------------------------------------------------------------
    def centroids(self, frame: Frame) -> np.ndarray:
        """Cluster centroids ``(K, 2)`` in G of ``frame``'s lidar points (module docstring)."""
        cl = self.config.clustering
        ego = frame.ego
        pts, removed, _ = lidar_points(frame, self.config.cloud)  # a 3-D cloud: ground removal first
        self.stats.update(removed)
        if len(pts) == 0:
            return np.zeros((0, 2))
        pts_g = to_global(pts, (ego.x, ego.y), ego.yaw)
        on_road = road_bound_mask(pts_g, self.road, cl.road_margin)
        self.stats["points_off_road"] += int((~on_road).sum())
        pts, pts_g = pts[on_road], pts_g[on_road]
        keep = bearing_filter(pts, cl.bearing_bin)
        pts_g = pts_g[keep]
        if len(pts_g) == 0:
            return np.zeros((0, 2))
        labels = distance_partition(pts_g, cl.distance)
        counts = np.bincount(labels)
        sums = np.stack([np.bincount(labels, weights=pts_g[:, 0]), np.bincount(labels, weights=pts_g[:, 1])], axis=1)
        big = counts >= cl.min_points
        self.stats["clusters_too_small"] += int((~big).sum())
        return sums[big] / counts[big, None]

    # -- the filter -----------------------------------------------------------------------------
    def _birth(self, frame: Frame, timestamp: datetime.datetime) -> Any:
        b, ego = self.baseline, frame.ego
        mean = np.array([[ego.x], [ego.v * np.cos(ego.yaw)], [ego.y], [ego.v * np.sin(ego.yaw)], [0.0]])
        cov = np.diag([b.birth_position_std**2, b.birth_speed_std**2, b.birth_position_std**2, b.birth_speed_std**2,
                       b.birth_turn_std**2])
        state = self._ss["TaggedWeightedGaussianState"]
        return state(mean, cov, weight=b.birth_weight, tag=state.BIRTH, timestamp=timestamp)

    def step(self, frame: Frame) -> list[Track]:
        """Process one frame: predict, hypothesise, PHD-update, reduce, extract (module docstring)."""
        if not isinstance(frame, Frame):
            raise ValueError(f"StoneSoupGMPHD.step needs a tracker.Frame; got {type(frame).__name__}")
        if self.t is not None and frame.t < self.t - 1e-9:
            raise ValueError(f"frame at t={frame.t!r} s is older than the last one (t={self.t!r} s)")
        self.t = frame.t
        self.stats["frames"] += 1
        timestamp = _EPOCH + datetime.timedelta(seconds=float(frame.t))
        centroids = self.centroids(frame)
        self.stats["clusters"] += len(centroids)
        detection = self._ss["Detection"]
        detections = {detection(c.reshape(2, 1), timestamp=timestamp, measurement_model=self._measurement_model)
                      for c in centroids}
        components = [*self.components, self._birth(frame, timestamp)]
        hypotheses = self._hypothesiser.hypothesise(components, detections, timestamp)
        mixture = self._updater.update(hypotheses)
        self.components = list(self._reducer.reduce(list(mixture.components)))
        self.stats["components"] += len(self.components)
        return self._extract(frame.t)

    def _extract(self, t: float) -> list[Track]:
        threshold = self.config.reduction.extraction_threshold
        best: dict[Any, Any] = {}
        for comp in self.components:
            if comp.tag == comp.BIRTH or float(comp.weight) <= threshold:
                continue
            if comp.tag not in best or float(comp.weight) > float(best[comp.tag].weight):
                best[comp.tag] = comp
        tracks = []
        for tag, comp in best.items():
            label = self._labels.setdefault(tag, len(self._labels) + 1)
            mean, cov = _cartesian_view(np.asarray(comp.state_vector, dtype=float).reshape(-1),
                                        np.asarray(comp.covar, dtype=float))
            tracks.append(Track.from_cartesian(label, t, mean, cov, self.road, weight=min(float(comp.weight), 1.0)))
        return sorted(tracks, key=lambda tr: tr.label)


def stonesoup_gmphd_factory(road: Road, config: TrackerConfig) -> StoneSoupGMPHD:
    """``tracker_factory`` of the ``stonesoup-gmphd`` variant (default ``StoneSoupGMPHDConfig``)."""
    return StoneSoupGMPHD(road, config)


__all__ = ["INSTALL_HINT", "MissingBaselineError", "StoneSoupGMPHD", "StoneSoupGMPHDConfig", "import_stonesoup",
           "stonesoup_gmphd_factory"]
