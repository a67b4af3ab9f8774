"""The extent rules of the UKF update of the pairs (``tracker.update``) as numba calls, in place.

Before the update, ``grow_extent_kernel``: a part's chord longer than its predicted side by more than
``max(GROWTH_MIN_EXCESS, GROWTH_SIGMAS sd)`` (``tracker.measurement``) widens the prior,
``P += e^2 d d^T`` with ``d`` the direction in which the vehicle grows while the end nearest the sensor
stays put (``_growth_direction``; ``tracker.update.grow_extent``). After it, ``extent_rules_kernel``:
the Schmidt hold of an extent no part shows whole (``L`` for the long sides, ``W`` for the short ones
keep their prior mean and variance, both held: their joint block;
``MeasurementConfig.hold_unobserved_extent``); where the length was held, a car's unmeasured length
replaced by a long vehicle's where the width is a truck's or a bus's (``BirthConfig.long_width``), or
by a motorcycle's where a measured width is narrow (``BirthConfig.narrow_width``), the end nearest the
sensor staying put (``_replace_length``); then the largest vehicle's limits (``BirthConfig.max_length``,
``max_width``: the estimate projected back onto them)."""

from __future__ import annotations

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
def _replace_length(mean, cov, corners, length, variance):  # pragma: no cover - compiled
    """A new length prior of one pair (``mean (D,)``, ``cov (D, D)`` in place; ``corners (4, 2)``
    its predicted mean rectangle in E): the length becomes ``length`` with ``variance`` added along
    ``d`` (``_growth_direction``), the end nearest the sensor staying put: ``m += e d``,
    ``P += variance d d^T`` with ``e = length - L``."""
    dim = mean.shape[0]
    d = np.empty(dim)
    _growth_direction(corners, mean[XI], LENGTH, d)
    e = length - mean[LENGTH]
    for j in range(dim):
        mean[j] += e * d[j]
    for j in range(dim):
        for k in range(dim):
            cov[j, k] += variance * d[j] * d[k]


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
def extent_rules_kernel(mean, cov, prior_mean, prior_cov, mode, sides, corners, hold, long_on, long_width,
                        long_below, long_variance, long_length, narrow_on, narrow_width, narrow_width_var,
                        narrow_above, narrow_variance, narrow_length, unmeasured_var, max_length,
                        max_width):  # pragma: no cover - compiled
    """The posteriors ``mean (P, D)``, ``cov (P, D, D)`` after the extent rules, in place (module
    docstring). ``mode``, ``sides (P, 2)``: the structure's parts; ``corners (P, 4, 2)``: the predicted
    mean rectangles. With ``hold``: a length (width) no part shows whole keeps its prior mean and
    variance (both held: their joint block), then, where the length was held, the long-vehicle prior
    (``long_on``: width at least ``long_width``, length below ``long_below``, its variance at least
    ``unmeasured_var``) and the narrow one (``narrow_on``: width at most ``narrow_width`` with variance at
    most ``narrow_width_var``, length above ``narrow_above``). Then ``L <= max_length``, ``W <= max_width``."""
    pairs = mean.shape[0]
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
                mean[p, LENGTH] = prior_mean[p, LENGTH]
                cov[p, LENGTH, LENGTH] = prior_cov[p, LENGTH, LENGTH]
            if not seen_width:
                mean[p, WIDTH] = prior_mean[p, WIDTH]
                cov[p, WIDTH, WIDTH] = prior_cov[p, WIDTH, WIDTH]
            if not seen_length and not seen_width:
                cov[p, LENGTH, WIDTH] = prior_cov[p, LENGTH, WIDTH]
                cov[p, WIDTH, LENGTH] = prior_cov[p, WIDTH, LENGTH]
            if not seen_length:
                if (long_on and mean[p, WIDTH] >= long_width and mean[p, LENGTH] < long_below
                        and cov[p, LENGTH, LENGTH] >= unmeasured_var):
                    _replace_length(mean[p], cov[p], corners[p], long_length, long_variance)
                if (narrow_on and mean[p, WIDTH] <= narrow_width and cov[p, WIDTH, WIDTH] <= narrow_width_var
                        and mean[p, LENGTH] > narrow_above and cov[p, LENGTH, LENGTH] >= unmeasured_var):
                    _replace_length(mean[p], cov[p], corners[p], narrow_length, narrow_variance)
        if mean[p, LENGTH] > max_length:  # np.minimum (a NaN stays a NaN)
            mean[p, LENGTH] = max_length
        if mean[p, WIDTH] > max_width:
            mean[p, WIDTH] = max_width
