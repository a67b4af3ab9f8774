"""The measurement structure of (cluster, predicted mean rectangle) pairs as one numba call
(``tracker.measurement.build_structure``; the model is ``tracker.measurement``'s module docstring).

Per pair, in this order: the predicted rectangle's visible sides and their outward normals; the side or
sides the cluster's chords face (one side; the corner's two adjacent sides; for a single point the
nearest visible side seen wide enough); whether each part shows its side whole or in part (the
visibility ``a = (chord + end margins) / predicted side``, and ``MeasurementConfig``'s rules on ends in
shadows, sharp free ends and sides longer than predicted) and the anchor of a side seen in part; then
per point the generating-point recipe (corner indices ``a``, ``b``, coefficients ``c1``, ``c2`` and the
linear coefficients ``coef``), the end-gap noise factors, the feature-to-measurement matrix, the stacked
measurement, its noise variances and row mask (``tracker.measurement.Structure``).
"""

from __future__ import annotations

import math

import numpy as np

from tracker.jit import njit

FULL, FROM_A, FROM_B, CENTRE, FIXED = range(5)  # as tracker.measurement
_SX = np.array([1.0, 1.0, -1.0, -1.0])
_SY = np.array([-1.0, 1.0, 1.0, -1.0])


@njit(inline="always")
def _sign(x: float) -> float:
    return 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0)


@njit
def structure_kernel(points, valid_in, part_in, proj_in, chord_start, chord_end, chord_dir, chord_len_in,
                     end_margin, end_gap, two_in, single_in, fused, velocity, centroid, occluded, not_free, ci,
                     corners, min_apparent, partial_visibility, free_gap, lidar_var, radar_var, use_radar, speed_row,
                     min_chord, shadows, has_sd, extent_sd, min_points, gate_sigmas, gate_slack, missed_rays,
                     shadowed_var, shadow_reach):
    """The fields of ``tracker.measurement.Structure`` for pairs ``(ci[p], corners[p])``; ``not_free (K, 2)``
    whether a bearing end is in a shadow or continues, ``extent_sd (P, 2)`` the sd of ``L``, ``W``;
    ``shadows``: the clusters have their shadow flags (the sharp-end and shadowed-part rules need them);
    ``has_sd``: ``extent_sd`` is known (the sharp parts' gate needs it); ``shadowed_var``:
    ``shadowed_lidar_sigma`` squared (negative: None); ``shadow_reach``: the range (m) from which an
    end's shadow flag is the lidar's range limit, not a nearer object (``inf``: every flag a shadow)."""
    sx = _SX
    sy = _SY
    count = len(ci)
    width = points.shape[1]
    dim = 2 * width + 2
    a_out = np.zeros((count, width), dtype=np.intp)
    b_out = np.zeros((count, width), dtype=np.intp)
    c1_out = np.zeros((count, width))
    c2_out = np.zeros((count, width))
    coef = np.zeros((count, width, 4))
    matrix = np.zeros((count, 10, dim))
    valid = np.zeros((count, width), dtype=np.bool_)
    two_out = np.zeros(count, dtype=np.bool_)
    sides = np.zeros((count, 2), dtype=np.intp)
    mode = np.zeros((count, 2), dtype=np.intp)
    radar_out = np.zeros(count, dtype=np.bool_)
    z = np.zeros((count, dim))
    r = np.ones((count, dim))
    mask = np.zeros((count, dim), dtype=np.bool_)
    factors = np.zeros((count, 2, dim))
    excess = np.zeros((count, 2))
    nrm = np.empty((4, 2))
    edge = np.empty((4, 2))
    side_len = np.empty(4)
    vis = np.empty(4, dtype=np.bool_)
    score = np.empty((3, 4))
    apparent = np.empty(4)
    dist = np.empty(4)
    inv_sqrt3 = 1.0 / math.sqrt(3.0)
    inv_sqrt12 = 1.0 / math.sqrt(12.0)
    for p in range(count):
        c = ci[p]
        k_ = corners[p]
        n_vis = 0
        for k in range(4):
            k1 = (k + 1) % 4
            dx = k_[k1, 0] - k_[k, 0]
            dy = k_[k1, 1] - k_[k, 1]
            edge[k, 0] = dx
            edge[k, 1] = dy
            length = math.sqrt(dx * dx + dy * dy)
            side_len[k] = length
            nn = max(length, 1e-12)
            nrm[k, 0] = dy / nn
            nrm[k, 1] = -dx / nn
            mx = 0.5 * (k_[k, 0] + k_[k1, 0])
            my = 0.5 * (k_[k, 1] + k_[k1, 1])
            vis[k] = (-mx) * nrm[k, 0] + (-my) * nrm[k, 1] > 0.0
            if vis[k]:
                n_vis += 1
            for q in range(3):  # the chord's normal: the chord turned by +90 deg
                score[q, k] = nrm[k, 0] * (-chord_dir[c, q, 1]) + nrm[k, 1] * chord_dir[c, q, 0]
        two = two_in[c] and n_vis == 2
        single = single_in[c] and not two
        k_one = 0
        for k in range(1, 4):
            if score[0, k] > score[0, k_one]:
                k_one = k
        j_two = 0
        best = score[1, 0] + score[2, 3]
        for j in range(1, 4):
            val = score[1, j] + score[2, j - 1]
            if val > best:
                best = val
                j_two = j
        # single point: the visible side nearest to it among those seen wide enough from the sensor
        z0x = points[c, 0, 0]
        z0y = points[c, 0, 1]
        app_max = -np.inf
        for k in range(4):
            ex, ey = edge[k, 0], edge[k, 1]
            t = ((z0x - k_[k, 0]) * ex + (z0y - k_[k, 1]) * ey) / max(side_len[k] ** 2, 1e-12)
            t = min(max(t, 0.0), 1.0)
            qx = k_[k, 0] + t * ex - z0x
            qy = k_[k, 1] + t * ey - z0y
            dist[k] = math.sqrt(qx * qx + qy * qy)
            mx = k_[k, 0] + 0.5 * ex
            my = k_[k, 1] + 0.5 * ey
            apparent[k] = side_len[k] * ((-mx) * nrm[k, 0] + (-my) * nrm[k, 1]) / max(math.sqrt(mx * mx + my * my), 1e-12)
            app_max = max(app_max, apparent[k])
        k_single = -1
        d_best = np.inf
        for k in range(4):
            if vis[k] and apparent[k] >= min_apparent * app_max:
                if k_single < 0 or dist[k] < d_best:
                    k_single = k
                    d_best = dist[k]
        if k_single < 0:
            k_single = k_one
        side0 = j_two if two else (k_single if single else k_one)
        side1 = (j_two - 1) % 4 if two else side0
        sides[p, 0] = side0
        sides[p, 1] = side1
        slot0 = 1 if two else 0
        slot1 = 2 if two else 0
        ln0 = chord_len_in[c, slot0]
        ln1 = chord_len_in[c, slot1]
        m0_lo = end_margin[c, slot0, 0]  # end-gap margins of each part's two ends
        m0_hi = end_margin[c, slot0, 1]
        m1_lo = end_margin[c, slot1, 0]
        m1_hi = end_margin[c, slot1, 1]
        if shadows and two:  # a far end in a shadow is no end of the side: no margin there
            if occluded[c, 0]:
                m0_lo = 0.0
            if occluded[c, 1]:
                m1_hi = 0.0
        partial0 = (ln0 + m0_lo + m0_hi) / max(side_len[side0], 1e-12) <= partial_visibility
        partial1 = (ln1 + m1_lo + m1_hi) / max(side_len[side1], 1e-12) <= partial_visibility
        # a one-sided part with exactly one end in another object's shadow and a sharp other end goes on
        # behind it: partially visible, anchored at the sharp end (a corner anchors the two-sided)
        occ_lo = occluded[c, 0]
        occ_hi = occluded[c, 1]
        sharp_lo = end_gap[c, 0, 0] <= free_gap
        sharp_hi = end_gap[c, 0, 1] <= free_gap
        if (shadows and not two and not single and not not_free[c, 0] and not not_free[c, 1]
                and sharp_lo and sharp_hi):
            partial0 = False  # both ends sharp and free: the whole side
            partial1 = False
        if shadows and has_sd and two:
            # each part from the fitted corner to a sharp, free far end (the first point for part 0,
            # the last for part 1), with enough points and a shrink within the gate, is its whole side
            n0 = 0
            n1 = 1  # the corner point belongs to both parts
            for m in range(width):
                if valid_in[c, m]:
                    if part_in[c, m] == 0:
                        n0 += 1
                    else:
                        n1 += 1
            sd0 = extent_sd[p, 0] if side0 % 2 == 1 else extent_sd[p, 1]  # odd sides are the length
            sd1 = extent_sd[p, 0] if side1 % 2 == 1 else extent_sd[p, 1]
            shrink0 = side_len[side0] - (ln0 + m0_lo + m0_hi)
            shrink1 = side_len[side1] - (ln1 + m1_lo + m1_hi)
            enough = n0 >= min_points and n1 >= min_points  # both: the corner is fitted from two lines
            # a far end is sharp by its ray gap, or because the predicted side goes on beyond it for
            # missed_rays whole gaps where the rays found nothing
            sharp0 = end_gap[c, 1, 0] <= free_gap or side_len[side0] - ln0 >= missed_rays * 2.0 * end_gap[c, 1, 0]
            sharp1 = end_gap[c, 2, 1] <= free_gap or side_len[side1] - ln1 >= missed_rays * 2.0 * end_gap[c, 2, 1]
            if enough and sharp0 and not not_free[c, 0] and shrink0 <= gate_sigmas * sd0 + gate_slack:
                partial0 = False
            if enough and sharp1 and not not_free[c, 1] and shrink1 <= gate_sigmas * sd1 + gate_slack:
                partial1 = False
        if shadows and two:
            # a part whose far end borders a shadow goes on behind it, unless longer than predicted
            # (its margin there is 0: a lower bound to the last return)
            if occ_lo and ln0 + (m0_lo + m0_hi) < side_len[side0]:
                partial0 = True
            if occ_hi and ln1 + (m1_lo + m1_hi) < side_len[side1]:
                partial1 = True
        shadowed = (not two) and ((occ_hi and not occ_lo and sharp_lo) or (occ_lo and not occ_hi and sharp_hi))
        if shadowed:
            partial0 = True
            partial1 = True
        # one-sided partial: anchored by the closest of first <-> P, last <-> Q, centroid <-> centre
        ps = (side0 + 1) % 4
        pe = side0
        dax = chord_start[c, 0, 0] - k_[ps, 0]
        day = chord_start[c, 0, 1] - k_[ps, 1]
        dbx = chord_end[c, 0, 0] - k_[pe, 0]
        dby = chord_end[c, 0, 1] - k_[pe, 1]
        dcx = centroid[c, 0] - 0.5 * (k_[ps, 0] + k_[pe, 0])
        dcy = centroid[c, 1] - 0.5 * (k_[ps, 1] + k_[pe, 1])
        d_a = math.sqrt(dax * dax + day * day)
        d_b = math.sqrt(dbx * dbx + dby * dby)
        d_c = math.sqrt(dcx * dcx + dcy * dcy)
        anchor = FROM_A
        if d_b < d_a:
            anchor = FROM_B
        if d_c < min(d_a, d_b):
            anchor = CENTRE
        if shadowed:  # the sharp end is the vehicle's corner
            anchor = FROM_A if occ_hi else FROM_B
        # one-sided, both ends in the shadows of nearer objects (not at the range limit): the points are
        # a window onto a side that goes on behind both, anywhere along it; the anchor's place along the
        # side takes the window's spread, uniform over the side's unseen length
        window_sd = 0.0
        if shadows and not two and not single and occ_lo and occ_hi:
            lo_range = math.sqrt(chord_start[c, 0, 0] ** 2 + chord_start[c, 0, 1] ** 2)
            hi_range = math.sqrt(chord_end[c, 0, 0] ** 2 + chord_end[c, 0, 1] ** 2)
            if lo_range < shadow_reach and hi_range < shadow_reach:
                partial0 = True
                partial1 = True
                window_sd = max(side_len[side0] - ln0, 0.0) * inv_sqrt12
        mode_one = FIXED if single else (anchor if partial0 else FULL)
        mode[p, 0] = (FROM_B if partial0 else FULL) if two else mode_one
        mode[p, 1] = (FROM_A if partial1 else FULL) if two else mode_one
        two_out[p] = two
        excess[p, 0] = -np.inf if single else ln0 - side_len[side0]
        excess[p, 1] = -np.inf if single else ln1 - side_len[side1]
        radar = fused[c] and use_radar
        radar_out[p] = radar
        point_var = lidar_var  # the update's variance of this pair's points
        if shadowed_var >= 0.0 and (occ_lo or occ_hi):
            for q in range(2):
                if mode[p, q] == FROM_A or mode[p, q] == FROM_B or mode[p, q] == CENTRE:
                    point_var = shadowed_var
        last_part = 1 if two else 0
        for m in range(width):
            ok = valid_in[c, m]
            valid[p, m] = ok
            part = part_in[c, m] if two else 0
            proj = proj_in[c, 1, m] if two else proj_in[c, 0, m]
            mp = mode[p, part]
            sc = (sides[p, part] + 1) % 4
            ec = sides[p, part]
            slot = slot1 if part == 1 else slot0
            ln = chord_len_in[c, slot]
            e_lo = m1_lo if part == 1 else m0_lo
            e_hi = m1_hi if part == 1 else m0_hi
            frac = (proj + e_lo) / max(ln + e_lo + e_hi, min_chord)
            px = points[c, m, 0]
            py = points[c, m, 1]
            pqx = k_[ec, 0] - k_[sc, 0]
            pqy = k_[ec, 1] - k_[sc, 1]
            fixed_frac = ((px - k_[sc, 0]) * pqx + (py - k_[sc, 1]) * pqy) / max(pqx * pqx + pqy * pqy, 1e-12)
            fixed_frac = min(max(fixed_frac, 0.0), 1.0)
            a = ec if mp == FROM_B else sc
            b = sc if mp == FROM_B else ec
            a_out[p, m] = a
            b_out[p, m] = b
            if mp == FULL:
                c1 = frac
            elif mp == CENTRE:
                c1 = 0.5
            elif mp == FIXED:
                c1 = fixed_frac
            else:
                c1 = 0.0
            if mp == FROM_A:
                c2 = proj + e_lo
            elif mp == FROM_B:
                c2 = ln - proj + e_hi
            elif mp == CENTRE:
                c2 = proj - 0.5 * ln + 0.5 * (e_lo - e_hi)
            else:
                c2 = 0.0
            if not ok:
                continue
            c1_out[p, m] = c1
            c2_out[p, m] = c2
            dx = sx[b] - sx[a]
            dy = sy[b] - sy[a]
            ax = 0.5 * (sx[a] + c1 * dx)
            gx = c2 * _sign(dx)
            ay = 0.5 * (sy[a] + c1 * dy)
            gy = c2 * _sign(dy)
            coef[p, m, 0] = ax
            coef[p, m, 1] = gx
            coef[p, m, 2] = ay
            coef[p, m, 3] = gy
            # end-gap noise factors along the side (module docstring of tracker.measurement)
            t = c1 if mp == FULL else 0.0
            if mp == FULL:
                k_lo = 1.0 - t
                k_hi = -t
            else:
                k_lo = 1.0 if mp == FROM_A else (0.5 if mp == CENTRE else 0.0)
                k_hi = -1.0 if mp == FROM_B else (-0.5 if mp == CENTRE else 0.0)
            nq = max(math.sqrt(pqx * pqx + pqy * pqy), 1e-12)
            ux = pqx / nq
            uy = pqy / nq
            std_lo = (e_lo if part == 0 else 0.0) * inv_sqrt3
            std_hi = (e_hi if part == last_part else 0.0) * inv_sqrt3
            f_lo = k_lo * std_lo
            if window_sd > 0.0:  # the window's place: one more shift along the side, shared by its points
                f_lo = math.sqrt(f_lo * f_lo + window_sd * window_sd)
            factors[p, 0, 2 * m] = f_lo * ux
            factors[p, 0, 2 * m + 1] = f_lo * uy
            factors[p, 1, 2 * m] = k_hi * std_hi * ux
            factors[p, 1, 2 * m + 1] = k_hi * std_hi * uy
            mask[p, 2 * m] = True
            mask[p, 2 * m + 1] = True
            z[p, 2 * m] = px
            z[p, 2 * m + 1] = py
            r[p, 2 * m] = point_var
            r[p, 2 * m + 1] = point_var
            xs = 2 * m
            ys = 2 * m + 1
            matrix[p, 0, xs] = 1.0
            matrix[p, 2, xs] = ax
            matrix[p, 4, xs] = gx
            matrix[p, 5, xs] = -gy
            matrix[p, 6, xs] = -ay
            matrix[p, 1, ys] = 1.0
            matrix[p, 3, ys] = ax
            matrix[p, 5, ys] = gx
            matrix[p, 4, ys] = gy
            matrix[p, 7, ys] = ay
        if radar:
            if speed_row:  # one row: the component along the predicted mean heading
                hx = k_[0, 0] - k_[3, 0]
                hy = k_[0, 1] - k_[3, 1]
                nh = max(math.sqrt(hx * hx + hy * hy), 1e-12)
                ux = hx / nh
                uy = hy / nh
                z[p, dim - 2] = velocity[c, 0] * ux + velocity[c, 1] * uy
                r[p, dim - 2] = radar_var
                mask[p, dim - 2] = True
                matrix[p, 8, dim - 2] = ux
                matrix[p, 9, dim - 2] = uy
            else:
                z[p, dim - 2] = velocity[c, 0]
                z[p, dim - 1] = velocity[c, 1]
                r[p, dim - 2] = radar_var
                r[p, dim - 1] = radar_var
                mask[p, dim - 2] = True
                mask[p, dim - 1] = True
                matrix[p, 8, dim - 2] = 1.0
                matrix[p, 9, dim - 1] = 1.0
    return (a_out, b_out, c1_out, c2_out, coef, matrix, valid, two_out, sides, mode, radar_out, z, r, mask, factors,
            excess)
