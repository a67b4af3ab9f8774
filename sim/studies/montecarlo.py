"""Monte Carlo studies: many runs (scenario x variant x seed), locally in processes or on Ray.

A study is a list of ``RunTask``s (``plan``): every scenario with every variant for the seeds
``seed0 .. seed0 + runs - 1`` (the same seeds for every variant: common random numbers, so variant
differences are not drowned in scenario noise). ``run_task`` runs one and returns one CSV row: the
scenario, variant, seed, simulated seconds and every scalar metric of ``sim.evaluation.runner`` (metrics.json
keys). Runs are independent and deterministic, so the rows do not depend on the backend, the number
of workers or the order in which runs finish (only the wall-clock keys, ``sim.evaluation.runner.TIMING_KEYS``,
differ):

- ``backend="local"``: ``workers`` processes (``concurrent.futures.ProcessPoolExecutor``; 1 runs in
  this process);
- ``backend="ray"``: one Ray task per run (``num_cpus=1``) on ``ray.init(address=...)`` (an existing
  cluster, e.g. ``"auto"``) or, without an address, a local Ray started with ``workers`` CPUs. Ray is
  an optional extra: ``pip install "frenet-eot[distributed]"``. Tasks carry the scenario's content
  (not its path), so remote workers need only the installed package.

``summarize_runs`` gives per scenario, variant and metric the number of runs with a value, the mean,
the standard deviation and the 95 % confidence interval of the mean (Student t, ``n - 1`` degrees of
freedom; none for a single run). ``write_study`` writes ``runs.csv`` (one row per run),
``summary.csv`` and ``summary.json`` (with the throughput: simulated seconds per wall second per
worker).

**Interruptions and resuming.** ``run_study(..., on_row=...)`` hands every run's row to ``on_row`` as
the run ends; ``RunsFile.add`` rewrites ``runs.csv`` with it (atomically: a temporary file, flushed to
disk, then a rename), so a study stopped by Ctrl-C, or killed, leaves its finished rows. A run counts as
finished only once its row is in the file: ``RunsFile.rows`` and ``pending`` follow the file as it is
on disk, whenever Ctrl-C lands (before, during or right after the write), and ``StudyInterrupted``
carries the rows whose ``on_row`` returned (worker processes ignore SIGINT and are terminated, so they
print nothing). ``RunsFile.resume`` reads an existing ``runs.csv`` back and matches its rows to the
planned tasks (scenario, variant, seed and simulated seconds); the study then runs only the missing
tasks, and the rows of the interrupted and the resumed parts are identical to those of one
uninterrupted study (runs are deterministic), apart from the wall-clock keys.
"""

from __future__ import annotations

import csv
import json
import math
import os
import re
import signal
import tempfile
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sim.evaluation.runner import TIMING_KEYS, check_scenario_settings, run_scenario, with_lidar_model
from sim.evaluation.variants import DEFAULT_VARIANT, check_variant
from sim.world.scenario import parse_scenario, read_scenario_data, resolve_scenario_path
from tracker.warmup import warm_up

BACKENDS = ("local", "ray")
#: Columns of runs.csv that identify a run (the metrics follow).
ID_COLUMNS = ("scenario", "variant", "seed", "sim_s")


@dataclass(frozen=True)
class RunTask:
    """One run of a study: the scenario (its parsed TOML ``data`` and where it came from, ``source``),
    the ``variant``, the ``seed``, an optional shorter ``duration`` (s), a ``roadside`` override
    (``None``: the scenario's), an optional ``tracker_factory(road, config)`` (default
    ``tracker.Tracker``; a custom tracker must be picklable by reference for process workers) and
    an optional ``lidar_model`` replacing the scenario's ``sensors.lidar.model``."""

    name: str
    source: str
    data: dict[str, Any]
    variant: str
    seed: int
    duration: float | None = None
    roadside: bool | None = None
    tracker_factory: Callable[..., Any] | None = None
    lidar_model: str | None = None


def scenario_task_data(path: str | Path) -> tuple[str, str, dict[str, Any]]:
    """``(name, source, data)`` of a scenario file (or shipped name), validated once here."""
    p = resolve_scenario_path(path)
    data = read_scenario_data(p)
    spec = parse_scenario(data, str(p))
    return spec.name, str(p), data


def plan(
    scenarios: Sequence[str | Path],
    runs: int,
    variants: Sequence[str] = (DEFAULT_VARIANT,),
    *,
    seed0: int = 0,
    duration: float | None = None,
    roadside: bool | None = None,
    tracker_factory: Callable[..., Any] | None = None,
    lidar_model: str | None = None,
    tracker_overrides: dict[str, Any] | None = None,
) -> list[RunTask]:
    """The tasks of a study: every scenario x variant x seed in ``seed0 .. seed0 + runs - 1``.
    ``tracker_overrides`` (nested tables, as a scenario's ``[tracker]``) go on top of every scenario's
    own ``[tracker]`` overrides: an ablation of the tracker's configuration over a whole suite."""
    if isinstance(runs, bool) or not isinstance(runs, int) or runs < 1:
        raise ValueError(f"runs must be an integer >= 1; got {runs!r}")
    if isinstance(seed0, bool) or not isinstance(seed0, int) or seed0 < 0:
        raise ValueError(f"seed0 must be a non-negative integer; got {seed0!r}")
    for v in variants:
        check_variant(v)
    loaded = [scenario_task_data(s) for s in scenarios]
    if tracker_overrides:
        loaded = [(name, source, {**data, "tracker": merge_tables(data.get("tracker", {}), tracker_overrides)})
                  for name, source, data in loaded]
    checked = []
    for name, source, data in loaded:  # bad [sensors] / [tracker] / [faults] settings: an error now, not in a worker
        spec = parse_scenario(data, source)
        # a replay's duration is its recording's when the file gives none: every task carries its scenario's
        checked.append((name, source, data if "duration" in data else {**data, "duration": spec.duration}))
        if lidar_model is not None:
            spec = with_lidar_model(spec, lidar_model)
        for v in variants:
            check_scenario_settings(spec, v)
    loaded = checked
    if duration is not None:
        for name, _, data in loaded:
            if not (isinstance(duration, (int, float)) and math.isfinite(duration) and 0.0 < duration <= float(data["duration"])):
                raise ValueError(
                    f"duration must be in (0, {float(data['duration']):g}] s for scenario {name!r}; got {duration!r}"
                )
    return [
        RunTask(name, source, data, variant, seed0 + k, duration, roadside, tracker_factory, lidar_model)
        for name, source, data in loaded
        for variant in variants
        for k in range(runs)
    ]


def merge_tables(base: dict[str, Any], top: dict[str, Any]) -> dict[str, Any]:
    """``base`` with ``top``'s entries put over it, nested tables merged key by key (a new dict)."""
    out = dict(base)
    for key, value in top.items():
        out[key] = merge_tables(out[key], value) if isinstance(value, dict) and isinstance(out.get(key), dict) else value
    return out


def _scalar(value: Any) -> bool:
    return value is None or (isinstance(value, (int, float)) and not isinstance(value, bool))


def run_task(task: RunTask) -> dict[str, Any]:
    """Run one task and return its row: ``scenario``, ``variant``, ``seed``, ``sim_s`` and the scalar
    metrics of ``sim.evaluation.runner`` (``None`` where undefined)."""
    spec = parse_scenario(task.data, task.source)
    result = run_scenario(spec, task.seed, task.variant, duration=task.duration, roadside=task.roadside,
                          tracker_factory=task.tracker_factory, lidar_model=task.lidar_model)
    row: dict[str, Any] = {"scenario": task.name, "variant": task.variant, "seed": task.seed, "sim_s": result.duration}
    for key, value in result.metrics.items():
        if _scalar(value):
            row[key] = None if isinstance(value, float) and not math.isfinite(value) else value
    return row


class StudyInterrupted(Exception):
    """A study stopped by Ctrl-C (``KeyboardInterrupt``): ``rows`` holds, in task order, the row of
    every finished run (with ``on_row``: every run whose ``on_row`` returned) and ``None`` for the others."""

    def __init__(self, rows: list[dict[str, Any] | None]) -> None:
        self.rows = rows
        done = sum(r is not None for r in rows)
        super().__init__(f"interrupted after {done} of {len(rows)} runs")

    @property
    def finished(self) -> int:
        """How many runs finished."""
        return sum(r is not None for r in self.rows)


RowCallback = Callable[[int, dict[str, Any]], None]


def _ignore_sigint() -> None:
    """Worker initializer: Ctrl-C is the parent's to handle (it terminates the workers)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _finished(rows: list[dict[str, Any] | None], i: int, row: dict[str, Any], done: int, total: int,
              progress: Callable[[int, int], None] | None, on_row: RowCallback | None) -> None:
    """Record the row of task ``i``: it counts in ``rows`` only if ``on_row`` (which writes it) returns."""
    rows[i] = row
    if on_row is not None:
        try:
            on_row(i, row)
        except BaseException:
            rows[i] = None
            raise
    if progress is not None:
        progress(done, total)


def _run_local(tasks: list[RunTask], workers: int, progress: Callable[[int, int], None] | None,
               on_row: RowCallback | None = None) -> list[dict[str, Any]]:
    rows: list[dict[str, Any] | None] = [None] * len(tasks)
    if workers <= 1:
        try:
            for i, task in enumerate(tasks):
                _finished(rows, i, run_task(task), i + 1, len(tasks), progress, on_row)
        except KeyboardInterrupt:
            raise StudyInterrupted(rows) from None
        return rows  # type: ignore[return-value]
    warm_up()  # the tracker's compiled kernels, once, before the workers load them from the cache
    pool = ProcessPoolExecutor(max_workers=workers, initializer=_ignore_sigint)
    try:
        futures = {pool.submit(run_task, task): i for i, task in enumerate(tasks)}
        for done, future in enumerate(as_completed(futures), start=1):
            _finished(rows, futures[future], future.result(), done, len(tasks), progress, on_row)
    except KeyboardInterrupt:
        processes = list(getattr(pool, "_processes", {}).values())  # running workers would finish their runs first
        pool.shutdown(wait=False, cancel_futures=True)
        for process in processes:
            process.terminate()
        raise StudyInterrupted(rows) from None
    pool.shutdown()
    return rows  # type: ignore[return-value]


def import_ray() -> Any:
    """The ``ray`` module, or a ``RuntimeError`` saying how to install it."""
    try:
        import ray
    except ImportError:
        raise RuntimeError(
            "the Ray backend needs Ray, which is an optional extra: pip install \"frenet-eot[distributed]\" "
            "(or use --backend local)"
        ) from None
    return ray


def _run_ray(
    tasks: list[RunTask], workers: int, address: str | None, progress: Callable[[int, int], None] | None,
    on_row: RowCallback | None = None,
) -> list[dict[str, Any]]:
    ray = import_ray()
    started = False
    if not ray.is_initialized():
        if address:
            ray.init(address=address, logging_level="WARNING")
        else:
            ray.init(num_cpus=max(1, workers), include_dashboard=False, logging_level="WARNING")
        started = True
    try:
        remote = ray.remote(num_cpus=1)(run_task)
        refs = [remote.remote(task) for task in tasks]
        index = {ref: i for i, ref in enumerate(refs)}
        rows: list[dict[str, Any] | None] = [None] * len(tasks)
        pending = list(refs)
        try:
            while pending:
                ready, pending = ray.wait(pending, num_returns=1)
                for ref in ready:
                    _finished(rows, index[ref], ray.get(ref), len(tasks) - len(pending), len(tasks), progress, on_row)
        except KeyboardInterrupt:
            for ref in pending:
                ray.cancel(ref, force=True)
            raise StudyInterrupted(rows) from None
        return rows  # type: ignore[return-value]
    finally:
        if started:
            ray.shutdown()


@dataclass(frozen=True)
class Study:
    """The rows of a study (task order), the backend, the workers and the wall time (s)."""

    rows: list[dict[str, Any]]
    backend: str
    workers: int
    wall_s: float

    @property
    def simulated_s(self) -> float:
        """Total simulated seconds over all runs."""
        return float(sum(r["sim_s"] for r in self.rows))

    @property
    def throughput(self) -> float:
        """Simulated seconds per wall second per worker."""
        return self.simulated_s / (self.wall_s * max(1, self.workers)) if self.wall_s > 0 else float("nan")


def run_study(
    tasks: Sequence[RunTask],
    *,
    workers: int = 1,
    backend: str = "local",
    address: str | None = None,
    progress: Callable[[int, int], None] | None = None,
    on_row: RowCallback | None = None,
) -> Study:
    """Run every task on ``backend`` (``"local"`` or ``"ray"``) with ``workers`` workers; rows in
    task order. ``address`` is the Ray cluster address (Ray only). ``progress(done, total)`` and
    ``on_row(task_index, row)`` are called as each run finishes. Ctrl-C raises ``StudyInterrupted``
    with the rows finished so far."""
    if backend not in BACKENDS:
        raise ValueError(f"unknown backend {backend!r}; choose one of: {', '.join(BACKENDS)}")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers must be an integer >= 1; got {workers!r}")
    if address and backend != "ray":
        raise ValueError("address applies to the Ray backend only")
    tasks = list(tasks)
    start = time.perf_counter()
    if backend == "local":
        rows = _run_local(tasks, workers, progress, on_row)
    else:
        rows = _run_ray(tasks, workers, address, progress, on_row)
    return Study(rows, backend, workers, time.perf_counter() - start)


# -- summary ---------------------------------------------------------------------------------------
def metric_columns(rows: Sequence[dict[str, Any]]) -> list[str]:
    """The metric columns of ``rows`` (every key but the identifying ones), in first-seen order."""
    seen: dict[str, None] = {}
    for row in rows:
        for key in row:
            if key not in ID_COLUMNS:
                seen.setdefault(key, None)
    return list(seen)


def _t_quantile(df: int) -> float:
    from scipy.stats import t

    return float(t.ppf(0.975, df))


def summarize_runs(rows: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per scenario, variant and metric: ``n`` (runs with a value), ``mean``, ``std`` (sample),
    ``ci95_low``, ``ci95_high`` (Student t interval of the mean; ``None`` for n < 2)."""
    groups: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for row in rows:
        groups.setdefault((row["scenario"], row["variant"]), []).append(row)
    out = []
    for (scenario, variant), members in groups.items():
        for metric in metric_columns(members):
            values = np.array([r[metric] for r in members if r.get(metric) is not None], dtype=float)
            n = int(values.size)
            mean = float(values.mean()) if n else None
            std = float(values.std(ddof=1)) if n > 1 else None
            half = _t_quantile(n - 1) * std / math.sqrt(n) if n > 1 and std is not None else None
            out.append({
                "scenario": scenario,
                "variant": variant,
                "metric": metric,
                "n": n,
                "mean": mean,
                "std": std,
                "ci95_low": None if half is None or mean is None else mean - half,
                "ci95_high": None if half is None or mean is None else mean + half,
            })
    return out


def _fmt(value: Any) -> Any:
    if value is None:
        return ""
    if isinstance(value, float):
        return repr(value)
    return value


def write_runs(rows: Sequence[dict[str, Any]], path: str | Path) -> Path:
    """Write ``rows`` to the CSV file ``path`` (ID columns, then every metric in first-seen order;
    empty cells for ``None``), atomically: a temporary file in the same folder, flushed to disk, then a
    rename. On return the file holds ``rows``; after an exception it is as it was."""
    path = Path(path)
    columns = list(ID_COLUMNS) + metric_columns(rows)
    fd, tmp = tempfile.mkstemp(prefix=".runs-", suffix=".csv", dir=path.parent)
    try:
        with os.fdopen(fd, "w", newline="", encoding="utf-8") as fh:
            writer = csv.writer(fh)
            writer.writerow(columns)
            for row in rows:
                writer.writerow([_fmt(row.get(c)) for c in columns])
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


_INT = re.compile(r"^-?\d+$")


def _parse_cell(text: str) -> Any:
    if text == "":
        return None
    if _INT.match(text):
        return int(text)
    try:
        return float(text)
    except ValueError:
        return text


def read_runs(path: str | Path) -> list[dict[str, Any]]:
    """The rows of a ``runs.csv`` written by ``write_runs`` (ints, floats, ``None`` for empty cells,
    strings for the scenario and variant). Raises ``ValueError`` naming the file when it is not one."""
    path = Path(path)
    with open(path, newline="", encoding="utf-8") as fh:
        reader = csv.DictReader(fh)
        header = reader.fieldnames or []
        if list(header[: len(ID_COLUMNS)]) != list(ID_COLUMNS):
            raise ValueError(f"{path}: not a runs.csv of `eot montecarlo` (its first columns must be {', '.join(ID_COLUMNS)})")
        rows = []
        for k, raw in enumerate(reader, start=2):
            row = {key: _parse_cell(value or "") for key, value in raw.items()}
            row["scenario"], row["variant"] = str(raw["scenario"]), str(raw["variant"])
            if not isinstance(row["seed"], int) or not isinstance(row["sim_s"], (int, float)):
                raise ValueError(f"{path}: line {k}: seed and sim_s must be numbers; got {raw['seed']!r}, {raw['sim_s']!r}")
            rows.append(row)
    return rows


def task_duration(task: RunTask) -> float:
    """The simulated seconds of ``task`` (its ``duration`` or its scenario's)."""
    return float(task.duration if task.duration is not None else task.data["duration"])


class RunsFile:
    """``runs.csv`` of a study kept current while it runs: ``add(i, row)`` (an ``on_row`` callback)
    rewrites the file with every row so far and the row of task ``i``, in task order; ``resume()``
    first loads the rows of an earlier, interrupted run of the same study. ``rows`` (and ``pending``)
    never count a row the file on disk does not hold, nor miss one ``add`` put there, also when an
    exception (Ctrl-C) interrupts ``add``."""

    def __init__(self, path: str | Path, tasks: Sequence[RunTask]) -> None:
        self.path = Path(path)
        self.tasks = list(tasks)
        self.rows: list[dict[str, Any] | None] = [None] * len(self.tasks)

    def resume(self) -> int:
        """Load the rows of an existing ``runs.csv`` (none when there is no file) into their tasks;
        returns how many. Raises ``ValueError`` when the file holds a row this study does not plan
        (another scenario, variant, seed or duration): resuming must not mix two studies."""
        if not self.path.exists():
            return 0
        index = {(t.name, t.variant, t.seed): i for i, t in enumerate(self.tasks)}
        loaded = 0
        for row in read_runs(self.path):
            key = (row["scenario"], row["variant"], row["seed"])
            i = index.get(key)
            if i is None:
                raise ValueError(
                    f"{self.path} has a run this study does not plan (scenario {key[0]}, variant {key[1]}, seed {key[2]}); "
                    "resume with the same arguments, or write to another --out"
                )
            if not math.isclose(float(row["sim_s"]), task_duration(self.tasks[i]), rel_tol=0, abs_tol=1e-9):
                raise ValueError(
                    f"{self.path}: the run (scenario {key[0]}, variant {key[1]}, seed {key[2]}) simulated {row['sim_s']} s; "
                    f"this study asks for {task_duration(self.tasks[i]):g} s; resume with the same --duration"
                )
            self.rows[i] = row
            loaded += 1
        return loaded

    @property
    def pending(self) -> list[int]:
        """Indices of the tasks without a row."""
        return [i for i, row in enumerate(self.rows) if row is None]

    def add(self, i: int, row: dict[str, Any]) -> None:
        """Rewrite the file with the row of task ``i`` added; the row is recorded in ``rows`` once the
        file holding it is in place. When the write is interrupted, ``rows`` follows the file: the
        row is recorded if, and only if, the file on disk has it."""
        rows = list(self.rows)
        rows[i] = row
        try:
            write_runs([r for r in rows if r is not None], self.path)
            self.rows[i] = row
        except BaseException:
            if self._on_disk(i):
                self.rows[i] = row
            raise

    def _on_disk(self, i: int) -> bool:
        """Whether ``runs.csv`` on disk has the row of task ``i``."""
        task = self.tasks[i]
        try:
            return any((r["scenario"], r["variant"], r["seed"]) == (task.name, task.variant, task.seed)
                       for r in read_runs(self.path))
        except (OSError, ValueError):
            return False

    def write(self) -> Path:
        """Rewrite the file with every row so far (task order)."""
        return write_runs([r for r in self.rows if r is not None], self.path)


def write_study(study: Study, out: str | Path) -> dict[str, Path]:
    """Write ``runs.csv``, ``summary.csv`` and ``summary.json`` into the folder ``out``."""
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    paths = {"runs": folder / "runs.csv", "summary": folder / "summary.csv", "summary_json": folder / "summary.json"}
    write_runs(study.rows, paths["runs"])
    summary = summarize_runs(study.rows)
    keys = ["scenario", "variant", "metric", "n", "mean", "std", "ci95_low", "ci95_high"]
    with open(paths["summary"], "w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        writer.writerow(keys)
        for item in summary:
            writer.writerow([_fmt(item[k]) for k in keys])
    doc = {
        "runs": len(study.rows),
        "backend": study.backend,
        "workers": study.workers,
        "wall_s": study.wall_s,
        "simulated_s": study.simulated_s,
        "sim_s_per_wall_s_per_worker": study.throughput,
        "timing_metrics": sorted(TIMING_KEYS),
        "note": "mean and 95 % CI of the mean (Student t) per scenario, variant and metric; "
                "GOSPA parts are p-th-power sums (see metrics.json of a run)",
        "summary": summary,
    }
    with open(paths["summary_json"], "w", encoding="utf-8") as fh:
        json.dump(doc, fh, indent=2)
        fh.write("\n")
    return paths


def default_workers() -> int:
    """Workers when none are asked for: the CPUs this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover (not Linux)
        return max(1, os.cpu_count() or 1)


__all__ = [
    "BACKENDS",
    "RunTask",
    "RunsFile",
    "Study",
    "StudyInterrupted",
    "default_workers",
    "import_ray",
    "plan",
    "read_runs",
    "run_study",
    "run_task",
    "scenario_task_data",
    "summarize_runs",
    "task_duration",
    "write_runs",
    "write_study",
]
