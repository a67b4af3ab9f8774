"""Label continuity across losses: re-identification of a lost track by a newly confirmed one.

A GM-PHD filter's labels live on its components. When a vehicle hides behind another for a few
seconds, its component's weight decays below the extraction threshold (or the component is pruned or
merged away) and the vehicle, once it reappears, is confirmed under a new label: an identity switch
for every planner and every metric, although nothing about the vehicle changed.

``LostTracks`` remembers, for ``window`` seconds, the last reported state of every track that stopped
being reported. When a label is confirmed for the first time, the lost tracks are predicted to the
current time with the tracker's own motion model (UKF prediction, so their uncertainty grows with the
time lost) and the newcomers are assigned to them (``scipy.optimize.linear_sum_assignment``) on the
squared Mahalanobis distance of the position,

    d^2 = r^T (P_lost[:2, :2] + P_new[:2, :2])^-1 r,    r = position_new - position_lost (predicted),

with the difference along a closed road taken the short way round; a pair is accepted inside the
chi-square quantile ``probability`` with 2 degrees of freedom. The motion model holds the speed
constant, and a vehicle hidden while it accelerates or brakes drifts from that prediction by
``a tau^2 / 2`` after ``tau`` seconds without an update. The residual's part along the heading (along
``s`` in road coordinates) that such a speed change explains is removed before the distance is taken:
up to ``accel tau^2 / 2`` ahead of the prediction (``accel`` m/s^2 the acceleration allowed for) and
up to the distance braking at ``brake`` loses behind it (``brake tau^2 / 2``, ending at standstill:
``v tau - v^2 / (2 brake)`` once ``v < brake tau``). The reach is a bound, not a spread: a vehicle is
no more likely to have driven at exactly its old speed than to have braked. The reach is asymmetric
because vehicles brake far harder than they accelerate: a car braking at 6 m/s^2 while hidden for 2 s
lies 12 m behind its coasting prediction, far outside the 4 m a 2 m/s^2 allowance reaches, and with a
symmetric reach it could match the prediction of the vehicle behind it instead of its own. An accepted newcomer
takes the lost track's label. A lost track whose label is reported again by itself leaves the store.

A track lost while it turned off its lane's direction (an intersection, a lane change) is predicted
on along its last course and yaw rate, which the road-following prior of the motion model relaxes only
over a second or two: after 1.7 s lost, a car that was turning 22 deg off its lane at 0.5 rad/s
is predicted 4.7 m to the side of where it comes back, having in fact followed its lane through the
turn. With ``lane_following`` each lost track is also predicted as a vehicle that follows its lane
from the moment it was lost (its course set to the lane's direction, 0 along ``s`` or pi against it,
its yaw rate to 0, the covariance as lost), and a newcomer matches the track when it lies within the
gate of either prediction (the smaller distance counts). Road coordinates only: a Cartesian state has
no lane to follow.

The same match covers a track that is still reported but coasts (no cluster updated it this frame)
while a newcomer is confirmed next to it: its prediction missed its vehicle's points, which then
seeded the newcomer's birth ("replaced by a newborn"). The newcomer takes the coasting track's label
and the coasting track's components are dropped (``Tracker``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.stats import chi2

from tracker.angles import wrap_angle
from tracker.motion import XI, XI_DOT, MotionModel, predict
from tracker.ukf import UnscentedTransform

#: Cost of an assignment outside the gate (never accepted).
_INFEASIBLE = 1e12


@dataclass
class _Lost:
    t: float  # when this state was reported (s)
    mean: np.ndarray
    cov: np.ndarray
    updated: float  # when a cluster last updated the track (s)


class LostTracks:
    """The store of recently lost tracks and the re-identification of newcomers (module docstring).

    ``window`` (s): how long a lost track can be re-identified (0: never); ``probability``: the gate's
    chi-square quantile; ``accel`` (m/s^2): the acceleration the gate allows for while a track is not
    updated; ``period`` (m): the length of a closed road for the position ``s`` (``None``: no wrap);
    ``cartesian``: states are ``[x, y, v, psi, ...]`` (the allowance lies along ``psi``), else road
    coordinates (along ``s``); ``brake`` (m/s^2; ``None``: ``accel``): the deceleration allowed for
    behind the prediction (it stops at standstill); ``lane_following``: a lost track is also predicted
    as following its lane (module docstring; ignored with ``cartesian``)."""

    def __init__(self, window: float, probability: float, ut: UnscentedTransform, motion: MotionModel,
                 period: float | None = None, accel: float = 0.0, cartesian: bool = False,
                 brake: float | None = None, lane_following: bool = False) -> None:
        self.window = float(window)
        self.gate = float(chi2.ppf(probability, 2))
        self.ut = ut
        self.motion = motion
        self.period = period
        self.accel = float(accel)
        self.brake = None if brake is None else float(brake)
        self.cartesian = cartesian
        self.lane_following = bool(lane_following) and not cartesian
        self.lost: dict[int, _Lost] = {}
        # last frame's reported tracks, kept as observe's arrays (a _Lost record made only for a track
        # that is lost): when they were reported, label -> row, the rows' means and covariances, and
        # label -> when a cluster last updated the track
        self._last_t = 0.0
        self._last_rows: dict[int, int] = {}
        self._last_means: np.ndarray = np.zeros((0, 0))
        self._last_covs: np.ndarray = np.zeros((0, 0, 0))
        self._last_updated: dict[int, float] = {}

    def observe(self, t: float, labels: np.ndarray | list[int], means: np.ndarray, covs: np.ndarray,
                updated: np.ndarray | list[bool] | None = None) -> None:
        """Record this frame's reported tracks ``labels (N,)``, ``means (N, D)``, ``covs (N, D, D)``
        (``updated (N,)``: which a cluster updated this frame; default all): labels reported last frame
        and not now become lost; lost labels reported again, and those lost longer than ``window``,
        leave the store. The arrays are kept, not copied (the store only reads them): rows of the
        last frame become ``_Lost`` records only when their track is lost."""
        labels = labels if isinstance(labels, list) else np.asarray(labels).tolist()
        if updated is None:
            updated = [True] * len(labels)
        elif not isinstance(updated, list):
            updated = np.asarray(updated, dtype=bool).tolist()
        if not len(means) == len(covs) == len(updated) == len(labels):
            raise ValueError(f"LostTracks.observe needs as many means, covariances and updated flags as labels; got "
                             f"{len(means)}, {len(covs)}, {len(updated)} for {len(labels)} labels")
        rows = dict(zip(labels, range(len(labels))))  # a label given twice: its last row, as in now
        if all(updated):
            now = dict.fromkeys(labels, t)
        else:
            before = self._last_updated
            now = {lab: t if up or lab not in before else before[lab] for lab, up in zip(labels, updated)}
        lost = self.lost
        if not self._last_rows.keys() <= rows.keys():  # some of last frame's tracks are lost
            for lab in self._last_rows:
                if lab not in rows:
                    lost[lab] = self._last_entry(lab)
        if lost:
            self.lost = {lab: e for lab, e in lost.items() if lab not in rows and t - e.t <= self.window}
        self._last_t, self._last_rows, self._last_means, self._last_covs = t, rows, means, covs
        self._last_updated = now

    def _last_entry(self, label: int) -> _Lost:
        """The record of last frame's reported track ``label`` (its state then, when last updated)."""
        row = self._last_rows[label]
        return _Lost(self._last_t, self._last_means[row], self._last_covs[row], self._last_updated[label])

    def last_reported(self, label: int) -> tuple[np.ndarray, np.ndarray] | None:
        """The mean and covariance of track ``label`` as reported last frame (None: not reported)."""
        row = self._last_rows.get(int(label))
        return None if row is None else (self._last_means[row], self._last_covs[row])

    def last_updated(self, label: int, default: float) -> float:
        """When a cluster last updated the reported track ``label`` (s; ``default`` if unknown)."""
        return self._last_updated.get(int(label), default)

    def match(self, t: float, means: np.ndarray, covs: np.ndarray,
              coasting: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
              reported: np.ndarray | None = None) -> np.ndarray:
        """For newcomers ``means (N, 7)``, ``covs (N, 7, 7)`` at time ``t``: the label each takes, or -1.
        Candidates are the lost tracks (predicted to ``t``), the tracks reported last frame whose
        labels are not among ``reported`` (this frame's; lost in this very frame, which ``observe``
        has not stored yet) and ``coasting = (labels, means, covs)``: tracks still reported but not
        updated this frame, at ``t`` (a track whose prediction missed its vehicle's points, from which
        the newcomer was born). Matched lost labels leave the store."""
        out = np.full(len(means), -1, dtype=int)
        if reported is not None and self.window > 0.0:  # lost this frame: candidates like the stored ones
            now = set(int(x) for x in np.asarray(reported).reshape(-1))
            for lab in self._last_rows:
                if lab not in now and lab not in self.lost:
                    self.lost[lab] = self._last_entry(lab)
        lost = list(self.lost) if self.window > 0.0 else []
        extra = 0 if coasting is None else len(coasting[0])
        if not len(means) or not (lost or extra):
            return out
        labels = np.array(lost + ([] if coasting is None else [int(x) for x in coasting[0]]), dtype=int)
        dim = means.shape[1]
        cand_m, cand_p = np.zeros((0, dim)), np.zeros((0, dim, dim))
        if lost:
            cand_m, cand_p = self._predicted(t, lost)
        if extra:
            cand_m, cand_p = np.concatenate([cand_m, coasting[1]]), np.concatenate([cand_p, coasting[2]])
        unseen = t - np.array([self.lost[lab].updated for lab in lost] + [self.last_updated(lab, t) for lab in labels[len(lost):]])
        d2 = self._distances(means, covs, cand_m, cand_p, unseen)
        if lost and self.lane_following:  # ... or where each lost track would be had it followed its lane
            lane_m, lane_p = self._predicted(t, lost, lane_following=True)
            d2[:, :len(lost)] = np.minimum(d2[:, :len(lost)], self._distances(means, covs, lane_m, lane_p, unseen[:len(lost)]))
        cost = np.where(d2 <= self.gate, d2, _INFEASIBLE)
        rows, cols = linear_sum_assignment(cost)
        for i, k in zip(rows, cols):
            if cost[i, k] < _INFEASIBLE:
                out[i] = labels[k]
                self.lost.pop(int(labels[k]), None)
        return out

    def _distances(self, means: np.ndarray, covs: np.ndarray, cand_m: np.ndarray, cand_p: np.ndarray,
                   unseen: np.ndarray) -> np.ndarray:
        """Squared Mahalanobis distances ``(N, K)`` of the newcomers' positions from the candidates'
        (module docstring: the short way round a closed road, the reach of a speed change removed)."""
        r = means[:, None, :2] - cand_m[None, :, :2]  # (N, K, 2)
        if self.period is not None:
            r[..., 0] = np.mod(r[..., 0] + 0.5 * self.period, self.period) - 0.5 * self.period
        if self.accel > 0.0 or self.brake is not None:  # the speed change a hidden vehicle may have made
            r = self._beyond_reach(np.maximum(unseen, 0.0), r, cand_m)
        s = covs[:, None, :2, :2] + cand_p[None, :, :2, :2]
        return np.einsum("nki,nki->nk", r, np.linalg.solve(s, r[..., None])[..., 0])

    def _along(self, cand_m: np.ndarray) -> np.ndarray:
        """The unit vector along which each candidate drives ``(K, 2)``: its heading in G, or ``s``."""
        if self.cartesian:
            return np.stack([np.cos(cand_m[:, 3]), np.sin(cand_m[:, 3])], axis=1)
        return np.tile([1.0, 0.0], (len(cand_m), 1))

    def _beyond_reach(self, tau: np.ndarray, r: np.ndarray, cand_m: np.ndarray) -> np.ndarray:
        """The residuals ``r (N, K, 2)`` with their part along the road inside the candidate's reach
        removed: after ``tau (K,)`` s unseen a vehicle at speed ``v`` lies up to ``accel tau^2 / 2``
        ahead of its constant-speed prediction and up to what braking at ``brake`` loses behind it
        (``brake tau^2 / 2``, or ``v tau - v^2 / (2 brake)`` once it would have stopped: it does not
        drive backwards)."""
        ahead = 0.5 * self.accel * tau ** 2
        if self.brake is None:
            behind = ahead
        else:
            v = np.maximum(cand_m[:, 2], 0.0)
            behind = np.where(v < self.brake * tau, v * tau - 0.5 * v ** 2 / self.brake, 0.5 * self.brake * tau ** 2)
        u = self._along(cand_m)  # (K, 2)
        along = np.einsum("nki,ki->nk", r, u)
        inside = np.clip(along, -behind[None, :], ahead[None, :])
        return r - inside[..., None] * u[None]

    def _predicted(self, t: float, labels: list[int], lane_following: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """The lost tracks' states predicted to ``t`` (one UKF prediction per distinct loss time); with
        ``lane_following`` from their states as lost with the course along the lane (``xi`` 0, or pi
        for a track driving against ``s``) and no yaw rate."""
        means = np.stack([self.lost[lab].mean for lab in labels])
        if lane_following:
            against = np.abs(wrap_angle(means[:, XI])) > 0.5 * np.pi
            means[:, XI] = np.where(against, np.pi, 0.0)
            means[:, XI_DOT] = 0.0
        covs = np.stack([self.lost[lab].cov for lab in labels])
        times = np.array([self.lost[lab].t for lab in labels])
        for t0 in np.unique(times):
            rows = np.flatnonzero(times == t0)
            if t - t0 > 0.0:
                means[rows], covs[rows] = predict(self.ut, self.motion, means[rows], covs[rows], float(t - t0))
        return means, covs
