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
off the road dropped, then ``reduce`` (one compiled call when the kernels are on).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from tracker import compiled as compiled_kernels
from tracker.ukf import NO_WRAP, Wrapping
from tracker.compiled.reduction import (absorb_candidates_kernel, overlapping_candidates_kernel,
                                       overlapping_pairs_kernel, reduce_kernel)


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

    The distances of every pair, ``d_ij^T P_i^-1 d_ij`` with ``d_ij = m_i - m_j`` (wrapped), are
    computed at once; the greedy grouping (heaviest remaining component ``j`` takes every remaining
    ``i`` within the gate) is then a loop of boolean operations, and all groups are moment-matched in
    one batched pass (``_moment_match_groups``). The merged mean is the weighted mean (circular for
    angles, about the group's heaviest component), the covariance the weighted spread plus the weighted
    covariances. (By ``tracker.compiled.reduction`` when the compiled kernels are on.)
    """
    n = len(mix)
    if n <= 1:
        return mix
    if compiled_kernels.enabled():
        from tracker.compiled.reduction import merge_kernel

        weights, means, covs, anchor = merge_kernel(
            np.ascontiguousarray(mix.weights, dtype=float), np.ascontiguousarray(mix.means, dtype=float),
            np.ascontiguousarray(mix.covs, dtype=float), float(gate), *_wrapping_args(wrapping))
        return Mixture(weights, means, covs, mix.labels[anchor])
    inv = np.linalg.inv(mix.covs)
    d = wrapping.residual(mix.means[:, None, :] - mix.means[None, :, :])  # (i, j, D): m_i - m_j
    maha = np.einsum("ijd,ide,ije->ij", d, inv, d)
    within = maha <= gate
    remaining = np.ones(n, dtype=bool)
    group = np.full(n, -1)
    anchors = []
    for j in np.argsort(-mix.weights, kind="stable"):  # each iteration removes at least component j
        if not remaining[j]:
            continue
        members = remaining & within[:, j]
        members[j] = True
        group[members] = len(anchors)
        anchors.append(j)
        remaining &= ~members
    anchor = np.array(anchors)
    weights, means, covs = _moment_match_groups(mix, group, anchor, wrapping)
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


def _moment_match_groups(mix: Mixture, group: np.ndarray, anchor: np.ndarray,
                         wrapping: Wrapping) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``_moment_match`` of every group at once: component ``i`` belongs to group ``group[i]`` whose
    residuals are taken about component ``anchor[group[i]]``. Returns weights ``(G,)``, means
    ``(G, D)`` and covariances ``(G, D, D)``."""
    count = len(anchor)
    w = mix.weights
    w_sum = np.bincount(group, weights=w, minlength=count)
    dev = wrapping.residual(mix.means - mix.means[anchor[group]])
    mean_dev = np.zeros((count, mix.means.shape[1]))
    np.add.at(mean_dev, group, w[:, None] * dev)
    mean_dev /= w_sum[:, None]
    means = wrapping.wrap(mix.means[anchor] + mean_dev)
    spread = dev - mean_dev[group]
    cov = np.zeros((count,) + mix.covs.shape[1:])
    np.add.at(cov, group, w[:, None, None] * (mix.covs + spread[:, :, None] * spread[:, None, :]))
    cov /= w_sum[:, None, None]
    return w_sum, means, 0.5 * (cov + np.swapaxes(cov, 1, 2))


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
    lateral_bounds: tuple[float, float],
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
    on the road (``lo <= lateral <= hi``, ``lateral_bounds = (lo, hi)``), ``reduce``d; with ``s_period``
    coordinate 0 then taken modulo it (``numpy.mod``: a closed road's ``s``). Returns the mixture, the
    number of components out of view and the number in view but off the road. (In one call of
    ``tracker.compiled.reduction.reduce_kernel`` when the compiled kernels are on; ``merge_same_label``,
    and then the cap and the modulo, stay here in the frames where two heavy merged components share
    a label.)"""
    if len(near_range) != len(mix) or len(lateral) != len(mix):
        raise ValueError(f"need one range and one lateral offset per component ({len(mix)}); "
                         f"got {len(near_range)} and {len(lateral)}")
    lo, hi = lateral_bounds
    if compiled_kernels.enabled() and len(mix):
        weights, means, covs, source, left_view, off_road, pending = reduce_kernel(
            np.ascontiguousarray(mix.weights, dtype=float), np.ascontiguousarray(mix.means, dtype=float),
            np.ascontiguousarray(mix.covs, dtype=float), np.ascontiguousarray(mix.labels, dtype=np.int64),
            np.ascontiguousarray(near_range, dtype=float), float(max_range), np.ascontiguousarray(lateral, dtype=float),
            float(lo), float(hi), float(prune_threshold), float(merge_gate), *_wrapping_args(wrapping),
            -1.0 if same_label_distance is None else float(same_label_min_weight), int(max_components),
            0.0 if s_period is None else float(s_period))
        mix = Mixture(weights, means, covs, mix.labels[source])
        if pending:
            mix = cap(merge_same_label(mix, same_label_distance, same_label_min_weight, wrapping=wrapping,
                                       along_length=same_label_along_length), max_components)
            if s_period is not None and len(mix):
                mix.means[:, 0] = np.mod(mix.means[:, 0], s_period)
        return mix, left_view, off_road
    inside = near_range <= max_range
    on_road = (lateral >= lo) & (lateral <= hi)
    left_view, off_road = int((~inside).sum()), int((inside & ~on_road).sum())
    mix = reduce(mix.take(inside & on_road), prune_threshold=prune_threshold, merge_gate=merge_gate,
                 max_components=max_components, wrapping=wrapping, same_label_distance=same_label_distance,
                 same_label_min_weight=same_label_min_weight, same_label_along_length=same_label_along_length)
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
    """``absorb_overlapping``'s candidates by the compiled kernels (``absorb_candidates_kernel``: the
    heaviest component of each label of weight >= ``min_weight``, heaviest first) and whether they may
    overlap: False when there are fewer than two or ``overlapping_pairs_kernel`` finds no pair (along
    the road in one call with the candidates, ``overlapping_candidates_kernel``; along the heading,
    whose cosine and sine numpy takes, in a second); True where that test does not apply (fewer than 7
    state entries, a periodic position other than ``s`` alone), for the numpy test to decide."""
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
    keep_labels: frozenset[int] | set[int] = frozenset(),
    updated: frozenset[int] | set[int] = frozenset(),
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
    union of two duplicates of one car, each with the prior's 4.5 m and a few metres apart, would be a
    vehicle far longer than the car), but not when only one of them is in ``updated``: a coasting
    track's rectangle is its prediction, not a fragment seen, and its union with the newcomer on the
    vehicle would stretch the vehicle by the prediction's error.
    Every component of the absorbed label is dropped. Returns the mixture and the number of labels
    absorbed."""
    position_periods, s_period = _position_periods(wrapping)
    if compiled_kernels.enabled():
        # the usual frame: no two labels overlap, which compiled passes over the pairs tell
        cand, overlapping = _screened_candidates(mix, min_weight, overlap, cartesian, bool(position_periods), s_period)
        if not overlapping:
            return mix, 0
    else:
        heavy = np.flatnonzero(mix.weights >= min_weight)
        if len(heavy) < 2:
            return mix, 0
        order = heavy[np.argsort(-mix.weights[heavy], kind="stable")]
        seen: set[int] = set()  # a few heavy components: a set beats numpy.unique's sort
        first = [k for k, lab in enumerate(mix.labels[order].tolist()) if not (lab in seen or seen.add(lab))]
        cand = order[first]  # the heaviest component of each label, heaviest first
        if len(cand) < 2:
            return mix, 0
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
