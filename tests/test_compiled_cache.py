"""The kernels' on-disk cache is never stale: editing a kernel file recompiles the kernels of other
files that call it (``tracker.jit``), with no manual step.

The end-to-end test works on a copy of the ``tracker`` package in a temporary folder, with two new
kernel files (a caller and its callee in another file); each step runs in a new process, as a user's
next command would.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import tracker
from tracker.compiled import _cache

CALLEE = '''from tracker.jit import njit


@njit
def value():
    return {value}
'''
CALLER = '''from tracker.jit import njit
from tracker.compiled.probe_callee import value


@njit
def call():
    return value() + 1.0
'''
SCRIPT = '''from tracker.compiled.probe_caller import call
print(call(), sum(call.stats.cache_hits.values()), sum(call.stats.cache_misses.values()))
'''


def _run(root: Path) -> tuple[float, int, int]:
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "NUMBA_DISABLE_JIT")}
    env["PYTHONPATH"] = str(root)
    out = subprocess.run([sys.executable, "-c", SCRIPT], cwd=root, env=env, capture_output=True, text=True, check=True)
    result, hits, misses = out.stdout.split()
    return float(result), int(hits), int(misses)


def test_editing_a_callee_recompiles_its_callers(tmp_path):
    package = Path(tracker.__file__).parent
    shutil.copytree(package, tmp_path / "tracker", ignore=shutil.ignore_patterns("__pycache__"))
    kernels = tmp_path / "tracker" / "compiled"
    (kernels / "probe_callee.py").write_text(CALLEE.format(value="1.0"))
    (kernels / "probe_caller.py").write_text(CALLER)

    assert _run(tmp_path) == (2.0, 0, 1)  # compiled and cached
    assert _run(tmp_path) == (2.0, 1, 0)  # loaded from the cache
    (kernels / "probe_callee.py").write_text(CALLEE.format(value="5.0"))  # only the callee's file changes
    assert _run(tmp_path) == (6.0, 0, 1)  # the caller recompiled with the new callee (numba alone: 2.0)
    assert _run(tmp_path) == (6.0, 1, 0)


def test_stamp_covers_the_kernel_folder(tmp_path, monkeypatch):
    folder = tmp_path / "kernels"
    folder.mkdir()
    (folder / "a.py").write_text("A = 1\n")
    (folder / "b.py").write_text("B = 1\n")
    outside = tmp_path / "outside.py"
    outside.write_text("C = 1\n")
    monkeypatch.setattr(_cache, "KERNEL_DIR", folder)
    monkeypatch.setattr(_cache, "_MEMO", {})
    first = {f: _cache.stamp(str(f)) for f in (folder / "a.py", outside)}
    assert [p.name for p in _cache.covered_files(str(outside))] == ["a.py", "b.py", "outside.py"]
    (folder / "b.py").write_text("B = 2  # edited\n")
    second = {f: _cache.stamp(str(f)) for f in first}
    assert all(first[f] != second[f] for f in first)  # an edit of b.py re-keys a.py's and outside's kernels
    assert _cache.stamp(str(outside)) == second[outside]  # deterministic


@pytest.mark.parametrize("name", ["wrap_angle", "corner_offset"])
def test_the_tracker_kernels_use_the_package_stamp(name):
    from tracker.compiled import geometry

    locator = getattr(geometry, name)._cache._impl.locator
    assert type(locator).__name__.startswith("PackageStamp")
    assert locator.get_source_stamp() == _cache.stamp(geometry.__file__)
