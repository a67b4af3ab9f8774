"""Compiled mixture reduction: ``tracker.reduction.merge`` in one numba call (``merge_kernel``), the
whole reduce stage's first part (``reduce_kernel``: the field-of-view and road test, prune, merge, cap,
the closed road's ``s``), ``Tracker._drop_inside_updated``'s test (``inside_updated_kernel``) and
``absorb_overlapping``'s screen (``absorb_candidates_kernel``, ``overlapping_pairs_kernel``,
``overlapping_candidates_kernel``).

The merge takes the same steps as the numpy reference: the Mahalanobis distance of every pair ``d_ij^T
P_i^-1 d_ij`` (``d_ij = m_i - m_j``, wrapped coordinates wrapped; a pair whose ``d_k^2 / P_i[k, k]``, a
lower bound of it when ``P_i`` is positive definite, already exceeds the gate on the first or second
coordinate is rejected without it, and ``P_i^-1`` is computed only for the components some pair needs it
of: so a singular covariance raises ``LinAlgError`` here only when a pair needs its inverse, where the
numpy reference inverts them all), the greedy grouping (the heaviest remaining component takes every
remaining one within the gate; ties of weight in index order), and the moment match of each group about
its heaviest component (weighted mean, circular for angles; weighted covariances plus the weighted
spread, symmetrised)."""

from __future__ import annotations

import math

import numpy as np

from tracker.compiled import njit
from tracker.compiled.clustering import points_in_rectangles_kernel


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
    closed road). The same arithmetic as the numpy test, element by element; the diagonal False."""
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
    and on the road (``lateral_lo <= lateral <= lateral_hi``) of weight ``>= prune_threshold``, merged
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
        on_road = lateral[i] >= lateral_lo and lateral[i] <= lateral_hi
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
