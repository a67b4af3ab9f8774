"""Benchmarks run by ``eot bench TARGET``, and all of them by ``eot bench`` (no target).

Each public module in this package is one target named after the module. It defines
``run(args: argparse.Namespace) -> dict`` returning the measured numbers (JSON-serialisable) and,
optionally, ``add_arguments(parser)`` for its own options and ``summary(result) -> str | None`` for a
line printed after the JSON. Benchmarks measure speed; tests never assert wall-clock time. Targets:

- ``road``: ``tracker.Road``'s to_frenet / to_cartesian, one point and 10^5 points;
- ``filter``: one UKF predict and update, and a batch of components x clusters;
- ``tracker``: the multi-target tracker's ms per frame at 1 to 50 targets in view (``--compare-stonesoup``);
- ``world``: traffic only, ms of wall time per simulated second;
- ``sensors``: lidar ray casting (the compiled caster vs pymunk), radar cycles and rig frames;
- ``lidar3d``: one scan per 3-D lidar model over a sloped road with traffic and clutter, and the tracker on it;
- ``ground``: per 3-D lidar model over a suite's runs, ground removal (ours and Patchwork++) against the labels;
- ``env``: ``eot/TrackedRoad-v0`` steps per second with the tracker in the loop;
- ``montecarlo``: simulated seconds per wall second per worker.

Modules whose names start with ``_`` are helpers, not targets:

- ``_suite``: ``eot bench`` with no target: every section, ``eot-output/bench.json`` and a table (``--quick``);
- ``_table``: that table;
- ``_machine``: the machine, the git state, peak memory, one-core pinning;
- ``_traffic``: the tracker benchmark's all-in-view scene;
- ``_tracking``: timing trackers frame by frame on that scene;
- ``_stonesoup``: Stone Soup's GM-PHD timed against ours;
- ``_patchwork``: Patchwork++ (``pypatchworkpp``), the reference ground segmentation of ``lidar3d`` and ``ground``;
- ``_timing``: the shared timing helper.

Commands::

    eot bench                                   # everything -> eot-output/bench.json + a table
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
