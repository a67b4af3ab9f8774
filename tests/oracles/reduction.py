"""The mixture reduction (``tracker.reduction``) in numpy: Vo & Ma's merge one component at a time, the
reduce stage of the tracker written step by step, and the screen of ``absorb_overlapping``."""

from __future__ import annotations

import numpy as np

from tracker.reduction import Mixture, cap, merge_same_label
from tracker.ukf import NO_WRAP, Wrapping


def merge(mix: Mixture, gate: float, wrapping: Wrapping = NO_WRAP) -> Mixture:
    """The heaviest remaining component ``j`` (ties in index order) takes every remaining ``i`` with
    ``(m_i - m_j)^T P_i^-1 (m_i - m_j) <= gate`` (residuals wrapped); the group's moment-matched Gaussian
    (weights summed, the weighted mean about ``m_j``, the weighted covariances plus the weighted spread,
    symmetrised) keeps ``j``'s label."""
    if len(mix) <= 1:
        return mix
    inv = np.linalg.inv(mix.covs)
    remaining = np.ones(len(mix), dtype=bool)
    out_w, out_m, out_p, out_l = [], [], [], []
    for j in np.argsort(-mix.weights, kind="stable"):
        if not remaining[j]:
            continue
        idx = np.flatnonzero(remaining)
        d = wrapping.residual(mix.means[idx] - mix.means[j])
        group = idx[np.einsum("ni,nij,nj->n", d, inv[idx], d) <= gate]
        group = np.union1d(group, [j])
        w = mix.weights[group]
        dev = wrapping.residual(mix.means[group] - mix.means[j])
        mean_dev = (w[:, None] * dev).sum(axis=0) / w.sum()
        spread = dev - mean_dev
        cov = (w[:, None, None] * (mix.covs[group] + spread[:, :, None] * spread[:, None, :])).sum(axis=0) / w.sum()
        out_w.append(w.sum())
        out_m.append(wrapping.wrap(mix.means[j] + mean_dev))
        out_p.append(0.5 * (cov + cov.T))
        out_l.append(mix.labels[j])
        remaining[group] = False
    return Mixture(np.array(out_w), np.array(out_m), np.array(out_p), np.array(out_l))


def reduce_in_view(mix: Mixture, near_range: np.ndarray, max_range: float, lateral: np.ndarray,
                   lateral_bounds: tuple[float, float], *, prune_threshold: float, merge_gate: float,
                   max_components: int, wrapping: Wrapping = NO_WRAP, same_label_distance: float | None = None,
                   same_label_min_weight: float = 0.5, same_label_along_length: bool = False,
                   s_period: float | None = None) -> tuple[Mixture, int, int]:
    """The components in view and on the road, pruned, merged (``merge``), heavy same-label fragments
    merged (``merge_same_label``), capped and ``s`` taken modulo ``s_period``; with the counts of the
    components out of view and of those in view but off the road."""
    inside = near_range <= max_range
    on_road = (lateral >= lateral_bounds[0]) & (lateral <= lateral_bounds[1])
    counts = int((~inside).sum()), int((inside & ~on_road).sum())
    mix = mix.take(inside & on_road)
    mix = merge(mix.take(mix.weights >= prune_threshold), merge_gate, wrapping)
    if same_label_distance is not None:
        mix = merge_same_label(mix, same_label_distance, same_label_min_weight, wrapping=wrapping,
                               along_length=same_label_along_length)
    mix = cap(mix, max_components)
    if s_period is not None and len(mix):
        mix.means[:, 0] = np.mod(mix.means[:, 0], s_period)
    return mix, *counts


def absorb_candidates(mix: Mixture, min_weight: float) -> np.ndarray:
    """The heaviest component of each label among those of weight >= ``min_weight``, heaviest first
    (ties in index order)."""
    heavy = np.flatnonzero(mix.weights >= min_weight)
    order = heavy[np.argsort(-mix.weights[heavy], kind="stable")]
    _, first = np.unique(mix.labels[order], return_index=True)
    return order[np.sort(first)]


def overlapping(means: np.ndarray, overlap: float, cartesian: bool, position_periods=()) -> np.ndarray:
    """``over[i, j]``: the rectangles of states ``i`` and ``j`` (``[s, n, ., xi, ., L, W]``; Cartesian:
    ``[x, y, ., psi, ., L, W]``) overlap along the road (along ``i``'s heading) by more than ``overlap``
    m, each centre within half the narrower width of the other's across it; the diagonal False."""
    d = means[None, :, :2] - means[:, None, :2]  # d[i, j] = position of j - position of i
    if position_periods:
        d = Wrapping(periods=tuple(position_periods)).residual(d)
    if cartesian:
        c, s = np.cos(means[:, 3])[:, None], np.sin(means[:, 3])[:, None]
        along, across = d[..., 0] * c + d[..., 1] * s, -d[..., 0] * s + d[..., 1] * c
    else:
        along, across = d[..., 0], d[..., 1]
    length, width = means[:, 5], means[:, 6]
    over = ((np.abs(along) < 0.5 * (length[:, None] + length[None, :]) - overlap)
            & (np.abs(across) < 0.5 * np.minimum(width[:, None], width[None, :])))
    np.fill_diagonal(over, False)
    return over
