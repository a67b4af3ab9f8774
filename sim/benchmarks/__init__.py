"""Micro-benchmarks run by ``eot bench TARGET``.

Each module in this package is one target named after the module. It defines
``run(args: argparse.Namespace) -> dict`` returning the measured numbers (JSON-serialisable) and,
optionally, ``add_arguments(parser)`` for its own options. Benchmarks measure speed; tests never assert
wall-clock time.
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
