"""The rectangle measurement model (``tracker.measurement``) in plain numpy, vectorised over pairs:
states to rectangles in the vehicle frame E by the exact conversion (``to_vehicle``), the visible sides
of a rectangle, and the measurement structure of (cluster, predicted mean rectangle) pairs
(``build_structure``: one/two-sided, side matching, partial visibility and anchoring, the generating
points' recipe, the end-gap noise factors, the feature-to-measurement matrix; the rules are described in
``tracker.measurement``'s module docstring and ``MeasurementConfig``)."""

from __future__ import annotations

import numpy as np

from tracker.config import MeasurementConfig
from tracker.frame import EgoState
from tracker.measurement import (_free_ends,CENTRE, FIXED, FROM_A, FROM_B, FULL, GROWTH_MIN_EXCESS, GROWTH_SIGMAS, MIN_CHORD,
                                 MIN_EXTENT, MISSED_RAYS_SHARP, NEXT_CORNER, SX, SY, ClusterBatch, Rectangles, Structure)


def side_normals(corners: np.ndarray) -> np.ndarray:
    """Unit outward normals ``(..., 4, 2)`` of sides ``K_k -> K_{k+1}`` (corners counter-clockwise)."""
    d = corners[..., NEXT_CORNER, :] - corners
    nrm = np.stack([d[..., 1], -d[..., 0]], axis=-1)  # direction turned by -90 deg
    return nrm / np.maximum(np.linalg.norm(nrm, axis=-1, keepdims=True), 1e-12)


def visible_sides(corners: np.ndarray, sensor: np.ndarray | None = None) -> np.ndarray:
    """Which sides ``(..., 4)`` of the rectangles face ``sensor`` (default: the E origin)."""
    sensor = np.zeros(2) if sensor is None else np.asarray(sensor, dtype=float)
    mid = 0.5 * (corners + corners[..., NEXT_CORNER, :])
    return np.einsum("...kd,...kd->...k", sensor - mid, side_normals(corners)) > 0.0


def to_vehicle(states: np.ndarray, ego: EgoState | tuple, road=None, coordinates: str = "curvilinear") -> Rectangles:
    """States ``(..., 7 or 8)`` as rectangles in E: a curvilinear ``(s, n)`` goes to G through the road's
    frame (``c(s) + n (-sin theta, cos theta)``, open roads extrapolated along their end tangents),
    heading ``psi = theta(s) + xi``; a Cartesian state directly; then ``p_E = R(-yaw_ego) (p_G - p_ego)``,
    ``psi_E = psi - yaw_ego``; the extent floored at ``MIN_EXTENT``."""
    ego = EgoState.coerce(ego)
    x = np.asarray(states, dtype=float)
    if coordinates == "curvilinear":
        xy, theta, _ = road.frame(x[..., 0], extrapolate=True)
        n = x[..., 1]
        gx = xy[..., 0] - n * np.sin(theta) - ego.x
        gy = xy[..., 1] + n * np.cos(theta) - ego.y
        psi = theta + x[..., 3] - ego.yaw
    else:
        gx, gy = x[..., 0] - ego.x, x[..., 1] - ego.y
        psi = x[..., 3] - ego.yaw
    c, s = np.cos(ego.yaw), np.sin(ego.yaw)
    center = np.stack([c * gx + s * gy, -s * gx + c * gy], axis=-1)
    return Rectangles(center, psi, x[..., 2], np.maximum(x[..., 5], MIN_EXTENT), np.maximum(x[..., 6], MIN_EXTENT))


def shows_longer_side(excess: np.ndarray, sd: np.ndarray) -> np.ndarray:
    """Whether a chord ``excess`` (m) longer than its predicted side is evidence of a longer side, not
    noise: more than ``max(GROWTH_MIN_EXCESS, GROWTH_SIGMAS sd)`` (``sd`` that extent's standard
    deviation). The evidence of the extent growth."""
    return excess > np.maximum(GROWTH_MIN_EXCESS, GROWTH_SIGMAS * sd)


def _lidar_variance(config: MeasurementConfig, mode: np.ndarray, shadowed: np.ndarray) -> np.ndarray:
    """Per pair, the variance of each lidar coordinate in the update: ``shadowed_lidar_sigma^2`` for a
    pair with a part partially visible (``mode (P, 2)`` anchored) whose cluster borders a shadow
    (``shadowed (P,)``), ``lidar_sigma^2`` otherwise."""
    base = np.full(len(mode), config.lidar_sigma**2)
    if config.shadowed_lidar_sigma is None:
        return base
    anchored = ((mode == FROM_A) | (mode == FROM_B) | (mode == CENTRE)).any(axis=1)
    return np.where(anchored & shadowed, config.shadowed_lidar_sigma**2, base)


def build_structure(batch: ClusterBatch, cluster_index: np.ndarray, mean_corners: np.ndarray, config: MeasurementConfig,
                    use_radar: bool = True, *, extent_sd: np.ndarray | None = None,
                    lidar_range: float = np.inf) -> Structure:
    """The measurement structure of pairs (cluster ``cluster_index (P,)``, predicted mean rectangle
    ``mean_corners (P, 4, 2)`` in E), ``tracker.measurement.build_structure``'s fields; ``extent_sd (P, 2)``
    the predicted standard deviations of ``L`` and ``W`` (m; None: the rules that need them off);
    ``lidar_range`` (m): an end within ``shadow_range_margin`` of it is flagged for the range limit."""
    ci = np.asarray(cluster_index, dtype=np.intp)
    if extent_sd is not None:
        extent_sd = np.asarray(extent_sd, dtype=float).reshape(len(ci), 2)
    p_count = len(ci)
    rows = np.arange(p_count)
    nrm = side_normals(mean_corners)  # (P, 4, 2)
    vis = visible_sides(mean_corners)  # (P, 4)
    side_len = np.linalg.norm(mean_corners[..., NEXT_CORNER, :] - mean_corners, axis=-1)  # (P, 4)
    cdir = batch.chord_dir[ci]  # (P, 3, 2)
    normal_of_chord = np.stack([-cdir[..., 1], cdir[..., 0]], axis=-1)  # chord turned by +90 deg
    score = np.einsum("pkd,pqd->pqk", nrm, normal_of_chord)  # (P, slot, side)
    two = batch.two_sided[ci] & (vis.sum(axis=1) == 2)
    single = batch.single[ci] & ~two
    k_one = np.argmax(score[:, 0, :], axis=1)
    j_two = np.argmax(score[:, 1, :] + np.roll(score[:, 2, :], 1, axis=1), axis=1)  # sides j and j - 1
    # single point: the visible side of the mean rectangle nearest to the point
    z0 = batch.points[ci, 0]  # (P, 2)
    e = mean_corners[..., NEXT_CORNER, :] - mean_corners
    t_seg = np.clip(np.einsum("pkd,pkd->pk", z0[:, None, :] - mean_corners, e) / np.maximum(side_len**2, 1e-12), 0, 1)
    dist = np.linalg.norm(mean_corners + t_seg[..., None] * e - z0[:, None, :], axis=-1)
    # ... among the visible sides that look wide enough from the sensor (not seen at grazing incidence)
    mid = mean_corners + 0.5 * e
    apparent = side_len * np.einsum("pkd,pkd->pk", -mid, nrm) / np.maximum(np.linalg.norm(mid, axis=-1), 1e-12)
    eligible = vis & (apparent >= config.single_point_min_apparent * apparent.max(axis=1, keepdims=True))
    dist = np.where(eligible, dist, np.inf)
    k_single = np.where(eligible.any(axis=1), np.argmin(dist, axis=1), k_one)
    side0 = np.where(two, j_two, np.where(single, k_single, k_one))
    sides = np.stack([side0, np.where(two, (j_two - 1) % 4, side0)], axis=1)  # (P, 2) side of each part
    start_c, end_c = (sides + 1) % 4, sides  # side k is traversed from K_{k+1} to K_k
    # chords of the two parts as this pair sees them: slots 1, 2 if two-sided, else slot 0 twice
    slots = np.where(two[:, None], np.array([1, 2]), np.array([0, 0]))  # (P, 2)
    chord_len = np.take_along_axis(batch.chord_len[ci], slots, axis=1)
    margin = np.take_along_axis(batch.end_margin[ci], slots[..., None], axis=1)  # (P, 2 parts, 2 ends)
    occ = batch.occluded_end[ci] if batch.occluded_end is not None else np.zeros((p_count, 2), dtype=bool)
    shadows = batch.occluded_end is not None  # the sharp-end and shadowed-part rules need the shadow flags
    if shadows:
        # a two-sided part's far end (part 0: the first point, part 1: the last) in a shadow is no end of
        # the side: no end-gap margin there, the chord reaches at least to the last return
        margin[:, 0, 0] = np.where(two & occ[:, 0], 0.0, margin[:, 0, 0])
        margin[:, 1, 1] = np.where(two & occ[:, 1], 0.0, margin[:, 1, 1])
    covered = chord_len + margin.sum(axis=2)
    predicted = side_len[rows[:, None], sides]  # (P, 2) the predicted length of each part's side
    alpha = covered / np.maximum(predicted, 1e-12)
    partial = alpha <= config.partial_visibility
    # a part with an end in another object's shadow goes on behind it: partially visible
    # one-sided only (a corner anchors the two-sided), and only when the other end is sharp (its
    # end-gap margin at most shadow_free_gap: not a far or grazing side whose next ray skips metres)
    sharp_end = batch.end_gap[ci] <= config.shadow_free_gap  # (P, 3 slots, 2 ends): half a ray gap at most
    sharp = sharp_end[:, 0]  # (P, 2 ends) of the one-sided chord
    free = _free_ends(batch, ci)  # (P, 2) the bearing ends: in no shadow, not continued
    if shadows:
        # a one-sided part with both ends sharp and free is the whole side, however much shorter than
        # predicted (a convex rectangle shows each visible side whole): a motorcycle's rear is 0.8 m,
        # not the visible part of a car's 1.8 m
        whole = ~two & ~single & sharp[:, 0] & sharp[:, 1] & free[:, 0] & free[:, 1]
        partial &= ~whole[:, None]
    if shadows and extent_sd is not None:
        # each part of a two-sided cluster runs from the fitted corner to a far end, the cluster's first
        # (part 0, slot 1's start) or last point (part 1, slot 2's end): whole if that end is sharp and
        # free, both parts have enough points (the corner is where two well-fitted lines meet: with two
        # points on the other side it is the last return before the corner, up to a ray gap short of it),
        # and the side it would shrink is within the gate
        part_pts = np.stack([(batch.valid[ci] & (batch.part[ci] == 0)).sum(axis=1),
                             (batch.valid[ci] & (batch.part[ci] == 1)).sum(axis=1) + 1], axis=1)  # the corner in both
        # ... a far end is sharp by its ray gap, or because the predicted side goes on beyond it for
        # MISSED_RAYS_SHARP whole gaps (2 half gaps each) where the rays found nothing
        far_gap = np.stack([batch.end_gap[ci, 1, 0], batch.end_gap[ci, 2, 1]], axis=1)
        far_sharp = (far_gap <= config.shadow_free_gap) | (predicted - chord_len >= MISSED_RAYS_SHARP * 2.0 * far_gap)
        sd = np.where(sides % 2 == 1, extent_sd[:, :1], extent_sd[:, 1:])  # odd sides are the length
        shrink = predicted - covered
        consistent = shrink <= config.whole_gate_sigmas * sd + config.whole_gate_slack
        enough = part_pts.min(axis=1, keepdims=True) >= config.whole_min_points
        partial &= ~(two[:, None] & far_sharp & free & enough & consistent)
    if shadows:
        # ... and the side goes on behind it: partially visible, anchored at the corner, unless the chord
        # is longer than its predicted side (a lower bound: measured whole, to the last return); taken
        # whole, a side that an occluder hides a little more every frame would shrink with what shows
        partial |= two[:, None] & occ & (covered < predicted)
    shadowed = ~two & (occ[:, 1] & ~occ[:, 0] & sharp[:, 0] | occ[:, 0] & ~occ[:, 1] & sharp[:, 1])
    partial |= shadowed[:, None]
    # one-sided with both ends in nearer objects' shadows (not at the range limit): a window onto a side
    # that goes on behind both, its place along the side uniform over the unseen length
    reach = lidar_range - config.shadow_range_margin
    inside = ((np.linalg.norm(batch.chord_start[ci, 0], axis=-1) < reach)
              & (np.linalg.norm(batch.chord_end[ci, 0], axis=-1) < reach))
    window = shadows & ~two & ~single & occ[:, 0] & occ[:, 1] & inside
    partial |= window[:, None]
    window_sd = np.where(window, np.maximum(predicted[:, 0] - chord_len[:, 0], 0.0) / np.sqrt(12.0), 0.0)
    # one-sided partial: anchored by the closest of first <-> P, last <-> Q, centroid <-> centre
    p_start = mean_corners[rows, start_c[:, 0]]
    q_end = mean_corners[rows, end_c[:, 0]]
    d_a = np.linalg.norm(batch.chord_start[ci, 0] - p_start, axis=-1)
    d_b = np.linalg.norm(batch.chord_end[ci, 0] - q_end, axis=-1)
    d_c = np.linalg.norm(batch.centroid[ci] - 0.5 * (p_start + q_end), axis=-1)
    anchor = np.array([FROM_A, FROM_B, CENTRE])[np.argmin(np.stack([d_a, d_b, d_c], axis=1), axis=1)]
    # ... unless exactly one end is in a shadow: the other is the vehicle's corner
    anchor = np.where(shadowed, np.where(occ[:, 1], FROM_A, FROM_B), anchor)
    mode_one = np.where(single, FIXED, np.where(partial[:, 0], anchor, FULL))
    mode = np.stack([
        np.where(two, np.where(partial[:, 0], FROM_B, FULL), mode_one),  # first part: anchored at the corner
        np.where(two, np.where(partial[:, 1], FROM_A, FULL), mode_one),  # second part: starts at the corner
    ], axis=1)
    # per point
    valid = batch.valid[ci]
    part = np.where(two[:, None], batch.part[ci], 0)  # (P, M)
    proj = np.where(two[:, None], batch.proj[ci, 1], batch.proj[ci, 0])
    mp = np.take_along_axis(mode, part, axis=1)
    sc = np.take_along_axis(start_c, part, axis=1)
    ec = np.take_along_axis(end_c, part, axis=1)
    ln = np.take_along_axis(chord_len, part, axis=1)
    e_lo = np.take_along_axis(margin[..., 0], part, axis=1)
    e_hi = np.take_along_axis(margin[..., 1], part, axis=1)
    frac = (proj + e_lo) / np.maximum(ln + e_lo + e_hi, MIN_CHORD)
    pts = batch.points[ci]
    p_m = mean_corners[rows[:, None], sc]  # (P, M, 2)
    pq = mean_corners[rows[:, None], ec] - p_m
    fixed_frac = np.clip(
        np.einsum("pmd,pmd->pm", pts - p_m, pq) / np.maximum(np.einsum("pmd,pmd->pm", pq, pq), 1e-12), 0.0, 1.0
    )
    a = np.where(mp == FROM_B, ec, sc)
    b = np.where(mp == FROM_B, sc, ec)
    full, from_a, from_b, centre = mp == FULL, mp == FROM_A, mp == FROM_B, mp == CENTRE
    c1 = np.where(full, frac, np.where(centre, 0.5, np.where(mp == FIXED, fixed_frac, 0.0)))
    c2 = np.where(from_a, proj + e_lo, np.where(from_b, ln - proj + e_hi,
                                                np.where(centre, proj - 0.5 * ln + 0.5 * (e_lo - e_hi), 0.0)))
    c1, c2 = np.where(valid, c1, 0.0), np.where(valid, c2, 0.0)
    dx, dy = SX[b] - SX[a], SY[b] - SY[a]  # one of them is 0 (adjacent corners)
    coef = np.stack([0.5 * (SX[a] + c1 * dx), c2 * np.sign(dx), 0.5 * (SY[a] + c1 * dy), c2 * np.sign(dy)], axis=-1)
    coef = np.where(valid[..., None], coef, 0.0)
    # end-gap noise: the free ends' unknown offsets eps ~ U(-e, e) (var e^2 / 3) move the points along
    # their side by k_lo eps_lo + k_hi eps_hi, with (k_lo, k_hi) = (1 - t, -t) spread over a fully
    # visible side, (1, 0) / (0, -1) anchored at the start / end, (1/2, -1/2) centred, (0, 0) fixed
    t = np.where(full, c1, 0.0)
    k_lo = np.where(full, 1.0 - t, np.where(from_a, 1.0, np.where(centre, 0.5, 0.0)))
    k_hi = np.where(full, -t, np.where(from_b, -1.0, np.where(centre, -0.5, 0.0)))
    unit = pq / np.maximum(np.linalg.norm(pq, axis=-1, keepdims=True), 1e-12)  # (P, M, 2) side direction P -> Q
    last_part = np.where(two, 1, 0)[:, None]
    std_lo = np.where(part == 0, e_lo, 0.0) / np.sqrt(3.0)  # the first part's free start
    std_hi = np.where(part == last_part, e_hi, 0.0) / np.sqrt(3.0)  # the last part's free end
    # ... and a window's place, one more shift along the side shared by its points (with the start's)
    lo_sd = np.where(window_sd[:, None] > 0.0, np.sqrt((k_lo * std_lo) ** 2 + window_sd[:, None] ** 2), k_lo * std_lo)
    f_lo = np.where(valid[..., None], lo_sd[..., None] * unit, 0.0).reshape(p_count, -1)
    f_hi = np.where(valid[..., None], (k_hi * std_hi)[..., None] * unit, 0.0).reshape(p_count, -1)
    factors = np.stack([f_lo, f_hi], axis=1)  # (P, 2, 2M)
    # stacked measurement: x0, y0, x1, y1, ..., vx, vy
    m = pts.shape[1]
    radar = batch.fused[ci] & bool(use_radar)
    mask = np.concatenate([np.repeat(valid, 2, axis=1), np.repeat(radar[:, None], 2, axis=1)], axis=1)
    z = np.concatenate([pts.reshape(p_count, 2 * m), batch.velocity[ci]], axis=1)
    r = np.concatenate(
        [np.repeat(_lidar_variance(config, mode, occ.any(axis=1))[:, None], 2 * m, axis=1),
         np.full((p_count, 2), config.radar_velocity_sigma**2)],
        axis=1,
    )
    factors = np.concatenate([factors, np.zeros((p_count, 2, 2))], axis=2)  # no end noise on radar rows
    # features (cx, cy, L cos, L sin, cos, sin, W sin, W cos, v cos, v sin) -> stacked measurement
    ax, gx, ay, gy = (coef[..., i] for i in range(4))
    vf = valid.astype(float)
    matrix = np.zeros((p_count, 10, 2 * m + 2))
    xs, ys = matrix[:, :, 0 : 2 * m : 2], matrix[:, :, 1 : 2 * m : 2]
    xs[:, 0], xs[:, 2], xs[:, 4], xs[:, 5], xs[:, 6] = vf, ax, gx, -gy, -ay
    ys[:, 1], ys[:, 3], ys[:, 5], ys[:, 4], ys[:, 7] = vf, ax, gx, gy, ay
    if config.radar_rows == "speed":  # one row: the component along the predicted mean heading
        heading = mean_corners[:, 0] - mean_corners[:, 3]  # rear-right -> front-right corner
        u = heading / np.maximum(np.linalg.norm(heading, axis=-1, keepdims=True), 1e-12)
        z[:, -2] = np.einsum("pd,pd->p", batch.velocity[ci], u)
        mask[:, -1] = False
        matrix[:, 8, -2], matrix[:, 9, -2] = u[:, 0] * radar, u[:, 1] * radar
    else:
        matrix[:, 8, -2] = matrix[:, 9, -1] = radar
    return Structure(a=a, b=b, c1=c1, c2=c2, coef=coef, matrix=matrix, valid=valid, two_sided=two, sides=sides, mode=mode, radar=radar,
                     z=np.where(mask, z, 0.0), r=np.where(mask, r, 1.0), mask=mask, factors=factors,
                     excess=np.where(single[:, None], -np.inf, chord_len - predicted))
