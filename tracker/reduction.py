"""Gaussian-mixture reduction for the GM-PHD filter: prune, merge, cap (Vo & Ma 2006).

A mixture is held as arrays: ``weights`` (J,), ``means`` (J, D), ``covs`` (J, D, D) and integer
``labels`` (J,). Angle components (``angle_indices``, e.g. ``xi`` of the curvilinear state) are
handled on the circle: residuals are wrapped and merged means are circular weighted means.

- prune: drop components with weight below ``threshold``;
- merge: repeatedly take the heaviest remaining component ``j`` and merge every component ``i``
  with ``(m_i - m_j)^T P_i^-1 (m_i - m_j) <= gate`` into one moment-matched Gaussian; the merged
  component keeps the label of the heaviest (DESIGN.md);
- cap: keep the ``max_components`` heaviest.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tracker.angles import wrap_angle


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


def _residual(a: np.ndarray, b: np.ndarray, angle_indices: tuple[int, ...]) -> np.ndarray:
    d = a - b
    for k in angle_indices:
        d[..., k] = wrap_angle(d[..., k])
    return d


def prune(mix: Mixture, threshold: float) -> Mixture:
    """Components with weight >= ``threshold``."""
    return mix.take(mix.weights >= threshold)


def cap(mix: Mixture, max_components: int) -> Mixture:
    """The ``max_components`` heaviest components (in decreasing weight)."""
    if len(mix) <= max_components:
        return mix
    order = np.argsort(-mix.weights, kind="stable")[:max_components]
    return mix.take(order)


def merge(mix: Mixture, gate: float, angle_indices: tuple[int, ...] = ()) -> Mixture:
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
        d = _residual(mix.means[idx], mix.means[j][None, :], angle_indices)
        maha = np.einsum("ni,nij,nj->n", d, inv[idx], d)
        group = idx[maha <= gate]
        w = mix.weights[group]
        w_sum = float(w.sum())
        dev = _residual(mix.means[group], mix.means[j][None, :], angle_indices)
        mean_dev = (w[:, None] * dev).sum(axis=0) / w_sum
        mean = mix.means[j] + mean_dev
        for k in angle_indices:
            mean[k] = wrap_angle(mean[k])
        spread = dev - mean_dev
        cov = (w[:, None, None] * (mix.covs[group] + spread[:, :, None] * spread[:, None, :])).sum(axis=0) / w_sum
        w_out.append(w_sum)
        m_out.append(mean)
        p_out.append(0.5 * (cov + cov.T))
        l_out.append(mix.labels[j])
        remaining[group] = False
    return Mixture(np.array(w_out), np.array(m_out), np.array(p_out), np.array(l_out))


def reduce(
    mix: Mixture,
    *,
    prune_threshold: float,
    merge_gate: float,
    max_components: int,
    angle_indices: tuple[int, ...] = (),
) -> Mixture:
    """Prune, merge, then cap a mixture."""
    return cap(merge(prune(mix, prune_threshold), merge_gate, angle_indices), max_components)
