"""The UKF update of a batch of pairs as numba calls: ``kalman_kernel`` (``tracker.update.kalman_update``)
and ``measurement_update_kernel``, the rectangle model's measurement step (the predicted measurements,
the radar gate, then the update).

The update has the low-rank form of ``tracker.update``'s module docstring: per pair the whitened
measurement deviations ``A`` (the sigma points' columns, then the noise factors' columns with weight 1
and no state deviation), ``M = I + A^T A``, and the solves against ``M`` by its Cholesky factor. ``M``
is positive definite (``I`` plus a Gram matrix) unless a predicted measurement or a noise factor is not
finite: then ``numpy.linalg.LinAlgError`` is raised (``tracker.update.kalman_update`` keeps such pairs out
of the kernel and gives them a NaN posterior; ``update_pairs`` refuses them).
"""

from __future__ import annotations

import math

import numpy as np

from tracker.jit import njit
from tracker.ukf import _residual, _wrap, cholesky_into


@njit
def _cholesky(a, low):  # pragma: no cover - compiled
    """Lower Cholesky factor of the SPD matrix ``a`` into ``low`` (its upper triangle left as it is);
    ``numpy.linalg.LinAlgError`` when ``a`` is not positive definite."""
    if not cholesky_into(a, low):
        raise np.linalg.LinAlgError("kalman_kernel: M is not positive definite")


@njit(fastmath=True)
def _dot(a, b, count):  # pragma: no cover - compiled
    """``sum_k a[k] b[k]`` over the first ``count`` entries of two contiguous rows."""
    acc = 0.0
    for k in range(count):
        acc += a[k] * b[k]
    return acc


@njit(fastmath=True)
def _gram(a_cols, nu, count, sw, g, gram, m_mat):  # pragma: no cover - compiled
    """Of the whitened columns ``a_cols (cols, count)`` and innovation ``nu``: ``g = A^T nu``, the Gram
    matrix ``A^T A`` and ``M = I + sqrt(W) A^T A sqrt(W)`` (in place)."""
    cols = len(sw)
    for k in range(cols):
        g[k] = _dot(a_cols[k], nu, count)
        for l in range(k + 1):
            gram[k, l] = _dot(a_cols[k], a_cols[l], count)
            gram[l, k] = gram[k, l]
    for k in range(cols):
        for l in range(cols):
            m_mat[k, l] = sw[k] * gram[k, l] * sw[l]
        m_mat[k, k] += 1.0


@njit(fastmath=True)
def kalman_kernel(sigma, mean, cov, z_sigma, z, r, r_like, mask, factors, wm, wc, angles, period_index,
                  period):  # pragma: no cover - compiled
    """Posterior ``mean (P, n)``, ``cov (P, n, n)``, ``loglik (P,)``, ``nis (P,)``, ``dim (P,)``, the
    predicted measurement ``y (P, D)`` and the innovation ``(P, D)`` (both 0 on padded rows) of each
    pair (``tracker.update.kalman_update``; ``factors (P, E, D)``, ``E`` may be 0). The posterior uses
    the variances ``r``, the likelihood and the NIS ``r_like`` (a second pass for the pairs where they
    differ). Every sum runs over a contiguous row (the loops are laid out for it), so that fastmath may
    vectorise it."""
    pairs, num_sigma, n = sigma.shape
    rows = z.shape[1]
    extra = factors.shape[1]
    cols = num_sigma + extra
    log_2pi = math.log(2.0 * math.pi)
    post_mean = np.empty((pairs, n))
    post_cov = np.empty((pairs, n, n))
    loglik = np.empty(pairs)
    nis = np.empty(pairs)
    dim = np.zeros(pairs, dtype=np.int64)
    y = np.zeros((pairs, rows))
    innovation = np.zeros((pairs, rows))
    nu = np.empty(rows)
    a_cols = np.zeros((cols, rows))  # whitened columns of A (before the weights), padding left out
    xw = np.zeros((n, cols))  # X^T W: the state deviations times Wc (0 for the noise factors' columns)
    dev = np.empty(n)
    sw = np.ones(cols)  # sqrt(Wc) (1 for the factors)
    for i in range(num_sigma):
        sw[i] = math.sqrt(wc[i])
    gram = np.empty((cols, cols))  # A^T A
    g = np.empty(cols)  # A^T nu
    m_mat = np.empty((cols, cols))
    low = np.zeros((cols, cols))  # Cholesky factor L of M
    rhs = np.empty((1 + n, cols))  # [a; B], a = sqrt(W) g, B = X^T W G sqrt(W)
    vee = np.empty((cols, 1 + n))  # L^-1 [a, B^T]
    vtv = np.empty((1 + n, 1 + n))  # [a, B^T]^T M^-1 [a, B^T]
    acc_row = np.empty(1 + n)
    xwg = np.empty((n, cols))
    for p in range(pairs):
        logdet_r = 0.0
        count = 0
        for d in range(rows):
            if not mask[p, d]:
                continue
            acc = 0.0
            for i in range(num_sigma):
                acc += wm[i] * z_sigma[p, i, d]
            y[p, d] = acc
            isr = 1.0 / math.sqrt(r[p, d])
            logdet_r += math.log(r[p, d])
            innovation[p, d] = z[p, d] - acc
            nu[count] = (z[p, d] - acc) * isr
            for i in range(num_sigma):
                a_cols[i, count] = (z_sigma[p, i, d] - acc) * isr
            for e in range(extra):
                a_cols[num_sigma + e, count] = factors[p, e, d] * isr
            count += 1
        for i in range(num_sigma):
            for j in range(n):
                dev[j] = sigma[p, i, j] - mean[p, j]
            _residual(dev, angles, period_index, period)
            for j in range(n):
                xw[j, i] = dev[j] * wc[i]
        _gram(a_cols, nu, count, sw, g, gram, m_mat)
        for k in range(cols):
            rhs[0, k] = sw[k] * g[k]
        for j in range(n):
            for k in range(cols):
                xwg[j, k] = _dot(xw[j], gram[k], cols)  # gram is symmetric
                rhs[1 + j, k] = xwg[j, k] * sw[k]
        _cholesky(m_mat, low)
        logdet_m = 0.0
        for k in range(cols):  # V = L^-1 [a, B^T] (rows k), by forward substitution
            logdet_m += math.log(low[k, k])
            for c in range(1 + n):
                acc_row[c] = rhs[c, k]
            for l in range(k):
                factor = low[k, l]
                for c in range(1 + n):
                    acc_row[c] -= factor * vee[l, c]
            for c in range(1 + n):
                vee[k, c] = acc_row[c] / low[k, k]
        for c in range(1 + n):  # M^-1 = L^-T L^-1: a^T M^-1 a = |v_0|^2, B M^-1 a = V_B^T v_0, ...
            for l in range(1 + n):
                acc = 0.0
                for k in range(cols):
                    acc += vee[k, c] * vee[k, l]
                vtv[c, l] = acc
        q = _dot(nu, nu, count) - vtv[0, 0]
        nis[p] = q
        dim[p] = count
        loglik[p] = -0.5 * (count * log_2pi + 2.0 * logdet_m + logdet_r + q)
        for j in range(n):  # K nu = X^T W g - B M^-1 a
            post_mean[p, j] = mean[p, j] + _dot(xw[j], g, cols) - vtv[1 + j, 0]
        _wrap(post_mean[p], angles, period_index, period)
        for j in range(n):  # P+ = P - (X^T W G W X - B M^-1 B^T), symmetrised
            for i in range(j + 1):
                t_ji = _dot(xwg[j], xw[i], cols) - vtv[1 + j, 1 + i]
                t_ij = _dot(xwg[i], xw[j], cols) - vtv[1 + i, 1 + j]
                post_cov[p, j, i] = 0.5 * ((cov[p, j, i] - t_ji) + (cov[p, i, j] - t_ij))
                post_cov[p, i, j] = post_cov[p, j, i]
        differs = False
        for d in range(rows):
            if mask[p, d] and r_like[p, d] != r[p, d]:
                differs = True
                break
        if not differs:
            continue
        # the likelihood and NIS under r_like: the same low-rank form, whitened by r_like
        logdet_r = 0.0
        count = 0
        for d in range(rows):
            if not mask[p, d]:
                continue
            isr = 1.0 / math.sqrt(r_like[p, d])
            logdet_r += math.log(r_like[p, d])
            nu[count] = innovation[p, d] * isr
            for i in range(num_sigma):
                a_cols[i, count] = (z_sigma[p, i, d] - y[p, d]) * isr
            for e in range(extra):
                a_cols[num_sigma + e, count] = factors[p, e, d] * isr
            count += 1
        _gram(a_cols, nu, count, sw, g, gram, m_mat)
        _cholesky(m_mat, low)
        logdet_m = 0.0
        quad = 0.0
        for k in range(cols):  # v = L^-1 a, a = sqrt(W) g: a^T M^-1 a = |v|^2
            logdet_m += math.log(low[k, k])
            acc = sw[k] * g[k]
            for l in range(k):
                acc -= low[k, l] * vee[l, 0]
            vee[k, 0] = acc / low[k, k]
            quad += vee[k, 0] * vee[k, 0]
        q = _dot(nu, nu, count) - quad
        nis[p] = q
        loglik[p] = -0.5 * (count * log_2pi + 2.0 * logdet_m + logdet_r + q)
    return post_mean, post_cov, loglik, nis, dim, y, innovation


@njit
def _features(center, psi, v, length, width, p, i, out):  # pragma: no cover - compiled
    """The features of sigma point ``i`` of pair ``p`` in which its predicted measurement is linear
    (``tracker.measurement.predict_measurements``): ``(cx, cy, L cos psi, L sin psi, cos psi, sin psi,
    W sin psi, W cos psi, v cos psi, v sin psi)``, written to ``out (10,)``."""
    c, s = math.cos(psi[p, i]), math.sin(psi[p, i])
    out[0] = center[p, i, 0]
    out[1] = center[p, i, 1]
    out[2] = length[p, i] * c
    out[3] = length[p, i] * s
    out[4] = c
    out[5] = s
    out[6] = width[p, i] * s
    out[7] = width[p, i] * c
    out[8] = v[p, i] * c
    out[9] = v[p, i] * s


@njit
def _predicted(center, psi, v, length, width, matrix, mask, z_sigma):  # pragma: no cover - compiled
    """The rectangle measurement model ``h``: the predicted measurement of sigma point ``i`` of pair ``p``
    in row ``d`` is ``z_sigma[p, i, d] = features(p, i) . matrix[p, :, d]`` (``_features``; the rows
    where ``mask`` is False are left as they are)."""
    pairs, num_sigma, rows = z_sigma.shape
    feats = np.empty(10)
    for p in range(pairs):
        for i in range(num_sigma):
            _features(center, psi, v, length, width, p, i, feats)
            for d in range(rows):
                if not mask[p, d]:
                    continue
                acc = 0.0
                for k in range(10):
                    acc += feats[k] * matrix[p, k, d]
                z_sigma[p, i, d] = acc


@njit
def predict_measurements_kernel(center, psi, v, length, width, matrix):  # pragma: no cover - compiled
    """Every row of ``_predicted``: the predicted measurements ``(P, S, D)`` (``tracker.measurement.
    predict_measurements``)."""
    z_sigma = np.empty((center.shape[0], center.shape[1], matrix.shape[2]))
    _predicted(center, psi, v, length, width, matrix, np.ones((center.shape[0], matrix.shape[2]), dtype=np.bool_),
               z_sigma)
    return z_sigma


@njit
def measurement_update_kernel(sigma, mean, cov, center, psi, v, length, width, matrix, z, r, r_like, mask, factors,
                              radar, cluster_index, gate, wm, wc, angles, period_index, period):  # pragma: no cover - compiled
    """``tracker.update.update_pairs``' measurement step of the pairs in one call: the predicted
    measurement sigma points ``features @ matrix`` (``predict_measurements``; the sigma points'
    rectangles ``center (P, S, 2)``, ``psi``, ``v``, ``length``, ``width (P, S)``), the radar gate
    (``MeasurementConfig.radar_gate``; ``gate < 0``: off): a cluster's radar rows (the last two of ``D`` that any
    pair uses) are set aside when no pair with ``radar`` explains them (their own normalised
    innovation squared above ``gate``), and the UKF update (``kalman_kernel``; ``r_like`` the variances
    of its likelihood and NIS). Returns
    ``kalman_kernel``'s outputs and, per pair, whether its radar rows were set aside."""
    pairs, num_sigma, n = sigma.shape
    rows = matrix.shape[2]
    z_sigma = np.empty((pairs, num_sigma, rows))  # only the rows a pair uses are read, so only those are made
    _predicted(center, psi, v, length, width, matrix, mask, z_sigma)
    rejected = np.zeros(pairs, dtype=np.bool_)
    if gate >= 0.0 and pairs:
        radar_rows = np.zeros(2, dtype=np.int64)
        used = 0
        for d in range(max(rows - 2, 0), rows):
            for p in range(pairs):
                if mask[p, d]:
                    radar_rows[used] = d
                    used += 1
                    break
        clusters = 0
        for p in range(pairs):
            clusters = max(clusters, cluster_index[p] + 1)
        explained = np.zeros(clusters, dtype=np.bool_)
        y_v = np.empty(2)
        nu = np.empty(2)
        s_v = np.empty((2, 2))
        for p in range(pairs):
            if not radar[p]:
                continue
            if used == 0:  # no radar rows in use: nothing to set aside
                explained[cluster_index[p]] = True
                continue
            for a in range(used):
                acc = 0.0
                for i in range(num_sigma):
                    acc += wm[i] * z_sigma[p, i, radar_rows[a]]
                y_v[a] = acc
                nu[a] = z[p, radar_rows[a]] - acc
            for a in range(used):
                for b in range(used):
                    acc = 0.0
                    for i in range(num_sigma):
                        acc += wc[i] * (z_sigma[p, i, radar_rows[a]] - y_v[a]) * (z_sigma[p, i, radar_rows[b]] - y_v[b])
                    s_v[a, b] = acc
                s_v[a, a] += r[p, radar_rows[a]]
            if used == 1:
                q = nu[0] * nu[0] / s_v[0, 0]
            else:  # nu^T S^-1 nu of the 2 x 2 block
                det = s_v[0, 0] * s_v[1, 1] - s_v[0, 1] * s_v[1, 0]
                q = (s_v[1, 1] * nu[0] * nu[0] - (s_v[0, 1] + s_v[1, 0]) * nu[0] * nu[1] + s_v[0, 0] * nu[1] * nu[1]) / det
            if q <= gate:
                explained[cluster_index[p]] = True
        any_rejected = False
        for p in range(pairs):
            rejected[p] = radar[p] and not explained[cluster_index[p]]
            any_rejected = any_rejected or rejected[p]
        if any_rejected:
            mask = mask.copy()
            z = z.copy()
            r = r.copy()
            r_like = r_like.copy()
            for p in range(pairs):
                if rejected[p]:
                    for d in range(max(rows - 2, 0), rows):
                        mask[p, d] = False
                        z[p, d] = 0.0
                        r[p, d] = 1.0
                        r_like[p, d] = 1.0
    post_mean, post_cov, loglik, nis, dim, y, innovation = kalman_kernel(
        sigma, mean, cov, z_sigma, z, r, r_like, mask, factors, wm, wc, angles, period_index, period)
    return post_mean, post_cov, loglik, nis, dim, y, innovation, rejected
