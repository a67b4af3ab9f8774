"""The UKF update of the pairs (``tracker.update``) in plain numpy: the update of a batch of pairs in
the low-rank form (the matrix inversion lemma over the sigma points' columns), the predicted
measurements of the rectangle model, the radar gate, the extent growth before the update and the
extent rules after it, and ``update_pairs``, the whole update of (component, cluster) pairs from these
steps and ``oracles.measurement``'s conversion to E and measurement structure."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from oracles.measurement import build_structure, shows_longer_side, to_vehicle

from tracker.config import BirthConfig, TrackerConfig
from tracker.measurement import FULL, Rectangles, Structure
from tracker.motion import LENGTH, WIDTH, XI
from tracker.ukf import UnscentedTransform, Wrapping
from tracker.update import UpdateResult, likelihood_variances, state_wrapping

LOG_2PI = float(np.log(2.0 * np.pi))


def kalman_update(ut: UnscentedTransform, sigma: np.ndarray, mean: np.ndarray, cov: np.ndarray, z_sigma: np.ndarray,
                  z: np.ndarray, r: np.ndarray, mask: np.ndarray | None = None, wrapping: Wrapping = Wrapping(),
                  factors: np.ndarray | None = None, r_likelihood: np.ndarray | None = None) -> UpdateResult:
    """The UKF update of each pair by the rows ``mask[p]`` of its measurement, batched over the pairs in
    the low-rank form of ``tracker.update``'s module docstring: with the whitened deviations
    ``A = R^-1/2 [sqrt(Wc_i) (Z_i - y)]`` (the noise factors ``factors (P, E, D)`` as extra columns of
    weight 1 and no state deviation) and ``M = I + A^T A``, ``S^-1 = R^-1/2 (I - A M^-1 A^T) R^-1/2`` and
    ``det S = det R det M``; ``m+ = m + K (z - y)``, ``P+ = P - T S^-1 T^T`` (symmetrised), the
    log-likelihood and the NIS with ``r_likelihood`` (default ``r``). The predicted measurement and the
    innovation are 0 on unused rows. (``tests/test_update.py`` checks this form against the dense
    textbook update.)"""
    mask = np.ones(z.shape, dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
    r_like = r if r_likelihood is None else r_likelihood
    wm = ut.wm
    inv_sqrt_r = np.where(mask, 1.0 / np.sqrt(np.where(mask, r, 1.0)), 0.0)  # (P, D)
    y = (wm @ z_sigma) * mask  # (P, D)
    zt = z_sigma * inv_sqrt_r[:, None, :]  # (P, S, D) whitened deviations (one temporary, then in place)
    zt -= (y * inv_sqrt_r)[:, None, :]
    nu = (z - y) * inv_sqrt_r  # whitened innovation
    xc = ut.deviations(sigma, mean, wrapping)  # (P, S, n)
    wc = ut.wc
    gram = zt @ np.swapaxes(zt, 1, 2)  # (P, S, S)
    g = (zt @ nu[..., None])[..., 0]  # (P, S)
    if factors is not None and factors.shape[1]:  # extra columns: weight 1, no state deviation
        f = np.asarray(factors, dtype=float) * inv_sqrt_r[:, None, :]  # (P, E, D)
        g_zf = zt @ np.swapaxes(f, 1, 2)  # (P, S, E)
        g_ff = f @ np.swapaxes(f, 1, 2)
        gram = np.concatenate(
            [np.concatenate([gram, g_zf], axis=2), np.concatenate([np.swapaxes(g_zf, 1, 2), g_ff], axis=2)], axis=1
        )
        g = np.concatenate([g, (f @ nu[..., None])[..., 0]], axis=1)
        xc = np.concatenate([xc, np.zeros((xc.shape[0], f.shape[1], xc.shape[2]))], axis=1)
        wc = np.concatenate([wc, np.ones(f.shape[1])])
    sw = np.sqrt(wc)
    m_mat = np.eye(len(wc)) + sw[:, None] * gram * sw[None, :]
    a_vec = sw * g
    xw = np.swapaxes(xc * wc[:, None], 1, 2)  # (P, n, S): X^T W
    xwg = xw @ gram  # (P, n, S)
    b_mat = xwg * sw  # T~ A (P, n, S)
    rhs = np.concatenate([a_vec[..., None], np.swapaxes(b_mat, 1, 2)], axis=2)  # (P, S, 1 + n)
    sol = np.linalg.solve(m_mat, rhs)
    m_inv_a, m_inv_bt = sol[..., 0], sol[..., 1:]
    nis = np.einsum("pd,pd->p", nu, nu) - np.einsum("ps,ps->p", a_vec, m_inv_a)
    logdet_m = 2.0 * np.log(np.diagonal(np.linalg.cholesky(m_mat), axis1=1, axis2=2)).sum(axis=1)  # M = I + A^T A is SPD
    logdet = logdet_m + np.sum(np.log(np.where(mask, r, 1.0)), axis=1)
    dim = mask.sum(axis=1)
    k_nu = (xw @ g[..., None])[..., 0] - (b_mat @ m_inv_a[..., None])[..., 0]
    t_st = xwg @ np.swapaxes(xw, 1, 2) - b_mat @ m_inv_bt
    post_mean = mean + k_nu
    if not wrapping.empty:
        post_mean = wrapping.wrap(post_mean)
    post_cov = cov - t_st
    post_cov = 0.5 * (post_cov + np.swapaxes(post_cov, 1, 2))
    loglik = -0.5 * (dim * LOG_2PI + logdet + nis)
    differs = np.flatnonzero(np.any(mask & (r_like != r), axis=1))
    if len(differs):  # the likelihood and NIS of these pairs under r_likelihood
        other = kalman_update(ut, sigma[differs], mean[differs], cov[differs], z_sigma[differs], z[differs],
                              r_like[differs], mask[differs], wrapping,
                              None if factors is None else np.asarray(factors, dtype=float)[differs])
        loglik[differs], nis[differs] = other.log_likelihood, other.nis
    return UpdateResult(post_mean, post_cov, loglik, nis, dim, y, (z - y) * mask)


def predict_measurements(rect: Rectangles, structure: Structure) -> np.ndarray:
    """``tracker.measurement.predict_measurements`` as one batched numpy product: the features of every
    sigma point's rectangle times ``Structure.matrix``."""
    c, s = np.cos(rect.psi), np.sin(rect.psi)
    feats = np.stack(
        [rect.center[..., 0], rect.center[..., 1], rect.length * c, rect.length * s, c, s,
         rect.width * s, rect.width * c, rect.v * c, rect.v * s],
        axis=-1,
    )
    return feats @ structure.matrix


def gate_radar_rows(ut: UnscentedTransform, structure: Structure, z_sigma: np.ndarray, cluster_index: np.ndarray,
                    gate: float) -> tuple[Structure, np.ndarray]:
    """Set aside the radar velocity of clusters that no pair explains (``MeasurementConfig.radar_gate``).

    Per pair with radar rows, their own normalised innovation squared ``nu^T S_v^-1 nu`` (``S_v`` the
    rows' block of ``S``: the sigma points' spread plus ``R``; one row in ``"speed"`` mode, two in
    ``"velocity"`` mode) is compared with ``gate``; when it exceeds the gate for *every* pair of a
    cluster, the detection is no velocity of anything predicted there (a false alarm or another
    vehicle's detection joined to the cluster), and the cluster's pairs are updated without it. A
    detection some pair explains stays for all of them: it still tells the hypotheses apart. Returns the
    structure (radar rows masked where rejected) and, per pair, whether its radar rows were rejected."""
    width = structure.mask.shape[1]
    rows = np.flatnonzero(structure.mask.any(axis=0) & (np.arange(width) >= width - 2))  # the radar rows in use
    has = structure.radar
    fused = np.flatnonzero(has)
    if len(rows) == 1:  # "speed": one row, S is a number
        zs = z_sigma[fused, :, rows[0]]  # (F, S) the radar row's sigma points of the pairs with radar
        y = zs @ ut.wm
        dev = zs - y[:, None]
        nis_f = (structure.z[fused, rows[0]] - y) ** 2 / ((dev * dev) @ ut.wc + structure.r[fused, rows[0]])
    else:
        zs = z_sigma[fused][:, :, rows]  # (F, S, k)
        y = np.einsum("s,psk->pk", ut.wm, zs)
        dev = zs - y[:, None, :]
        nu = structure.z[fused][:, rows] - y
        s_v = np.einsum("s,psk,psl->pkl", ut.wc, dev, dev) + structure.r[fused][:, rows][:, :, None] * np.eye(len(rows))
        nis_f = np.einsum("pk,pk->p", nu, np.linalg.solve(s_v, nu[..., None])[..., 0])
    nis = np.full(len(has), np.inf)
    nis[fused] = nis_f
    explained = np.zeros(int(cluster_index.max()) + 1 if len(cluster_index) else 0, dtype=bool)
    explained[cluster_index[has & (nis <= gate)]] = True
    rejected = has & ~explained[cluster_index]
    if not rejected.any():
        return structure, rejected
    mask = structure.mask.copy()
    mask[rejected[:, None] & (np.arange(mask.shape[1]) >= mask.shape[1] - 2)[None, :]] = False
    return dataclasses.replace(structure, mask=mask, radar=has & ~rejected, z=np.where(mask, structure.z, 0.0),
                               r=np.where(mask, structure.r, 1.0)), rejected


def grow_extent(means: np.ndarray, covs: np.ndarray, structure: Structure,
                mean_corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The prior of each pair widened where a part's chord exceeds its predicted side by evidence of a
    longer side (``shows_longer_side``; long parts, odd sides, for ``L``, the others for ``W``):
    ``P += e^2 d d^T`` with ``d = extent_growth_direction``. Returns the mask of widened pairs and the
    covariances (a copy)."""
    long_part = structure.sides % 2 == 1  # (P, 2): sides 1, 3 run along the length
    excess = np.where(np.isfinite(structure.excess), structure.excess, -np.inf)
    out = covs.copy()
    grown = np.zeros(len(means), dtype=bool)
    for index, is_part in ((LENGTH, long_part), (WIDTH, ~long_part)):
        e = np.max(np.where(is_part, excess, -np.inf), axis=1)  # (P,)
        sd = np.sqrt(np.maximum(covs[:, index, index], 0.0))
        hit = shows_longer_side(e, sd)
        if not hit.any():
            continue
        d = extent_growth_direction(mean_corners, means[:, XI], means.shape[1], index)
        out += np.where(hit, e, 0.0)[:, None, None] ** 2 * d[:, :, None] * d[:, None, :]
        grown |= hit
    return grown, out


def extent_growth_direction(mean_corners: np.ndarray, heading: np.ndarray, dim: int, index: int) -> np.ndarray:
    """The state direction ``d (P, dim)`` in which rectangles grow their length (``index = LENGTH``) or
    width (``WIDTH``) by 1 m while the end nearest the sensor stays put: ``0.5 sgn u`` in the position
    slots (``u = (cos h, sin h)`` along the body for the length, ``(-sin h, cos h)`` across it for the
    width, ``h`` the ``heading`` state ``xi`` or ``psi``), 1 in the extent slot; ``sgn = +1`` when the
    sensor (the E origin) lies behind the centre along that axis of ``mean_corners (P, 4, 2)`` in E.
    Used by ``grow_extent`` and ``replace_length_prior``."""
    corners = np.asarray(mean_corners, dtype=float)
    body = corners[:, 0] - corners[:, 3]  # rear-right -> front-right: the body axis in E
    axis = body if index == LENGTH else np.stack([-body[:, 1], body[:, 0]], axis=-1)
    sgn = np.where(np.einsum("pd,pd->p", corners.mean(axis=1), axis) >= 0.0, 1.0, -1.0)
    c, s = np.cos(heading), np.sin(heading)
    d = np.zeros((len(corners), dim))
    d[:, 0], d[:, 1] = (0.5 * sgn * c, 0.5 * sgn * s) if index == LENGTH else (0.5 * sgn * -s, 0.5 * sgn * c)
    d[:, index] = 1.0
    return d


def hold_unobserved_extent(res: UpdateResult, prior_mean: np.ndarray, prior_cov: np.ndarray, structure: Structure,
                           mean_corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Keep ``L`` (``W``) of a pair at its prior mean and variance unless the cluster shows a long
    (short) side fully -- the Schmidt ("consider") update of an unobserved extent, in place.

    Seen only from its rear, a car's length is unobservable: the points fix ``s - L/2``, and the
    normal update moves ``L`` by the prior's ``s``-``L`` correlation times every along-track innovation.
    Any small model error (slip, a timing lag, an accelerating car) then drains into ``L`` frame after
    frame. The Schmidt update with the extent as a consider
    parameter is the normal one with the extent's gain row set to zero: its mean and variance stay at the
    prior, the other states and their cross-covariances with it are updated as usual (``P+ = P - K S K^T``
    everywhere but ``P+[L, L] = P[L, L]``; when both ``L`` and ``W`` are held their whole 2 x 2 block,
    the cross term included, stays the prior's), which keeps ``P+`` positive semi-definite. Where a
    held ``L``'s face (a short side) is shown fully, the mean also keeps that face where the update put
    it: it moves by ``(L_prior - L+) d`` (``d`` the growth direction, ``extent_growth_direction``), the
    centre by half the length's change; through the prior's ``s``-``L`` correlation the Schmidt gain
    explains a face seen off its prediction by ``L``, and with ``L`` held the centre would not follow
    the face. Returns the masks of pairs whose ``L`` and whose ``W`` were held."""
    full = structure.mode == FULL  # (P, 2 parts)
    long_side = structure.sides % 2 == 1  # sides 1 (left) and 3 (right) run along the length
    hold_length, hold_width = ~(full & long_side).any(axis=1), ~(full & ~long_side).any(axis=1)
    face = hold_length & ~hold_width
    if face.any():
        d = extent_growth_direction(np.asarray(mean_corners, dtype=float)[face], res.mean[face, XI], res.mean.shape[1],
                                    LENGTH)
        res.mean[face] += (prior_mean[face, LENGTH] - res.mean[face, LENGTH])[:, None] * d
    hold_extent(res, prior_mean, prior_cov, hold_length, hold_width)
    return hold_length, hold_width


def hold_extent(res: UpdateResult, prior_mean: np.ndarray, prior_cov: np.ndarray, hold_length: np.ndarray,
                hold_width: np.ndarray) -> None:
    """The Schmidt update's consider parameters, in place: ``L`` where ``hold_length`` and ``W`` where
    ``hold_width`` (masks over the pairs) keep their prior mean and variance, and where both are held
    their joint 2 x 2 block stays the prior's (``hold_unobserved_extent``)."""
    for index, hold in ((LENGTH, hold_length), (WIDTH, hold_width)):
        res.mean[hold, index] = prior_mean[hold, index]
        res.cov[hold, index, index] = prior_cov[hold, index, index]
    both = hold_length & hold_width  # both consider parameters: their joint block stays the prior's
    res.cov[both, LENGTH, WIDTH] = prior_cov[both, LENGTH, WIDTH]
    res.cov[both, WIDTH, LENGTH] = prior_cov[both, WIDTH, LENGTH]


def class_length_prior(width: np.ndarray, width_var: np.ndarray, classes,
                       width_error_std: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """The length prior ``(mean, variance)`` of vehicles whose widths are ``N(width, width_var)`` (arrays
    ``(P,)``), from the vehicle classes ``classes`` (``tracker.config.VehicleClass``), a measured width
    straying from the body's by ``width_error_std`` beyond its variance (mirrors, label boxes).

    The class of a vehicle is unknown; its width tells it: with the classes' shares as the prior and
    their width distributions, widened by the width's own variance and its error, as the likelihood,
    ``p(c | w) = share_c N(w; width_c, width_std_c^2 + err^2 + var_w) / sum_k share_k N(w; width_k, ...)``.
    The length given the width is the mixture of the classes' lengths with those weights; its mean and
    variance are ``sum_c p_c length_c`` and ``sum_c p_c (length_std_c^2 + length_c^2) - mean^2``."""
    share = np.array([c.share for c in classes])
    mu_w = np.array([c.width for c in classes])
    var_w = (np.array([c.width_std**2 + width_error_std**2 for c in classes])
             + np.asarray(width_var, dtype=float)[:, None])
    log_w = np.log(share) - 0.5 * np.log(var_w) - 0.5 * (np.asarray(width, dtype=float)[:, None] - mu_w) ** 2 / var_w
    p = np.exp(log_w - log_w.max(axis=1, keepdims=True))
    p /= p.sum(axis=1, keepdims=True)
    mu_l = np.array([c.length for c in classes])
    mean = p @ mu_l
    return mean, np.maximum(p @ (np.array([c.length_std for c in classes]) ** 2 + mu_l**2) - mean**2, 0.0)


def vehicle_class_prior(res: UpdateResult, held_length: np.ndarray, held_width: np.ndarray, mean_corners: np.ndarray,
                        config: BirthConfig) -> np.ndarray:
    """A held, unmeasured length given the prior of the vehicle classes by a width seen whole, in place.

    Seen from behind, a bus is a 2.5 m wide rear: its width is measured, its length never (the Schmidt
    update holds it, ``hold_unobserved_extent``), and a track born with a car's 4.5 m puts the centre of
    a 16 m bus ~6 m behind the bus's; a motorcycle's 0.8 m rear likewise puts it ~1.2 m ahead. A pair
    whose length was held this update and never measured (its standard deviation at least
    ``0.9 length_std``: births start at ``length_std`` or wider, and only a side seen whole narrows it) and whose width was seen whole takes the classes' length given its posterior
    width (``class_length_prior``) where that lies beyond one standard deviation of the held length
    (within it the held prior already covers the classes' guess, and a change would trade one guess for
    another) and is longer, or where the length is still no more than a
    car's prior (``config.length``: points that showed a longer side bound it from below, so the classes
    may lengthen it but not undercut it), or where its standard deviation exceeds ``1.5 length_std`` (a
    spread no fit gives: the length is the classes' prior on an earlier width) and the classes are
    sure of a short vehicle (their spread at most ``length_std``; a car born on an oblique fit 2.6 m
    wide is shortened once its rear shows 1.9 m, a truck grown by a side it showed is not): the mean moves there and the variance rises to the classes'
    where it is lower, the end nearest the sensor staying put (``replace_length_prior``). Applied again in
    later frames it moves the length with the width's posterior and adds no variance the length
    already has. Returns the mask of the pairs changed."""
    hit = held_length & ~held_width & (res.cov[:, LENGTH, LENGTH] >= (0.9 * config.length_std) ** 2)
    if not hit.any():
        return hit
    mean, var = class_length_prior(res.mean[:, WIDTH], np.maximum(res.cov[:, WIDTH, WIDTH], 0.0), config.classes,
                                   config.width_error_std)
    e = mean - res.mean[:, LENGTH]
    # no fit is that uncertain: the classes' own prior, undercut only where the width rules out the long classes
    from_classes = (res.cov[:, LENGTH, LENGTH] > (1.5 * config.length_std) ** 2) & (var <= config.length_std**2)
    hit &= ((e > 0.0) | (res.mean[:, LENGTH] <= config.length) | from_classes) & (e * e > res.cov[:, LENGTH, LENGTH])
    if not hit.any():
        return hit
    target = np.where(e > 0.0, np.maximum(var, res.cov[:, LENGTH, LENGTH]), var)
    return replace_length_prior(res, hit, mean_corners, mean[hit], target[hit])


def replace_length_prior(res: UpdateResult, hit: np.ndarray, mean_corners: np.ndarray, length: np.ndarray,
                         variance: np.ndarray) -> np.ndarray:
    """Give the pairs ``hit`` the length ``length`` with variance ``variance`` (arrays over the pairs
    hit) in place of their unmeasured one, the end nearest the sensor staying put with its uncertainty.
    With ``d`` the direction of ``grow_extent`` (``0.5 sgn (cos h, sin h)`` in the position slots, 1 in
    the ``L`` slot) and ``a`` its position part: ``m += (length - L) d``; a larger variance is added
    along ``d`` (``P += (variance - P_LL) d d^T``); a smaller one scales the length's deviation by
    ``r = sqrt(variance / P_LL)`` in the coordinates ``y = T x`` of the near end and the length::

        P <- T^-1 S T P T^T S T^-T,   T = I - a e_L^T,  S = I + (r - 1) e_L e_L^T

    (written as the three matrices; the product kernel folds them into one). Returns ``hit``."""
    if not hit.any():
        return hit
    d = extent_growth_direction(np.asarray(mean_corners, dtype=float)[hit], res.mean[hit, XI], res.mean.shape[1], LENGTH)
    e = length - res.mean[hit, LENGTH]
    res.mean[hit] += e[:, None] * d
    eye = np.eye(res.mean.shape[1])
    for row, p in enumerate(np.flatnonzero(hit)):
        target = float(np.ravel(variance)[row])
        if target >= res.cov[p, LENGTH, LENGTH]:
            res.cov[p] += (target - res.cov[p, LENGTH, LENGTH]) * np.outer(d[row], d[row])
            continue
        a = d[row].copy()
        a[LENGTH] = 0.0
        t = eye - np.outer(a, eye[LENGTH])
        s = eye.copy()
        s[LENGTH, LENGTH] = math.sqrt(target / res.cov[p, LENGTH, LENGTH])
        m = np.linalg.inv(t) @ s @ t
        res.cov[p] = m @ res.cov[p] @ m.T
    return hit


def apply_extent_rules(res: UpdateResult, prior_mean: np.ndarray, prior_cov: np.ndarray, structure: Structure,
                       mean_corners: np.ndarray, config: TrackerConfig) -> UpdateResult:
    """The extent rules after the update, in place: ``hold_unobserved_extent``, then where a length was
    held and the width seen ``vehicle_class_prior``, then the vehicle sizes' limits (the estimate
    projected back onto ``BirthConfig.min_length`` .. ``max_length``, ``min_width`` .. ``max_width``)."""
    b = config.birth
    if config.measurement.hold_unobserved_extent:
        held_length, held_width = hold_unobserved_extent(res, prior_mean, prior_cov, structure, mean_corners)
        if b.classes is not None:
            vehicle_class_prior(res, held_length, held_width, mean_corners, b)
    for index, low, high in ((LENGTH, b.min_length, b.max_length), (WIDTH, b.min_width, b.max_width)):
        np.clip(res.mean[:, index], low, np.inf if high is None else high, out=res.mean[:, index])
    return res


def update_pairs(means: np.ndarray, covs: np.ndarray, batch, component_index: np.ndarray, cluster_index: np.ndarray,
                 ego, road, config: TrackerConfig, ut: UnscentedTransform) -> UpdateResult:
    """The update of the pairs ``(component_index[p], cluster_index[p])`` (``tracker.update.update_pairs``
    with the exact conversion to E): the components' sigma points and their rectangles, the structure of
    each pair from its component's predicted mean, the extent growth (new sigma points where a prior
    widened), the predicted measurements, the radar gate, the update with the likelihood's variances
    and the extent rules."""
    comp = np.asarray(component_index, dtype=np.intp)
    clu = np.asarray(cluster_index, dtype=np.intp)
    wrapping = state_wrapping(road, config.coordinates)
    mcfg = config.measurement
    used, inverse = np.unique(comp, return_inverse=True)
    sigma = ut.sigma_points(means[used], covs[used], wrapping)
    rect = to_vehicle(sigma, ego, road, config.coordinates)
    mean_corners = rect.corners()[:, 0][inverse]  # the central sigma point is the mean
    pair_means, pair_covs = means[comp], covs[comp]
    extent_sd = np.sqrt(np.maximum(np.stack([pair_covs[:, LENGTH, LENGTH], pair_covs[:, WIDTH, WIDTH]], axis=1), 0.0))
    structure = build_structure(batch, clu, mean_corners, mcfg, config.use_radar, extent_sd=extent_sd,
                                lidar_range=config.detection.lidar_range)
    pair_sigma, pair_rect = sigma[inverse], rect.take(inverse)
    if mcfg.grow_extent:
        grown, grown_covs = grow_extent(pair_means, pair_covs, structure, mean_corners)
        if grown.any():
            pair_covs = grown_covs
            pair_sigma = pair_sigma.copy()
            pair_sigma[grown] = ut.sigma_points(pair_means[grown], grown_covs[grown], wrapping)
            pair_rect = to_vehicle(pair_sigma, ego, road, config.coordinates)
    z_sigma = predict_measurements(pair_rect, structure)
    rejected = np.zeros(len(comp), dtype=bool)
    if mcfg.radar_gate is not None and structure.radar.any():
        structure, rejected = gate_radar_rows(ut, structure, z_sigma, clu, mcfg.radar_gate)
    res = kalman_update(ut, pair_sigma, pair_means, pair_covs, z_sigma, structure.z, structure.r, structure.mask,
                        wrapping, structure.factors, likelihood_variances(structure, mcfg))
    res = dataclasses.replace(res, radar_rejected=rejected)
    return apply_extent_rules(res, pair_means, pair_covs, structure, mean_corners, config)
