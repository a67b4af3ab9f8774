"""Tests of tracker/config.py: defaults, validation with clear errors, variants and dict loading."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from tracker.config import (BirthConfig, ClusteringConfig, DetectionConfig, MeasurementConfig, MotionConfig, ProcessNoise, ReductionConfig,
                            TrackerConfig, UKFParams, VehicleClass)


def test_defaults_are_the_documented_ones() -> None:
    c = TrackerConfig()
    assert c.coordinates == "curvilinear" and c.motion.model == "frenet" and c.use_radar
    assert c.measurement.two_side_eigen_ratio == 50.0 and c.measurement.two_side_min_residual == 0.05
    assert c.measurement.partial_visibility == 0.9
    assert c.reduction.extraction_threshold == 0.5
    assert c.reduction.confirm_min_points == 2 and c.measurement.single_point_min_apparent == 0.25
    assert c.reduction.reidentify_window == 10.0 and c.reduction.report_range == 0.0
    assert c.reduction.report_road_margin == 0.0 and c.reduction.report_position_std == 5.0
    assert c.motion.acceleration and (c.motion.acceleration_time, c.motion.jerk, c.motion.residual_accel) == (6.0, 0.7, 0.15)
    assert c.motion.coast_acceleration_time == 0.5 and c.motion.coast_acceleration_std == 1.0
    assert (c.motion.coast_established_sigmas, c.motion.coast_established_time) == (2.0, 4.0)
    assert (c.motion.quiet_jerk, c.motion.manoeuvre_sigmas, c.motion.manoeuvre_hold) == (0.3, 2.0, 2.0)
    assert c.motion.manoeuvre_memory == 0.5
    assert c.measurement.whole_min_points == 3
    assert c.reduction.same_label_along_length
    assert (c.birth.min_cluster_points_radar, c.birth.sparse_min_range, c.birth.min_cluster_points_fused) == (1, 70.0, 2)
    assert (c.birth.width_error_std, c.birth.width_error_vehicles) == (0.0, 3)
    assert (c.birth.first_scan, c.birth.same_frame, c.birth.after_update_points) == (True, True, 3)
    assert (c.measurement.shadow_window, c.measurement.shadow_margin, c.measurement.shadow_free_gap) == (2.5, 0.5, 0.3)
    assert (c.ukf.alpha, c.ukf.beta, c.ukf.kappa) == (1.0, 2.0, 0.0)
    assert (c.detection.hidden_update_p_detection, c.detection.missed_weight_cap) == (0.05, False)


@pytest.mark.parametrize(
    "build, match",
    [
        (lambda: MeasurementConfig(lidar_sigma=-0.1), r"MeasurementConfig.lidar_sigma must be > 0"),
        (lambda: MeasurementConfig(partial_visibility=1.5), r"partial_visibility must be >= 0.0 and <= 1.0"),
        (lambda: MeasurementConfig(max_cluster_points=2), r"max_cluster_points must be an integer >= 3"),
        (lambda: MeasurementConfig(single_point_min_apparent=2.0), r"single_point_min_apparent must be >= 0.0 and <= 1.0"),
        (lambda: ReductionConfig(confirm_min_points=0), r"ReductionConfig.confirm_min_points must be an integer >= 1"),
        (lambda: ClusteringConfig(grazing_angle=0.0), r"ClusteringConfig.grazing_angle must be > 0.0 and < 1.57"),
        (lambda: ClusteringConfig(grazing_max_gap=0.0), r"ClusteringConfig.grazing_max_gap must be > 0.0 m"),
        (lambda: ReductionConfig(reidentify_probability=1.0), r"reidentify_probability must be > 0.0 and < 1.0"),
        (lambda: ReductionConfig(reidentify_brake=0.0), r"ReductionConfig.reidentify_brake must be > 0.0 m/s\^2"),
        (lambda: MotionConfig(acceleration_time=0.0), r"MotionConfig.acceleration_time must be > 0.0 s"),
        (lambda: MotionConfig(acceleration="yes"), r"MotionConfig.acceleration must be true or false"),
        (lambda: ProcessNoise(accel=float("nan")), r"ProcessNoise.accel must be finite"),
        (lambda: UKFParams(alpha=1e-3), r"Wc0"),
        (lambda: MeasurementConfig(radar_gate=-1.0), r"MeasurementConfig.radar_gate must be > 0"),
        (lambda: MotionConfig(coast_established_time=0.0), r"MotionConfig.coast_established_time must be > 0.0 s"),
        (lambda: MotionConfig(coast_established_sigmas=-1.0), r"MotionConfig.coast_established_sigmas must be >= 0"),
        (lambda: MotionConfig(quiet_jerk=0.9), r"MotionConfig.quiet_jerk \(0.9 m s\^-2.5\) must not exceed MotionConfig.jerk \(0.7\)"),
        (lambda: MotionConfig(quiet_jerk=-0.1), r"MotionConfig.quiet_jerk must be >= 0"),
        (lambda: MotionConfig(manoeuvre_sigmas=0.0), r"MotionConfig.manoeuvre_sigmas must be > 0"),
        (lambda: MotionConfig(manoeuvre_hold=-1.0), r"MotionConfig.manoeuvre_hold must be >= 0"),
        (lambda: MotionConfig(manoeuvre_memory=0.0), r"MotionConfig.manoeuvre_memory must be > 0"),
        (lambda: MeasurementConfig(two_side_min_residual=-0.01), r"MeasurementConfig.two_side_min_residual must be >= 0"),
        (lambda: MeasurementConfig(two_side_line_residual=0.0), r"MeasurementConfig.two_side_line_residual must be > 0"),
        (lambda: MeasurementConfig(whole_min_points=1), r"MeasurementConfig.whole_min_points must be an integer >= 2"),
        (lambda: MeasurementConfig(whole_gate_sigmas=-1.0), r"MeasurementConfig.whole_gate_sigmas"),
        (lambda: MeasurementConfig(whole_gate_slack=float("nan")), r"MeasurementConfig.whole_gate_slack"),
        (lambda: MeasurementConfig(continuation_rays=0.0), r"MeasurementConfig.continuation_rays"),
        (lambda: MeasurementConfig(continuation_offset=-0.1), r"MeasurementConfig.continuation_offset"),
        (lambda: DetectionConfig(hidden_update_p_detection=0.0), r"hidden_update_p_detection must be > 0.0 and <= 1.0"),
        (lambda: DetectionConfig(missed_weight_cap=1), r"DetectionConfig.missed_weight_cap must be true or false"),
        (lambda: TrackerConfig(coordinates="polar"), r"coordinates must be one of"),
        (lambda: TrackerConfig(use_radar="yes"), r"use_radar must be true or false"),
        (lambda: TrackerConfig(detection=DetectionConfig(lidar_resolution=math.radians(0.35))),
         r"clustering.bearing_bin \(0.2 deg\) is narrower than the lidar's azimuth step detection.lidar_resolution \(0.35 deg\)"),
    ],
)
def test_bad_values_name_the_field(build, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        build()


def test_variants() -> None:
    assert TrackerConfig.for_variant("curvilinear-fused") == TrackerConfig()
    lidar = TrackerConfig.for_variant("cartesian-lidar")
    assert lidar.coordinates == "cartesian" and not lidar.use_radar
    assert TrackerConfig.for_variant("point").object_model == "point"
    with pytest.raises(ValueError, match="unknown tracker variant"):
        TrackerConfig.for_variant("polar-fused")


def test_from_dict() -> None:
    c = TrackerConfig.from_dict({"coordinates": "cartesian", "measurement": {"lidar_sigma": 0.05}})
    assert c.coordinates == "cartesian" and c.measurement.lidar_sigma == 0.05
    assert c.measurement.partial_visibility == 0.9
    with pytest.raises(ValueError, match="unknown key.*'lidar_sigm'.*accepted"):
        TrackerConfig.from_dict({"measurement": {"lidar_sigm": 0.05}})
    with pytest.raises(ValueError, match="unknown tracker configuration key 'noise'"):
        TrackerConfig.from_dict({"noise": {}})
    assert dataclasses.replace(c, use_radar=False).use_radar is False


def test_the_vehicle_classes_are_checked() -> None:
    """``BirthConfig.classes`` takes ``VehicleClass`` es or tables of their fields (as a TOML file gives
    them), rejects an empty or a bad table, repeated names and sizes that are not positive, each with a
    one-line message naming the field."""
    table = {"name": "car", "share": 1.0, "length": 4.5, "length_std": 0.4, "width": 1.8, "width_std": 0.08}
    assert BirthConfig(classes=[table]).classes == (VehicleClass(**table),)
    assert BirthConfig(classes=None).classes is None
    for bad, message in (([], "at least one VehicleClass"), ("car", "a list of vehicle classes"),
                         ([table, table], "distinct names"), ([dict(table, share=0.0)], "share must be > 0"),
                         ([dict(table, width_std=-1.0)], "width_std must be > 0"),
                         ([{"name": "car"}], "exactly the keys name, share"), ([dict(table, colour=1)], "got name, share")):
        with pytest.raises(ValueError, match=message):
            BirthConfig(classes=bad)
    with pytest.raises(ValueError, match="fit_width_std"):
        BirthConfig(fit_width_std=0.0)
    with pytest.raises(ValueError, match="width_error_std must be >= 0"):
        BirthConfig(width_error_std=-0.1)
    for bad in (0, 2.5, True):
        with pytest.raises(ValueError, match="after_update_points"):
            BirthConfig(after_update_points=bad)
    assert BirthConfig(after_update_points=None).after_update_points is None


def test_default_vehicle_classes() -> None:
    """The default classes (``tracker.config.VEHICLE_CLASSES``, sources in docs/tracker.md): car, van/SUV/
    pickup, truck, bus and motorcycle; trucks and buses within the legal width limits (2.55 m EU, 2.6 m US)."""
    classes = {c.name: c for c in BirthConfig().classes}
    assert list(classes) == ["car", "van-suv-pickup", "truck", "bus", "motorcycle"]
    assert all(c.width <= 2.6 for c in classes.values()) and sum(c.share for c in classes.values()) == pytest.approx(1.0, abs=0.01)


def test_the_default_prior_size_is_the_classes() -> None:
    """A vehicle whose length or width is never seen keeps the birth's prior: a car's length (the
    ``car`` class's mean) and the classes' mean width weighed by their shares (1.91 m), each the
    least-squares guess of what the classes say."""
    cfg = BirthConfig()
    classes = {c.name: c for c in cfg.classes}
    assert cfg.length == classes["car"].length
    shares = np.array([c.share for c in cfg.classes])
    widths = np.array([c.width for c in cfg.classes])
    assert cfg.width == pytest.approx(shares @ widths / shares.sum(), abs=0.02)
