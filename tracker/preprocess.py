"""Lidar preprocessing before clustering (the paper's "sensor data preprocessing").

Three steps, each vectorised and each reporting what it removed so nothing is lost silently:

1. ``drop_nonfinite``: NaN/inf points are dropped and counted (real drivers emit them).
2. ``road_bound_mask``: points outside the road bounds widened by a margin are discarded, using the
   Road's projection (roadside clutter: guard rails, trees, parked cars).
3. ``bearing_filter``: the paper's filter keeping the closest point per bearing bin, which removes
   points seen "through" an object (returns from inside a vehicle or from behind a gap).
"""

from __future__ import annotations

import numpy as np

from tracker.config import ClusteringConfig
from tracker.frame import Frame
from tracker.road import Road
from tracker.transforms import to_global


def drop_nonfinite(points: np.ndarray) -> tuple[np.ndarray, int]:
    """Rows of ``points`` (N, 2) with both coordinates finite, and the number dropped."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    keep = np.isfinite(pts).all(axis=1)
    return pts[keep], int(len(pts) - keep.sum())


def road_bound_mask(points_g: np.ndarray, road: Road, margin: float = 0.5) -> np.ndarray:
    """Which points (N, 2) in G lie within the road bounds widened by ``margin`` metres."""
    if len(points_g) == 0:
        return np.zeros(0, dtype=bool)
    return road.on_road(points_g, margin=margin)


def bearing_filter(points_e: np.ndarray, bin_width: float = np.deg2rad(0.2)) -> np.ndarray:
    """Indices of the closest point in each bearing bin of ``bin_width`` rad (seen from the E origin),
    in increasing bearing order. ``bin_width`` should be at least the lidar's azimuth resolution."""
    if not bin_width > 0:
        raise ValueError(f"bin_width must be > 0 rad; got {bin_width!r}")
    pts = np.asarray(points_e, dtype=float).reshape(-1, 2)
    if len(pts) == 0:
        return np.zeros(0, dtype=int)
    bearing = np.arctan2(pts[:, 1], pts[:, 0])
    rng = np.hypot(pts[:, 0], pts[:, 1])
    bins = np.floor((bearing + np.pi) / bin_width).astype(np.int64)
    order = np.lexsort((rng, bins))  # by bin, then by range
    first = np.ones(len(order), dtype=bool)
    first[1:] = bins[order][1:] != bins[order][:-1]
    return order[first]


def preprocess_frame(frame: Frame, road: Road, config: ClusteringConfig) -> tuple[np.ndarray, np.ndarray, dict[str, int]]:
    """The three steps on one frame's lidar points (E): returns ``(scan, points, counts)`` -- every
    finite return (occluders for the detection model), the points kept for clustering, and how many
    each step removed (``points_nonfinite``, ``points_off_road``, ``points_bearing_filtered``)."""
    ego = frame.ego
    scan, dropped = drop_nonfinite(frame.lidar)
    counts = {"points_nonfinite": dropped, "points_off_road": 0, "points_bearing_filtered": 0}
    if len(scan) == 0:
        return scan, scan, counts
    on_road = road_bound_mask(to_global(scan, (ego.x, ego.y), ego.yaw), road, config.road_margin)
    counts["points_off_road"] = int((~on_road).sum())
    pts = scan[on_road]
    keep = bearing_filter(pts, config.bearing_bin)
    counts["points_bearing_filtered"] = len(pts) - len(keep)
    return scan, pts[keep], counts
