"""Errors split by what the sensors have shown of each vehicle: its length (its width), or not yet.

A vehicle seen only from behind or ahead shows its width but not its length: the tracker holds the
size prior's length, and the centre, half a length from the seen end, inherits half the length's error.
How much of a run's position error is of that kind depends on the traffic's geometry (a queue
followed in one lane shows few sides; overtakes and curves show many), so the run's seen pairs are
split by whether the matched vehicle's length has been shown: a side seen whole
(``sim.evaluation.long_vehicles.side_shown``: facing the lidar, densely sampled, all its returns, both
ends of its bearing span reached) in this frame or an earlier one. Truth only decides the split; the
tracker's own beliefs (its length variance) play no part. The width likewise: a vehicle seen only
from the side shows its length but not its width, which the tracker then holds at its size prior;
the seen pairs are also split by whether the vehicle's width has been shown, an end (front or rear)
seen whole (``sim.evaluation.long_vehicles.face_shown``, the same test of the end).

Keys (extended trackers; ``None`` where a part has no pair):

- ``length_shown_share``: of the matched pairs on visible vehicles (those of ``pos_rmse_seen_m``), the
  share whose vehicle has shown its length;
- ``pos_rmse_seen_length_shown_m``, ``pos_rmse_seen_length_unshown_m``: ``pos_rmse_seen_m`` over each
  part (m), whose squares, weighted by the parts' pair counts, add up to its square;
- ``length_rmse_seen_shown_m``, ``length_rmse_seen_unshown_m``: the length RMSE over each part (m);
- ``matched_pairs_seen``, ``matched_pairs_seen_length_shown``: the pair counts (for pooling runs);
- ``width_shown_share``, ``width_rmse_seen_shown_m``, ``width_rmse_seen_unshown_m``,
  ``matched_pairs_seen_width_shown``: the same for the width.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from sim.evaluation.long_vehicles import face_shown, side_shown
from sim.evaluation.metrics import matched_errors, rmse

if TYPE_CHECKING:
    from sim.evaluation.records import FrameRecord


def shown_pairs(frames: list[FrameRecord], resolution: float) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                                         np.ndarray, np.ndarray]:
    """Per matched pair on a visible vehicle, over the frames in order: whether the vehicle has shown
    its length and whether its width (in this frame or an earlier one), and the pair's position,
    length and width errors (m)."""
    shown_ids = [np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)]  # length, width
    flags, faces, position, length, width = [], [], [], [], []
    for f in frames:
        snap = f.truth
        if not len(snap.ids):
            continue
        view = ((snap.ego.x, snap.ego.y), snap.xy, snap.yaw, snap.length, snap.width, f.lidar_points, resolution,
                f.lidar_bearings)
        for k, test in enumerate((side_shown, face_shown)):
            shown_ids[k] = np.union1d(shown_ids[k], snap.ids[test(*view)])
        rows = np.flatnonzero(f.scored)[np.asarray(f.gospa.truth_index, dtype=int)]  # truth rows of the pairs
        if not len(rows):
            continue
        err = matched_errors(f.truth_state[f.scored], f.track_state, f.gospa)
        seen = f.visible[rows]
        flags.append(np.isin(snap.ids[rows], shown_ids[0])[seen])
        faces.append(np.isin(snap.ids[rows], shown_ids[1])[seen])
        position.append(err.position[seen])
        length.append(err.length[seen])
        width.append(err.width[seen])
    if not flags:
        return np.zeros(0, dtype=bool), np.zeros(0, dtype=bool), np.zeros(0), np.zeros(0), np.zeros(0)
    return (np.concatenate(flags), np.concatenate(faces), np.concatenate(position), np.concatenate(length),
            np.concatenate(width))


def metrics(frames: list[FrameRecord], resolution: float) -> dict[str, Any]:
    """The keys of the module docstring for a run's scored ``frames``, the lidar's angular step
    ``resolution`` (rad)."""
    shown, face, position, length, width = shown_pairs(frames, resolution)
    return {
        "length_shown_share": float(shown.mean()) if shown.size else None,
        "pos_rmse_seen_length_shown_m": rmse([position[shown]]),
        "pos_rmse_seen_length_unshown_m": rmse([position[~shown]]),
        "length_rmse_seen_shown_m": rmse([length[shown]]),
        "length_rmse_seen_unshown_m": rmse([length[~shown]]),
        "matched_pairs_seen": int(shown.size),
        "matched_pairs_seen_length_shown": int(shown.sum()),
        "width_shown_share": float(face.mean()) if face.size else None,
        "width_rmse_seen_shown_m": rmse([width[face]]),
        "width_rmse_seen_unshown_m": rmse([width[~face]]),
        "matched_pairs_seen_width_shown": int(face.sum()),
    }
