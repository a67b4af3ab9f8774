"""The lane-flow prior of coasting tracks: a vehicle nobody sees drives at its lane's speed.

A track that no cluster and no radar detection updated in the last frame (hidden behind another
vehicle, between the beams of a far scan) is predicted by its own motion model alone, with the speed it
had when it was last seen. In queues that speed goes stale within seconds: the traffic around it brakes
and accelerates, the hidden vehicle with it, and its track falls behind or runs ahead until it lies
metres from the vehicle (a false track and a missed vehicle in GOSPA; a new label when the vehicle shows
again). Vehicles in one lane cannot drive through each other: a hidden vehicle's speed is, to within the
spread of speeds in a lane, that of the vehicles seen ahead and behind it in its lane.

``flow_speeds``: per coasting component, the lane's flow speed ``v_f``, the mean of the speeds of the
nearest *seen* vehicle ahead of it and the nearest behind it in its lane within ``window`` metres along
the road (the ego counts as seen; either one alone where only one is there; NaN without either). Lanes
are ``Road.lane_index`` at each centre (the lanes present at its ``s``), so an auxiliary lane or a
turning pocket is its own lane.

``pull_to_flow``: the prior as a pseudo-measurement of the speed, ``z = v_f`` with ``H = e_v``, of
variance ``R = sigma_f^2 tau / dt`` (``sigma_f`` the spread of speeds in a lane, ``tau`` the time over
which the pull amounts to one measurement of that variance, ``dt`` the frame interval: the same pull per
second at any frame rate), by the Kalman update::

    K = P e_v / (P_vv + R),    m <- m + K (v_f - v),    P <- P - K e_v^T P

which moves the correlated states with the speed (the acceleration state, the position along the road)
and keeps ``P`` positive definite. ``MotionConfig.flow_speed_std``, ``flow_time``, ``flow_window``;
``docs/tracker.md`` ("Departures from the paper").
"""

from __future__ import annotations

import numpy as np

from tracker.road import Road

#: Index of the speed ``v`` in the state.
SPEED = 2


def flow_speeds(road: Road, source: np.ndarray, target: np.ndarray, window: float) -> np.ndarray:
    """The lane-flow speed (m/s) at each of ``target (T, 2)`` road points ``(s, n)`` from the seen
    vehicles ``source (S, 3)`` rows ``(s, n, v)``: the mean speed of the nearest one ahead and the nearest
    one behind in the target's lane within ``window`` (m) along the road; NaN where there is neither."""
    out = np.full(len(target), np.nan)
    if not len(target) or not len(source):
        return out
    lane_t = road.lane_index(target[:, 1], target[:, 0])
    lane_s = road.lane_index(source[:, 1], source[:, 0])
    gap = road.s_difference(source[None, :, 0], target[:, None, 0])  # (T, S) along the road, + ahead
    near = (lane_t[:, None] == lane_s[None, :]) & (np.abs(gap) <= window) & (gap != 0.0)
    ahead = np.where(near & (gap > 0.0), gap, np.inf)
    behind = np.where(near & (gap < 0.0), -gap, np.inf)
    i_a, i_b = np.argmin(ahead, axis=1), np.argmin(behind, axis=1)
    rows = np.arange(len(target))
    has_a, has_b = np.isfinite(ahead[rows, i_a]), np.isfinite(behind[rows, i_b])
    v_a = np.where(has_a, source[i_a, 2], 0.0)
    v_b = np.where(has_b, source[i_b, 2], 0.0)
    count = has_a.astype(float) + has_b
    found = count > 0
    out[found] = (v_a + v_b)[found] / count[found]
    return out


def pull_to_flow(means: np.ndarray, covs: np.ndarray, rows: np.ndarray, flow: np.ndarray, variance: float) -> None:
    """The pseudo-measurement ``v = flow`` of variance ``variance`` ((m/s)^2) on the components
    ``rows`` of ``means (N, D)`` / ``covs (N, D, D)``, in place (module docstring); ``flow`` per row."""
    if not len(rows):
        return
    p = covs[rows]  # (R, D, D)
    col = p[:, :, SPEED]  # P e_v
    gain = col / (p[:, SPEED, SPEED] + variance)[:, None]
    means[rows] += gain * (flow - means[rows, SPEED])[:, None]
    covs[rows] = p - gain[:, :, None] * col[:, None, :]
