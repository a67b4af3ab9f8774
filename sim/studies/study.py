"""The paper's comparison study (``eot compare``): every variant over a suite with the same seeds.

``run_compare`` runs the Monte Carlo of ``sim.studies.montecarlo`` (``plan`` + ``run_study``) for every
*available* variant (``sim.evaluation.variants.probe_variant``: a variant whose optional dependency is missing
here is skipped with its reason; any other failure to build a variant is an error) over the scenarios of a suite and the seeds ``seed0 .. seed0 + runs - 1``. All variants
see the same simulated data for the same scenario and seed (the world, the sensors and the clutter
are seeded by the seed alone), so differences between variants are *paired*: ``paired_difference``
takes, per (scenario, seed), variant A's value minus variant B's and gives the mean and its 95 %
Student t interval over the pairs (``mean_interval``). Optionally the hard suite and the real-traffic suite run too
(``hard_runs`` and ``real_runs`` seeds per scenario and variant).

The figures need per-frame series of a few runs (``FIGURE_RUNS``: GOSPA and cardinality over time,
fused vs lidar-only on curvy-multi; GOSPA and yaw, curvilinear vs Cartesian on curve-single; the
followed car's position, yaw, length and width on chicane-follow for every variant). They are rerun
for the study's first seed (the paper's figures are single runs), in local processes (also with
``backend="ray"``: they are a handful of runs), with
``series_of`` keeping one row per frame (``SERIES_COLUMNS``); runs are deterministic, so these are
the same runs as those of ``runs.csv`` for that seed (``run_compare`` checks the GOSPA mean).

Files (``write_compare``, in ``OUT/report/``): ``runs.csv`` (the standard-suite rows, as
``eot montecarlo`` writes them), ``hard_runs.csv`` and ``real_runs.csv`` (when those suites ran), ``series.csv`` and
``study.json`` (settings, skipped variants with their reasons, wall times, the command line).
``read_compare`` reads them back, so the report can be rebuilt without rerunning (``--report-only``).
"""

from __future__ import annotations

import csv
import json
import math
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

from sim.studies.montecarlo import plan, read_runs, run_study, write_runs
from sim.world.scenario import load_scenario, load_suite, resolve_scenario_path
from tracker.warmup import warm_up

#: The variants of the study, in report order (docs/architecture.md).
STUDY_VARIANTS: tuple[str, ...] = (
    "curvilinear-fused", "curvilinear-lidar", "cartesian-fused", "paper-motion", "paper", "point-gnn",
    "stonesoup-gmphd",
)  # fmt: skip
#: Scenario -> variants whose per-frame series the figures need (only those in the suite and available).
FIGURE_RUNS: dict[str, tuple[str, ...]] = {
    "curvy-multi": ("curvilinear-fused", "curvilinear-lidar"),
    "curve-single": ("curvilinear-fused", "cartesian-fused"),
    "chicane-follow": STUDY_VARIANTS,
}
#: Confidence level of every interval of the study.
CONFIDENCE = 0.95
#: Columns of series.csv: one row per frame of a figure run; the ``truth_*`` / ``est_*`` columns
#: describe the run's target vehicle (the one scored in most frames) and the track GOSPA assigns to it
#: (NaN when none; ``est_length`` / ``est_width`` NaN for point trackers).
SERIES_COLUMNS = (
    "scenario", "variant", "seed", "t", "gospa", "gospa_localization", "gospa_missed", "gospa_false", "n_truth",
    "n_tracks", "tracker_ms", "target_id", "truth_x", "truth_y", "truth_yaw", "truth_length", "truth_width",
    "est_x", "est_y", "est_yaw", "est_length", "est_width",
)  # fmt: skip


# -- intervals -------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Interval:
    """Mean of ``n`` values and its Student t interval ``[low, high]`` at ``CONFIDENCE`` (``None``
    bounds for n < 2; ``None`` mean for n = 0)."""

    n: int
    mean: float | None
    low: float | None
    high: float | None

    @property
    def half_width(self) -> float | None:
        """Half the interval's width (``None`` without an interval)."""
        return None if self.low is None or self.high is None else 0.5 * (self.high - self.low)

    def excludes_zero(self) -> bool:
        """Whether the interval lies entirely on one side of zero."""
        return self.low is not None and self.high is not None and (self.low > 0.0 or self.high < 0.0)


def mean_interval(values: Sequence[float | None], confidence: float = CONFIDENCE) -> Interval:
    """Mean and Student t interval (``n - 1`` degrees of freedom) of the non-missing ``values``."""
    arr = np.array([v for v in values if v is not None and math.isfinite(v)], dtype=float)
    n = int(arr.size)
    if n == 0:
        return Interval(0, None, None, None)
    mean = float(arr.mean())
    if n < 2:
        return Interval(1, mean, None, None)
    half = float(stats.t.ppf(0.5 + 0.5 * confidence, n - 1) * arr.std(ddof=1) / math.sqrt(n))
    return Interval(n, mean, mean - half, mean + half)


@dataclass(frozen=True)
class Paired:
    """Paired difference ``a - b`` of ``metric`` over (scenario, seed) pairs where both have a value:
    ``diff`` (its ``Interval``), the means of ``a`` and ``b`` over the same pairs and the scenarios."""

    metric: str
    a: str
    b: str
    scenarios: tuple[str, ...]
    diff: Interval
    a_mean: float | None
    b_mean: float | None


def paired_values(rows: Sequence[dict[str, Any]], metric: str, a: str, b: str,
                  scenarios: Sequence[str] | None = None) -> list[tuple[str, int, float, float]]:
    """``(scenario, seed, value_a, value_b)`` for every (scenario, seed) both variants ran with a
    value of ``metric`` (restricted to ``scenarios`` when given), sorted by scenario and seed."""
    keep = None if scenarios is None else set(scenarios)
    by: dict[tuple[str, str, int], float] = {}
    for row in rows:
        value = row.get(metric)
        if value is None or (keep is not None and row["scenario"] not in keep):
            continue
        if isinstance(value, float) and not math.isfinite(value):
            continue
        by[(row["variant"], row["scenario"], int(row["seed"]))] = float(value)
    out = []
    for (variant, scenario, seed), va in by.items():
        if variant == a and (b, scenario, seed) in by:
            out.append((scenario, seed, va, by[(b, scenario, seed)]))
    return sorted(out)


def paired_difference(rows: Sequence[dict[str, Any]], metric: str, a: str, b: str,
                      scenarios: Sequence[str] | None = None, confidence: float = CONFIDENCE) -> Paired:
    """The paired difference ``a - b`` of ``metric`` (``Paired``; see ``paired_values``)."""
    pairs = paired_values(rows, metric, a, b, scenarios)
    va = np.array([p[2] for p in pairs], dtype=float)
    vb = np.array([p[3] for p in pairs], dtype=float)
    used = tuple(dict.fromkeys(p[0] for p in pairs))
    return Paired(metric, a, b, used, mean_interval((va - vb).tolist(), confidence),
                  float(va.mean()) if len(va) else None, float(vb.mean()) if len(vb) else None)


# -- scenarios -------------------------------------------------------------------------------------
def suite_paths(suite: str) -> list[str]:
    """Scenario files of a suite (a shipped suite name or a suite .toml)."""
    path = resolve_scenario_path(suite)
    return [str(p) for p in load_suite(path).paths]


def max_curvature(path: str | Path, samples_per_m: float = 1.0) -> float | None:
    """The largest |curvature| (1/m) of a scenario's road (``None`` for a generated road, which is
    drawn per seed)."""
    spec = load_scenario(path)
    if spec.road is None and spec.replay is None:
        return None
    road = spec.build_road()
    s = np.linspace(0.0, road.length, max(2, int(road.length * samples_per_m)), endpoint=not road.closed)
    return float(np.max(np.abs(road.curvature(s))))


# -- figure series ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class SeriesTask:
    """One figure run: scenario file ``path``, ``variant``, ``seed``, optional ``duration`` (s)."""

    path: str
    variant: str
    seed: int
    duration: float | None = None


def series_of(task: SeriesTask) -> tuple[list[dict[str, Any]], float | None]:
    """Run ``task`` and return its ``series.csv`` rows (``SERIES_COLUMNS``) and its GOSPA mean."""
    from sim.evaluation.runner import run_scenario

    spec = load_scenario(task.path)
    result = run_scenario(spec, task.seed, task.variant, duration=task.duration)
    extent = bool(result.settings.get("estimates_extent", True))
    counts: dict[int, int] = {}
    for f in result.frames:
        for vid in f.truth.ids[f.scored].tolist():
            counts[int(vid)] = counts.get(int(vid), 0) + 1
    target = max(counts, key=lambda k: (counts[k], -k)) if counts else -1
    rows = []
    nan = float("nan")
    for f in result.frames:
        truth = [nan] * 5
        est = [nan] * 5
        where = np.flatnonzero((f.truth.ids == target) & f.scored)
        if where.size:
            x = f.truth_state[where[0]]
            truth = [x[0], x[1], x[3], x[5], x[6]]
            assigned = np.flatnonzero(f.track_truth_id == target)
            if assigned.size:
                e = f.track_state[assigned[0]]
                est = [e[0], e[1], e[3], e[5] if extent else nan, e[6] if extent else nan]
        g = f.gospa
        rows.append(dict(zip(SERIES_COLUMNS, [
            spec.name, task.variant, task.seed, f.t, g.gospa, g.localization, g.missed, g.false, f.n_truth, f.n_tracks_scored,
            f.tracker_ms, target, *map(float, truth), *map(float, est),
        ])))  # fmt: skip
    return rows, result.metrics.get("gospa_mean")


def figure_tasks(paths: Sequence[str], variants: Sequence[str], seed: int, duration: float | None) -> list[SeriesTask]:
    """The figure runs (``FIGURE_RUNS``) among the suite's scenarios and the available variants."""
    tasks = []
    for path in paths:
        name = load_scenario(path).name
        for variant in FIGURE_RUNS.get(name, ()):
            if variant in variants:
                tasks.append(SeriesTask(path, variant, seed, duration))
    return tasks


def run_series(tasks: Sequence[SeriesTask], workers: int) -> list[tuple[list[dict[str, Any]], float | None]]:
    """``series_of`` for every task, in ``workers`` processes (1: in this process), in task order."""
    if workers <= 1 or len(tasks) <= 1:
        return [series_of(t) for t in tasks]
    warm_up()  # the tracker's compiled kernels, once, before the workers load them from the cache
    with ProcessPoolExecutor(max_workers=min(workers, len(tasks))) as pool:
        return list(pool.map(series_of, tasks))


# -- the study -------------------------------------------------------------------------------------
@dataclass
class CompareData:
    """Everything the report needs: the standard-suite ``rows`` (runs.csv rows), the ``hard_rows`` and
    ``real_rows`` (empty when the hard or the real-traffic suite did not run), the figure ``series`` rows and ``meta`` (settings,
    ``variants`` run, ``skipped`` variant -> reason, ``curvature`` scenario -> max |kappa| 1/m, wall
    times s, command)."""

    rows: list[dict[str, Any]]
    hard_rows: list[dict[str, Any]] = field(default_factory=list)
    series: list[dict[str, Any]] = field(default_factory=list)
    meta: dict[str, Any] = field(default_factory=dict)
    real_rows: list[dict[str, Any]] = field(default_factory=list)


@dataclass(frozen=True)
class CompareSettings:
    """Settings of ``run_compare``: ``suite`` (name or file), ``runs`` (seeds per scenario and variant),
    ``variants`` (those asked for; unavailable ones are skipped), ``seed0`` (first seed), ``duration``
    (s per run; ``None``: each scenario's), ``workers``, ``backend`` (``local`` | ``ray``), ``address``
    (Ray), ``hard_suite`` and ``hard_runs`` (0: no hard-suite section), ``real_suite`` and ``real_runs``
    (0: no real-traffic section)."""

    suite: str = "standard"
    runs: int = 20
    variants: tuple[str, ...] = STUDY_VARIANTS
    seed0: int = 0
    duration: float | None = None
    workers: int = 1
    backend: str = "local"
    address: str | None = None
    hard_suite: str = "hard"
    hard_runs: int = 0
    real_suite: str = "real"
    real_runs: int = 0


def split_available(variants: Sequence[str]) -> tuple[list[str], dict[str, str]]:
    """The variants that can be built here, and those whose optional dependency is missing, with the
    reason (``probe_variant``); any other failure to build a variant propagates."""
    from sim.evaluation.variants import probe_variant

    ok, skipped = [], {}
    for v in variants:
        reason = probe_variant(v)
        if reason is None:
            ok.append(v)
        else:
            skipped[v] = reason
    return ok, skipped


Progress = Callable[[int, int], None]


def run_compare(settings: CompareSettings, *, progress: Callable[[str, int], Progress] | None = None,
                warn: Callable[[str], None] | None = None) -> CompareData:
    """Run the study of ``settings`` (module docstring). ``progress(label, total)`` makes a
    ``(done, total)`` callback per phase; ``warn(text)`` is told about every skipped variant.
    Raises ``ValueError`` when no asked variant can be built or a setting is bad."""
    variants, skipped = split_available(settings.variants)
    for name, reason in skipped.items():
        if warn is not None:
            warn(f"skipping variant {name}: {reason}")
    if not variants:
        raise ValueError("none of the asked variants can be built here: " + "; ".join(f"{k}: {v}" for k, v in skipped.items()))
    paths = suite_paths(settings.suite)
    meta: dict[str, Any] = {"settings": asdict(settings), "variants": variants, "skipped": skipped}
    meta["curvature"] = {load_scenario(p).name: max_curvature(p) for p in paths}

    def phase(label: str, total: int) -> Progress | None:
        return progress(label, total) if progress is not None else None

    tasks = plan(paths, settings.runs, variants, seed0=settings.seed0, duration=settings.duration)
    # the other suites are planned (and their files and settings checked) before anything runs
    extra_plans = [(key, suite, suite_paths(suite)) for key, suite, runs in
                   (("hard", settings.hard_suite, settings.hard_runs), ("real", settings.real_suite, settings.real_runs))
                   if runs > 0]
    extra_tasks = {key: plan(p, getattr(settings, f"{key}_runs"), variants, seed0=settings.seed0, duration=settings.duration)
                   for key, _, p in extra_plans}
    start = time.perf_counter()
    study = run_study(tasks, workers=settings.workers, backend=settings.backend, address=settings.address,
                      progress=phase(f"{len(tasks)} runs ({settings.suite})", len(tasks)))
    meta["study_wall_s"] = study.wall_s
    extra: dict[str, list[dict[str, Any]]] = {"hard": [], "real": []}
    for key, suite, extra_paths in extra_plans:
        result = run_study(extra_tasks[key], workers=settings.workers, backend=settings.backend, address=settings.address,
                           progress=phase(f"{len(extra_tasks[key])} runs ({suite})", len(extra_tasks[key])))
        extra[key] = result.rows
        meta[f"{key}_wall_s"] = result.wall_s
        meta[f"{key}_curvature"] = {load_scenario(p).name: max_curvature(p) for p in extra_paths}
    series_tasks = figure_tasks(paths, variants, settings.seed0, settings.duration)
    t0 = time.perf_counter()
    bar = phase(f"{len(series_tasks)} figure runs", len(series_tasks))
    outputs = run_series(series_tasks, settings.workers)
    if bar is not None:
        bar(len(series_tasks), len(series_tasks))
    meta["figure_wall_s"] = time.perf_counter() - t0
    series = [row for rows, _ in outputs for row in rows]
    meta["figure_runs_match"] = _check_figure_runs(study.rows, series_tasks, outputs)
    meta["total_wall_s"] = time.perf_counter() - start
    return CompareData(study.rows, extra["hard"], series, meta, extra["real"])


def _check_figure_runs(rows: list[dict[str, Any]], tasks: Sequence[SeriesTask],
                       outputs: Sequence[tuple[list[dict[str, Any]], float | None]]) -> bool:
    """Whether every figure run reproduced its runs.csv row's GOSPA mean (deterministic runs)."""
    index = {(r["scenario"], r["variant"], r["seed"]): r.get("gospa_mean") for r in rows}
    for task, (series, gospa_mean) in zip(tasks, outputs):
        if not series:
            continue
        expected = index.get((series[0]["scenario"], task.variant, task.seed))
        if expected is not None and gospa_mean is not None and not math.isclose(expected, gospa_mean, rel_tol=1e-9):
            return False
    return True


# -- files -----------------------------------------------------------------------------------------
def _cell(value: Any) -> Any:
    if isinstance(value, float):
        return "" if math.isnan(value) else repr(value)
    return value


def write_series(rows: Sequence[dict[str, Any]], path: str | Path) -> Path:
    """Write the figure series rows to ``path`` (columns ``SERIES_COLUMNS``; empty cells for NaN)."""
    path = Path(path)
    with open(path, "w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        writer.writerow(SERIES_COLUMNS)
        for row in rows:
            writer.writerow([_cell(row[c]) for c in SERIES_COLUMNS])
    return path


def read_series(path: str | Path) -> list[dict[str, Any]]:
    """The rows of a ``series.csv`` written by ``write_series`` (NaN for empty cells)."""
    text_columns = {"scenario", "variant"}
    int_columns = {"seed", "n_truth", "n_tracks", "target_id"}
    out = []
    with open(path, newline="", encoding="utf-8") as fh:
        for raw in csv.DictReader(fh):
            row: dict[str, Any] = {}
            for key in SERIES_COLUMNS:
                value = raw[key]
                if key in text_columns:
                    row[key] = value
                elif key in int_columns:
                    row[key] = int(value)
                else:
                    row[key] = float(value) if value != "" else float("nan")
            out.append(row)
    return out


def write_compare(data: CompareData, folder: str | Path) -> dict[str, Path]:
    """Write runs.csv, hard_runs.csv and real_runs.csv (if any), series.csv and study.json into ``folder``."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = {"runs": write_runs(data.rows, folder / "runs.csv"), "series": write_series(data.series, folder / "series.csv")}
    for key, rows in (("hard_runs", data.hard_rows), ("real_runs", data.real_rows)):
        path = folder / f"{key}.csv"
        if rows:
            paths[key] = write_runs(rows, path)
        elif path.exists():  # from an earlier study: it would describe other runs
            path.unlink()
    paths["study"] = folder / "study.json"
    paths["study"].write_text(json.dumps(data.meta, indent=2, default=str) + "\n", encoding="utf-8")
    return paths


def read_compare(folder: str | Path) -> CompareData:
    """The study written by ``write_compare`` into ``folder`` (``ValueError`` naming a missing file)."""
    folder = Path(folder)
    for name in ("runs.csv", "series.csv", "study.json"):
        if not (folder / name).exists():
            raise ValueError(f"{folder / name} is missing: run `eot compare` first (without --report-only)")
    hard, real = folder / "hard_runs.csv", folder / "real_runs.csv"
    return CompareData(
        read_runs(folder / "runs.csv"),
        read_runs(hard) if hard.exists() else [],
        read_series(folder / "series.csv"),
        json.loads((folder / "study.json").read_text(encoding="utf-8")),
        read_runs(real) if real.exists() else [],
    )


__all__ = [
    "CONFIDENCE",
    "FIGURE_RUNS",
    "SERIES_COLUMNS",
    "STUDY_VARIANTS",
    "CompareData",
    "CompareSettings",
    "Interval",
    "Paired",
    "SeriesTask",
    "figure_tasks",
    "max_curvature",
    "mean_interval",
    "paired_difference",
    "paired_values",
    "read_compare",
    "read_series",
    "run_compare",
    "series_of",
    "split_available",
    "suite_paths",
    "write_compare",
    "write_series",
]
