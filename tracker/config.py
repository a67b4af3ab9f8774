"""Typed configuration of the tracker: every tunable number, with its unit and default, in one place.

``TrackerConfig`` holds three top-level choices (coordinates, object model, radar use) and one section
per part of the filter, each a frozen dataclass validated on construction (a bad value raises
``ValueError`` naming the field, the value and the allowed range):

- ``ProcessNoise``: additive process noise densities (``tracker.motion.process_noise``);
- ``UKFParams``: the unscented transform's ``alpha, beta, kappa`` and the covariance floor;
- ``MotionConfig``: the motion model (exact Frenet kinematics or the paper's flat constant turn), the
  road-following prior, the acceleration state and its manoeuvre-gated jerk;
- ``MeasurementConfig``: the rectangle measurement model (lidar noise, one/two sides, partial
  visibility, shadows, extent rules) and the radar rows, including radar-only updates;
- ``DetectionConfig``: ``P_D``, ``P_S``, clutter, the lidar's resolution and range, occlusion;
- ``BirthConfig``: road births, cluster births and the vehicle-size priors and limits;
- ``GatingConfig``: which (component, cluster) pairs are updated;
- ``ReductionConfig``: prune, merge, cap, extraction, label management and re-identification;
- ``ClusteringConfig``: lidar preprocessing, clustering and radar association;
- ``PointConfig``: the point-object GNN tracker (``object_model = "point"``);
- ``tracker.cloud.CloudConfig``: the 3-D point-cloud pipeline (frames with ``(N, 3)`` lidar).

Every field carries a one-line ``#:`` comment: meaning, unit and default. Why a rule exists, and where
it departs from the paper, is explained in ``docs/tracker.md``.

Study variants are configurations of the same machinery: ``TrackerConfig.for_variant(name)`` with
``name`` like ``"curvilinear-fused"``, ``"cartesian-lidar"``, ``"point-fused"``.
``TrackerConfig.from_dict`` builds one from nested dictionaries (e.g. a TOML table), rejecting unknown
keys by name.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, Literal

from tracker.checks import check_real as _check
from tracker.cloud import CloudConfig

#: Dimension of the target state ``[s, n, v, xi, xi_dot, L, W]`` (or ``[x, y, v, psi, psi_dot, L, W]``).
STATE_DIM = 7


def _check_int(cls_name: str, name: str, value: Any, low: int) -> None:
    if isinstance(value, bool) or not isinstance(value, int) or value < low:
        raise ValueError(f"{cls_name}.{name} must be an integer >= {low}; got {value!r}")


def _check_choice(cls_name: str, name: str, value: Any, choices: tuple[str, ...]) -> None:
    if value not in choices:
        raise ValueError(f"{cls_name}.{name} must be one of {', '.join(map(repr, choices))}; got {value!r}")


@dataclass(frozen=True)
class ProcessNoise:
    """Additive process noise as continuous-time white-noise densities, discretised over ``dt``.

    Over ``dt`` the covariance added is ``Q = G diag(accel^2, yaw_accel^2) G^T + diag(random walks)^2 dt``:
    white acceleration and yaw acceleration integrated exactly over the step (the ``dt^3/3``, ``dt^2/2``
    terms) plus direct random walks. The position terms act along and across the target's heading.
    See ``tracker.motion.process_noise`` and ``docs/tracker.md`` ("Prediction").
    """

    #: White acceleration density on ``v`` and the position along the heading (m s^-1.5; default 0.5).
    accel: float = 0.5
    #: White yaw acceleration density on ``xi_dot`` and ``xi`` (``psi_dot``, ``psi``) (rad s^-1.5; default 0.2).
    yaw_accel: float = 0.2
    #: Random walk of the position along the heading, for model error (m s^-0.5; default 0.02).
    along: float = 0.02
    #: Random walk of the position across the heading, e.g. unpredicted lane changes (m s^-0.5; default 0.05).
    lateral: float = 0.05
    #: Random walk of the heading ``xi`` (``psi``) (rad s^-0.5; default 0.01).
    heading: float = 0.01
    #: Random walk of the length ``L``; 0 freezes it once converged (m s^-0.5; default 0.02).
    length: float = 0.02
    #: Random walk of the width ``W``; 0 freezes it once converged (m s^-0.5; default 0.01).
    width: float = 0.01

    def __post_init__(self) -> None:
        units = {"accel": "m/s^1.5", "yaw_accel": "rad/s^1.5", "along": "m/s^0.5", "lateral": "m/s^0.5",
                 "heading": "rad/s^0.5", "length": "m/s^0.5", "width": "m/s^0.5"}
        for name, unit in units.items():
            _check("ProcessNoise", name, getattr(self, name), low=0.0, unit=unit)


@dataclass(frozen=True)
class UKFParams:
    """Unscented transform parameters (Wan & van der Merwe scaling) and the covariance floor.

    ``lambda = alpha^2 (n + kappa) - n``; sigma points ``mean +/- sqrt(n + lambda) * chol(P)`` columns;
    weights ``Wm0 = lambda / (n + lambda)``, ``Wc0 = Wm0 + 1 - alpha^2 + beta``, ``Wi = 1 / (2 (n + lambda))``.
    The tracker requires every covariance weight to be non-negative (``Wc0 >= 0``): the innovation
    covariance is then positive definite by construction and the update can use its low-rank form
    (``tracker.update``). The default (``alpha = 1, beta = 2, kappa = 0``) gives ``Wm0 = 0``, ``Wc0 = 2``;
    a tiny ``alpha`` (the textbook 1e-3) gives ``Wm0 ~ -1e6`` and is refused.
    """

    #: Spread of the sigma points, > 0; must keep ``Wc0 >= 0`` (dimensionless; default 1.0).
    alpha: float = 1.0
    #: Prior-distribution weight of the central sigma point, >= 0 (2 is optimal for Gaussians; default 2.0).
    beta: float = 2.0
    #: Secondary scaling of the sigma-point spread (dimensionless; default 0.0).
    kappa: float = 0.0
    #: Floor the SPD repair lifts a covariance's eigenvalues to (state units squared; default 1e-9).
    min_eigenvalue: float = 1e-9

    def __post_init__(self) -> None:
        _check("UKFParams", "alpha", self.alpha, low=0.0, low_open=True)
        _check("UKFParams", "beta", self.beta, low=0.0)
        _check("UKFParams", "kappa", self.kappa)
        _check("UKFParams", "min_eigenvalue", self.min_eigenvalue, low=0.0, low_open=True)
        n = STATE_DIM
        lam = self.alpha**2 * (n + self.kappa) - n
        if n + lam <= 0:
            raise ValueError(
                f"UKFParams: alpha^2 (n + kappa) = {n + lam!r} must be > 0 (n = {n}); raise alpha or kappa"
            )
        wc0 = lam / (n + lam) + 1.0 - self.alpha**2 + self.beta
        if wc0 < 0:
            raise ValueError(
                f"UKFParams: the central covariance weight Wc0 = {wc0!r} is negative (alpha={self.alpha}, "
                f"beta={self.beta}, kappa={self.kappa}); the tracker needs Wc0 >= 0: use alpha near 1 "
                "(default 1.0) or a larger beta"
            )


@dataclass(frozen=True)
class MotionConfig:
    """Motion model of a target (``tracker.motion``).

    ``model = "frenet"`` integrates the exact Frenet kinematics ``s' = v cos(xi + beta) / (1 - kappa(s) n)``,
    ``n' = v sin(xi + beta)`` with RK4, plus a road-following prior on ``xi`` and ``xi_dot``, a kinematic
    slip angle ``beta`` and an internal acceleration state (Singer model) whose jerk is gated by
    manoeuvres; ``"paper"`` is the paper's constant-turn model in ``(s, n)``, which treats the road frame
    as flat (seven states, constant speed). A Cartesian-state tracker always uses the Cartesian
    constant-turn model. The acceleration and manoeuvre fields apply only to ``"frenet"``. Why each part
    exists: ``docs/tracker.md`` ("Prediction", "Departures from the paper").
    """

    #: ``"frenet"``: exact Frenet kinematics (RK4); ``"paper"``: the paper's flat constant turn (default "frenet").
    model: Literal["frenet", "paper"] = "frenet"
    #: Largest RK4 sub-step of the exact model: ``ceil(dt / max_step)`` sub-steps (s; default 0.1).
    max_step: float = 0.1
    #: Floor of ``1 - kappa n``, keeping a sigma point beyond the centre of curvature finite (default 0.1).
    min_denominator: float = 0.1
    #: Rear axle behind the centre, as a fraction of ``L``, for the slip angle; 0: the paper's no slip (default 0.5).
    slip_lever: float = 0.5
    #: Road-following prior: rate at which the course ``xi + beta`` relaxes to 0, or to pi against ``s`` (1/s; default 1.0; 0: off).
    heading_decay: float = 1.0
    #: Road-following prior: rate at which ``xi_dot`` relaxes to 0 (1/s; default 2.0; 0: off).
    yaw_rate_decay: float = 2.0
    #: Carry the longitudinal acceleration ``a`` as an internal 8th state (Singer model; exact model only; default True).
    acceleration: bool = True
    #: Singer time constant: an acceleration persists about this long, then fades (s; default 6.0).
    acceleration_time: float = 6.0
    #: White jerk density driving ``a`` during a manoeuvre (m s^-2.5; default 0.7).
    jerk: float = 0.7
    #: White acceleration on ``v`` with the acceleration state, replacing ``ProcessNoise.accel`` (m s^-1.5; default 0.15).
    residual_accel: float = 0.15
    #: Standard deviation of a newborn's acceleration, whose mean is 0 (m/s^2; default 1.0).
    acceleration_std: float = 1.0
    #: Time constant with which ``a`` fades while no cluster updates a track (s; default 0.5; None: ``acceleration_time``).
    coast_acceleration_time: float | None = 0.5
    #: ``|a|`` of at least this many standard deviations is established and fades slower (default 2.0; None: off).
    coast_established_sigmas: float | None = 2.0
    #: Time constant with which an established acceleration fades while coasting (s; default 4.0).
    coast_established_time: float = 4.0
    #: ... and its variance toward the spread of accelerations in traffic, not toward certainty of none (m/s^2; default 1.0; None: toward 0).
    coast_acceleration_std: float | None = 1.0
    #: Jerk density of a label that is not manoeuvring (m s^-2.5; default 0.3; None: ``jerk`` always).
    quiet_jerk: float | None = 0.3
    #: A correction of ``s`` beyond this many expected standard deviations flags a manoeuvre (default 2.0).
    manoeuvre_sigmas: float = 2.0
    #: How long a flagged label is predicted with the full ``jerk`` (s; default 2.0).
    manoeuvre_hold: float = 2.0
    #: Time constant of the fading mean of ``s`` corrections that flags a steady lag (s; default 0.5; None: off).
    manoeuvre_memory: float | None = 0.5
    #: Lane-flow prior of coasting tracks: spread of speeds in a lane (m/s; default 1.5; None: off; ``tracker.flow``).
    flow_speed_std: float | None = 1.5
    #: ... the time over which the pull amounts to one measurement of that spread (s; default 1.0).
    flow_time: float = 1.0
    #: ... the seen vehicles ahead and behind in the lane within this distance along the road set the flow (m; default 25.0).
    flow_window: float = 25.0

    def __post_init__(self) -> None:
        _check_choice("MotionConfig", "model", self.model, ("frenet", "paper"))
        _check("MotionConfig", "max_step", self.max_step, low=0.0, low_open=True, unit="s")
        _check("MotionConfig", "min_denominator", self.min_denominator, low=0.0, high=1.0, low_open=True)
        _check("MotionConfig", "slip_lever", self.slip_lever, low=0.0, high=1.0)
        _check("MotionConfig", "heading_decay", self.heading_decay, low=0.0, high=10.0, unit="1/s")
        _check("MotionConfig", "yaw_rate_decay", self.yaw_rate_decay, low=0.0, high=10.0, unit="1/s")
        if not isinstance(self.acceleration, bool):
            raise ValueError(f"MotionConfig.acceleration must be true or false; got {self.acceleration!r}")
        _check("MotionConfig", "acceleration_time", self.acceleration_time, low=0.0, low_open=True, unit="s")
        if self.coast_acceleration_time is not None:
            _check("MotionConfig", "coast_acceleration_time", self.coast_acceleration_time, low=0.0, low_open=True,
                   unit="s")
        if self.coast_established_sigmas is not None:
            _check("MotionConfig", "coast_established_sigmas", self.coast_established_sigmas, low=0.0)
        _check("MotionConfig", "coast_established_time", self.coast_established_time, low=0.0, low_open=True, unit="s")
        if self.coast_acceleration_std is not None:
            _check("MotionConfig", "coast_acceleration_std", self.coast_acceleration_std, low=0.0, unit="m/s^2")
        _check("MotionConfig", "jerk", self.jerk, low=0.0, unit="m s^-2.5")
        _check("MotionConfig", "residual_accel", self.residual_accel, low=0.0, unit="m s^-1.5")
        _check("MotionConfig", "acceleration_std", self.acceleration_std, low=0.0, low_open=True, unit="m/s^2")
        if self.quiet_jerk is not None:
            _check("MotionConfig", "quiet_jerk", self.quiet_jerk, low=0.0, unit="m s^-2.5")
            if self.quiet_jerk > self.jerk:
                raise ValueError(f"MotionConfig.quiet_jerk ({self.quiet_jerk!r} m s^-2.5) must not exceed "
                                 f"MotionConfig.jerk ({self.jerk!r}), the jerk of a manoeuvre")
        _check("MotionConfig", "manoeuvre_sigmas", self.manoeuvre_sigmas, low=0.0, low_open=True)
        _check("MotionConfig", "manoeuvre_hold", self.manoeuvre_hold, low=0.0, unit="s")
        if self.manoeuvre_memory is not None:
            _check("MotionConfig", "manoeuvre_memory", self.manoeuvre_memory, low=0.0, low_open=True, unit="s")
        if self.flow_speed_std is not None:
            _check("MotionConfig", "flow_speed_std", self.flow_speed_std, low=0.0, low_open=True, unit="m/s")
        _check("MotionConfig", "flow_time", self.flow_time, low=0.0, low_open=True, unit="s")
        _check("MotionConfig", "flow_window", self.flow_window, low=0.0, low_open=True, unit="m")


@dataclass(frozen=True)
class MeasurementConfig:
    """Rectangle measurement model (lidar), radar rows of fused clusters and radar-only updates.

    The model itself (chords, corner, side matching, generating points, end gaps) is described in
    ``tracker.measurement``; the visibility rules that decide whether a part of a cluster shows a whole
    side or part of one (shadows, sharp ends, continuation) and the extent rules (hold, growth) in
    ``docs/tracker.md`` ("Update", "Departures from the paper"). Several rules need the shadow flags
    (``shadow_window`` not None): sharp sides shown whole, sharp parts shown whole and shadowed parts held
    partially visible.
    """

    #: Std of a lidar point about its generating point, per axis in E, model error included (m; default 0.1).
    lidar_sigma: float = 0.1
    #: Std of a radar detection's absolute velocity, per axis in E (m/s; default 0.5).
    radar_velocity_sigma: float = 0.5
    #: A detection that joined no cluster updates a coasting track it fits (fused only; default True).
    radar_only_update: bool = True
    #: Std of a radar-only detection about the predicted rectangle's point nearest it, per axis (m; default 2.0).
    radar_position_sigma: float = 2.0
    #: A cluster is two-sided in the data when ``lambda_max / lambda_min`` of its points is below this (default 50.0).
    two_side_eigen_ratio: float = 50.0
    #: ... and the RMS distance of its points from their one fitted line exceeds this: range noise bends no face (m; default 0.05; 0: off).
    two_side_min_residual: float = 0.05
    #: A cluster whose points lie farther than this (RMS) from one fitted line is two-sided whatever its eigenvalue ratio, where its split is a near corner (``tracker.measurement.SPLIT_MIN_SIN``, ``SPLIT_MAX_SPACING``): a long dense side and a short face seen at grazing incidence (m; default 0.15; None: the ratio alone).
    two_side_line_residual: float | None = 0.15
    #: A side covering at most this fraction of its predicted length is partially visible (MATLAB 0.6; default 0.9).
    partial_visibility: float = 0.9
    #: Larger clusters are thinned evenly in bearing to this many points before the update (default 60).
    max_cluster_points: int = 60
    #: Fewest points for which the two-sided model (corner split) is tried (default 4).
    min_points_two_sided: int = 4
    #: ``"speed"``: one row, radar velocity along the predicted heading; ``"velocity"``: the paper's two (default "speed").
    radar_rows: Literal["speed", "velocity"] = "speed"
    #: ``L`` (``W``) keeps its prior unless a long (short) side is seen whole, a face seen whole where the update put it (default True).
    hold_unobserved_extent: bool = True
    #: Widen the extent prior when a side's points run well past the predicted rectangle (default True).
    grow_extent: bool = True
    #: A lone point fits only visible sides that look at least this fraction as wide as the widest (default 0.25).
    single_point_min_apparent: float = 0.25
    #: State to E: ``"exact"`` via the centerline, or ``"euler"``, the paper's Algorithm 1 (default "exact").
    conversion: Literal["exact", "euler"] = "exact"
    #: Rays beyond a cluster end searched for a nearer return: another object's shadow (rays; default 2.5; None: off).
    shadow_window: float | None = 2.5
    #: A return at least this much nearer than the end point casts the shadow (m; default 0.5).
    shadow_margin: float = 0.5
    #: An end within this of ``DetectionConfig.lidar_range`` counts as shadowed too (m; default 5.0).
    shadow_range_margin: float = 5.0
    #: An end is sharp when half the expected ray gap there is at most this (m; default 0.3).
    shadow_free_gap: float = 0.3
    #: Lidar std in the state update of an anchored part whose cluster borders a shadow (m; default 0.15; None: off).
    shadowed_lidar_sigma: float | None = 0.15
    #: Fewest points each part needs to be whole at a sharp, free far end, the corner counted in both: two lines through three points each (default 3).
    whole_min_points: int = 3
    #: A sharp part shown whole may shrink a side by at most this many std of its extent plus the slack (default 3.0).
    whole_gate_sigmas: float = 3.0
    #: Slack added to that gate (m; default 0.3).
    whole_gate_slack: float = 0.3
    #: An end continues if a return lies within this many ray gaps beyond it on its line (default 3.0; None: off).
    continuation_rays: float | None = 3.0
    #: ... and at most this far from that line (m; default 0.3).
    continuation_offset: float = 0.3
    #: A fused cluster's radar velocity whose own NIS exceeds this for every pair is set aside (default 25.0; None: off).
    radar_gate: float | None = 25.0

    def __post_init__(self) -> None:
        _check("MeasurementConfig", "lidar_sigma", self.lidar_sigma, low=0.0, low_open=True, unit="m")
        _check("MeasurementConfig", "radar_velocity_sigma", self.radar_velocity_sigma, low=0.0, low_open=True,
               unit="m/s")
        _check("MeasurementConfig", "radar_position_sigma", self.radar_position_sigma, low=0.0, low_open=True, unit="m")
        _check("MeasurementConfig", "two_side_eigen_ratio", self.two_side_eigen_ratio, low=1.0, low_open=True)
        _check("MeasurementConfig", "two_side_min_residual", self.two_side_min_residual, low=0.0, unit="m")
        if self.two_side_line_residual is not None:
            _check("MeasurementConfig", "two_side_line_residual", self.two_side_line_residual, low=0.0, low_open=True,
                   unit="m")
        _check("MeasurementConfig", "partial_visibility", self.partial_visibility, low=0.0, high=1.0)
        if self.shadow_window is not None:
            _check("MeasurementConfig", "shadow_window", self.shadow_window, low=0.0, low_open=True)
        _check("MeasurementConfig", "shadow_margin", self.shadow_margin, low=0.0, unit="m")
        _check("MeasurementConfig", "shadow_range_margin", self.shadow_range_margin, low=0.0, unit="m")
        _check("MeasurementConfig", "shadow_free_gap", self.shadow_free_gap, low=0.0, unit="m")
        if self.shadowed_lidar_sigma is not None:
            _check("MeasurementConfig", "shadowed_lidar_sigma", self.shadowed_lidar_sigma, low=0.0, low_open=True,
                   unit="m")
        _check_int("MeasurementConfig", "whole_min_points", self.whole_min_points, 2)
        _check("MeasurementConfig", "whole_gate_sigmas", self.whole_gate_sigmas, low=0.0)
        _check("MeasurementConfig", "whole_gate_slack", self.whole_gate_slack, low=0.0, unit="m")
        if self.continuation_rays is not None:
            _check("MeasurementConfig", "continuation_rays", self.continuation_rays, low=0.0, low_open=True)
        _check("MeasurementConfig", "continuation_offset", self.continuation_offset, low=0.0, unit="m")
        if self.radar_gate is not None:
            _check("MeasurementConfig", "radar_gate", self.radar_gate, low=0.0, low_open=True)
        _check_int("MeasurementConfig", "max_cluster_points", self.max_cluster_points, 3)
        _check_int("MeasurementConfig", "min_points_two_sided", self.min_points_two_sided, 3)
        _check_choice("MeasurementConfig", "radar_rows", self.radar_rows, ("speed", "velocity"))
        if not isinstance(self.hold_unobserved_extent, bool):
            raise ValueError(f"MeasurementConfig.hold_unobserved_extent must be true or false; got {self.hold_unobserved_extent!r}")
        if not isinstance(self.grow_extent, bool):
            raise ValueError(f"MeasurementConfig.grow_extent must be true or false; got {self.grow_extent!r}")
        _check("MeasurementConfig", "single_point_min_apparent", self.single_point_min_apparent, low=0.0, high=1.0)
        _check_choice("MeasurementConfig", "conversion", self.conversion, ("exact", "euler"))


@dataclass(frozen=True)
class DetectionConfig:
    """Detection and clutter model of the GM-PHD update (``tracker.detection``).

    A component's predicted rectangle expects ``gamma = (bearing span) / lidar_resolution`` points
    (scaled by its visible fraction when ``occlusion``), and ``P_D = p_detection`` while its nearest
    corner is within ``lidar_range`` (0 beyond; lowered when mostly hidden). Clutter is Poisson with
    ``clutter_rate`` points per frame spread uniformly at ``clutter_density``.
    """

    #: ``P_D``: probability that a target in the field of view yields a cluster (default 0.9).
    p_detection: float = 0.9
    #: ``P_S``: probability that a target survives one frame (default 0.99).
    p_survival: float = 0.99
    #: Mean number ``lambda`` of clutter points per frame (points/frame; default 1.0).
    clutter_rate: float = 1.0
    #: Spatial density ``c(z)`` of a clutter point, uniform over the road in view (1/m^2; default 1/5000).
    clutter_density: float = 1.0 / 5000.0
    #: Bearing step of the lidar: ``gamma = bearing span / lidar_resolution`` points expected (rad; default 0.2 deg).
    lidar_resolution: float = math.radians(0.2)
    #: Lidar range: ``P_D = 0`` for a rectangle whose nearest corner is beyond it (m; default 100.0).
    lidar_range: float = 100.0
    #: Scale ``gamma`` and ``P_D`` by the fraction of the bearing span not hidden by nearer tracks or returns (default True).
    occlusion: bool = True
    #: Cap a label's missed-detection weight at one minus its updated components' weight (default False).
    missed_weight_cap: bool = False
    #: Least ``P_D`` with which a hidden track's component still pairs with clusters (default 0.05; None: off).
    hidden_update_p_detection: float | None = 0.05

    def __post_init__(self) -> None:
        _check("DetectionConfig", "p_detection", self.p_detection, low=0.0, high=1.0, low_open=True)
        _check("DetectionConfig", "p_survival", self.p_survival, low=0.0, high=1.0, low_open=True)
        _check("DetectionConfig", "clutter_rate", self.clutter_rate, low=0.0, low_open=True, unit="points/frame")
        _check("DetectionConfig", "clutter_density", self.clutter_density, low=0.0, low_open=True, unit="1/m^2")
        _check("DetectionConfig", "lidar_resolution", self.lidar_resolution, low=0.0, low_open=True, unit="rad")
        _check("DetectionConfig", "lidar_range", self.lidar_range, low=0.0, low_open=True, unit="m")
        if self.hidden_update_p_detection is not None:
            _check("DetectionConfig", "hidden_update_p_detection", self.hidden_update_p_detection, low=0.0, high=1.0,
                   low_open=True)
        for name in ("occlusion", "missed_weight_cap"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"DetectionConfig.{name} must be true or false; got {getattr(self, name)!r}")


@dataclass(frozen=True)
class VehicleClass:
    """One class of road vehicle: its share of the traffic and its length and width distributions
    (normal, mean and standard deviation of the body, mirrors excluded), for the size prior of
    ``BirthConfig.classes``. The defaults' sources: ``docs/tracker.md`` ("Vehicle classes")."""

    #: Name of the class, e.g. "car" (no default).
    name: str
    #: Share of the traffic, by vehicle-distance travelled; the classes' shares need not sum to 1 (> 0; no default).
    share: float
    #: Mean length (m; no default).
    length: float
    #: Std of the length (m; no default).
    length_std: float
    #: Mean width (m; no default).
    width: float
    #: Std of the width (m; no default).
    width_std: float

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"VehicleClass.name must be a non-empty string; got {self.name!r}")
        _check(f"VehicleClass {self.name!r}", "share", self.share, low=0.0, low_open=True)
        for name in ("length", "length_std", "width", "width_std"):
            _check(f"VehicleClass {self.name!r}", name, getattr(self, name), low=0.0, low_open=True, unit="m")


#: The default classes (``docs/tracker.md``, "Vehicle classes", cites the sources): shares of the
#: vehicle-distance travelled in FHWA Highway Statistics table VM-1; sizes from fleet statistics,
#: typical models and the legal width limits of trucks and buses (2.55 m EU, 2.6 m US).
VEHICLE_CLASSES: tuple[VehicleClass, ...] = (
    VehicleClass("car", share=0.68, length=4.7, length_std=0.4, width=1.80, width_std=0.08),
    VehicleClass("van-suv-pickup", share=0.21, length=5.4, length_std=0.5, width=2.02, width_std=0.10),
    VehicleClass("truck", share=0.095, length=12.0, length_std=3.5, width=2.52, width_std=0.06),
    VehicleClass("bus", share=0.005, length=12.5, length_std=2.0, width=2.55, width_std=0.03),
    VehicleClass("motorcycle", share=0.007, length=2.2, length_std=0.25, width=0.80, width_std=0.10),
)


@dataclass(frozen=True)
class BirthConfig:
    """Birth intensity and the vehicle-size priors (``tracker.birth``, ``tracker.update``).

    Road births: one component per lane near the lidar's range limit, ahead and behind (prior spreads
    ``position_std``, ``lateral_std``, ``speed_std``, ...). Cluster births: one component per cluster of
    the previous frame that no track explained, from an L-shape fit (centre, heading, extent), the speed
    from a joined radar detection when fused; a cluster that no component could explain (beyond every
    pre-gate) is born in its own frame (``first_scan``, ``same_frame``). The vehicle classes
    (``classes``) give an unmeasured length its prior from the measured width: the classes weighed by
    their share and the width's likelihood, the length their mixture's mean and variance
    (``tracker.extent.class_length_prior``);
    ``min_length`` .. ``max_length`` and ``min_width`` .. ``max_width`` bound every estimate. Details:
    ``docs/tracker.md`` ("Births", "Departures from the paper").
    """

    #: Weight of each birth component (default 0.05).
    weight: float = 0.05
    #: Road births sit this far inside the lidar range, ahead and behind (m; default 5.0).
    range_margin: float = 5.0
    #: Prior speed of births without a radar detection (m/s; default None: the ego's speed).
    speed: float | None = None
    #: Std of that prior speed (m/s; default 5.0).
    speed_std: float = 5.0
    #: Std of a cluster birth's speed taken from its lane's flow, without radar (m/s; default 3.0; None: the prior speed above; ``tracker.flow``).
    flow_speed_std: float | None = 3.0
    #: Prior length of a road birth, and the least length of a cluster birth: the car class's (m; default 4.7).
    length: float = 4.7
    #: Prior width of a road birth, and the least width of a cluster birth: the classes' mean, 1.91 m (m; default 1.9).
    width: float = 1.9
    #: Std of a car's prior length (m; default 1.0).
    length_std: float = 1.0
    #: Std of the prior width (m; default 0.3).
    width_std: float = 0.3
    #: Std of a road birth's position along the road (m; default 2.0).
    position_std: float = 2.0
    #: Std of a road birth's position across the road (m; default 0.5).
    lateral_std: float = 0.5
    #: Std of a birth's heading ``xi`` (rad; default 0.1).
    heading_std: float = 0.1
    #: Std of a birth's heading rate ``xi_dot`` (rad/s; default 0.05).
    heading_rate_std: float = 0.05
    #: Fewest points of an unexplained cluster that seeds a birth (default 2: a far car's two returns).
    min_cluster_points: int = 2
    #: A cluster whose fitted rectangle is shorter than this on both sides shows no orientation: its birth takes the lane's direction (m; default 1.0; 0: every fit's).
    min_oriented_extent: float = 1.0
    #: Crossing traffic (``tracker.course``): a cluster birth whose joined radar velocity is at least this fast and crosses its lane's direction at 45-135 deg takes that course as its heading's reference; a component whose own cluster's does so across its heading is turned a quarter turn to it (m/s; default 3.0; None: off).
    crossing_min_speed: float | None = 3.0
    #: ... with a joined radar detection, beyond ``sparse_min_range`` (fused; default 1; None: ``min_cluster_points``).
    min_cluster_points_radar: int | None = 1
    #: ``min_cluster_points_radar`` applies to clusters whose every point is at least this far (m; default 70.0).
    sparse_min_range: float = 70.0
    #: ... with a joined radar detection, at any range (fused only; default 2, below ``min_cluster_points`` only when that is raised; None: ``min_cluster_points``).
    min_cluster_points_fused: int | None = 2
    #: The first frame with lidar points seeds births from its clusters and updates them in that frame (default True).
    first_scan: bool = True
    #: Later frames: clusters beyond every component's pre-gate (``GatingConfig.distance``) seed births that this frame's update takes (default True; False: they wait a frame, as in the paper).
    same_frame: bool = True
    #: Later frames: a cluster of ``min_cluster_points`` up to this many points that this frame's update left unexplained, within reach of no coasting track, is born and updated in the frame (default 3; None: it waits a frame, as in the paper).
    after_update_points: int | None = 3
    #: Use road births, per lane near the range limits (default True).
    road: bool = True
    #: Vehicle classes whose sizes and shares weigh an unmeasured length by the measured width (default ``VEHICLE_CLASSES``; None: off).
    classes: tuple[VehicleClass, ...] | None = VEHICLE_CLASSES
    #: Std of a cluster's fitted width as evidence of its class, at a cluster birth (m; default 0.1).
    fit_width_std: float = 0.1
    #: Std of a measured width about the body's, beyond the filter's variance: mirrors, label boxes (m; default 0.0).
    width_error_std: float = 0.0
    #: Learn ``width_error_std`` from the vehicles measured whole once this many are (default 3; None: never; ``tracker.fleet``).
    width_error_vehicles: int | None = 3
    #: Longest vehicle: estimates and cluster births beyond it are projected back onto it (m; default 25.0; None: no limit).
    max_length: float | None = 25.0
    #: Widest vehicle: estimates and cluster births beyond it are projected back onto it (m; default 3.0; None: no limit).
    max_width: float | None = 3.0
    #: Shortest vehicle: shorter estimates are projected back onto it (m; default 1.5, a motorcycle's 2.2 m less three std).
    min_length: float = 1.5
    #: Narrowest vehicle: narrower estimates are projected back onto it (m; default 0.5, a motorcycle's 0.8 m less three std).
    min_width: float = 0.5

    def __post_init__(self) -> None:
        _check_int("BirthConfig", "min_cluster_points", self.min_cluster_points, 1)
        if self.min_cluster_points_radar is not None:
            _check_int("BirthConfig", "min_cluster_points_radar", self.min_cluster_points_radar, 1)
        _check("BirthConfig", "sparse_min_range", self.sparse_min_range, low=0.0, unit="m")
        if self.after_update_points is not None:
            _check_int("BirthConfig", "after_update_points", self.after_update_points, 1)
        _check("BirthConfig", "min_oriented_extent", self.min_oriented_extent, low=0.0, unit="m")
        if self.crossing_min_speed is not None:
            _check("BirthConfig", "crossing_min_speed", self.crossing_min_speed, low=0.0, low_open=True, unit="m/s")
        if self.flow_speed_std is not None:
            _check("BirthConfig", "flow_speed_std", self.flow_speed_std, low=0.0, low_open=True, unit="m/s")
        if self.min_cluster_points_fused is not None:
            _check_int("BirthConfig", "min_cluster_points_fused", self.min_cluster_points_fused, 1)
        if self.classes is not None:
            if isinstance(self.classes, (str, bytes, dict)) or not hasattr(self.classes, "__iter__"):
                raise ValueError(f"BirthConfig.classes must be a list of vehicle classes or None; got {self.classes!r}")
            fields = [f.name for f in dataclasses.fields(VehicleClass)]
            for c in self.classes:
                if isinstance(c, dict) and sorted(c) != sorted(fields):
                    raise ValueError(f"BirthConfig.classes: a class table needs exactly the keys {', '.join(fields)}; "
                                     f"got {', '.join(map(str, c)) or 'none'}")
            classes = tuple(VehicleClass(**c) if isinstance(c, dict) else c for c in self.classes)
            if not classes or not all(isinstance(c, VehicleClass) for c in classes):
                raise ValueError(f"BirthConfig.classes must hold at least one VehicleClass (or a table of its fields); "
                                 f"got {self.classes!r}")
            if len({c.name for c in classes}) != len(classes):
                raise ValueError(f"BirthConfig.classes must have distinct names; got {[c.name for c in classes]!r}")
            object.__setattr__(self, "classes", classes)
        _check("BirthConfig", "fit_width_std", self.fit_width_std, low=0.0, low_open=True, unit="m")
        _check("BirthConfig", "width_error_std", self.width_error_std, low=0.0, unit="m")
        if self.width_error_vehicles is not None:
            _check_int("BirthConfig", "width_error_vehicles", self.width_error_vehicles, 1)
        for name in ("max_length", "max_width"):
            if getattr(self, name) is not None:
                _check("BirthConfig", name, getattr(self, name), low=0.0, low_open=True, unit="m")
        for low, high in (("min_length", "max_length"), ("min_width", "max_width")):
            value, limit = getattr(self, low), getattr(self, high)
            _check("BirthConfig", low, value, low=0.0, unit="m")
            if limit is not None and value > limit:
                raise ValueError(f"BirthConfig.{low} must not exceed {high} ({limit} m); got {value} m")
        if not isinstance(self.road, bool):
            raise ValueError(f"BirthConfig.road must be true or false; got {self.road!r}")
        _check("BirthConfig", "weight", self.weight, low=0.0, high=1.0, low_open=True)
        _check("BirthConfig", "range_margin", self.range_margin, low=0.0, unit="m")
        if self.speed is not None:
            _check("BirthConfig", "speed", self.speed, unit="m/s")
        for name in ("speed_std", "length", "width", "length_std", "width_std", "position_std", "lateral_std",
                     "heading_std", "heading_rate_std"):
            _check("BirthConfig", name, getattr(self, name), low=0.0, low_open=True)


@dataclass(frozen=True)
class GatingConfig:
    """Which (component, cluster) pairs are updated at all.

    A cluster is tried for a component when its centroid lies within ``distance`` of the circle
    around the component's predicted rectangle (centre distance at most ``distance + hypot(L, W) / 2``),
    then kept when the pair's normalised innovation lies inside the chi-square ``probability`` quantile
    of its measurement dimension. A reported track's own cluster (its points inside the track's predicted
    rectangle) updates it even past the gate.
    """

    #: Pre-gate: the cluster centroid within this of the circle around the predicted rectangle (m; default 5.0).
    distance: float = 5.0
    #: Gate: chi-square quantile of the pair's normalised innovation, by measurement dimension (default 0.9999).
    probability: float = 0.9999

    def __post_init__(self) -> None:
        _check("GatingConfig", "distance", self.distance, low=0.0, low_open=True, unit="m")
        _check("GatingConfig", "probability", self.probability, low=0.0, high=1.0, low_open=True)


@dataclass(frozen=True)
class ReductionConfig:
    """Mixture reduction (Vo & Ma GM-PHD), extraction and label management.

    Prune, angle-aware merge and cap as in the GM-PHD filter; then the rules that keep one label per
    vehicle: merging a track's posteriors updated by fragments of its points, dropping duplicates inside
    a seen vehicle, absorbing overlapping labels, confirmation before a first report, hysteresis on the
    reporting weight and re-identification of lost tracks (``tracker.identity``). Details:
    ``docs/tracker.md`` ("Reduction", "Extraction and labels").
    """

    #: Components lighter than this are dropped (default 1e-4).
    prune_threshold: float = 1e-4
    #: Components within this squared Mahalanobis distance are merged, angle-aware (default 4.0).
    merge_threshold: float = 4.0
    #: Cap on the number of components, the heaviest kept (default 100).
    max_components: int = 100
    #: Components heavier than this are reported as tracks (default 0.5).
    extraction_threshold: float = 0.5
    #: A label reported last frame stays reported while its heaviest component exceeds this (default 0.3; None: off).
    keep_threshold: float | None = 0.3
    #: Components whose nearest corner is beyond the lidar range plus this are dropped (m; default 2.0).
    fov_margin: float = 2.0
    #: Components whose centre lies beyond a road edge by more than this are dropped (m; default 1.0).
    road_margin: float = 1.0
    #: Components of one label above ``extraction_threshold`` this close to its heaviest are merged (m; default 3.0).
    same_label_distance: float = 3.0
    #: ... or within half the heavier one's length along its heading and ``same_label_distance`` across it (default True).
    same_label_along_length: bool = True
    #: Tracks are reported while their centre is within ``lidar_range`` plus this (m; default 0.0; None: all).
    report_range: float | None = 0.0
    #: Tracks are reported while their centre is within the road's edges widened by this (m; default 0.0: on the road; None: all, up to ``road_margin``).
    report_road_margin: float | None = 0.0
    #: Tracks are reported while their position's std (root of the trace of its 2x2 block) is at most this (m; default 5.0; None: all).
    report_position_std: float | None = 5.0
    #: A label is first reported only after a cluster of at least this many points updated it (default 2).
    confirm_min_points: int = 2
    #: A radar detection joined to the cluster counts as one of those points (fused; default True).
    confirm_radar_point: bool = True
    #: A lost track is remembered this long for re-identification (s; default 10.0; 0: off).
    reidentify_window: float = 10.0
    #: Re-identification gate: chi-square quantile, 2 degrees of freedom, of the position distance (default 0.99).
    reidentify_probability: float = 0.99
    #: Acceleration a hidden vehicle may have made: reach ahead of its prediction (m/s^2; default 2.0).
    reidentify_accel: float = 2.0
    #: Deceleration a hidden vehicle may have made, up to standstill (m/s^2; default 8.0; None: ``reidentify_accel``).
    reidentify_brake: float | None = 8.0
    #: A lost track also matches a newcomer where it would be had it followed its lane since it was lost (default True; road coordinates only).
    reidentify_lane_following: bool = True
    #: Drop a label without a reportable posterior whose centre lies inside a seen vehicle's rectangle (default True).
    drop_inside_updated: bool = True
    #: Of a label's components above the threshold, one holding none of the frame's lidar points is not reported (no split target) where another holds some (default True).
    drop_unseen_branches: bool = True
    #: Two labels whose rectangles overlap along the road by more than this are one vehicle (m; default 0.5; None: off).
    absorb_overlap: float | None = 0.5

    def __post_init__(self) -> None:
        _check("ReductionConfig", "prune_threshold", self.prune_threshold, low=0.0, high=1.0)
        _check("ReductionConfig", "merge_threshold", self.merge_threshold, low=0.0)
        _check_int("ReductionConfig", "max_components", self.max_components, 1)
        _check("ReductionConfig", "extraction_threshold", self.extraction_threshold, low=0.0, high=1.0)
        if self.keep_threshold is not None:
            _check("ReductionConfig", "keep_threshold", self.keep_threshold, low=0.0, high=self.extraction_threshold,
                   low_open=True)
        _check("ReductionConfig", "fov_margin", self.fov_margin, low=0.0, unit="m")
        _check("ReductionConfig", "road_margin", self.road_margin, low=0.0, unit="m")
        _check("ReductionConfig", "same_label_distance", self.same_label_distance, low=0.0, unit="m")
        for name in ("same_label_along_length", "reidentify_lane_following", "confirm_radar_point", "drop_unseen_branches"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"ReductionConfig.{name} must be true or false; got {getattr(self, name)!r}")
        if self.report_range is not None:
            _check("ReductionConfig", "report_range", self.report_range, unit="m")
        if self.report_road_margin is not None:
            _check("ReductionConfig", "report_road_margin", self.report_road_margin, low=0.0, unit="m")
        if self.report_position_std is not None:
            _check("ReductionConfig", "report_position_std", self.report_position_std, low=0.0, low_open=True, unit="m")
        _check_int("ReductionConfig", "confirm_min_points", self.confirm_min_points, 1)
        _check("ReductionConfig", "reidentify_window", self.reidentify_window, low=0.0, unit="s")
        _check("ReductionConfig", "reidentify_probability", self.reidentify_probability, low=0.0, high=1.0,
               low_open=True, high_open=True)
        _check("ReductionConfig", "reidentify_accel", self.reidentify_accel, low=0.0, unit="m/s^2")
        if self.absorb_overlap is not None:
            _check("ReductionConfig", "absorb_overlap", self.absorb_overlap, low=0.0, unit="m")
        if self.reidentify_brake is not None:
            _check("ReductionConfig", "reidentify_brake", self.reidentify_brake, low=0.0, low_open=True, unit="m/s^2")


@dataclass(frozen=True)
class ClusteringConfig:
    """Lidar preprocessing, clustering and radar association (``tracker.preprocess``, ``tracker.clustering``).

    Points off the road (plus ``road_margin``) are dropped, the bearing filter keeps the nearest point per
    ``bearing_bin``; points inside a reported track's predicted rectangle (plus ``track_margin`` along and
    ``across_margin`` across it) form its cluster, the rest are partitioned into connected components at ``distance``; clusters wider across
    the road than one vehicle are cut, and a track's cluster at a hole along the track (the track then
    shortened to end there); lone fragments continuing a track's side join it; radar
    detections join the nearest cluster (by its nearest point) within ``radar_gate``. Details:
    ``docs/tracker.md`` ("Clustering").
    """

    #: Lidar points within the road bounds widened by this are kept (m; default 0.5).
    road_margin: float = 0.5
    #: The paper's bearing filter keeps the nearest point per bin of this width, at least the lidar's azimuth step (rad; default 0.2 deg).
    bearing_bin: float = math.radians(0.2)
    #: Points inside a reported track's predicted rectangle grown by this along its length form its cluster (m; default 1.0).
    track_margin: float = 1.0
    #: ... and by this across it (m; default 0.5: vehicles in the next lane come that close).
    across_margin: float = 0.5
    #: Two tracks each reported 3+ frames in a row whose predicted rectangles overlap by at most this on some axis are neighbours, each keeping its points; more, or a younger track at any overlap: duplicates of one vehicle sharing them (m; default 0.3).
    duplicate_depth: float = 0.3
    #: The other points form connected components of points closer than this (m; default 1.0).
    distance: float = 1.0
    #: Points on neighbouring rays (``bearing_bin`` apart) also join when closer than ``r dtheta / sin`` of this: a surface the rays meet at this incidence or steeper, a far car's side (``tracker.clustering.ray_partition``; rad; default 4 deg; None: off).
    grazing_angle: float | None = math.radians(4.0)
    #: ... but never when farther apart than this (m; default 4.0).
    grazing_max_gap: float = 4.0
    #: Smaller clusters are dropped and counted (default 1).
    min_points: int = 1
    #: A radar detection joins a cluster whose nearest point lies within this, greedily by distance (m; default 3.0).
    radar_gate: float = 3.0
    #: A cluster spanning more than this across the road (in ``n``) is cut at its largest gap (m; default 2.6: the widest class, a bus, is 2.55; None: off).
    split_width: float | None = 2.6
    #: ... if that lateral gap is at least this (m; default 0.4: real cars abreast come within 0.45 m).
    split_gap: float = 0.4
    #: A track's cluster is cut along the track at a gap between consecutive points of at least this, unshadowed (m; default 1.0; None: off).
    along_gap: float | None = 1.0
    #: ... and of at least this many ray gaps ``r^2 step / d`` of a side there, ``step`` = ``detection.lidar_resolution`` (default 3.0).
    along_gap_rays: float = 3.0
    #: ... into parts of at least this many points each (default 3: a lone far return is more likely a grazing side's end).
    along_min_part: int = 3
    #: A lone component of at most this many points continuing a track's side joins its cluster (default 1; None: off).
    fragment_points: int | None = 1
    #: The track's rectangle is stretched at its far end by this many std of its length (default 4.0).
    fragment_sigmas: float = 4.0
    #: The fragment must lie within this of the track's long side facing the sensor (m; default 0.5; None: no test).
    fragment_side_tolerance: float | None = 0.5

    def __post_init__(self) -> None:
        for name, unit in (("road_margin", "m"), ("track_margin", "m"), ("across_margin", "m"), ("duplicate_depth", "m"),
                           ("split_gap", "m")):
            _check("ClusteringConfig", name, getattr(self, name), low=0.0, unit=unit)
        if self.fragment_points is not None:
            _check_int("ClusteringConfig", "fragment_points", self.fragment_points, 1)
        _check("ClusteringConfig", "fragment_sigmas", self.fragment_sigmas, low=0.0)
        if self.fragment_side_tolerance is not None:
            _check("ClusteringConfig", "fragment_side_tolerance", self.fragment_side_tolerance, low=0.0, unit="m")
        if self.split_width is not None:
            _check("ClusteringConfig", "split_width", self.split_width, low=0.0, low_open=True, unit="m")
        if self.along_gap is not None:
            _check("ClusteringConfig", "along_gap", self.along_gap, low=0.0, low_open=True, unit="m")
        _check("ClusteringConfig", "along_gap_rays", self.along_gap_rays, low=0.0)
        _check_int("ClusteringConfig", "along_min_part", self.along_min_part, 1)
        if self.grazing_angle is not None:
            _check("ClusteringConfig", "grazing_angle", self.grazing_angle, low=0.0, high=0.5 * math.pi, low_open=True,
                   high_open=True, unit="rad")
        for name, unit in (("bearing_bin", "rad"), ("distance", "m"), ("radar_gate", "m"), ("grazing_max_gap", "m")):
            _check("ClusteringConfig", name, getattr(self, name), low=0.0, low_open=True, unit=unit)
        _check_int("ClusteringConfig", "min_points", self.min_points, 1)


@dataclass(frozen=True)
class PointConfig:
    """The point-object GNN tracker (``TrackerConfig.object_model = "point"``, ``tracker.point``).

    Gating uses ``GatingConfig`` (pre-gate distance, chi-square probability), births ``BirthConfig``
    (spreads) and ``min_cluster_points`` (a two-point cluster's centroid, unlike a rectangle fitted
    to it, is no position of the vehicle), the radar noise ``MeasurementConfig.radar_velocity_sigma``.
    """

    #: Std of a cluster centroid about the tracked point, per axis in E (m; default 0.5).
    centroid_sigma: float = 0.5
    #: Fewest points of an unassigned cluster that starts a tentative track (default 3; the extended trackers' births take ``BirthConfig.min_cluster_points``).
    min_cluster_points: int = 3
    #: A tentative track is confirmed after this many associations ... (default 3).
    confirm_hits: int = 3
    #: ... within its last this many frames (M-of-N; default 5).
    confirm_window: int = 5
    #: A confirmed track is deleted after this many consecutive misses (default 5).
    max_misses: int = 5
    #: A tentative track is deleted after this many consecutive misses (default 2).
    tentative_max_misses: int = 2

    def __post_init__(self) -> None:
        _check("PointConfig", "centroid_sigma", self.centroid_sigma, low=0.0, low_open=True, unit="m")
        for name in ("min_cluster_points", "confirm_hits", "confirm_window", "max_misses", "tentative_max_misses"):
            _check_int("PointConfig", name, getattr(self, name), 1)
        if self.confirm_hits > self.confirm_window:
            raise ValueError(
                f"PointConfig.confirm_hits ({self.confirm_hits}) must be <= confirm_window ({self.confirm_window})"
            )


_SECTIONS: dict[str, type] = {
    "process_noise": ProcessNoise,
    "ukf": UKFParams,
    "motion": MotionConfig,
    "measurement": MeasurementConfig,
    "detection": DetectionConfig,
    "birth": BirthConfig,
    "gating": GatingConfig,
    "reduction": ReductionConfig,
    "clustering": ClusteringConfig,
    "point": PointConfig,
    "cloud": CloudConfig,
}


@dataclass(frozen=True)
class TrackerConfig:
    """The whole tracker configuration: three top-level choices and one section per part.

    The sections are the classes above (see them for units and defaults); ``cloud``
    (``tracker.cloud.CloudConfig``) is used only for frames whose lidar is a 3-D cloud: the lidar's
    mount pose and the ground removal.
    """

    #: ``"curvilinear"``: state ``[s, n, v, xi, xi_dot, L, W]``; ``"cartesian"``: ``[x, y, v, psi, psi_dot, L, W]`` in G (default "curvilinear").
    coordinates: Literal["curvilinear", "cartesian"] = "curvilinear"
    #: ``"extended"``: rectangle EOT; ``"point"``: point-object GNN on centroids, curvilinear only (default "extended").
    object_model: Literal["extended", "point"] = "extended"
    #: Fuse radar detections: velocity rows of fused clusters and radar-only updates (default True).
    use_radar: bool = True
    #: Process noise (``ProcessNoise``).
    process_noise: ProcessNoise = field(default_factory=ProcessNoise)
    #: Unscented transform (``UKFParams``).
    ukf: UKFParams = field(default_factory=UKFParams)
    #: Motion model (``MotionConfig``).
    motion: MotionConfig = field(default_factory=MotionConfig)
    #: Measurement model (``MeasurementConfig``).
    measurement: MeasurementConfig = field(default_factory=MeasurementConfig)
    #: Detection and clutter model (``DetectionConfig``).
    detection: DetectionConfig = field(default_factory=DetectionConfig)
    #: Birth intensity and size priors (``BirthConfig``).
    birth: BirthConfig = field(default_factory=BirthConfig)
    #: Gating (``GatingConfig``).
    gating: GatingConfig = field(default_factory=GatingConfig)
    #: Reduction, extraction and labels (``ReductionConfig``).
    reduction: ReductionConfig = field(default_factory=ReductionConfig)
    #: Preprocessing, clustering, radar association (``ClusteringConfig``).
    clustering: ClusteringConfig = field(default_factory=ClusteringConfig)
    #: Point-object tracker (``PointConfig``; ``object_model = "point"`` only).
    point: PointConfig = field(default_factory=PointConfig)
    #: 3-D point-cloud pipeline (``tracker.cloud.CloudConfig``; frames with ``(N, 3)`` lidar only).
    cloud: CloudConfig = field(default_factory=CloudConfig)

    def __post_init__(self) -> None:
        _check_choice("TrackerConfig", "coordinates", self.coordinates, ("curvilinear", "cartesian"))
        _check_choice("TrackerConfig", "object_model", self.object_model, ("extended", "point"))
        if self.object_model == "point" and self.coordinates != "curvilinear":
            raise ValueError("TrackerConfig: object_model='point' tracks in curvilinear coordinates only; "
                             "set coordinates='curvilinear'")
        if not isinstance(self.use_radar, bool):
            raise ValueError(f"TrackerConfig.use_radar must be true or false; got {self.use_radar!r}")
        for name, cls in _SECTIONS.items():
            if not isinstance(getattr(self, name), cls):
                raise ValueError(
                    f"TrackerConfig.{name} must be a {cls.__name__}; got {type(getattr(self, name)).__name__}"
                )
        bin_, step = self.clustering.bearing_bin, self.detection.lidar_resolution
        if bin_ < step * (1.0 - 1e-9):
            raise ValueError(
                f"TrackerConfig: clustering.bearing_bin ({math.degrees(bin_):.4g} deg) is narrower than the lidar's "
                f"azimuth step detection.lidar_resolution ({math.degrees(step):.4g} deg); set bearing_bin to the step"
            )

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> TrackerConfig:
        """A config from nested dictionaries (e.g. a parsed TOML table); unknown keys raise
        ``ValueError`` naming the key and the accepted ones."""
        if not isinstance(data, dict):
            raise ValueError(f"tracker configuration must be a table/dict; got {type(data).__name__}")
        top = {f.name for f in dataclasses.fields(cls)}
        kwargs: dict[str, Any] = {}
        for key, value in data.items():
            if key not in top:
                raise ValueError(f"unknown tracker configuration key {key!r}; accepted: {', '.join(sorted(top))}")
            if key in _SECTIONS:
                section = _SECTIONS[key]
                if isinstance(value, section):
                    kwargs[key] = value
                    continue
                if not isinstance(value, dict):
                    raise ValueError(f"tracker configuration {key!r} must be a table/dict; got {value!r}")
                names = {f.name for f in dataclasses.fields(section)}
                unknown = sorted(set(value) - names)
                if unknown:
                    raise ValueError(
                        f"unknown key(s) {', '.join(map(repr, unknown))} in tracker configuration {key!r}; "
                        f"accepted: {', '.join(sorted(names))}"
                    )
                kwargs[key] = section(**value)
            else:
                kwargs[key] = value
        return cls(**kwargs)

    @classmethod
    def for_variant(cls, name: str, **overrides: Any) -> TrackerConfig:
        """The configuration of a study variant ``"<model>-<sensors>"``: model ``curvilinear``,
        ``cartesian`` or ``point``; sensors ``fused`` (lidar + radar) or ``lidar``. A bare model name
        means fused. ``overrides`` replace top-level fields."""
        model, _, sensors = name.partition("-")
        sensors = sensors or "fused"
        if model not in ("curvilinear", "cartesian", "point") or sensors not in ("fused", "lidar"):
            raise ValueError(
                f"unknown tracker variant {name!r}; use '<curvilinear|cartesian|point>-<fused|lidar>', "
                "e.g. 'curvilinear-fused'"
            )
        base = cls(
            coordinates="cartesian" if model == "cartesian" else "curvilinear",
            object_model="point" if model == "point" else "extended",
            use_radar=sensors == "fused",
        )
        if model == "cartesian":  # the softer update trusts a prediction that leaves the road (MeasurementConfig)
            base = dataclasses.replace(base, measurement=dataclasses.replace(base.measurement, shadowed_lidar_sigma=None))
        return dataclasses.replace(base, **overrides) if overrides else base
