"""The one dependency rule of DESIGN.md: ``tracker`` never imports ``sim``, highway-env, gymnasium,
pymunk or matplotlib (a user with real data needs only numpy and scipy)."""

from __future__ import annotations

import pkgutil
import subprocess
import sys

import tracker

FORBIDDEN = ("sim", "highway_env", "gymnasium", "pymunk", "matplotlib", "pygame")


def test_tracker_imports_only_numpy_and_scipy():
    modules = sorted(f"tracker.{m.name}" for m in pkgutil.iter_modules(tracker.__path__))
    assert "tracker.road" in modules
    code = (
        "import importlib, sys\n"
        f"for name in {modules!r}: importlib.import_module(name)\n"
        "tops = {m.split('.')[0] for m in sys.modules}\n"
        "third = sorted(t for t in tops if t not in sys.stdlib_module_names and not t.startswith('_')\n"
        "               and t not in ('tracker', 'numpy', 'scipy'))\n"
        f"bad = sorted(t for t in tops if t in {FORBIDDEN!r})\n"
        "print(','.join(bad) + '|' + ','.join(third))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    bad, third = out.stdout.strip().split("|")
    assert bad == "", f"tracker pulled in: {bad}"
    # anything else outside the standard library must be a dependency of numpy/scipy themselves
    allowed_transitive = {"packaging", "typing_extensions", "cython_runtime"}  # cython_runtime: made by scipy's extensions
    optional = {"numba", "llvmlite"}  # the `fast` extra, imported by tracker/compiled only (when installed)
    assert set(filter(None, third.split(","))) <= allowed_transitive | optional, f"tracker imports third-party: {third}"


def test_tracker_runs_without_numba():
    """numba is optional: with it hidden, ``tracker`` imports, runs its numpy code, and says so."""
    code = (
        "import sys; sys.modules['numba'] = None\n"
        "import numpy as np\n"
        "from tracker import Road, Tracker, TrackerConfig, Frame, EgoState, compiled\n"
        "assert not compiled.available() and not compiled.enabled()\n"
        "road = Road.from_curvature([(200.0, 0.0, 0.0)], lanes=2, lane_width=3.5)\n"
        "tr = Tracker(road, TrackerConfig())\n"
        "pts = np.column_stack([np.full(20, 15.0), np.linspace(-1.0, 1.0, 20)])\n"
        "for k in range(3): tr.step(Frame(t=0.1 * k, ego=EgoState(10.0, 0.0, 0.0, 10.0), lidar=pts))\n"
        "try:\n"
        "    compiled.require()\n"
        "except RuntimeError as e:\n"
        "    print('refused:', e)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert "pip install" in out.stdout


def test_scenarios_ship_inside_the_package():
    """``sim/scenarios`` links to the repository's ``scenarios/`` (the one source), and pyproject makes it
    package data, so a wheel carries the files (.ci/run installs one and runs ``eot`` elsewhere)."""
    import tomllib
    from pathlib import Path

    from sim.world.scenario import SCENARIO_DIR

    root = Path(__file__).resolve().parents[1]
    link = root / "sim" / "scenarios"
    assert link.is_symlink() and link.resolve() == (root / "scenarios").resolve()
    assert SCENARIO_DIR.resolve() == (root / "scenarios").resolve()
    assert (SCENARIO_DIR / "curvy-multi.toml").is_file() and (SCENARIO_DIR / "standard.toml").is_file()
    with open(root / "pyproject.toml", "rb") as fh:
        config = tomllib.load(fh)["tool"]["setuptools"]
    assert "scenarios/*.toml" in config["package-data"]["sim"]
    assert "sim*" in config["packages"]["find"]["include"]
