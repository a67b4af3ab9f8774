"""The observation of ``eot/TrackedRoad-v0``: one row per vehicle in road coordinates.

``Box(1 + max_tracks, 11)``, float32. Columns (``COLUMNS``), SI units:

==========  ==============================================================================
present     1 for a filled row, 0 for padding (then the whole row is 0)
ds          ``s - s_ego`` (m): along-road distance of the rectangle centre from the ego's
            (wrapped into [-length/2, length/2) on a closed road)
n           lateral offset of the centre (m, positive to the left of the driving direction)
v           speed (m/s) along the vehicle's heading
xi          heading relative to the road tangent (rad)
xi_dot      its rate (rad/s)
length      (m)
width       (m)
sigma_s     standard deviation of ``s`` from the track's covariance (m); 0 for truth and the ego
sigma_n     standard deviation of ``n`` (m); 0 for truth and the ego
label       the track's label (``perception = "tracks"``) or the vehicle's id ("truth"); 0 for the ego
==========  ==============================================================================

Row 0 is the ego (as in highway-env's ``Kinematics`` observation): ``present = 1``, ``ds = 0`` and its
own ``n, v, xi, xi_dot, L, W`` (odometry, exact). Rows 1.. are the other vehicles sorted by ``|ds|``
(nearest first), at most ``max_tracks`` of them:

- ``perception = "tracks"``: the tracker's tracks at the latest lidar frame;
- ``perception = "truth"``: the vehicles a perfect tracker would report at that frame -- the runner's
  scored truth set (centre within the lidar range and on the road, occluded ones included).

So "truth" and "tracks" differ only by the tracker. Values are clipped into ``LIMITS`` (generous
physical bounds). With ``normalize = True`` each column but ``present`` and ``label`` is divided by
``SCALES`` and clipped to [-1, 1].
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from gymnasium import spaces

from sim.runner import truth_set

if TYPE_CHECKING:
    from sim.env.core import TrackedRoadEnv

COLUMNS = ("present", "ds", "n", "v", "xi", "xi_dot", "length", "width", "sigma_s", "sigma_n", "label")
#: Column index by name.
COL = {name: i for i, name in enumerate(COLUMNS)}
#: Divisors of the columns with ``normalize = True`` (``present`` and ``label`` are kept as they are):
#: ds by the lidar range (100 m), n by 10 m, v by 40 m/s (highway-env's MAX_SPEED), angles by pi,
#: xi_dot by 1 rad/s, length by 20 m, width by 3 m, deviations by 10 m.
SCALES = {"ds": 100.0, "n": 10.0, "v": 40.0, "xi": np.pi, "xi_dot": 1.0, "length": 20.0, "width": 3.0,
          "sigma_s": 10.0, "sigma_n": 10.0}
_SCALE_ROW = np.array([SCALES.get(c, 1.0) for c in COLUMNS])
_SCALED = np.array([c in SCALES for c in COLUMNS])


#: Bounds of the unnormalised columns (values outside, e.g. a diverged track's, are clipped into them).
LIMITS = {"present": (0.0, 1.0), "ds": (-1e4, 1e4), "n": (-100.0, 100.0), "v": (0.0, 100.0), "xi": (-np.pi, np.pi),
          "xi_dot": (-10.0, 10.0), "length": (0.0, 50.0), "width": (0.0, 10.0), "sigma_s": (0.0, 1e4),
          "sigma_n": (0.0, 1e4), "label": (0.0, 2.0**24)}
_LOW = np.array([LIMITS[c][0] for c in COLUMNS])
_HIGH = np.array([LIMITS[c][1] for c in COLUMNS])


def observation_space(max_tracks: int, normalize: bool) -> spaces.Box:
    """The ``Box`` of the observation: ``LIMITS`` per column, or [-1, 1] for the scaled columns with
    ``normalize`` (``[0, 1]`` where the column is non-negative)."""
    low, high = _LOW.copy(), _HIGH.copy()
    if normalize:
        low[_SCALED] = np.maximum(low[_SCALED] / _SCALE_ROW[_SCALED], -1.0)
        high[_SCALED] = np.minimum(high[_SCALED] / _SCALE_ROW[_SCALED], 1.0)
    rows = 1 + int(max_tracks)
    return spaces.Box(np.tile(low, (rows, 1)).astype(np.float32), np.tile(high, (rows, 1)).astype(np.float32),
                      dtype=np.float32)


def build_rows(ego: np.ndarray, others: np.ndarray, max_tracks: int, normalize: bool) -> np.ndarray:
    """The observation array from the ego row ``ego (11,)`` and the other rows ``others (K, 11)``
    (any order; sorted here by ``|ds|``, the nearest ``max_tracks`` kept)."""
    obs = np.zeros((1 + max_tracks, len(COLUMNS)), dtype=np.float64)
    obs[0] = ego
    if len(others):
        order = np.argsort(np.abs(others[:, COL["ds"]]), kind="stable")[:max_tracks]
        obs[1 : 1 + len(order)] = others[order]
    obs = np.clip(obs, _LOW, _HIGH)
    if normalize:
        obs[:, _SCALED] = np.clip(obs[:, _SCALED] / _SCALE_ROW[_SCALED], -1.0, 1.0)
    return obs.astype(np.float32)


def denormalize(obs: np.ndarray) -> np.ndarray:
    """Undo ``normalize`` (up to the clipping): the observation in SI units."""
    out = np.array(obs, dtype=np.float64)
    out[..., _SCALED] = out[..., _SCALED] * _SCALE_ROW[_SCALED]
    return out


def _wrap(ds: np.ndarray, length: float, closed: bool) -> np.ndarray:
    if not closed:
        return ds
    return (ds + 0.5 * length) % length - 0.5 * length


class TrackObservation:
    """highway-env's ``ObservationType`` interface (``space()``, ``observe()``) for the rows above."""

    def __init__(self, env: TrackedRoadEnv) -> None:
        self.env = env

    def space(self) -> spaces.Box:
        s = self.env.settings
        return observation_space(s.max_tracks, s.normalize)

    def ego_row(self) -> np.ndarray:
        """The ego's row (unnormalised)."""
        e = self.env.world.ego_state()
        return np.array([1.0, 0.0, e.n, e.v, e.xi, e.xi_dot, e.length, e.width, 0.0, 0.0, 0.0])

    def other_rows(self) -> np.ndarray:
        """Rows (K, 11) of the other vehicles, unsorted and unnormalised."""
        env = self.env
        road = env.world.road
        ego_s = env.world.ego_state().s
        if env.settings.perception == "tracks":
            tracks = env.tracks
            if not tracks:
                return np.zeros((0, len(COLUMNS)))
            mean = np.stack([tr.mean for tr in tracks])
            var = np.stack([np.diag(tr.cov)[:2] for tr in tracks])
            labels = np.array([tr.label for tr in tracks], dtype=float)
            rows = np.column_stack([np.ones(len(tracks)), mean[:, 0] - ego_s, mean[:, 1:7],
                                    np.sqrt(np.maximum(var, 0.0)), labels])
        else:
            snap = env.last_frame.truth
            keep = truth_set(snap, road, env.rig.config.lidar.max_range)
            count = int(keep.sum())
            rows = np.column_stack([
                np.ones(count), snap.s[keep] - ego_s, snap.n[keep], snap.v[keep], snap.xi[keep], snap.xi_dot[keep],
                snap.length[keep], snap.width[keep], np.zeros(count), np.zeros(count), snap.ids[keep].astype(float),
            ]).reshape(-1, len(COLUMNS))
        rows[:, COL["ds"]] = _wrap(rows[:, COL["ds"]], road.length, road.closed)
        return rows

    def observe(self) -> np.ndarray:
        s = self.env.settings
        return build_rows(self.ego_row(), self.other_rows(), s.max_tracks, s.normalize)


def rows_to_dicts(obs: np.ndarray) -> list[dict[str, Any]]:
    """The present rows of an (unnormalised) observation as dicts keyed by ``COLUMNS`` (for humans)."""
    return [dict(zip(COLUMNS, map(float, row))) for row in np.asarray(obs) if row[0] > 0.5]


__all__ = ["COL", "COLUMNS", "LIMITS", "SCALES", "TrackObservation", "build_rows", "denormalize", "observation_space", "rows_to_dicts"]
