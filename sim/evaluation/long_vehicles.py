"""The hard suite's long-vehicle target: a truck's or bus's length within 1 m of the truth 3 s after its
side is first seen, measured from a run's scored frames.

A long vehicle (``length >= LONG_VEHICLE_LENGTH``) has its side *seen* in the first frame where, from
the ego (the lidar at its centre):

- the ego lies beyond one of its long sides (lateral offset in the vehicle's axes above ``W / 2``), so
  that side faces the lidar;
- the side subtends at least ``SIDE_MIN_RAYS`` lidar rays;
- the rays land at most ``SIDE_MAX_RAY_GAP`` apart along it at its far corner (``r^2 delta / d``: the
  range ``r`` of that corner, the lidar's angular step ``delta``, the side's line at ``d`` from the
  lidar), i.e. the side is sampled densely enough to show its length, not seen edge-on;
- the vehicle has the returns its visible side and end would give (one per ray), all but
  ``SIDE_MISSING_SHARE`` of them and one more (the lidar drops 1 % of its returns, and a ray count
  from the corners' bearings is good to a ray), and, where the frames record them
  (``FrameRecord.lidar_bearings``), its returns reach both ends of its outline's bearing span to
  within ``END_RAYS`` rays: the whole side is in view, not a part of it beside an occluder (a long
  bus whose front few metres are hidden by roadside objects still shows over 90 % of its returns,
  but its length cannot be observed).

``LENGTH_DELAY`` later the length of the track that GOSPA assigns to it is compared with the truth;
a vehicle the run ends on within that delay, or that is no longer scored then (beyond the lidar range),
is not counted. A vehicle without a track then counts as a miss. ``metrics`` gives ``long_sides_seen`` (vehicles counted), ``long_length_within_1m`` (of them,
tracked with ``|L - L_true| <= LENGTH_TOLERANCE``) and ``long_length_err_max_m`` (the largest
``|L - L_true|`` among the tracked ones; None without any).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from tracker.angles import wrap_angle
from tracker.measurement import rectangle_corners

if TYPE_CHECKING:
    from sim.evaluation.records import FrameRecord

#: A vehicle at least this long (m) is a long vehicle (trucks 8-18 m, buses; a van is 6 m).
LONG_VEHICLE_LENGTH = 8.0
#: Its side is seen when it subtends at least this many lidar rays ...
SIDE_MIN_RAYS = 5.0
#: ... that land at most this far apart along it (m) at its far corner ...
SIDE_MAX_RAY_GAP = 1.0
#: ... and the vehicle shows all but this share (and one) of the returns its visible sides would give.
SIDE_MISSING_SHARE = 0.1
#: ... its returns reaching both ends of its bearing span to within this many rays.
END_RAYS = 1.5
#: The length is compared this long (s) after the side is first seen ...
LENGTH_DELAY = 3.0
#: ... and counts as learned within this (m).
LENGTH_TOLERANCE = 1.0


def _subtended(ego: np.ndarray, p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Angle (rad) that the segments ``p -> q`` (N, 2) subtend at ``ego`` (2,)."""
    a = np.arctan2(p[:, 1] - ego[1], p[:, 0] - ego[0])
    b = np.arctan2(q[:, 1] - ego[1], q[:, 0] - ego[0])
    return np.abs(wrap_angle(a - b))


def side_seen(ego_xy: np.ndarray, xy: np.ndarray, yaw: np.ndarray, length: np.ndarray, width: np.ndarray,
              returns: np.ndarray, resolution: float, bearings: np.ndarray | None = None) -> np.ndarray:
    """Whether each vehicle (centres ``xy (N, 2)`` in G, ``yaw``, ``length``, ``width``, lidar ``returns``
    in this frame, each ``(N,)``; ``bearings (N, 2)`` the lowest and highest bearing of its returns, as
    ``FrameRecord.lidar_bearings``, or None) is a long vehicle whose side the lidar at ``ego_xy`` (G, m)
    with angular step ``resolution`` (rad) sees (module docstring): ``side_shown`` of a long vehicle."""
    return (np.asarray(length, dtype=float) >= LONG_VEHICLE_LENGTH) & side_shown(ego_xy, xy, yaw, length, width, returns,
                                                                                 resolution, bearings)


def side_shown(ego_xy: np.ndarray, xy: np.ndarray, yaw: np.ndarray, length: np.ndarray, width: np.ndarray,
               returns: np.ndarray, resolution: float, bearings: np.ndarray | None = None) -> np.ndarray:
    """Whether the lidar shows each vehicle's side whole, whatever its length (the arguments as
    ``side_seen``'s): the side faces the lidar, subtends ``SIDE_MIN_RAYS`` rays sampled at most
    ``SIDE_MAX_RAY_GAP`` apart, the vehicle shows all but ``SIDE_MISSING_SHARE`` (and one) of its
    visible sides' returns and, with ``bearings``, they reach both ends of its outline's bearing span:
    the frame shows its length."""
    ego = np.asarray(ego_xy, dtype=float).reshape(2)
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    c, s = np.cos(yaw), np.sin(yaw)
    ex, ey = np.stack([c, s], axis=1), np.stack([-s, c], axis=1)  # the vehicle's axes
    rel = ego[None, :] - xy
    lon = np.einsum("nd,nd->n", rel, ex)
    lat = np.einsum("nd,nd->n", rel, ey)
    half_l, half_w = 0.5 * np.asarray(length, dtype=float), 0.5 * np.asarray(width, dtype=float)
    side_y = np.sign(lat) * half_w  # the long side facing the ego
    front = xy + half_l[:, None] * ex + side_y[:, None] * ey
    rear = xy - half_l[:, None] * ex + side_y[:, None] * ey
    side_rays = _subtended(ego, front, rear) / resolution
    end_x = np.sign(lon) * half_l  # the end facing the ego, if the ego is beyond it
    end_rays = np.where(np.abs(lon) > half_l,
                        _subtended(ego, xy + end_x[:, None] * ex + half_w[:, None] * ey,
                                   xy + end_x[:, None] * ex - half_w[:, None] * ey) / resolution, 0.0)
    far = np.maximum(np.linalg.norm(front - ego, axis=1), np.linalg.norm(rear - ego, axis=1))
    distance = np.maximum(np.abs(lat) - half_w, 1e-3)  # the side's line from the lidar
    dense = far**2 * resolution / distance <= SIDE_MAX_RAY_GAP
    shown = np.asarray(returns, dtype=float) >= (1.0 - SIDE_MISSING_SHARE) * (side_rays + end_rays) - 1.0
    if bearings is not None:  # the returns reach both ends of the outline's bearing span
        centre = np.arctan2(xy[:, 1] - ego[1], xy[:, 0] - ego[0])
        corners = rectangle_corners(xy, np.asarray(yaw, dtype=float), 2.0 * half_l, 2.0 * half_w)  # (N, 4, 2)
        rel = wrap_angle(np.arctan2(corners[..., 1] - ego[1], corners[..., 0] - ego[0]) - centre[:, None])
        lo, hi = centre + rel.min(axis=1), centre + rel.max(axis=1)
        got = np.asarray(bearings, dtype=float).reshape(-1, 2)
        with np.errstate(invalid="ignore"):
            shown &= (got[:, 0] <= lo + END_RAYS * resolution) & (got[:, 1] >= hi - END_RAYS * resolution)
    return (np.abs(lat) > half_w) & (side_rays >= SIDE_MIN_RAYS) & dense & shown


def face_shown(ego_xy: np.ndarray, xy: np.ndarray, yaw: np.ndarray, length: np.ndarray, width: np.ndarray,
               returns: np.ndarray, resolution: float, bearings: np.ndarray | None = None) -> np.ndarray:
    """Whether the lidar shows each vehicle's width: ``side_shown``'s test of the end (front or rear)
    facing it, the vehicle turned by a quarter turn so that its end is the side tested (the arguments as
    ``side_shown``'s): the ego lies beyond that end, which subtends ``SIDE_MIN_RAYS`` rays sampled at
    most ``SIDE_MAX_RAY_GAP`` apart, and the returns are all there and reach both ends of the outline's
    bearing span."""
    return side_shown(ego_xy, xy, np.asarray(yaw, dtype=float) + 0.5 * np.pi, width, length, returns, resolution,
                      bearings)


def length_errors(frames: list[FrameRecord], resolution: float) -> list[tuple[int, float, float, float | None]]:
    """Per long vehicle whose side is seen with ``LENGTH_DELAY`` of the run left: ``(truth id, time its
    side was first seen (s), its length (m), the assigned track's length error (m) LENGTH_DELAY later
    or None without a track)``."""
    first: dict[int, tuple[int, float]] = {}
    for k, f in enumerate(frames):
        snap = f.truth
        if not len(snap.ids):
            continue
        seen = side_seen((snap.ego.x, snap.ego.y), snap.xy, snap.yaw, snap.length, snap.width, f.lidar_points,
                         resolution, getattr(f, "lidar_bearings", None))
        for tid in snap.ids[seen].tolist():
            first.setdefault(int(tid), (k, f.t))
    out = []
    for tid, (k, t0) in first.items():
        later = next((f for f in frames[k:] if f.t >= t0 + LENGTH_DELAY - 1e-9), None)
        if later is None:
            continue  # the run ends (or the vehicle leaves the scored frames) within the delay
        row = np.flatnonzero(later.truth.ids == tid)
        if not len(row) or not later.scored[row[0]]:
            continue  # gone, or no longer scored (beyond the lidar range, off the road)
        truth_length = float(later.truth.length[row[0]])
        track = np.flatnonzero(later.track_truth_id == tid)
        error = float(later.track_state[track[0], 5] - truth_length) if len(track) else None
        out.append((tid, float(t0), truth_length, error))
    return out


def metrics(frames: list[FrameRecord], resolution: float) -> dict[str, Any]:
    """``long_sides_seen``, ``long_length_within_1m``, ``long_length_err_max_m`` (module docstring)."""
    rows = length_errors(frames, resolution)
    errors = [abs(e) for _, _, _, e in rows if e is not None]
    return {
        "long_sides_seen": len(rows),
        "long_length_within_1m": int(sum(e <= LENGTH_TOLERANCE for e in errors)),
        "long_length_err_max_m": max(errors) if errors else None,
    }
