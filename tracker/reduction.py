"""Gaussian-mixture reduction for the GM-PHD filter: prune, merge, cap (Vo & Ma 2006).

A mixture is held as arrays: ``weights`` (J,), ``means`` (J, D), ``covs`` (J, D, D) and integer
``labels`` (J,). Wrapped coordinates (a ``tracker.ukf.Wrapping``: angles such as ``xi``, and ``s`` on a
closed road) are handled on the circle: residuals are wrapped and merged means are circular
weighted means, so components on either side of ``s = 0`` merge.

- prune: drop components with weight below ``threshold``;
- merge: repeatedly take the heaviest remaining component ``j`` and merge every component ``i``
  with ``(m_i - m_j)^T P_i^-1 (m_i - m_j) <= gate`` into one moment-matched Gaussian; the merged
  component keeps the label of the heaviest (DESIGN.md);
- cap: keep the ``max_components`` heaviest.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tracker.ukf import NO_WRAP, Wrapping


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
) -> Mixture:
    """Merge components of weight >= ``min_weight`` that share a label and whose positions (state
    entries ``position``) lie within ``distance`` metres of the heaviest of them: posteriors of one
    track updated by fragments of one vehicle's points (split clusters), which the Mahalanobis gate
    keeps apart when they are tight. Light components (e.g. the missed-detection copy) are left alone."""
    heavy = mix.weights >= min_weight
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
            w_sum, mean, cov = _moment_match(mix, idx[near], j, wrapping)
            w_out.append(np.array([w_sum]))
            m_out.append(mean[None, :])
            p_out.append(cov[None, :, :])
            l_out.append(np.array([label]))
            idx = idx[~near]
    return Mixture(np.concatenate(w_out), np.concatenate(m_out), np.concatenate(p_out), np.concatenate(l_out))


def merge(mix: Mixture, gate: float, wrapping: Wrapping = NO_WRAP) -> Mixture:
    """Merge components within Mahalanobis distance^2 ``gate`` of the heaviest remaining one.

    One pass per output component, each vectorised over the remaining components. The merged
    mean is the weighted mean (circular for angles), the covariance the weighted spread plus the
    weighted covariances (moment matching).
    """
    n = len(mix)
    if n <= 1:
        return mix
    inv = np.linalg.inv(mix.covs)
    remaining = np.ones(n, dtype=bool)
    order = np.argsort(-mix.weights, kind="stable")
    w_out, m_out, p_out, l_out = [], [], [], []
    for j in order:  # each iteration removes at least component j
        if not remaining[j]:
            continue
        idx = np.flatnonzero(remaining)
        d = wrapping.residual(mix.means[idx] - mix.means[j][None, :])
        maha = np.einsum("ni,nij,nj->n", d, inv[idx], d)
        group = idx[maha <= gate]
        w_sum, mean, cov = _moment_match(mix, group, j, wrapping)
        w_out.append(w_sum)
        m_out.append(mean)
        p_out.append(cov)
        l_out.append(mix.labels[j])
        remaining[group] = False
    return Mixture(np.array(w_out), np.array(m_out), np.array(p_out), np.array(l_out))


def reduce(
    mix: Mixture,
    *,
    prune_threshold: float,
    merge_gate: float,
    max_components: int,
    wrapping: Wrapping = NO_WRAP,
    same_label_distance: float | None = None,
    same_label_min_weight: float = 0.5,
) -> Mixture:
    """Prune, merge, then (with ``same_label_distance``) merge heavy same-label fragments
    (``merge_same_label``), and cap a mixture."""
    mix = merge(prune(mix, prune_threshold), merge_gate, wrapping)
    if same_label_distance is not None:
        mix = merge_same_label(mix, same_label_distance, same_label_min_weight, wrapping=wrapping)
    return cap(mix, max_components)
