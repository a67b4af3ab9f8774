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
        f"bad = sorted(m for m in sys.modules if m.split('.')[0] in {FORBIDDEN!r})\n"
        "print(','.join(bad))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "", f"tracker pulled in: {out.stdout.strip()}"
