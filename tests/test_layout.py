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
    assert set(filter(None, third.split(","))) <= allowed_transitive, f"tracker imports third-party: {third}"


def test_scenarios_ship_inside_the_package():
    """``sim/scenarios`` links to the repository's ``scenarios/`` (the one source), and pyproject makes it
    package data, so a wheel carries the files (.ci/run installs one and runs ``eot`` elsewhere)."""
    import tomllib
    from pathlib import Path

    from sim.scenario import SCENARIO_DIR

    root = Path(__file__).resolve().parents[1]
    link = root / "sim" / "scenarios"
    assert link.is_symlink() and link.resolve() == (root / "scenarios").resolve()
    assert SCENARIO_DIR.resolve() == (root / "scenarios").resolve()
    assert (SCENARIO_DIR / "curvy-multi.toml").is_file() and (SCENARIO_DIR / "standard.toml").is_file()
    with open(root / "pyproject.toml", "rb") as fh:
        config = tomllib.load(fh)["tool"]["setuptools"]
    assert "scenarios/*.toml" in config["package-data"]["sim"]
    assert "sim*" in config["packages"]["find"]["include"]
