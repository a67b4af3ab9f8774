"""Write ``tests/reference/tracks.npz``: the tracks of a fixed synthetic run (tests/scenes.py), which
``tests/test_reference.py`` checks today's tracker reproduces -- the guard that a speed-up changed no
result. Re-make it only for an intended change of the tracker's numbers, and say so in the
commit::

    python tests/make_reference.py
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from scenes import Car, Scene  # noqa: E402

from tracker import Road, Tracker, TrackerConfig  # noqa: E402

REFERENCE = Path(__file__).parent / "reference" / "tracks.npz"
DT = 0.1
FRAMES = 40


def reference_scene() -> Scene:
    """Ego and six cars on a 3-lane curve (R 150 m) with radar: followers, a car changing lane, one
    overtaking the ego, one hidden behind another for a while."""
    road = Road.from_curvature([(200.0, 0.0, 0.0), (300.0, 0.0, 1 / 150.0), (600.0, 1 / 150.0, 1 / 150.0)],
                               lanes=3, lane_width=3.5)
    cars = [
        Car(125.0, -3.5, 15.0),
        Car(120.0, 0.0, 17.0, lane_change=(1.0, 3.0, 3.5)),
        Car(140.0, 3.5, 14.0, length=12.0, width=2.5),
        Car(160.0, 3.5, 14.0),
        Car(95.0, 3.5, 20.0),
        Car(170.0, 0.0, 16.0, accel=1.5),
    ]
    return Scene(road, Car(100.0, -3.5, 15.0), cars, radar=True)


def run_reference() -> dict[str, np.ndarray]:
    """Per reported track row: frame index, label, weight, mean (7), covariance (7 x 7)."""
    scene = reference_scene()
    rng = np.random.default_rng(2026)
    # the reference's model with these rules off: a single extraction threshold (ReductionConfig.
    # keep_threshold), no radar-backed sparse births (BirthConfig.min_cluster_points_radar), no
    # shadow-aware anchoring (MeasurementConfig.shadow_window; the rules that need the shadow flags are
    # off with it: sharp ends and sides, shadowed parts, shadow-aware births, shadowed_lidar_sigma),
    # constant speed (MotionConfig.acceleration; the manoeuvre-gated jerk, MotionConfig.quiet_jerk, needs
    # it), no updates of components the occlusion model hides (DetectionConfig.hidden_update_p_detection),
    # no radar gate (MeasurementConfig.radar_gate), no births from two radar-backed points (BirthConfig.
    # min_cluster_points_fused), no first-scan, same-frame or after-update births (BirthConfig.first_scan, same_frame,
    # after_update_points), no dropping of tracks
    # inside a seen vehicle (ReductionConfig.drop_inside_updated), no radar-only updates of coasting
    # tracks (MeasurementConfig.radar_only_update), no absorption of overlapping labels (ReductionConfig.
    # absorb_overlap), no motorcycles among the vehicle classes (BirthConfig.classes), no one-point fragments joined to
    # the track they continue (ClusteringConfig.fragment_points), no joins of neighbouring rays at a grazing angle
    # (ClusteringConfig.grazing_angle), two-sidedness by the eigenvalue ratio alone (MeasurementConfig.
    # two_side_min_residual, two_side_line_residual; the window between two shadows needs the shadow flags): the
    # reference guards the speed-ups against unintended changes of the model
    base = TrackerConfig()
    config = TrackerConfig(
        reduction=dataclasses.replace(base.reduction, keep_threshold=None, drop_inside_updated=False, absorb_overlap=None),
        birth=dataclasses.replace(base.birth, min_cluster_points_radar=None, min_cluster_points_fused=None,
                                  first_scan=False, same_frame=False, after_update_points=None,
                                  classes=tuple(c for c in base.birth.classes if c.name != "motorcycle")),
        measurement=dataclasses.replace(base.measurement, shadow_window=None, radar_gate=None, radar_only_update=False,
                                        shadowed_lidar_sigma=None, two_side_min_residual=0.0,
                                        two_side_line_residual=None),
        motion=dataclasses.replace(base.motion, acceleration=False),
        detection=dataclasses.replace(base.detection, hidden_update_p_detection=None),
        clustering=dataclasses.replace(base.clustering, fragment_points=None, grazing_angle=None),
    )
    tracker = Tracker(scene.road, config)
    frame_idx, labels, weights, means, covs = [], [], [], [], []
    for k in range(FRAMES):
        for tr in tracker.step(scene.frame(k * DT, rng)):
            frame_idx.append(k)
            labels.append(tr.label)
            weights.append(tr.weight)
            means.append(tr.mean)
            covs.append(tr.cov)
    return {"frame": np.array(frame_idx), "label": np.array(labels), "weight": np.array(weights),
            "mean": np.array(means).reshape(-1, 7), "cov": np.array(covs).reshape(-1, 7, 7)}


if __name__ == "__main__":
    REFERENCE.parent.mkdir(exist_ok=True)
    out = run_reference()
    np.savez_compressed(REFERENCE, **out)
    print(f"wrote {REFERENCE}: {len(out['frame'])} track rows over {FRAMES} frames, labels {sorted(set(out['label'].tolist()))}")
