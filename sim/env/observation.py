"""The observation of ``eot/TrackedRoad-v0``: one row of features per vehicle in road coordinates, and
the rows' track labels in ``info["labels"]``.

``Box(1 + max_tracks, 10)``, float32. Columns (``COLUMNS``), SI units, and their bounds (``limits``;
``R`` is the scenario's lidar ``max_range``, 100 m by default):

==========  ==============================================================  ==========================
column      meaning                                                         bounds
==========  ==============================================================  ==========================
present     1 for a filled row, 0 for padding (then the whole row is 0)     [0, 1]
ds          ``s - s_ego`` (m): along-road distance of the rectangle centre  [-2 R, 2 R] (+-200 m)
            from the ego's (wrapped into [-length/2, length/2) on a closed
            road)
n           lateral offset of the centre (m, positive to the left of the    [-20, 20] m
            driving direction)
v           speed (m/s) along the vehicle's heading                         [0, 50] m/s
xi          heading relative to the road tangent (rad)                      [-pi, pi]
xi_dot      its rate (rad/s)                                                [-2, 2] rad/s
length      (m)                                                             [0, 25] m
width       (m)                                                             [0, 4] m
sigma_s     standard deviation of ``s`` from the track's covariance (m);    [0, 10] m
            0 for truth and the ego
sigma_n     standard deviation of ``n`` (m); 0 for truth and the ego        [0, 10] m
==========  ==============================================================  ==========================

Where the bounds come from (values outside them, e.g. a diverged track's, are clipped into them):
``ds``: what the lidar sees lies within ``R`` of the ego, and along a bending road the arc to it is
longer than the straight line (up to ``pi R / 2`` round a half circle), so ``DS_RANGE_FACTOR * R``;
``n``: half the widest road a scenario may have (6 lanes of 5 m) plus 5 m beyond its edge
(``N_LIMIT_M``); ``v``: 1.25 times the scenarios' top speed (``sim.world.scenario.MAX_SPEED``, 40 m/s);
``xi_dot``: above any road vehicle's yaw rate relative to the road (``XI_DOT_LIMIT``); ``length`` and
``width``: 1.25 and 1.33 times the largest vehicle a scenario may have (20 x 3 m); ``sigma_s`` and
``sigma_n``: a deviation beyond ``SIGMA_LIMIT_M`` (about three lane widths) says the position is not
known at the scale of a lane.

Row 0 is the ego (as in highway-env's ``Kinematics`` observation): ``present = 1``, ``ds = 0`` and its
own ``n, v, xi, xi_dot, length, width`` (odometry, exact). Rows 1.. are the other vehicles sorted by
``|ds|`` (nearest first), at most ``max_tracks`` of them:

- ``perception = "tracks"``: the tracker's tracks at the latest lidar frame;
- ``perception = "truth"``: the vehicles a perfect tracker would report at that frame -- the runner's
  scored truth set (centre within the lidar range and on the road, occluded ones included).

So "truth" and "tracks" differ only by the tracker, and have the same layout. **Labels** are
identities, not features, so they are not in the array: ``info["labels"]`` (int64, ``1 + max_tracks``)
gives each row's track label (``"tracks"``) or vehicle id (``"truth"``), -1 for the ego row and for
padding; a planner uses them to follow a vehicle from step to step (``sim.env.planner``). With
``normalize = True`` every column is divided by the larger magnitude of its bounds (``scales``), so
the box is [-1, 1] for the signed columns and [0, 1] for the others.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np
from gymnasium import spaces

from sim.evaluation.runner import truth_set
from sim.world.scenario import MAX_SPEED

if TYPE_CHECKING:
    from sim.env.view import EnvView

COLUMNS = ("present", "ds", "n", "v", "xi", "xi_dot", "length", "width", "sigma_s", "sigma_n")
#: Column index by name.
COL = {name: i for i, name in enumerate(COLUMNS)}
#: The lidar's default range (m; ``sim.sensors.lidar.LidarConfig.max_range``), for ``limits()``.
DEFAULT_LIDAR_RANGE = 100.0
#: ``|ds|`` is bounded by this many lidar ranges.
DS_RANGE_FACTOR = 2.0
#: ``|n|`` bound (m): half of 6 lanes of 5 m (the widest road a scenario may have) plus 5 m.
N_LIMIT_M = 20.0
#: Speed bound (m/s): 1.25 x the scenarios' top speed.
V_LIMIT_MPS = 1.25 * MAX_SPEED
#: ``|xi_dot|`` bound (rad/s).
XI_DOT_LIMIT = 2.0
#: Length and width bounds (m): vehicles are at most 20 x 3 m.
LENGTH_LIMIT_M = 25.0
WIDTH_LIMIT_M = 4.0
#: Bound of the position deviations ``sigma_s``, ``sigma_n`` (m).
SIGMA_LIMIT_M = 10.0
#: ``info["labels"]`` of the ego row and of padding rows.
NO_LABEL = -1


def limits(max_range: float = DEFAULT_LIDAR_RANGE) -> dict[str, tuple[float, float]]:
    """The bounds ``(low, high)`` of each column (SI units) for a lidar of range ``max_range`` (m)."""
    ds = DS_RANGE_FACTOR * float(max_range)
    return {"present": (0.0, 1.0), "ds": (-ds, ds), "n": (-N_LIMIT_M, N_LIMIT_M), "v": (0.0, V_LIMIT_MPS),
            "xi": (-math.pi, math.pi), "xi_dot": (-XI_DOT_LIMIT, XI_DOT_LIMIT), "length": (0.0, LENGTH_LIMIT_M),
            "width": (0.0, WIDTH_LIMIT_M), "sigma_s": (0.0, SIGMA_LIMIT_M), "sigma_n": (0.0, SIGMA_LIMIT_M)}


def scales(max_range: float = DEFAULT_LIDAR_RANGE) -> dict[str, float]:
    """The divisors of ``normalize = True``: each column's larger bound magnitude (``limits``)."""
    return {c: max(abs(lo), abs(hi)) for c, (lo, hi) in limits(max_range).items()}


def _bound_rows(max_range: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    lim = limits(max_range)
    scale = scales(max_range)
    return (np.array([lim[c][0] for c in COLUMNS]), np.array([lim[c][1] for c in COLUMNS]),
            np.array([scale[c] for c in COLUMNS]))


def observation_space(max_tracks: int, normalize: bool, max_range: float = DEFAULT_LIDAR_RANGE) -> spaces.Box:
    """The ``Box`` of the observation: ``limits(max_range)`` per column, or those divided by
    ``scales(max_range)`` with ``normalize`` ([-1, 1] or [0, 1])."""
    low, high, scale = _bound_rows(max_range)
    if normalize:
        low, high = low / scale, high / scale
    rows = 1 + int(max_tracks)
    return spaces.Box(np.tile(low, (rows, 1)).astype(np.float32), np.tile(high, (rows, 1)).astype(np.float32),
                      dtype=np.float32)


def build_rows(ego: np.ndarray, others: np.ndarray, max_tracks: int, normalize: bool,
               max_range: float = DEFAULT_LIDAR_RANGE, labels: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The observation array and its row labels from the ego row ``ego (10,)`` and the other rows
    ``others (K, 10)`` with their ``labels (K,)`` (any order; sorted here by ``|ds|``, the nearest
    ``max_tracks`` kept; labels default to ``NO_LABEL``)."""
    obs = np.zeros((1 + max_tracks, len(COLUMNS)), dtype=np.float64)
    row_labels = np.full(1 + max_tracks, NO_LABEL, dtype=np.int64)
    obs[0] = ego
    if len(others):
        order = np.argsort(np.abs(others[:, COL["ds"]]), kind="stable")[:max_tracks]
        obs[1 : 1 + len(order)] = others[order]
        if labels is not None:
            row_labels[1 : 1 + len(order)] = np.asarray(labels, dtype=np.int64)[order]
    low, high, scale = _bound_rows(max_range)
    obs = np.clip(obs, low, high)
    if normalize:
        obs = obs / scale
    return obs.astype(np.float32), row_labels


def denormalize(obs: np.ndarray, max_range: float = DEFAULT_LIDAR_RANGE) -> np.ndarray:
    """Undo ``normalize`` (up to the clipping): the observation in SI units."""
    return np.array(obs, dtype=np.float64) * _bound_rows(max_range)[2]


def _wrap(ds: np.ndarray, length: float, closed: bool) -> np.ndarray:
    if not closed:
        return ds
    return (ds + 0.5 * length) % length - 0.5 * length


class TrackObservation:
    """highway-env's ``ObservationType`` interface (``space()``, ``observe()``) for the rows above;
    ``labels`` holds the row labels of the last ``observe()`` (the env's ``info["labels"]``)."""

    def __init__(self, env: EnvView) -> None:
        self.env = env
        self.labels = np.full(1 + env.settings.max_tracks, NO_LABEL, dtype=np.int64)

    @property
    def max_range(self) -> float:
        """The scenario's lidar range (m), which bounds ``ds``."""
        return self.env.lidar_range

    def space(self) -> spaces.Box:
        s = self.env.settings
        return observation_space(s.max_tracks, s.normalize, self.max_range)

    def ego_row(self) -> np.ndarray:
        """The ego's row (unnormalised)."""
        e = self.env.world.ego_state()
        return np.array([1.0, 0.0, e.n, e.v, e.xi, e.xi_dot, e.length, e.width, 0.0, 0.0])

    def other_rows(self) -> tuple[np.ndarray, np.ndarray]:
        """Rows (K, 10) of the other vehicles, unsorted and unnormalised, and their labels (K,)."""
        env = self.env
        road = env.world.road
        ego_s = env.world.ego_state().s
        if env.settings.perception == "tracks":
            tracks = env.tracks
            if not tracks:
                return np.zeros((0, len(COLUMNS))), np.zeros(0, dtype=np.int64)
            mean = np.stack([tr.mean for tr in tracks])
            var = np.stack([np.diag(tr.cov)[:2] for tr in tracks])
            labels = np.array([tr.label for tr in tracks], dtype=np.int64)
            rows = np.column_stack([np.ones(len(tracks)), mean[:, 0] - ego_s, mean[:, 1:7], np.sqrt(np.maximum(var, 0.0))])
        else:
            snap = env.last_frame.truth
            keep = truth_set(snap, road, env.rig.config.lidar.max_range)
            count = int(keep.sum())
            rows = np.column_stack([
                np.ones(count), snap.s[keep] - ego_s, snap.n[keep], snap.v[keep], snap.xi[keep], snap.xi_dot[keep],
                snap.length[keep], snap.width[keep], np.zeros(count), np.zeros(count),
            ]).reshape(-1, len(COLUMNS))
            labels = np.asarray(snap.ids[keep], dtype=np.int64)
        rows[:, COL["ds"]] = _wrap(rows[:, COL["ds"]], road.length, road.closed)
        return rows, labels

    def observe(self) -> np.ndarray:
        s = self.env.settings
        others, labels = self.other_rows()
        obs, self.labels = build_rows(self.ego_row(), others, s.max_tracks, s.normalize, self.max_range, labels)
        return obs


def rows_to_dicts(obs: np.ndarray, labels: np.ndarray | None = None) -> list[dict[str, Any]]:
    """The present rows of an (unnormalised) observation as dicts keyed by ``COLUMNS`` (for humans),
    with ``"label"`` from ``labels`` (``info["labels"]``) when given."""
    out = []
    for k, row in enumerate(np.asarray(obs)):
        if row[0] > 0.5:
            d = dict(zip(COLUMNS, map(float, row)))
            if labels is not None:
                d["label"] = int(labels[k])
            out.append(d)
    return out


__all__ = [
    "COL", "COLUMNS", "DEFAULT_LIDAR_RANGE", "DS_RANGE_FACTOR", "LENGTH_LIMIT_M", "NO_LABEL", "N_LIMIT_M", "SIGMA_LIMIT_M",
    "TrackObservation", "V_LIMIT_MPS", "WIDTH_LIMIT_M", "XI_DOT_LIMIT", "build_rows", "denormalize", "limits",
    "observation_space", "rows_to_dicts", "scales",
]  # fmt: skip
