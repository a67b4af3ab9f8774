"""sim.world.replay and replay scenarios: recorded traffic as the truth of a run, its road from the lane
map, the `real` suite and `eot replay`."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from sim.world.replay import ReplayWorld, load_recording
from sim.world.scenario import SCENARIO_DIR, ScenarioError, load_suite, parse_scenario
from sim.world.world import World

pytest.importorskip("commonroad")

REAL = SCENARIO_DIR / "real"
US101_1 = REAL / "USA_US101-1_1_T-1.xml.gz"  # two recorded cars, 6 s
US101_3 = REAL / "USA_US101-3_1_T-1.xml.gz"


def _spec(path=US101_1, **replay):
    return parse_scenario({"name": "r", "description": "d", "replay": {"file": str(path), **replay}}, "test")


def test_truth_follows_the_recording_and_the_road():
    spec = _spec(US101_3)
    world = ReplayWorld.from_spec(spec, seed=3)
    recording, _ = load_recording(str(US101_3))
    ego = recording.vehicle(world.ego_id)
    assert spec.duration == pytest.approx(ego.end - ego.start) == pytest.approx(8.0)
    snap = world.truth_at(2.05)  # between two samples
    x, y, _, v, _ = ego.state_at(ego.start + 2.05)
    assert (snap.ego.x, snap.ego.y, snap.ego.v) == pytest.approx((x, y, v))
    when = ego.start + 2.05
    recorded = {car.id for car in recording if car.id != world.ego_id and car.state_at(when) is not None}
    assert world.ego_id not in snap.ids and recorded <= set(snap.ids.tolist())
    for row, vid in enumerate(snap.ids):
        car = recording.vehicle(int(vid))
        state = car.state_at(when)
        if state is None:  # its recording ended on the road: carried on at its last speed and heading
            assert car.end < when
            gone = when - car.end
            state = car.xy[-1] + car.v[-1] * gone * np.array([math.cos(car.yaw[-1]), math.sin(car.yaw[-1])])
            assert world.road.on_road(state[None])[0]
        assert snap.xy[row] == pytest.approx(state[:2])
        assert (snap.length[row], snap.width[row]) == (car.length, car.width)
    # road coordinates are the road's own conversion, and the heading relative to the road is small on a freeway
    s, n = world.road.to_frenet(snap.xy)
    np.testing.assert_allclose(snap.s, np.asarray(s).reshape(-1))
    np.testing.assert_allclose(snap.n, np.asarray(n).reshape(-1))
    on = (snap.s > 0) & (snap.s < world.road.length)
    assert np.abs(np.degrees(snap.xi[on])).max() < 15.0
    # the ego drives inside the road it is given
    es, en = world.road.to_frenet((snap.ego.x, snap.ego.y))
    right, left = world.road.edges(np.asarray(es).reshape(-1))
    assert right[0] < float(np.asarray(en).reshape(-1)[0]) < left[0]
    assert np.isnan(world.poses_at(2.05).s).all()
    # xi_dot is the rate of xi: against central differences over 0.02 s, vehicles on the road
    dt = 0.01
    before, after = world.truth_at(3.0 - dt), world.truth_at(3.0 + dt)
    mid = world.truth_at(3.0)
    both = np.intersect1d(np.intersect1d(before.ids, after.ids), mid.ids)
    rows = [np.flatnonzero(snap.ids == vid)[0] for snap in (before, mid, after) for vid in both]
    k = len(both)
    xi_rate = np.angle(np.exp(1j * (after.xi[rows[2 * k:]] - before.xi[rows[:k]]))) / (2 * dt)
    on = (mid.s[rows[k:2 * k]] > 5.0) & (mid.s[rows[k:2 * k]] < world.road.length - 5.0)
    assert on.sum() > 10
    np.testing.assert_allclose(mid.xi_dot[rows[k:2 * k]][on], xi_rate[on], atol=0.05)
    # late in the run vehicles whose recording ended are carried on, as long as they are on the road
    late = world.truth_at(7.9)
    carried = [vid for vid in late.ids if recording.vehicle(int(vid)).end < ego.start + 7.9]
    assert carried and world.info()["replay_carried_on"] >= len(carried)
    assert world.road.on_road(late.xy[np.isin(late.ids, carried)]).all()


def test_smoothed_and_raw_truth():
    smoothed, report = load_recording(str(US101_3), "smoothed")
    raw, none = load_recording(str(US101_3), "raw")
    assert none is None and report.widths_bounded > 0 and 0.0 < report.position_change_rms_m < 0.3
    assert max(v.width for v in smoothed if v.length <= 6.0) <= 2.1 < max(v.width for v in raw if v.length <= 6.0)
    assert report.smoothed_accel_max < 5.0 < report.raw_accel_max
    world = ReplayWorld.from_spec(_spec(US101_3, truth="raw"))
    assert world.info()["replay_truth"] == "raw" and "replay_widths_bounded" not in world.info()


def test_replay_spec_errors_name_the_field(tmp_path):
    with pytest.raises(ScenarioError, match=r"road: a replay takes its road and traffic from the recording"):
        parse_scenario({"name": "r", "description": "d", "replay": {"file": str(US101_1)},
                        "road": {"segments": [[100.0, 0.0, 0.0]]}}, "f.toml")
    with pytest.raises(ScenarioError, match=r"duration = 60.0: the ego is recorded for 6 s"):
        parse_scenario({"name": "r", "description": "d", "duration": 60.0, "replay": {"file": str(US101_1)}}, "f.toml")
    with pytest.raises(ScenarioError, match=r"replay.file = .*absent.xml.*no such recording"):
        _spec(tmp_path / "absent.xml")
    with pytest.raises(ScenarioError, match=r"replay.ego = 12345: recording .* no vehicle 12345; its vehicles are"):
        _spec(US101_1, ego=12345)
    with pytest.raises(ScenarioError, match=r"replay.ego = 12345: "):  # the same with a duration given
        parse_scenario({"name": "r", "description": "d", "duration": 2.0, "replay": {"file": str(US101_1), "ego": 12345}}, "f")
    with pytest.raises(ScenarioError, match=r"replay.file = .*absent.xml.*no such recording"):
        parse_scenario({"name": "r", "description": "d", "duration": 2.0, "replay": {"file": str(tmp_path / "absent.xml")}}, "f")
    with pytest.raises(ScenarioError, match="description must be one line"):
        parse_scenario({"name": "r", "description": "a\nb", "replay": {"file": str(US101_1)}}, "f")
    corrupt = tmp_path / "corrupt.xml.gz"
    corrupt.write_bytes(US101_1.read_bytes()[:200] + b"\x00" * 500)
    with pytest.raises(ScenarioError, match=r"replay.file = .*corrupt.xml.gz.*not a readable gzip file"):
        _spec(corrupt)
    with pytest.raises(ScenarioError, match=r"replay.truth") as err:
        _spec(US101_1, truth="cleaned")
    assert "duration" not in str(err.value)  # a replay's duration is optional: only the bad field is named
    with pytest.raises(ValueError, match=r"its world is sim.world.replay.ReplayWorld"):
        World(_spec())


def test_run_scores_the_replay():
    from sim.evaluation.runner import run_scenario

    spec = _spec(US101_1)
    result = run_scenario(spec, seed=0, duration=2.0)
    m = result.metrics
    assert m["frames"] == 21 and m["replay_recording"] == "USA_US101-1_1_T-1" and m["replay_vehicles"] == 1
    assert m["replay_ego"] in (v.id for v in load_recording(str(US101_1))[0])
    # one other car, seen throughout, close to its recorded place
    assert m["truth_count_mean"] == pytest.approx(1.0) and m["pos_rmse_m"] < 1.5
    assert result.settings["roadside_objects"] == 0  # a replay's scene is the recording's: no simulated clutter


def test_real_suite_lists_every_recording():
    suite = load_suite("real")
    assert len(suite.paths) == 14 == len(list(REAL.glob("*.xml.gz")))
    names = {p.stem for p in suite.paths}
    assert {"real-us101-3", "real-lanker-1-2"} <= names
    text = (REAL / "real-us101-3.toml").read_text()
    assert 'file = "USA_US101-3_1_T-1.xml.gz"' in text


def test_cli_replay(tmp_path, capsys):
    from sim import cli

    out = tmp_path / "run"
    assert cli.main(["replay", str(US101_1), "--duration", "1.0", "--out", str(out), "--quiet", "--raw"]) == 0
    printed = capsys.readouterr().out
    assert "replay: USA_US101-1_1_T-1, ego" in printed and "truth raw" in printed
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["replay_truth"] == "raw" and metrics["frames"] == 11
    for name in ("events.csv", "birdseye.png", "tracks.csv", "truth.csv"):
        assert (out / name).is_file()
    assert cli.main(["replay", str(tmp_path / "absent.xml")]) == cli.USAGE_EXIT
    assert cli.main(["replay", str(REAL / "README.md")]) == cli.USAGE_EXIT
    err = capsys.readouterr().err.strip().splitlines()
    assert err[0] == f"eot replay: no such recording {tmp_path / 'absent.xml'}"
    assert err[1] == "eot replay: README.md: a recording is a CommonRoad scenario file (.xml or .xml.gz)"
    assert math.isfinite(metrics["gospa_mean"])


def test_run_recording_from_python():
    """A recording built in code (any source) on the user's road: the car ahead is tracked where it is."""
    import sim
    from tracker import Road

    t = np.round(np.arange(0.0, 5.01, 0.1), 6)
    ego = sim.RecordedVehicle(1, t, np.column_stack([10 * t, 0 * t]), 0 * t, np.full(t.shape, 10.0), 4.6, 1.9)
    car = sim.RecordedVehicle(2, t, np.column_stack([20 + 12 * t, 3.5 + 0 * t]), 0 * t, np.full(t.shape, 12.0), 4.4, 1.8)
    recording = sim.Recording("mine", (ego, car))
    road = Road.from_curvature([(300.0, 0.0, 0.0)], start=(-50.0, 0.0, 0.0), lanes=3, lane_width=3.5, right_edge=-5.25)
    result = sim.run_recording(recording, road, ego=1, seed=2)
    m = result.metrics
    assert m["frames"] == 51 and m["replay_ego"] == 1 and m["replay_truth"] == "smoothed" and m["replay_carried_on"] == 0
    assert m["truth_count_mean"] == 1.0 and m["pos_rmse_m"] < 0.2 and m["id_switches"] == 0
    assert abs(m["length_rmse_m"]) < 0.5
    with pytest.raises(ValueError, match=r"recording 'mine' has no lane map \(map_file\); give its road"):
        sim.run_recording(recording, ego=1)
    with pytest.raises(ValueError, match="needs a sim.world.recording.Recording"):
        sim.run_recording("recording.xml")
