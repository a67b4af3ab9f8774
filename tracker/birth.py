"""Birth intensity of the GM-PHD filter (the paper's equation Prediction_eq3):
``lambda_b = lambda_R(x_ego) + lambda(Z_{k-1})``.

- ``road_births``: per lane, a component near the lidar's range limit ahead of and behind the ego
  (where vehicles enter the field of view), in road coordinates;
- ``cluster_births``: one component per cluster of the previous frame that no track explained, from
  an L-shape rectangle fit (centre, heading, extent; a side that was not seen takes the prior extent and
  the centre moves away from the sensor by the missing half, unless the cluster's near end borders
  another object's shadow: then the missing half may lie on either side, a spread instead of a
  shift), the fit's axes turned by the quarter turn that puts the heading closest to the road
  direction (``|xi| <= pi/4``: vehicles drive along the road; a cluster of one or two points, or one
  shorter than ``BirthConfig.min_oriented_extent`` on both sides, takes the lane's direction; a vehicle
  whose radar course crosses the lane, ``tracker.course.crossing_course``, takes that course instead), and the
  speed from an associated radar
  detection when fused (on a two-way road, not from one that points more than ``BACKWARD_SPEED``
  against that heading: the detection of a vehicle passing in the other direction).

Both return curvilinear means (B, 7) and covariances (B, 7, 7); ``to_cartesian_gaussians`` maps them to
the Cartesian variant's state by the unscented transform.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from tracker.angles import wrap_angle
from tracker.config import BirthConfig
from tracker.course import crossing_course
from tracker.detection import occluded_fraction
from tracker.extent import class_arrays, class_length_prior
from tracker.frame import EgoState
from tracker.measurement import MIN_EXTENT, Rectangles
from tracker.road import Road
from tracker.shape_fit import fit_rectangle
from tracker.track import curvilinear_to_cartesian
from tracker.transforms import rotate, to_global
from tracker.ukf import UnscentedTransform, Wrapping
import math
from tracker.jit import njit
from tracker.centerline import to_vehicle_kernel
from tracker.detection import _occluded, _spans


#: Speed (m/s) against its heading beyond which a cluster birth on a two-way road does not take its radar velocity:
#: the heading follows the lane's traffic, so such a detection is a passing vehicle's in the other lane.
BACKWARD_SPEED = 2.0


def birth_covariance(config: BirthConfig, count: int) -> np.ndarray:
    """Diagonal prior covariances (count, 7, 7) of birth components (``BirthConfig`` spreads)."""
    return np.broadcast_to(_diagonal_variances(_birth_spreads(config)), (count, 7, 7)).copy()


def _birth_spreads(config: BirthConfig) -> tuple[float, ...]:
    """The seven standard deviations of a birth component's state (``BirthConfig``)."""
    return tuple(float(x) for x in (config.position_std, config.lateral_std, config.speed_std, config.heading_std,
                                    config.heading_rate_std, config.length_std, config.width_std))


@lru_cache(maxsize=32)
def _diagonal_variances(std: tuple[float, ...]) -> np.ndarray:
    """``diag(std^2)`` (read-only; a tracker asks for the same spreads every frame)."""
    out = np.diag(np.array(std) ** 2)
    out.flags.writeable = False
    return out


def _birth_arc_lengths(road: Road, s_ego: float, lidar_range: float, config: BirthConfig) -> np.ndarray:
    """``s_ego +- (lidar_range - range_margin)`` (m): wrapped on a closed road, only those on an open one."""
    reach = max(lidar_range - config.range_margin, 0.0)
    s = np.array([s_ego + reach, s_ego - reach])
    if road.closed:
        return np.mod(s, road.length)
    return s[(s >= 0.0) & (s <= road.length)]


def _lane_rows(road: Road, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One row per (arc length, driving lane present there), arc length first then lane 0 (rightmost)
    up: the rows' ``s`` and ``n`` (m) and heading ``xi`` (rad: 0 in a lane along ``s``, pi in an
    oncoming one)."""
    layout = road.layout
    # equal driving lanes everywhere: Road.lane_centers, whose centres (right + (k + 1/2) w) are the lanes'
    # own numbers to the last bit (the midpoints of the layout's boundaries can differ in it)
    if getattr(layout, "_uniform", None) is not None and not layout.two_way:
        lanes = road.lane_centers
        return np.repeat(s, len(lanes)), np.tile(lanes, len(s)), np.zeros(len(s) * len(lanes))
    centres = road.lane_centers_at(s)  # (len(s), lanes), NaN where a lane is absent
    driving = np.array([k == "driving" for k in layout.kinds])
    present = ~np.isnan(centres) & driving[None, :]
    i, j = np.nonzero(present)
    xi = np.where(layout.directions[j] < 0, np.pi, 0.0)
    return s[i], centres[i, j], xi


def road_births(road: Road, s_ego: float, ego_speed: float, lidar_range: float, config: BirthConfig) -> tuple[np.ndarray, np.ndarray]:
    """Components per driving lane present at ``s_ego +- (lidar_range - range_margin)`` (m), heading
    with the lane's traffic; on an open road only those on the road. Speed: ``config.speed`` or the ego's."""
    s_rows, n_rows, xi_rows = _lane_rows(road, _birth_arc_lengths(road, s_ego, lidar_range, config))
    speed = ego_speed if config.speed is None else config.speed
    means = np.zeros((len(s_rows), 7))
    means[:, 0], means[:, 1], means[:, 3] = s_rows, n_rows, xi_rows
    means[:, 2] = speed
    means[:, 5], means[:, 6] = config.length, config.width
    return means, birth_covariance(config, len(means))


def entering_view(rect: Rectangles, tracks: Rectangles, track_labels: np.ndarray, gate_distance: float) -> np.ndarray:
    """Which birth rectangles ``rect`` (E) a vehicle can enter the view in: less than half of each hidden
    by the tracks' rectangles ``tracks`` (``occluded_fraction``) and its centre farther than
    ``gate_distance`` (m) from every track's."""
    hidden = occluded_fraction(rect, np.full(len(rect.center), -1), tracks, track_labels)
    gap = np.linalg.norm(rect.center[:, None, :] - tracks.center[None, :, :], axis=2).min(axis=1)
    return (hidden < 0.5) & (gap > gate_distance)


def with_acceleration(means: np.ndarray, covs: np.ndarray, acceleration_var: float | None) -> tuple[np.ndarray, np.ndarray]:
    """Birth components ``(B, 7)`` with the acceleration state appended (``a = 0``, variance
    ``acceleration_var``, m^2/s^4); None: returned as they are (no acceleration state)."""
    if acceleration_var is None:
        return means, covs
    m = np.zeros((len(means), 8))
    p = np.zeros((len(means), 8, 8))
    m[:, :7], p[:, :7, :7] = means, covs
    p[:, 7, 7] = acceleration_var
    return m, p


def visible_road_births(road: Road, s_ego: float, ego: EgoState, lidar_range: float, config: BirthConfig,
                        acceleration_var: float | None, tracks: Rectangles, track_labels: np.ndarray,
                        gate_distance: float) -> tuple[np.ndarray, np.ndarray]:
    """``road_births`` (curvilinear) with the acceleration state appended (``a = 0``, variance
    ``acceleration_var``; None: no acceleration state) and, where there are tracks (``track_labels``
    not empty; their rectangles ``tracks`` in E), only the components ``entering_view`` keeps. One
    compiled call (``road_births_kernel``)."""
    if len(track_labels) != len(tracks.center):
        raise ValueError(f"visible_road_births needs one label per track; got {len(track_labels)} labels and "
                         f"{len(tracks.center)} tracks")
    kind, *curve = road._curve.kernel_args()
    return road_births_kernel(
        *_lane_rows(road, _birth_arc_lengths(road, s_ego, lidar_range, config)),
        float(ego.v if config.speed is None else config.speed), float(config.length), float(config.width),
        _diagonal_variances(_birth_spreads(config)), 0.0 if acceleration_var is None else float(acceleration_var),
        7 if acceleration_var is None else 8, kind, float(ego.x), float(ego.y), float(ego.yaw), road.closed, road.length,
        road._ends_array, *curve, MIN_EXTENT, np.ascontiguousarray(tracks.corners()),
        np.ascontiguousarray(tracks.center, dtype=float), np.ascontiguousarray(track_labels, dtype=np.int64),
        float(gate_distance))


SPARSE_POINTS = 3
"""A cluster of fewer points than this shows no orientation (``cluster_births``)."""

SHADOW_SIDE_MIN = 0.5
"""m: a cluster's shadowed end says on which side of the points an unseen extent lies only along a
direction in which its two ends lie at least this far apart (``cluster_births``, ``shadowed``): across a
side, both ends of the side lie on the same line."""


def shadow_side(shadowed_end: np.ndarray, free_end: np.ndarray, direction: np.ndarray) -> float:
    """On which side of a cluster along ``direction`` (unit, E) its unseen part lies when one end
    (``shadowed_end``, E, m) borders another object's shadow and the other (``free_end``) does not:
    ``+1`` or ``-1`` (the shadowed end's side), ``0`` when the ends lie less than ``SHADOW_SIDE_MIN``
    apart along it (the shadow says nothing there)."""
    along = float((np.asarray(shadowed_end) - np.asarray(free_end)) @ direction)
    return 0.0 if abs(along) < SHADOW_SIDE_MIN else float(np.sign(along))


def _fewest_points(config: BirthConfig, points: np.ndarray, fused: bool) -> int:
    """The fewest points an unexplained cluster ``points (N, 2)`` (E, m) needs to seed a birth:
    ``min_cluster_points``; when a radar detection joined it, ``min_cluster_points_fused`` (if set, at
    any range) or ``min_cluster_points_radar`` (if set, when it lies at least ``sparse_min_range`` from
    the ego), whichever is fewer."""
    fewest = config.min_cluster_points
    if fused and len(points):
        if config.min_cluster_points_fused is not None:
            fewest = min(fewest, config.min_cluster_points_fused)
        if config.min_cluster_points_radar is not None and float(np.min(np.hypot(points[:, 0], points[:, 1]))) >= config.sparse_min_range:
            fewest = min(fewest, config.min_cluster_points_radar)
    return fewest


def cluster_births(
    clusters: list[np.ndarray],
    velocities: list[np.ndarray | None],
    ego: EgoState,
    road: Road,
    config: BirthConfig,
    shadowed: list[tuple[np.ndarray, np.ndarray] | None] | None = None,
    prior_speeds: list[tuple[float, float] | None] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Components from unexplained clusters (points (N, 2) in E at the ego pose ``ego``), each with an
    optional radar velocity ``(vx, vy)`` in E (m/s). ``prior_speeds`` (per cluster, None: none): the
    speed and its std (m/s) that a birth without a radar velocity takes instead of ``config.speed`` (the
    ego's) and ``config.speed_std``: its lane's flow (``tracker.flow``). ``shadowed`` (per cluster, None: none): the
    cluster's end in bearing that borders another object's shadow and its other, free end (E, m), where
    exactly one does: where the shadowed end is the one nearer the sensor
    along the length, the unseen part of the length may lie beyond the points or behind the object, so
    the centre stays at the points' along it and the position takes half the unseen length as its
    spread, uncorrelated with ``L``. Clusters with fewer than
    ``config.min_cluster_points`` points are skipped, unless a radar detection joined them and they
    have ``config.min_cluster_points_fused``, or they lie ``config.sparse_min_range`` or farther and have
    ``config.min_cluster_points_radar`` (``_fewest_points``); a cluster of fewer than ``SPARSE_POINTS``
    takes the road's direction as its heading, and so does one shorter than
    ``config.min_oriented_extent`` on both sides of its fit (its extent then measured along and across
    that direction, its unseen length and width beyond it as for any other cluster)."""
    means, stds, length_stds, sparse, levers, spreads = [], [], [], [], [], []
    if shadowed is None:
        shadowed = [None] * len(clusters)
    if prior_speeds is None:
        prior_speeds = [None] * len(clusters)
    for pts, vel, shadow, prior in zip(clusters, velocities, shadowed, prior_speeds):  # a handful per frame; the fit is vectorised
        if len(pts) < _fewest_points(config, pts, vel is not None):
            continue
        sparse_k = len(pts) < SPARSE_POINTS
        fit = fit_rectangle(pts)
        # a few centimetres of points (a corner, the end of a side behind another vehicle) show no
        # orientation either: their fitted axes are noise, which the quarter turn below would keep
        short_k = not sparse_k and max(fit.length, fit.width) < config.min_oriented_extent
        # the fit's axes are ambiguous by quarter turns: take the one closest to the direction of the
        # traffic in the lane there (vehicles drive along their lane: pi from the road's in an oncoming
        # lane), swapping length and width for an odd quarter turn
        probe = to_global(fit.center[None, :], (ego.x, ego.y), ego.yaw)[0]
        s_fit, n_fit = road.to_frenet(probe)
        theta_road = float(road.frame(np.array([s_fit]), extrapolate=True)[1][0])
        lane_xi = np.pi if road.two_way and int(road.lane_direction(s_fit, n_fit)) < 0 else 0.0
        theta_fit = theta_road + lane_xi
        course = crossing_course(vel, theta_fit - ego.yaw, config.crossing_min_speed)
        if course is not None:  # not following its lane (crossing it): the radar's course is the direction
            theta_fit = course + ego.yaw
            lane_xi = float(wrap_angle(theta_fit - theta_road))
        if sparse_k or short_k:  # no orientation in one or two points, or a short cluster: the lane's direction
            psi_e = theta_fit - ego.yaw
        else:
            turns = np.arange(4)
            xi_k = wrap_angle(fit.heading + ego.yaw + 0.5 * np.pi * turns - theta_fit)
            k = int(np.argmin(np.abs(xi_k)))
            psi_e = fit.heading + 0.5 * np.pi * k
            fit_len, fit_wid = (fit.length, fit.width) if k % 2 == 0 else (fit.width, fit.length)
        axis = np.array([np.cos(psi_e), np.sin(psi_e)])
        lateral = np.array([-axis[1], axis[0]])
        if sparse_k or short_k:  # the points' extent along and across the road's direction
            fit_len, fit_wid = np.ptp((pts - fit.center) @ np.column_stack([axis, lateral]), axis=0)
        length, width = max(fit_len, config.length), max(fit_wid, config.width)
        length_std, long = config.length_std, False
        if config.classes is not None:  # the classes' length given the fitted width (tracker.extent.class_length_prior)
            class_length, class_var = class_length_prior(float(fit_wid), config.fit_width_std**2,
                                                         *class_arrays(config.classes, config.width_error_std))
            if class_length - length > config.length_std:  # beyond the car prior's spread: the rest is unseen
                length, length_std = class_length, math.sqrt(max(class_var, config.length_std**2))
                long = class_var > config.length_std**2  # too wide a spread for the centre's linear shift
        # no road vehicle is longer or wider than the limits: a larger cluster is two vehicles' points (or
        # a vehicle's and a roadside object's); the birth keeps the end nearest the sensor, as the
        # update projects its estimates back onto the limits (tracker.update.update_pairs)
        if config.max_length is not None:
            length = min(length, config.max_length)
        if config.max_width is not None:
            width = min(width, config.max_width)
        centre = fit.center.copy()
        # the unseen extent lies beyond the points; a sparse cluster's points most likely lie across a
        # rear or a front, so it is not shifted sideways
        unseen = ((axis, length - fit_len),) if sparse_k else ((axis, length - fit_len), (lateral, width - fit_wid))
        shifts = np.zeros((2, 2))  # per extent (L, W): the centre's shift in E per metre of it (0: none)
        either = np.zeros(2)  # half the unseen length, along it, where its side is unknown (E, m)
        for k, (direction, missing) in enumerate(unseen):
            away = 1.0 if float(centre @ direction) >= 0.0 else -1.0  # the unseen half lies beyond
            if k == 0 and shadow is not None and missing > 0.0 and shadow_side(shadow[0], shadow[1], direction) == -away:
                # ... or, along the length, behind the object whose shadow the near end borders: either side
                either = 0.5 * missing * direction
                continue
            centre += away * 0.5 * missing * direction
            if missing > 0.0 and not long:
                shifts[k] = away * 0.5 * direction
        centre_g = to_global(centre[None, :], (ego.x, ego.y), ego.yaw)[0]
        s, n = road.to_frenet(centre_g, s_hint=s_fit)
        _, theta, curvature = road.frame(np.array([s]), extrapolate=True)
        # the shifts in road coordinates: E's axes turned onto the road's (e_s, e_n), s scaled by the
        # road metric 1 / (1 - kappa n)
        metric = [1.0 / max(1.0 - float(curvature[0]) * n, 0.1), 1.0]
        levers.append(rotate(shifts, ego.yaw - theta[0]) * metric)
        spreads.append(rotate(either, ego.yaw - theta[0]) * metric)
        xi = lane_xi if sparse_k and course is None else float(wrap_angle(psi_e + ego.yaw - theta[0]))
        along = None if vel is None else float(vel @ np.array([np.cos(psi_e), np.sin(psi_e)]))
        if along is not None and not (road.two_way and along < -BACKWARD_SPEED):
            speed, speed_std = along, None
        elif prior is not None:  # no radar, or one against the lane's traffic: the lane's flow
            speed, speed_std = prior
        else:  # no radar, or (two-way road) a radar velocity against the lane's traffic: another vehicle's
            speed, speed_std = ego.v if config.speed is None else config.speed, config.speed_std
        means.append([s, n, speed, xi, 0.0, length, width])
        stds.append(speed_std if speed_std is not None else 1.0)
        length_stds.append(length_std)
        sparse.append(sparse_k)
    if not means:
        return np.zeros((0, 7)), np.zeros((0, 7, 7))
    covs = birth_covariance(config, len(means))
    covs[:, 2, 2] = np.array(stds) ** 2
    covs[:, 5, 5] = np.array(length_stds) ** 2
    covs[:, 0, 0] = covs[:, 1, 1] = 0.5**2  # the fit locates a cluster's rectangle to a few decimetres
    # one or two points may lie on the rear or on a side: the centre is known to about half a length
    covs[np.array(sparse), 0, 0] = (0.5 * config.length) ** 2
    correlate_unseen_extent(covs, np.array(levers), ~np.array(sparse))
    g = np.array(spreads)  # (B, 2) in (s, n): an unseen half that may lie on either side of the points
    covs[:, :2, :2] += g[:, :, None] * g[:, None, :]
    return np.array(means), covs


def correlate_unseen_extent(covs: np.ndarray, levers: np.ndarray, rows: np.ndarray) -> None:
    """Give the births ``rows`` (mask) the covariance of a centre placed half an unseen extent beyond
    the points, in place.

    A cluster birth's centre is the fit's visible edge plus half the extent the points do not show:
    ``(s, n) = e + g_L L + g_W W`` with ``e`` the edge (spread ``P_e``, the diagonal position block
    already in ``covs``) and ``g_L``, ``g_W`` (``levers (B, 2, 2)``: per extent, the shift of ``(s, n)``
    per metre of it; 0 where the extent was seen whole) half the unit direction away from the sensor.
    Hence::

        P[sn, sn] = P_e + g_L g_L^T var(L) + g_W g_W^T var(W),   P[sn, L] = g_L var(L),   P[sn, W] = g_W var(W)

    Without the correlation the unseen length's uncertainty would sit in ``s`` independently of ``L``:
    seen from the rear, with the length held (``MeasurementConfig.hold_unobserved_extent``, ``tracker.extent``), the filter
    would keep the rear's along-road position (``s - L/2``) uncertain by the length's spread for
    seconds, although the lidar fixes it to centimetres, and the lidar would then tell it little about
    the speed. With the correlation the first update pins the visible edge."""
    for k, index in ((0, 5), (1, 6)):  # (levers slot, extent index): L, W
        g = levers[:, k, :] * rows[:, None]  # (B, 2)
        var = covs[:, index, index]
        covs[:, :2, :2] += np.einsum("bi,bj->bij", g, g) * var[:, None, None]
        covs[:, :2, index] = g * var[:, None]
        covs[:, index, :2] = g * var[:, None]


def to_cartesian_gaussians(
    road: Road, means: np.ndarray, covs: np.ndarray, ut: UnscentedTransform | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Curvilinear Gaussians (B, 7) / (B, 7, 7) to Cartesian ``[x, y, v, psi, psi_dot, L, W]`` ones by
    the unscented transform of ``tracker.track.curvilinear_to_cartesian`` (batched)."""
    if len(means) == 0:
        return means.copy(), covs.copy()
    ut = ut if ut is not None else UnscentedTransform()
    wrap_in = Wrapping(angles=(3,), periods=((0, road.length),) if road.closed else ())
    mean, cov, _ = ut.transform(lambda x: curvilinear_to_cartesian(road, x), means, covs, wrap_in, Wrapping(angles=(3,)))
    return mean, cov

# --------------------------------------------------------------------------------------------------
# The compiled kernels of this stage: the road births of a frame with the acceleration state and the
# test of where a vehicle can enter the view (``visible_road_births``) in one call (``road_births_kernel``):
# the components per lane, their rectangles in E (``to_vehicle_kernel``), the part of each hidden by the
# tracks (``detection._spans``, ``detection._occluded``) and the distance to the nearest track's centre.
# --------------------------------------------------------------------------------------------------


@njit
def road_births_kernel(s, lateral, heading, speed, length_prior, width_prior, cov7, accel_var, dim, kind, ego_x, ego_y,
                       ego_yaw, closed, length, ends, table, bucket_cell, starts_next, inv_bucket, hops, nodes, weights,
                       min_extent, track_corners, track_centers, track_labels, gate_distance):  # pragma: no cover - compiled
    """Birth components ``(means (B, dim), covs (B, dim, dim))`` at the road points ``(s, lateral)`` (m)
    with headings ``heading`` (rad; one row each: ``_lane_rows``), speed ``speed``, extent ``length_prior``
    x ``width_prior``, covariance ``cov7 (7, 7)`` (and ``accel_var`` for the acceleration state when
    ``dim`` is 8); where tracks are given (``track_labels`` not empty: their rectangles' corners and
    centres in E), only those whose rectangle in E (the ego at ``ego_x, ego_y, ego_yaw`` in G) is less
    than half hidden by the tracks (``occluded_fraction``) and lies farther than ``gate_distance`` (m)
    from every track's centre."""
    count = len(s)
    means = np.zeros((count, dim))
    for row in range(count):
        means[row, 0] = s[row]
        means[row, 1] = lateral[row]
        means[row, 2] = speed
        means[row, 3] = heading[row]
        means[row, 5] = length_prior
        means[row, 6] = width_prior
    keep = np.ones(count, dtype=np.bool_)
    if count and len(track_labels):
        center, _psi, corners = to_vehicle_kernel(kind, means, ego_x, ego_y, ego_yaw, closed, length, ends, table,
                                                  bucket_cell, starts_next, inv_bucket, hops, nodes, weights, min_extent)
        lo, hi, rng, _near = _spans(corners, center)
        hidden = _occluded(lo, hi, rng, np.full(count, -1, dtype=np.int64), track_corners, track_centers, track_labels)
        for b in range(count):
            gap = np.inf
            for t in range(len(track_labels)):
                dx = center[b, 0] - track_centers[t, 0]
                dy = center[b, 1] - track_centers[t, 1]
                gap = min(gap, math.sqrt(dx * dx + dy * dy))
            keep[b] = hidden[b] < 0.5 and gap > gate_distance
    kept = 0
    for b in range(count):
        kept += keep[b]
    out_means = np.empty((kept, dim))
    out_covs = np.zeros((kept, dim, dim))
    k = 0
    for b in range(count):
        if not keep[b]:
            continue
        out_means[k] = means[b]
        for r in range(7):
            for c in range(7):
                out_covs[k, r, c] = cov7[r, c]
        if dim == 8:
            out_covs[k, 7, 7] = accel_var
        k += 1
    return out_means, out_covs
