"""The calls through which ``tracker.compiled.warm_up`` compiles (or loads) every kernel, in shares
that compile in parallel on a cold cache.

- ``update_share``: the update of the pairs (``tracker.update.update_clusters``: the fused kernel, then
  by hand-back the two steps and the staged kernels) and the cluster preparation alone. A helper
  process runs it (``python -P -m tracker.compiled._warm``) while the calling process runs
- ``first_frame`` (a tracker's first frame in which no cluster pairs with a component: the road filter,
  the grouping of the points, the radar association, the road births, the detection model, the
  reduction), ``other_calls`` (the kernels a small scene may not reach) and ``predict_share``;
- ``scene``: a few frames of a small tracked scene (two cars, lidar and radar) that reach the kernels
  of every stage, the update's included; after the shares it loads them from the cache.

The shares reach disjoint sets of kernels, so that the two processes do not compile the same one
(a kernel both reach is compiled by whichever comes first, and loaded by the other where the cache
already holds it).
"""

from __future__ import annotations

import dataclasses

import numpy as np

EGO = (100.0, 0.0, 0.0, 10.0, 0.0)  # x, y (m), yaw (rad), speed (m/s), yaw rate (rad/s) of the scenes' ego
LIDAR_STEP_DEG = 0.2  # the scenes' lidar resolution (deg)


def _road():
    from tracker.road import Road

    return Road.from_curvature([(300.0, 0.0, 0.0)], lanes=2, lane_width=3.5)


def _tracker(first_scan: bool = True):
    from tracker.config import TrackerConfig
    from tracker.tracker import Tracker

    config = TrackerConfig()
    if not first_scan:
        config = dataclasses.replace(config, birth=dataclasses.replace(config.birth, first_scan=False))
    return Tracker(_road(), config)


def _bearings() -> np.ndarray:
    return np.arange(-np.pi, np.pi, np.radians(LIDAR_STEP_DEG))


def _scan(centres: np.ndarray, length: float = 4.5, width: float = 1.9) -> list[np.ndarray]:
    """Per vehicle (centres ``(V, 2)`` in the ego frame, heading 0) its lidar returns."""
    from tracker.measurement import rectangle_corners, rectangle_scan

    bearings = _bearings()
    return [rectangle_scan(rectangle_corners(c, np.array(0.0), np.array(length), np.array(width)), bearings)[0]
            for c in centres]


def _frame(k: int):
    """Frame ``k`` (0.1 s apart) of two cars ahead of the ego, 15 and 22 m away at first, in both lanes."""
    from tracker.frame import EgoState, Frame, RadarDetections

    t = 0.1 * k
    cars = np.array([[15.0 + 12.0 * t, 1.75], [22.0 + 10.0 * t, -1.75]])
    radar = RadarDetections(t=np.full(2, t), x=cars[:, 0], y=cars[:, 1], vx=np.array([12.0, 10.0]), vy=np.zeros(2))
    return Frame(t, EgoState(*EGO), np.concatenate(_scan(cars)), radar)


def first_frame() -> None:
    """One frame of a tracker without first-scan births: its road births lie at the lidar's range
    limit, far from the two cars, so no cluster pairs with a component and the update's kernels are
    not reached."""
    tracker = _tracker(first_scan=False)
    tracker.road.frame(np.array([1.0, 2.0]))
    tracker.road.to_frenet(np.array([[10.0, 1.0], [20.0, -1.0]]))  # Road._project's kernels
    tracker.step(_frame(0))


def update_share() -> None:
    """The update of the pairs as the tracker calls it (``update_clusters``): a truck's 12 m side seen by
    a component with a car's length prior, whose prior is widened, so that the fused kernel hands the
    pairs back to the two steps and the staged kernels; and the clusters prepared alone, with and
    without their shadow flags (``tracker.preparation``)."""
    from tracker.frame import EgoState
    from tracker.preparation import prepare_batch, prepare_scanned_batch
    from tracker.update import update_clusters, update_pairs

    tracker = _tracker()
    ego = EgoState(*EGO)
    truck = _scan(np.array([[30.0, 1.75]]), length=12.0, width=2.5)[0]
    scan = np.concatenate([truck, *_scan(np.array([[15.0, -1.75]]))])
    mean = np.zeros((1, tracker.dim))
    mean[0, :7] = [130.0, 1.75, 10.0, 0.0, 0.0, 4.5, 1.9]
    cov = np.diag(np.r_[1.0, 0.2, 1.0, 0.01, 0.01, 0.25, 0.04, np.ones(tracker.dim - 7)])[None]
    pair = np.zeros(1, dtype=np.intp)
    update_clusters(mean, cov, truck, np.array([0, len(truck)]), np.zeros((1, 2)), np.ones(1, dtype=bool), pair, pair,
                    scan, ego, tracker.road, tracker.config, tracker.ut)
    batch = prepare_batch([truck], tracker.config.measurement)
    prepare_scanned_batch([truck], tracker.config.measurement, None, truck, 0.01, 100.0)  # the two steps' first
    update_pairs(mean, cov, batch, np.zeros(1, dtype=int), np.zeros(1, dtype=int), ego, tracker.road, tracker.config,
                 tracker.ut)


def predict_share() -> None:
    """The UKF prediction of two components (``Tracker._predict`` as a frame calls it)."""
    from tracker.reduction import Mixture

    tracker = _tracker()
    means = np.zeros((2, tracker.dim))
    means[:, :7] = [[115.0, 1.75, 12.0, 0.0, 0.0, 4.5, 1.9], [122.0, -1.75, 10.0, 0.0, 0.0, 4.5, 1.9]]
    covs = np.broadcast_to(np.diag(np.r_[1.0, 0.2, 1.0, 0.01, 0.01, 0.25, 0.04, np.ones(tracker.dim - 7)]),
                           (2, tracker.dim, tracker.dim)).copy()
    tracker.mixture = Mixture(np.array([0.9, 0.8]), means, covs, np.array([1, 2]))
    tracker._predict(0.1, set())


def other_calls() -> None:
    """The kernels that a small scene may not reach: a closed road's frame, the Cartesian births'
    occlusion test, the points in rectangles, the grouping's second call and its hand-back's partition,
    the reduce stage whatever the scene reached (the reduction in view, the test of the components
    inside an updated one's rectangle, ``absorb_overlapping``'s screen along the road and in Cartesian
    axes), the report-range centres of the extraction."""
    from tracker.clustering import SPLIT_MAX_CUTS, distance_partition, points_in_rectangles
    from tracker.compiled.clustering import ordered_clusters_kernel
    from tracker.compiled.reduction import inside_updated_kernel
    from tracker.detection import occluded_fraction
    from tracker.frame import EgoState
    from tracker.measurement import Rectangles
    from tracker.reduction import Mixture, absorb_overlapping, reduce_in_view
    from tracker.road import Road
    from tracker.tracker import _centres, _duplicate_groups

    ring = Road.from_waypoints(np.array([[100.0, 0.0], [0.0, 100.0], [-100.0, 0.0], [0.0, -100.0]]), closed=True)
    ring.frame(np.array([1.0, 2.0]))
    tracker = _tracker()
    road = tracker.road
    rect = Rectangles(np.array([[10.0, 0.0], [11.0, 0.5]]), np.zeros(2), np.zeros(2), np.full(2, 4.5), np.full(2, 1.9))
    _duplicate_groups(rect)
    occluded_fraction(rect, np.array([1, 2]), rect, np.array([3, 4]))
    points_in_rectangles(np.array([[10.0, 0.0]]), rect.center, rect.psi, rect.length, rect.width, 1.0)
    pts = np.array([[10.0, 0.0], [10.5, 0.0]])
    distance_partition(pts, 1.0)
    ordered_clusters_kernel(pts, np.array([0, -1]), np.array([True, False]), np.zeros(2, dtype=np.int64), 1, np.zeros(2),
                            True, 3.0, 0.5, SPLIT_MAX_CUTS)
    means = np.array([[130.0, 1.75, 10.0, 0.0, 0.0, 4.5, 1.9], [130.5, 1.75, 10.0, 0.0, 0.0, 4.5, 1.9]])
    mix = Mixture(np.array([0.9, 0.6]), means, np.broadcast_to(np.eye(7), (2, 7, 7)).copy(), np.array([1, 1]))
    reduce_in_view(mix, np.full(2, 30.0), 102.0, means[:, 1], (-5.0, 5.0), prune_threshold=1e-4, merge_gate=4.0,
                   max_components=100, wrapping=tracker.wrapping, same_label_distance=3.0, s_period=500.0)
    inside_updated_kernel(rect.center, np.ones(1), np.zeros(1), rect.length, rect.width, np.zeros(1, dtype=np.int64),
                          np.ones(1, dtype=np.int64))
    two = Mixture(mix.weights, mix.means, mix.covs, np.array([1, 2]))
    absorb_overlapping(two, 0.5, 0.5, tracker.wrapping)
    absorb_overlapping(two, 0.5, 0.5, tracker.wrapping, cartesian=True)
    _centres(means, np.array([0, 1], dtype=np.intp), EgoState(*EGO), road, "curvilinear")


def scene(frames: int = 4) -> None:
    """``frames`` frames of the two cars tracked with the default configuration (first-scan births,
    then the update of the pairs, the prediction, the reduction, the extraction)."""
    tracker = _tracker()
    for k in range(frames):
        tracker.step(_frame(k))


if __name__ == "__main__":  # the helper process of warm_up
    update_share()
