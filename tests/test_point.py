"""Tests of tracker/point.py: the point-object GNN tracker on cluster centroids (the ``point-gnn``
baseline), on synthetic frames from rectangles (tests/scenes.py)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scenes import Car, Scene

from tracker import Road, Tracker, TrackerConfig
from tracker.config import PointConfig
from tracker.point import PointTracker
from tracker.transforms import to_local

DT = 0.1


@pytest.fixture(scope="module")
def curve() -> Road:
    return Road.from_curvature([(2 * np.pi * 150.0, 1 / 150.0, 1 / 150.0)], closed=True, lanes=3, lane_width=3.5)


def run(scene: Scene, config: TrackerConfig, duration: float, seed: int = 0):
    rng = np.random.default_rng(seed)
    tracker = Tracker(scene.road, config)
    frames = [tracker.step(scene.frame(k * DT, rng)) for k in range(int(round(duration / DT)) + 1)]
    return frames, tracker


def test_the_point_variant_builds_a_point_tracker_and_validates(curve):
    assert isinstance(Tracker(curve, TrackerConfig.for_variant("point-fused")), PointTracker)
    with pytest.raises(ValueError, match="curvilinear coordinates only"):
        TrackerConfig(object_model="point", coordinates="cartesian")
    with pytest.raises(ValueError, match=r"confirm_hits \(6\) must be <= confirm_window \(5\)"):
        PointConfig(confirm_hits=6)


def test_two_cars_tracked_at_their_visible_centroids_with_stable_labels(curve):
    """Two cars ahead in the neighbouring lanes: each gets one confirmed track after the M-of-N delay
    (3 hits: the third frame), labels never change, the speed is right (radar), and the position is the
    centroid of the visible points -- between the car's centre and the sensor -- not the centre."""
    scene = Scene(curve, Car(0.0, 0.0, 15.0), [Car(20.0, -3.5, 16.0), Car(25.0, 3.5, 14.0)], radar=True)
    frames, tracker = run(scene, TrackerConfig.for_variant("point-fused"), 8.0)
    assert frames[0] == [] and frames[1] == [] and len(frames[2]) == 2  # confirmed on the third hit
    labels = set()
    for k, tracks in enumerate(frames[10:], start=10):
        assert len(tracks) == 2 and all(not tr.extent for tr in tracks)
        ego_xy, ego_yaw = scene.ego.pose(curve, k * DT)
        truth = scene.truth(k * DT)
        for row, car in zip(truth, scene.cars):
            centres = np.array([tr.cartesian(curve)[:2] for tr in tracks])
            j = int(np.argmin(np.linalg.norm(centres - row[:2], axis=1)))
            labels.add((tracks[j].label, car.s0))
            # the track sits between the centre and the sensor: closer to the ego than the centre
            track_e = to_local(centres[j][None], ego_xy, ego_yaw)[0]
            centre_e = to_local(row[None, :2], ego_xy, ego_yaw)[0]
            assert np.linalg.norm(track_e) < np.linalg.norm(centre_e)
            assert np.linalg.norm(centres[j] - row[:2]) < car.length / 2 + 0.5
            assert abs(tracks[j].v - row[3]) < 0.5
    assert len(labels) == 2  # one label per car, never changed
    assert tracker.stats["tracks_deleted"] == 0


def test_a_track_coasts_then_is_deleted_after_max_misses(curve):
    """The car leaves the lidar's view (range 30 m, the car pulls away): the track is reported while it
    is seen, kept through ``max_misses - 1`` missed frames, then deleted."""
    scene = Scene(curve, Car(0.0, 0.0, 15.0), [Car(20.0, 0.0, 25.0)], max_range=30.0)
    config = dataclasses.replace(TrackerConfig.for_variant("point-lidar"), point=PointConfig(max_misses=4))
    frames, tracker = run(scene, config, 3.0)
    seen = [k for k in range(len(frames)) if 20.0 + 10.0 * k * DT - 2.4 < 29.9]  # rear within range
    last_seen = seen[-1]
    assert all(len(frames[k]) == 1 for k in range(2, last_seen + 1))
    assert len(frames[last_seen + 3]) == 1 and frames[last_seen + 4] == []
    assert tracker.stats["tracks_deleted"] == 1


@pytest.mark.parametrize("fewest, tracked", [(3, False), (2, True)])
def test_a_two_point_cluster_starts_a_track_only_when_allowed(curve, fewest, tracked):
    """``PointConfig.min_cluster_points`` (3): a car 50 m ahead scanned at 1 deg shows two returns
    every frame; the point tracker starts no track from them by default, and tracks it from the third
    frame when two points are enough."""
    scene = Scene(curve, Car(0.0, 0.0, 15.0), [Car(50.0, 0.0, 15.0, width=1.8)], resolution=np.radians(1.0))
    rng = np.random.default_rng(0)
    assert {len(scene.frame(k * DT, rng).lidar) for k in range(30)} == {2}
    config = dataclasses.replace(TrackerConfig.for_variant("point-lidar"), point=PointConfig(min_cluster_points=fewest))
    frames, _ = run(scene, config, 2.9)
    reported = [len(tracks) for tracks in frames]
    if tracked:
        assert reported[:2] == [0, 0] and all(n == 1 for n in reported[2:])
    else:
        assert sum(reported) == 0
