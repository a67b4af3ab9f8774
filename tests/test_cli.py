"""The ``eot`` command: run writes every file with sane values (subprocess), Monte Carlo, the demo's
defaults, and one-line errors with exit status 2 for unknown scenarios and variants."""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from sim import cli

DESIGN_KEYS = (
    "frames", "gospa_mean", "gospa_localization_mean", "gospa_missed_mean", "gospa_false_mean",
    "cardinality_error_mean", "pos_rmse_m", "yaw_rmse_deg", "length_rmse_m", "width_rmse_m",
    "speed_rmse_mps", "id_switches", "tracker_ms_median", "tracker_ms_p95",
)  # fmt: skip


def test_eot_run_writes_every_file(tmp_path):
    out = tmp_path / "run"
    env = dict(os.environ, MPLBACKEND="Agg")
    proc = subprocess.run(
        [sys.executable, "-m", "sim.cli", "run", "curve-single", "--duration", "2", "--seed", "1", "--out", str(out),
         "--gif", "--no-roadside", "--quiet"],
        capture_output=True, text=True, env=env, timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    # 12 files, plus tracker_events.csv from the tracker's last_events
    assert "GOSPA mean (m)" in proc.stdout and "wrote 13 files" in proc.stdout
    assert (out / "tracker_events.csv").is_file()
    assert "diagnostics: losses and label changes by cause" in proc.stdout
    metrics = json.loads((out / "metrics.json").read_text())
    for key in DESIGN_KEYS:
        assert key in metrics, key
    assert metrics["scenario"] == "curve-single" and metrics["seed"] == 1 and metrics["variant"] == "curvilinear-fused"
    assert metrics["frames"] == 21 and metrics["truth_count_mean"] == 1.0
    assert 0.0 <= metrics["gospa_mean"] < 5.0 and metrics["pos_rmse_m"] < 1.5
    parts = sum(metrics[k] for k in ("gospa_localization_mean", "gospa_missed_mean", "gospa_false_mean"))
    assert metrics["gospa_mean"] ** 2 <= parts + 1e-9  # mean of sqrt <= sqrt of mean
    with open(out / "timeseries.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 21 and float(rows[-1]["t"]) == pytest.approx(2.0)
    for row in rows:
        total = float(row["gospa_localization"]) + float(row["gospa_missed"]) + float(row["gospa_false"])
        assert float(row["gospa"]) == pytest.approx(total**0.5, abs=1e-12)
        assert row["n_truth"] == "1"
    with open(out / "tracks.csv", newline="") as fh:
        tracks = list(csv.DictReader(fh))
    assert tracks and {"label", "s", "n", "x", "y", "psi", "truth_id", "s_rel"} <= set(tracks[0])
    assert sum(r["truth_id"] == "1" for r in tracks) >= 15  # the car is tracked most of the time
    with open(out / "truth.csv", newline="") as fh:
        assert len(list(csv.DictReader(fh))) == 21
    for name in ("gospa.png", "gospa_visible.png", "birdseye.png", "targets.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
    assert (out / "run.gif").read_bytes()[:6] in (b"GIF89a", b"GIF87a")
    # the diagnostics of `eot inspect` come with every run
    assert (out / "events.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with open(out / "events.csv", newline="") as fh:
        events = list(csv.DictReader(fh))
    assert list(events[0]) == ["t", "truth_id", "label", "event", "cause", "detail"]
    assert {"entered", "first_lidar", "confirmed"} <= {e["event"] for e in events}
    assert sum(e["event"] == "label_change" for e in events) == metrics["id_switches"]
    assert (out / "worst_intervals.csv").exists()


def _main(capsys, *argv):
    code = cli.main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_unknown_scenario_is_one_line_with_choices(capsys):
    code, out, err = _main(capsys, "run", "no-such-scenario")
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and "curvy-multi" in err and "no-such-scenario" in err
    code, _, err = _main(capsys, "montecarlo", "no-such-suite", "--runs", "1", "--out", "x")
    assert code == 2 and err.count("\n") == 1 and "suite standard" in err


def test_unknown_variant_is_one_line_with_choices(capsys):
    code, _, err = _main(capsys, "run", "curve-single", "--variant", "polar")
    assert code == 2 and err.count("\n") == 1
    assert "curvilinear-fused, curvilinear-lidar, cartesian-fused, paper-motion" in err
    code, _, err = _main(capsys, "montecarlo", "curve-single", "--runs", "1", "--out", "x", "--variant", "curvilinear-fused,bad")
    assert code == 2 and "'bad'" in err


def test_a_suite_is_not_one_scenario(capsys):
    code, _, err = _main(capsys, "run", "standard")
    assert code == 2 and "suite" in err


def test_invalid_scenario_file_is_exit_2(capsys, tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "bad"\ndescription = "x"\nduration = -1.0\n')
    code, _, err = _main(capsys, "run", str(bad))
    assert code == 2 and "duration" in err and err.count("\n") == 1


def test_ray_backend_without_ray(capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # as if not installed
    code, _, err = _main(capsys, "montecarlo", "curve-single", "--runs", "1", "--out", "x", "--backend", "ray")
    assert code == 2 and "frenet-eot[distributed]" in err


def test_montecarlo_writes_runs_and_summary(capsys, tmp_path):
    code, out, _ = _main(capsys, "montecarlo", "curve-single", "--runs", "2", "--duration", "0.5", "--out",
                         str(tmp_path), "--variant", "curvilinear-fused", "--variant", "curvilinear-lidar", "--quiet")
    assert code == 0
    assert "simulated s per wall s per worker" in out and "curvilinear-lidar" in out
    with open(tmp_path / "runs.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [(r["variant"], r["seed"]) for r in rows] == [
        ("curvilinear-fused", "0"), ("curvilinear-fused", "1"), ("curvilinear-lidar", "0"), ("curvilinear-lidar", "1")]
    assert all(r["frames"] == "6" for r in rows)
    doc = json.loads((tmp_path / "summary.json").read_text())
    gospa = [s for s in doc["summary"] if s["metric"] == "gospa_mean"]
    assert len(gospa) == 2 and all(s["n"] == 2 for s in gospa)


def test_demo_runs_curvy_multi_into_the_output_folder(monkeypatch):
    calls = []
    monkeypatch.setattr(cli, "_run_and_write", lambda scenario, **kw: calls.append((scenario, kw)) or 0)
    assert cli.main(["demo"]) == 0
    scenario, kw = calls[0]
    assert scenario == "curvy-multi" and kw["out"] == "eot-output/demo" and kw["gif"] is True
    assert kw["variant"] == "curvilinear-fused" and kw["seed"] == 0 and kw["duration"] is None


def test_compare_usage_errors_are_one_line(capsys, tmp_path):
    code, out, err = _main(capsys, "compare", "--variants", "no-such-variant", "--out", str(tmp_path))
    assert code == 2 and out == "" and "unknown variant" in err and "stonesoup-gmphd" in err
    code, out, err = _main(capsys, "compare", "--runs", "0", "--out", str(tmp_path))
    assert code == 2 and "--runs must be >= 1" in err
    code, out, err = _main(capsys, "compare", "--report-only", "--out", str(tmp_path))
    assert code == 2 and "runs.csv is missing" in err


def test_scenarios_still_lists(capsys):
    code, out, _ = _main(capsys, "scenarios")
    assert code == 0 and "curvy-multi" in out and "suite standard" in out


def test_run_default_output_folder(monkeypatch):
    calls = []
    monkeypatch.setattr(cli, "_run_and_write", lambda scenario, **kw: calls.append((scenario, kw)) or 0)
    assert cli.main(["run", "cut-in", "--seed", "4", "--variant", "paper-motion"]) == 0
    scenario, kw = calls[0]
    assert Path(scenario).name == "cut-in.toml" and kw["out"] == "eot-output/cut-in-paper-motion-seed4"


def test_default_outputs_are_untracked():
    """Every command's default output lies under ``eot-output/``, which git ignores: running the README's
    commands in a checkout never modifies the committed reference outputs in ``results/``."""
    parser = cli.build_parser()
    defaults = {}
    for action in parser._subparsers._group_actions:
        for name, sub in action.choices.items():
            for a in sub._actions:
                if "--out" in a.option_strings and isinstance(a.default, str):
                    defaults[name] = a.default
    assert {"demo", "closed-loop", "compare", "bench"} <= set(defaults), defaults
    for name, default in defaults.items():
        assert Path(default).parts[0] == cli.OUTPUT_ROOT, (name, default)
    ignored = (Path(__file__).parents[1] / ".gitignore").read_text().split()
    assert f"/{cli.OUTPUT_ROOT}/" in ignored


def test_progress_bar_lines():
    import io

    from sim.progress import NestedProgress, ProgressBar

    stream = io.StringIO()  # not a terminal: tqdm draws the first and the final state
    bar = ProgressBar(20, "runs", stream=stream)
    for i in range(1, 21):
        bar(i)
    bar.close()
    text = stream.getvalue()
    assert bar.done == 20 and "runs: 100%" in text and "20/20" in text
    quiet = io.StringIO()
    with ProgressBar(5, stream=quiet, enabled=False) as off:
        off(5)
    assert quiet.getvalue() == ""
    unknown = ProgressBar(0, "frames", stream=io.StringIO())
    unknown(3, 10)  # the runner gives the total with the first call
    assert unknown.total == 10 and unknown.done == 3
    log = io.StringIO()
    with NestedProgress({"a": 2, "b": 1}, "3 runs", stream=log) as bars:
        bars.done("a"), bars.done("b"), bars.done("a")
        assert bars.outer.done == 3 and bars.inner["a"].done == 2 and bars.inner["b"].done == 1
    assert "3/3" in log.getvalue() and "  a" not in log.getvalue()  # in a log only the outer bar


def test_run_and_montecarlo_with_the_vlp16_lidar(capsys, tmp_path):
    """--lidar-model vlp16: raw 3-D clouds through the tracker's ground removal; `eot run` writes the
    pipeline figure cloud.png and the ground-removal metrics; the Monte Carlo rows carry them."""
    code, out, _ = _main(capsys, "run", "curve-single", "--duration", "0.5", "--lidar-model", "vlp16",
                         "--out", str(tmp_path / "run"), "--quiet")
    assert code == 0 and "cloud.png" in out
    with Image.open(tmp_path / "run" / "cloud.png") as im:
        rgb = np.asarray(im.convert("RGB"))
    assert im.size[0] >= 1200 and rgb.std() > 10  # three panels, not blank
    metrics = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert metrics["cloud_ground_recall"] > 0.99 and metrics["cloud_vehicle_kept"] > 0.99
    code, out, _ = _main(capsys, "montecarlo", "curve-single", "--runs", "1", "--duration", "0.5", "--lidar-model", "vlp16",
                         "--out", str(tmp_path / "mc"), "--quiet")
    assert code == 0
    with open(tmp_path / "mc" / "runs.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert float(rows[0]["cloud_ground_recall"]) > 0.99
    with pytest.raises(SystemExit) as info:  # argparse's own usage error
        cli.main(["run", "curve-single", "--lidar-model", "hdl64"])
    assert info.value.code == 2 and "lidar model must be one of" in capsys.readouterr().err


def test_summary_table_shows_oncoming_vehicles_only_where_there_are_some():
    from sim.cli import summary_table

    base = {"frames": 10, "id_switches": 0}
    assert "oncoming" not in summary_table(base)
    assert "oncoming" not in summary_table({**base, "oncoming_matched_pairs": 0})
    text = summary_table({**base, "oncoming_matched_pairs": 40, "oncoming_yaw_rmse_deg": 0.61,
                          "oncoming_speed_rmse_mps": 0.14, "oncoming_id_switches": 0})
    row = next(line for line in text.splitlines() if line.startswith("oncoming"))
    assert "0.61" in row and "0.14" in row


def test_summary_table_splits_the_seen_position_by_whether_the_length_was_shown():
    from sim.cli import summary_table

    base = {"frames": 10, "yaw_rmse_deg": 0.4}
    assert "length shown" not in summary_table(base)  # a point tracker: no split
    text = summary_table({**base, "length_shown_share": 0.41, "pos_rmse_seen_length_shown_m": 0.114,
                          "pos_rmse_seen_length_unshown_m": 0.472})
    lines = text.splitlines()
    row = next(i for i, line in enumerate(lines) if "length shown / not shown" in line)
    assert "0.114 / 0.472 (0.41)" in lines[row] and lines[row + 1].startswith("yaw RMSE")
    assert "width, end shown" not in text
    text = summary_table({**base, "width_shown_share": 0.62, "width_rmse_seen_shown_m": 0.051,
                          "width_rmse_seen_unshown_m": 0.262, "id_switches": 1})
    lines = text.splitlines()
    row = next(i for i, line in enumerate(lines) if "width, end shown / not shown" in line)
    assert "0.051 / 0.262 (0.62)" in lines[row] and lines[row + 1].startswith("ID switches")


def test_road_draws_and_summarises_a_route_through_a_lane_map(tmp_path, capsys):
    """``eot road``: the route's road over the map (road.png) and its summary (road.json); a start off every
    lanelet and a malformed flag are one-line usage errors."""
    pytest.importorskip("commonroad")
    import json
    from pathlib import Path

    from sim import cli

    lane_map = Path(__file__).resolve().parent / "data" / "USA_US101-1_1_T-1.xml"
    assert cli.main(["road", str(lane_map), "--start", "0,0,-0.765", "--out", str(tmp_path)]) == 0
    summary = json.loads((tmp_path / "road.json").read_text())
    assert summary["lanes"] == 6 and not summary["two_way"] and summary["length_m"] > 50.0
    assert 18.0 < summary["width_min_m"] <= summary["width_max_m"] < 25.0  # six lanes of 3.2-3.9 m
    assert (tmp_path / "road.png").stat().st_size > 10_000
    assert cli.main(["road", str(lane_map), "--start", "5000,5000,0", "--out", str(tmp_path)]) == cli.USAGE_EXIT
    assert cli.main(["road", str(lane_map), "--start", "0,0", "--out", str(tmp_path)]) == cli.USAGE_EXIT
    err = capsys.readouterr().err.strip().splitlines()
    assert err[0].startswith("eot road: ") and "lies on no lanelet" in err[0]
    assert err[1] == "eot road: --start '0,0': expected 3 comma-separated numbers"
