"""Gaussian-mixture reduction for the GM-PHD filter: prune, merge, cap (Vo & Ma 2006).

A mixture is held as arrays: ``weights`` (J,), ``means`` (J, D), ``covs`` (J, D, D) and integer
``labels`` (J,). Wrapped coordinates (a ``tracker.ukf.Wrapping``: angles such as ``xi``, and ``s`` on a
closed road) are handled on the circle: residuals are wrapped and merged means are circular
weighted means, so components on either side of ``s = 0`` merge.

- prune: drop components with weight below ``threshold``;
- merge: repeatedly take the heaviest remaining component ``j`` and merge every component ``i``
  with ``(m_i - m_j)^T P_i^-1 (m_i - m_j) <= gate`` into one moment-matched Gaussian; the merged
  component keeps the label of the heaviest (docs/architecture.md);
- cap: keep the ``max_components`` heaviest.

``reduce_in_view`` is the tracker's reduce stage before its overlap rules: the components out of view or
off the road dropped, then ``reduce``, in one compiled call (``reduce_kernel``). ``absorb_overlapping``
lets one label absorb another whose rectangle overlaps its own (two tracks of one vehicle). The stage's
numba kernels are at the end of the module.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Set as AbstractSet
from dataclasses import dataclass

import numpy as np

from tracker.ukf import NO_WRAP, Wrapping
from tracker.jit import njit
from tracker.clustering import points_in_rectangles_kernel


@dataclass
class Mixture:
    """A labelled Gaussian mixture (arrays, one row per component)."""

    weights: np.ndarray
    means: np.ndarray
    covs: np.ndarray
    labels: np.ndarray

    def __len__(self) -> int:
        return len(self.weights)

    def take(self, index: np.ndarray) -> Mixture:
        """The components at ``index`` (indices or a boolean mask)."""
        return Mixture(self.weights[index], self.means[index], self.covs[index], self.labels[index])


def prune(mix: Mixture, threshold: float) -> Mixture:
    """Components with weight >= ``threshold``."""
    return mix.take(mix.weights >= threshold)


def cap(mix: Mixture, max_components: int) -> Mixture:
    """The ``max_components`` heaviest components (in decreasing weight)."""
    if len(mix) <= max_components:
        return mix
    order = np.argsort(-mix.weights, kind="stable")[:max_components]
    return mix.take(order)


def _moment_match(mix: Mixture, group: np.ndarray, anchor: int, wrapping: Wrapping) -> tuple[float, np.ndarray, np.ndarray]:
    """Weight, mean and covariance of one Gaussian matching the moments of components ``group``;
    residuals are taken about component ``anchor`` (so angles average on the circle)."""
    w = mix.weights[group]
    w_sum = float(w.sum())
    dev = wrapping.residual(mix.means[group] - mix.means[anchor][None, :])
    mean_dev = (w[:, None] * dev).sum(axis=0) / w_sum
    mean = wrapping.wrap(mix.means[anchor] + mean_dev)
    spread = dev - mean_dev
    cov = (w[:, None, None] * (mix.covs[group] + spread[:, :, None] * spread[:, None, :])).sum(axis=0) / w_sum
    return w_sum, mean, 0.5 * (cov + cov.T)


def merge_same_label(
    mix: Mixture,
    distance: float,
    min_weight: float = 0.5,
    position: tuple[int, int] = (0, 1),
    wrapping: Wrapping = NO_WRAP,
    along_length: bool = False,
) -> Mixture:
    """Merge components of weight >= ``min_weight`` that share a label and whose positions (state
    entries ``position``) lie within ``distance`` metres of the heaviest of them: posteriors of one
    track updated by fragments of one vehicle's points (split clusters), which the Mahalanobis gate
    keeps apart when they are tight. Light components (e.g. the missed-detection copy) are left alone.
    With ``along_length`` also those within half the heaviest's length ``L`` (state entry 5) along its
    heading (entry 3: ``xi`` in road axes, ``psi`` in Cartesian ones) and ``distance`` across it: the
    fragments of a truck's or bus's points anchor its posteriors metres apart along it."""
    heavy = mix.weights >= min_weight
    heavy_labels = mix.labels[heavy].tolist()
    if len(set(heavy_labels)) == len(heavy_labels):  # the usual frame: no label twice (np.unique costs more)
        return mix
    labels, counts = np.unique(mix.labels[heavy], return_counts=True)
    shared = labels[counts > 1]
    if len(shared) == 0:
        return mix
    keep = ~(np.isin(mix.labels, shared) & heavy)
    w_out, m_out, p_out, l_out = [mix.weights[keep]], [mix.means[keep]], [mix.covs[keep]], [mix.labels[keep]]
    pos = list(position)
    for label in shared:  # labels with several components: a few per frame
        idx = np.flatnonzero((mix.labels == label) & heavy)
        idx = idx[np.argsort(-mix.weights[idx], kind="stable")]
        while len(idx):
            j = idx[0]
            gap = wrapping.residual(mix.means[idx] - mix.means[j][None, :])[:, pos]
            near = np.linalg.norm(gap, axis=1) <= distance
            if along_length:
                c, s = math.cos(mix.means[j, 3]), math.sin(mix.means[j, 3])
                along, across = gap[:, 0] * c + gap[:, 1] * s, -gap[:, 0] * s + gap[:, 1] * c
                near |= (np.abs(along) <= 0.5 * mix.means[j, 5]) & (np.abs(across) <= distance)
            w_sum, mean, cov = _moment_match(mix, idx[near], j, wrapping)
            w_out.append(np.array([w_sum]))
            m_out.append(mean[None, :])
            p_out.append(cov[None, :, :])
            l_out.append(np.array([label]))
            idx = idx[~near]
    return Mixture(np.concatenate(w_out), np.concatenate(m_out), np.concatenate(p_out), np.concatenate(l_out))


def merge(mix: Mixture, gate: float, wrapping: Wrapping = NO_WRAP) -> Mixture:
    """Merge components within Mahalanobis distance^2 ``gate`` of the heaviest remaining one.

    The heaviest remaining component ``j`` (ties of weight in index order) takes every remaining ``i``
    with ``d_ij^T P_i^-1 d_ij <= gate``, ``d_ij = m_i - m_j`` (wrapped coordinates wrapped); each group
    becomes one moment-matched Gaussian: the weights' sum, the weighted mean (circular for angles, about
    the group's heaviest component), the weighted covariances plus the weighted spread. The group keeps
    the label of its heaviest component. One compiled call (``merge_kernel``); a singular ``P_i`` that
    some pair needs raises ``numpy.linalg.LinAlgError``.
    """
    if len(mix) <= 1:
        return mix
    weights, means, covs, anchor = merge_kernel(
        np.ascontiguousarray(mix.weights, dtype=float), np.ascontiguousarray(mix.means, dtype=float),
        np.ascontiguousarray(mix.covs, dtype=float), float(gate), *_wrapping_args(wrapping))
    return Mixture(weights, means, covs, mix.labels[anchor])


@functools.lru_cache(maxsize=64)
def _wrapping_args(wrapping: Wrapping) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(angles, period_index, periods)`` of ``wrapping`` as the compiled merge takes them (int64,
    int64, float arrays; kept per wrapping: the kernels only read them)."""
    out = (np.array(wrapping.angles, dtype=np.int64), np.array([i for i, _ in wrapping.periods], dtype=np.int64),
           np.array([p for _, p in wrapping.periods], dtype=float))
    for array in out:
        array.flags.writeable = False  # shared by every call
    return out


def reduce(
    mix: Mixture,
    *,
    prune_threshold: float,
    merge_gate: float,
    max_components: int,
    wrapping: Wrapping = NO_WRAP,
    same_label_distance: float | None = None,
    same_label_min_weight: float = 0.5,
    same_label_along_length: bool = False,
) -> Mixture:
    """Prune, merge, then (with ``same_label_distance``) merge heavy same-label fragments
    (``merge_same_label``, ``along_length``), and cap a mixture."""
    mix = merge(prune(mix, prune_threshold), merge_gate, wrapping)
    if same_label_distance is not None:
        mix = merge_same_label(mix, same_label_distance, same_label_min_weight, wrapping=wrapping,
                               along_length=same_label_along_length)
    return cap(mix, max_components)


def reduce_in_view(
    mix: Mixture,
    near_range: np.ndarray,
    max_range: float,
    lateral: np.ndarray,
    lateral_bounds: tuple[float | np.ndarray, float | np.ndarray],
    *,
    prune_threshold: float,
    merge_gate: float,
    max_components: int,
    wrapping: Wrapping = NO_WRAP,
    same_label_distance: float | None = None,
    same_label_min_weight: float = 0.5,
    same_label_along_length: bool = False,
    s_period: float | None = None,
) -> tuple[Mixture, int, int]:
    """The components in view (``near_range <= max_range``: the range of each one's nearest corner) and
    on the road (``lo <= lateral <= hi``, ``lateral_bounds = (lo, hi)``: scalars or one per component,
    m), ``reduce``d; with ``s_period``
    coordinate 0 then taken modulo it (``numpy.mod``: a closed road's ``s``). Returns the mixture, the
    number of components out of view and the number in view but off the road. In one call of
    ``reduce_kernel``; ``merge_same_label``, and then the cap and the modulo, follow here in the frames
    where two heavy merged components share a label."""
    if len(near_range) != len(mix) or len(lateral) != len(mix):
        raise ValueError(f"need one range and one lateral offset per component ({len(mix)}); "
                         f"got {len(near_range)} and {len(lateral)}")
    lo, hi = (np.ascontiguousarray(np.broadcast_to(np.asarray(b, dtype=float), (len(mix),))) for b in lateral_bounds)
    weights, means, covs, source, left_view, off_road, pending = reduce_kernel(
        np.ascontiguousarray(mix.weights, dtype=float), np.ascontiguousarray(mix.means, dtype=float),
        np.ascontiguousarray(mix.covs, dtype=float), np.ascontiguousarray(mix.labels, dtype=np.int64),
        np.ascontiguousarray(near_range, dtype=float), float(max_range), np.ascontiguousarray(lateral, dtype=float),
        lo, hi, float(prune_threshold), float(merge_gate), *_wrapping_args(wrapping),
        -1.0 if same_label_distance is None else float(same_label_min_weight), int(max_components),
        0.0 if s_period is None else float(s_period))
    mix = Mixture(weights, means, covs, mix.labels[source])
    if pending:
        mix = cap(merge_same_label(mix, same_label_distance, same_label_min_weight, wrapping=wrapping,
                                   along_length=same_label_along_length), max_components)
        if s_period is not None and len(mix):
            mix.means[:, 0] = np.mod(mix.means[:, 0], s_period)
    return mix, left_view, off_road


@functools.lru_cache(maxsize=64)
def _position_periods(wrapping: Wrapping) -> tuple[tuple[tuple[int, float], ...], float | None]:
    """The periodic position coordinates of ``wrapping`` (index 0 or 1: ``s`` on a closed road), and
    the period when that is coordinate 0 alone (else None)."""
    position_periods = tuple(p for p in wrapping.periods if p[0] < 2)
    s_period = position_periods[0][1] if len(position_periods) == 1 and position_periods[0][0] == 0 else None
    return position_periods, s_period


def _screened_candidates(mix: Mixture, min_weight: float, overlap: float, cartesian: bool, position_periodic: bool,
                         s_period: float | None) -> tuple[np.ndarray, bool]:
    """``absorb_overlapping``'s candidates (``absorb_candidates_kernel``: the heaviest component of each
    label of weight >= ``min_weight``, heaviest first) and whether they may overlap: False when there
    are fewer than two or ``overlapping_pairs_kernel`` finds no pair (along the road in one call with
    the candidates, ``overlapping_candidates_kernel``; along the heading, whose cosine and sine numpy
    takes, in a second); True where that test does not apply (fewer than 7 state entries, a periodic
    position other than ``s`` alone), for ``absorb_overlapping``'s own test of the pairs to decide."""
    weights = np.ascontiguousarray(mix.weights, dtype=float)
    labels = np.ascontiguousarray(mix.labels, dtype=np.int64)
    if mix.means.shape[1] >= 7 and (not position_periodic or s_period is not None):
        if not cartesian:
            cand, overlapping = overlapping_candidates_kernel(
                weights, np.ascontiguousarray(mix.means, dtype=float), labels, float(min_weight), float(overlap),
                float(s_period or 0.0))
            return cand, bool(overlapping)
        cand = absorb_candidates_kernel(weights, labels, float(min_weight))
        if len(cand) < 2:
            return cand, False
        m = mix.means[cand]
        return cand, bool(overlapping_pairs_kernel(np.ascontiguousarray(m), np.cos(m[:, 3]), np.sin(m[:, 3]), True,
                                                   float(overlap), float(s_period or 0.0)).any())
    cand = absorb_candidates_kernel(weights, labels, float(min_weight))
    return cand, len(cand) >= 2


#: Standard deviation (m) of a length known well enough to widen a keeper's rectangle to the union with
#: an absorbed one's (``absorb_overlapping``): a side seen; a prior's (a car's 1 m, a truck's 3.5 m) is not.
UNION_LENGTH_STD = 0.5


def absorb_overlapping(
    mix: Mixture,
    min_weight: float,
    overlap: float,
    wrapping: Wrapping = NO_WRAP,
    cartesian: bool = False,
    keep_labels: AbstractSet[int] = frozenset(),
    updated: AbstractSet[int] = frozenset(),
) -> tuple[Mixture, int]:
    """Two vehicles cannot overlap: per pair of labels whose heaviest components (weight >= ``min_weight``)
    overlap as rectangles along the road (``s``; along the keeper's heading ``psi`` for Cartesian states)
    by more than ``overlap`` m, each centre within half the narrower width of the other's across it, one
    label absorbs the other. These are the fragments of one vehicle's points tracked apart: a truck or
    bus first seen at long range or at grazing incidence, whose side's returns lie farther apart than the
    clustering distance, becomes two or three short tracks along one line, and the labels trade the
    vehicle back and forth; or one vehicle born twice from the first scan. The keeper is a label of
    ``keep_labels`` (last frame's tracks) if one of the two is; of two newcomers the longer (the vehicle
    is at least as long as either fragment shows: a truck's prior over a car's), at equal lengths the
    smaller (older) label. The state is the keeper's unless only the other label is in ``updated`` (a
    cluster gave it a reportable posterior this frame): a coasting track's prediction that missed its
    vehicle, whose returning points then seeded a newcomer beside it, gives its label to the newcomer's
    state (as ``tracker.identity`` does for a newcomer confirmed next to a coasting track). Its weight
    becomes the larger of the two (one target). When both lengths are
    known to ``UNION_LENGTH_STD`` its rectangle becomes the union of the two along the heading (centre
    and length ``L``; the larger width ``W``), the variances of the moved centre and of ``L`` and ``W``
    grown by the squares of their changes (a prior's length says nothing of where the vehicle ends: the
    union of two duplicates of one car, each with the prior's 4.7 m and a few metres apart, would be a
    vehicle far longer than the car), but not when only one of them is in ``updated``: a coasting
    track's rectangle is its prediction, not a fragment seen, and its union with the newcomer on the
    vehicle would stretch the vehicle by the prediction's error.
    Every component of the absorbed label is dropped. Returns the mixture and the number of labels
    absorbed."""
    position_periods, s_period = _position_periods(wrapping)
    # the usual frame: no two labels overlap, which compiled passes over the pairs tell
    cand, overlapping = _screened_candidates(mix, min_weight, overlap, cartesian, bool(position_periods), s_period)
    if not overlapping:
        return mix, 0
    # the pairs of candidates that overlap, and how far along the keeper's axis the other lies (its union)
    m = mix.means[cand]
    d = m[None, :, :2] - m[:, None, :2]  # d[i, j] = position of j - position of i
    if position_periods:
        d = Wrapping(periods=position_periods).residual(d)
    if cartesian:
        c, s = np.cos(m[:, 3])[:, None], np.sin(m[:, 3])[:, None]
        along, across = d[..., 0] * c + d[..., 1] * s, -d[..., 0] * s + d[..., 1] * c
    else:
        along, across = d[..., 0], d[..., 1]
    length, width = m[:, 5], m[:, 6]
    over = ((np.abs(along) < 0.5 * (length[:, None] + length[None, :]) - overlap)
            & (np.abs(across) < 0.5 * np.minimum(width[:, None], width[None, :])))
    np.fill_diagonal(over, False)
    if not over.any():
        return mix, 0
    weights, means, covs = mix.weights.copy(), mix.means.copy(), mix.covs.copy()
    gone: set[int] = set()
    relabel: dict[int, int] = {}
    absorbed = 0
    for i, j in zip(*np.nonzero(np.triu(over))):
        li, lj = int(mix.labels[cand[i]]), int(mix.labels[cand[j]])
        if li in gone or lj in gone:
            continue
        if (li in keep_labels) != (lj in keep_labels):
            k, a = (i, j) if li in keep_labels else (j, i)
        elif li not in keep_labels and length[i] != length[j]:  # two newcomers: the longer hypothesis
            k, a = (i, j) if length[i] > length[j] else (j, i)
        else:
            k, a = (i, j) if li < lj else (j, i)
        label = int(mix.labels[cand[k]])
        one_coasts = (li in updated) != (lj in updated)
        if one_coasts:  # the state: the one a cluster updated, not a coasting one
            k, a = (i, j) if li in updated else (j, i)
        ck, ca = cand[k], cand[a]
        weights[ck] = max(weights[ck], mix.weights[ca])
        gone.add(int(mix.labels[ca]))
        if int(mix.labels[ck]) != label:
            relabel[int(mix.labels[ck])] = label
        absorbed += 1
        if max(mix.covs[ck, 5, 5], mix.covs[ca, 5, 5]) > UNION_LENGTH_STD**2:
            continue  # a length not seen: no evidence of where the vehicle ends
        if one_coasts:
            continue  # a coasting track's predicted rectangle is no fragment that was seen
        lo = min(-0.5 * length[k], along[k, a] - 0.5 * length[a])
        hi = max(0.5 * length[k], along[k, a] + 0.5 * length[a])
        shift, new_length, new_width = 0.5 * (lo + hi), hi - lo, max(width[k], width[a])
        u = np.array([np.cos(m[k, 3]), np.sin(m[k, 3])]) if cartesian else np.array([1.0, 0.0])
        means[ck, :2] += shift * u
        covs[ck, :2, :2] += shift**2 * np.outer(u, u)
        covs[ck, 5, 5] += (new_length - length[k]) ** 2
        covs[ck, 6, 6] += (new_width - width[k]) ** 2
        means[ck, 5], means[ck, 6] = new_length, new_width
    keep = ~np.isin(mix.labels, np.array(sorted(gone), dtype=mix.labels.dtype))
    labels = mix.labels.copy()
    for source, target in relabel.items():
        labels[mix.labels == source] = target
    if not wrapping.empty:
        means = wrapping.wrap(means)
    return Mixture(weights[keep], means[keep], covs[keep], labels[keep]), absorbed

# --------------------------------------------------------------------------------------------------
# The compiled kernels of this stage.
#
# The merge (``merge_kernel``), the whole reduce stage's first part (``reduce_kernel``: the field-of-view
# and road test, prune, merge, cap, the closed road's ``s``), ``Tracker._drop_inside_updated``'s test
# (``inside_updated_kernel``) and ``absorb_overlapping``'s screen (``absorb_candidates_kernel``,
# ``overlapping_pairs_kernel``, ``overlapping_candidates_kernel``).
#
# The merge (Vo & Ma): the Mahalanobis distance ``d_ij^T P_i^-1 d_ij`` of a pair (``d_ij = m_i - m_j``,
# wrapped coordinates wrapped); a pair whose ``d_k^2 / P_i[k, k]``, a lower bound of it when ``P_i`` is
# positive definite, already exceeds the gate on the first or second coordinate is rejected without it,
# and ``P_i^-1`` is computed only for the components some pair needs it of (so a singular covariance
# raises ``LinAlgError`` only when a pair needs its inverse). The greedy grouping: the heaviest remaining
# component takes every remaining one within the gate (ties of weight in index order). The moment match
# of each group about its heaviest component: the weighted mean, circular for angles; the weighted
# covariances plus the weighted spread, symmetrised.
# --------------------------------------------------------------------------------------------------


@njit(inline="always")
def _residual(x, angles, period_index, periods):
    for a in angles:
        x[a] = np.pi - ((np.pi - x[a]) % (2.0 * np.pi))
    for k in range(len(period_index)):
        i = period_index[k]
        x[i] -= periods[k] * math.floor(x[i] / periods[k] + 0.5)


#: A pair is skipped without its Mahalanobis distance only when a coordinate's bound exceeds the gate
#: by this factor: the bound holds exactly, so the skipped pairs are those the full test rejects.
MERGE_BOUND_MARGIN = 1.0 + 1e-6


@njit
def merge_kernel(weights, means, covs, gate, angles, period_index, periods):
    """Merged weights ``(G,)``, means ``(G, D)``, covariances ``(G, D, D)`` and the index of each
    group's heaviest component ``(G,)``."""
    n, dim = means.shape
    inv = np.empty((n, dim, dim))
    inverted = np.zeros(n, dtype=np.bool_)  # P_i^-1 computed when a pair first needs it
    order = np.argsort(-weights, kind="mergesort")
    remaining = np.ones(n, dtype=np.bool_)
    group = np.full(n, -1, dtype=np.int64)
    anchors = np.empty(n, dtype=np.int64)
    count = 0
    d = np.empty(dim)
    for j in order:
        if not remaining[j]:
            continue
        for i in range(n):
            if not remaining[i] or i == j:
                continue
            for k in range(dim):
                d[k] = means[i, k] - means[j, k]
            _residual(d, angles, period_index, periods)
            # d^T P^-1 d >= d_k^2 / P_kk for every coordinate k (Cauchy-Schwarz): a pair that the
            # position alone puts beyond the gate (with a margin far above rounding) is not merged,
            # without the inverse and the quadratic form (most pairs: other vehicles)
            if ((covs[i, 0, 0] > 0.0 and d[0] * d[0] > MERGE_BOUND_MARGIN * gate * covs[i, 0, 0])
                    or (dim > 1 and covs[i, 1, 1] > 0.0 and d[1] * d[1] > MERGE_BOUND_MARGIN * gate * covs[i, 1, 1])):
                continue
            if not inverted[i]:
                inv[i] = np.linalg.inv(covs[i])
                inverted[i] = True
            maha = 0.0
            for a in range(dim):
                row = 0.0
                for b in range(dim):
                    row += inv[i, a, b] * d[b]
                maha += d[a] * row
            if maha <= gate:
                group[i] = count
                remaining[i] = False
        group[j] = count
        remaining[j] = False
        anchors[count] = j
        count += 1
    w_sum = np.zeros(count)
    mean_dev = np.zeros((count, dim))
    dev = np.empty((n, dim))
    for i in range(n):
        g = group[i]
        w_sum[g] += weights[i]
        for k in range(dim):
            dev[i, k] = means[i, k] - means[anchors[g], k]
        _residual(dev[i], angles, period_index, periods)
        for k in range(dim):
            mean_dev[g, k] += weights[i] * dev[i, k]
    out_means = np.empty((count, dim))
    for g in range(count):
        for k in range(dim):
            mean_dev[g, k] /= w_sum[g]
            out_means[g, k] = means[anchors[g], k] + mean_dev[g, k]
        for a in angles:  # wrap: angles to (-pi, pi], periodic coordinates to [0, P)
            out_means[g, a] = np.pi - ((np.pi - out_means[g, a]) % (2.0 * np.pi))
        for k in range(len(period_index)):
            out_means[g, period_index[k]] = out_means[g, period_index[k]] % periods[k]
    cov = np.zeros((count, dim, dim))
    for i in range(n):
        g = group[i]
        for a in range(dim):
            sa = dev[i, a] - mean_dev[g, a]
            for b in range(dim):
                cov[g, a, b] += weights[i] * (covs[i, a, b] + sa * (dev[i, b] - mean_dev[g, b]))
    out_covs = np.empty((count, dim, dim))
    for g in range(count):
        for a in range(dim):
            for b in range(dim):
                cov[g, a, b] /= w_sum[g]
        for a in range(dim):
            for b in range(dim):
                out_covs[g, a, b] = 0.5 * (cov[g, a, b] + cov[g, b, a])
    return w_sum, out_means, out_covs, anchors[:count].copy()


@njit
def overlapping_pairs_kernel(means, cos_h, sin_h, cartesian, overlap, period):  # pragma: no cover - compiled
    """``tracker.reduction.absorb_overlapping``'s test of the candidates' means ``(N, D)``: ``over[i, j]``
    when the rectangles of ``i`` and ``j`` overlap along the road (``s``; along ``i``'s heading, of cosine
    ``cos_h[i]`` and sine ``sin_h[i]``, for ``cartesian`` states) by more than ``overlap`` m, each centre
    within half the narrower width of the other's across it; ``period`` > 0: ``s`` wraps with it (a
    closed road). The diagonal is False."""
    n = len(means)
    over = np.zeros((n, n), dtype=np.bool_)
    for i in range(n):
        for j in range(n):
            if i == j:
                continue
            d0 = means[j, 0] - means[i, 0]
            d1 = means[j, 1] - means[i, 1]
            if period > 0.0:
                d0 -= period * math.floor(d0 / period + 0.5)
            if cartesian:
                along = d0 * cos_h[i] + d1 * sin_h[i]
                across = -d0 * sin_h[i] + d1 * cos_h[i]
            else:
                along, across = d0, d1
            over[i, j] = (abs(along) < 0.5 * (means[i, 5] + means[j, 5]) - overlap
                          and abs(across) < 0.5 * min(means[i, 6], means[j, 6]))
    return over


@njit
def reduce_kernel(weights, means, covs, labels, near, near_limit, lateral, lateral_lo, lateral_hi,  # pragma: no cover
                  prune_threshold, gate, angles, period_index, periods, same_label_weight, max_components, s_period):
    """``tracker.reduction.reduce_in_view`` in one call: the components in view (``near <= near_limit``)
    and on the road (``lateral_lo[i] <= lateral[i] <= lateral_hi[i]``) of weight ``>= prune_threshold``, merged
    (``merge_kernel``, when more than one), capped at the ``max_components`` heaviest (a stable sort of
    ``-w``) and, with ``s_period > 0``, coordinate 0 taken modulo it (a closed road's ``s``).

    ``same_label_weight >= 0``: when two merged components of weight ``>= same_label_weight`` share a
    label (``labels`` int64), the cap and the modulo are left to the caller (``merge_same_label`` comes
    first) and ``pending`` is True. Returns weights ``(G,)``, means ``(G, D)``, covariances
    ``(G, D, D)``, the index in the input of each component's label ``(G,)``, the number of components
    out of view, the number in view but off the road, and ``pending``."""
    n, dim = means.shape
    left_view = 0
    off_road = 0
    kept = np.empty(n, dtype=np.int64)
    k = 0
    for i in range(n):
        inside = near[i] <= near_limit
        on_road = lateral[i] >= lateral_lo[i] and lateral[i] <= lateral_hi[i]
        if not inside:
            left_view += 1
        elif not on_road:
            off_road += 1
        elif weights[i] >= prune_threshold:
            kept[k] = i
            k += 1
    w = np.empty(k)
    m = np.empty((k, dim))
    p = np.empty((k, dim, dim))
    for r in range(k):
        i = kept[r]
        w[r] = weights[i]
        m[r] = means[i]
        p[r] = covs[i]
    source = kept[:k].copy()
    if k > 1:
        w, m, p, anchor = merge_kernel(w, m, p, gate, angles, period_index, periods)
        source = source[anchor]
    count = len(w)
    if same_label_weight >= 0.0:
        for a in range(count):
            if not w[a] >= same_label_weight:
                continue
            for b in range(a + 1, count):
                if w[b] >= same_label_weight and labels[source[b]] == labels[source[a]]:
                    return w, m, p, source, left_view, off_road, True
    if count > max_components:
        order = np.argsort(-w, kind="mergesort")[:max_components]
        w, m, p, source = w[order], m[order], p[order], source[order]
        count = max_components
    if s_period > 0.0:
        for r in range(count):
            m[r, 0] = m[r, 0] % s_period
    return w, m, p, source, left_view, off_road, False


@njit
def inside_updated_kernel(center, cos_seen, sin_seen, length, width, seen, idle):  # pragma: no cover - compiled
    """``tracker.tracker.Tracker._drop_inside_updated``'s test: which components ``idle`` (indices) have
    their rectangle's centre ``center (N, 2)`` inside the rectangle of one of the components ``seen``
    (indices; ``cos_seen``, ``sin_seen`` their headings' cosine and sine, ``length``, ``width`` ``(N,)``
    everyone's extent), as ``tracker.clustering.points_in_rectangles`` (margin 0) finds them
    (``points_in_rectangles_kernel``). Returns the mask ``(N,)`` of the components kept (those not
    inside) and the number dropped."""
    n_seen = len(seen)
    ctr = np.empty((n_seen, 2))
    half_l = np.empty(n_seen)
    half_w = np.empty(n_seen)
    for r in range(n_seen):
        k = seen[r]
        ctr[r, 0] = center[k, 0]
        ctr[r, 1] = center[k, 1]
        half_l[r] = 0.5 * length[k] + 0.0
        half_w[r] = 0.5 * width[k] + 0.0
    pts = np.empty((len(idle), 2))
    for r in range(len(idle)):
        pts[r, 0] = center[idle[r], 0]
        pts[r, 1] = center[idle[r], 1]
    owner = points_in_rectangles_kernel(pts, ctr, cos_seen, sin_seen, half_l, half_w)
    keep = np.ones(len(center), dtype=np.bool_)
    dropped = 0
    for r in range(len(idle)):
        if owner[r] >= 0:
            keep[idle[r]] = False
            dropped += 1
    return keep, dropped


@njit
def absorb_candidates_kernel(weights, labels, min_weight):  # pragma: no cover - compiled
    """``tracker.reduction.absorb_overlapping``'s candidates: the heaviest component of each label among
    those of weight ``>= min_weight`` (``labels`` int64), heaviest first (ties in index order). Returns
    their indices."""
    n = len(weights)
    heavy = np.empty(n, dtype=np.int64)
    h = 0
    for i in range(n):
        if weights[i] >= min_weight:
            heavy[h] = i
            h += 1
    heavy = heavy[:h]
    neg = np.empty(h)
    for r in range(h):
        neg[r] = -weights[heavy[r]]
    order = heavy[np.argsort(neg, kind="mergesort")]
    cand = np.empty(h, dtype=np.int64)
    c = 0
    for r in range(h):
        label = labels[order[r]]
        first = True
        for q in range(c):
            if labels[cand[q]] == label:
                first = False
                break
        if first:
            cand[c] = order[r]
            c += 1
    return cand[:c].copy()


@njit
def overlapping_candidates_kernel(weights, means, labels, min_weight, overlap, period):  # pragma: no cover - compiled
    """``absorb_candidates_kernel``'s candidates of states in road axes and whether two of them overlap
    (``overlapping_pairs_kernel`` along the road, the heading not used; ``period`` > 0: ``s`` wraps)."""
    cand = absorb_candidates_kernel(weights, labels, min_weight)
    c = len(cand)
    if c < 2:
        return cand, False
    m = np.empty((c, means.shape[1]))
    for r in range(c):
        m[r] = means[cand[r]]
    over = overlapping_pairs_kernel(m, np.ones(c), np.zeros(c), False, overlap, period)
    return cand, over.any()
