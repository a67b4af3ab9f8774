"""The UKF update of Gaussians by clusters, batched over (component, cluster) pairs.

For a pair with predicted state sigma points ``X_i`` (around ``m``, ``P``) and predicted measurement
sigma points ``Z_i = h(X_i)`` (``tracker.measurement``, ``D`` rows, ``R = diag(r)``)::

    y = sum Wm_i Z_i,   S = sum Wc_i (Z_i - y)(Z_i - y)^T + R,   T = sum Wc_i (X_i - m)(Z_i - y)^T
    K = T S^-1,   m+ = m + K (z - y),   P+ = P - K S K^T = P - T S^-1 T^T
    log N(z; y, S) = -1/2 (D log 2 pi + log det S + (z - y)^T S^-1 (z - y))

(the paper's equations Update_eq2..7). The measurement noise may carry low-rank terms,
``R = diag(r) + F^T F`` (the rectangle model's end-gap uncertainty, ``tracker.measurement``). ``S`` is ``D x D`` with ``D = 2 |C| (+ 2 radar rows)`` but has
rank ``2n + 1 = 15`` above ``R``: with ``A = R^-1/2 [sqrt(Wc_i) (Z_i - y)]`` (``D x 15``, all ``Wc_i >= 0``,
which ``UKFParams`` guarantees) and ``M = I + A^T A`` (15 x 15, SPD), the matrix inversion lemma gives
``S^-1 = R^-1/2 (I - A M^-1 A^T) R^-1/2`` and ``det S = det R det M``. Everything above is computed from
the Gram matrix ``A^T A`` and ``A^T R^-1/2 (z - y)``: the cost is ``O(D n^2)`` per pair instead of
``O(D^3)``, exact (not an approximation), and batched over pairs with padded rows masked out. The
noise factors ``F`` join ``A`` as extra columns (weight 1, no state deviation).

``kalman_update`` is one call of ``tracker.kalman.kalman_kernel`` over the pairs. ``update_pairs`` of
curvilinear states with the exact conversion to E is one call of ``tracker.pairs.update_pairs_kernel``,
from the sigma points' rectangles through the measurement structure, the extent growth, the predicted
measurements, the radar gate and the update to the extent rules; where that call hands the pairs back
(a widened prior, a non-finite or not positive definite input), and for Cartesian states and the
paper's Euler conversion, the same steps run one kernel at a time (``tracker.structure``,
``tracker.extent``, ``tracker.kalman.measurement_update_kernel``): the same numbers. The kernels wrap at
most one periodic coordinate (``s`` on a closed road).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from tracker.config import VEHICLE_CLASSES, MeasurementConfig, TrackerConfig
from tracker.extent import class_arrays, extent_rules_kernel, grow_extent_kernel
from tracker.frame import EgoState
from tracker.indices import unique_indices
from tracker.kalman import kalman_kernel, measurement_update_kernel
from tracker.measurement import (GROWTH_MIN_EXCESS, GROWTH_SIGMAS, MIN_EXTENT, Cluster, ClusterBatch, Rectangles,
                                 Structure, build_structure, prepare_settings,
                                 structure_batch_args, structure_config_args, to_vehicle)
from tracker.motion import CARTESIAN_WRAPPING, LENGTH, WIDTH, curvilinear_wrapping
from tracker.preparation import prepare_scanned_batch
from tracker.road import Road
from tracker.ukf import UnscentedTransform, Wrapping
from tracker.centerline import sigma_rectangles_kernel
from tracker.pairs import DONE, prepared_pairs_kernel, update_pairs_kernel



@dataclass(frozen=True)
class UpdateResult:
    """Posterior of each pair: ``mean (P, 7)``, ``cov (P, 7, 7)``; ``log_likelihood (P,)`` =
    ``log N(z; y, S)`` (natural log, of the stacked measurement in its units); ``nis (P,)`` the normalised
    innovation squared ``(z - y)^T S^-1 (z - y)``; ``dim (P,)`` the measurement dimension ``D``;
    ``predicted (P, D_max)`` the predicted measurement ``y`` (padded rows 0); ``innovation (P, D_max)``;
    ``radar_rejected (P,)`` (``update_pairs``; None from ``kalman_update``): the pair's cluster had a
    radar velocity that the radar gate (``MeasurementConfig.radar_gate``) set aside."""

    mean: np.ndarray
    cov: np.ndarray
    log_likelihood: np.ndarray
    nis: np.ndarray
    dim: np.ndarray
    predicted: np.ndarray
    innovation: np.ndarray
    radar_rejected: np.ndarray | None = None

    def __getitem__(self, i: int) -> UpdateResult:
        """The result of pair ``i`` (arrays keep a leading axis of length 1)."""
        sl = slice(i, i + 1) if i != -1 else slice(-1, None)
        return UpdateResult(*(None if getattr(self, f) is None else getattr(self, f)[sl] for f in self.__dataclass_fields__))


def kalman_update(
    ut: UnscentedTransform,
    sigma: np.ndarray,
    mean: np.ndarray,
    cov: np.ndarray,
    z_sigma: np.ndarray,
    z: np.ndarray,
    r: np.ndarray,
    mask: np.ndarray | None = None,
    wrapping: Wrapping = Wrapping(),
    factors: np.ndarray | None = None,
    r_likelihood: np.ndarray | None = None,
) -> UpdateResult:
    """UKF update of ``P`` Gaussians (``mean (P, n)``, ``cov (P, n, n)``, their sigma points
    ``sigma (P, S, n)``) by measurements ``z (P, D)`` with predicted measurement sigma points
    ``z_sigma (P, S, D)``, noise ``R = diag(r) + sum_e f_e f_e^T`` (variances ``r (P, D)``, optional
    low-rank ``factors (P, E, D)``) and row mask ``mask (P, D)`` (False rows are padding and take no
    part). Low-rank form, see the module docstring: the noise factors enter like extra sigma-point
    columns with weight 1 and no state deviation. ``r_likelihood (P, D)`` (default ``r``): the variances
    of the log-likelihood and NIS, where they differ from the update's
    (``MeasurementConfig.shadowed_lidar_sigma`` softens the update, not the weights or the gate).
    By ``tracker.kalman.kalman_kernel``; a pair whose predicted measurement or noise factors are not
    finite comes out NaN (mean, covariance, likelihood and NIS). At most one periodic coordinate."""
    sigma, mean, cov = (np.asarray(a, dtype=float) for a in (sigma, mean, cov))
    z_sigma, z, r = (np.asarray(a, dtype=float) for a in (z_sigma, z, r))
    mask = np.ones(z.shape, dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
    if z_sigma.shape[:2] != sigma.shape[:2] or z_sigma.shape[2] != z.shape[1] or r.shape != z.shape:
        raise ValueError(
            f"kalman_update: inconsistent shapes sigma {sigma.shape}, z_sigma {z_sigma.shape}, z {z.shape}, r {r.shape}"
        )
    _check_noise(r, mask)
    r_like = r if r_likelihood is None else np.asarray(r_likelihood, dtype=float)
    if r_like is not r:
        if r_like.shape != r.shape:
            raise ValueError(f"kalman_update: r_likelihood {r_like.shape} must have the shape of r {r.shape}")
        _check_noise(r_like, mask)
    if len(wrapping.periods) > 1:
        raise ValueError(f"kalman_update wraps at most one periodic coordinate; got {len(wrapping.periods)}")
    extra = np.zeros((z.shape[0], 0, z.shape[1])) if factors is None else np.asarray(factors, dtype=float)
    # a pair whose predicted measurement or noise factors are not finite has no posterior (NaN); the others
    # are updated alone (the kernel treats every pair on its own, so they get the numbers of a full batch)
    unused = ~mask[:, None, :]  # padded rows take no part
    finite = (np.isfinite(z_sigma) | unused).all(axis=(1, 2)) & (np.isfinite(extra) | unused).all(axis=(1, 2))
    if finite.all():
        contiguous = (np.ascontiguousarray(a) for a in (sigma, mean, cov, z_sigma, z, r, r_like, mask, extra))
        return UpdateResult(*kalman_kernel(*contiguous, ut.wm, ut.wc, *wrapping.kernel_args()))
    good = np.flatnonzero(finite)
    with np.errstate(invalid="ignore"):
        predicted = (ut.wm @ z_sigma) * mask
    out = UpdateResult(np.full(mean.shape, np.nan), np.full(cov.shape, np.nan), np.full(len(z), np.nan),
                       np.full(len(z), np.nan), mask.sum(axis=1).astype(np.int64), predicted, (z - predicted) * mask)
    if len(good):
        part = (np.ascontiguousarray(a[good]) for a in (sigma, mean, cov, z_sigma, z, r, r_like, mask, extra))
        done = UpdateResult(*kalman_kernel(*part, ut.wm, ut.wc, *wrapping.kernel_args()))
        for field in ("mean", "cov", "log_likelihood", "nis", "dim", "predicted", "innovation"):
            getattr(out, field)[good] = getattr(done, field)
    return out


def _check_noise(r: np.ndarray, mask: np.ndarray) -> None:
    """A clear error for a measurement noise variance (of a row in use) that is not positive."""
    if np.any(r[mask] <= 0):
        raise ValueError("kalman_update: measurement noise variances r must be > 0")


def state_wrapping(road: Road | None, coordinates: str) -> Wrapping:
    """Wrapped state coordinates: ``xi`` (or ``psi``), and ``s`` on a closed road (curvilinear)."""
    if coordinates == "cartesian":
        return CARTESIAN_WRAPPING
    if road is None:
        raise ValueError("a curvilinear state needs the road")
    return curvilinear_wrapping(road)


def update_pairs(
    means: np.ndarray,
    covs: np.ndarray,
    clusters: list[Cluster] | ClusterBatch,
    component_index: np.ndarray,
    cluster_index: np.ndarray,
    ego: EgoState | tuple,
    road: Road | None,
    config: TrackerConfig | None = None,
    ut: UnscentedTransform | None = None,
) -> UpdateResult:
    """Update components ``means (C, D)``, ``covs (C, D, D)`` (``D = 7``, or 8 with the acceleration state) by prepared ``clusters`` (lidar points in
    E at the ego pose ``ego``; a list of ``Cluster`` or their ``ClusterBatch``) for the pairs ``(component_index[p], cluster_index[p])``; returns one
    posterior and log-likelihood per pair. Sigma points and their rectangles in E are computed once per
    component; the measurement structure is built from each component's mean (``tracker.measurement``).
    ``config.coordinates`` selects the curvilinear (needs ``road``) or Cartesian state;
    ``config.use_radar`` the velocity rows of fused clusters."""
    config = config if config is not None else TrackerConfig()
    means = np.asarray(means, dtype=float)
    dim = means.shape[-1]  # 7, or 8 with the motion model's acceleration state
    means = means.reshape(-1, dim)
    ut = ut if ut is not None else UnscentedTransform(config.ukf, n=dim)
    covs = np.asarray(covs, dtype=float).reshape(-1, dim, dim)
    comp = np.asarray(component_index, dtype=np.intp).reshape(-1)
    clu = np.asarray(cluster_index, dtype=np.intp).reshape(-1)
    if comp.shape != clu.shape:
        raise ValueError(f"component_index and cluster_index must pair up; got {comp.shape} and {clu.shape}")
    batch = clusters if isinstance(clusters, ClusterBatch) else (ClusterBatch.of(clusters) if len(clusters) else None)
    n_clusters = 0 if batch is None else len(batch.points)
    if len(comp) and (comp.min() < 0 or comp.max() >= len(means) or clu.min() < 0 or clu.max() >= n_clusters):
        raise ValueError("update_pairs: a pair refers to a component or cluster that does not exist")
    wrapping = state_wrapping(road, config.coordinates)
    if len(comp) == 0:
        d = 2 * (0 if batch is None else batch.points.shape[1]) + 2
        return UpdateResult(np.zeros((0, dim)), np.zeros((0, dim, dim)), np.zeros(0), np.zeros(0), np.zeros(0, dtype=int),
                            np.zeros((0, d)), np.zeros((0, d)), np.zeros(0, dtype=bool))
    used, inverse = unique_indices(comp, len(means))
    euler_s0 = None
    if config.measurement.conversion == "euler" and config.coordinates == "curvilinear":
        ego_state = EgoState.coerce(ego)
        euler_s0 = float(road.to_frenet((ego_state.x, ego_state.y))[0])  # the paper integrates from the ego
    if euler_s0 is None and batch is not None:
        fused = _update_pairs_fused(means[used], covs[used], inverse, clu, batch, ego, road, config, ut, wrapping)
        if fused is not None:
            return fused
    sigma, rect = sigma_rectangles(ut, means[used], covs[used], wrapping, ego, road, config.coordinates, euler_s0)
    mean_corners = rect.take((slice(None), 0)).corners()  # (U, 4, 2): the central sigma point is the mean
    pair_means, pair_covs = means[comp], covs[comp]
    extent_sd = np.sqrt(np.maximum(np.stack([pair_covs[:, LENGTH, LENGTH], pair_covs[:, WIDTH, WIDTH]], axis=1), 0.0))
    structure = build_structure(batch, clu, mean_corners[inverse], config.measurement, config.use_radar,
                                extent_sd=extent_sd, lidar_range=config.detection.lidar_range)
    pair_sigma, pair_rect = sigma[inverse], rect.take(inverse)
    if config.measurement.grow_extent:
        grown, grown_covs = grow_extent(pair_means, pair_covs, structure, mean_corners[inverse])
        if grown.any():  # new sigma points for the pairs whose prior was widened (rare: a side came into view)
            pair_covs = grown_covs
            pair_sigma = pair_sigma.copy()
            pair_sigma[grown] = ut.sigma_points(pair_means[grown], grown_covs[grown], wrapping)
            pair_rect = to_vehicle(pair_sigma, ego, road, config.coordinates, euler_s0)
    res = _measure(ut, pair_sigma, pair_means, pair_covs, pair_rect, structure, clu, config.measurement.radar_gate,
                   wrapping, likelihood_variances(structure, config.measurement))
    return apply_extent_rules(res, pair_means, pair_covs, structure, mean_corners[inverse], config)


#: A held length is still unmeasured while its standard deviation is at least this fraction of
#: ``BirthConfig.length_std``: every birth starts at ``length_std`` or wider, the vehicle classes' prior only
#: widens it, and only a side seen whole narrows it.
UNMEASURED = 0.9

#: A held length whose standard deviation exceeds this multiple of ``BirthConfig.length_std`` is the
#: vehicle classes' prior, not a fit: a birth's fitted length has ``length_std``, and only the classes'
#: mixture (a truck's or bus's length among a car's) is wider. Such a length is the classes' prior given
#: an earlier width, and follows the width as the updates measure it: longer, and shorter where the
#: classes' spread is at most ``length_std`` (the width rules out the long classes).
CLASS_PRIOR = 1.5


def _extent_rule_args(config: TrackerConfig) -> tuple:
    """The settings' arguments of the compiled extent rules (``tracker.extent.extent_rules_kernel``
    after its arrays): the hold, the vehicle classes' size prior (its arrays, the variances of an
    unmeasured length (``UNMEASURED``) and of the classes' own prior (``CLASS_PRIOR``), the largest
    classes' variance that may shorten it, the car's prior length below which the classes may shorten
    a held length) and the smallest and largest vehicle."""
    b = config.birth
    return ((bool(config.measurement.hold_unobserved_extent), b.classes is not None)
            + class_arrays(b.classes or VEHICLE_CLASSES, b.width_error_std)
            + ((UNMEASURED * b.length_std)**2, (CLASS_PRIOR * b.length_std)**2, b.length_std**2, float(b.length),
               float(b.min_length), float(b.min_width),
               math.inf if b.max_length is None else float(b.max_length),
               math.inf if b.max_width is None else float(b.max_width)))


def _fused_update_applies(config: TrackerConfig, road: Road | None, wrapping: Wrapping) -> bool:
    """Whether the update of the pairs may take its one compiled call (``update_pairs_kernel``, also
    inside ``prepared_pairs_kernel``): the curvilinear state with its road, the exact conversion to E
    (not the paper's Euler one, ``MeasurementConfig.conversion``) and at most one periodic coordinate."""
    return (config.coordinates == "curvilinear" and road is not None and config.measurement.conversion != "euler"
            and len(wrapping.periods) <= 1)


def update_clusters(
    means: np.ndarray, covs: np.ndarray, points: np.ndarray, offsets: np.ndarray, velocity: np.ndarray,
    has_velocity: np.ndarray, component_index: np.ndarray, cluster_index: np.ndarray, scan: np.ndarray,
    ego: EgoState | tuple, road: Road | None, config: TrackerConfig, ut: UnscentedTransform,
) -> tuple[UpdateResult, int | None, int | None]:
    """The GM-PHD update of the pairs ``(component_index[p], cluster_index[p])``: the clusters in some
    pair, ``points[offsets[k]:offsets[k + 1]]`` (E, m) with their radar velocities ``velocity[k]`` (m/s)
    where ``has_velocity[k]``, prepared by ``tracker.preparation.prepare_scanned_batch`` in the frame's
    lidar returns ``scan`` (``config.detection``'s resolution and range), then ``update_pairs`` of the
    components in some pair. Returns the result and the numbers of the prepared clusters' ends in a
    shadow and continued (``ClusterBatch.occluded_end``, ``continued_end``; None where that flag is
    off). One compiled call (``tracker.pairs.prepared_pairs_kernel``: the same kernels in the
    same order, the same numbers) where the fused update applies (``_update_pairs_fused``) and every
    cluster in some pair is non-empty and finite; else the two steps."""
    comp = np.asarray(component_index, dtype=np.intp).reshape(-1)
    clu = np.asarray(cluster_index, dtype=np.intp).reshape(-1)
    offsets = np.asarray(offsets, dtype=np.intp).reshape(-1)
    if comp.shape != clu.shape:
        raise ValueError(f"component_index and cluster_index must pair up; got {comp.shape} and {clu.shape}")
    if not len(offsets) or offsets[0] != 0 or offsets[-1] != len(points) or (np.diff(offsets) < 0).any():
        raise ValueError(f"update_clusters: offsets must rise from 0 to the number of points ({len(points)}); "
                         f"got {offsets.tolist()}")
    if len(comp) and (comp.min() < 0 or comp.max() >= len(means) or clu.min() < 0 or clu.max() >= len(offsets) - 1):
        raise ValueError("update_clusters: a pair refers to a component or cluster that does not exist")
    fused = _update_clusters_fused(means, covs, points, offsets, velocity, has_velocity, comp, clu, scan, ego, road,
                                   config, ut)
    if fused is not None:
        return fused
    det, mcfg = config.detection, config.measurement
    used, slot = unique_indices(clu, len(offsets) - 1)
    clusters = [points[offsets[k]:offsets[k + 1]] for k in used.tolist()]
    velocities = [velocity[k] if has_velocity[k] else None for k in used.tolist()]
    batch = prepare_scanned_batch(clusters, mcfg, velocities, scan, det.lidar_resolution, det.lidar_range)
    res = update_pairs(means, covs, batch, comp, slot, ego, road, config, ut)
    occluded = None if batch.occluded_end is None else int(np.count_nonzero(batch.occluded_end))
    continued = None if batch.continued_end is None else int(np.count_nonzero(batch.continued_end))
    return res, occluded, continued


def _fused_settings(config: TrackerConfig) -> tuple[tuple, tuple, tuple, bool, bool]:
    """The settings' arguments of ``prepared_pairs_kernel`` (the preparation's, the shadow flags', the
    update's from ``min_apparent`` on) and whether the shadow and continuation flags are on; built once
    per configuration (a frozen dataclass: kept in its instance dictionary, outside its fields)."""
    cached = config.__dict__.get("_fused_update_settings")
    if cached is None:
        mcfg, det = config.measurement, config.detection
        shadows = mcfg.shadow_window is not None
        continuation = shadows and mcfg.continuation_rays is not None
        window = mcfg.shadow_window * det.lidar_resolution if shadows else 0.0
        scanned = (shadows, float(window), float(mcfg.shadow_margin), float(det.lidar_range),
                   float(mcfg.shadow_range_margin), continuation, float(mcfg.continuation_rays or 0.0),
                   float(mcfg.continuation_offset))
        head, tail = structure_config_args(mcfg, config.use_radar, det.lidar_range)
        update = (MIN_EXTENT, *head, *tail, bool(mcfg.grow_extent), GROWTH_MIN_EXCESS, GROWTH_SIGMAS,
                  -1.0 if mcfg.radar_gate is None else float(mcfg.radar_gate), *_extent_rule_args(config))
        cached = (prepare_settings(mcfg), scanned, update, shadows, continuation)
        config.__dict__["_fused_update_settings"] = cached
    return cached


def _update_clusters_fused(means: np.ndarray, covs: np.ndarray, points: np.ndarray, offsets: np.ndarray,
                           velocity: np.ndarray, has_velocity: np.ndarray, comp: np.ndarray, clu: np.ndarray,
                           scan: np.ndarray, ego: EgoState | tuple, road: Road | None, config: TrackerConfig,
                           ut: UnscentedTransform) -> tuple[UpdateResult, int | None, int | None] | None:
    """``update_clusters`` in one compiled call; None where it does not apply or hands back (the
    conditions of ``_update_pairs_fused``, a cluster in some pair empty or not finite, a scan that is not
    ``(N, 2)``, or points and velocities of other shapes)."""
    if not len(comp) or config.coordinates != "curvilinear" or road is None:
        return None
    wrapping = state_wrapping(road, config.coordinates)
    if not _fused_update_applies(config, road, wrapping):
        return None
    scan = np.asarray(scan, dtype=float)
    points = np.asarray(points, dtype=float)
    velocity = np.asarray(velocity, dtype=float)
    has_velocity = np.asarray(has_velocity, dtype=bool)
    if (scan.ndim != 2 or scan.shape[1] != 2 or points.ndim != 2 or points.shape[1] != 2
            or velocity.shape != (len(offsets) - 1, 2) or has_velocity.shape != (len(offsets) - 1,)
            or not np.isfinite(velocity[has_velocity]).all()):
        return None  # the two steps say what is wrong
    prepare, scanned, update, shadows, continuation = _fused_settings(config)
    ego = EgoState.coerce(ego)
    kind, *curve = road._curve.kernel_args()
    c = np.ascontiguousarray
    try:
        status, *out, occluded, continued = prepared_pairs_kernel(
            c(points), offsets, c(has_velocity, dtype=np.bool_), c(velocity, dtype=float), c(means, dtype=float),
            c(covs, dtype=float), comp, clu, *prepare, c(scan), *scanned, ut.scale, ut.wm, ut.wc,
            *wrapping.kernel_args(), kind, float(ego.x), float(ego.y), float(ego.yaw), road.closed, road.length,
            road._ends_array, *curve, *update)
    except np.linalg.LinAlgError:  # a prior or an innovation that is not positive definite: the two steps
        return None
    if status != DONE:
        return None
    return UpdateResult(*out), int(occluded) if shadows else None, int(continued) if continuation else None


def _update_pairs_fused(means: np.ndarray, covs: np.ndarray, inverse: np.ndarray, clu: np.ndarray, batch: ClusterBatch,
                        ego: EgoState | tuple, road: Road | None, config: TrackerConfig, ut: UnscentedTransform,
                        wrapping: Wrapping) -> UpdateResult | None:
    """``update_pairs``' compiled steps in one call (``tracker.pairs.update_pairs_kernel``: the
    same kernels in the same order, the same numbers) for the components ``means (U, D)``, ``covs`` in
    some pair (pair ``p``: component ``inverse[p]``, cluster ``clu[p]``); ``None`` where it does not
    apply (``_fused_update_applies``) or where the kernel hands the pairs back (a non-finite or not
    positive definite prior, a widened prior, a variance that is not positive): the staged path then
    runs."""
    if not len(means) or not _fused_update_applies(config, road, wrapping):
        return None
    mcfg = config.measurement
    ego = EgoState.coerce(ego)
    kind, *curve = road._curve.kernel_args()
    head, tail = structure_config_args(mcfg, config.use_radar, config.detection.lidar_range)
    c = np.ascontiguousarray
    try:
        status, *out = update_pairs_kernel(
            c(means, dtype=float), c(covs, dtype=float), c(inverse, dtype=np.intp), c(clu, dtype=np.intp), ut.scale,
            ut.wm, ut.wc, *wrapping.kernel_args(), kind, float(ego.x), float(ego.y), float(ego.yaw), road.closed,
            road.length, road._ends_array, *curve, MIN_EXTENT, *structure_batch_args(batch), *head,
            batch.occluded_end is not None, *tail,
            bool(mcfg.grow_extent), GROWTH_MIN_EXCESS, GROWTH_SIGMAS,
            -1.0 if mcfg.radar_gate is None else float(mcfg.radar_gate), *_extent_rule_args(config))
    except np.linalg.LinAlgError:  # a prior or an innovation that is not positive definite: the staged path
        return None
    if status != DONE:
        return None
    return UpdateResult(*out)


def apply_extent_rules(res: UpdateResult, prior_mean: np.ndarray, prior_cov: np.ndarray, structure: Structure,
                       mean_corners: np.ndarray, config: TrackerConfig) -> UpdateResult:
    """The extent rules after the update, in place (``tracker.extent.extent_rules_kernel``): the
    hold of an unobserved extent (``MeasurementConfig.hold_unobserved_extent``), then where a
    length was held and unmeasured and the width seen whole the vehicle classes' length prior
    (``BirthConfig.classes``), then the vehicle sizes' limits (``BirthConfig.min_length`` .. ``max_length``,
    ``min_width`` .. ``max_width``: the estimate projected back onto them); ``tracker.extent``'s module docstring says what each rule does. ``mean_corners (P, 4, 2)``: the
    pairs' predicted mean rectangles in E."""
    mean, cov = np.ascontiguousarray(res.mean), np.ascontiguousarray(res.cov)
    extent_rules_kernel(
        mean, cov, np.ascontiguousarray(prior_mean), np.ascontiguousarray(prior_cov),
        np.ascontiguousarray(structure.mode), np.ascontiguousarray(structure.sides),
        np.ascontiguousarray(mean_corners, dtype=float), *_extent_rule_args(config))
    return res if mean is res.mean and cov is res.cov else dataclasses.replace(res, mean=mean, cov=cov)


def sigma_rectangles(ut: UnscentedTransform, means: np.ndarray, covs: np.ndarray, wrapping: Wrapping,
                     ego: EgoState | tuple, road: Road | None, coordinates: str,
                     euler_s0: float | None = None) -> tuple[np.ndarray, Rectangles]:
    """The sigma points ``(C, S, n)`` of ``N(means, covs)`` and their rectangles in E ``(C, S)``
    (``UnscentedTransform.sigma_points``, then ``tracker.measurement.to_vehicle``); for curvilinear
    states with the exact conversion, by one call of ``tracker.centerline.sigma_rectangles_kernel``
    (the same numbers), unless a covariance is not positive definite (``sigma_points`` repairs it)."""
    if (coordinates == "curvilinear" and euler_s0 is None and road is not None
            and len(wrapping.periods) <= 1 and means.ndim == 2 and len(means)):
        ego = EgoState.coerce(ego)
        kind, *curve = road._curve.kernel_args()
        try:
            sigma, center, psi, corners, finite = sigma_rectangles_kernel(
                np.ascontiguousarray(means, dtype=float), np.ascontiguousarray(covs, dtype=float), ut.scale,
                *wrapping.kernel_args(), kind, float(ego.x), float(ego.y), float(ego.yaw), road.closed, road.length,
                road._ends_array, *curve, MIN_EXTENT)
        except np.linalg.LinAlgError:  # not positive definite: sigma_points repairs and counts it
            finite = None
        if finite is False:
            raise ValueError("sigma_points: mean and cov must be finite (a NaN/inf entered the filter)")
        if finite:
            return sigma, Rectangles.of_states(sigma, center, psi, corners)
    sigma = ut.sigma_points(means, covs, wrapping)
    return sigma, to_vehicle(sigma, ego, road, coordinates, euler_s0)


def likelihood_variances(structure: Structure, config: MeasurementConfig) -> np.ndarray | None:
    """The variances ``(P, D)`` of the pairs' likelihood and NIS: ``structure.r`` with every lidar row at
    ``lidar_sigma^2`` (``MeasurementConfig.shadowed_lidar_sigma`` softens the update of some pairs, not
    their weight or their gate); None where no pair's update was softened. A pair's lidar rows share
    one variance and its first row is a point (a cluster's points come first in its row of the batch,
    as ``tracker.preparation`` and ``ClusterBatch.of`` build it): the first row tells."""
    nominal = config.lidar_sigma**2
    if config.shadowed_lidar_sigma is None or not len(structure.r):
        return None
    # a pair's lidar rows share one variance (tracker.measurement): its first row, always a point, tells
    if not np.any(structure.r[:, 0][structure.mask[:, 0]] != nominal):
        return None
    lidar = structure.mask[:, :-2]  # the last two rows are the radar's
    r = structure.r.copy()
    r[:, :-2] = np.where(lidar, nominal, r[:, :-2])
    return r


def _measure(ut: UnscentedTransform, sigma: np.ndarray, means: np.ndarray, covs: np.ndarray, rect: Rectangles,
             structure: Structure, cluster_index: np.ndarray, gate: float | None, wrapping: Wrapping,
             r_like: np.ndarray | None = None) -> UpdateResult:
    """The measurement step of the pairs in one call of ``tracker.kalman.measurement_update_kernel``:
    the predicted measurements (``predict_measurements``), the radar gate (``MeasurementConfig.radar_gate``:
    a cluster's radar rows set aside where no pair explains them) and the update (``kalman_update``). A predicted measurement that is not finite (a NaN or an infinity in a
    sigma point's rectangle) is refused with a ``ValueError``."""
    _check_noise(structure.r, structure.mask)
    c = np.ascontiguousarray
    shape = sigma.shape[:2]
    try:
        out = measurement_update_kernel(
            c(sigma), c(means), c(covs), c(rect.center),
            *(c(a) if a.shape == shape else c(np.broadcast_to(a, shape)) for a in (rect.psi, rect.v, rect.length, rect.width)),
            c(structure.matrix), c(structure.z), c(structure.r), c(structure.r if r_like is None else r_like),
            c(structure.mask), c(np.zeros((len(means), 0, structure.z.shape[1])) if structure.factors is None
                                 else structure.factors), c(structure.radar), c(cluster_index),
            -1.0 if gate is None else float(gate), ut.wm, ut.wc, *wrapping.kernel_args())
    except np.linalg.LinAlgError:  # the factorisation of a pair's innovation failed: a non-finite prediction
        raise ValueError("update_pairs: a predicted measurement is not finite (a NaN/inf in a sigma point's "
                         "rectangle)") from None
    return UpdateResult(*out)


def grow_extent(
    means: np.ndarray, covs: np.ndarray, structure: Structure, mean_corners: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Widen the prior of pairs whose cluster shows a side longer than the predicted rectangle's.

    A track born from a truck's rear has a car's length prior (``BirthConfig.length`` 4.7 +- 1 m). When
    the truck's side comes into view its points run 5-15 m past the predicted rectangle: the innovation
    is far outside the gate, the track is not updated, and a newborn takes the cluster. A side's chord
    (the extent of its points, without the end-gap margins) is a lower bound of its length, so an
    excess ``e = chord - predicted`` (``Structure.excess``) above ``max(GROWTH_MIN_EXCESS, GROWTH_SIGMAS
    sqrt(P[L, L]))`` is evidence that the prior is wrong, not noise. (The end-gap margins are left out
    because at grazing views they are large and would let a converged car's length grow falsely.) The
    prior then gets the variance ``e^2`` along the direction in which the vehicle can grow while the end
    nearest the sensor stays put::

        P += e^2 d d^T,   d = 0.5 sgn (cos h, sin h) in the position slots, 1 in the L slot

    (``h`` = ``xi`` (``psi``) of the mean, ``sgn`` = +1 when the sensor is behind the centre along the
    body axis), and likewise ``W`` with the left normal ``(-sin h, cos h)`` for a short side; the update
    then learns the extent from the side itself. Returns the mask of widened pairs ``(P,)`` and the covariances (a copy; unchanged where the mask is
    False). By ``tracker.extent.grow_extent_kernel``."""
    c = np.ascontiguousarray
    return grow_extent_kernel(c(means, dtype=float), c(covs, dtype=float), c(structure.excess, dtype=float),
                              c(structure.sides), c(mean_corners, dtype=float), GROWTH_MIN_EXCESS, GROWTH_SIGMAS)


def update(
    mean: np.ndarray,
    cov: np.ndarray,
    cluster: Cluster,
    ego: EgoState | tuple,
    road: Road | None,
    config: TrackerConfig | None = None,
    ut: UnscentedTransform | None = None,
) -> tuple[np.ndarray, np.ndarray, float]:
    """Update one Gaussian ``mean (7,)``, ``cov (7, 7)`` by one prepared cluster. Returns the
    posterior mean, covariance and ``log N(z; y, S)``."""
    res = update_pairs(mean, cov, [cluster], np.zeros(1, dtype=int), np.zeros(1, dtype=int), ego, road, config, ut)
    return res.mean[0], res.cov[0], float(res.log_likelihood[0])
