"""Tests of ``tracker.warmup.warm_up``'s report of a cold cache and of its split into shares that
compile in parallel: with a kernel missing from the cache it says so before compiling and says how long
it took, and starts the helper process; with every kernel cached it says nothing (in this process and in
a new one); the shares reach disjoint kernels, so that the two processes do not compile the same one."""

from __future__ import annotations

import re
import subprocess
import sys

import pytest

from tracker import warmup


class FakeHelper:
    """Stands for the helper process (``subprocess.Popen``)."""

    def __init__(self) -> None:
        self.waited = False

    def wait(self, timeout=None) -> int:
        self.waited = True
        return 0

    def poll(self) -> int:
        return 0

    def kill(self) -> None:  # pragma: no cover - a helper that is still running when warm_up ends
        raise AssertionError("the helper was waited for")


def compile_something() -> None:
    """Compile a new function (never cached): a numba compile event, as a kernel missing from the cache."""
    import numba

    numba.njit(cache=False)(lambda x: x + 1)(1)


@pytest.fixture
def cold_warm_up(monkeypatch):
    """``warm_up`` as on a first call in this process, its shares replaced by ``shares`` (a dict of
    name -> function; the others do nothing), the helper by a ``FakeHelper``; returns ``run(shares,
    capture)`` giving the reported lines (with ``capture``; else they go to the default, stderr) and the
    helpers started."""
    def run(shares: dict, capture: bool = True) -> tuple[list[str], list[FakeHelper]]:
        for name in ("first_frame", "predict_share", "other_calls", "update_share", "scene"):
            monkeypatch.setattr(warmup, name, shares.get(name, lambda: None))
        monkeypatch.setattr(warmup, "_EXTRA_WARM_UPS", [])
        monkeypatch.setattr(warmup, "_WARM", False)
        helpers: list[FakeHelper] = []
        monkeypatch.setattr(warmup, "_start_helper", lambda: helpers.append(FakeHelper()) or helpers[-1])
        lines: list[str] = []
        previous = warmup.report_to(lines.append if capture else warmup._stderr_line)
        try:
            warmup.warm_up()
        finally:
            warmup.report_to(previous)
        return lines, helpers

    return run


def test_a_kernel_missing_from_the_cache_is_reported_before_and_after_compiling(cold_warm_up):
    lines, helpers = cold_warm_up({"first_frame": compile_something})
    assert len(lines) == 2
    assert lines[0].startswith("compiling the tracker's kernels once")
    assert f"about {warmup.COMPILE_ESTIMATE_S} s" in lines[0] and "cache" in lines[0]
    assert re.fullmatch(r"compiled the tracker's kernels in \d+ s", lines[1])
    assert len(helpers) == 1 and helpers[0].waited  # the helper compiled its share meanwhile


def test_every_kernel_cached_says_nothing_and_starts_no_helper(cold_warm_up):
    lines, helpers = cold_warm_up({})
    assert lines == [] and helpers == []


def test_a_compilation_after_the_helper_share_starts_no_helper(cold_warm_up):
    """Once this process has waited for the helper's share, a kernel still missing compiles here (and is
    reported), without a helper."""
    lines, helpers = cold_warm_up({"scene": compile_something})
    assert len(lines) == 2 and helpers == []


def test_the_report_goes_to_stderr_by_default(cold_warm_up, capsys):
    cold_warm_up({"first_frame": compile_something}, capture=False)
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.startswith("compiling the tracker's kernels once")
    assert "compiled the tracker's kernels in" in captured.err


def run_python(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)


def warm_every_kernel() -> None:
    """Compile (or load) every kernel in this process, the simulator's caster's included, so that the
    cache holds them all."""
    import sim.sensors.raycast  # noqa: F401 - registers the caster's warm-up

    warmup.warm_up()
    for function in warmup._EXTRA_WARM_UPS:
        function()


def test_a_process_with_every_kernel_cached_prints_nothing():
    warm_every_kernel()
    out = run_python("import sim.sensors.raycast\nfrom tracker.warmup import warm_up\nwarm_up()\n")
    assert out.returncode == 0, out.stderr
    assert out.stdout == "" and out.stderr == ""


def test_the_helper_process_runs_its_share():
    warm_every_kernel()  # the helper loads its kernels from the cache
    helper = warmup._start_helper()
    if helper is None:
        pytest.skip("one CPU: warm_up starts no helper")
    assert helper.wait(timeout=600) == 0


KERNELS = {  # the kernels that tell the shares apart
    "update": ["pairs.prepared_pairs_kernel", "pairs.update_pairs_kernel", "kalman.measurement_update_kernel",
               "structure.structure_kernel", "preparation.scanned_batch_kernel"],
    "other": ["clustering.cluster_points_kernel", "preprocess.road_filter_kernel", "reduction.reduce_kernel",
              "birth.road_births_kernel", "motion.ukf_predict_kernel", "detection.detection_kernel"],
}


def kernels_reached(share_code: str) -> dict[str, list[str]]:
    """Which of ``KERNELS`` a new process has compiled or loaded after running ``share_code``."""
    code = (
        "import importlib, json\n"
        f"{share_code}\n"
        f"kernels = {KERNELS!r}\n"
        "def reached(name):\n"
        "    module, kernel = name.split('.')\n"
        "    return bool(getattr(importlib.import_module('tracker.' + module), kernel).signatures)\n"
        "print(json.dumps({group: [k for k in names if reached(k)] for group, names in kernels.items()}))\n"
    )
    out = run_python(code)
    assert out.returncode == 0, out.stderr
    import json

    return json.loads(out.stdout.strip().splitlines()[-1])


def test_the_helper_share_and_this_process_share_reach_disjoint_kernels():
    warm_every_kernel()  # the new processes load the kernels from the cache
    helper = kernels_reached("import runpy\nrunpy.run_module('tracker.warmup', run_name='__main__')")
    assert helper["update"] == KERNELS["update"] and helper["other"] == []
    own = kernels_reached("from tracker import warmup\nwarmup.first_frame()\nwarmup.predict_share()\n"
                          "warmup.other_calls()")
    assert own["update"] == [] and own["other"] == KERNELS["other"]


#: The kernels the tracker calls from Python code (kernels called only inside other kernels compile, or
#: load from the cache, with their callers).
CALLED_FROM_PYTHON = [
    "preparation.prepare_kernel", "structure.structure_kernel", "centerline.curve_frame", "centerline.project_kernel",
    "motion.ukf_predict_kernel", "clustering.partition_points_kernel", "clustering.cluster_points_kernel",
    "clustering.ordered_clusters_kernel", "clustering.cluster_radar_kernel", "clustering.points_in_rectangles_kernel",
    "clustering.overlap_groups_kernel", "reduction.reduce_kernel", "centerline.rectangles_kernel",
    "centerline.sigma_rectangles_kernel", "detection.detection_kernel", "detection.occluded_kernel",
    "clustering.occluded_ends_kernel", "kalman.measurement_update_kernel", "extent.grow_extent_kernel",
    "extent.extent_rules_kernel", "pairs.update_pairs_kernel", "preparation.scanned_batch_kernel",
    "reduction.overlapping_pairs_kernel", "preprocess.road_filter_kernel", "centerline.seed_kernel",
    "centerline.node_seed_kernel",
    "gating.candidate_pairs_kernel", "pairs.prepared_pairs_kernel", "birth.road_births_kernel",
    "ukf.certainly_positive_definite", "reduction.inside_updated_kernel", "reduction.absorb_candidates_kernel",
    "reduction.overlapping_candidates_kernel", "extraction.report_centres_kernel", "cloud.wall_feet_kernel",
    "cloud.classify_kernel", "cloud.seen_over_kernel", "clustering.ray_links_kernel",
]


def test_warm_up_compiles_every_kernel_once_per_process():
    """After warm_up() every kernel the tracker calls from Python code has a compiled signature, and a
    tracked scene compiles none more (no compilation inside a timed frame)."""
    import importlib

    warmup.warm_up()
    kernels = []
    for name in CALLED_FROM_PYTHON:
        module, kernel = name.split(".")
        kernels.append(getattr(importlib.import_module(f"tracker.{module}"), kernel))
    before = [len(k.signatures) for k in kernels]
    missing = [name for name, n in zip(CALLED_FROM_PYTHON, before) if n == 0]
    assert not missing, f"kernels warm_up does not reach: {missing}"
    warmup.scene(15)
    assert [len(k.signatures) for k in kernels] == before
