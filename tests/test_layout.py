"""The layout rules of docs/architecture.md: ``tracker`` never imports ``sim``, highway-env, gymnasium,
pymunk or matplotlib (a user with real data needs only numpy and scipy); ``sim`` is grouped into parts
that import only the parts below them, and no module of ``sim`` is part of an import circle."""

from __future__ import annotations

import ast
import graphlib
import pkgutil
import subprocess
import sys
from pathlib import Path

import pytest

import tracker

ROOT = Path(__file__).resolve().parents[1]

FORBIDDEN = ("sim", "highway_env", "gymnasium", "pymunk", "matplotlib", "pygame")


def test_tracker_imports_only_numpy_and_scipy():
    modules = sorted(f"tracker.{m.name}" for m in pkgutil.iter_modules(tracker.__path__))
    assert "tracker.road" in modules
    code = (
        "import importlib, sys\n"
        "start = {m.split('.')[0] for m in sys.modules}\n"  # what the interpreter loaded itself (site, .pth files)
        f"for name in {modules!r}: importlib.import_module(name)\n"
        "tops = {m.split('.')[0] for m in sys.modules} - start\n"
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
    compiler = {"numba", "llvmlite", "yaml"}  # the kernels' compiler (tracker.jit); numba reads a YAML config if it can
    assert set(filter(None, third.split(","))) <= allowed_transitive | compiler, f"tracker imports third-party: {third}"


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


# -- sim: parts and import graph ----------------------------------------------------------------
#: Files directly in sim/: the public API (``__init__``) and the command line.
SIM_TOP_LEVEL = {"__init__.py", "cli.py", "progress.py"}
#: The parts of ``sim`` bottom-up: a module may import its own part and the parts of a lower rank,
#: never a higher one. ``sim`` is the package's public API (``sim/__init__.py``: ``load_scenario``,
#: ``run_scenario``, ``ENV_ID``), which ``sim.env`` reads ``ENV_ID`` from.
SIM_LAYERS = {
    "sim.world": 0,
    "sim.sensors": 1,
    "sim.baselines": 1,
    "sim.evaluation": 2,
    "sim": 3,
    "sim.env": 4,
    "sim.studies": 5,
    "sim.cli": 6,
    "sim.progress": 6,
    "sim.benchmarks": 6,
}


def sim_modules(package: str = "sim") -> dict[str, Path]:
    """Every module of ``package`` by dotted name (a package by its ``__init__.py``)."""
    found = {}
    for path in sorted((ROOT / package).rglob("*.py")):
        parts = path.relative_to(ROOT).with_suffix("").parts
        found[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return found


def sim_import_graph(package: str = "sim") -> dict[str, set[str]]:
    """Module -> the modules of ``package`` it imports: every import statement anywhere in the module
    (top level, in functions, under ``if TYPE_CHECKING:``); ``from x import y`` counts as importing
    ``x.y`` when that is a module, else ``x``; relative imports are resolved."""
    modules = sim_modules(package)
    graph: dict[str, set[str]] = {name: set() for name in modules}
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package.split(".")[: len(package.split(".")) - node.level + 1]
                    source = ".".join(base + ([node.module] if node.module else []))
                else:
                    source = node.module or ""
                targets = [f"{source}.{alias.name}" if f"{source}.{alias.name}" in modules else source
                           for alias in node.names]
            else:
                continue
            for target in targets:
                while target and target not in modules:  # sim.x.y.Name -> sim.x.y
                    target = target.rpartition(".")[0]
                if target and target != name:
                    graph[name].add(target)
    return graph


def sim_part(module: str) -> str:
    """The part of ``sim`` a module belongs to (a key of ``SIM_LAYERS``)."""
    parts = module.split(".")
    return ".".join(parts[:2])


def test_sim_import_graph_sees_every_kind_of_import():
    graph = sim_import_graph()
    assert "sim.evaluation.runner" in graph["sim"]  # function-level, in sim.__getattr__
    assert "sim.env.view" in graph["sim.env.observation"]  # under `if TYPE_CHECKING:`
    assert "sim.evaluation.records" in graph["sim.evaluation.long_vehicles"]
    assert "sim.sensors.lidar" in graph["sim.sensors"]  # a package's __init__ re-exporting
    assert "sim.benchmarks._suite" in graph["sim.cli"]


def test_sim_has_no_import_cycles():
    graph = sim_import_graph()
    try:
        order = list(graphlib.TopologicalSorter(graph).static_order())
    except graphlib.CycleError as err:
        pytest.fail("import cycle in sim: " + " -> ".join(err.args[1]))
    assert set(order) == set(graph)


def test_sim_is_grouped_into_layered_parts():
    sim = ROOT / "sim"
    loose = sorted(p.name for p in sim.glob("*.py") if p.name not in SIM_TOP_LEVEL)
    assert not loose, f"modules directly in sim/ belong in a sub-package: {loose}"
    packages = sorted(p for p in sim.iterdir() if p.is_dir() and not p.is_symlink() and p.name != "__pycache__")
    assert {f"sim.{p.name}" for p in packages} | {f"sim.{Path(n).stem}" for n in SIM_TOP_LEVEL - {"__init__.py"}} \
        | {"sim"} == set(SIM_LAYERS)
    # each sub-package's docstring names every module in it (one line per module)
    for package in packages:
        doc = ast.get_docstring(ast.parse((package / "__init__.py").read_text())) or ""
        for module in sorted(p.stem for p in package.glob("*.py") if p.name != "__init__.py"):
            assert f"``sim.{package.name}.{module}``" in doc or f"``{module}``" in doc, \
                f"sim/{package.name}/__init__.py's docstring does not say what {module}.py holds"
    # lower parts never import higher ones
    upward = sorted(f"{a} imports {b}" for a, targets in sim_import_graph().items() for b in targets
                    if SIM_LAYERS[sim_part(a)] < SIM_LAYERS[sim_part(b)])
    assert not upward, upward


# -- tracker: import graph ----------------------------------------------------------------------
#: The tracker's lower layers: the geometry, the road, the UKF and the motion model, with the kernels'
#: compiler, the input checks and the configuration (which holds the 3-D pipeline's ``CloudConfig``
#: from ``tracker.cloud``, a module that imports only ``tracker.checks``). They never import a stage
#: above them (clustering, measurement, update, births, reduction, the tracker itself).
TRACKER_LOWER = ("tracker.jit", "tracker.checks", "tracker.config", "tracker.cloud", "tracker.angles",
                 "tracker.geometry", "tracker.transforms", "tracker.centerline", "tracker.lanes", "tracker.road", "tracker.ukf",
                 "tracker.motion")


def _closure(graph: dict[str, set[str]], start: str) -> set[str]:
    seen, todo = set(), [start]
    while todo:
        for target in graph[todo.pop()]:
            if target not in seen:
                seen.add(target)
                todo.append(target)
    return seen


def test_tracker_has_no_import_cycles():
    graph = sim_import_graph("tracker")
    del graph["tracker"]  # the package's public API re-exports the stages; no stage imports it
    graph = {name: targets - {"tracker"} for name, targets in graph.items()}
    try:
        order = list(graphlib.TopologicalSorter(graph).static_order())
    except graphlib.CycleError as err:
        pytest.fail("import cycle in tracker: " + " -> ".join(err.args[1]))
    assert set(order) == set(graph)


def test_tracker_lower_layers_import_no_stage_above_them():
    graph = sim_import_graph("tracker")
    lower = set(TRACKER_LOWER)
    assert lower <= set(graph)
    upward = sorted(f"{a} imports {b}" for a in lower for b in _closure(graph, a) - lower)
    assert not upward, upward
