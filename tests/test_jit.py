"""``tracker.jit``: the kernels' on-disk cache is never stale. Editing a module recompiles the kernels of
every module that imports it (directly or through others), with no manual step, and leaves the others
cached.

The end-to-end test works on a copy of the ``tracker`` package in a temporary folder, with new kernel
modules (a caller, its callee in another module, and a module the caller does not import); each step runs
in a new process, as a user's next command would.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import tracker
from tracker import jit

CALLEE = '''from tracker.jit import njit


@njit
def value():
    return {value}
'''
CALLER = '''from tracker.jit import njit
from tracker.probe_callee import value


@njit
def call():
    return value() + 1.0
'''
SCRIPT = '''from tracker.probe_caller import call
print(call(), sum(call.stats.cache_hits.values()), sum(call.stats.cache_misses.values()))
'''


def _run(root: Path) -> tuple[float, int, int]:
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "NUMBA_DISABLE_JIT")}
    env["PYTHONPATH"] = str(root)
    out = subprocess.run([sys.executable, "-c", SCRIPT], cwd=root, env=env, capture_output=True, text=True, check=True)
    result, hits, misses = out.stdout.split()
    return float(result), int(hits), int(misses)


def test_editing_a_callee_recompiles_its_callers_only(tmp_path):
    package = Path(tracker.__file__).parent
    shutil.copytree(package, tmp_path / "tracker", ignore=shutil.ignore_patterns("__pycache__"))
    kernels = tmp_path / "tracker"
    (kernels / "probe_callee.py").write_text(CALLEE.format(value="1.0"))
    (kernels / "probe_caller.py").write_text(CALLER)
    (kernels / "probe_unrelated.py").write_text(CALLEE.format(value="7.0"))

    assert _run(tmp_path) == (2.0, 0, 1)  # compiled and cached
    assert _run(tmp_path) == (2.0, 1, 0)  # loaded from the cache
    (kernels / "probe_unrelated.py").write_text(CALLEE.format(value="8.0"))  # a module the caller does not import
    assert _run(tmp_path) == (2.0, 1, 0)  # still loaded from the cache
    (kernels / "probe_callee.py").write_text(CALLEE.format(value="5.0"))  # only the callee's module changes
    assert _run(tmp_path) == (6.0, 0, 1)  # the caller recompiled with the new callee (numba alone: 2.0)
    assert _run(tmp_path) == (6.0, 1, 0)


def _names(paths: list[str]) -> set[str]:
    return {str(Path(p).relative_to(Path(tracker.__file__).parents[1])) for p in paths}


def test_a_stamp_covers_the_modules_a_kernel_imports_transitively():
    import tracker.pairs

    covered = _names(jit.imported_files(tracker.pairs.__file__))
    # pairs calls the kernels of these modules (and they call geometry's and the UKF's)
    assert {"tracker/pairs.py", "tracker/centerline.py", "tracker/kalman.py", "tracker/extent.py",
            "tracker/structure.py", "tracker/preparation.py", "tracker/ukf.py", "tracker/geometry.py",
            "tracker/jit.py"} <= covered
    assert "tracker/tracker.py" not in covered and "tracker/warmup.py" not in covered
    assert _names(jit.imported_files(jit.__file__)) == {"tracker/jit.py"}


def test_a_stamp_changes_with_each_covered_file(monkeypatch):
    """Every file ``imported_files`` lists is part of the stamp: an edit of any one changes it."""
    import tracker.pairs

    target = tracker.pairs.__file__
    first = jit.stamp(target)
    assert jit.stamp(target) == first  # deterministic
    read = Path.read_bytes
    for edited in jit.imported_files(target):
        monkeypatch.setattr(Path, "read_bytes", lambda self, e=edited: read(self) + (b"#" if str(self) == e else b""))
        assert jit.stamp(target) != first, edited
    monkeypatch.setattr(Path, "read_bytes", read)
    assert jit.stamp(target) == first


def test_the_tracker_kernels_use_the_import_stamp():
    from tracker import geometry

    locator = geometry.wrap_angle._cache._impl.locator
    assert type(locator).__name__.startswith("ImportStamp")
    assert locator.get_source_stamp() == jit.stamp(geometry.__file__)
