"""``FrameRecord``: one scored frame of a run, as ``sim.evaluation.runner`` records it and everything
after the run reads it (the summary metrics, ``sim.evaluation.long_vehicles``, the lidar-dropout measures
of ``sim.evaluation.dropouts``, the figures of ``sim.evaluation.plots``).

The truth set, the visible set and the three GOSPA scorings are defined in ``sim.evaluation.runner``'s
docstring; this module only holds the record, so the modules that read records need not import the runner.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.evaluation.metrics import GospaResult
from sim.world.truth import Snapshot
from tracker import Frame, Track


@dataclass(frozen=True, eq=False)
class FrameRecord:
    """One scored frame at time ``t`` (s).

    - ``truth``: the snapshot (all other vehicles); ``scored`` (bool per truth row): the truth set of
      ``sim.evaluation.runner``'s docstring; ``visible``: scored and seen by at least
      ``min_visible_points`` lidar points; ``lidar_points`` (int per truth row): points on each vehicle
      in this scan;
    - ``truth_state`` (N, 7): truth rows ``[x, y, v, yaw, yaw_rate, L, W]`` in G;
    - ``tracks``: the tracker's output; ``track_state`` (K, 7): their ``Track.cartesian`` views;
    - ``gospa`` / ``gospa_visible``: ``GospaResult`` against the scored / visible truth (indices into
      ``np.flatnonzero(scored)`` / ``np.flatnonzero(visible)`` and into ``tracks``);
    - ``on_hidden`` (K,): tracks that ``gospa`` assigns to a scored vehicle that is not visible (a
      track kept through an occlusion); ``gospa_seen``: the visible truth against the other tracks
      (indices into ``np.flatnonzero(visible)`` and ``np.flatnonzero(~on_hidden)``), the visible-only
      score that does not count a kept track of a hidden vehicle as false;
    - ``on_edge`` (K,): tracks on an *edge vehicle* (centre off the road, body on it:
      ``sim.evaluation.runner.edge_set``), set aside from all three scorings (``score_frame``);
    - ``track_truth_id`` (K,): the truth id each track is assigned to in ``gospa`` (-1: none);
    - ``tracker_ms``: wall time of ``Tracker.step`` (ms); ``ego_s``: the ego's arc length (m);
    - ``frame``: the tracker's input (kept only with ``keep_sensor_data``; for the GIF);
    - ``tracker_events``: the tracker's ``last_events`` after this step, normalised by
      ``sim.evaluation.runner.normalize_tracker_events`` (``None`` when the tracker does not expose them);
    - ``lidar_bearings`` (N, 2): the lowest and highest bearing from the ego (rad, in G, unwrapped about
      the bearing of the vehicle's centre) of each truth vehicle's lidar returns in this scan (NaN
      without any): which part of its outline the lidar reached (``sim.evaluation.long_vehicles``)."""

    t: float
    truth: Snapshot
    scored: np.ndarray
    visible: np.ndarray
    lidar_points: np.ndarray
    truth_state: np.ndarray
    tracks: list[Track]
    track_state: np.ndarray
    gospa: GospaResult
    gospa_visible: GospaResult
    track_truth_id: np.ndarray
    tracker_ms: float
    ego_s: float
    frame: Frame | None = None
    tracker_events: dict[str, list] | None = None
    on_hidden: np.ndarray | None = None
    gospa_seen: GospaResult | None = None
    lidar_bearings: np.ndarray | None = None
    on_edge: np.ndarray | None = None

    @property
    def n_truth(self) -> int:
        """Size of the scored truth set."""
        return int(self.scored.sum())

    @property
    def n_visible(self) -> int:
        """Size of the visible truth set."""
        return int(self.visible.sum())

    @property
    def n_tracks(self) -> int:
        """Number of reported tracks."""
        return len(self.tracks)

    @property
    def n_tracks_scored(self) -> int:
        """Number of reported tracks that the scorings count: all but those on edge vehicles."""
        return len(self.tracks) - (0 if self.on_edge is None else int(self.on_edge.sum()))


__all__ = ["FrameRecord"]
