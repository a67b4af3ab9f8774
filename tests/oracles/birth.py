"""The road births of a frame (``tracker.birth.visible_road_births``) step by step: the components per
lane, the acceleration state, and only those a vehicle can enter the view in (less than half hidden by
the tracks, by the occlusion of ``oracles.detection``, and farther than the gate from every track)."""

from __future__ import annotations

import numpy as np

from oracles.detection import occluded_fraction
from tracker.birth import road_births
from tracker.config import BirthConfig
from tracker.frame import EgoState
from tracker.measurement import Rectangles, to_vehicle
from tracker.road import Road


def entering_view(rect: Rectangles, tracks: Rectangles, track_labels: np.ndarray, gate_distance: float) -> np.ndarray:
    """Which birth rectangles are less than half hidden by the tracks and farther than ``gate_distance``
    (m) from every track's centre."""
    hidden = occluded_fraction(rect, np.full(len(rect.center), -1), tracks, track_labels)
    gap = np.linalg.norm(rect.center[:, None, :] - tracks.center[None, :, :], axis=2).min(axis=1)
    return (hidden < 0.5) & (gap > gate_distance)


def visible_road_births(road: Road, s_ego: float, ego: EgoState, lidar_range: float, config: BirthConfig,
                        acceleration_var: float | None, tracks: Rectangles, track_labels: np.ndarray,
                        gate_distance: float) -> tuple[np.ndarray, np.ndarray]:
    """``road_births`` with ``a = 0`` of variance ``acceleration_var`` appended (None: none), then where
    there are tracks only the births ``entering_view`` keeps."""
    means, covs = road_births(road, s_ego, ego.v, lidar_range, config)
    if acceleration_var is not None:
        means = np.concatenate([means, np.zeros((len(means), 1))], axis=1)
        covs = np.pad(covs, ((0, 0), (0, 1), (0, 1)))
        covs[:, 7, 7] = acceleration_var
    if len(means) and len(track_labels):
        keep = entering_view(to_vehicle(means, ego, road), tracks, track_labels, gate_distance)
        means, covs = means[keep], covs[keep]
    return means, covs
