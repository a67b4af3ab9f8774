"""The multi-target tracker: the paper's GM-PHD extended-target filter around the single-target UKF.

``Tracker(road, config).step(frame) -> list[Track]``. One step:

1. **Predict** the mixture over ``dt`` (UKF through the motion model), weights times ``P_S``, the
   tracks that nothing updated in the last frame first pulled towards their lane's speed
   (``tracker.flow``); add the births: road components (per lane near the range limits, where the view is not blocked and
   no track is within ``gating.distance``) and the previous frame's unexplained clusters
   (``tracker.birth``), the road births only in frames with lidar points. A frame older than the last
   raises ``ValueError``;
   ``dt = 0`` predicts nothing.
2. **Preprocess** the lidar (``tracker.preprocess``): non-finite points dropped, points off the road
   (plus ``clustering.road_margin``) dropped, the bearing filter. Every drop is counted in ``stats``.
   Lidar is the primary sensor: a frame without lidar points only predicts.
3. **Cluster** (``tracker.clustering``): points inside a reported track's predicted rectangle (plus
   ``clustering.track_margin``) form its cluster, even in fragments; overlapping track rectangles (duplicate
   hypotheses of one vehicle) share one; a connected component (distance partitioning) that a track
   owns in part joins it entirely; the rest are clusters by distance partitioning. Radar detections,
   moved to the frame time with their own velocity, join clusters by greedy nearest neighbour within
   ``clustering.radar_gate``; such clusters are *fused* (their absolute velocity enters the update).
   Clusters that no component explains and that lie outside every track's rectangle seed births.
4. **Update** (Granstrom et al. 2012 with one partition, the paper's weights). With the state-dependent
   ``gamma(x)`` and ``P_D(x)`` of ``tracker.detection``:

   - missed detection: ``w (1 - (1 - e^-gamma) P_D)``;
   - cluster ``W`` and component ``i`` (only gated pairs: centroid within ``gating.distance`` of the
     predicted rectangle, then the normalised innovation inside the chi-square ``gating.probability``
     quantile; a reported track's own cluster, whose points lie in its predicted rectangle, always
     updates it): ``w_i^W = P_D w_i Gamma_i L_i^W / (delta_{|W|,1} + sum_j P_D w_j Gamma_j L_j^W)`` with
     ``Gamma = e^-gamma gamma^|W|`` and ``L = N(z_W; y, S) prod_z 1 / (lambda c(z))``, in the log domain.

   Departures: a component of a label reported before, inside the lidar range, whose ``P_D`` the
   occlusion model puts below ``detection.hidden_update_p_detection`` takes that value in its pairs'
   weights (not in its missed-detection term), so that a car the model takes for hidden can still be
   updated by the points it shows; a fused cluster's radar velocity that no pair explains
   (``measurement.radar_gate``) is set aside for all its pairs (``tracker.kalman.measurement_update_kernel``);
   optionally (``detection.missed_weight_cap``, off) a label's missed-detection weight is capped at one
   minus what its updated components took. A cluster of a few points (``birth.after_update_points``)
   that the update left unexplained, next to no coasting track, is born and updated in a second pass of
   the update that takes only those births and clusters (``_births_after_update``).

5. **Reduce**: drop components that left the field of view (nearest corner farther than
   ``detection.lidar_range + reduction.fov_margin``) or the road (centre beyond the road edges by more
   than ``reduction.road_margin``), prune, angle-aware merge, then merge reportable components (weight
   above the extraction threshold) of one label within ``reduction.same_label_distance`` (a track
   updated by fragments of one vehicle's points), cap
   (``tracker.reduction``); and **extract**: components with
   weight above ``reduction.extraction_threshold`` (0.5) whose centre lies within the lidar range
   (``reduction.report_range``) are tracks, a new label only once a cluster of
   ``reduction.confirm_min_points`` (2) points has updated it (fused, a radar velocity the update used
   counts as one, ``reduction.confirm_radar_point``), and a newly confirmed track takes the
   label of a track lost within ``reduction.reidentify_window`` whose prediction it matches
   (``tracker.identity``). Labels: births get new ones,
   updates inherit, merges keep the heaviest's; a label is reported at most once per frame (a second
   component with the same label above the threshold gets a new label: the target split).
6. **Learn** the width error of the vehicle classes' size prior from the tracks measured whole
   (``tracker.fleet``, ``birth.width_error_vehicles``): the next frames' updates and births use it.

The Cartesian variant (``coordinates="cartesian"``) runs the same machinery on
``[x, y, v, psi, psi_dot, L, W]`` in G and reports tracks converted to road coordinates.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections import Counter
from collections.abc import Container, KeysView

import numpy as np
from scipy.stats import chi2

from tracker.birth import (cluster_births, entering_view, road_births, to_cartesian_gaussians, visible_road_births,
                           with_acceleration)
from tracker.cloud import CloudResult
from tracker.clustering import (bearing_extremes, cluster_radar_ranges, fragment_owners,
                                occluded_ends, points_in_rectangles, ray_partition, SPLIT_MAX_CUTS)
from tracker.config import TrackerConfig
from tracker.course import TURN_FRAMES, TURN_TOLERANCE, agrees_along, crossing_courses, turn_to_course
from tracker.detection import cap_missed_weights, detection_model, nearest_range
from tracker.frame import EgoState, Frame
from tracker.identity import LostTracks
from tracker.measurement import MIN_EXTENT, Rectangles, to_vehicle
from tracker.motion import LENGTH, V, WIDTH, make_motion, predict, relax_acceleration
from tracker.point import PointTracker
from tracker.preprocess import filter_points, lidar_points, nearest_per_ray
from tracker.reduction import Mixture, absorb_overlapping, reduce, reduce_in_view
from tracker.road import Road
from tracker.track import Track
from tracker.transforms import to_global
from tracker.radar_update import RADAR_ONLY_CLEARANCE, update_coasting
from tracker.ukf import UnscentedTransform, ensure_spd
from tracker.update import CLASS_PRIOR, state_wrapping, update_clusters
from tracker.clustering import along_cuts_kernel, cluster_points_kernel, ordered_clusters_kernel, overlap_groups_kernel
from tracker.extent import bound_at_holes_kernel, class_arrays, class_prior_lengths_kernel
from tracker.fleet import MEASURED_WIDTH_STD, WidthError
from tracker.flow import flow_speeds, pull_to_flow
from tracker.extraction import report_centres_kernel
from tracker.gating import candidate_pairs_kernel
from tracker.reduction import inside_updated_kernel

#: Frames whose time precedes the last one by more than this (s) are rejected.
TIME_TOLERANCE = 1e-9

#: A track reported in at least this many frames in a row may touch a neighbour's predicted rectangle by
#: ``ClusteringConfig.duplicate_depth`` and keep its own points (``Tracker._duplicate_depths``).
ESTABLISHED_FRAMES = 3

#: ``cluster_points_kernel``'s components when the kernel is to find them itself (none given).
_PARTITION_HERE = np.zeros(0, dtype=np.int64)

#: The stages of ``Tracker.step`` timed in ``Tracker.stage_seconds``, in their order: the prediction
#: (cluster births of the last frame joining first), the lidar preprocessing, the road births (with the
#: last frame's tracks' rectangles they avoid), the clustering (radar association included), the GM-PHD
#: update (in the first scanned frame also the first scan's births), the radar-only updates of coasting tracks,
#: the cluster births for the next frame, the reduction (field of view, prune, merge, overlaps) and
#: the extraction of the tracks (labels, re-identification, events).
STAGES = ("predict", "preprocess", "road_births", "cluster", "update", "radar_update", "cluster_births", "reduce",
          "extract")


class Tracker:
    """GM-PHD extended-object tracker on ``road`` configured by ``config`` (module docstring).

    ``stats`` counts, over the tracker's life: ``frames``, ``predict_only_frames``,
    ``points_nonfinite``, ``points_off_road``, ``points_bearing_filtered``, ``clusters``,
    ``clusters_fused``, ``clusters_too_small``, ``clusters_split`` (parts added by cutting clusters wider
    across the road than one vehicle, ``clustering.split_width``), ``clusters_cut_along`` (parts added by
    cutting track clusters at a hole along the track, ``clustering.along_gap``),
    ``components_shortened_at_holes`` (components shortened to end at such a hole), ``fragment_points_adopted`` (lone returns
    joined to the track whose side they continue, ``clustering.fragment_points``), ``pairs_pre_gated`` (centroid within the gating
    distance of the rectangle's circumscribed circle), ``pairs_updated``, ``own_clusters_past_gate``,
    ``cluster_ends_occluded`` (ends of updating clusters next to another object's shadow),
    ``cluster_ends_continued`` (ends whose side goes on in another cluster, ``measurement.continuation_rays``),
    ``radar_velocities_rejected`` (fused clusters whose radar velocity no pair explains,
    ``measurement.radar_gate``), ``turned_to_radar_course`` (components turned a quarter turn to their own
    cluster's radar course across their heading, ``tracker.course``),
    ``covariances_repaired`` (posteriors lifted to positive definite, ``tracker.ukf.ensure_spd``),
    ``births_road``, ``births_cluster``, ``births_first_scan`` (``birth.first_scan``), ``births_same_frame``
    (``birth.same_frame``), ``births_after_update`` (``birth.after_update_points``), ``births_shadowed``
    (unexplained clusters with exactly one end in bearing next to another object's shadow, ``measurement.shadow_window``),
    ``components_inside_updated_dropped`` (``reduction.drop_inside_updated``), ``components_left_view``, ``components_off_road``,
    ``label_splits``, ``unseen_branches_unreported`` (a label's components above the threshold left out of
    the report because another of its components holds this frame's points and they hold none),
    ``births_awaiting_support`` (components above the extraction threshold not yet
    reported: no cluster of ``reduction.confirm_min_points`` points has updated their label),
    ``labels_reidentified`` (newly confirmed tracks that took a lost track's label, ``tracker.identity``),
    ``coasting_tracks_taken_over``, ``tracks_beyond_report_range`` (components above the threshold not
    reported because their centre lies beyond ``detection.lidar_range + reduction.report_range``),
    ``tracks_off_road_unreported`` (components above the threshold not reported because their centre lies
    beyond a road edge by more than ``reduction.report_road_margin``), ``tracks_uncertain_unreported``
    (components above the threshold not reported because their position's std exceeds
    ``reduction.report_position_std``),
    ``tracks_kept_below_threshold`` (tracks reported under ``reduction.keep_threshold``'s hysteresis).
    ``last_events`` (dict of label lists) says what happened to the tracks in the
    last ``step`` (``_record_events``), for diagnostics (``eot inspect``).
    ``stage_seconds`` sums the wall time (s, ``time.perf_counter``) of each stage of ``step`` over the
    tracker's life, by ``STAGES`` name: where a frame's time goes (``eot bench`` reports it per frame).
    Wall times are not deterministic: they are kept apart from ``stats``.
    """

    def __new__(cls, road: Road | None = None, config: TrackerConfig | None = None) -> Tracker:
        """``Tracker(road, config)`` with ``config.object_model == "point"`` builds the point-object GNN
        tracker (``tracker.point.PointTracker``: the same ``step``, ``stats`` and ``last_events``)."""
        if cls is Tracker and isinstance(config, TrackerConfig) and config.object_model == "point":
            return PointTracker(road, config)  # type: ignore[return-value]
        return super().__new__(cls)

    def __init__(self, road: Road, config: TrackerConfig | None = None) -> None:
        if not isinstance(road, Road):
            raise ValueError(f"Tracker needs a tracker.Road; got {type(road).__name__}")
        config = TrackerConfig() if config is None else config
        if not isinstance(config, TrackerConfig):
            raise ValueError(f"Tracker config must be a TrackerConfig; got {type(config).__name__}")
        self.road = road
        self.config = config
        #: the width error of the vehicle classes' size prior, learned from the vehicles measured whole
        #: (``tracker.fleet``, ``BirthConfig.width_error_vehicles``)
        self.width_error = WidthError(config.birth)
        self._sized = config  # the config with the width error in use (``_learn_width_error``)
        self.cartesian = config.coordinates == "cartesian"
        self.motion = make_motion(config, road)
        self.dim = self.motion.dim  # 7, or 8 with the acceleration state (MotionConfig.acceleration)
        self.ut = UnscentedTransform(config.ukf, n=self.dim)
        self.wrapping = state_wrapping(road, config.coordinates)
        self.mixture = Mixture(np.zeros(0), np.zeros((0, self.dim)), np.zeros((0, self.dim, self.dim)), np.zeros(0, dtype=int))
        self.t: float | None = None
        self.stats: Counter[str] = Counter()
        self._crossing_frames: dict[int, tuple[int, int]] = {}  # tracker.course: radar courses across a label's heading
        self.stage_seconds: dict[str, float] = dict.fromkeys(STAGES, 0.0)
        #: the 3-D pipeline's result for the last frame (``tracker.cloud.CloudResult``; None when its lidar was 2-D)
        self.last_cloud: CloudResult | None = None
        self._next_label = 1
        self._s_ego: float | None = None
        self._ego_road = (0.0, 0.0, 0.0)  # the ego's (s, n, v) in this frame: a seen vehicle of the lane flow
        self._reported = np.zeros(0, dtype=int)  # indices into the mixture of last frame's tracks
        self._pending = (np.zeros((0, self.dim)), np.zeros((0, self.dim, self.dim)))  # cluster births for the next frame
        self._owned = np.zeros(0, dtype=int)  # per cluster: the track group owning it, or -1
        self._component_group = np.zeros(0, dtype=int)  # per component: its track group, or -1
        self._scan = np.zeros((0, 2))  # the frame's finite lidar returns in E (of a 3-D cloud: the nearest per ray)
        self._point_n = np.zeros(0)  # lateral road offsets (m) of the points kept for clustering
        self._streak: dict[int, int] = {}  # label reported in the last frame -> frames it has been reported in a row
        self._updated_labels: set[int] = set()
        self._strong_labels: set[int] = set()  # labels a cluster updated to a reportable posterior this frame
        self._ever_reported: set[int] = set()
        self._scanned = False  # a frame with lidar points has been processed (BirthConfig.first_scan)
        self._free_radar = np.zeros(0, dtype=int)  # the frame's radar detections that joined no cluster
        self._points = np.zeros((0, 2))  # the frame's lidar points kept for clustering, in E
        self._radar_updated: set[int] = set()  # labels a radar-only update refined in the last frame
        self._support: dict[int, int] = {}  # label -> most lidar points of a cluster that updated it
        # manoeuvre-gated jerk (MotionConfig.quiet_jerk): label -> time (s) until which it is predicted
        # with the full jerk, and the labels whose manoeuvre was detected in the last frame
        self._manoeuvre_until: dict[int, float] = {}
        self._manoeuvre_onset: set[int] = set()
        self._manoeuvre_score: dict[int, tuple[float, float]] = {}  # label -> (time, fading mean of z)
        self._frame_dt = 0.0  # the current frame's interval (s)
        red = config.reduction
        self._lost = LostTracks(red.reidentify_window, red.reidentify_probability, self.ut, self.motion,
                                road.length if road.closed and not self.cartesian else None,
                                red.reidentify_accel, self.cartesian, red.reidentify_brake,
                                red.reidentify_lane_following)
        self.last_events: dict[str, list] = {"born": [], "updated": [], "missed": [], "dropped": [], "merged": []}
        max_dim = 2 * config.measurement.max_cluster_points + 2
        self._gate_table = chi2.ppf(config.gating.probability, np.arange(max_dim + 1))  # by dimension

    # -- public -----------------------------------------------------------------------------------
    def step(self, frame: Frame) -> list[Track]:
        """Process one frame (its lidar points, radar detections and ego pose); returns the tracks."""
        if not isinstance(frame, Frame):
            raise ValueError(f"Tracker.step needs a tracker.Frame; got {type(frame).__name__}")
        if self.t is not None and frame.t < self.t - TIME_TOLERANCE:
            raise ValueError(f"frame at t={frame.t!r} s is older than the last one (t={self.t!r} s); frames must not go back in time")
        dt = 0.0 if self.t is None else max(frame.t - self.t, 0.0)
        self.t = frame.t
        self._frame_dt = dt
        self.stats["frames"] += 1
        clock, spent = time.perf_counter, self.stage_seconds
        t0 = clock()
        ego = frame.ego
        s_ego, n_ego = self.road.to_frenet((ego.x, ego.y), s_hint=self._s_ego)
        self._s_ego = s_ego
        self._ego_road = (float(s_ego), float(n_ego), float(ego.v))
        previous = self.mixture.labels[self._reported].tolist()  # last frame's tracks
        updated_before, self._updated_labels = self._updated_labels | self._radar_updated, set()
        self._strong_labels = set()
        self._radar_updated = set()
        self._pull_to_flow(dt, updated_before)
        self._predict(dt, updated_before)
        t1 = clock()
        spent["predict"] += t1 - t0
        points, scanned = self._preprocess(frame)
        t0 = clock()
        spent["preprocess"] += t0 - t1
        if not scanned:
            # no lidar points at all (a blackout): predict only; no road births, which no scan could
            # confirm or discount (their weight would stand unchanged until the lidar returns); the
            # radar's detections still update the tracks (all of them coasting now)
            self.stats["predict_only_frames"] += 1
            self._points = np.zeros((0, 2))
            self._free_radar = np.arange(len(frame.radar))
            if self.config.use_radar and self.config.measurement.radar_only_update:
                self._update_by_radar(frame)
            t1 = clock()
            spent["radar_update"] += t1 - t0
        else:
            # last frame's tracks as predicted rectangles in E: births avoid them, clustering assigns to them
            track_rect = to_vehicle(self.mixture.means[self._reported], ego, self.road, self.config.coordinates)
            later = self._scanned  # a frame after the first with lidar points
            first = not later and self.config.birth.first_scan
            self._scanned = True
            if not first:
                self._add_births(ego, s_ego, track_rect, self.mixture.labels[self._reported])
            t1 = clock()
            spent["road_births"] += t1 - t0
            clusters, velocities = self._cluster(points, frame, track_rect)
            t0 = clock()
            spent["cluster"] += t0 - t1
            if first:  # the first scan's vehicles are born now; the road births avoid them as they avoid tracks
                born = self._births_now(ego, clusters, velocities, np.zeros(len(clusters), dtype=bool))
                self.stats["births_first_scan"] += len(born)
                self._add_births(ego, s_ego, to_vehicle(self.mixture.means[born], ego, self.road, self.config.coordinates),
                                 self.mixture.labels[born])
                self._component_group = np.full(len(self.mixture), -1)  # no reported track owns a component yet
            elif later and self.config.birth.same_frame and clusters:  # clusters no component reaches are born now
                born = self._births_now(ego, clusters, velocities, self._reached(ego, clusters))
                self.stats["births_same_frame"] += len(born)
                self._component_group = np.concatenate([self._component_group, np.full(len(born), -1)])
            explained = self._update(ego, clusters, velocities)
            if later and self.config.birth.after_update_points is not None and clusters:
                explained |= self._births_after_update(ego, clusters, velocities, explained)
            t1 = clock()
            spent["update"] += t1 - t0
            if self.config.use_radar and self.config.measurement.radar_only_update:
                self._update_by_radar(frame)
            t0 = clock()
            spent["radar_update"] += t0 - t1
            self._plan_cluster_births(ego, clusters, velocities, explained)
            t1 = clock()
            spent["cluster_births"] += t1 - t0
        self._reduce(ego)
        t0 = clock()
        spent["reduce"] += t0 - t1
        tracks = self._extract(frame.t, ego)
        self._learn_width_error(ego)
        self._record_events(previous, tracks)
        spent["extract"] += clock() - t0
        return tracks

    # -- steps ------------------------------------------------------------------------------------
    def _predict(self, dt: float, updated: set[int] | None = None) -> None:
        """Predict over ``dt``; with the acceleration state and
        ``MotionConfig.coast_acceleration_time``, the components of labels that no cluster updated in the
        last frame (``updated``) first have their acceleration relaxed by ``exp(-dt /
        coast_acceleration_time)`` (mean, and the covariance's row and column: the linear map ``a -> f
        a``), or by ``exp(-dt / coast_established_time)`` where it is established (``|a| >=
        coast_established_sigmas sd(a)``); their acceleration's variance relaxes with the same factor ``f``
        toward ``MotionConfig.coast_acceleration_std`` squared (``f^2 var + (1 - f^2) std^2``, a lower
        bound of the variance after the scaling). With ``MotionConfig.quiet_jerk`` the jerk is chosen per
        component (``_manoeuvre_jerk``)."""
        mix = self.mixture
        coast = self.config.motion.coast_acceleration_time
        relax = None  # the acceleration's factor per component (applied in the prediction's first step)
        spread = None  # the least variance of each coasting component's relaxed acceleration
        if self.dim == 8 and coast is not None and dt > 0.0 and updated is not None and len(mix):
            idle = ~_labels_in(mix.labels, updated)
            if idle.any():
                f = np.full(int(idle.sum()), math.exp(-dt / coast))
                motion = self.config.motion
                if motion.coast_established_sigmas is not None:
                    # an acceleration the measurements established (|a| >= k sd(a)) fades slowly
                    a, var = mix.means[idle, 7], mix.covs[idle, 7, 7]
                    established = np.abs(a) >= motion.coast_established_sigmas * np.sqrt(np.maximum(var, 0.0))
                    f[established] = math.exp(-dt / motion.coast_established_time)
                relax = np.ones(len(mix))
                relax[idle] = f
                if motion.coast_acceleration_std is not None:  # toward traffic's spread, not to certainty
                    spread = np.full(len(mix), -np.inf)
                    spread[idle] = f**2 * mix.covs[idle, 7, 7] + (1.0 - f**2) * motion.coast_acceleration_std**2
        pending_m, pending_p = self._pending
        if len(pending_m):  # last frame's cluster births join before the prediction (born at t_{k-1})
            mix = self._with_births(mix, pending_m, pending_p)
            self.stats["births_cluster"] += len(pending_m)
            self._pending = (np.zeros((0, self.dim)), np.zeros((0, self.dim, self.dim)))
            if relax is not None:
                relax = np.concatenate([relax, np.ones(len(pending_m))])
            if spread is not None:
                spread = np.concatenate([spread, np.full(len(pending_m), -np.inf)])
        jerk = floor = None
        if self.dim == 8 and self.config.motion.quiet_jerk is not None:
            jerk, floor = self._manoeuvre_jerk(mix)
        if spread is not None:
            floor = spread if floor is None else np.maximum(floor, spread)
        if dt > 0.0 and len(mix):
            means, covs = predict(self.ut, self.motion, mix.means, mix.covs, dt, jerk, relax, floor)
            mix = Mixture(mix.weights * self.config.detection.p_survival, means, covs, mix.labels)
        elif floor is not None:  # no time passed: only a manoeuvre's onset changes the acceleration
            mix = Mixture(mix.weights, *relax_acceleration(mix.means, mix.covs, None, floor), mix.labels)
        self.mixture = mix

    def _learn_width_error(self, ego: EgoState) -> None:
        """This frame's tracks (``_reported``) to the width-error estimator (``tracker.fleet``). Where its
        value changed, the config of the updates and the cluster births (``_sized``) takes it as
        ``BirthConfig.width_error_std``, and the components whose length is the vehicle classes' prior
        (its std above ``CLASS_PRIOR`` x ``BirthConfig.length_std``: no fit is that uncertain) on a
        measured width (std at most ``tracker.fleet.MEASURED_WIDTH_STD``) take the prior anew
        (``tracker.extent.class_prior_lengths_kernel``): it was drawn with the classes' widths read as
        bodies, and the extent rules move a held length only by more than its own spread."""
        rep = self._reported
        birth = self.config.birth
        if not len(rep) or birth.classes is None:
            return
        mix = self.mixture
        self.width_error.observe(mix.labels[rep], mix.means[rep], mix.covs[rep])
        error = self.width_error.value
        if error == self._sized.birth.width_error_std:
            return
        self._sized = dataclasses.replace(self.config, birth=dataclasses.replace(birth, width_error_std=error))
        self.stats["width_error_changes"] += 1
        rows = np.flatnonzero((mix.covs[:, LENGTH, LENGTH] > (CLASS_PRIOR * birth.length_std) ** 2)
                              & (mix.covs[:, WIDTH, WIDTH] <= MEASURED_WIDTH_STD**2))
        if len(rows):
            corners = to_vehicle(mix.means, ego, self.road, self.config.coordinates).corners()
            class_prior_lengths_kernel(mix.means, mix.covs, np.ascontiguousarray(corners), rows,
                                       *class_arrays(birth.classes, error), float(birth.length),
                                       float(birth.length_std) ** 2)
            self.stats["class_lengths_renewed"] += len(rows)

    def _pull_to_flow(self, dt: float, updated: set[int]) -> None:
        """The lane-flow prior (``tracker.flow``, ``MotionConfig.flow_speed_std``): the components of the
        tracks that nothing updated in the last frame (labels reported before, neither a cluster nor a
        radar detection in ``updated``) take the pseudo-measurement of their lane's speed, set by last
        frame's updated tracks and the ego (``_flow_sources``). Road coordinates only."""
        motion = self.config.motion
        mix = self.mixture
        if motion.flow_speed_std is None or dt <= 0.0 or self.cartesian or not len(mix) or not self._ever_reported:
            return
        idle = np.flatnonzero(_labels_in(mix.labels, self._ever_reported) & ~_labels_in(mix.labels, updated))
        if not len(idle):
            return
        seen = self._reported[_labels_in(mix.labels[self._reported], updated)]
        flow = flow_speeds(self.road, self._flow_sources(seen), mix.means[idle][:, :2], motion.flow_window)
        found = np.isfinite(flow)
        variance = motion.flow_speed_std**2 * motion.flow_time / dt
        pull_to_flow(mix.means, mix.covs, idle[found], flow[found], variance)
        self.stats["flow_pulls"] += int(found.sum())

    def _flow_sources(self, seen: np.ndarray) -> np.ndarray:
        """The seen vehicles of the lane flow (``tracker.flow.flow_speeds``), rows ``(s, n, v)``: the
        mixture's components ``seen`` and the ego."""
        return np.vstack([self.mixture.means[seen][:, :3], [self._ego_road]])

    def _manoeuvre_jerk(self, mix: Mixture) -> tuple[np.ndarray, np.ndarray | None]:
        """The manoeuvre-gated jerk (``MotionConfig.quiet_jerk``): per component, ``jerk`` while its
        label manoeuvres (an update moved it by more than ``manoeuvre_sigmas`` of the correction's
        expected spread within the last ``manoeuvre_hold`` s: ``_detect_manoeuvres``), else
        ``quiet_jerk``. The labels whose manoeuvre began in the last frame with a single large
        correction (an abrupt onset, not a steady lag: ``_detect_manoeuvres``) first have the
        acceleration's variance raised to at least the Singer model's stationary one, ``jerk^2
        acceleration_time / 2`` (only the diagonal entry: the covariance stays positive definite), so
        the filter takes a braking's onset at once instead of over the seconds the quiet jerk would need
        to build that spread. Returns the jerk per component and that variance floor per component
        (``-inf`` where none; None: no onset), which the prediction applies (``tracker.motion.predict``)."""
        motion = self.config.motion
        floor = None
        if self._manoeuvre_onset and len(mix):
            onset = _labels_in(mix.labels, self._manoeuvre_onset)
            if onset.any():
                floor = np.full(len(mix), -np.inf)
                floor[onset] = motion.jerk**2 * motion.acceleration_time / 2.0
        self._manoeuvre_onset = set()
        now = -math.inf if self.t is None else self.t - self._frame_dt  # the last frame's time
        self._manoeuvre_until = {lab: t for lab, t in self._manoeuvre_until.items() if t >= now}
        if motion.manoeuvre_memory is not None:  # a fading mean not updated for 10 time constants is ~0: forget it
            forget = now - 10.0 * motion.manoeuvre_memory
            self._manoeuvre_score = {lab: v for lab, v in self._manoeuvre_score.items() if v[0] >= forget}
        jerk = np.full(len(mix), motion.quiet_jerk)
        if self._manoeuvre_until and len(mix):
            jerk[_labels_in(mix.labels, self._manoeuvre_until)] = motion.jerk
        return jerk, floor

    def _detect_manoeuvres(self, prior_means: np.ndarray, prior_covs: np.ndarray, post_means: np.ndarray,
                           post_covs: np.ndarray, labels: np.ndarray, weights: np.ndarray) -> None:
        """Flag the labels an update moved unexpectedly (``MotionConfig.quiet_jerk``). Per label, its pair
        of highest posterior weight: the correction of ``s``, ``d = s_post - s_prior``, has the expected
        variance ``P_prior[s, s] - P_post[s, s]`` (the Kalman gain's ``K S K^T``), so ``z = d / sqrt(.)``
        is ~N(0, 1) while the label moves as predicted. A label manoeuvres when ``|z| >
        manoeuvre_sigmas`` (the rear of a car that starts braking moves against the quiet prediction at
        once, a frame before the speed's correction says so), or when the fading mean of its ``z``
        (``m = alpha m + (1 - alpha) z``, ``alpha = exp(-dt / manoeuvre_memory)``) leaves
        ``manoeuvre_sigmas`` of its own spread under no manoeuvre, ``sqrt((1 - alpha) / (1 + alpha))``: a
        steady lag, corrections of one sign frame after frame none of which is large alone (a gentle,
        drawn-out acceleration in queueing traffic). Flagging starts (or extends) the label's
        ``manoeuvre_hold`` seconds of full jerk; a label newly flagged by a single correction is an
        abrupt onset (``_manoeuvre_jerk`` raises its acceleration's variance). A steady lag does not
        raise it: it is flagged while the filter follows an acceleration it has learned (a car pulling
        away at 2 m/s^2), whose estimate the raise would discard."""
        motion = self.config.motion
        order = np.lexsort((-weights, labels))
        ordered = labels[order]
        head = np.ones(len(order), dtype=bool)
        np.not_equal(ordered[1:], ordered[:-1], out=head[1:])
        first = order[head]
        chosen = labels[first].tolist()
        d = self.wrapping.coordinate_residual(post_means[first, 0] - prior_means[first, 0], 0)
        z = d / np.sqrt(np.maximum(prior_covs[first, 0, 0] - post_covs[first, 0, 0], 1e-12))
        jump = np.abs(z) > motion.manoeuvre_sigmas
        moved = jump.copy()
        if motion.manoeuvre_memory is not None and self._frame_dt > 0.0:
            previous = np.array([self._manoeuvre_score.get(lab, (self.t - self._frame_dt, 0.0)) for lab in chosen])
            alpha = np.exp(-np.maximum(self.t - previous[:, 0], 0.0) / motion.manoeuvre_memory)
            fading = alpha * previous[:, 1] + (1.0 - alpha) * z
            self._manoeuvre_score.update(zip(chosen, zip([self.t] * len(chosen), fading.tolist())))
            a = math.exp(-self._frame_dt / motion.manoeuvre_memory)
            moved |= np.abs(fading) > motion.manoeuvre_sigmas * math.sqrt((1.0 - a) / (1.0 + a))
        until = self.t + motion.manoeuvre_hold
        for lab, abrupt in zip(labels[first][moved].tolist(), jump[moved].tolist()):
            if abrupt and lab not in self._manoeuvre_until:
                self._manoeuvre_onset.add(lab)
            self._manoeuvre_until[lab] = until

    def _add_births(self, ego: EgoState, s_ego: float, tracks: Rectangles, track_labels: np.ndarray) -> None:
        """Road births (``tracker.birth.road_births``), but none where ``tracks`` (rectangles in E, with
        their labels) hide at least half of it or lie within the gating distance."""
        cfg = self.config
        if not cfg.birth.road:
            return
        if not self.cartesian:  # a vehicle can enter the view only where it is not blocked and no track is
            means, covs = visible_road_births(self.road, s_ego, ego, cfg.detection.lidar_range, cfg.birth,
                                              self._acceleration_var(), tracks, track_labels, cfg.gating.distance)
        else:
            means, covs = road_births(self.road, s_ego, ego.v, cfg.detection.lidar_range, cfg.birth)
            means, covs = self._with_acceleration(*to_cartesian_gaussians(self.road, means, covs, self.ut))
            if len(means) and len(track_labels):
                keep = entering_view(to_vehicle(means, ego, self.road, cfg.coordinates), tracks, track_labels,
                                     cfg.gating.distance)
                means, covs = means[keep], covs[keep]
        self.mixture = self._with_births(self.mixture, means, covs)
        self.stats["births_road"] += len(means)

    def _with_births(self, mix: Mixture, means: np.ndarray, covs: np.ndarray) -> Mixture:
        """``mix`` with birth components ``means``, ``covs`` appended (weight ``birth.weight``, new labels)."""
        return Mixture(np.concatenate([mix.weights, np.full(len(means), self.config.birth.weight)]),
                       np.concatenate([mix.means, means]), np.concatenate([mix.covs, covs]),
                       np.concatenate([mix.labels, self._new_labels(len(means))]))

    def _preprocess(self, frame: Frame) -> tuple[np.ndarray, bool]:
        """Points kept for clustering, and whether the frame had any finite lidar point at all (of a
        3-D cloud: any point left after ground removal; ``last_cloud`` keeps the pipeline's result)."""
        self._scan, removed, self.last_cloud = lidar_points(frame, self.config.cloud)
        points, counts, self._point_n = filter_points(self._scan, frame.ego, self.road, self.config.clustering)
        if self.last_cloud is not None:  # a 3-D cloud: the occluders are the nearest return of each ray
            self._scan = nearest_per_ray(self._scan, self.config.detection.lidar_resolution)
        self._points = points
        self.stats.update(removed)
        self.stats.update(counts)
        return points, len(self._scan) > 0

    def _cluster(self, points: np.ndarray, frame: Frame, rect: Rectangles) -> tuple[list[np.ndarray], list[np.ndarray | None]]:
        """The frame's clusters (views of the points ordered by cluster) and their radar velocities (or
        None); sets ``_owned`` (each cluster's track group, or -1), ``_component_group`` (each
        component's track group, or -1) and ``_free_radar`` (the detections that joined no cluster).
        The grouping is ``_grouped_points``, the radar association
        ``tracker.clustering.cluster_radar_ranges``."""
        cfg = self.config.clustering
        self._hole_bounds = None
        if len(points):
            ordered, edges, owned = self._grouped_points(points, rect)
            if self._hole_bounds is not None:
                self._bound_at_holes(frame.ego)
        else:
            self._component_group = np.full(len(self.mixture), -1)
            ordered, edges, owned = np.zeros((0, 2)), np.zeros(1, dtype=np.int64), np.zeros(0, dtype=int)
        bounds = edges.tolist()
        clusters = [ordered[a:b] for a, b in zip(bounds[:-1], bounds[1:])]
        lo, hi = edges[:-1], edges[1:]
        if cfg.min_points > 1 and clusters:
            big = (hi - lo) >= cfg.min_points
            self.stats["clusters_too_small"] += int((~big).sum())
            clusters = [c for c, keep in zip(clusters, big.tolist()) if keep]
            owned, lo, hi = owned[big], lo[big], hi[big]
        else:
            self.stats["clusters_too_small"] += 0  # the counter exists from the first clustered frame on
        self._owned = owned
        if self.config.use_radar and clusters and len(frame.radar):
            velocities, self._free_radar = cluster_radar_ranges(ordered, lo, hi, frame.radar, frame.t, cfg.radar_gate)
        else:
            velocities = [None] * len(clusters)
            self._free_radar = np.arange(len(frame.radar))  # detections that joined no cluster
        self.stats["clusters"] += len(clusters)
        self.stats["clusters_fused"] += sum(v is not None for v in velocities)
        return clusters, velocities

    def _grouped_points(self, points: np.ndarray, rect: Rectangles) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The points grouped into clusters (``tracker.clustering.cluster_points_kernel``): points inside
        a reported track's predicted rectangle (plus ``clustering.track_margin`` along it and
        ``clustering.across_margin`` across it) go to its group
        (rectangles overlapping by more than ``clustering.duplicate_depth``, ``_duplicate_groups``, are
        one); a connected component
        (``_partition``) that a group owns in part joins it entirely; lone fragments may continue
        a track (``_fragments_adopted``, between the kernel's two halves); all points a group owns form
        one cluster, even in fragments (a partly hidden car), the other points one cluster per connected
        component; clusters wider across the road than one vehicle (``clustering.split_width``) are cut
        at their largest lateral gap (``clustering.split_gap``): two long vehicles side by side whose
        points the lidar sees as one line, or that a drifted track's rectangle owns together. The points'
        lateral offsets are the road-bound test's (``self._point_n``). Of a track-owned cluster cut in
        parts, the part with the most points inside the track's rectangle stays the track's; the others
        become free clusters (any track may take them in the update, else they seed births). Returns
        the points ordered by cluster (groups first, then components, then the cut parts; ties by
        index), the clusters' edges ``(K + 1,)`` in them and each cluster's group (or -1); sets
        ``_component_group`` and counts ``clusters_split``."""
        cfg = self.config.clustering
        tracks = self._reported
        labels = self.mixture.labels
        fragment = cfg.fragment_points is not None and len(tracks)
        split = cfg.split_width is not None
        head = (points, rect.center, np.cos(rect.psi), np.sin(rect.psi), rect.length, rect.width, float(cfg.track_margin),
                float(cfg.across_margin), rect.corners(), self._duplicate_depths(labels[tracks]), labels, labels[tracks],
                float(cfg.distance))
        tail = (self._point_n, int(cfg.fragment_points) if fragment else -1, split,
                float(cfg.split_width) if split else 0.0, float(cfg.split_gap), SPLIT_MAX_CUTS)
        # _PARTITION_HERE: the kernel partitions at the one distance itself; with the grazing rule, ray_partition
        partition = _PARTITION_HERE if cfg.grazing_angle is None else self._partition(points)
        ok, done, groups, owner, inside, component, component_group, ordered, edges, owned, added = cluster_points_kernel(
            *head, partition, *tail)
        if not ok:  # points the partition's grid does not hold: their components from the whole graph
            ok, done, groups, owner, inside, component, component_group, ordered, edges, owned, added = (
                cluster_points_kernel(*head, self._partition(points), *tail))
        self._component_group = component_group
        if not done:
            owner = self._fragments_adopted(points, rect, groups, component, owner)
            ordered, edges, owned, added = ordered_clusters_kernel(points, owner, inside, component, len(tracks),
                                                                   self._point_n, split,
                                                                   float(cfg.split_width) if split else 0.0,
                                                                   float(cfg.split_gap), SPLIT_MAX_CUTS)
        if added:
            self.stats["clusters_split"] += int(added)
        if cfg.along_gap is not None and len(tracks) and (owned >= 0).any():
            first = np.unique(groups, return_index=True)[1]  # per group, its first track
            axes = (rect.center[first], np.cos(rect.psi[first]), np.sin(rect.psi[first]))  # centre, heading
            ordered, edges, owned, cut, bounds = along_cuts_kernel(
                ordered, edges, owned, *axes, 0.5 * rect.length[first], 0.5 * rect.width[first], self._scan,
                float(self.config.detection.lidar_resolution), float(cfg.along_gap_rays), float(cfg.along_gap),
                float(self.config.measurement.shadow_margin), int(cfg.along_min_part))
            self.stats["clusters_cut_along"] += int(cut)
            if cut:
                self._hole_bounds = (bounds, *axes)
        else:
            self.stats["clusters_cut_along"] += 0  # the counter exists from the first clustered frame on
        return ordered, edges, owned

    def _partition(self, points: np.ndarray) -> np.ndarray:
        """The connected components of the frame's points (``tracker.clustering.ray_partition``)."""
        cfg = self.config.clustering
        return ray_partition(points, cfg.distance, cfg.grazing_angle, cfg.bearing_bin, cfg.grazing_max_gap)

    @property
    def _reported_labels(self) -> KeysView[int]:
        """The labels reported in the last frame (``_streak``'s keys)."""
        return self._streak.keys()

    def _duplicate_depths(self, track_labels: np.ndarray) -> np.ndarray:
        """Per last frame's track, the overlap (m) its predicted rectangle may have with another's and
        the two stay neighbours (``_duplicate_groups``): ``clustering.duplicate_depth`` for a track
        reported in at least ``ESTABLISHED_FRAMES`` frames in a row, 0 for a younger one (a new track
        beside an established one is more often a second hypothesis of its vehicle than a vehicle)."""
        depth = float(self.config.clustering.duplicate_depth)
        return np.array([depth if self._streak.get(lab, 0) >= ESTABLISHED_FRAMES else 0.0
                         for lab in track_labels.tolist()], dtype=float)

    def _bound_at_holes(self, ego: EgoState) -> None:
        """The components of the track groups whose clusters were cut along their length
        (``clustering.along_gap``) shortened to end at the seen free space of the cut, the end nearest
        the sensor staying put (``tracker.extent.bound_at_holes_kernel``, length variance at least
        ``birth.length_std`` squared); counted in ``components_shortened_at_holes``."""
        bounds, ctr, c, s = self._hole_bounds
        mix = self.mixture
        idx = np.flatnonzero(self._component_group >= 0)
        if len(idx) == 0:
            return
        means, covs = mix.means[idx], mix.covs[idx]
        corners = to_vehicle(means, ego, self.road, self.config.coordinates).corners()
        shortened = bound_at_holes_kernel(means, covs, corners, self._component_group[idx], ctr, c, s, bounds,
                                          float(self.config.birth.length_std) ** 2)
        if shortened:
            mix.means[idx], mix.covs[idx] = means, covs
        self.stats["components_shortened_at_holes"] += int(shortened)

    def _fragments_adopted(self, points: np.ndarray, rect: Rectangles, groups: np.ndarray, component: np.ndarray,
                           owner: np.ndarray) -> np.ndarray:
        """``owner`` with the lone fragments that continue a track's side past its predicted front
        (``clustering.fragment_points``; ``tracker.clustering.fragment_owners``) given to its group;
        counted in ``fragment_points_adopted``."""
        cfg = self.config.clustering
        tracks = self._reported
        sd = np.sqrt(np.maximum(self.mixture.covs[tracks, LENGTH, LENGTH], 0.0))
        held = np.zeros(int(groups.max()) + 1, dtype=bool)
        held[owner[owner >= 0]] = True  # the groups holding points this frame
        adopted = fragment_owners(points, component, owner < 0, rect.center, rect.psi, rect.length,
                                  rect.width, sd, cfg.track_margin, cfg.fragment_points, cfg.fragment_sigmas,
                                  held[groups], cfg.fragment_side_tolerance)
        taken = adopted >= 0
        if taken.any():
            self.stats["fragment_points_adopted"] += int(taken.sum())
            owner = np.where(taken, groups[np.maximum(adopted, 0)], owner)
        return owner

    def _update(self, ego: EgoState, clusters: list[np.ndarray], velocities: list[np.ndarray | None],
                rows: np.ndarray | None = None, open_clusters: np.ndarray | None = None) -> np.ndarray:
        """GM-PHD update; returns which clusters some component explained (a gated pair). With ``rows``
        (component indices) only those components are updated, and only with the clusters
        ``open_clusters`` (mask); the others pass unchanged (the second pass of ``_births_after_update``)."""
        cfg = self._sized
        mix = self.mixture
        explained = np.zeros(len(clusters), dtype=bool)
        if len(mix) == 0:
            return explained
        rect = to_vehicle(mix.means, ego, self.road, cfg.coordinates)
        occ = self._reported
        gamma, p_d = detection_model(
            rect, mix.labels, cfg.detection,
            rect.take(occ) if len(occ) else None, mix.labels[occ] if len(occ) else None,
            scan=self._scan,
        )
        missed_w = mix.weights * (1.0 - (1.0 - np.exp(-gamma)) * p_d)
        floor = cfg.detection.hidden_update_p_detection
        if floor is not None and self._ever_reported:
            # the tracks' components the occlusion model hides still pair with clusters (DetectionConfig)
            lift = _labels_in(mix.labels, self._ever_reported) & (p_d < floor) & (nearest_range(rect) <= cfg.detection.lidar_range)
            p_d = np.where(lift, floor, p_d)
        if rows is not None:  # the other components are not detected in this pass: their weights stand
            only = np.zeros(len(mix), dtype=bool)
            only[rows] = True
            p_d = np.where(only, p_d, 0.0)
            missed_w = np.where(only, missed_w, mix.weights)
        new_w, new_m, new_p, new_l = [missed_w], [mix.means], [mix.covs], [mix.labels]
        if clusters:
            # a cluster a track owns (its points lie in the track's predicted rectangle) is that track's:
            # only the components of the track's group compete for it, so a newborn or another
            # track's hypothesis cannot take it over when the track's own fit is poor for a frame
            comp, clu, size, offsets, points = self._pre_gated(rect, clusters, p_d, self._owned, self._component_group)
            if open_clusters is not None:
                keep = open_clusters[clu]
                comp, clu = comp[keep], clu[keep]
            cluster_size = size
            self.stats["pairs_pre_gated"] += len(comp)
            if len(comp):
                # a track's own cluster: its points lie in the track's predicted rectangle
                own = (self._owned[clu] >= 0) & (self._owned[clu] == self._component_group[comp])
                has_velocity = np.zeros(len(clusters), dtype=bool)
                velocity = np.zeros((len(clusters), 2))
                if cfg.use_radar:
                    for k, v in enumerate(velocities):
                        if v is not None:
                            has_velocity[k], velocity[k] = True, v
                    if rows is None:  # once per frame (not again in the second pass of births after the update)
                        self._turn_to_courses(rect, comp[own], velocity[clu[own]], has_velocity[clu[own]])
                res, occluded, continued = update_clusters(mix.means, mix.covs, points, offsets, velocity, has_velocity,
                                                           comp, clu, self._scan, ego, self.road, cfg, self.ut)
                if occluded is not None:  # MeasurementConfig.shadow_window
                    self.stats["cluster_ends_occluded"] += occluded
                if continued is not None:
                    self.stats["cluster_ends_continued"] += continued
                rejected = res.radar_rejected
                self.stats["radar_velocities_rejected"] += len(np.unique(clu[rejected])) if rejected.any() else 0
                inside = res.nis <= self._gate_table[np.minimum(res.dim, len(self._gate_table) - 1)]
                # a track's own cluster is associated by geometry: it updates the track even when the
                # model fits it badly (a manoeuvre, partial occlusion), instead of the track coasting on
                # a stale prediction until it is lost
                self.stats["own_clusters_past_gate"] += int((own & ~inside).sum())
                inside |= own
                comp, clu = comp[inside], clu[inside]
                self.stats["pairs_updated"] += len(comp)
                pair_labels = mix.labels[comp]
                labels_list = pair_labels.tolist()
                self._updated_labels.update(labels_list)
                if len(comp):
                    size = size[clu]
                    support = size
                    if cfg.reduction.confirm_radar_point:  # a radar velocity the pair's update used is a second sensor's detection
                        joined = has_velocity[clu] if rejected is None else has_velocity[clu] & ~rejected[inside]
                        support = size + joined
                    for lab, n_pts in zip(labels_list, support.tolist()):
                        if n_pts > self._support.get(lab, 0):
                            self._support[lab] = n_pts
                    lam_c = cfg.detection.clutter_rate * cfg.detection.clutter_density
                    log_num = (
                        np.log(np.maximum(p_d[comp], 1e-300)) + np.log(np.maximum(mix.weights[comp], 1e-300))
                        - gamma[comp] + size * np.log(gamma[comp])
                        + res.log_likelihood[inside] - size * math.log(lam_c)
                    )
                    explained[clu] = True
                    # normalise per cluster in the log domain; a single-point cluster's denominator
                    # also holds delta_{|W|,1} = 1 (log 0), the clutter alternative
                    single = cluster_size == 1
                    peak = np.full(len(clusters), -np.inf)
                    peak[single] = 0.0
                    np.maximum.at(peak, clu, log_num)
                    scaled = np.exp(log_num - peak[clu])
                    total = np.bincount(clu, weights=scaled, minlength=len(clusters))
                    total += np.where(single, np.exp(-np.clip(peak, -700.0, 700.0)), 0.0)
                    weights = scaled / total[clu]
                    # the UKF's posterior is a covariance only when the sigma points represent the prior;
                    # after a long gap (heading spread over the circle, wrapped residuals) it may not be:
                    # lift such matrices to positive definite and count them
                    post_cov, repaired = ensure_spd(res.cov[inside], cfg.ukf.min_eigenvalue)
                    self.stats["covariances_repaired"] += repaired
                    post_mean = res.mean[inside]
                    if cfg.detection.missed_weight_cap:
                        new_w[0] = cap_missed_weights(missed_w, mix.labels, weights, pair_labels)
                    if self.dim == 8 and cfg.motion.quiet_jerk is not None:
                        self._detect_manoeuvres(mix.means[comp], mix.covs[comp], post_mean, post_cov, pair_labels,
                                                weights)
                    self._strong_labels.update(pair_labels[weights > cfg.reduction.extraction_threshold].tolist())
                    new_w.append(weights)
                    new_m.append(post_mean)
                    new_p.append(post_cov)
                    new_l.append(pair_labels)
        self.mixture = Mixture(np.concatenate(new_w), np.concatenate(new_m), np.concatenate(new_p), np.concatenate(new_l))
        return explained

    def _update_by_radar(self, frame: Frame) -> None:
        """Radar-only updates (``tracker.radar_update``) of the components of tracks (labels reported
        before) that no cluster updated in this frame, by the detections that joined no cluster."""
        mix = self.mixture
        if not len(mix) or not len(self._free_radar) or not self._ever_reported:
            return
        updated = _labels_in(mix.labels, self._updated_labels)
        coasting = np.flatnonzero(_labels_in(mix.labels, self._ever_reported) & ~updated)
        if not len(coasting):
            return
        free = self._free_radar
        xy = frame.radar.positions_at(frame.t, free)
        if len(self._points):
            # a detection next to lidar returns is of a vehicle the lidar sees (the second cycle's
            # detection of a tracked car, a car not yet confirmed): its points speak for it
            # (a few detections against the frame's points: one (F, N) pass, no tree to build)
            gap2 = np.min((self._points[None, :, 0] - xy[:, None, 0]) ** 2 + (self._points[None, :, 1] - xy[:, None, 1]) ** 2,
                          axis=1)
            clear = gap2 > RADAR_ONLY_CLEARANCE**2
            free, xy = free[clear], xy[clear]
        seen = np.flatnonzero(updated & (mix.weights > self.config.reduction.extraction_threshold))
        if len(seen):
            # a detection on (or next to) a vehicle that its points updated in this frame is that vehicle's
            rect = to_vehicle(mix.means[seen], frame.ego, self.road, self.config.coordinates)
            free = free[points_in_rectangles(xy, rect.center, rect.psi, rect.length, rect.width,
                                             self.config.clustering.track_margin) < 0]
        res = update_coasting(mix.means, mix.covs, coasting, frame.radar, free, frame.t, frame.ego,
                              self.road, self.config, self.ut, mix.labels)
        if len(res.component):
            post_cov, repaired = ensure_spd(res.cov, self.config.ukf.min_eigenvalue)
            self.stats["covariances_repaired"] += repaired
            mix.means[res.component] = res.mean
            mix.covs[res.component] = post_cov
            self.stats["radar_only_updates"] += len(res.component)
            self._radar_updated.update(int(lab) for lab in mix.labels[res.component])

    def _turn_to_courses(self, rect: Rectangles, comp: np.ndarray, velocity: np.ndarray, has_velocity: np.ndarray) -> None:
        """Components ``comp`` paired with their track's own cluster, whose radar velocity is
        ``velocity (P, 2)`` where ``has_velocity (P,)``: those whose course lies at nearly a right angle
        to their heading, their label's in ``TURN_FRAMES`` consecutive frames, and whose part along the
        heading agrees with their speed (``tracker.course.agrees_along``), are turned by the quarter turn
        nearer that course, in place, before the update (``tracker.course``;
        ``BirthConfig.crossing_min_speed``); counted in ``stats["turned_to_radar_course"]``."""
        min_speed = self._sized.birth.crossing_min_speed
        if min_speed is None:
            return
        mix = self.mixture
        comp, vel = comp[has_velocity], velocity[has_velocity]
        psi = rect.psi[comp]
        course = crossing_courses(vel, psi, min_speed, TURN_TOLERANCE)
        cross = ~np.isnan(course)
        cross[cross] = agrees_along(mix.means[comp[cross], V], mix.covs[comp[cross], V, V], psi[cross],
                                    vel[cross], self._sized.measurement.radar_velocity_sigma**2)
        frame = self.stats["frames"]
        last = self._crossing_frames  # label -> (last frame with a crossing course, consecutive frames to it)
        shown: dict[int, tuple[int, int]] = {}
        for k in np.flatnonzero(cross).tolist():  # the few components showing a crossing course
            label = int(mix.labels[comp[k]])
            before, count = last.get(label, (-2, 0))
            shown[label] = (frame, count + 1 if before == frame - 1 else 1)
            if shown[label][1] >= TURN_FRAMES:
                turn_to_course(mix.means[comp[k]], mix.covs[comp[k]], float(psi[k]), float(course[k]),
                               float(np.hypot(*vel[k])), self._sized.birth.speed_std**2)
                self.stats["turned_to_radar_course"] += 1
        self._crossing_frames = shown

    def _plan_cluster_births(self, ego: EgoState, clusters: list[np.ndarray], velocities: list[np.ndarray | None], explained: np.ndarray) -> None:
        """Clusters that no component explained and that lie outside every reported track's rectangle
        seed births for the next frame (a cluster inside a track's rectangle that failed its gate is
        that track's, badly predicted, not a new vehicle)."""
        self._pending = self._cluster_births(ego, clusters, velocities, explained)

    def _cluster_births(self, ego: EgoState, clusters: list[np.ndarray], velocities: list[np.ndarray | None],
                        explained: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Birth components (means, covariances) of the clusters neither ``explained`` nor owned by a track."""
        idle = [k for k in range(len(clusters)) if not explained[k] and self._owned[k] < 0]
        if not idle:
            return np.zeros((0, self.dim)), np.zeros((0, self.dim, self.dim))
        points = [clusters[k] for k in idle]
        means, covs = cluster_births(points, [velocities[k] if self.config.use_radar else None for k in idle],
                                     ego, self.road, self._sized.birth, self._shadowed_ends(points),
                                     self._birth_flow(ego, points))
        if self.cartesian:
            means, covs = to_cartesian_gaussians(self.road, means, covs, self.ut)
        return self._with_acceleration(means, covs)

    def _birth_flow(self, ego: EgoState, points: list[np.ndarray]) -> list[tuple[float, float] | None] | None:
        """Per cluster ``points`` (E), the prior speed and std of its birth without a radar velocity: its
        lane's flow (``tracker.flow``) at the cluster's centroid, from this frame's updated tracks and the
        ego (``MotionConfig.flow_window``), with the std ``BirthConfig.flow_speed_std``; None where no seen
        vehicle is near in its lane (the ego's speed then, ``BirthConfig.speed``). None with
        ``BirthConfig.flow_speed_std`` None, in the Cartesian variant, or with ``BirthConfig.speed`` set."""
        motion, birth = self.config.motion, self.config.birth
        if birth.flow_speed_std is None or self.cartesian or not points or birth.speed is not None:
            return None
        mix = self.mixture
        seen = np.flatnonzero(_labels_in(mix.labels, self._updated_labels)
                              & (mix.weights > self.config.reduction.extraction_threshold))
        centroid = to_global(np.array([p.mean(axis=0) for p in points]), (ego.x, ego.y), ego.yaw)
        s, n = self.road.to_frenet(centroid)
        flow = flow_speeds(self.road, self._flow_sources(seen), np.column_stack([np.atleast_1d(s), np.atleast_1d(n)]),
                           motion.flow_window)
        return [None if not np.isfinite(v) else (float(v), float(birth.flow_speed_std)) for v in flow]

    def _births_now(self, ego: EgoState, clusters: list[np.ndarray], velocities: list[np.ndarray | None],
                    skip: np.ndarray) -> np.ndarray:
        """Births of this frame's clusters (but those in ``skip`` and those a track owns) that join the
        mixture now, before this frame's update: the births the next frame would have had, one frame
        earlier (``BirthConfig.first_scan``, ``BirthConfig.same_frame``). Returns their indices in the
        mixture."""
        means, covs = self._cluster_births(ego, clusters, velocities, skip)
        born = np.arange(len(self.mixture), len(self.mixture) + len(means))
        if len(means):
            self.mixture = self._with_births(self.mixture, means, covs)
        return born

    def _births_after_update(self, ego: EgoState, clusters: list[np.ndarray], velocities: list[np.ndarray | None],
                             explained: np.ndarray) -> np.ndarray:
        """``BirthConfig.after_update_points``: the clusters of ``min_cluster_points`` to that many points
        that this frame's update left ``explained`` by no component, that no track owns and that no
        coasting track (reported before, not updated this frame) reaches with its pre-gate, are born
        (``_births_now``) and updated in a second pass that updates only those births with only those
        clusters. Returns which clusters the births explained."""
        size = np.array([len(c) for c in clusters])
        birth = self.config.birth
        open_clusters = (~explained & (self._owned < 0) & (size >= birth.min_cluster_points)
                         & (size <= birth.after_update_points))
        if not open_clusters.any():
            return np.zeros(len(clusters), dtype=bool)
        mix = self.mixture
        coasting = _labels_in(mix.labels, self._ever_reported) & ~_labels_in(mix.labels, self._updated_labels)
        open_clusters &= ~self._reached(ego, clusters, coasting)
        if not open_clusters.any():
            return np.zeros(len(clusters), dtype=bool)
        born = self._births_now(ego, clusters, velocities, ~open_clusters)
        self.stats["births_after_update"] += len(born)
        if not len(born):
            return np.zeros(len(clusters), dtype=bool)
        # the first update's posteriors and the births belong to no track group
        grown = len(self.mixture) - len(self._component_group)
        self._component_group = np.concatenate([self._component_group, np.full(grown, -1)])
        return self._update(ego, clusters, velocities, born, open_clusters)

    def _reached(self, ego: EgoState, clusters: list[np.ndarray], among: np.ndarray | None = None) -> np.ndarray:
        """Per cluster, whether some component of the mixture (``among``: a mask of the components that
        count; all by default) could explain it: its centroid within the update's pre-gate
        (``gating.distance`` of the circle around the component's rectangle)."""
        mix = self.mixture
        if not len(mix):
            return np.zeros(len(clusters), dtype=bool)
        rect = to_vehicle(mix.means, ego, self.road, self.config.coordinates)
        which = np.ones(len(mix)) if among is None else among.astype(float)
        clu = self._pre_gated(rect, clusters, which, np.full(len(clusters), -1), np.full(len(mix), -1))[1]
        reached = np.zeros(len(clusters), dtype=bool)
        reached[clu] = True
        return reached

    def _pre_gated(self, rect: Rectangles, clusters: list[np.ndarray], p_d: np.ndarray, owned: np.ndarray,
                   group: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The update's pre-gate (``GatingConfig.distance``): the (component, cluster) pairs of the
        components' rectangles ``rect`` and ``clusters`` that ``_candidate_pairs`` tries (with ``p_d``,
        ``owned``, ``group`` as there), and the clusters stacked: their sizes (K,), offsets (K + 1,)
        and points."""
        size = np.array([len(c) for c in clusters])
        offsets = np.zeros(len(size) + 1, dtype=np.intp)
        np.cumsum(size, out=offsets[1:])
        points = np.concatenate(clusters)
        reach = self.config.gating.distance + 0.5 * np.hypot(rect.length, rect.width)
        comp, clu = _candidate_pairs(rect.center, reach, points, offsets, p_d, owned, group)
        return comp, clu, size, offsets, points

    def _shadowed_ends(self, clusters: list[np.ndarray]) -> list[tuple[np.ndarray, np.ndarray] | None] | None:
        """Per cluster, its end in bearing that borders another object's shadow and its free end, where
        exactly one end does (None without the shadow flags)."""
        mcfg, det = self.config.measurement, self.config.detection
        if not (mcfg.shadow_window is not None and clusters and len(self._scan)):
            return None
        ends = bearing_extremes(clusters)
        occ = occluded_ends(ends, self._scan, mcfg.shadow_window * det.lidar_resolution, mcfg.shadow_margin,
                            det.lidar_range, mcfg.shadow_range_margin)
        one = occ[:, 0] != occ[:, 1]
        self.stats["births_shadowed"] += int(one.sum())
        return [(e[0], e[1]) if o[0] else (e[1], e[0]) if k else None for e, o, k in zip(ends, occ, one)]

    def _with_acceleration(self, means: np.ndarray, covs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Birth components ``(B, 7)`` with the acceleration state appended when the motion model has
        one (``a = 0``, std ``MotionConfig.acceleration_std``)."""
        return with_acceleration(means, covs, self._acceleration_var())

    def _acceleration_var(self) -> float | None:
        """The birth components' acceleration variance (``MotionConfig.acceleration_std`` squared; None
        without the acceleration state)."""
        return self.config.motion.acceleration_std ** 2 if self.dim == 8 else None

    def _reduce(self, ego: EgoState) -> None:
        """Targets that left the field of view (the range of the rectangle's nearest corner beyond the
        lidar's range and ``fov_margin``) or the road (the centre's lateral offset beyond an edge by
        ``road_margin``, or past an open road's end by as much: only objects on the road are tracked, the
        paper) are no longer tracked; the
        rest is pruned, merged and capped (``reduction.reduce_in_view``), ``s`` taken modulo a closed
        road's length; then ``_drop_inside_updated`` and ``absorb_overlapping``."""
        red = self.config.reduction
        mix = self.mixture
        s_period = self.road.length if self.road.closed and not self.cartesian else None
        if len(mix):
            rect = to_vehicle(mix.means, ego, self.road, self.config.coordinates)
            self.mixture, left_view, off_road = reduce_in_view(
                mix, nearest_range(rect), self.config.detection.lidar_range + red.fov_margin, *self._lateral(mix.means, red.road_margin),
                prune_threshold=red.prune_threshold, merge_gate=red.merge_threshold, max_components=red.max_components,
                wrapping=self.wrapping, same_label_distance=red.same_label_distance,
                same_label_min_weight=red.extraction_threshold, same_label_along_length=red.same_label_along_length,
                s_period=s_period)
            self.stats["components_left_view"] += left_view
            self.stats["components_off_road"] += off_road
        else:
            self.mixture = reduce(
                mix, prune_threshold=red.prune_threshold, merge_gate=red.merge_threshold,
                max_components=red.max_components, wrapping=self.wrapping,
                same_label_distance=red.same_label_distance, same_label_min_weight=red.extraction_threshold,
                same_label_along_length=red.same_label_along_length,
            )
        if red.drop_inside_updated and self._strong_labels and len(self.mixture):
            self._drop_inside_updated(ego)
        if red.absorb_overlap is not None and len(self.mixture) > 1:
            self.mixture, absorbed = absorb_overlapping(self.mixture, red.extraction_threshold, red.absorb_overlap,
                                                        self.wrapping, self.cartesian, self._reported_labels,
                                                        self._strong_labels)
            self.stats["labels_absorbed_overlapping"] += absorbed

    def _drop_inside_updated(self, ego: EgoState) -> None:
        """``ReductionConfig.drop_inside_updated``: drop the components of labels without a reportable
        posterior in this frame (none above the extraction threshold) whose centre lies inside the
        rectangle of another label's reportable posterior: a duplicate of the seen vehicle, whether no
        cluster updated it or its vehicle's cluster did, weakly, beside the track that took it (the
        centres inside the rectangles as ``points_in_rectangles`` finds them, margin 0:
        ``tracker.reduction.inside_updated_kernel``)."""
        mix = self.mixture
        updated = _labels_in(mix.labels, self._strong_labels)
        seen = updated & (mix.weights > self.config.reduction.extraction_threshold)
        if not seen.any() or updated.all():
            return
        rect = to_vehicle(mix.means, ego, self.road, self.config.coordinates)
        seen, idle = np.flatnonzero(seen), np.flatnonzero(~updated)
        psi = rect.psi[seen]
        keep, dropped = inside_updated_kernel(rect.center, np.cos(psi), np.sin(psi), rect.length, rect.width, seen, idle)
        if dropped:
            self.stats["components_inside_updated_dropped"] += dropped
            self.mixture = mix.take(keep)

    def _lateral(self, means: np.ndarray, margin: float) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray]]:
        """Lateral road offset ``n`` (m) of state means (projected for the Cartesian state), and the road's
        edges at their ``s`` widened by ``margin`` (m): ``(n, (right - margin, left + margin))``; on an open
        road, none (an empty interval) beyond its ends widened by ``margin``."""
        if not self.cartesian:
            s, n = means[:, 0], means[:, 1]
        else:
            s, n = self.road.to_frenet(means[:, :2])
            s, n = np.asarray(s).reshape(-1), np.asarray(n).reshape(-1)
        right, left = self.road.edges(s)
        if not self.road.closed:  # past an open road's ends is off the road too: no edges there
            beyond = (s < -margin) | (s > self.road.length + margin)
            right, left = np.where(beyond, np.inf, right), np.where(beyond, -np.inf, left)
        return n, (right - margin, left + margin)

    def _extract(self, t: float, ego: EgoState) -> list[Track]:
        """This frame's tracks (in decreasing weight, but a split label's continuation, ``_continuation_first``,
        before its other components; ``_reported`` their mixture indices): the components
        above ``extraction_threshold`` (and those ``_kept_below_threshold``) whose centre lies within
        ``detection.lidar_range + report_range`` of the ego and within the road's edges widened by
        ``report_road_margin``, whose position's std is at most ``report_position_std``, of labels
        reported before or confirmed by a cluster of ``confirm_min_points`` points, re-identified (``_reidentify``), a label's second
        component relabelled (a split target); the lost-track store observes them. The few components'
        weights and labels are handled as Python lists (one numpy call per array, not per test)."""
        mix = self.mixture
        red = self.config.reduction
        weights = mix.weights.tolist()
        labels = mix.labels.tolist()
        threshold = red.extraction_threshold
        above = [i for i, w in enumerate(weights) if w > threshold]
        if red.keep_threshold is not None and self._reported_labels:
            above += self._kept_below_threshold(above, weights, labels)
        if above and red.report_range is not None:  # the field of view tracks are reported in
            centre = _centres(mix.means, np.array(above, dtype=np.intp), ego, self.road, self.config.coordinates)
            inside = (np.hypot(centre[:, 0], centre[:, 1])
                      <= self.config.detection.lidar_range + red.report_range).tolist()
            self.stats["tracks_beyond_report_range"] += inside.count(False)
            above = [i for i, ok in zip(above, inside) if ok]
        if above and red.report_road_margin is not None:  # on the road: the tracker's targets
            n, (right, left) = self._lateral(mix.means[np.array(above, dtype=np.intp)], red.report_road_margin)
            on_road = ((n >= right) & (n <= left)).tolist()
            self.stats["tracks_off_road_unreported"] += on_road.count(False)
            above = [i for i, ok in zip(above, on_road) if ok]
        if above and red.report_position_std is not None:  # where it is known: a position to report
            block = mix.covs[np.array(above, dtype=np.intp), :2, :2]
            known = (block[:, 0, 0] + block[:, 1, 1] <= red.report_position_std**2).tolist()
            self.stats["tracks_uncertain_unreported"] += known.count(False)
            above = [i for i, ok in zip(above, known) if ok]
        # decreasing weight, ties in index order (a stable sort's reverse keeps equal keys in order)
        above.sort(key=weights.__getitem__, reverse=True)
        # a label not reported before needs the support of a large enough cluster (confirm_min_points)
        need = red.confirm_min_points
        if need > 1:
            ever, support = self._ever_reported, self._support
            confirmed = [i for i in above if labels[i] in ever or support.get(labels[i], 0) >= need]
            self.stats["births_awaiting_support"] += len(above) - len(confirmed)
            above = confirmed
            alive = set(labels)
            if not support.keys() <= alive:  # forget the support of labels no component carries
                for lab in [lab for lab in support if lab not in alive]:
                    del support[lab]
        keep = self._reidentify(t, above, labels)
        if keep is not None:  # labels changed
            if not keep.all():  # a newcomer took over a coasting track: the track's components go
                chosen = np.array(above, dtype=np.intp)
                self.stats["coasting_tracks_taken_over"] += int(len(np.unique(mix.labels[chosen][~keep[chosen]])))
                position = np.cumsum(keep) - 1
                above = position[chosen[keep[chosen]]].tolist()
                self.mixture = mix = mix.take(keep)
                weights = mix.weights.tolist()
            labels = mix.labels.tolist()
        reported = [labels[i] for i in above]
        seen = set(reported)
        if len(seen) < len(reported) and red.drop_unseen_branches and len(self._points):
            above = self._without_unseen_branches(above, labels, ego)
            reported = [labels[i] for i in above]
            seen = set(reported)
        if len(seen) < len(reported):  # one label per frame: a second component is a split target
            above = self._continuation_first(above, labels)
            reported = [labels[i] for i in above]
            seen = set()
            for k, i in enumerate(above):
                old = labels[i]
                if old in seen:
                    mix.labels[i] = self._new_labels(1)[0]
                    labels[i] = reported[k] = int(mix.labels[i])
                    self._support[labels[i]] = self._support.get(old, 0)
                    self.stats["label_splits"] += 1
                seen.add(labels[i])
        index = np.array(above, dtype=np.intp)
        self._reported = index
        self._streak = {lab: self._streak.get(lab, 0) + 1 for lab in reported}
        means, covs = mix.means[index], mix.covs[index]
        updated = self._updated_labels
        self._lost.observe(t, reported, means, covs, [lab in updated for lab in reported])
        if not self.cartesian:
            if means.shape[1] != 7:
                means, covs = means[:, :7], covs[:, :7, :7]
            return Track.checked_batch(reported, t, means, covs, [weights[i] for i in above])
        return [Track.from_cartesian(int(mix.labels[i]), t, mix.means[i], mix.covs[i], self.road, float(mix.weights[i]),
                                     self.ut) for i in above]

    def _without_unseen_branches(self, above: list[int], labels: list[int], ego: EgoState) -> list[int]:
        """``above`` without, of each label held by several components, those whose rectangle (grown by
        ``clustering.track_margin``) holds none of this frame's lidar points while another of the label's
        does (``reduction.drop_unseen_branches``): the label's hypothesis that its vehicle went
        undetected, where its points show it elsewhere, is the same vehicle, not a second one (a split
        target). A far vehicle's label keeps most of its weight in that hypothesis (few expected points,
        a small detection probability), so it can stay above the threshold metres from the vehicle."""
        count = Counter(labels[i] for i in above)
        shared = [k for k, i in enumerate(above) if count[labels[i]] > 1]
        rect = to_vehicle(self.mixture.means[np.array([above[k] for k in shared], dtype=np.intp)], ego, self.road,
                          self.config.coordinates)
        margin = self.config.clustering.track_margin
        holds = {}
        for j, k in enumerate(shared):
            inside = points_in_rectangles(self._points, rect.center[j:j + 1], rect.psi[j:j + 1], rect.length[j:j + 1],
                                          rect.width[j:j + 1], margin)
            holds[k] = bool((inside >= 0).any())
        seen_labels = {labels[above[k]] for k in shared if holds[k]}
        keep = [i for k, i in enumerate(above) if holds.get(k, True) or labels[i] not in seen_labels]
        self.stats["unseen_branches_unreported"] += len(above) - len(keep)
        return keep

    def _continuation_first(self, above: list[int], labels: list[int]) -> list[int]:
        """``above`` (in decreasing weight) with, of each label held by several components, the heaviest
        that continues the label's track first: a component within ``gating.distance`` (m) of where the
        track reported last frame would be now at its speed. It keeps the label; the others are split
        targets. A label's stale low-weight hypothesis far from its track that a cluster of another
        vehicle lifted (every pair's weight is normalised per cluster, so it may tie with the track's
        own) is another vehicle, not the track; where none or all continue the track, the heaviest keeps
        the label."""
        groups: dict[int, list[int]] = {}
        for k, i in enumerate(above):
            groups.setdefault(labels[i], []).append(k)
        order = list(range(len(above)))
        mix, dt, gate = self.mixture, self._frame_dt, float(self.config.gating.distance)
        for lab, ks in groups.items():
            last = self._lost.last_reported(lab) if len(ks) > 1 else None
            if last is None:
                continue
            mean = last[0]
            if self.cartesian:
                now = mean[:2] + mean[2] * dt * np.array([math.cos(mean[3]), math.sin(mean[3])])
            else:
                now = np.array([mean[0] + mean[2] * dt, mean[1]])
            r = mix.means[[above[k] for k in ks], :2] - now
            if not self.cartesian:
                r[:, 0] = self.road.s_difference(r[:, 0], 0.0)
            near = np.hypot(r[:, 0], r[:, 1]) <= gate
            if near.any() and not near[0]:
                first, best = ks[0], ks[int(np.argmax(near))]
                order[first], order[best] = order[best], order[first]
        return [above[k] for k in order]

    def _kept_below_threshold(self, above: list[int], weights: list[float], labels: list[int]) -> list[int]:
        """Components below ``extraction_threshold`` still reported (``ReductionConfig.keep_threshold``):
        per label reported last frame without a component among ``above`` (the indices above the
        threshold) now, its heaviest component (the first in index order among equal weights) if it
        weighs more than ``keep_threshold``. ``weights`` and ``labels`` are the mixture's, as lists;
        returns the chosen indices in increasing order."""
        red = self.config.reduction
        keep, threshold = red.keep_threshold, red.extraction_threshold
        low = [i for i, w in enumerate(weights) if keep < w <= threshold]
        if not low:
            return low
        low.sort(key=weights.__getitem__, reverse=True)  # decreasing weight, ties in index order
        taken = {labels[i] for i in above}
        reported = self._reported_labels
        best: dict[int, int] = {}
        for i in low:
            lab = labels[i]
            if lab in reported and lab not in taken and lab not in best:
                best[lab] = i
        self.stats["tracks_kept_below_threshold"] += len(best)
        return sorted(best.values())

    def _reidentify(self, t: float, above: list[int], labels: list[int]) -> np.ndarray | None:
        """Components about to be reported (``above``; ``labels`` the mixture's labels as a list) under
        a label never reported before take the label of a recently lost track, or of a reported track
        that coasts this frame, that they match (``tracker.identity.LostTracks``), with all their label's
        components; the old track's own components (a coasting track's, or a lost track's remaining
        low-weight hypotheses) are dropped. Returns the mask of components kept, or None when no
        component is about to be reported under a new label (nothing changes)."""
        ever = self._ever_reported
        new = [i for i in above if labels[i] not in ever]
        if not new:
            return None
        mix = self.mixture
        keep = np.ones(len(mix), dtype=bool)
        coasting = [i for i in above if labels[i] in ever and labels[i] not in self._updated_labels]
        if self.config.reduction.reidentify_window <= 0.0:
            coasting = []
        coasting_index = np.array(coasting, dtype=np.intp)
        old = self._lost.match(t, mix.means[new], mix.covs[new],
                               (mix.labels[coasting_index], mix.means[coasting_index], mix.covs[coasting_index]),
                               mix.labels[above])
        for i, lab in zip(new, old):
            if lab < 0:
                continue
            newcomer = int(mix.labels[i])
            keep &= mix.labels != lab  # the old track's hypotheses: a coasting track's, a lost one's low-weight ones
            mix.labels[mix.labels == newcomer] = lab
            self._support[int(lab)] = max(self._support.get(int(lab), 0), self._support.pop(newcomer, 0))
            self.stats["labels_reidentified"] += 1
        return keep

    def _record_events(self, previous: list[int], tracks: list[Track]) -> None:
        """``last_events`` of this step, by label: ``born`` (tracks reported for the first time),
        ``updated`` (reported tracks a cluster updated), ``missed`` (last frame's tracks no cluster
        updated), ``dropped`` (last frame's tracks with no component left: left the view or the road,
        pruned, or merged into another component), ``merged`` (not separated from ``dropped``: empty)."""
        reported = [tr.label for tr in tracks]
        alive = set(self.mixture.labels.tolist())
        self.last_events = {
            "born": [lab for lab in reported if lab not in self._ever_reported],
            "updated": [lab for lab in reported if lab in self._updated_labels],
            "missed": [lab for lab in previous if lab not in self._updated_labels],
            "dropped": [lab for lab in previous if lab not in alive],
            "merged": [],
        }
        self._ever_reported.update(reported)

    def _new_labels(self, count: int) -> np.ndarray:
        labels = np.arange(self._next_label, self._next_label + count)
        self._next_label += count
        return labels


def _centres(means: np.ndarray, index: np.ndarray, ego: EgoState, road: Road, coordinates: str) -> np.ndarray:
    """The rectangle centres ``(K, 2)`` in E of the states ``means[index]``: ``to_vehicle(...).center``,
    for curvilinear states by one compiled call (``tracker.extraction.report_centres_kernel``, which
    computes them with ``to_vehicle``'s kernel); Cartesian states, no rows and a non-finite ``s`` (whose
    error ``to_vehicle`` raises) take ``to_vehicle``."""
    if coordinates == "curvilinear" and len(index):
        kind, *curve = road._curve.kernel_args()
        means = means if means.flags.c_contiguous else np.ascontiguousarray(means)
        centre, finite = report_centres_kernel(kind, means, index, float(ego.x), float(ego.y), float(ego.yaw),
                                               road.closed, road.length, road._ends_array, *curve, MIN_EXTENT)
        if finite:
            return centre
    return to_vehicle(means[index], ego, road, coordinates).center  # (with a non-finite s: its error)


def _labels_in(labels: np.ndarray, chosen: Container[int]) -> np.ndarray:
    """Whether each of ``labels`` is in ``chosen`` (a set or dict that grows with the run: one lookup
    per label, not an ``isin`` over it)."""
    return np.fromiter(map(chosen.__contains__, labels.tolist()), dtype=bool, count=len(labels))


def _candidate_pairs(center: np.ndarray, reach: np.ndarray, points: np.ndarray, offsets: np.ndarray,
                     p_d: np.ndarray, owned: np.ndarray, group: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The (component, cluster) pairs the update tries, row-major: the component's rectangle centre
    ``center`` within ``reach`` (m) of the centroid of cluster ``k`` (``points[offsets[k]:offsets[k + 1]]``,
    non-empty), ``p_d > 0``, and the cluster either owned by no track (``owned < 0``) or by the
    component's track group ``group`` (one compiled call, ``tracker.gating.candidate_pairs_kernel``)."""
    centroid = np.add.reduceat(points, offsets[:-1]) / np.diff(offsets)[:, None]
    return candidate_pairs_kernel(np.ascontiguousarray(center, dtype=float), np.ascontiguousarray(reach, dtype=float),
                                  centroid, np.ascontiguousarray(p_d, dtype=float),
                                  np.ascontiguousarray(owned, dtype=np.int64), np.ascontiguousarray(group, dtype=np.int64))


def _duplicate_groups(rect: Rectangles, depth: np.ndarray | float = 0.0) -> np.ndarray:
    """Group index (T,) of track rectangles: two rectangles overlapping by more than the smaller of their
    ``depth`` (m, per rectangle or one for all) on every axis of the separating-axis test are one group,
    so duplicate hypotheses of one vehicle do not split its points between them, while neighbours whose
    predictions touch keep theirs (``ClusteringConfig.duplicate_depth``;
    ``tracker.clustering.overlap_groups_kernel``)."""
    count = len(rect.center)
    if count <= 1:
        return np.zeros(count, dtype=int)
    depths = np.broadcast_to(np.asarray(depth, dtype=float), (count,)).copy()
    return overlap_groups_kernel(np.ascontiguousarray(rect.corners()), np.cos(rect.psi), np.sin(rect.psi), depths)
