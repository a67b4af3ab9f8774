"""Sensor faults (``[faults]`` in the scenario format, ``sim.sensors.faults``): validation, what each fault does
to the frames, the dropout measures (coasting, re-acquisition with the same label) and the rig's
delayed lidar scan."""

from __future__ import annotations

import tomllib
from types import SimpleNamespace

import numpy as np
import pytest

from sim.evaluation.dropouts import DropoutOutcome, dropout_metrics, dropout_outcomes
from sim.evaluation.runner import check_scenario_settings, run_scenario
from sim.sensors import SensorRig
from sim.sensors.faults import in_intervals
from sim.world.scenario import SCENARIO_DIR, ScenarioError, load_suite, parse_scenario
from sim.world.world import World


def _spec(faults: dict | None = None, duration: float = 2.0, sensors: dict | None = None):
    with open(SCENARIO_DIR / "curve-single.toml", "rb") as fh:
        data = tomllib.load(fh)
    data["duration"] = duration
    data["sensors"] = dict(sensors or {}, roadside=False)
    if faults is not None:
        data["faults"] = faults
    return parse_scenario(data, "test.toml")


# -- validation ----------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("faults", "needle"),
    [
        ({"lidar_dropout": [[1.5, 1.0]]}, "faults.lidar_dropout[0] = [1.5, 1.0]: need 0 <= start < end"),
        ({"radar_dropout": [[0.5, 9.0]]}, "faults.radar_dropout[0] = [0.5, 9.0]: must end by the duration (2.0 s)"),
        ({"lidar_spikes": 1.5}, "faults.lidar_spikes = 1.5"),
        ({"lidar_time_offset": -0.01}, "faults.lidar_time_offset = -0.01"),
        ({"duplicate_frames": [2.0]}, "faults.duplicate_frames[0] = 2.0: must be < duration"),
        ({"lidar_dropuot": [[0.0, 1.0]]}, "faults.lidar_dropuot = [[0.0, 1.0]]: unknown key; allowed keys here: lidar_dropout"),
    ],
)
def test_bad_faults_are_errors_naming_the_field(faults, needle):
    with pytest.raises(ScenarioError) as info:
        _spec(faults)
    assert needle in str(info.value) and str(info.value).startswith("test.toml:")


def test_time_offset_must_be_below_the_lidar_period():
    spec = _spec({"lidar_time_offset": 0.15})  # valid on its own, but the lidar runs at 10 Hz
    with pytest.raises(ScenarioError, match=r"faults.lidar_time_offset = 0.15: must be below the lidar's period \(0.1 s"):
        check_scenario_settings(spec)
    check_scenario_settings(_spec({"lidar_time_offset": 0.15}, sensors={"lidar": {"rate_hz": 5.0}}))


def test_faults_suite_has_one_valid_scenario_per_fault():
    suite = load_suite(SCENARIO_DIR / "faults.toml")
    specs = suite.load()
    assert [s.name for s in specs][0] == "fault-baseline" and specs[0].faults is None
    faulty = {s.name: s.faults for s in specs[1:]}
    assert faulty["fault-lidar-dropout"].lidar_dropout == [(6.0, 8.0)] == faulty["fault-lidar-dropout"].radar_dropout
    assert faulty["fault-radar-only"].lidar_dropout == [(6.0, 8.0)] and not faulty["fault-radar-only"].radar_dropout
    assert faulty["fault-radar-missing"].radar_missing
    assert faulty["fault-time-offset"].lidar_time_offset == 0.05
    assert faulty["fault-lidar-spikes"].lidar_spikes == 0.05
    assert faulty["fault-duplicate-frame"].duplicate_frames == [4.0, 8.0, 12.0]
    for spec in specs:  # same road and traffic: only the faults differ
        assert spec.road == specs[0].road and spec.vehicles == specs[0].vehicles and spec.duration == 16.0
        check_scenario_settings(spec)


# -- what the faults do ----------------------------------------------------------------------------
def test_dropouts_spikes_and_duplicates_change_only_their_frames():
    clean = run_scenario(_spec(), 3, keep_sensor_data=True)
    faults = {"lidar_dropout": [[0.5, 0.8]], "radar_dropout": [[1.0, 1.2]], "lidar_spikes": 0.2,
              "duplicate_frames": [1.45]}
    faulty = run_scenario(_spec(faults), 3, keep_sensor_data=True)
    assert len(clean.frames) == 21 and len(faulty.frames) == 22  # the 1.5 s frame twice
    times = [round(f.t, 3) for f in faulty.frames]
    assert times.count(1.5) == 2 and faulty.frames[15].frame is faulty.frames[16].frame
    m = faulty.metrics
    assert m["fault_lidar_frames_dropped"] == 3 and m["fault_frames_duplicated"] == 1  # 0.5, 0.6, 0.7
    radar_in_dropout = sum(len(f.frame.radar) for f in clean.frames if 1.0 <= f.t < 1.2)
    assert radar_in_dropout > 0 and m["fault_radar_detections_dropped"] == radar_in_dropout
    clean_by_t = {round(f.t, 3): f for f in clean.frames}
    spiked = total = 0
    for k, rec in enumerate(faulty.frames):
        if k == 16:
            continue  # the duplicate: the same frame again
        ref = clean_by_t[round(rec.t, 3)]
        t = rec.t
        if 0.5 <= t < 0.8:
            assert rec.frame.lidar.shape == (0, 2) and rec.lidar_points.sum() == 0
        else:
            pts, ref_pts = rec.frame.lidar, ref.frame.lidar
            assert pts.shape == ref_pts.shape  # spikes move points, they do not add or remove any
            moved = np.any(pts != ref_pts, axis=1)
            # a spike stays on its ray, at a range within the lidar's [0.5, 100] m
            cross = pts[moved, 0] * ref_pts[moved, 1] - pts[moved, 1] * ref_pts[moved, 0]
            assert np.allclose(cross / np.linalg.norm(ref_pts[moved], axis=1), 0.0, atol=1e-9)
            assert np.all((pts[moved] * ref_pts[moved]).sum(axis=1) > 0)
            r = np.linalg.norm(pts[moved], axis=1)
            assert np.all((r >= 0.5) & (r <= 100.0))
            spiked += int(moved.sum())
            total += len(pts)
        if 1.0 <= t < 1.2:
            assert len(rec.frame.radar) == 0
        else:
            assert len(rec.frame.radar) == len(ref.frame.radar)
    assert m["fault_lidar_points_spiked"] == spiked
    assert total > 300 and 0.12 < spiked / total < 0.28  # 20 % (4 sigma bounds)
    # the truth and the ego are untouched
    assert np.array_equal(faulty.frames[0].truth_state, clean.frames[0].truth_state)


def test_radar_missing_drops_every_detection():
    result = run_scenario(_spec({"radar_missing": True}), 0, keep_sensor_data=True)
    assert all(len(f.frame.radar) == 0 for f in result.frames)
    assert result.metrics["fault_radar_frames_dropped"] > 10


def test_lidar_delay_scans_the_world_before_the_stamp():
    spec = _spec()
    rig = SensorRig()
    on_time = rig.run(World(spec, 0).truth_at, 0.5, seed=1)
    late = list(rig.frames(World(spec, 0).truth_at, 0.5, seed=1, lidar_delay=0.05))
    assert [f.frame.t for f in late] == [f.frame.t for f in on_time]
    for a, b in zip(on_time[1:], late[1:]):
        assert b.lidar.t == pytest.approx(a.frame.t - 0.05)
        assert b.frame.ego == a.frame.ego and b.truth.t == a.truth.t  # pose and truth at the stamp
        # the car ahead moved ~0.05 s x its speed relative to the ego less in the late scan
        assert not np.array_equal(a.frame.lidar, b.frame.lidar)
    with pytest.raises(ValueError, match="lidar_delay must be in"):
        next(rig.frames(World(spec, 0).truth_at, 0.5, lidar_delay=0.1))


# -- dropout measures ------------------------------------------------------------------------------
def _record(t, tracks, assigned, scored_ids):
    ids = np.array(sorted({1, 2, 3}))
    return SimpleNamespace(
        t=t,
        tracks=[SimpleNamespace(label=lab) for lab in tracks],
        track_truth_id=np.array(assigned, dtype=int),
        truth=SimpleNamespace(ids=ids),
        scored=np.isin(ids, scored_ids),
    )


def test_dropout_outcomes_count_coasting_and_labels():
    records = [
        _record(0.9, [10, 20, 30], [1, 2, 3], [1, 2, 3]),  # before the dropout [1, 2)
        _record(1.5, [10, 20], [1, -1], [1, 2, 3]),
        _record(1.9, [10], [-1], [1, 2, 3]),  # last frame of the dropout: only label 10 coasted
        _record(2.5, [10, 40], [1, 2], [1, 2]),
        _record(3.0, [10, 40], [1, 2], [1, 2]),  # end of the 1 s window: vehicle 3 left the scored set
    ]
    out = dropout_outcomes(records, [(1.0, 2.0)], window_s=1.0)
    assert [(o.vehicle_id, o.label, o.coasted, o.reacquired, o.label_after) for o in out] == [
        (1, 10, True, True, 10), (2, 20, False, False, 40)]
    assert all(o.check_t == 3.0 for o in out)
    assert dropout_metrics(out) == {"fault_dropout_vehicles": 2, "fault_dropout_coasted": 1,
                                    "fault_dropout_reacquired": 1, "fault_dropout_reacquired_fraction": 0.5}
    assert dropout_outcomes(records, [(1.0, 2.0)], window_s=1.5) == []  # no frame at the window's end
    assert dropout_metrics([])["fault_dropout_reacquired_fraction"] is None
    assert isinstance(out[0], DropoutOutcome)


def test_a_short_blackout_on_one_car_keeps_its_label():
    faults = {"lidar_dropout": [[1.0, 1.3]], "radar_dropout": [[1.0, 1.3]]}
    result = run_scenario(_spec(faults, duration=2.5), 0)
    m = result.metrics
    assert m["fault_lidar_frames_dropped"] == 3 and m["fault_radar_frames_dropped"] == 3
    assert m["fault_dropout_vehicles"] == 1  # the one car, tracked before and in range after
    assert m["fault_dropout_coasted"] == 1 and m["fault_dropout_reacquired"] == 1


def test_in_intervals_is_half_open():
    assert in_intervals(1.0, [(1.0, 2.0)]) and not in_intervals(2.0, [(1.0, 2.0)]) and not in_intervals(0.5, [])
