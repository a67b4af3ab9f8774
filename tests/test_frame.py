"""tracker.frame: the tracker's input dataclasses and their validation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tracker.frame import EgoState, Frame, RadarDetections


def test_frame_holds_copies_as_readonly_float_arrays():
    pts = np.array([[1.0, 2.0], [3.0, 4.0]])
    radar = np.array([[0.05, 10.0, 1.0, 20.0, 0.5]])
    frame = Frame(0.1, (1.0, 2.0, 0.3, 25.0, 0.01), pts, radar)
    pts[0, 0] = 99.0  # the frame copied its input
    assert frame.lidar[0, 0] == 1.0
    assert frame.lidar.dtype == np.float64 and frame.lidar.shape == (2, 2)
    assert not frame.lidar.flags.writeable and not frame.radar.x.flags.writeable
    assert frame.ego == EgoState(1.0, 2.0, 0.3, 25.0, 0.01)
    assert len(frame.radar) == 1
    np.testing.assert_array_equal(frame.radar.as_array(), radar)
    np.testing.assert_array_equal(frame.radar.xy, [[10.0, 1.0]])
    np.testing.assert_array_equal(frame.radar.velocity, [[20.0, 0.5]])


def test_frame_empty_parts_and_duck_typed_ego():
    class Pose:  # e.g. sim.world.truth.EgoPose: extra attributes are ignored
        x, y, yaw, v, yaw_rate, length = 1.0, 2.0, 3.0, 4.0, 0.5, 4.8

    frame = Frame(2.0, Pose(), None, None)
    assert frame.lidar.shape == (0, 2) and len(frame.radar) == 0
    assert frame.ego == EgoState(1.0, 2.0, 3.0, 4.0, 0.5)
    assert Frame(0.0, EgoState(0, 0, 0), np.zeros(0)).lidar.shape == (0, 2)


def test_ego_yaw_is_wrapped():
    assert EgoState(0, 0, 3 * math.pi / 2).yaw == pytest.approx(-math.pi / 2)
    assert EgoState(0, 0, -math.pi).yaw == pytest.approx(math.pi)


def test_driver_clouds_with_intensity_and_organized_clouds():
    """(N, 4) x, y, z, intensity: the geometry in ``lidar``, the intensity in ``lidar_intensity``; an organized
    (rows, columns, 4) cloud with NaN where a ray returned nothing is flattened row by row."""
    cloud = np.arange(24, dtype=float).reshape(6, 4)
    frame = Frame(0.0, (0, 0, 0), cloud)
    assert frame.lidar.shape == (6, 3) and np.array_equal(frame.lidar, cloud[:, :3])
    assert np.array_equal(frame.lidar_intensity, cloud[:, 3]) and not frame.lidar_intensity.flags.writeable
    organized = cloud.reshape(2, 3, 4).copy()
    organized[1, 2, :3] = np.nan
    flat = Frame(0.0, (0, 0, 0), organized)
    assert flat.lidar.shape == (6, 3) and np.isnan(flat.lidar[5]).all() and flat.lidar_intensity[5] == 23.0
    assert Frame(0.0, (0, 0, 0), cloud[:, :3]).lidar_intensity is None
    assert Frame(0.0, (0, 0, 0), np.zeros((0, 4))).lidar.shape == (0, 3)


def test_a_tracker_takes_a_driver_cloud_as_its_xyz():
    """The tracker's output is the same for a cloud with an intensity column (organized, NaN rows) as for
    its x, y, z alone."""
    from sim import load_scenario
    from sim.evaluation.runner import build_rig, rig_config_for, tracker_config_for, with_lidar_model
    from sim.world.world import World
    from tracker import Tracker

    spec = with_lidar_model(load_scenario("curve-single"), "vlp16")
    world = World(spec, seed=0)
    rig_config, clutter = rig_config_for(spec)
    rig = build_rig(rig_config, clutter, world.road, seed=0, ground=world.ground)
    config = tracker_config_for(spec, "curvilinear-fused", rig_config)
    plain, driver = Tracker(world.road, config), Tracker(world.road, config)
    rng = np.random.default_rng(0)
    for sf in rig.run(world.truth_at, 1.0, seed=0):
        f = sf.frame
        a = plain.step(f)
        cloud = np.column_stack([f.lidar, rng.uniform(0, 255, len(f.lidar))])
        cloud = np.concatenate([cloud, np.full((50, 4), np.nan)])  # rays that returned nothing
        b = driver.step(Frame(f.t, f.ego, cloud, f.radar))
        assert a
        assert [t.label for t in a] == [t.label for t in b]
        np.testing.assert_array_equal(np.array([t.mean for t in a]), np.array([t.mean for t in b]))


def test_non_finite_lidar_points_are_allowed_for_the_tracker_to_drop():
    frame = Frame(0.0, EgoState(0, 0, 0), [[np.nan, 1.0], [2.0, 3.0]])
    assert np.isnan(frame.lidar[0, 0])


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"t": float("nan")}, "Frame.t must be finite"),
        ({"t": "soon"}, "Frame.t must be a real number"),
        ({"ego": (0.0, 0.0)}, "3 to 5 numbers"),
        ({"ego": (0.0, float("inf"), 0.0)}, "EgoState.y must be finite"),
        ({"ego": object()}, "Frame.ego must be"),
        ({"lidar": np.zeros((3, 5))}, r"Frame.lidar must have shape \(N, 2\)"),
        ({"lidar": np.zeros((2, 3, 2))}, r"Frame.lidar must have shape \(N, 2\)"),
        ({"lidar": np.zeros((3, 4)), "lidar_intensity": np.zeros(3)}, "given twice"),
        ({"lidar": np.zeros((3, 3)), "lidar_intensity": np.zeros(2)}, "2 values for a lidar of shape \\(3, 3\\)"),
        ({"lidar": np.zeros((3, 2)), "lidar_intensity": np.zeros(3)}, "one per point of a 3-D cloud"),
        ({"lidar": [["a", "b"]]}, "Frame.lidar must be a numeric"),
        ({"radar": np.zeros((2, 4))}, r"shape \(N, 5\)"),
        ({"radar": [[1.5, 0, 0, 0, 0]]}, "after the frame time"),
    ],
)
def test_frame_rejects_bad_input(kwargs, message):
    args = {"t": 1.0, "ego": (0.0, 0.0, 0.0), "lidar": None, "radar": None} | kwargs
    with pytest.raises(ValueError, match=message):
        Frame(**args)


def test_radar_detections_reject_bad_input():
    with pytest.raises(ValueError, match=r"RadarDetections.x has 1 entries but RadarDetections.t has 2"):
        RadarDetections([0.0, 0.1], [1.0], [1.0, 2.0], [0.0, 0.0], [0.0, 0.0])
    with pytest.raises(ValueError, match=r"RadarDetections.vy\[1\] must be finite"):
        RadarDetections([0.0, 0.1], [1.0, 2.0], [1.0, 2.0], [0.0, 0.0], [0.0, np.nan])
    with pytest.raises(ValueError, match="must be 1-D"):
        RadarDetections(np.zeros((2, 2)), np.zeros(2), np.zeros(2), np.zeros(2), np.zeros(2))
    assert len(RadarDetections.empty()) == 0
    assert RadarDetections.empty().as_array().shape == (0, 5)


def test_radar_positions_are_moved_to_the_frame_time_with_their_own_velocity():
    radar = RadarDetections(t=[0.93, 1.0, 0.95], x=[10.0, -5.0, 0.0], y=[2.0, 1.0, 3.0], vx=[20.0, 0.0, -4.0],
                            vy=[0.0, 3.0, 2.0])
    np.testing.assert_allclose(radar.positions_at(1.0), [[11.4, 2.0], [-5.0, 1.0], [-0.2, 3.1]], atol=1e-12)
    np.testing.assert_allclose(radar.positions_at(1.0, np.array([2, 0])), [[-0.2, 3.1], [11.4, 2.0]], atol=1e-12)
    assert radar.positions_at(1.0, np.zeros(0, dtype=int)).shape == (0, 2)
