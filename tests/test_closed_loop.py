"""sim.studies.closed_loop: modes and faults, one run's metrics and traced events, the paired differences
to truth (against scipy's t interval), the outputs and the ``eot closed-loop`` command."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest
from scipy import stats

from sim.studies.closed_loop import (
    DROPOUT_S,
    EVENT_COLUMNS,
    METRICS,
    Task,
    fault_config,
    paired_rows,
    parse_mode,
    plan,
    run_task,
    wilson,
    write_outputs,
)
from sim.world.generator import realize
from sim.world.scenario import load_scenario, resolve_scenario_path


def test_closed_loop_run_reports_the_metrics():
    row, events = run_task(Task("emergency-brake", "emergency-brake", "truth", 0, duration=9.0))
    assert row["collision"] == 0 and row["sim_s"] == pytest.approx(9.0)
    assert 0.5 < row["min_time_headway_s"] < 3.0  # the lead stops at 8 m/s^2 ahead of the ego
    assert 1.0 < row["min_ttc_s"] < 10.0
    assert 5.0 < row["mean_speed_mps"] < 20.0
    assert row["phantom_brake_events"] == 0 and row["late_brake_events"] == 0  # truth has no phantoms
    assert all(e["kind"] != "collision" for e in events)


def test_wilson_interval():
    lo, hi = wilson(0, 20)
    assert lo == 0.0 and hi == pytest.approx(0.1611, abs=1e-3)
    lo, hi = wilson(10, 20)
    assert lo == pytest.approx(0.2993, abs=1e-3) and hi == pytest.approx(0.7007, abs=1e-3)
    assert math.isclose(sum(wilson(3, 10)), 2 * (3 + 1.96**2 / 2) / (10 + 1.96**2), rel_tol=1e-3)


def test_eot_closed_loop_command(tmp_path, capsys):
    from sim.cli import main

    out = tmp_path / "cl"
    assert main(["closed-loop", "cut-in", "--runs", "2", "--duration", "1", "--out", str(out), "--quiet",
                 "--variant", "curvilinear-lidar"]) == 0
    assert {p.name for p in out.iterdir()} >= {"runs.csv", "summary.csv", "summary.json", "events.csv", "table.md",
                                               "closed_loop.png"}
    table = (out / "table.md").read_text()
    assert "| cut-in | truth | 2 | 0/2 [0.00, 0.66] |" in table and "| cut-in | curvilinear-lidar | 2 |" in table
    assert "eot closed-loop cut-in --runs 2 --workers 1 --variant curvilinear-lidar --duration 1" in table
    rows = (out / "runs.csv").read_text().splitlines()
    assert len(rows) == 1 + 4 and rows[0].startswith("scenario,variant,seed,sim_s,collision,collision_ahead,min_time_headway_s")
    assert main(["closed-loop", "cut-in", "--variant", "nope", "--out", str(out)]) == 2
    assert "unknown variant 'nope'" in capsys.readouterr().err


def test_modes_name_a_variant_and_optionally_a_fault():
    assert parse_mode("truth") == ("truth", None)
    assert parse_mode("point-gnn") == ("point-gnn", None)
    assert parse_mode("curvilinear-fused+lidar-dropout") == ("curvilinear-fused", "lidar-dropout")
    with pytest.raises(ValueError, match="unknown fault 'rain'; choose one of: radar-missing, lidar-dropout"):
        parse_mode("curvilinear-fused+rain")
    with pytest.raises(ValueError, match="unknown variant 'nope'"):
        parse_mode("nope+radar-missing")
    with pytest.raises(ValueError, match="the truth mode has no sensors to fail"):
        parse_mode("truth+radar-missing")


def test_the_lidar_dropout_is_centred_on_the_hazard_and_kept_in_the_run():
    assert fault_config(None, 14.0, 5.0) is None
    assert fault_config("radar-missing", 14.0, 5.0) == {"radar_missing": True}
    assert fault_config("lidar-dropout", 14.0, 5.0) == {"lidar_dropout": [[5.0 - DROPOUT_S / 2, 5.0 + DROPOUT_S / 2]]}
    assert fault_config("lidar-dropout", 14.0, 0.3) == {"lidar_dropout": [[0.0, DROPOUT_S]]}
    assert fault_config("lidar-dropout", 14.0, 13.9) == {"lidar_dropout": [[14.0 - DROPOUT_S, 14.0]]}
    assert fault_config("lidar-dropout", 10.0, None) == {"lidar_dropout": [[5.0 - DROPOUT_S / 2, 5.0 + DROPOUT_S / 2]]}
    tasks = plan(["family-cut-out"], 3, ["curvilinear-fused+lidar-dropout"], seed0=4)
    spec = load_scenario("family-cut-out")
    assert [t.mode for t in tasks] == ["truth"] * 3 + ["curvilinear-fused+lidar-dropout"] * 3
    for task in tasks[3:]:
        start, end = task.faults["lidar_dropout"][0]
        assert start + DROPOUT_S / 2 == pytest.approx(realize(spec, task.seed).hazard_t, abs=1e-3)
        assert end - start == pytest.approx(DROPOUT_S)
    assert all(t.faults is None for t in tasks[:3])


def test_a_fault_mode_runs_the_faulty_sensors_and_traces_its_events():
    """cut-out with the lidar silent around the reveal: 20 lidar frames carry no points. Lane-splitting
    with the lidar silent as the motorcycle passes: the ego brakes hard for the coasting track, and the
    event row names what the tracker reported against the truth."""
    from sim.env import TrackedRoadEnv

    faults = fault_config("lidar-dropout", 14.0, realize(load_scenario("family-cut-out"), 1).hazard_t)
    env = TrackedRoadEnv({"scenario": "family-cut-out", "action": "ContinuousAction", "variant": "curvilinear-fused",
                          "faults": faults})
    env.reset(seed=1)
    while not env.step(np.zeros(2, dtype=np.float32))[3]:
        pass
    assert env.fault_injector.counts["lidar_frames_dropped"] == round(DROPOUT_S * 10)
    faults = fault_config("lidar-dropout", 16.0, realize(load_scenario("family-lane-splitting"), 0).hazard_t)
    source = str(resolve_scenario_path("family-lane-splitting"))
    row, events = run_task(Task("family-lane-splitting", source, "curvilinear-fused+lidar-dropout", 0, None, faults))
    assert set(METRICS) <= set(row) and row["progress_m"] > 50.0
    traced = [e for e in events if e["kind"] in ("hard_brake", "phantom_brake", "lateral_brake", "late_brake")]
    assert len(traced) == row["hard_brake_events"] + row["phantom_brake_events"] + row["lateral_brake_events"] \
        + row["late_brake_events"] >= 1
    for e in traced:
        assert list(e) == list(EVENT_COLUMNS)
        assert e["track_label"] != "" and e["truth_id"] != ""  # the track and the vehicle it is compared with
        assert e["track_error_m"] == pytest.approx(math.hypot(e["track_ds"] - e["truth_ds"], e["track_n"] - e["truth_n"]), abs=2e-3)


def test_rear_ttc_and_progress_of_a_run_with_a_fast_vehicle_behind():
    row, _ = run_task(Task("family-merge-fast-rear", "family-merge-fast-rear", "truth", 2))
    spec = realize(load_scenario("family-merge-fast-rear"), 2)
    assert row["collision"] == 0
    assert row["progress_m"] == pytest.approx(row["mean_speed_mps"] * spec.duration, rel=0.05)
    assert row["min_rear_ttc_s"] < 20.0 or row["min_ttc_s"] < 20.0  # something closed in on the ego


def test_paired_differences_match_scipy_and_count_discordant_collisions():
    rng = np.random.default_rng(0)
    rows = []
    truth_ttc = rng.uniform(2.0, 8.0, 12)
    mode_ttc = truth_ttc - rng.uniform(0.0, 1.0, 12)
    collide_truth = [0] * 12
    collide_mode = [1, 1, 0] + [0] * 9
    collide_truth[5] = 1
    for k in range(12):
        for mode, ttc, hit in (("truth", truth_ttc[k], collide_truth[k]), ("point-gnn", mode_ttc[k], collide_mode[k])):
            row = {m: 0.0 for m in METRICS}
            row.update(scenario="family-x", variant=mode, seed=k, sim_s=10.0, collision=hit, min_ttc_s=float(ttc))
            rows.append(row)
    paired = {p["metric"]: p for p in paired_rows(rows)}
    d = mode_ttc - truth_ttc
    half = stats.t.ppf(0.975, 11) * d.std(ddof=1) / math.sqrt(12)
    assert paired["min_ttc_s"]["diff"] == pytest.approx(d.mean())
    assert paired["min_ttc_s"]["ci95_low"] == pytest.approx(d.mean() - half)
    assert paired["min_ttc_s"]["ci95_high"] == pytest.approx(d.mean() + half)
    assert paired["collision"]["only_mode"] == 2 and paired["collision"]["only_truth"] == 1


def test_outputs_hold_the_paired_table_and_a_figure_per_scenario(tmp_path):
    tasks = plan(["family-lane-splitting"], 2, ["point-gnn"], duration=3.0)
    rows, events = [], []
    for task in tasks:
        row, ev = run_task(task)
        rows.append(row)
        events += ev
    paths = write_outputs(rows, events, tmp_path, command="eot closed-loop test", wall_s=1.0, workers=1)
    assert (tmp_path / "family_family-lane-splitting.png").stat().st_size > 10_000
    table = paths["table"].read_text()
    assert "## Differences to truth, paired per seed" in table
    assert "| family-lane-splitting | point-gnn | 0 / 0 |" in table
    with open(paths["paired"], newline="") as fh:
        paired = list(csv.DictReader(fh))
    assert {p["metric"] for p in paired} == set(METRICS) and all(p["mode"] == "point-gnn" for p in paired)


def test_a_brake_is_traced_against_the_truth_the_planner_decided_on():
    """With truth as perception the planner's lead is the true vehicle: its traced error is exactly 0
    (cut-out: the ego brakes hard for the revealed standing car in some seeds)."""
    hard: list = []
    for seed in range(12):
        row, events = run_task(Task("family-cut-out", "family-cut-out", "truth", seed))
        hard = [e for e in events if e["kind"] == "hard_brake"]
        assert row["hard_brake_events"] == len(hard)
        if hard:
            break
    assert hard
    for e in hard:
        assert e["track_error_m"] == 0.0 and e["track_label"] == e["truth_id"]


def test_an_unavailable_variant_is_refused_before_running_and_left_out_of_all(monkeypatch, tmp_path, capsys):
    from sim.cli import main
    from sim.evaluation import variants
    from sim.studies import closed_loop

    def probe(name: str) -> str | None:
        return "install the 'baselines' extra" if name == "stonesoup-gmphd" else None

    monkeypatch.setattr(closed_loop, "probe_variant", probe)
    monkeypatch.setattr(variants, "probe_variant", probe)
    with pytest.raises(ValueError, match="variant stonesoup-gmphd is not available here: install the 'baselines' extra"):
        plan(["family-cut-in"], 1, ["stonesoup-gmphd+radar-missing"])
    out = tmp_path / "cl"
    assert main(["closed-loop", "family-cut-in", "--runs", "1", "--duration", "0.4", "--variant", "all", "--no-truth",
                 "--out", str(out), "--quiet"]) == 0
    err = capsys.readouterr().err
    assert "--variant all leaves out stonesoup-gmphd: install the 'baselines' extra" in err
    modes = {row.split(",")[1] for row in (out / "runs.csv").read_text().splitlines()[1:]}
    assert modes == set(variants.VARIANTS) - {"stonesoup-gmphd"}


def test_truth_never_brakes_for_a_misplaced_or_phantom_vehicle():
    """With truth as perception every brake is for a true vehicle in the ego's lanes or its own path
    (cut-out: the ego swerving past the revealed car brakes for it while its body still overlaps it)."""
    for seed in range(6):
        row, _ = run_task(Task("family-cut-out", "family-cut-out", "truth", seed))
        assert row["lateral_brake_events"] == 0 and row["phantom_brake_events"] == 0 and row["late_brake_events"] == 0


def test_real_traffic_in_the_loop_from_the_planning_problem():
    """A recording in the loop: truth and a tracker drive the planning problem's ego among recorded
    vehicles; the goal columns are filled (empty for a family); a collision says where the other
    vehicle was; the cruise speed covers the route to the goal by the middle of its time interval."""
    pytest.importorskip("commonroad")
    from sim.studies.closed_loop import make_env, set_speed_for

    tasks = plan(["real/real-lanker-1-1"], 1, ["curvilinear-fused"])
    assert [t.mode for t in tasks] == ["truth", "curvilinear-fused"]
    rows = [run_task(t)[0] for t in tasks]
    for row in rows:
        assert row["sim_s"] == pytest.approx(4.0) and row["collision"] == 0
        assert row["goal_reached"] == 1 and 3.0 <= row["time_to_goal_s"] <= 4.0  # in the goal's own interval here
        assert row["progress_m"] > 25.0
    family = run_task(plan(["family-cut-in"], 1, [], duration=1.0)[0])[0]
    assert family["goal_reached"] is None and family["time_to_goal_s"] is None
    env = make_env(tasks[0].source, "truth")
    env.reset(seed=0)
    p = env.world.planning
    s_goal = float(np.asarray(env.world.road.to_frenet(p.goal_center)[0]).reshape(-1)[0])
    expected = (s_goal - env.world.ego_state().s) / (0.5 * (p.goal_time[0] + p.goal_time[1]) - p.t)
    assert set_speed_for(env) == pytest.approx(max(expected, p.v))
    env.close()
    with pytest.raises(ValueError, match=r"duration must be in \(0, 4\] s for real-lanker-1-1"):
        plan(["real/real-lanker-1-1"], 1, [], duration=5.0)


def test_a_collision_event_says_where_the_other_vehicle_was():
    """us101-12: a recorded vehicle that does not react drives into the back of the truth planner's ego."""
    pytest.importorskip("commonroad")
    row, events = run_task(plan(["real/real-us101-12"], 1, [])[0])
    hits = [e for e in events if e["kind"] == "collision"]
    assert row["collision"] == 1 and row["collision_ahead"] == 0 and len(hits) == 1
    assert "(behind the ego)" in hits[0]["detail"] and hits[0]["truth_ds"] < -2.4
