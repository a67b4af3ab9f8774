"""Benchmarks run by ``eot bench TARGET``, and all of them by ``eot bench`` (no target).

Each public module in this package is one target named after the module. It defines
``run(args: argparse.Namespace) -> dict`` returning the measured numbers (JSON-serialisable) and,
optionally, ``add_arguments(parser)`` for its own options and ``summary(result) -> str | None`` for a
line printed after the JSON. Modules whose names start with ``_`` are helpers, not targets:
``_suite`` (``eot bench`` with no target: every section, ``results/bench.json`` and a table, see
``--quick``), ``_table`` (that table), ``_machine`` (machine, git state, peak memory, one-core
pinning), ``_traffic`` / ``_tracking`` (the tracker benchmark's all-in-view scene and timing),
``_stonesoup`` (Stone Soup's GM-PHD timed against ours), ``_timing``. Benchmarks measure speed; tests
never assert wall-clock time.

Commands::

    eot bench                                   # everything -> results/bench.json + a table
    eot bench --quick --out /tmp/bench.json     # the whole path in seconds
    eot bench tracker --compare-stonesoup       # ratio to Stone Soup's GM-PHD (extra 'baselines')
"""

from __future__ import annotations

import importlib
import pkgutil
from types import ModuleType


def targets() -> dict[str, ModuleType]:
    """The benchmark modules of this package, keyed by target name (module name, ``_`` -> ``-``)."""
    found = {}
    for info in pkgutil.iter_modules(__path__):
        if info.name.startswith("_"):
            continue
        found[info.name.replace("_", "-")] = importlib.import_module(f"{__name__}.{info.name}")
    return found
