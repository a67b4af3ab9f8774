"""Monte Carlo: planning, the summary's confidence intervals, the output files, and backend agreement
(2 local workers = serial; a tiny Ray run = local, when Ray is installed), and that a run counts as
finished only once its row is in runs.csv."""

from __future__ import annotations

import csv
import json
import math

import pytest

from sim.studies import montecarlo
from sim.studies.montecarlo import (
    RunsFile,
    Study,
    StudyInterrupted,
    plan,
    read_runs,
    run_study,
    summarize_runs,
    write_study,
)
from sim.evaluation.runner import TIMING_KEYS
from sim.evaluation.variants import UnknownVariantError


def _strip(rows):
    return [{k: v for k, v in row.items() if k not in TIMING_KEYS} for row in rows]


def test_plan_crosses_scenarios_variants_and_seeds():
    tasks = plan(["curve-single", "cut-in"], 3, ["curvilinear-fused", "curvilinear-lidar"], seed0=5, duration=1.0)
    assert len(tasks) == 12
    assert [(t.name, t.variant, t.seed) for t in tasks[:4]] == [
        ("curve-single", "curvilinear-fused", 5), ("curve-single", "curvilinear-fused", 6),
        ("curve-single", "curvilinear-fused", 7), ("curve-single", "curvilinear-lidar", 5),
    ]  # fmt: skip
    assert {t.duration for t in tasks} == {1.0}
    assert tasks[0].data["name"] == "curve-single"  # the content travels, not the path
    with pytest.raises(UnknownVariantError, match="choose one of"):
        plan(["curve-single"], 1, ["nope"])
    with pytest.raises(ValueError, match="runs"):
        plan(["curve-single"], 0)


def test_plan_puts_tracker_overrides_over_the_scenarios_own():
    """``tracker_overrides`` reach every task's ``[tracker]`` table (merged key by key over the scenario's
    own: ``merge_tables``), and the run's tracker configuration (``tracker_config_for``) has them."""
    from sim.evaluation.runner import tracker_config_for
    from sim.world.scenario import parse_scenario

    tasks = plan(["cut-in"], 1, tracker_overrides={"measurement": {"grow_extent": False}, "birth": {"classes": None}})
    table = tasks[0].data["tracker"]
    assert table == {"measurement": {"grow_extent": False}, "birth": {"classes": None}}
    config = tracker_config_for(parse_scenario(tasks[0].data, tasks[0].source), tasks[0].variant)
    assert config.measurement.grow_extent is False and config.birth.classes is None
    with pytest.raises(ValueError, match="unknown key"):
        plan(["cut-in"], 1, tracker_overrides={"measurement": {"nope": 1}})


def test_merge_tables_merges_nested_tables_and_leaves_its_inputs():
    base = {"a": {"x": 1, "y": 2}, "b": 3}
    top = {"a": {"y": 5, "z": 6}, "c": {"k": 7}}
    assert montecarlo.merge_tables(base, top) == {"a": {"x": 1, "y": 5, "z": 6}, "b": 3, "c": {"k": 7}}
    assert base == {"a": {"x": 1, "y": 2}, "b": 3}


def test_summary_mean_and_t_interval():
    rows = [{"scenario": "a", "variant": "v", "seed": i, "sim_s": 1.0, "x": float(x), "y": None if i else 2.0}
            for i, x in enumerate([1, 2, 3, 4])]
    rows.append({"scenario": "b", "variant": "v", "seed": 0, "sim_s": 1.0, "x": 7.0, "y": None})
    summary = {(s["scenario"], s["metric"]): s for s in summarize_runs(rows)}
    x = summary[("a", "x")]
    std = math.sqrt(sum((v - 2.5) ** 2 for v in [1, 2, 3, 4]) / 3)
    half = 3.182446305284263 * std / 2.0  # t(0.975, 3) * s / sqrt(4)
    assert x["n"] == 4 and x["mean"] == 2.5 and x["std"] == pytest.approx(std)
    assert x["ci95_low"] == pytest.approx(2.5 - half, rel=1e-12) and x["ci95_high"] == pytest.approx(2.5 + half, rel=1e-12)
    # missing values are skipped; one value has no interval; no value has no mean
    assert summary[("a", "y")]["n"] == 1 and summary[("a", "y")]["mean"] == 2.0 and summary[("a", "y")]["ci95_low"] is None
    assert summary[("b", "y")]["n"] == 0 and summary[("b", "y")]["mean"] is None
    assert summary[("b", "x")]["mean"] == 7.0 and summary[("b", "x")]["std"] is None


def test_write_study_files(tmp_path):
    rows = [{"scenario": "a", "variant": "v", "seed": i, "sim_s": 2.0, "gospa_mean": 0.5 * i, "pos_rmse_m": None}
            for i in range(3)]
    paths = write_study(Study(rows, "local", 2, 1.5), tmp_path)
    with open(paths["runs"], newline="") as fh:
        got = list(csv.DictReader(fh))
    assert len(got) == 3 and got[2]["gospa_mean"] == "1.0" and got[0]["pos_rmse_m"] == ""
    doc = json.loads(paths["summary_json"].read_text())
    assert doc["runs"] == 3 and doc["simulated_s"] == 6.0
    assert doc["sim_s_per_wall_s_per_worker"] == pytest.approx(6.0 / (1.5 * 2))
    with open(paths["summary"], newline="") as fh:
        summary = {r["metric"]: r for r in csv.DictReader(fh)}
    assert float(summary["gospa_mean"]["mean"]) == 0.5 and summary["pos_rmse_m"]["n"] == "0"


@pytest.fixture(scope="module")
def small_tasks():
    # the real tracker, 2 scenarios x 2 seeds, 1 s each
    return plan(["curve-single", "cut-in"], 2, ["curvilinear-fused"], duration=1.0)


@pytest.fixture(scope="module")
def serial(small_tasks):
    return run_study(small_tasks, workers=1)


def test_two_local_workers_equal_serial(small_tasks, serial):
    done = []
    parallel = run_study(small_tasks, workers=2, progress=lambda d, n: done.append((d, n)))
    assert _strip(parallel.rows) == _strip(serial.rows)
    assert [r["seed"] for r in serial.rows] == [0, 1, 0, 1]
    assert serial.rows[0]["frames"] == 11 and serial.rows[0]["gospa_mean"] is not None
    assert done[-1] == (4, 4) and len(done) == 4
    assert parallel.throughput > 0 and parallel.simulated_s == 4.0


def test_bad_backend_and_workers(small_tasks):
    with pytest.raises(ValueError, match="local, ray"):
        run_study(small_tasks, backend="spark")
    with pytest.raises(ValueError, match="workers"):
        run_study(small_tasks, workers=0)


def test_ray_equals_local(small_tasks, serial):
    pytest.importorskip("ray")
    ray_study = run_study(small_tasks, workers=2, backend="ray")
    assert _strip(ray_study.rows) == _strip(serial.rows)


def test_plan_rejects_a_duration_longer_than_the_scenario():
    with pytest.raises(ValueError, match=r"duration must be in \(0, 20\] s for scenario 'curve-single'"):
        plan(["curve-single"], 1, duration=100.0)
    with pytest.raises(ValueError, match="duration must be in"):
        plan(["curve-single"], 1, duration=0.0)


def _fake_rows(monkeypatch):
    def run(task):
        return {"scenario": task.name, "variant": task.variant, "seed": task.seed, "sim_s": montecarlo.task_duration(task),
                "gospa_mean": 0.1 * task.seed}

    monkeypatch.setattr(montecarlo, "run_task", run)


@pytest.mark.parametrize("written", [False, True])
def test_runs_file_counts_a_row_only_once_the_file_has_it(tmp_path, monkeypatch, written):
    tasks = plan(["curve-single"], 3, duration=0.5)
    runs = RunsFile(tmp_path / "runs.csv", tasks)
    row = {"scenario": "curve-single", "variant": "curvilinear-fused", "sim_s": 0.5, "gospa_mean": 1.0}
    runs.add(0, dict(row, seed=0))
    real = montecarlo.write_runs

    def interrupted(rows, path):
        if written:
            real(rows, path)
        raise KeyboardInterrupt

    monkeypatch.setattr(montecarlo, "write_runs", interrupted)
    with pytest.raises(KeyboardInterrupt):
        runs.add(1, dict(row, seed=1))
    on_disk = [r["seed"] for r in read_runs(runs.path)]
    assert on_disk == ([0, 1] if written else [0])
    assert [i for i, r in enumerate(runs.rows) if r is not None] == on_disk
    assert runs.pending == [i for i in range(3) if i not in on_disk]


def test_an_interrupted_on_row_does_not_count_its_run(monkeypatch):
    _fake_rows(monkeypatch)
    tasks = plan(["curve-single"], 4, duration=0.5)
    seen = []

    def on_row(i, row):
        if len(seen) == 2:
            raise KeyboardInterrupt
        seen.append(i)

    with pytest.raises(StudyInterrupted) as info:
        run_study(tasks, on_row=on_row)
    assert info.value.finished == 2 and [r is not None for r in info.value.rows] == [True, True, False, False]
    assert "interrupted after 2 of 4 runs" in str(info.value)


def test_write_runs_leaves_the_old_file_when_interrupted(tmp_path, monkeypatch):
    path = tmp_path / "runs.csv"
    rows = [{"scenario": "a", "variant": "v", "seed": i, "sim_s": 1.0, "x": float(i)} for i in range(3)]
    montecarlo.write_runs(rows[:1], path)

    def replace(src, dst):
        raise KeyboardInterrupt

    monkeypatch.setattr(montecarlo.os, "replace", replace)
    with pytest.raises(KeyboardInterrupt):
        montecarlo.write_runs(rows, path)
    monkeypatch.undo()
    assert [r["seed"] for r in read_runs(path)] == [0] and sorted(p.name for p in tmp_path.iterdir()) == ["runs.csv"]


def test_a_scenario_on_a_lane_map_runs_in_a_study():
    """A study reads the scenario file itself: the lane map's path, relative to the file, resolves there
    too (the task carries it absolute, so a worker anywhere finds the map)."""
    pytest.importorskip("commonroad")
    from pathlib import Path

    from sim.studies.montecarlo import plan, run_task

    path = Path(__file__).resolve().parents[1] / "scenarios" / "maps" / "freeway-us101.toml"
    tasks = plan([path], 1, duration=1.0)
    assert Path(tasks[0].data["road"]["map"]).is_absolute()
    row = run_task(tasks[0])
    assert row["scenario"] == "freeway-us101" and row["frames"] > 5
