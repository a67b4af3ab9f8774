"""Tests of ``tracker.warmup.warm_up``'s report of a cold cache and of its split into shares that
compile in parallel: with a kernel missing from the cache it says so before compiling and says how long
it took, and starts the helper process; with every kernel cached it says nothing (in this process and in
a new one); the shares reach disjoint kernels, so that the two processes do not compile the same one."""

from __future__ import annotations

import re
import subprocess
import sys

import pytest

from tracker import compiled

pytest.importorskip("numba")


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
    from tracker.compiled import _warm

    def run(shares: dict, capture: bool = True) -> tuple[list[str], list[FakeHelper]]:
        for name in ("first_frame", "predict_share", "other_calls", "update_share", "scene"):
            monkeypatch.setattr(_warm, name, shares.get(name, lambda: None))
        monkeypatch.setattr(compiled, "_EXTRA_WARM_UPS", [])
        monkeypatch.setattr(compiled, "_WARM", False)
        helpers: list[FakeHelper] = []
        monkeypatch.setattr(compiled, "_start_helper", lambda: helpers.append(FakeHelper()) or helpers[-1])
        lines: list[str] = []
        previous = compiled.report_to(lines.append if capture else compiled._stderr_line)
        try:
            assert compiled.warm_up()
        finally:
            compiled.report_to(previous)
        return lines, helpers

    return run


def test_a_kernel_missing_from_the_cache_is_reported_before_and_after_compiling(cold_warm_up):
    lines, helpers = cold_warm_up({"first_frame": compile_something})
    assert len(lines) == 2
    assert lines[0].startswith("compiling the tracker's kernels once")
    assert f"about {compiled.COMPILE_ESTIMATE_S} s" in lines[0] and "cache" in lines[0]
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

    compiled.warm_up()
    for function in compiled._EXTRA_WARM_UPS:
        function()


def test_a_process_with_every_kernel_cached_prints_nothing():
    warm_every_kernel()
    out = run_python("import sim.sensors.raycast\nfrom tracker import compiled\nassert compiled.warm_up()\n")
    assert out.returncode == 0, out.stderr
    assert out.stdout == "" and out.stderr == ""


def test_the_helper_process_runs_its_share():
    warm_every_kernel()  # the helper loads its kernels from the cache
    helper = compiled._start_helper()
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
        "    return bool(getattr(importlib.import_module('tracker.compiled.' + module), kernel).signatures)\n"
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
    own = kernels_reached("from tracker.compiled import _warm\n_warm.first_frame()\n_warm.predict_share()\n"
                          "_warm.other_calls()")
    assert own["update"] == [] and own["other"] == KERNELS["other"]
