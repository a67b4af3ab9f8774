"""``eot bench``: the whole-suite run writes a complete bench.json, the Stone Soup comparison, the scene.

Speed is never asserted here (docs/architecture.md): only that every number exists, is finite and positive, and
that the scenes are what they claim (every car in view). The quick run takes a few seconds.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import sys
from pathlib import Path

import numpy as np
import pytest

from sim.benchmarks._machine import one_core
from sim.benchmarks._suite import (
    SECTIONS,
    Settings,
    mc_worker_counts,
    stonesoup_section,
)
from sim.benchmarks._table import format_table
from sim.benchmarks._tracking import in_view, sensor_frames
from sim.benchmarks._traffic import MIN_GAP, layout
from sim.cli import main
from tracker.tracker import STAGES

HAS_STONESOUP = True
try:
    import stonesoup  # noqa: F401
except ImportError:
    HAS_STONESOUP = False


def _numbers(value, path="result"):
    """Every int/float leaf of a JSON value with its path (bools and strings left out)."""
    if isinstance(value, dict):
        for k, v in value.items():
            yield from _numbers(v, f"{path}.{k}")
    elif isinstance(value, list):
        for i, v in enumerate(value):
            yield from _numbers(v, f"{path}[{i}]")
    elif isinstance(value, (int, float)) and not isinstance(value, bool):
        yield path, value


def _positive(value) -> bool:
    return isinstance(value, (int, float)) and math.isfinite(value) and value > 0


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench") / "sub" / "bench.json"
    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer):
        status = main(["bench", "--quick", "--quiet", "--out", str(out)])
    return status, out, buffer.getvalue()


def test_quick_run_writes_every_section(quick):
    status, out, printed = quick
    assert status == 0
    result = json.loads(out.read_text(encoding="utf-8"))
    for key in (*SECTIONS, "machine", "memory", "settings", "command", "wall_s", "section_wall_s"):
        assert key in result, key
    assert result["quick"] is True
    assert result["command"].startswith("eot bench --quick")
    assert set(result["section_wall_s"]) == set(SECTIONS)
    assert f"wrote {out}" in printed
    assert "tracker ms per frame" in printed and "Monte Carlo curvy-multi" in printed and "vlp16 scan" in printed and "os1-128 scan" in printed


def test_quick_run_numbers_are_finite(quick):
    result = json.loads(quick[1].read_text(encoding="utf-8"))
    leaves = list(_numbers(result))
    assert len(leaves) > 50
    bad = [(p, v) for p, v in leaves if not math.isfinite(v)]
    assert not bad


def test_quick_run_tracker_rows(quick):
    result = json.loads(quick[1].read_text(encoding="utf-8"))
    rows = result["tracker"]["results"]
    assert list(rows) == ["curvilinear-fused", "curvilinear-lidar"]
    assert result["kernels"]["warm_up_s"] >= 0.0
    for variant, by_count in rows.items():
        assert list(by_count) == [str(c) for c in Settings.make(True).tracker_counts]
        for count, row in by_count.items():
            assert _positive(row["ms_median"]) and _positive(row["ms_p95"]), (variant, count)
            assert row["ms_p95"] >= row["ms_median"]
            assert row["frames_timed"] == 10
            assert row["in_view_mean"] == int(count)  # the scene keeps every car in view
            assert row["lanes"] == 4
            # where the frame goes: every stage of Tracker.step, inside the step's own time
            assert list(row["stage_ms"]) == list(STAGES)
            assert all(ms >= 0.0 for ms in row["stage_ms"].values()) and row["stage_ms"]["update"] > 0.0
            assert sum(row["stage_ms"].values()) <= row["ms_mean"] + 1e-3
    assert "where a frame goes (curvilinear-fused" in quick[2]


def test_quick_run_other_sections(quick):
    result = json.loads(quick[1].read_text(encoding="utf-8"))
    assert _positive(result["lidar"]["scan_ms"]) and result["lidar"]["rays"] == 1800
    assert list(result["lidar3d"]) == ["vlp16", "vlp32c", "hdl64e", "os1-128", "rig"]
    rays = {"vlp16": 16 * 1800, "vlp32c": 32 * 1800, "hdl64e": 64 * 2000, "os1-128": 128 * 1024}
    rays["rig"] = rays["vlp32c"] + rays["os1-128"]
    rig = result["lidar3d"]["rig"]
    assert rig["model"] == "vlp32c+os1-128" and rig["scene"]["points"] > 100_000  # the merged cloud in E
    for name, row in result["lidar3d"].items():
        assert row["model"] == (name if name != "rig" else "vlp32c+os1-128") and row["scene"]["rays"] == rays[name]
        assert row["scene"]["ground_points"] > 1000 and row["scene"]["vehicle_points"] > 100
        assert _positive(row["scan"]["median_ms"]) and _positive(row["preprocess"]["median_ms"])
        assert _positive(row["tracker_step"]["median_ms"]) and row["tracker_step"]["tracks"] >= 5
        assert all(0.9 <= v <= 1.0 for v in row["ground_removal"].values()), (name, row["ground_removal"])
        pw = row["patchworkpp"]  # Patchwork++ beside ours on the same cloud (the test extra installs it)
        assert pw.get("per_lidar", False) == (name == "rig")  # on a rig: each lidar's own points, its own height
        assert _positive(pw["median_ms"]) and all(0.5 <= pw[k] <= 1.0 for k in ("recall", "precision", "vehicle_points_kept"))
    assert set(result["world"]) == {"curvy-multi", "dense-highway"}
    assert all(_positive(w["ms_per_simulated_s"]) for w in result["world"].values())
    e2e = result["end_to_end"]
    assert set(e2e) == {"curvy-multi", "dense-highway"}
    for row in e2e.values():
        assert _positive(row["sim_s_per_wall_s"]) and row["simulated_s"] == 1.0 and row["frames"] == 11
        assert _positive(row["first_sim_s_per_wall_s"]) and row["repeats"] == 1
        assert 0 < row["tracker_share"] < 1
    workers = result["montecarlo"]["workers"]
    assert list(workers)[:2] == ["1", "2"]
    for row in workers.values():
        assert _positive(row["runs_per_min"]) and _positive(row["sim_s_per_wall_s"])
    assert workers["2"]["runs"] == 2
    assert _positive(result["env"]["tracks"]["steps_per_s"]) and _positive(result["env"]["truth"]["steps_per_s"])
    assert _positive(result["memory"]["self_peak_rss_mb"])
    machine = result["machine"]
    assert machine["cores"] == os.cpu_count() and machine["cpu_model"]
    assert machine["python"] and machine["numpy"] == np.__version__ and machine["scipy"]
    if HAS_STONESOUP:
        ss = result["stonesoup"]
        assert ss["targets"] == 10 and ss["frames"] == 10
        assert all(_positive(x) for x in ss["ratio_stonesoup_over_ours"].values())
    else:
        assert 'pip install -e ".[baselines]"' in result["stonesoup"]["skipped"]


def test_table_reports_a_skipped_comparison(quick):
    result = json.loads(quick[1].read_text(encoding="utf-8"))
    result["stonesoup"] = {"skipped": "no Stone Soup here"}
    assert "Stone Soup comparison skipped: no Stone Soup here" in format_table(result)


@pytest.mark.skipif(not HAS_STONESOUP, reason="Stone Soup (extra 'baselines') is not installed")
def test_compare_stonesoup_prints_the_ratio(tmp_path, capsys):
    out = tmp_path / "tracker.json"
    status = main(["bench", "tracker", "--targets", "1", "--frames", "3", "--variants", "curvilinear-fused",
                   "--compare-stonesoup", "--stonesoup-frames", "5", "--json", str(out)])
    assert status == 0
    printed = capsys.readouterr().out
    assert "Stone Soup / ours =" in printed and "10 point targets, 5 frames" in printed
    ss = json.loads(out.read_text(encoding="utf-8"))["stonesoup"]
    assert ss["targets"] == 10 and ss["frames"] == 5 and ss["stonesoup"]["in_view_mean"] == 10
    for variant, ratio in ss["ratio_stonesoup_over_ours"].items():
        assert _positive(ratio)
        assert ratio == pytest.approx(ss["stonesoup"]["ms_median"] / ss["ours"][variant]["ms_median"], rel=0.01)


@pytest.mark.skipif(not HAS_STONESOUP, reason="Stone Soup (extra 'baselines') is not installed")
def test_repeated_timings_keep_each_rows_fastest_round(tmp_path):
    """``--repeat 2``: every tracker row and the Stone Soup comparison's rows are the fastest of two
    rounds (``best_of``), with both rounds' medians beside them, and the ratio is of the fastest ones."""
    out = tmp_path / "tracker.json"
    status = main(["bench", "tracker", "--targets", "1", "5", "--frames", "3", "--variants", "curvilinear-fused",
                   "--repeat", "2", "--compare-stonesoup", "--stonesoup-frames", "4",
                   "--json", str(out)])
    assert status == 0
    result = json.loads(out.read_text(encoding="utf-8"))
    assert result["repeat"] == 2
    for row in result["results"]["curvilinear-fused"].values():
        assert row["rounds"] == 2 and len(row["ms_median_rounds"]) == 2
        assert row["ms_median"] == min(row["ms_median_rounds"])
    ss = result["stonesoup"]
    for row in (ss["stonesoup"], *ss["ours"].values()):
        assert row["rounds"] == 2 and row["ms_median"] == min(row["ms_median_rounds"])
    for variant, ratio in ss["ratio_stonesoup_over_ours"].items():
        assert ratio == pytest.approx(ss["stonesoup"]["ms_median"] / ss["ours"][variant]["ms_median"], rel=0.01)
    with pytest.raises(ValueError, match="repeat"):
        from sim.benchmarks.tracker import measure

        measure([1], ["curvilinear-fused"], 2, repeat=0)


def test_compare_stonesoup_without_stonesoup_exits_2(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "stonesoup", None)  # `import stonesoup` raises ImportError
    status = main(["bench", "tracker", "--targets", "1", "--frames", "2", "--compare-stonesoup"])
    captured = capsys.readouterr()
    assert status == 2
    assert captured.out == ""  # nothing measured before the check
    assert 'pip install -e ".[baselines]"' in captured.err and "Traceback" not in captured.err
    assert "skipped" in stonesoup_section(Settings.make(True))


def test_unknown_section_is_a_usage_error(capsys):
    assert main(["bench", "--only", "tracker,nope"]) == 2
    assert "nope" in capsys.readouterr().err


def test_scene_keeps_every_car_in_view_and_apart():
    scene, frames = sensor_frames(20, 3)
    assert len(scene) == 20 and scene.lanes == 4
    assert np.all(in_view(frames) == 20)
    for lane in np.unique(scene.lane):
        s = np.sort(scene.s0[scene.lane == lane])
        gaps = np.diff(np.concatenate([s, s[:1] + scene.road.length]))
        assert gaps.min() >= MIN_GAP
    wide = layout(20, lanes=10)
    assert wide.lanes == 10 and len(wide) == 20
    with pytest.raises(ValueError, match="do not fit"):
        layout(60, lanes=2)


def test_mc_worker_counts():
    assert mc_worker_counts(1) == [1, 2]
    assert mc_worker_counts(2) == [1, 2]
    assert mc_worker_counts(6) == [1, 2, 4, 6]
    assert mc_worker_counts(16) == [1, 2, 4, 8, 16]


@pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="no CPU affinity on this platform")
def test_one_core_pins_and_restores():
    before = os.sched_getaffinity(0)
    with one_core() as cpu:
        assert os.sched_getaffinity(0) == {cpu}
    assert os.sched_getaffinity(0) == before
    with one_core(False) as cpu:
        assert cpu is None and os.sched_getaffinity(0) == before


def test_ground_removal_study_scores_ours_and_patchwork_on_the_same_clouds(tmp_path):
    """``eot bench ground``'s study on a one-scenario suite, one seed, the VLP-16 (every 50th of 201 scans: 5): both methods scored
    against the simulator's labels of the same scans; ours keeps the vehicles and removes the ground
    (the real-lidar targets: >= 99.5 % and >= 99 %)."""
    from sim.benchmarks.ground import (
        GROUND_REMOVED_TARGET,
        VEHICLE_KEPT_TARGET,
        bench_ground,
    )

    scenarios = Path(__file__).resolve().parents[1] / "scenarios"
    suite = tmp_path / "one.toml"
    suite.write_text(f'name = "one"\ndescription = "curve-single"\nscenarios = ["{scenarios / "curve-single.toml"}"]\n')
    result = bench_ground(["vlp16"], str(suite), seeds=1, every=50, verbose=False)
    assert result["scenarios"] == ["curve-single"] and list(result["models"]) == ["vlp16"]
    ours, theirs = result["models"]["vlp16"]["ours"], result["models"]["vlp16"]["patchworkpp"]
    assert ours["scans"] == theirs["scans"] == 5 and ours["ground_points"] == theirs["ground_points"] > 1000
    assert ours["vehicle_kept"] >= VEHICLE_KEPT_TARGET and ours["ground_removed"] >= GROUND_REMOVED_TARGET
    assert all(0.0 <= theirs[k] <= 1.0 for k in ("ground_removed", "precision", "vehicle_kept", "roadside_kept"))
    with pytest.raises(ValueError, match="models must be some of"):
        bench_ground(["vlp64"], str(suite))
