"""The ``eot`` command line: ``demo``, ``run``, ``replay``, ``inspect``, ``montecarlo``, ``compare``, ``closed-loop``,
``soak``, ``scenarios``, ``bench``. Every command writes under ``eot-output/`` unless ``--out`` names a folder.

``eot compare`` runs every study variant over a suite with the same seeds and writes ``REPORT.md``
with its figures and CSVs (``sim.studies.study``, ``sim.studies.claims``, ``sim.studies.report``); a
variant that cannot be built here is skipped with a warning and a note in the report;
``--report-only`` rebuilds the report from ``OUT/report/``.

``eot run`` / ``eot demo`` also write the run's diagnostics (``sim.evaluation.inspect``: ``events.csv``,
``worst_intervals.csv``, ``events.png``) and print one line of them; ``eot inspect RUN_DIR`` prints
the full summary (per vehicle a line, then the worst GOSPA intervals with their causes) and
rewrites those files (``--out`` elsewhere). A missing or incomplete run folder is a one-line error
with exit status 2.

``eot bench`` with no target runs every benchmark (tracker ms per frame at 1-50 targets in view,
Stone Soup's GM-PHD ratio, lidar, world, end to end, Monte Carlo, env, peak memory, the machine) and
writes ``eot-output/bench.json`` (``--out``) plus a table; ``--quick`` shrinks it to seconds
(``sim.benchmarks._suite``). ``eot bench TARGET`` runs one benchmark; ``eot bench tracker
--compare-stonesoup`` needs the extra ``baselines`` (exit 2 with the install command otherwise).

``eot soak [SCENARIO]`` streams one long run (default: ``dense-highway-loop`` for an hour of
simulated time) and writes ``soak.csv`` (a row per window) and ``soak.json`` (``sim.studies.soak``).
``eot montecarlo`` rewrites ``runs.csv`` as each run finishes; after Ctrl-C, ``--resume`` with the same
arguments runs only the missing rows.

Exit status: 0 on success; 2, with one line on stderr and never a traceback, for a usage error
(unknown scenario, suite or variant -- the line lists the choices --, a malformed or invalid scenario
file, unknown keys or out-of-range values in it, a missing file or folder, an output folder that
cannot be written, a missing optional dependency), for an interrupted Monte Carlo (Ctrl-C; the line
says how to resume it); nothing here
prints output that looks like results unless it computed them.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from sim.world.scenario import ScenarioSpec

USAGE_EXIT = 2
#: Default parent folder of every command's outputs (relative to the working directory; not tracked by git).
#: The committed reference outputs under ``results/`` are re-made by passing ``--out results/...``.
OUTPUT_ROOT = "eot-output"


def _bench(args: argparse.Namespace) -> int:
    """``eot bench TARGET``: one benchmark module's numbers as JSON (and its ``summary`` line, if any)."""
    import json

    from sim.baselines.stonesoup_gmphd import MissingBaselineError

    try:
        result = args.module.run(args)
    except MissingBaselineError as exc:
        raise UsageError(str(exc)) from None
    text = json.dumps(result, indent=2)
    print(text)
    summary = getattr(args.module, "summary", None)
    line = summary(result) if summary is not None else None
    if line:
        print(line)
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            fh.write(text + "\n")
    return 0


def _bench_all(args: argparse.Namespace) -> int:
    """``eot bench`` with no target: every section (``sim.benchmarks._suite``), the JSON file and a table."""
    from sim.benchmarks._suite import SECTIONS, Settings, run_all, stderr_log, write
    from sim.benchmarks._table import format_table

    sections = tuple(x for item in (args.only or [",".join(SECTIONS)]) for x in item.split(",") if x)
    unknown = [x for x in sections if x not in SECTIONS]
    if unknown:
        raise UsageError(f"unknown section(s) {', '.join(unknown)}; choose from: {', '.join(SECTIONS)}")
    command = " ".join(["eot bench", *(["--quick"] if args.quick else []), *(["--no-pin"] if args.no_pin else []),
                        *(["--only", *sections] if args.only else []), "--out", args.bench_out])
    result = run_all(Settings.make(args.quick), sections, pin=not args.no_pin, command=command,
                     log=None if args.quiet else stderr_log)
    path = write(result, args.bench_out)
    print(format_table(result))
    print(f"wrote {path}")
    return 0


def _numbers(text: str, count: int, flag: str) -> tuple[float, ...]:
    """``count`` comma-separated finite numbers of a CLI flag, or a ``UsageError`` naming it."""
    import math

    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != count or not all(math.isfinite(v) for v in values):
        raise UsageError(f"{flag} {text!r}: expected {count} comma-separated numbers")
    return values


def _road(args: argparse.Namespace) -> int:
    """``eot road MAP --start X,Y,YAW``: the road of a route through a lane map, as a figure over the map's
    lanelets (``road.png``) and a summary (``road.json``), to check it before tracking on it."""
    import json
    from pathlib import Path

    import numpy as np

    from sim.evaluation.plots import route_figure
    from tracker.maps import read_map, route_corridor

    start = _numbers(args.start, 3, "--start")
    goal = None if args.goal is None else _numbers(args.goal, 2, "--goal")
    via = None if not args.via else [_numbers(v, 2, "--via") for v in args.via]
    path = Path(args.map)
    if not path.is_file():
        raise UsageError(f"no such map file {path}")
    try:
        graph = read_map(path)
        corridor = route_corridor(graph, start, goal, via=via)
    except (ValueError, ImportError) as exc:  # a broken map, a start off every lanelet, a missing reader
        raise UsageError(str(exc)) from None
    road = corridor.road
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    s = np.linspace(0.0, road.length, max(2, int(road.length) + 1))
    right, left = road.edges(s)
    summary = {
        "map": str(path), "start": list(start), "goal": None if goal is None else list(goal),
        "route": [int(i) for i in corridor.route], "length_m": float(road.length), "lanes": int(road.lanes),
        "lane_directions": [int(d) for d in road.lane_directions], "lane_kinds": list(road.layout.kinds),
        "two_way": bool(road.two_way), "uniform": bool(road.uniform),
        "width_min_m": float((left - right).min()), "width_max_m": float((left - right).max()),
        "lanelets_in_road": len(corridor.members), "lanelets_in_map": len(graph.lanelets),
    }
    (out / "road.json").write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    fig = route_figure(graph, corridor, start, goal)
    fig.savefig(out / "road.png")
    print(f"{path.name}: a route of {len(corridor.route)} lanelets, {road.length:.1f} m, up to {road.lanes} lanes "
          f"({'two-way' if road.two_way else 'one-way'}), {summary['width_min_m']:.1f}-{summary['width_max_m']:.1f} m wide")
    print(f"wrote {out / 'road.png'} and {out / 'road.json'}")
    return 0


def _scenarios(args: argparse.Namespace) -> int:
    """List the suites and the scenario files of a folder (name and one-line description)."""
    from pathlib import Path

    from sim.world.scenario import SCENARIO_DIR, ScenarioError, is_suite_file, load_scenario, load_suite

    folder = Path(args.dir) if args.dir else SCENARIO_DIR
    if not folder.is_dir():
        raise UsageError(f"no such folder {folder}")
    files = sorted(folder.glob("*.toml"))
    suites = [p for p in files if is_suite_file(p)]
    status = 0
    for path in suites:
        try:
            suite = load_suite(path)
        except ScenarioError as exc:
            print(f"suite {path.name}: INVALID: {exc}")
            status = 1
            continue
        members = ", ".join(p.stem for p in suite.paths)
        print(f"suite {suite.name} ({path.name}): {suite.description}\n  {members}")
    if suites:
        print()
    rows = []
    for path in files:
        if path in suites:
            continue
        try:
            spec = load_scenario(path)
            rows.append((spec.name, spec.description))
        except ScenarioError as exc:
            rows.append((path.stem, f"INVALID: {exc}"))
            status = 1
    width = max((len(name) for name, _ in rows), default=0)
    for name, description in rows:
        print(f"{name:<{width}}  {description}")
    return status


# -- scenario and variant names -------------------------------------------------------------------
class UsageError(Exception):
    """A bad scenario, suite or variant name on the command line (one line, exit status 2)."""


def _shipped() -> tuple[list[str], list[str]]:
    """Names of the shipped scenarios and suites (``scenarios/``)."""
    from sim.world.scenario import SCENARIO_DIR, is_suite_file

    files = sorted(SCENARIO_DIR.glob("*.toml"))
    suites = [p.stem for p in files if is_suite_file(p)]
    return [p.stem for p in files if p.stem not in suites], suites


def _resolve_scenarios(name: str, *, allow_suite: bool) -> list[str]:
    """Scenario file paths for ``name``: a scenario file or shipped name, or (``allow_suite``) a suite
    file or shipped suite name. Unknown names raise ``UsageError`` listing the choices."""
    from pathlib import Path

    from sim.world.scenario import ScenarioError, is_suite_file, load_scenario, load_suite, shipped_scenario

    path = Path(name)
    found = path if path.is_file() else shipped_scenario(name)
    scenarios, suites = _shipped()
    if found is None:
        what = "scenario or suite" if allow_suite else "scenario"
        choices = ", ".join(scenarios + ([f"suite {s}" for s in suites] if allow_suite else []))
        if path.suffix == ".toml" or len(path.parts) > 1:
            raise UsageError(f"no such file {name}; shipped {what}s: {choices}")
        raise UsageError(f"unknown {what} {name!r}; choose one of: {choices} (or give a .toml file)")
    try:
        if is_suite_file(found):
            if not allow_suite:
                raise UsageError(f"{name!r} is a suite; `eot run` takes one scenario: {', '.join(scenarios)}")
            return [str(p) for p in load_suite(found).paths]
        load_scenario(found)
    except ScenarioError as exc:
        raise UsageError(" ".join(str(exc).split())) from None
    return [str(found)]


def _check_variants(names: list[str]) -> list[str]:
    from sim.evaluation.variants import UnknownVariantError, check_variant

    try:
        return [check_variant(v) for v in names]
    except UnknownVariantError as exc:
        raise UsageError(str(exc)) from None


def _fmt_value(value: object, digits: int = 3) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.{digits}f}"
    return str(value)


def summary_table(metrics: dict) -> str:
    """A short text table of a run's main metrics."""
    m = metrics
    rows = [
        ("frames", _fmt_value(m.get("frames"))),
        ("GOSPA mean (m)", _fmt_value(m.get("gospa_mean"))),
        ("  localisation / missed / false (m^2, p-th-power sums)",
         " / ".join(_fmt_value(m.get(k), 2) for k in ("gospa_localization_mean", "gospa_missed_mean", "gospa_false_mean"))),
        ("GOSPA mean, visible vehicles only (m)", _fmt_value(m.get("gospa_visible_mean"))),
        ("  the same without tracks kept on hidden vehicles (m)", _fmt_value(m.get("gospa_seen_mean"))),
        ("true / estimated count (mean)",
         f"{_fmt_value(m.get('truth_count_mean'), 2)} / {_fmt_value(m.get('track_count_mean'), 2)}"),
        ("cardinality error mean |N_est - N_true|", _fmt_value(m.get("cardinality_error_mean"))),
        ("position RMSE (m)", _fmt_value(m.get("pos_rmse_m"))),
        ("  while visible / while hidden (m)",
         f"{_fmt_value(m.get('pos_rmse_seen_m'))} / {_fmt_value(m.get('pos_rmse_hidden_m'))}"),
        ("  visible: along / across the heading (m)",
         f"{_fmt_value(m.get('pos_rmse_seen_along_m'))} / {_fmt_value(m.get('pos_rmse_seen_across_m'))}"),
        ("yaw RMSE (deg)", _fmt_value(m.get("yaw_rmse_deg"))),
        ("speed RMSE (m/s)", _fmt_value(m.get("speed_rmse_mps"))),
        ("length / width RMSE (m)", f"{_fmt_value(m.get('length_rmse_m'))} / {_fmt_value(m.get('width_rmse_m'))}"),
        ("ID switches", _fmt_value(m.get("id_switches"))),
        ("tracker ms per frame (median / p95)",
         f"{_fmt_value(m.get('tracker_ms_median'), 1)} / {_fmt_value(m.get('tracker_ms_p95'), 1)}"),
    ]
    if m.get("length_shown_share") is not None:  # extended trackers: the seen pairs by whether the length was shown
        rows.insert(rows.index(("yaw RMSE (deg)", _fmt_value(m.get("yaw_rmse_deg")))), (
            "  visible: length shown / not shown (m; share shown)",
            f"{_fmt_value(m.get('pos_rmse_seen_length_shown_m'))} / {_fmt_value(m.get('pos_rmse_seen_length_unshown_m'))}"
            f" ({_fmt_value(m.get('length_shown_share'), 2)})"))
    if m.get("width_shown_share") is not None:  # ... and the width by whether an end was shown
        rows.insert(rows.index(("ID switches", _fmt_value(m.get("id_switches")))), (
            "  visible: width, end shown / not shown (m; share shown)",
            f"{_fmt_value(m.get('width_rmse_seen_shown_m'))} / {_fmt_value(m.get('width_rmse_seen_unshown_m'))}"
            f" ({_fmt_value(m.get('width_shown_share'), 2)})"))
    if m.get("oncoming_matched_pairs"):  # a two-way road with traffic against s in view
        rows.insert(rows.index(("ID switches", _fmt_value(m.get("id_switches")))) + 1, (
            "oncoming vehicles: yaw (deg) / speed (m/s) RMSE, ID switches",
            f"{_fmt_value(m.get('oncoming_yaw_rmse_deg'))} / {_fmt_value(m.get('oncoming_speed_rmse_mps'))}, "
            f"{_fmt_value(m.get('oncoming_id_switches'))}"))
    width = max(len(k) for k, _ in rows)
    return "\n".join(f"{k:<{width}}  {v}" for k, v in rows)


def _run_and_write(scenario: str | ScenarioSpec, *, seed: int, variant: str, out: str, gif: bool, duration: float | None,
                   roadside: bool | None, quiet: bool, lidar_model: str | None = None) -> int:
    import time
    from pathlib import Path

    from sim.evaluation.inspect import headline, inspect_run, write_inspection
    from sim.evaluation.plots import write_figures
    from sim.evaluation.results import write_results
    from sim.evaluation.runner import check_scenario_settings, rig_config_for, run_scenario, with_lidar_model
    from sim.evaluation.variants import check_variant
    from sim.progress import ProgressBar
    from sim.world.scenario import ScenarioError, ScenarioSpec, load_scenario

    spec = scenario if isinstance(scenario, ScenarioSpec) else load_scenario(scenario)
    try:  # usage errors are checked here; an error inside the run is a bug and keeps its traceback
        if lidar_model is not None:
            spec = with_lidar_model(spec, lidar_model)
        check_variant(variant)
        if duration is not None and not (0.0 < duration <= spec.duration):
            raise ValueError(f"--duration must be in (0, {spec.duration:g}] s for {spec.name}; got {duration:g}")
        if seed < 0:
            raise ValueError(f"--seed must be >= 0; got {seed}")
        check_scenario_settings(spec, variant)
        _check_writable(out)
    except (ValueError, UsageError) as exc:
        print(f"eot: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    start = time.perf_counter()
    cloud = rig_config_for(spec)[0].lidar.model != "2d"  # the 3-D pipeline's figure needs a kept frame
    with ProgressBar(0, f"{spec.name} / {variant} / seed {seed}", enabled=not quiet) as bar:
        try:
            result = run_scenario(spec, seed, variant, duration=duration, roadside=roadside,
                                  keep_sensor_data=gif or cloud, progress=bar)
        except ScenarioError as exc:  # e.g. a bad [sensors] / [tracker] override in the file
            bar.close()
            print(f"eot: {' '.join(str(exc).split())}", file=sys.stderr)
            return 2
    paths = write_results(result, out)
    with ProgressBar(0, "figures" + (" + GIF" if gif else ""), enabled=not quiet) as bar:
        paths.update(write_figures(result, out, gif=gif, progress=bar))
    insp = inspect_run(out)  # the diagnostics read back the files just written: one code path with `eot inspect`
    paths.update(write_inspection(insp, out))
    wall = time.perf_counter() - start
    print(f"{spec.name} / {variant} / seed {seed}: {result.duration:g} s simulated in {wall:.1f} s wall "
          f"(GOSPA: alpha 2, p 2, c 5 m; parts are p-th-power sums)")
    print(summary_table(result.metrics))
    if "replay_recording" in result.metrics:
        print(replay_line(result.metrics))
    print(f"diagnostics: {headline(insp)} (`eot inspect {out}` for the timelines)")
    print(f"wrote {len(paths)} files to {Path(out)}/: " + ", ".join(sorted(p.name for p in paths.values())))
    return 0


def replay_line(metrics: dict) -> str:
    """One line on a replay: the recording, its ego, and which truth (smoothed or raw) was used."""
    from sim.world.smoothing import SmootherConfig

    m = metrics
    text = f"replay: {m['replay_recording']}, ego {m['replay_ego']}, {m['replay_vehicles']} recorded vehicles, truth {m['replay_truth']}"
    if m.get("replay_truth") == "smoothed":
        text += (f" (RTS smoother moved the centres by {m['replay_position_change_rms_m']:.2f} m RMS; "
                 f"{m['replay_widths_bounded']} car widths bounded at {SmootherConfig().max_car_width:g} m)")
    return text


def _replay(args: argparse.Namespace) -> int:
    """``eot replay FILE``: a recorded CommonRoad scenario through the sensors and the tracker."""
    from pathlib import Path

    from sim.world.scenario import ScenarioError, parse_scenario, scenario_name

    path = Path(args.file)
    if not path.is_file():
        raise UsageError(f"no such recording {args.file}")
    if not path.name.lower().endswith((".xml", ".xml.gz")):
        raise UsageError(f"{path.name}: a recording is a CommonRoad scenario file (.xml or .xml.gz)")
    variant = _check_variants([args.variant])[0]
    stem = path.name.split(".")[0]
    name = scenario_name(stem)
    replay = {"file": str(path.resolve()), "truth": "raw" if args.raw else "smoothed"}
    if args.ego is not None:
        replay["ego"] = args.ego
    try:
        spec = parse_scenario({"name": name, "description": f"replay of {path.name}", "replay": replay}, str(path))
    except ScenarioError as exc:
        raise UsageError(" ".join(str(exc).split())) from None
    out = args.out or f"{OUTPUT_ROOT}/replay-{name}-{variant}-seed{args.seed}"
    return _run_and_write(spec, seed=args.seed, variant=variant, out=out, gif=args.gif, duration=args.duration,
                          roadside=False if args.no_roadside else None, quiet=args.quiet, lidar_model=args.lidar_model)


def _demo(args: argparse.Namespace) -> int:
    """``eot demo``: curvy-multi with defaults into ``eot-output/demo/`` (``--out``) with figures and the GIF."""
    return _run_and_write("curvy-multi", seed=args.seed, variant="curvilinear-fused", out=args.out, gif=not args.no_gif,
                          duration=None, roadside=None, quiet=args.quiet)


def _run(args: argparse.Namespace) -> int:
    """``eot run SCENARIO``."""
    paths = _resolve_scenarios(args.scenario, allow_suite=False)
    variant = _check_variants([args.variant])[0]
    from pathlib import Path

    name = Path(paths[0]).stem
    out = args.out or f"{OUTPUT_ROOT}/{name}-{variant}-seed{args.seed}"
    return _run_and_write(paths[0], seed=args.seed, variant=variant, out=out, gif=args.gif, duration=args.duration,
                          roadside=False if args.no_roadside else None, quiet=args.quiet, lidar_model=args.lidar_model)


def _inspect(args: argparse.Namespace) -> int:
    """``eot inspect RUN_DIR``: print the diagnostics of a run folder and write their files."""
    from sim.evaluation.inspect import InspectError, inspect_run, summary_text, write_inspection

    try:
        insp = inspect_run(args.run_dir, top=args.top, threshold=args.threshold)
    except InspectError as exc:
        raise UsageError(" ".join(str(exc).split())) from None
    print(summary_text(insp))
    out = args.out or args.run_dir
    paths = write_inspection(insp, out)
    print(f"wrote {', '.join(str(p) for p in paths.values())}")
    return 0


def _tracker_settings(items: list[str] | None) -> dict:
    """``--set SECTION.FIELD=VALUE`` options as nested tables of tracker overrides (``VALUE`` read as a
    TOML value: ``true``, ``0.5``, ``"exact"``; ``none`` for None)."""
    import tomllib

    out: dict = {}
    for item in items or []:
        key, sep, text = item.partition("=")
        path = key.strip().split(".")
        if not sep or not all(path):
            raise UsageError(f"--set needs SECTION.FIELD=VALUE (e.g. measurement.grow_extent=false); got {item!r}")
        text = text.strip()
        if text.lower() in ("none", "null"):
            value = None
        else:
            try:
                value = tomllib.loads(f"v = {text}")["v"]
            except tomllib.TOMLDecodeError:
                raise UsageError(f"--set {key}: {text!r} is not a value (true, false, none, a number or a quoted "
                                 "string)") from None
        table = out
        for part in path[:-1]:
            table = table.setdefault(part, {})
        table[path[-1]] = value
    return out


def _lidar_model(text: str) -> str:
    """``--lidar-model``'s value, checked (``sim.evaluation.runner.lidar_models``)."""
    from sim.evaluation.runner import lidar_models

    try:
        lidar_models(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def _split_variants(values: list[str] | None) -> list[str]:
    from sim.evaluation.variants import DEFAULT_VARIANT

    names = [v.strip() for value in (values or [DEFAULT_VARIANT]) for v in value.split(",") if v.strip()]
    return list(dict.fromkeys(names))


def _montecarlo(args: argparse.Namespace) -> int:
    """``eot montecarlo SCENARIO_OR_SUITE --runs N``: ``runs.csv`` is rewritten as each run finishes;
    Ctrl-C stops with a one-line message (exit status 2) and ``--resume`` runs only the missing rows."""
    from pathlib import Path

    from sim.studies.montecarlo import (
        RunsFile,
        Study,
        StudyInterrupted,
        plan,
        run_study,
        summarize_runs,
        write_study,
    )
    from sim.progress import NestedProgress

    paths = _resolve_scenarios(args.target, allow_suite=True)
    variants = _check_variants(_split_variants(args.variant))
    if args.runs < 1:
        raise UsageError(f"--runs must be >= 1; got {args.runs}")
    if args.workers < 1:
        raise UsageError(f"--workers must be >= 1; got {args.workers}")
    _check_backend(args)
    try:
        tasks = plan(paths, args.runs, variants, seed0=args.seed, duration=args.duration,
                     roadside=False if args.no_roadside else None, lidar_model=args.lidar_model,
                     tracker_overrides=_tracker_settings(args.set))
    except ValueError as exc:
        raise UsageError(" ".join(str(exc).split())) from None
    out = Path(args.out)
    _check_writable(out)
    runs_file = RunsFile(out / "runs.csv", tasks)
    if args.resume:
        try:
            resumed = runs_file.resume()
        except (ValueError, OSError) as exc:
            raise UsageError(" ".join(str(exc).split())) from None
    pending = runs_file.pending
    if args.resume:
        print(f"resuming: {resumed} of {len(tasks)} runs already in {runs_file.path}; {len(pending)} to run")
    todo = [tasks[i] for i in pending]
    groups: dict[str, int] = {}
    for task in todo:
        groups[task.name] = groups.get(task.name, 0) + 1
    label = f"{len(todo)} runs on {args.backend} ({args.workers} worker{'s' if args.workers > 1 else ''})"
    with NestedProgress(groups, label, enabled=not args.quiet) as bars:
        def on_row(k: int, row: dict) -> None:
            runs_file.add(pending[k], row)
            bars.done(todo[k].name)

        try:
            part = run_study(todo, workers=args.workers, backend=args.backend, address=args.address, on_row=on_row)
        except StudyInterrupted:
            bars.close()
            done = len(tasks) - len(runs_file.pending)
            raise UsageError(
                f"interrupted: {done} of {len(tasks)} runs finished and are in {runs_file.path}; "
                "run the same command with --resume to complete the study"
            ) from None
    study = Study([r for r in runs_file.rows if r is not None], part.backend, part.workers, part.wall_s)
    files = write_study(study, out)
    summary = summarize_runs(study.rows)
    shown = ["gospa_mean", "cardinality_error_mean", "pos_rmse_m", "yaw_rmse_deg", "id_switches"]
    print(f"{len(study.rows)} runs, {study.simulated_s:g} s simulated in {study.wall_s:.1f} s wall: "
          f"{study.throughput:.2f} simulated s per wall s per worker")
    header = f"{'scenario':<16} {'variant':<18} " + " ".join(f"{m:>24}" for m in shown)
    print(header)
    by_key = {(r["scenario"], r["variant"], r["metric"]): r for r in summary}
    for scenario in dict.fromkeys(r["scenario"] for r in study.rows):
        for variant in variants:
            cells = []
            for metric in shown:
                item = by_key.get((scenario, variant, metric))
                if item is None or item["mean"] is None:
                    cells.append(f"{'-':>24}")
                elif item["ci95_low"] is None:
                    cells.append(f"{item['mean']:>24.3f}")
                else:
                    half = 0.5 * (item["ci95_high"] - item["ci95_low"])
                    cells.append(f"{item['mean']:>14.3f} +- {half:<7.3f}")
            print(f"{scenario:<16} {variant:<18} " + " ".join(cells))
    print("(mean +- 95 % CI half-width over seeds; GOSPA alpha 2, p 2, c 5 m)")
    print(f"wrote {', '.join(str(p) for p in files.values())}")
    return 0


def _soak(args: argparse.Namespace) -> int:
    """``eot soak [SCENARIO]``: one long streamed run; soak.csv (a row per window) and soak.json."""
    import csv
    import json
    import subprocess
    from dataclasses import fields
    from pathlib import Path

    from sim.progress import ProgressBar
    from sim.studies.soak import SOAK_SCENARIO, SoakConfig, SoakWindow, run_soak, window_row
    from sim.world.scenario import load_scenario

    paths = _resolve_scenarios(args.scenario or SOAK_SCENARIO, allow_suite=False)
    variant = _check_variants([args.variant])[0]
    spec = load_scenario(paths[0])
    try:
        config = SoakConfig(spec, duration_s=args.duration, window_s=args.window, seed=args.seed, variant=variant,
                            roadside=False if args.no_roadside else None)
    except ValueError as exc:
        raise UsageError(" ".join(str(exc).split())) from None
    out = Path(args.out or f"{OUTPUT_ROOT}/soak-{spec.name}-seed{args.seed}")
    _check_writable(out)
    columns = [f.name for f in fields(SoakWindow)]
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                                cwd=Path(__file__).parent, timeout=10).stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        commit = None
    with open(out / "soak.csv", "w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=columns)
        writer.writeheader()

        def on_window(window: SoakWindow) -> None:
            writer.writerow(window_row(window))
            fh.flush()

        with ProgressBar(0, f"soak {spec.name} / {variant} / seed {args.seed}", enabled=not args.quiet,
                         unit="frame") as bar:
            result = run_soak(config, on_window=on_window, progress=bar)
    doc = {"scenario": spec.name, "variant": variant, "seed": args.seed, "duration_s": config.duration,
           "window_s": config.window_s, "commit": commit, "summary": result.summary}
    (out / "soak.json").write_text(json.dumps(doc, indent=2) + "\n", encoding="utf-8")
    s = result.summary
    print(f"soak {spec.name} / {variant} / seed {args.seed}: {s['simulated_s']:g} s simulated ({s['frames']} frames) "
          f"in {s['wall_s']:.0f} s wall")
    print(f"components max {s['components_max']} (mean {s['components_mean']:.1f}); tracks mean {s['tracks_mean']:.2f}, "
          f"scored vehicles mean {s['truth_mean']:.2f}; labels born {s['labels_born']}")
    print(f"resident memory {s['rss_first_window_mb']:.1f} MB after the first window -> {s['rss_end_mb']:.1f} MB at the end "
          f"(growth {s['rss_growth_mb']:+.1f} MB, max {s['rss_max_mb']:.1f} MB)")
    print(f"non-finite frames {s['nonfinite_frames']}, non-PSD or asymmetric track covariances {s['bad_covariances']}")
    print(f"tracker ms per frame, median of the first / last {s['edge_windows']} windows: "
          f"{s['tracker_ms_median_first']:.1f} / {s['tracker_ms_median_last']:.1f} (max {s['tracker_ms_max']:.1f}; CPU "
          f"{s['tracker_cpu_ms_median_first']:.1f} / {s['tracker_cpu_ms_median_last']:.1f}); "
          f"GOSPA mean {s['gospa_mean']:.3f} m")
    print(f"wrote {out / 'soak.csv'}, {out / 'soak.json'}")
    return 0


def _closed_loop(args: argparse.Namespace) -> int:
    """``eot closed-loop [SCENARIO_OR_SUITE]``: the planner on truth and on tracks over seeds
    (``sim.studies.closed_loop``); table, figure, runs and events in ``--out``."""
    import shlex
    import time
    from pathlib import Path

    from sim.progress import ProgressBar
    from sim.evaluation.variants import VARIANTS, probe_variant
    from sim.studies.closed_loop import parse_mode, plan, run_tasks, write_outputs

    paths = _resolve_scenarios(args.target, allow_suite=True)
    variants = []
    for name in _split_variants(args.variant or ["curvilinear-fused,curvilinear-lidar"]):
        if name != "all":
            variants.append(name)
            continue
        for variant in VARIANTS:  # every variant this installation can build
            reason = probe_variant(variant)
            if reason is None:
                variants.append(variant)
            else:
                print(f"eot closed-loop: --variant all leaves out {variant}: {reason}", file=sys.stderr)
    variants = list(dict.fromkeys(variants))
    for name in variants:
        try:
            parse_mode(name)
        except ValueError as exc:
            raise UsageError(f"--variant: {exc}") from None
    if args.runs < 1:
        raise UsageError(f"--runs must be >= 1; got {args.runs}")
    if args.workers < 1:
        raise UsageError(f"--workers must be >= 1; got {args.workers}")
    if args.seed < 0:
        raise UsageError(f"--seed must be >= 0; got {args.seed}")
    try:
        tasks = plan(paths, args.runs, variants, seed0=args.seed, truth=not args.no_truth, duration=args.duration)
    except ValueError as exc:
        raise UsageError(" ".join(str(exc).split())) from None
    try:
        Path(args.out).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UsageError(f"cannot create the output folder {args.out}: {exc.strerror or type(exc).__name__}") from None
    start = time.perf_counter()
    label = f"{len(tasks)} closed-loop runs ({args.workers} worker{'s' if args.workers > 1 else ''})"
    with ProgressBar(len(tasks), label, enabled=not args.quiet) as bar:
        rows, events = run_tasks(tasks, workers=args.workers, progress=bar)
    wall = time.perf_counter() - start
    parts = [args.target, "--runs", str(args.runs), "--workers", str(args.workers), "--variant", ",".join(variants)]
    parts += (["--no-truth"] if args.no_truth else []) + (["--seed", str(args.seed)] if args.seed else [])
    parts += (["--duration", f"{args.duration:g}"] if args.duration is not None else []) + ["--out", str(args.out)]
    command = "eot closed-loop " + " ".join(shlex.quote(a) for a in parts)
    files = write_outputs(rows, events, args.out, command=command, wall_s=wall, workers=args.workers)
    print(files["table"].read_text(encoding="utf-8"))
    print(f"{len(rows)} runs in {wall:.1f} s wall; wrote {', '.join(str(p) for p in files.values())}")
    return 0


def _check_backend(args: argparse.Namespace) -> None:
    """``--backend ray`` needs Ray installed; ``--address`` goes with Ray only."""
    from sim.studies.montecarlo import import_ray

    if args.backend == "ray":
        try:
            import_ray()
        except RuntimeError as exc:
            raise UsageError(str(exc)) from None
    elif args.address:
        raise UsageError("--address applies to --backend ray only")


def _check_writable(folder: object) -> None:
    """Create ``folder`` (and parents) and check that a file can be written in it; ``UsageError``
    (one line) otherwise."""
    import tempfile
    from pathlib import Path

    path = Path(str(folder))
    try:
        path.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=path):
            pass
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise UsageError(f"cannot write to the output folder {path}: {reason}") from None


def _compare(args: argparse.Namespace) -> int:
    """``eot compare``: run every variant over a suite with the same seeds and write REPORT.md."""
    import shlex
    import subprocess
    from pathlib import Path

    from sim.progress import ProgressBar
    from sim.studies.report import write_report
    from sim.studies.study import STUDY_VARIANTS, CompareSettings, read_compare, run_compare, write_compare

    out = Path(args.out)
    folder = out / "report"
    if args.report_only:
        try:
            data = read_compare(folder)
        except ValueError as exc:
            raise UsageError(str(exc)) from None
        paths = write_report(data, out)
        print(f"rebuilt {paths['report']} from {folder}/")
        return 0
    variants = _check_variants(_split_variants(args.variants) if args.variants else list(STUDY_VARIANTS))
    _resolve_scenarios(args.suite, allow_suite=True)
    for name, value, low in (("--runs", args.runs, 1), ("--workers", args.workers, 1), ("--hard-runs", args.hard_runs, 0),
                             ("--real-runs", args.real_runs, 0)):
        if value < low:
            raise UsageError(f"{name} must be >= {low}; got {value}")
    _check_backend(args)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UsageError(f"cannot write to the output folder {folder}: {exc.strerror or type(exc).__name__}") from None
    settings = CompareSettings(suite=args.suite, runs=args.runs, variants=tuple(variants), seed0=args.seed,
                               duration=args.duration, workers=args.workers, backend=args.backend, address=args.address,
                               hard_runs=args.hard_runs, real_runs=args.real_runs)
    bars: list[ProgressBar] = []

    def progress(label: str, total: int) -> ProgressBar:
        bar = ProgressBar(total, label, enabled=not args.quiet)
        bars.append(bar)
        return bar

    try:
        data = run_compare(settings, progress=progress, warn=lambda text: print(f"eot compare: warning: {text}", file=sys.stderr))
    except ValueError as exc:
        raise UsageError(" ".join(str(exc).split())) from None
    finally:
        for bar in bars:
            bar.close()
    data.meta["command"] = " ".join(["eot compare", f"--suite {shlex.quote(args.suite)}", f"--runs {args.runs}",
                                     f"--workers {args.workers}", f"--backend {args.backend}", f"--out {shlex.quote(args.out)}",
                                     f"--variants {','.join(variants)}", f"--seed {args.seed}"]
                                    + ([f"--duration {args.duration:g}"] if args.duration is not None else [])
                                    + ([f"--hard-runs {args.hard_runs}"] if args.hard_runs else [])
                                    + ([f"--real-runs {args.real_runs}"] if args.real_runs else []))
    try:
        data.meta["commit"] = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                                             cwd=Path(__file__).parent, timeout=10).stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        data.meta["commit"] = None
    files = write_compare(data, folder)
    paths = write_report(data, out)
    print(f"{len(data.rows)} runs in {data.meta['study_wall_s']:.1f} s wall (figure runs {data.meta['figure_wall_s']:.1f} s); "
          f"variants: {', '.join(data.meta['variants'])}")
    for name, reason in data.meta["skipped"].items():
        print(f"  skipped {name}: {reason}")
    print("mean wall seconds per run, by variant (all scenarios):")
    for v in data.meta["variants"]:
        walls = [r["wall_s"] for r in data.rows if r["variant"] == v and r.get("wall_s") is not None]
        ms = [r["tracker_ms_mean"] for r in data.rows if r["variant"] == v and r.get("tracker_ms_mean") is not None]
        if walls:
            print(f"  {v:<18} {sum(walls) / len(walls):7.1f} s per run, tracker {sum(ms) / max(1, len(ms)):6.1f} ms per frame")
    print(f"wrote {paths['report']}, {len(paths) - 1 + len(files)} files in {folder}/")
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``eot`` with one sub-parser per subcommand."""
    parser = argparse.ArgumentParser(
        prog="eot",
        description="frenet-eot: extended object tracking in Frenet road coordinates.",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    from sim.evaluation.variants import DEFAULT_VARIANT, VARIANTS

    p = sub.add_parser("demo", help=f"run curvy-multi with defaults; figures, GIF and a summary in {OUTPUT_ROOT}/demo/")
    p.add_argument("--out", default=f"{OUTPUT_ROOT}/demo", help=f"output folder (default: {OUTPUT_ROOT}/demo)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--no-gif", action="store_true", help="skip the animated GIF")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_demo)

    p = sub.add_parser("run", help="run one scenario: metrics.json, CSVs and figures")
    p.add_argument("scenario", help="scenario name (see `eot scenarios`) or a .toml file")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--variant", default=DEFAULT_VARIANT, help=f"tracker variant: {', '.join(VARIANTS)}")
    p.add_argument("--out", help=f"output folder (default: {OUTPUT_ROOT}/SCENARIO-VARIANT-seedN)")
    p.add_argument("--gif", action="store_true", help="also write an animated GIF (run.gif)")
    p.add_argument("--duration", type=float, help="simulate only this many seconds (default: the scenario's)")
    p.add_argument("--no-roadside", action="store_true", help="no roadside clutter (posts, trees, parked cars)")
    p.add_argument("--lidar-model", type=_lidar_model,
                   help="lidar model, replacing the scenario's lidar: 2d (default) or a 3-D one, vlp16, vlp32c, hdl64e "
                        "or os1-128 (with the tracker's ground removal; writes cloud.png), or 3-D models joined by + "
                        "for a rig stacked on the roof (e.g. vlp32c+os1-128)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_run)

    p = sub.add_parser("replay", help="replay recorded traffic (a CommonRoad scenario) through the sensors and the tracker: "
                                      "the outputs of `eot run`")
    p.add_argument("file", metavar="FILE", help="CommonRoad scenario file with recorded vehicles (.xml or .xml.gz)")
    p.add_argument("--ego", type=int, help="id of the recorded vehicle that carries the sensors (default: the one recorded "
                                           "throughout with the most vehicles within 100 m)")
    p.add_argument("--variant", default=DEFAULT_VARIANT, help=f"tracker variant: {', '.join(VARIANTS)}")
    p.add_argument("--seed", type=int, default=0, help="random seed of the sensors (default 0)")
    p.add_argument("--lidar-model", type=_lidar_model,
                   help="lidar model (default: 2d): 2d, vlp16, vlp32c, hdl64e, os1-128, or 3-D models joined by + (a stacked rig)")
    p.add_argument("--raw", action="store_true", help="the recorded samples as truth (default: smoothed, sim.world.smoothing)")
    p.add_argument("--out", help=f"output folder (default: {OUTPUT_ROOT}/replay-NAME-VARIANT-seedN)")
    p.add_argument("--gif", action="store_true", help="also write an animated GIF (run.gif)")
    p.add_argument("--duration", type=float, help="replay only this many seconds (default: the ego's recorded time)")
    p.add_argument("--no-roadside", action="store_true", help="no roadside clutter (posts, trees, parked cars)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_replay)

    p = sub.add_parser("inspect", help="why a run went wrong: per-vehicle event timelines and the worst GOSPA intervals")
    p.add_argument("run_dir", metavar="RUN_DIR", help="a folder written by `eot run ... --out DIR`")
    p.add_argument("--top", type=int, default=5, help="how many worst intervals (default 5)")
    p.add_argument("--threshold", type=float,
                   help="GOSPA (m) above which frames form intervals (default: max(2 m, the run's 75th percentile))")
    p.add_argument("--out", help="write events.csv, worst_intervals.csv, events.png here (default: RUN_DIR)")
    p.set_defaults(func=_inspect)

    p = sub.add_parser("montecarlo", help="Monte Carlo study over seeds (local processes or Ray)")
    p.add_argument("target", metavar="SCENARIO_OR_SUITE", help="scenario or suite name, or a .toml file")
    p.add_argument("--runs", type=int, required=True, help="seeds per scenario and variant")
    p.add_argument("--out", required=True, help="output folder (runs.csv, summary.csv, summary.json)")
    p.add_argument("--workers", type=int, default=1, help="parallel workers (default 1)")
    p.add_argument("--backend", choices=("local", "ray"), default="local", help="local processes or Ray")
    p.add_argument("--address", help="Ray cluster address (e.g. auto); default: a local Ray with --workers CPUs")
    p.add_argument("--variant", action="append", help=f"tracker variant(s), repeat or comma-separate: {', '.join(VARIANTS)}")
    p.add_argument("--seed", type=int, default=0, help="first seed (seeds SEED .. SEED+RUNS-1)")
    p.add_argument("--duration", type=float, help="simulate only this many seconds per run")
    p.add_argument("--no-roadside", action="store_true", help="no roadside clutter")
    p.add_argument("--lidar-model", type=_lidar_model,
                   help="lidar model for every scenario, replacing its lidar: 2d, or 3-D vlp16, vlp32c, hdl64e, os1-128, "
                        "or 3-D models joined by + for a rig stacked on the roof (e.g. vlp32c+os1-128)")
    p.add_argument("--set", action="append", metavar="SECTION.FIELD=VALUE",
                   help="a tracker setting for every run, over the scenarios' own [tracker] overrides "
                        "(repeatable; e.g. measurement.grow_extent=false, birth.classes=none)")
    p.add_argument("--resume", action="store_true",
                   help="keep the runs already in OUT/runs.csv (an interrupted study) and run only the missing ones")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_montecarlo)

    p = sub.add_parser("soak", help="one long streamed run: component count, memory, non-finite states, ms per frame")
    p.add_argument("scenario", nargs="?", help="scenario name or .toml file (default: dense-highway-loop, a closed road)")
    p.add_argument("--duration", type=float, help="simulated seconds (default: the scenario's; dense-highway-loop: 3600)")
    p.add_argument("--window", type=float, default=60.0, help="simulated seconds per row of soak.csv (default 60)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--variant", default=DEFAULT_VARIANT, help=f"tracker variant: {', '.join(VARIANTS)}")
    p.add_argument("--no-roadside", action="store_true", help="no roadside clutter")
    p.add_argument("--out", help=f"output folder (default: {OUTPUT_ROOT}/soak-SCENARIO-seedN)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_soak)

    p = sub.add_parser("closed-loop", help="the planner on truth vs tracks over seeds: collisions, headway, TTC, jerk, track-caused events")
    p.add_argument("target", metavar="SCENARIO_OR_SUITE", nargs="?", default="closed-loop",
                   help="scenario or suite name, or a .toml file (default: the closed-loop suite)")
    p.add_argument("--runs", type=int, default=20, help="seeds per scenario and mode (default 20)")
    p.add_argument("--workers", type=int, default=1, help="parallel worker processes (default 1)")
    p.add_argument("--variant", action="append",
                   help=f"tracker modes, repeat or comma-separate (default curvilinear-fused,curvilinear-lidar): a "
                        f"variant ({', '.join(VARIANTS)}), 'all' for every one, or VARIANT+FAULT with a fault of "
                        "radar-missing, lidar-dropout (e.g. curvilinear-fused+lidar-dropout)")
    p.add_argument("--no-truth", action="store_true", help="skip the ground-truth perception mode")
    p.add_argument("--seed", type=int, default=0, help="first seed (seeds SEED .. SEED+RUNS-1)")
    p.add_argument("--duration", type=float, help="simulate only this many seconds per run")
    p.add_argument("--out", default=f"{OUTPUT_ROOT}/closed-loop", help=f"output folder (default: {OUTPUT_ROOT}/closed-loop)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_closed_loop)

    p = sub.add_parser("compare", help=f"the paper's comparison study: every variant, same seeds, REPORT.md (default {OUTPUT_ROOT}/compare/)")
    p.add_argument("--suite", default="standard", help="scenario suite (default: standard)")
    p.add_argument("--runs", type=int, default=20, help="seeds per scenario and variant (default 20)")
    p.add_argument("--workers", type=int, default=1, help="parallel workers (default 1)")
    p.add_argument("--backend", choices=("local", "ray"), default="local", help="local processes or Ray")
    p.add_argument("--address", help="Ray cluster address (e.g. auto); default: a local Ray with --workers CPUs")
    p.add_argument("--out", default=f"{OUTPUT_ROOT}/compare",
                   help=f"folder of REPORT.md; figures and CSVs go to OUT/report/ (default: {OUTPUT_ROOT}/compare)")
    p.add_argument("--variants", action="append",
                   help="variants, repeat or comma-separate (default: all of the study; unavailable ones are skipped)")
    p.add_argument("--seed", type=int, default=0, help="first seed (seeds SEED .. SEED+RUNS-1)")
    p.add_argument("--duration", type=float, help="simulate only this many seconds per run (quick checks)")
    p.add_argument("--hard-runs", type=int, default=0, help="also run the hard suite with this many seeds (default 0: no)")
    p.add_argument("--real-runs", type=int, default=0,
                   help="also run the real-traffic suite with this many seeds (default 0: no; needs .[maps])")
    p.add_argument("--report-only", action="store_true", help="rebuild REPORT.md from OUT/report/ without running")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_compare)
    p = sub.add_parser("road", help=f"the road of a route through a lane map (CommonRoad, Lanelet2, OpenDRIVE): "
                                    f"a figure and a summary to check it (default {OUTPUT_ROOT}/road/)")
    p.add_argument("map", help="lane map file: .xml (CommonRoad), .osm (Lanelet2) or .xodr (OpenDRIVE)")
    p.add_argument("--start", required=True, help="start pose X,Y,YAW (m, m, rad in the map's frame); "
                                                  "write --start=-1,2,0.5 when X is negative")
    p.add_argument("--goal", help="end of the route X,Y (m; default: straight on to the end of the map)")
    p.add_argument("--via", action="append", help="a point X,Y (m) the route passes; repeat in order")
    p.add_argument("--out", default=f"{OUTPUT_ROOT}/road", help="output folder (road.png, road.json)")
    p.set_defaults(func=_road)
    p = sub.add_parser("scenarios", help="list the scenario suites and files (name and description)")
    p.add_argument("--dir", help="folder of scenario files (default: the shipped scenarios)")
    p.set_defaults(func=_scenarios)
    from sim.benchmarks import targets

    bench = sub.add_parser("bench", help=f"benchmarks (speed, never asserted in tests); no target: all of them -> {OUTPUT_ROOT}/bench.json",
                           description=f"With no TARGET: every benchmark, a table, and the numbers in {OUTPUT_ROOT}/bench.json "
                                       "(sim.benchmarks._suite). With a TARGET: that benchmark's numbers as JSON.")
    bench.add_argument("--out", "--json", dest="bench_out", metavar="PATH", default=f"{OUTPUT_ROOT}/bench.json",
                       help=f"no target: where to write the JSON (default {OUTPUT_ROOT}/bench.json)")
    bench.add_argument("--quick", action="store_true", help="no target: shrink every part (seconds; numbers not meaningful)")
    bench.add_argument("--only", nargs="+", metavar="SECTION",
                       help="no target: only these sections (tracker stonesoup lidar lidar3d world end_to_end montecarlo env)")
    bench.add_argument("--no-pin", action="store_true", help="no target: do not pin the single-process parts to one CPU")
    bench.add_argument("--quiet", action="store_true", help="no target: no progress lines on stderr")
    bench.set_defaults(func=_bench_all)
    bench_sub = bench.add_subparsers(dest="target", metavar="TARGET", required=False)
    for name, module in sorted(targets().items()):
        p = bench_sub.add_parser(name, help=(module.__doc__ or "").strip().splitlines()[0])
        p.add_argument("--json", help="also write the numbers to this JSON file")
        if hasattr(module, "add_arguments"):
            module.add_arguments(p)
        p.set_defaults(func=_bench, module=module)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``eot`` console script; returns the process exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args))
    except UsageError as exc:
        print(f"eot {args.command}: {exc}", file=sys.stderr)
        return USAGE_EXIT
    except BrokenPipeError:  # `eot scenarios | head`: the reader left; nothing more to say
        sys.stderr.close()
        return 0
    except OSError as exc:  # a file or folder that cannot be read or written: one line, not a traceback
        where = f": {exc.filename}" if exc.filename else ""
        print(f"eot {args.command}: {exc.strerror or exc}{where}", file=sys.stderr)
        return USAGE_EXIT
    except KeyboardInterrupt:
        print(f"eot {args.command}: interrupted", file=sys.stderr)
        return USAGE_EXIT


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
