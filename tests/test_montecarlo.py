"""Monte Carlo: planning, the summary's confidence intervals, the output files, and backend agreement
(2 local workers = serial; a tiny Ray run = local, when Ray is installed)."""

from __future__ import annotations

import csv
import json
import math

import pytest

from sim.montecarlo import Study, plan, run_study, summarize_runs, write_study
from sim.runner import TIMING_KEYS
from sim.variants import UnknownVariantError


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
