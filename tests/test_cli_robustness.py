"""The command line under bad files and interruptions: malformed TOML, unknown keys, out-of-range values,
missing files and unwritable output folders are one line on stderr with exit status 2 (never a
traceback); an interrupted Monte Carlo leaves its finished rows in runs.csv and ``--resume`` completes
it."""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from sim import cli
from sim.studies import montecarlo
from sim.world.scenario import SCENARIO_DIR


def _main(capsys, *argv):
    code = cli.main([str(a) for a in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def _one_line(err: str) -> str:
    assert err.count("\n") == 1 and "Traceback" not in err, err
    return err


def _scenario(tmp_path: Path, text: str, name: str = "bad.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


GOOD = (SCENARIO_DIR / "curve-single.toml").read_text()


@pytest.mark.parametrize("command", ["run", "montecarlo", "soak"])
def test_malformed_toml(capsys, tmp_path, command):
    bad = _scenario(tmp_path, GOOD.replace("duration = ", "duration = [", 1))
    extra = ["--runs", "1", "--out", tmp_path / "mc"] if command == "montecarlo" else []
    code, out, err = _main(capsys, command, bad, *extra)
    assert code == 2 and out == ""
    assert "not valid TOML" in _one_line(err) and str(bad) in err


@pytest.mark.parametrize(
    ("old", "new", "needles"),
    [
        ("[ego]", "[ego]\nlaen = 1", ("ego.laen = 1: unknown key", "allowed keys here: lane, s, speed")),
        ("lane_width = 3.5", "lane_width = 9.0", ("road.lane_width = 9.0", "less than or equal to 5")),
        ("[ego]", "[faults]\nlidar_spikes = 2.0\n\n[ego]", ("faults.lidar_spikes = 2.0", "less than or equal to 1")),
    ],
)
def test_unknown_keys_and_out_of_range_values(capsys, tmp_path, old, new, needles):
    assert old in GOOD
    bad = _scenario(tmp_path, GOOD.replace(old, new, 1))
    for argv in (["run", bad], ["montecarlo", bad, "--runs", "2", "--out", tmp_path / "mc"]):
        code, _, err = _main(capsys, *argv)
        assert code == 2 and all(n in _one_line(err) for n in needles), err


def test_bad_override_fails_before_the_study_starts(capsys, tmp_path):
    bad = _scenario(tmp_path, GOOD + "\n[sensors.lidar]\nmax_rnage = 50.0\n")
    code, _, err = _main(capsys, "montecarlo", bad, "--runs", "2", "--workers", "2", "--out", tmp_path / "mc")
    assert code == 2 and "sensors.lidar.max_rnage = 50.0: unknown key" in _one_line(err)
    assert not (tmp_path / "mc" / "runs.csv").exists()


@pytest.mark.parametrize("option, needle", [
    ("measurement", "--set needs SECTION.FIELD=VALUE"),
    ("measurement.lidar_sigma=abc", "is not a value"),
    ("measurement.lidar_sigmaa=0.1", "tracker.measurement.lidar_sigmaa = 0.1: unknown key"),
])
def test_a_bad_tracker_setting_fails_before_the_study_starts(capsys, tmp_path, option, needle):
    code, _, err = _main(capsys, "montecarlo", "cut-in", "--runs", "1", "--set", option, "--out", tmp_path / "mc")
    assert code == 2 and needle in _one_line(err), err
    assert not (tmp_path / "mc" / "runs.csv").exists()


def test_tracker_settings_parse_toml_values():
    assert cli._tracker_settings(["measurement.grow_extent=false", "birth.classes=none", "reduction.prune_threshold=1e-3",
                                  "measurement.conversion=\"euler\""]) == {
        "measurement": {"grow_extent": False, "conversion": "euler"}, "birth": {"classes": None},
        "reduction": {"prune_threshold": 1e-3}}


def test_missing_files_and_folders(capsys, tmp_path):
    missing = tmp_path / "nope.toml"
    for argv in (["run", missing], ["montecarlo", missing, "--runs", "1", "--out", tmp_path / "mc"], ["soak", missing]):
        code, _, err = _main(capsys, *argv)
        assert code == 2 and f"no such file {missing}" in _one_line(err)
    code, _, err = _main(capsys, "scenarios", "--dir", tmp_path / "none")
    assert code == 2 and "no such folder" in _one_line(err)
    code, _, err = _main(capsys, "inspect", tmp_path / "none")
    assert code == 2
    _one_line(err)


def test_unwritable_output_folder(capsys, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("a file, not a folder")
    out = blocker / "out"  # cannot be created, even by root
    for argv in (["run", "curve-single", "--out", out, "--quiet"],
                 ["montecarlo", "curve-single", "--runs", "1", "--out", out, "--quiet"],
                 ["soak", "curve-single", "--duration", "1", "--out", out, "--quiet"]):
        code, stdout, err = _main(capsys, *argv)
        assert code == 2 and stdout == ""
        assert f"cannot write to the output folder {out}" in _one_line(err)


# -- interruption and --resume -----------------------------------------------------------------------
def _fake_run_task(calls: list, stop_after: int | None = None):
    def run(task: montecarlo.RunTask) -> dict:
        if stop_after is not None and len(calls) == stop_after:
            raise KeyboardInterrupt
        calls.append((task.name, task.variant, task.seed))
        return {"scenario": task.name, "variant": task.variant, "seed": task.seed,
                "sim_s": montecarlo.task_duration(task), "frames": 6, "gospa_mean": 0.25 * task.seed, "pos_rmse_m": None}

    return run


def test_interrupted_study_keeps_rows_and_resume_completes_it(capsys, tmp_path, monkeypatch):
    out = tmp_path / "mc"
    args = ["montecarlo", "curve-single", "--runs", "5", "--duration", "0.5", "--out", out, "--quiet",
            "--variant", "curvilinear-fused,curvilinear-lidar"]
    first: list = []
    monkeypatch.setattr(montecarlo, "run_task", _fake_run_task(first, stop_after=3))
    code, _, err = _main(capsys, *args)
    assert code == 2 and "interrupted: 3 of 10 runs finished" in _one_line(err) and "--resume" in err
    with open(out / "runs.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [(r["variant"], r["seed"]) for r in rows] == [("curvilinear-fused", "0"), ("curvilinear-fused", "1"),
                                                          ("curvilinear-fused", "2")]
    assert not (out / "summary.json").exists()
    second: list = []
    monkeypatch.setattr(montecarlo, "run_task", _fake_run_task(second))
    code, stdout, _ = _main(capsys, *args, "--resume")
    assert code == 0 and "resuming: 3 of 10 runs already in" in stdout
    assert second == [("curve-single", "curvilinear-fused", 3), ("curve-single", "curvilinear-fused", 4)] + [
        ("curve-single", "curvilinear-lidar", k) for k in range(5)]
    with open(out / "runs.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [(r["variant"], int(r["seed"])) for r in rows] == [(v, k) for v in ("curvilinear-fused", "curvilinear-lidar")
                                                              for k in range(5)]
    assert [float(r["gospa_mean"]) for r in rows[:5]] == [0.0, 0.25, 0.5, 0.75, 1.0] and rows[0]["pos_rmse_m"] == ""
    assert (out / "summary.json").exists()
    # a resume with other arguments would mix two studies
    code, _, err = _main(capsys, "montecarlo", "curve-single", "--runs", "5", "--duration", "0.4", "--out", out,
                         "--quiet", "--variant", "curvilinear-fused,curvilinear-lidar", "--resume")
    assert code == 2 and "simulated 0.5 s; this study asks for 0.4 s" in _one_line(err)
    code, _, err = _main(capsys, "montecarlo", "cut-in", "--runs", "1", "--out", out, "--quiet", "--resume")
    assert code == 2 and "has a run this study does not plan (scenario curve-single" in _one_line(err)


def test_ctrl_c_on_a_process_pool_leaves_rows_and_no_traceback(tmp_path):
    # 400 short runs: far more than finish between the first row and the signal (40 could all finish
    # first once the compiled kernels made runs fast, and the study then ended normally)
    # The child gets SIGINT's default disposition: a test run launched in the background of a
    # non-interactive shell inherits SIGINT ignored, Python then installs no KeyboardInterrupt handler,
    # and the study ran to its end (exit 0) whatever the signal
    out = tmp_path / "mc"
    env = dict(os.environ, MPLBACKEND="Agg")
    proc = subprocess.Popen(
        [sys.executable, "-m", "sim.cli", "montecarlo", "curve-single", "--runs", "400", "--duration", "0.3",
         "--no-roadside", "--workers", "2", "--out", str(out), "--quiet"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    deadline = time.monotonic() + 240
    rows: list = []
    while time.monotonic() < deadline and proc.poll() is None:
        if (out / "runs.csv").exists():
            with open(out / "runs.csv", newline="") as fh:
                rows = list(csv.DictReader(fh))
            if rows:
                break
        time.sleep(0.05)
    assert rows, "no run finished"
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 2, stderr
    assert "Traceback" not in stderr and stderr.count("\n") == 1 and "--resume" in stderr
    assert "of 400 runs finished" in stderr
    with open(out / "runs.csv", newline="") as fh:
        kept = list(csv.DictReader(fh))
    assert 1 <= len(kept) < 400 and all(r["frames"] == "4" for r in kept)
    done = int(stderr.split("interrupted: ")[1].split(" of")[0])
    assert done == len(kept)


def _rows_on_disk(out: Path) -> list[tuple[str, int]]:
    with open(out / "runs.csv", newline="") as fh:
        return [(r["variant"], int(r["seed"])) for r in csv.DictReader(fh)]


@pytest.mark.parametrize(("moment", "finished"), [
    ("before the write", 2),  # the third run's row exists, the file does not have it yet
    ("during the write", 2),  # the temporary file is written, not yet renamed onto runs.csv
    ("after the write", 3),  # runs.csv has the third row; the interrupt lands before add records it
    ("in the progress bar", 3),  # after add returned, in the CLI's own on_row
])
def test_ctrl_c_at_the_worst_moment_counts_only_the_rows_on_disk(capsys, tmp_path, monkeypatch, moment, finished):
    """The reported count is the rows in runs.csv wherever Ctrl-C lands around the third row's write,
    and --resume redoes exactly the runs the file lacks."""
    from sim.progress import NestedProgress

    out = tmp_path / "mc"
    args = ["montecarlo", "curve-single", "--runs", "5", "--duration", "0.5", "--out", out, "--quiet",
            "--variant", "curvilinear-fused,curvilinear-lidar"]
    real_write, real_replace, real_done = montecarlo.write_runs, os.replace, NestedProgress.done
    writes: list = []

    def write_runs(rows, path):
        writes.append(len(rows))
        if len(writes) == 3 and moment == "before the write":
            raise KeyboardInterrupt
        written = real_write(rows, path)
        if len(writes) == 3 and moment == "after the write":
            raise KeyboardInterrupt
        return written

    def replace(src, dst):
        if len(writes) == 3 and moment == "during the write":
            raise KeyboardInterrupt
        return real_replace(src, dst)

    def done(self, group):
        real_done(self, group)
        if len(writes) == 3 and moment == "in the progress bar":
            raise KeyboardInterrupt

    first: list = []
    monkeypatch.setattr(montecarlo, "run_task", _fake_run_task(first))
    monkeypatch.setattr(montecarlo, "write_runs", write_runs)
    monkeypatch.setattr(montecarlo.os, "replace", replace)
    monkeypatch.setattr(NestedProgress, "done", done)
    code, _, err = _main(capsys, *args)
    assert len(first) == 3 and writes == [1, 2, 3]  # three rows made, the third one's write interrupted
    assert code == 2 and f"interrupted: {finished} of 10 runs finished" in _one_line(err), err
    assert _rows_on_disk(out) == [("curvilinear-fused", k) for k in range(finished)]
    assert sorted(p.name for p in out.iterdir()) == ["runs.csv"]  # no temporary file left behind

    monkeypatch.setattr(montecarlo, "write_runs", real_write)
    monkeypatch.setattr(montecarlo.os, "replace", real_replace)
    monkeypatch.setattr(NestedProgress, "done", real_done)
    second: list = []
    monkeypatch.setattr(montecarlo, "run_task", _fake_run_task(second))
    code, stdout, _ = _main(capsys, *args, "--resume")
    assert code == 0 and f"resuming: {finished} of 10 runs already in" in stdout and f"; {10 - finished} to run" in stdout
    everything = [("curve-single", v, k) for v in ("curvilinear-fused", "curvilinear-lidar") for k in range(5)]
    assert second == everything[finished:]  # exactly the runs the file lacked, the unwritten third one included
    assert _rows_on_disk(out) == [(v, k) for _, v, k in everything]
