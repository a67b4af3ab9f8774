"""Radar-only updates of coasting tracks: a radar detection that joined no lidar cluster updates the
track the lidar cannot see.

The paper fuses the radar only through the lidar clusters (a cluster's velocity rows). A vehicle
hidden from the lidar (behind another, or showing it fewer points than a cluster needs) is often still
seen by a radar mounted elsewhere on the ego (the bumper), and the radar then reports its position and
velocity while the track coasts on a prediction that knows neither that the vehicle stopped nor that
it sped up (a car stopping behind a bus while its coasting track drives on at its old speed).

Model (``MeasurementConfig.radar_only_update``): a detection ``z`` is a point of the vehicle plus noise,
and its absolute velocity in E::

    h(x; z) = [ p(x; z), v (cos psi_E, sin psi_E) ],   R = diag(sp^2, sp^2, sv^2, sv^2)

with ``p(x; z)`` the rectangle's point nearest the detection (``nearest_points``; ``z`` itself where it
lies inside): the radar reports the nearest *visible* point of a vehicle, which on a vehicle half
hidden behind another lies anywhere along its visible side, metres beyond the point nearest the
sensor, so a detection tells where the vehicle is not, not which of its points it is. ``sp`` =
``radar_position_sigma``, ``sv = radar_velocity_sigma``. Only
the components of tracks (labels reported before) that no lidar cluster updated in this frame are
candidates, only detections that joined no cluster and lie clear of the lidar's returns
(``RADAR_ONLY_CLEARANCE``) and of the rectangles of the tracks updated in this frame are used, and a
pair counts only within ``RADAR_ONLY_LATERAL`` across the track's heading and within the gate
(``gating.probability`` of a chi-square with 4 degrees of freedom). A detection goes to one track and
a track takes one detection: the assignment (``scipy.optimize.linear_sum_assignment``) of least total
normalised innovation between tracks (each at its best component) and detections, because cars
queueing hidden nose to tail, whose position spreads have grown along the road, gate with each
other's detections, and a greedy choice would give one car's detection to its neighbour. Each component of the
chosen track takes its pair with that detection; its weight is left as the lidar update made it (the
detection refines where the vehicle is, not whether it exists: the GM-PHD's existence evidence stays
the lidar's, and a radar false alarm cannot create or keep a track). One batched UKF update
(``tracker.update.kalman_update``) over all gated pairs. With ``MeasurementConfig.hold_unobserved_extent``
the length and width keep their prior (``hold_extent``): one point shows no side whole.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.stats import chi2

from tracker.config import TrackerConfig
from tracker.frame import EgoState, RadarDetections
from tracker.measurement import Rectangles, to_vehicle
from tracker.motion import LENGTH, WIDTH, XI
from tracker.road import Road
from tracker.ukf import UnscentedTransform
from tracker.update import kalman_update, state_wrapping

#: Measurement rows of a radar-only detection: position (x, y) and velocity (vx, vy) in E.
RADAR_DIM = 4
#: A detection within this (m) of a lidar return kept for clustering is of a vehicle the lidar sees
#: (the radars cycle 1-2 times per lidar frame and only one detection joins a cluster; a car not yet
#: confirmed shows a point or two): it updates no coasting track (``Tracker._update_by_radar``).
RADAR_ONLY_CLEARANCE = 2.0
#: A detection farther than this (m) across the predicted heading from the predicted nearest point
#: updates no coasting track: it is another vehicle, in the next lane (a coasting track's lateral
#: spread grows to a metre in seconds, and the detection's 1 m noise then gates a car 2 m aside).
RADAR_ONLY_LATERAL = 1.0
#: The assignment's cost of a (track, detection) pair outside the gate (never chosen over a gated one).
NOT_GATED = 1e9


def nearest_in_body(rect: Rectangles, point: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The point of each rectangle nearest ``point`` (``(..., 2)`` in E, broadcast against the
    rectangles; default the E origin, the sensor) in the rectangle's own axes: ``u`` along its length,
    ``w`` across it, from its centre (m; ``point`` itself where it lies inside)."""
    c, s = np.cos(rect.psi), np.sin(rect.psi)
    ox, oy = -rect.center[..., 0], -rect.center[..., 1]
    if point is not None:
        ox, oy = ox + point[..., 0], oy + point[..., 1]
    u = np.clip(c * ox + s * oy, -0.5 * rect.length, 0.5 * rect.length)
    w = np.clip(-s * ox + c * oy, -0.5 * rect.width, 0.5 * rect.width)
    return u, w


def nearest_points(rect: Rectangles, point: np.ndarray | None = None) -> np.ndarray:
    """The point ``(..., 2)`` of each rectangle nearest ``point`` (``nearest_in_body``; default the
    E origin) in E."""
    c, s = np.cos(rect.psi), np.sin(rect.psi)
    u, w = nearest_in_body(rect, point)
    return np.stack([rect.center[..., 0] + c * u - s * w, rect.center[..., 1] + s * u + c * w], axis=-1)


def radar_measurement(rect: Rectangles, point: np.ndarray | None = None) -> np.ndarray:
    """``h(x)`` ``(..., 4)`` of rectangles: the point nearest the detection ``point`` (``(..., 2)``; the
    nearest the sensor without one) and the absolute velocity in E (module docstring)."""
    return np.concatenate([nearest_points(rect, point), rect.velocity()], axis=-1)


def hold_extent(prior_mean: np.ndarray, prior_cov: np.ndarray, mean: np.ndarray, cov: np.ndarray,
                rect: Rectangles, point: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Posteriors ``mean (U, D)``, ``cov (U, D, D)`` (``rect``: their rectangles in E) with the length
    and width held at the prior's (``prior_mean``, ``prior_cov``), as the lidar update holds an extent
    no side shows whole (``MeasurementConfig.hold_unobserved_extent``): one point shows no side whole.
    The rectangle's point nearest the detection ``point (U, 2)`` stays where the update put it: on an
    end (a long side), the centre moves by the change of half the length (width) along (across) the
    body, ``(cos xi, sin xi)`` in the state's position slots as ``tracker.extent``'s moves; the
    covariance is the Schmidt one (the ``L, W`` block the prior's, the rest the update's). Returns new
    arrays."""
    mean, cov = mean.copy(), cov.copy()
    u, w = nearest_in_body(rect, point)
    new_u = np.where(np.abs(u) >= 0.5 * rect.length - 1e-9, np.sign(u) * 0.5 * prior_mean[:, LENGTH], u)
    new_w = np.where(np.abs(w) >= 0.5 * rect.width - 1e-9, np.sign(w) * 0.5 * prior_mean[:, WIDTH], w)
    du, dw = u - new_u, w - new_w  # the centre's move in the body's axes (m)
    c, s = np.cos(mean[:, XI]), np.sin(mean[:, XI])
    mean[:, 0] += c * du - s * dw
    mean[:, 1] += s * du + c * dw
    ext = np.array([LENGTH, WIDTH])
    mean[:, ext] = prior_mean[:, ext]
    cov[:, ext[:, None], ext[None, :]] = prior_cov[:, ext[:, None], ext[None, :]]
    return mean, cov


@dataclass(frozen=True)
class RadarOnlyResult:
    """The radar-only updates of one frame: ``component (U,)`` the updated components' indices,
    ``detection (U,)`` the detection each took, ``mean (U, D)``, ``cov (U, D, D)`` their posteriors,
    ``nis (U,)`` the normalised innovations."""

    component: np.ndarray
    detection: np.ndarray
    mean: np.ndarray
    cov: np.ndarray
    nis: np.ndarray

    @staticmethod
    def empty(dim: int) -> RadarOnlyResult:
        return RadarOnlyResult(np.zeros(0, dtype=int), np.zeros(0, dtype=int), np.zeros((0, dim)),
                               np.zeros((0, dim, dim)), np.zeros(0))


def update_coasting(
    means: np.ndarray,
    covs: np.ndarray,
    candidates: np.ndarray,
    radar: RadarDetections,
    free: np.ndarray,
    t: float,
    ego: EgoState,
    road: Road | None,
    config: TrackerConfig,
    ut: UnscentedTransform,
    labels: np.ndarray | None = None,
) -> RadarOnlyResult:
    """Radar-only updates (module docstring) of the components ``candidates`` of ``means (C, D)``,
    ``covs (C, D, D)`` by the detections ``free`` (indices into ``radar``) at frame time ``t``, each
    moved to ``t`` with its own velocity first. With ``labels (C,)`` a detection goes to one label and
    a label takes one detection (the assignment of least total normalised innovation)."""
    dim = means.shape[-1]
    candidates = np.asarray(candidates, dtype=int)
    free = np.asarray(free, dtype=int)
    if len(candidates) == 0 or len(free) == 0:
        return RadarOnlyResult.empty(dim)
    z = np.column_stack([radar.positions_at(t, free), radar.vx[free], radar.vy[free]])
    rect = to_vehicle(means[candidates], ego, road, config.coordinates)
    # pre-gate on position: within the gating distance of the predicted rectangle, and within
    # RADAR_ONLY_LATERAL across the vehicle's heading of its point nearest the sensor (its own lane)
    rect_kf = Rectangles(rect.center[:, None, :], *(a[:, None] for a in (rect.psi, rect.v, rect.length, rect.width)))
    on = nearest_points(rect_kf, z[None, :, :2])  # (K, F, 2)
    near = nearest_points(rect)
    dx, dy = z[None, :, 0] - near[:, None, 0], z[None, :, 1] - near[:, None, 1]  # (K, F)
    c, s = np.cos(rect.psi)[:, None], np.sin(rect.psi)[:, None]
    across = np.abs(-s * dx + c * dy)
    gap = np.hypot(z[None, :, 0] - on[..., 0], z[None, :, 1] - on[..., 1])
    comp, det = np.nonzero((gap <= config.gating.distance) & (across <= RADAR_ONLY_LATERAL))
    if len(comp) == 0:
        return RadarOnlyResult.empty(dim)
    wrapping = state_wrapping(road, config.coordinates)
    used, inverse = np.unique(comp, return_inverse=True)
    idx = candidates[used]
    sigma = ut.sigma_points(means[idx], covs[idx], wrapping)[inverse]  # (P, S, D)
    z_sigma = radar_measurement(to_vehicle(sigma, ego, road, config.coordinates), z[det, None, :2])  # (P, S, 4)
    m = config.measurement
    r = np.array([m.radar_position_sigma**2] * 2 + [m.radar_velocity_sigma**2] * 2)
    prior_m, prior_p = means[idx][inverse], covs[idx][inverse]
    res = kalman_update(ut, sigma, prior_m, prior_p, z_sigma, z[det],
                        np.broadcast_to(r, (len(comp), RADAR_DIM)), wrapping=wrapping)
    gated = res.nis <= chi2.ppf(config.gating.probability, RADAR_DIM)
    if not gated.any():
        return RadarOnlyResult.empty(dim)
    pairs = np.flatnonzero(gated)
    if labels is not None:
        # one detection per track and one track per detection: the assignment of least total normalised
        # innovation between the tracks (labels, each at its best component) and the detections
        lab = np.asarray(labels)[candidates[comp[pairs]]]
        d = det[pairs]
        ids, li = np.unique(lab, return_inverse=True)
        cost = np.full((len(ids), len(free)), np.inf)
        np.minimum.at(cost, (li, d), res.nis[pairs])
        rows, cols = linear_sum_assignment(np.where(np.isfinite(cost), cost, NOT_GATED))
        chosen = np.full(len(ids), -1)
        ok = np.isfinite(cost[rows, cols])
        chosen[rows[ok]] = cols[ok]
        pairs = pairs[chosen[li] == d]
    # per component, the pair of smallest normalised innovation
    order = pairs[np.lexsort((res.nis[pairs], comp[pairs]))]
    first = order[np.concatenate([[True], np.diff(comp[order]) != 0])]
    post_m, post_p = res.mean[first], res.cov[first]
    if m.hold_unobserved_extent:
        post_m, post_p = hold_extent(prior_m[first], prior_p[first], post_m, post_p,
                                     to_vehicle(post_m, ego, road, config.coordinates), z[det[first], :2])
    return RadarOnlyResult(candidates[comp[first]], free[det[first]], post_m, post_p, res.nis[first])
