"""The extent rules of the UKF update of the pairs (``tracker.update``) as numba calls, in place.

Before the update, ``grow_extent_kernel``: a part's chord longer than its predicted side by more than
``max(GROWTH_MIN_EXCESS, GROWTH_SIGMAS sd)`` (``tracker.measurement``) widens the prior,
``P += e^2 d d^T`` with ``d`` the direction in which the vehicle grows while the end nearest the sensor
stays put (``_growth_direction``; ``tracker.update.grow_extent``). After it, ``extent_rules_kernel``:
the hold of an extent no part shows whole (``L`` for the long sides, ``W`` for the short ones keep
their prior mean and variance, both held: their joint block: the Schmidt update; a held ``L`` whose face,
a short side, is seen whole keeps the face where the update put it, the centre moving by half the
length's change, ``MeasurementConfig.hold_unobserved_extent``); where the length was held and is still unmeasured and
the width was seen whole, the length prior of the vehicle classes given the measured width
(``BirthConfig.classes``, ``class_length_prior``: the classes weighed by their share and the width's
likelihood, their lengths' mixture mean and variance) where it lies beyond one standard deviation of
the held length and is longer, or the length is still no more than a car's prior
(``BirthConfig.length``), or the length is the classes' own wide prior and the width now rules out the
long classes (``extent_rules_kernel``), the end nearest the sensor staying put with its uncertainty
(``_replace_length``); then the vehicle sizes' limits (``BirthConfig.min_length`` .. ``max_length``,
``min_width`` .. ``max_width``: the estimate projected back onto them)."""

from __future__ import annotations

import functools
import math

import numpy as np

from tracker.jit import njit
from tracker.structure import FULL
from tracker.motion import LENGTH, WIDTH, XI


@njit(inline="always")
def _growth_direction(corners, heading, index, d):  # pragma: no cover - compiled
    """The direction ``d (D,)`` in which one pair's rectangle grows by 1 m, into ``d`` (zeroed first):
    ``0.5 sgn u`` in the position slots (``u`` along the body for ``index = LENGTH``, across it for
    ``WIDTH``), 1 in the extent slot; ``sgn = +1`` when the sensor lies behind the centre along that
    axis of ``corners (4, 2)``."""
    bx, by = corners[0, 0] - corners[3, 0], corners[0, 1] - corners[3, 1]  # the body axis in E
    if index != LENGTH:
        bx, by = -by, bx
    cx = (((corners[0, 0] + corners[1, 0]) + corners[2, 0]) + corners[3, 0]) / 4.0
    cy = (((corners[0, 1] + corners[1, 1]) + corners[2, 1]) + corners[3, 1]) / 4.0
    sgn = 1.0 if cx * bx + cy * by >= 0.0 else -1.0
    c, s = math.cos(heading), math.sin(heading)
    d[:] = 0.0
    if index == LENGTH:
        d[0] = 0.5 * sgn * c
        d[1] = 0.5 * sgn * s
    else:
        d[0] = 0.5 * sgn * -s
        d[1] = 0.5 * sgn * c
    d[index] = 1.0


@njit(inline="always")
def _move_length(mean, corners, length, d):  # pragma: no cover - compiled
    """One pair's mean (``mean (D,)``, in place) given the length ``length``, the end nearest the sensor
    staying put: ``m += (length - L) d``, ``d`` (into the array ``d``) the growth direction of its
    predicted mean rectangle ``corners (4, 2)`` (``_growth_direction``)."""
    _growth_direction(corners, mean[XI], LENGTH, d)
    e = length - mean[LENGTH]
    for j in range(mean.shape[0]):
        mean[j] += e * d[j]


@njit(inline="always")
def _replace_length(mean, cov, corners, length, variance):  # pragma: no cover - compiled
    """A new length prior of one pair (``mean (D,)``, ``cov (D, D)`` in place; ``corners (4, 2)``
    its predicted mean rectangle in E): the length becomes ``length`` with variance ``variance``, the
    end nearest the sensor staying put, with its uncertainty. With ``d`` the growth direction
    (``_growth_direction``): ``m += (length - L) d``; a larger variance adds along ``d``,
    ``P += (variance - P_LL) d d^T``; a smaller one scales the length's deviation about the near end,
    ``P <- M P M^T`` with ``M = I + (r - 1) d e_L^T``, ``r = sqrt(variance / P_LL)`` (subtracting along
    ``d`` could leave ``P`` indefinite). Either way a face measured later moves the near end, not a
    length that the hold then discards."""
    dim = mean.shape[0]
    d = np.empty(dim)
    _move_length(mean, corners, length, d)
    old = cov[LENGTH, LENGTH]
    if variance >= old:  # more uncertain: the added variance along d
        for j in range(dim):
            for i in range(dim):
                cov[j, i] += (variance - old) * d[j] * d[i]
        return
    k = math.sqrt(variance / old) - 1.0
    col = cov[:, LENGTH].copy()
    for j in range(dim):
        for i in range(dim):
            cov[j, i] += k * (d[j] * col[i] + col[j] * d[i]) + k * k * old * d[j] * d[i]


@njit
def bound_at_holes_kernel(means, covs, corners, component_group, ctr, c, s, bounds, variance):  # pragma: no cover - compiled
    """The seen free space of the cuts along the tracks' clusters (``tracker.clustering.along_cuts_kernel``)
    applied to the components, in place: a component of group ``component_group[i]`` (-1: none) whose
    rectangle (``corners (N, 4, 2)`` in E) reaches past its group's bound on its far side (``bounds (G,
    2)``: ``(lo, hi)`` along the group's heading, cosine ``c``, sine ``s``, from ``ctr (G, 2)``; the far
    side the one away from the sensor, as the growth direction's) gets the length that ends there,
    the end nearest the sensor staying put (``_replace_length``; at least its width), and a length
    variance of at least ``variance``. A component whose body lies more than 30 deg off its group's
    heading is left alone. Returns the number of components shortened."""
    count = len(means)
    shortened = 0
    d = np.empty(means.shape[1])
    for i in range(count):
        g = component_group[i]
        if g < 0 or (bounds[g, 0] == -np.inf and bounds[g, 1] == np.inf):
            continue
        bx, by = corners[i, 0, 0] - corners[i, 3, 0], corners[i, 0, 1] - corners[i, 3, 1]  # the body axis in E
        norm = math.sqrt(bx * bx + by * by)
        if norm <= 0.0:
            continue
        bx /= norm
        by /= norm
        cx = (((corners[i, 0, 0] + corners[i, 1, 0]) + corners[i, 2, 0]) + corners[i, 3, 0]) / 4.0
        cy = (((corners[i, 0, 1] + corners[i, 1, 1]) + corners[i, 2, 1]) + corners[i, 3, 1]) / 4.0
        if cx * bx + cy * by < 0.0:  # the far side: away from the sensor along the body
            bx, by = -bx, -by
        along = bx * c[g] + by * s[g]
        if abs(along) < HOLE_MAX_COS_OFF:
            continue
        length = means[i, LENGTH]
        far = (cx - ctr[g, 0]) * c[g] + (cy - ctr[g, 1]) * s[g] + 0.5 * length * along
        excess = far - bounds[g, 1] if along > 0.0 else bounds[g, 0] - far
        if not excess > 0.0:
            continue
        target = max(length - excess / abs(along), means[i, WIDTH])
        if target >= length:
            continue
        _replace_length(means[i], covs[i], corners[i], target, max(covs[i, LENGTH, LENGTH], variance))
        shortened += 1
    return shortened


#: ``bound_at_holes_kernel`` leaves a component alone whose body's cosine with its group's heading is below this (30 deg).
HOLE_MAX_COS_OFF = math.cos(math.radians(30.0))


@functools.lru_cache(maxsize=16)
def class_arrays(classes: tuple, width_error_std: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                                                      np.ndarray]:
    """The arrays ``(C,)`` of ``class_length_prior`` from ``tracker.config.VehicleClass`` es: their
    shares, mean lengths, length variances, mean widths and width variances, the latter widened by
    ``width_error_std^2`` (``BirthConfig.width_error_std``: how far a measured width strays from the
    body's); cached: not to be written."""
    return (np.array([c.share for c in classes], dtype=float), np.array([c.length for c in classes], dtype=float),
           np.array([c.length_std**2 for c in classes], dtype=float), np.array([c.width for c in classes], dtype=float),
           np.array([c.width_std**2 + width_error_std**2 for c in classes], dtype=float))


@njit
def class_length_prior(width, width_var, share, length, length_var, class_width, class_width_var):  # pragma: no cover - compiled
    """The length prior of a vehicle whose width is ``N(width, width_var)`` (m, m^2): the classes
    (``tracker.config.VehicleClass``; arrays ``(C,)`` of their shares, mean lengths, length variances,
    mean widths and width variances) weighed by ``p(c | w) ∝ share_c N(width; class_width_c,
    class_width_var_c + width_var)``, and the mixture of their lengths' mean and variance
    ``(sum p_c mu_c, sum p_c (var_c + mu_c^2) - mean^2)`` returned."""
    count = share.shape[0]
    logw = np.empty(count)
    top = -math.inf
    for c in range(count):
        var = class_width_var[c] + width_var
        r = width - class_width[c]
        logw[c] = math.log(share[c]) - 0.5 * math.log(var) - 0.5 * r * r / var
        top = max(top, logw[c])
    total = 0.0
    first = 0.0
    second = 0.0
    for c in range(count):
        w = math.exp(logw[c] - top)
        total += w
        first += w * length[c]
        second += w * (length_var[c] + length[c] * length[c])
    mean = first / total
    return mean, max(second / total - mean * mean, 0.0)


@njit
def class_prior_lengths_kernel(means, covs, corners, rows, share, class_length, class_length_var, class_width,
                               class_width_var, car_length, car_var):  # pragma: no cover - compiled
    """The components ``rows`` of ``means (N, D)``, ``cov (N, D, D)`` (in place; ``corners (N, 4, 2)``
    their mean rectangles in E), whose lengths are the vehicle classes' prior, take it anew from their
    width as a cluster birth would (``tracker.birth.cluster_births``): the classes' mean and variance
    (``class_length_prior`` of the arrays; at least ``car_var``) where that mean is longer than a car's
    ``car_length`` by more than ``sqrt(car_var)``, else ``car_length`` with ``car_var``; the end nearest the
    sensor staying put (``_replace_length``). For when the classes' width variances changed (a learned
    ``BirthConfig.width_error_std``, ``tracker.fleet``)."""
    for p in rows:
        length, variance = class_length_prior(means[p, WIDTH], max(covs[p, WIDTH, WIDTH], 0.0), share, class_length,
                                              class_length_var, class_width, class_width_var)
        if length - car_length > math.sqrt(car_var):
            _replace_length(means[p], covs[p], corners[p], length, max(variance, car_var))
        else:
            _replace_length(means[p], covs[p], corners[p], car_length, car_var)


@njit
def grow_extent_kernel(means, covs, excess, sides, corners, min_excess, sigmas):  # pragma: no cover - compiled
    """``tracker.update.grow_extent``: per pair, the largest excess of a part over its predicted side
    (``excess (P, 2)``; long parts, odd ``sides``, for ``L``, the others for ``W``), and where it is
    evidence of a longer side (above ``max(min_excess, sigmas sd)``) the prior widened by ``e^2 d d^T``.
    Returns the mask of widened pairs and the covariances (a copy)."""
    pairs, dim = means.shape
    out = covs.copy()
    grown = np.zeros(pairs, dtype=np.bool_)
    d = np.empty(dim)
    for p in range(pairs):
        for index in (LENGTH, WIDTH):
            e = -math.inf
            for part in range(2):
                if (sides[p, part] % 2 == 1) == (index == LENGTH) and math.isfinite(excess[p, part]):
                    e = max(e, excess[p, part])
            sd = math.sqrt(max(covs[p, index, index], 0.0))
            if not e > max(min_excess, sigmas * sd):
                continue
            _growth_direction(corners[p], means[p, XI], index, d)
            e2 = e * e
            for j in range(dim):
                for k in range(dim):
                    out[p, j, k] += e2 * d[j] * d[k]
            grown[p] = True
    return grown, out


@njit
def extent_rules_kernel(mean, cov, prior_mean, prior_cov, mode, sides, corners, hold, classes_on, share, class_length,
                        class_length_var, class_width, class_width_var, unmeasured_var, class_prior_var, short_var, length_floor,
                        min_length, min_width, max_length, max_width):  # pragma: no cover - compiled
    """The posteriors ``mean (P, D)``, ``cov (P, D, D)`` after the extent rules, in place (module
    docstring). ``mode``, ``sides (P, 2)``: the structure's parts; ``corners (P, 4, 2)``: the predicted
    mean rectangles. With ``hold``: a length (width) no part shows whole keeps its prior mean and
    variance (both held: their joint block), a length whose face is seen whole with the face where the
    update put it (the mean moved by the change of ``L``, ``_move_length``; the covariance the Schmidt
    one, not loosened along it), then, with ``classes_on``, where the length was held and
    is still unmeasured (its variance at least ``unmeasured_var``) and the width was seen whole, the
    length prior of the vehicle classes given the width's posterior (``class_length_prior`` of the
    arrays ``share``, ``class_length``, ``class_length_var``, ``class_width``, ``class_width_var``)
    where it lies beyond one standard deviation of the held length (within it, the held prior already
    covers it), and only where it is longer, or where the held length is no more than a car's prior
    ``length_floor`` (a fitted side longer than that is a lower bound the classes may not undercut), or
    where its variance exceeds ``class_prior_var`` (no fit gives so wide a spread: the length is the
    classes' own prior, taken on an earlier width) and the classes' variance is at most ``short_var``
    (the width now rules out the long classes; a long vehicle's length grown by a side it showed is a
    lower bound, and stays): the mean moved to the classes' mean and the variance to theirs (where
    longer, the larger of theirs and the held one), the end nearest the sensor kept
    (``_replace_length``). Then ``min_length <= L <= max_length``, ``min_width <= W <= max_width``."""
    pairs = mean.shape[0]
    d = np.empty(mean.shape[1])
    for p in range(pairs):
        if hold:
            seen_length = False
            seen_width = False
            for part in range(2):
                if mode[p, part] == FULL:
                    if sides[p, part] % 2 == 1:
                        seen_length = True
                    else:
                        seen_width = True
            if not seen_length:
                if seen_width:  # a face seen whole: it stays where the update put it, the centre moving
                    _move_length(mean[p], corners[p], prior_mean[p, LENGTH], d)
                mean[p, LENGTH] = prior_mean[p, LENGTH]
                cov[p, LENGTH, LENGTH] = prior_cov[p, LENGTH, LENGTH]
            if not seen_width:
                mean[p, WIDTH] = prior_mean[p, WIDTH]
                cov[p, WIDTH, WIDTH] = prior_cov[p, WIDTH, WIDTH]
            if not seen_length and not seen_width:
                cov[p, LENGTH, WIDTH] = prior_cov[p, LENGTH, WIDTH]
                cov[p, WIDTH, LENGTH] = prior_cov[p, WIDTH, LENGTH]
            if classes_on and seen_width and not seen_length and cov[p, LENGTH, LENGTH] >= unmeasured_var:
                length, variance = class_length_prior(mean[p, WIDTH], max(cov[p, WIDTH, WIDTH], 0.0), share,
                                                      class_length, class_length_var, class_width, class_width_var)
                e = length - mean[p, LENGTH]
                if e * e > cov[p, LENGTH, LENGTH] and (e > 0.0 or mean[p, LENGTH] <= length_floor or (
                        cov[p, LENGTH, LENGTH] > class_prior_var and variance <= short_var)):
                    _replace_length(mean[p], cov[p], corners[p], length,
                                    max(variance, cov[p, LENGTH, LENGTH]) if e > 0.0 else variance)
        if mean[p, LENGTH] > max_length:  # np.clip (a NaN stays a NaN)
            mean[p, LENGTH] = max_length
        elif mean[p, LENGTH] < min_length:
            mean[p, LENGTH] = min_length
        if mean[p, WIDTH] > max_width:
            mean[p, WIDTH] = max_width
        elif mean[p, WIDTH] < min_width:
            mean[p, WIDTH] = min_width
