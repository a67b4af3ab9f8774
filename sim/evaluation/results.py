"""Writing a run's results: ``metrics.json``, ``timeseries.csv``, ``tracks.csv`` and ``truth.csv``.

- ``metrics.json``: ``scenario``, ``variant``, ``seed``, ``duration_s``, the GOSPA settings and
  convention, the truth-set rule, every key of ``Result.metrics`` (docs/architecture.md keys and more; see
  ``sim.evaluation.runner``; ``null`` where undefined, e.g. an RMSE without any assigned pair) and the
  tracker's ``tracker_stats`` counters.
- ``timeseries.csv``: one row per frame: ``t`` (s), ``n_truth`` (scored truth set), ``n_visible``,
  ``n_tracks``, ``gospa`` (m) and its parts ``gospa_localization``, ``gospa_missed``,
  ``gospa_false`` (p-th-power sums, m^2), the same for the visible-only scoring (``gospa_visible``
  ...), ``tracker_ms``, and the ego's pose ``ego_x, ego_y`` (m, G), ``ego_yaw`` (rad) and ``ego_s``
  (its arc length, m).
- ``tracks.csv``: one row per reported track per frame: ``t``, ``label``, ``weight``, the curvilinear
  state ``s, n, v, xi, xi_dot, length, width``, ``s_rel`` (``s - s_ego``, m), the Cartesian view
  ``x, y, psi, psi_dot`` (G), ``truth_id`` (the truth vehicle it is assigned to by GOSPA, -1 if
  none) and ``on_edge`` (1: on an edge vehicle, left out of the scorings; ``sim.evaluation.runner.edge_set``).
- ``truth.csv``: one row per other vehicle per frame: ``t``, ``id``, ``x, y, yaw, v, yaw_rate,
  length, width, s, n, xi``, ``scored`` and ``visible`` (0/1) and ``lidar_points``.
- ``tracker_events.csv`` (only when the tracker exposes ``last_events``; ``sim.evaluation.runner``): one row per
  label per event per frame: ``t``, ``label``, ``event`` (``born``, ``updated``, ``missed``,
  ``dropped``, ``merged``) and ``other_label`` (for ``merged``: the label that absorbed it; else -1).

Numbers are written with ``repr`` precision so the files round-trip exactly.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from sim.evaluation.metrics import GOSPA_C, GOSPA_P
from sim.evaluation.runner import TRACKER_EVENT_LABEL_KEYS, Result

GOSPA_CONVENTION = (
    "GOSPA alpha=2, order p and cut-off c as given (default p=2, c=5 m) on rectangle centres (x, y) in G; "
    "localization/missed/false are "
    "p-th-power sums (m^p) with gospa = (localization + missed + false)^(1/p) per frame; *_mean "
    "keys average per-frame values"
)
TRUTH_SET = (
    "other vehicles whose centre is within the lidar range of the ego and on the road, occluded ones "
    "included; *_visible_* keys score only those with at least one lidar point in the frame; a track on a "
    "vehicle whose centre is off the road but whose body reaches onto it (an edge vehicle) is left out"
)


def _clean(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_clean(v) for v in value]
    return value


def metrics_document(result: Result) -> dict[str, Any]:
    """The content of ``metrics.json`` for ``result`` (module docstring)."""
    doc: dict[str, Any] = {
        "scenario": result.spec.name,
        "variant": result.variant,
        "seed": result.seed,
        "duration_s": result.duration,
        "gospa_c_m": result.settings.get("gospa_c", GOSPA_C),
        "gospa_p": result.settings.get("gospa_p", GOSPA_P),
        "gospa_convention": GOSPA_CONVENTION,
        "min_visible_points": result.settings.get("min_visible_points"),
        "roadside_objects": result.settings.get("roadside_objects"),
        "truth_set": TRUTH_SET,
    }
    doc.update(result.metrics)
    doc["tracker_stats"] = result.tracker_stats
    return _clean(doc)


def _fmt(value: Any) -> Any:
    if isinstance(value, (float, np.floating)):
        return repr(float(value))
    if isinstance(value, (np.integer, np.bool_)):
        return int(value)
    return value


def _write_csv(path: Path, header: list[str], rows: list[list[Any]]) -> None:
    with open(path, "w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        writer.writerow(header)
        for row in rows:
            writer.writerow([_fmt(v) for v in row])


TIMESERIES_COLUMNS = [
    "t", "n_truth", "n_visible", "n_tracks",
    "gospa", "gospa_localization", "gospa_missed", "gospa_false",
    "gospa_visible", "gospa_visible_localization", "gospa_visible_missed", "gospa_visible_false",
    "tracker_ms", "ego_x", "ego_y", "ego_yaw", "ego_s",
]  # fmt: skip
TRACK_COLUMNS = [
    "t", "label", "weight", "s", "n", "v", "xi", "xi_dot", "length", "width", "s_rel",
    "x", "y", "psi", "psi_dot", "truth_id", "on_edge",
]  # fmt: skip
TRUTH_COLUMNS = [
    "t", "id", "x", "y", "yaw", "v", "yaw_rate", "length", "width", "s", "n", "xi", "scored", "visible",
    "lidar_points",
]  # fmt: skip
TRACKER_EVENT_COLUMNS = ["t", "label", "event", "other_label"]


def timeseries_rows(result: Result) -> list[list[Any]]:
    """Rows of ``timeseries.csv`` (columns ``TIMESERIES_COLUMNS``)."""
    rows = []
    for f in result.frames:
        g, gv = f.gospa, f.gospa_visible
        rows.append([f.t, f.n_truth, f.n_visible, f.n_tracks, g.gospa, g.localization, g.missed, g.false,
                     gv.gospa, gv.localization, gv.missed, gv.false, f.tracker_ms,
                     f.truth.ego.x, f.truth.ego.y, f.truth.ego.yaw, f.ego_s])
    return rows


def track_rows(result: Result) -> list[list[Any]]:
    """Rows of ``tracks.csv`` (columns ``TRACK_COLUMNS``)."""
    rows = []
    road = result.road
    for f in result.frames:
        for k, tr in enumerate(f.tracks):
            cart = f.track_state[k]
            rows.append([f.t, tr.label, tr.weight, *tr.mean.tolist(), tr.relative_s(road, f.ego_s),
                         cart[0], cart[1], cart[3], cart[4], int(f.track_truth_id[k]),
                         int(f.on_edge is not None and bool(f.on_edge[k]))])
    return rows


def truth_rows(result: Result) -> list[list[Any]]:
    """Rows of ``truth.csv`` (columns ``TRUTH_COLUMNS``)."""
    rows = []
    for f in result.frames:
        snap = f.truth
        for i in range(len(snap)):
            rows.append([f.t, int(snap.ids[i]), snap.xy[i, 0], snap.xy[i, 1], snap.yaw[i], snap.v[i],
                         snap.yaw_rate[i], snap.length[i], snap.width[i], snap.s[i], snap.n[i], snap.xi[i],
                         int(f.scored[i]), int(f.visible[i]), int(f.lidar_points[i])])
    return rows


def tracker_event_rows(result: Result) -> list[list[Any]] | None:
    """Rows of ``tracker_events.csv`` (columns ``TRACKER_EVENT_COLUMNS``), or ``None`` when no frame
    has tracker events (the tracker does not expose ``last_events``)."""
    if all(f.tracker_events is None for f in result.frames):
        return None
    rows: list[list[Any]] = []
    for f in result.frames:
        events = f.tracker_events or {}
        for key in TRACKER_EVENT_LABEL_KEYS:
            rows.extend([f.t, int(label), key, -1] for label in events.get(key, ()))
        rows.extend([f.t, int(absorbed), "merged", int(kept)] for absorbed, kept in events.get("merged", ()))
    return rows


def write_results(result: Result, out: str | Path) -> dict[str, Path]:
    """Write ``metrics.json``, ``timeseries.csv``, ``tracks.csv`` and ``truth.csv`` of ``result``
    (and ``tracker_events.csv`` when the tracker exposed events) into the folder ``out`` (created if
    needed); returns the paths by name."""
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    paths = {
        "metrics": folder / "metrics.json",
        "timeseries": folder / "timeseries.csv",
        "tracks": folder / "tracks.csv",
        "truth": folder / "truth.csv",
    }
    with open(paths["metrics"], "w", encoding="utf-8") as fh:
        json.dump(metrics_document(result), fh, indent=2)
        fh.write("\n")
    _write_csv(paths["timeseries"], TIMESERIES_COLUMNS, timeseries_rows(result))
    _write_csv(paths["tracks"], TRACK_COLUMNS, track_rows(result))
    _write_csv(paths["truth"], TRUTH_COLUMNS, truth_rows(result))
    events = tracker_event_rows(result)
    stale = folder / "tracker_events.csv"
    if events is not None:
        paths["tracker_events"] = stale
        _write_csv(stale, TRACKER_EVENT_COLUMNS, events)
    elif stale.exists():  # from an earlier run into the same folder: it would describe another run
        stale.unlink()
    return paths


__all__ = [
    "GOSPA_CONVENTION",
    "TIMESERIES_COLUMNS",
    "TRACKER_EVENT_COLUMNS",
    "TRACK_COLUMNS",
    "TRUTH_COLUMNS",
    "TRUTH_SET",
    "metrics_document",
    "tracker_event_rows",
    "write_results",
]
