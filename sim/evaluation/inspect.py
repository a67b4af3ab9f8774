"""Diagnostics of a run: why a vehicle was lost, and which moments cost the most GOSPA.

``inspect_run(folder)`` reads the files ``eot run ... --out DIR`` writes (``timeseries.csv``,
``truth.csv``, ``tracks.csv``, ``metrics.json`` and, when the tracker exposed ``last_events``,
``tracker_events.csv``; see ``sim.evaluation.results``) and returns an ``Inspection``: per true vehicle a
timeline of states and events, and the worst GOSPA intervals with their causes.
``write_inspection`` writes ``events.csv``, ``worst_intervals.csv`` and ``events.png``;
``summary_text`` is the printed human summary (``eot inspect RUN_DIR``). The assignment of tracks to
vehicles is the run's own GOSPA assignment (``tracks.csv`` column ``truth_id``), so label changes
here are exactly the run's ``id_switches``.

**States** of a vehicle in a frame (the bars of ``events.png``): *out of range* (not in the scored
truth set: beyond the lidar range or off the road, or not in the scene), *tracked* (a track is
GOSPA-assigned to it), *tracked, occluded* (assigned, but fewer than ``min_visible_points`` lidar
points on it), *visible, untracked* (no track assigned although the lidar sees it) and *occluded,
untracked*. "Visible" is the run's ``visible`` flag (at least ``min_visible_points`` lidar points,
default 1); "occluded" is in range with fewer.

**Events** (``events.csv``: ``t, truth_id, label, event, cause, detail``; ``label`` -1 where none):

- ``entered`` / ``left``: the vehicle enters / leaves the scored truth set (``left`` only while
  untracked; a tracked vehicle that leaves is ``lost`` with cause *out of range*);
- ``first_lidar``: its first frame with a lidar point;
- ``confirmed``: its first assigned track; the detail gives the delay after the first lidar point;
- ``never_tracked``: in range at some time but never assigned a track (cause *occluded* when the
  lidar never saw it, else *failed gate*);
- ``lost``: assigned in the previous frame, not in this one. Causes, first rule that applies:

  1. *out of range*: it left the scored truth set;
  2. *merged into another*: its label ``L`` vanished and either the tracker reported
     ``merged (L, K)`` (``tracker_events.csv``) within ``TRACKER_EVENT_WINDOW_S`` s, or a track
     ``K`` alive in both frames was, in the previous frame, assigned to another (neighbouring)
     vehicle and within ``MERGE_RADIUS_M`` m of ``L``'s last estimate;
  3. *replaced by newborn*: ``L`` vanished and the vehicle is assigned a label first reported no
     earlier than ``REPLACE_WINDOW_S`` s before ``L`` vanished, within ``REPLACE_WINDOW_S`` s;
  4. *label moved to another vehicle*: ``L`` is still reported and now assigned to another vehicle;
  5. *occluded*: the vehicle has fewer than ``min_visible_points`` lidar points in this frame, or
     had in at least ``OCCLUDED_FRACTION`` of the frames of the last ``LOSS_CONTEXT_S`` s (this
     frame included: a track that faded while hidden and vanished as the vehicle reappeared);
  6. *failed gate*: otherwise -- the lidar saw it, but its track was not kept (dropped, or still
     reported but farther than the cut-off ``c`` from it: coasting without updates). With tracker
     events the detail says whether the label was ``missed`` / ``dropped``.

- ``label_change``: assigned a label other than the last one it had (an ID switch, also after a gap).
  Causes: *label moved to another vehicle* (the old label is now assigned to another vehicle),
  *merged into another* (rule 2 above for the old label, with the new label as ``K`` allowed),
  *replaced by newborn* (the new label was first reported within ``REPLACE_WINDOW_S`` s of the old
  one's disappearance, or while the old one drifted off), *re-acquired* (a new label after a longer
  gap), else *occluded* / *failed gate* by the visibility rule 5 (the old label drifted off);
- ``reacquired``: assigned again, with the same label, after untracked frames;
- ``coasting`` (only with tracker events): assigned and visible, but its label ``missed`` (not
  updated) for at least ``COAST_MIN_FRAMES`` consecutive frames; cause *failed gate*.

**Costliest vehicles** (``vehicle_costs``; ``summary_text`` prints them): each vehicle's share of the
run's cost ``sum GOSPA^p dt``, from the attribution below (its localisation and missed parts and the
tracks charged to it), split by cause: which vehicles the run's GOSPA is about. The printed ranking
leaves out *missed while occluded* (a vehicle the lidar does not see), which on recorded traffic is
most of the cost and says nothing of what the tracker made of what it saw.

**Worst intervals** (``worst_intervals.csv``). Frames whose GOSPA reaches the threshold (default
``max(WORST_FLOOR_M, the WORST_QUANTILE quantile of the run's per-frame GOSPA)``, m) form runs;
runs separated by at most ``WORST_GAP_FRAMES`` frames are joined; runs are ranked by their cost
``sum GOSPA^p * dt`` (m^p s; the per-frame parts are p-th-power sums, so the cost splits exactly
into the causes below) and the top ``WORST_COUNT`` are kept. Each frame's GOSPA^p is attributed:

- *localisation*: the localisation part, per assigned (vehicle, track) pair ``d^p``;
- each unassigned track (false part, ``c^p/2``) by the vehicle whose body (its rectangle, ``truth.csv``'s
  ``yaw``, ``length``, ``width``) is nearest its centre, within ``NEAR_VEHICLE_M`` m (0 inside the body:
  a track on a long truck's rear, metres from its centre, is on the truck): *duplicate* when that
  vehicle is scored and already has a track,
  *displaced track* when it is scored and has none (its missed part goes there too: the track is on
  the vehicle but beyond the cut-off), *outside truth set* when the vehicle is not scored (out of
  lidar range or off the road); with no vehicle that near, *clutter*;
- each unassigned scored vehicle (missed part, ``c^p/2``) not displaced: *missed while visible* or
  *missed while occluded*.

The dominant cause of an interval is the one with the largest summed cost; the detail names the
vehicles / labels that carry it and the events inside the interval.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tracker.measurement import Rectangles
from tracker.radar_update import nearest_points

# -- thresholds (units in the names) ---------------------------------------------------------------
#: A new label assigned within this time (s) of the old label's disappearance is a *newborn* replacement.
REPLACE_WINDOW_S = 1.0
#: A vanished track's last estimate within this distance (m) of a surviving track that was assigned to
#: another vehicle: *merged into another*.
MERGE_RADIUS_M = 6.0
#: Tracker ``merged`` / ``dropped`` events are matched to a loss within this time (s) after it.
TRACKER_EVENT_WINDOW_S = 0.5
#: The visibility before a loss is judged over this time (s), the loss frame included.
LOSS_CONTEXT_S = 0.3
#: Fraction of those frames with too few lidar points for the cause *occluded*.
OCCLUDED_FRACTION = 0.5
#: With tracker events: consecutive frames (count) of ``missed`` while visible for a ``coasting`` event.
COAST_MIN_FRAMES = 3
#: An unassigned track whose centre is within this distance (m) of a vehicle's body (its rectangle; 0
#: inside) is on that vehicle: as far as 6 m from a car's centre reaches beyond its ends.
NEAR_VEHICLE_M = 3.5
#: Worst intervals: at most this many, over frames with GOSPA at least max(WORST_FLOOR_M (m), the
#: WORST_QUANTILE quantile of the run's GOSPA); runs split by at most WORST_GAP_FRAMES frames join.
WORST_COUNT = 5
WORST_FLOOR_M = 2.0
WORST_QUANTILE = 0.75
WORST_GAP_FRAMES = 1
#: Events this long (s) before an interval starts are listed with it (they often cause it).
EVENT_LEAD_S = 0.5
#: A confirmation this late (s) after the first lidar point is listed with the intervals it falls in.
SLOW_CONFIRM_S = 0.5
#: The summary names at most this many vehicles, costliest first (``vehicle_costs``).
COSTLIEST_COUNT = 5

# states of a vehicle in a frame
OUT_OF_RANGE, TRACKED, TRACKED_OCCLUDED, VISIBLE_UNTRACKED, OCCLUDED_UNTRACKED = range(5)
STATE_NAMES = ("out of range", "tracked", "tracked, occluded", "visible, untracked", "occluded, untracked")
STATE_COLORS = ("#e6e6e6", "#2ca02c", "#98df8a", "#d62728", "#8c8c8c")

# causes of losses and label changes
OCCLUDED = "occluded"
OUT_OF_RANGE_CAUSE = "out of range"
FAILED_GATE = "failed gate"
MERGED = "merged into another"
NEWBORN = "replaced by newborn"
MOVED = "label moved to another vehicle"
REACQUIRED = "re-acquired"

# causes of GOSPA cost (worst intervals)
GOSPA_CAUSES = ("missed while occluded", "missed while visible", "duplicate", "clutter", "localisation",
                "displaced track", "outside truth set")
(C_MISSED_OCCLUDED, C_MISSED_VISIBLE, C_DUPLICATE, C_CLUTTER, C_LOCALISATION, C_DISPLACED,
 C_OUTSIDE) = range(len(GOSPA_CAUSES))
CAUSE_COLORS = ("#8c8c8c", "#d62728", "#9467bd", "#ff7f0e", "#1f77b4", "#8c564b", "#bcbd22")

EVENT_COLUMNS = ["t", "truth_id", "label", "event", "cause", "detail"]
INTERVAL_COLUMNS = ["rank", "t_start", "t_end", "frames", "gospa_mean", "gospa_peak", "cost_m2s", "dominant_cause",
                    "dominant_share", *[f"share_{c.replace(' ', '_')}" for c in GOSPA_CAUSES], "detail", "events"]
REQUIRED_FILES = ("timeseries.csv", "truth.csv", "tracks.csv", "metrics.json")


class InspectError(ValueError):
    """A run folder that cannot be inspected (missing folder or file, missing column, bad value);
    the message is one line naming the file and what is wrong."""


# -- reading a run folder --------------------------------------------------------------------------
@dataclass(eq=False)
class RunData:
    """A run's tables as arrays (``load_run``). ``F`` frames at times ``t`` (s), ``V`` vehicles
    ``vehicle_ids`` (every vehicle of ``truth.csv``), ``R`` track rows.

    Per frame: ``gospa`` (m) and its parts ``localization``, ``missed``, ``false`` (m^p);
    ``ego_xy`` (F, 2) or ``None`` for old folders. Per frame and vehicle (F, V): ``present``,
    ``scored``, ``visible``, ``points`` (lidar points), ``xy`` (F, V, 2; NaN when absent), ``yaw`` (rad),
    ``length``, ``width`` (m; F, V; 0 where the folder has no such column: the body is its centre). Per track
    row: ``track_frame``, ``track_label``, ``track_xy`` (R, 2) and ``track_truth`` (assigned vehicle
    id, -1 none). ``tracker_events``: rows ``(frame, label, event, other_label)`` or ``None``.
    ``c`` (m), ``p``: the GOSPA settings; ``title``: scenario / variant / seed."""

    folder: Path | None
    title: str
    metrics: dict[str, Any]
    c: float
    p: float
    t: np.ndarray
    gospa: np.ndarray
    localization: np.ndarray
    missed: np.ndarray
    false: np.ndarray
    ego_xy: np.ndarray | None
    vehicle_ids: np.ndarray
    present: np.ndarray
    scored: np.ndarray
    visible: np.ndarray
    points: np.ndarray
    xy: np.ndarray
    track_frame: np.ndarray
    track_label: np.ndarray
    track_xy: np.ndarray
    track_truth: np.ndarray
    yaw: np.ndarray | None = None
    length: np.ndarray | None = None
    width: np.ndarray | None = None
    tracker_events: list[tuple[int, int, str, int]] | None = None

    def __post_init__(self) -> None:
        for name in ("yaw", "length", "width"):
            if getattr(self, name) is None:
                object.__setattr__(self, name, np.zeros(self.present.shape))

    def body_distance(self, k: int, xy: np.ndarray) -> np.ndarray:
        """Distances (U, V; m) from the points ``xy (U, 2)`` to the vehicles' bodies in frame ``k``: 0
        inside a rectangle, ``inf`` for a vehicle absent there (the distance to each body's point nearest
        the point, ``tracker.radar_update.nearest_points``)."""
        body = Rectangles(self.xy[k], self.yaw[k], np.zeros(len(self.yaw[k])), self.length[k], self.width[k])
        dist = np.linalg.norm(xy[:, None, :] - nearest_points(body, xy[:, None, :]), axis=-1)
        return np.where(np.isnan(dist), np.inf, dist)

    @property
    def dt(self) -> float:
        """The frame period (s): the median spacing of the frame times (0.1 s for a single frame)."""
        return float(np.median(np.diff(self.t))) if len(self.t) > 1 else 0.1


def _read_table(path: Path, needed: Sequence[str]) -> dict[str, list[str]]:
    """Columns (name -> list of strings) of the CSV ``path``; ``InspectError`` names a missing column."""
    try:
        with open(path, newline="", encoding="utf-8") as fh:
            reader = csv.reader(fh)
            header = next(reader, None)
            rows = list(reader)
    except OSError as exc:
        raise InspectError(f"cannot read {path}: {exc.strerror or exc}") from None
    if header is None:
        raise InspectError(f"{path} is empty (expected a header with {', '.join(needed)})")
    missing = [c for c in needed if c not in header]
    if missing:
        raise InspectError(f"{path} lacks the column(s) {', '.join(missing)}; re-run `eot run ... --out` to rewrite it")
    cols: dict[str, list[str]] = {name: [] for name in header}
    for k, row in enumerate(rows, start=2):
        if len(row) != len(header):
            raise InspectError(f"{path} line {k}: {len(row)} values for {len(header)} columns")
        for name, value in zip(header, row):
            cols[name].append(value)
    return cols


def _floats(cols: dict[str, list[str]], name: str, path: Path, dtype: type = float) -> np.ndarray:
    try:
        arr = np.array(cols[name], dtype=float)
    except ValueError:
        bad = next(v for v in cols[name] if not _is_number(v))
        raise InspectError(f"{path}: column {name} has the non-number {bad!r}") from None
    if dtype is int:
        return arr.astype(int)
    return arr


def _is_number(value: str) -> bool:
    try:
        float(value)
    except ValueError:
        return False
    return True


def _frame_index(times: np.ndarray, t: np.ndarray, path: Path) -> np.ndarray:
    """Index of each time of ``t`` in the frame times ``times`` (exact up to 1e-9 s)."""
    idx = np.clip(np.searchsorted(times, t - 1e-9), 0, max(len(times) - 1, 0))
    if len(t) and (len(times) == 0 or np.any(np.abs(times[idx] - t) > 1e-9)):
        bad = t[np.abs(times[idx] - t) > 1e-9][0] if len(times) else t[0]
        raise InspectError(f"{path} has a row at t = {bad!r} s that timeseries.csv has no frame for")
    return idx


def load_run(folder: str | Path) -> RunData:
    """Read the run folder ``folder`` (``eot run ... --out DIR``) into a ``RunData``.
    Raises ``InspectError`` (one line) for a missing folder, file or column."""
    root = Path(folder)
    if not root.is_dir():
        raise InspectError(f"no such folder {root} (give the folder that `eot run ... --out DIR` wrote)")
    for name in REQUIRED_FILES:
        if not (root / name).is_file():
            raise InspectError(f"{root} has no {name}; it is not a run folder (`eot run ... --out DIR` writes one)")
    try:
        metrics = json.loads((root / "metrics.json").read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as exc:
        raise InspectError(f"{root / 'metrics.json'} is not valid JSON: {exc}") from None
    if not isinstance(metrics, dict):
        raise InspectError(f"{root / 'metrics.json'} is not a JSON object")

    ts_path = root / "timeseries.csv"
    ts = _read_table(ts_path, ["t", "gospa", "gospa_localization", "gospa_missed", "gospa_false"])
    t = _floats(ts, "t", ts_path)
    if len(t) > 1 and np.any(np.diff(t) <= 0):
        raise InspectError(f"{ts_path}: frame times are not increasing")
    ego_xy = None
    if "ego_x" in ts and "ego_y" in ts:
        ego_xy = np.column_stack([_floats(ts, "ego_x", ts_path), _floats(ts, "ego_y", ts_path)]).reshape(-1, 2)

    tr_path = root / "truth.csv"
    tr = _read_table(tr_path, ["t", "id", "x", "y", "scored", "visible", "lidar_points"])
    frame = _frame_index(t, _floats(tr, "t", tr_path), tr_path)
    ids = _floats(tr, "id", tr_path, int)
    vehicle_ids = np.unique(ids)
    col = np.searchsorted(vehicle_ids, ids)
    shape = (len(t), len(vehicle_ids))
    present = np.zeros(shape, dtype=bool)
    scored = np.zeros(shape, dtype=bool)
    visible = np.zeros(shape, dtype=bool)
    points = np.zeros(shape, dtype=int)
    xy = np.full((*shape, 2), np.nan)
    present[frame, col] = True
    scored[frame, col] = _floats(tr, "scored", tr_path) > 0
    visible[frame, col] = _floats(tr, "visible", tr_path) > 0
    points[frame, col] = _floats(tr, "lidar_points", tr_path, int)
    xy[frame, col, 0] = _floats(tr, "x", tr_path)
    xy[frame, col, 1] = _floats(tr, "y", tr_path)
    body = {}
    for name in ("yaw", "length", "width"):  # older folders lack them: bodies are then their centres
        body[name] = np.zeros(shape)
        if name in tr:
            body[name][frame, col] = _floats(tr, name, tr_path)

    tk_path = root / "tracks.csv"
    tk = _read_table(tk_path, ["t", "label", "x", "y", "truth_id"])
    track_frame = _frame_index(t, _floats(tk, "t", tk_path), tk_path)
    track_truth = _floats(tk, "truth_id", tk_path, int)
    unknown = np.setdiff1d(track_truth[track_truth >= 0], vehicle_ids)
    if unknown.size:
        raise InspectError(f"{tk_path}: truth_id {int(unknown[0])} is not a vehicle of truth.csv")
    # tracks on edge vehicles (``on_edge`` 1: centre off the road, body on it) are left out of the
    # scorings, and out of this analysis; older folders lack the column and keep every track
    scored_rows = _floats(tk, "on_edge", tk_path, int) == 0 if "on_edge" in tk else np.ones(len(track_frame), dtype=bool)
    order = np.flatnonzero(scored_rows)[np.argsort(track_frame[scored_rows], kind="stable")]

    events = None
    ev_path = root / "tracker_events.csv"
    if ev_path.is_file():
        ev = _read_table(ev_path, ["t", "label", "event", "other_label"])
        ev_frame = _frame_index(t, _floats(ev, "t", ev_path), ev_path)
        events = list(zip(ev_frame.tolist(), _floats(ev, "label", ev_path, int).tolist(), ev["event"],
                          _floats(ev, "other_label", ev_path, int).tolist()))

    title = " / ".join(str(metrics.get(k, "?")) for k in ("scenario", "variant")) + f" / seed {metrics.get('seed', '?')}"
    return RunData(
        folder=root, title=title, metrics=metrics,
        c=float(metrics.get("gospa_c_m") or 5.0), p=float(metrics.get("gospa_p") or 2.0),
        t=t, gospa=_floats(ts, "gospa", ts_path), localization=_floats(ts, "gospa_localization", ts_path),
        missed=_floats(ts, "gospa_missed", ts_path), false=_floats(ts, "gospa_false", ts_path), ego_xy=ego_xy,
        vehicle_ids=vehicle_ids, present=present, scored=scored, visible=visible, points=points, xy=xy,
        track_frame=track_frame[order], track_label=_floats(tk, "label", tk_path, int)[order],
        track_xy=np.column_stack([_floats(tk, "x", tk_path), _floats(tk, "y", tk_path)]).reshape(-1, 2)[order],
        track_truth=track_truth[order], yaw=body["yaw"], length=body["length"], width=body["width"],
        tracker_events=events,
    )  # fmt: skip


# -- the analysis ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Event:
    """One row of ``events.csv``: time ``t`` (s), the vehicle ``truth_id``, the track ``label`` (-1:
    none), the ``event`` kind, its ``cause`` ("" where none) and a human ``detail``."""

    t: float
    truth_id: int
    label: int
    event: str
    cause: str
    detail: str
    delay_s: float | None = None  # confirmed: seconds after the first lidar point (not a CSV column)

    def row(self) -> list[Any]:
        """The CSV row (``EVENT_COLUMNS``)."""
        return [repr(float(self.t)), self.truth_id, self.label, self.event, self.cause, self.detail]


@dataclass(frozen=True)
class Interval:
    """A worst GOSPA interval: frames ``first..last`` (indices), times ``t_start``..``t_end`` (s),
    ``gospa_mean`` / ``gospa_peak`` (m), ``cost`` (sum GOSPA^p dt, m^p s), the cost per cause
    (``GOSPA_CAUSES`` order, m^p s), the ``dominant`` cause, a ``detail`` naming who carries it and
    the ``events`` in or just before it."""

    rank: int
    first: int
    last: int
    t_start: float
    t_end: float
    gospa_mean: float
    gospa_peak: float
    cost: float
    cause_cost: np.ndarray
    dominant: str
    detail: str
    events: str

    @property
    def shares(self) -> np.ndarray:
        """Share of the cost per cause (sums to 1; zeros for a zero-cost interval)."""
        return self.cause_cost / self.cost if self.cost > 0 else np.zeros_like(self.cause_cost)

    def row(self) -> list[Any]:
        """The CSV row (``INTERVAL_COLUMNS``)."""
        return [self.rank, repr(self.t_start), repr(self.t_end), self.last - self.first + 1, repr(self.gospa_mean),
                repr(self.gospa_peak), repr(self.cost), self.dominant, f"{float(self.shares.max(initial=0.0)):.3f}",
                *[f"{s:.3f}" for s in self.shares], self.detail, self.events]


@dataclass(eq=False)
class Inspection:
    """The diagnostics of a run: its ``data``, the ``labels`` reported (Lb,), per frame and vehicle
    the assigned ``label`` (F, V; -1 none) and ``states`` (F, V; ``STATE_NAMES``), the ``events``,
    per frame the GOSPA^p cost per cause ``cause_cost`` (F, C; m^p), the attribution ``items``
    (frame, cause, vehicle id, label, cost m^p, distance m; -1 where none), the interval
    ``threshold`` (m) and the ``intervals``, worst first."""

    data: RunData
    labels: np.ndarray
    assigned: np.ndarray
    states: np.ndarray
    events: list[Event]
    cause_cost: np.ndarray
    items: np.ndarray
    threshold: float
    intervals: list[Interval] = field(default_factory=list)

    def vehicles_in_range(self) -> np.ndarray:
        """Indices (into ``data.vehicle_ids``) of the vehicles scored in at least one frame."""
        return np.flatnonzero(self.data.scored.any(axis=0))


@dataclass(eq=False)
class _Labels:
    """Per label (Lb): presence (F, Lb), estimate (F, Lb, 2), assigned vehicle id (F, Lb; -1 false,
    -2 absent), first / last frame."""

    labels: np.ndarray
    present: np.ndarray
    xy: np.ndarray
    truth: np.ndarray
    first: np.ndarray
    last: np.ndarray

    def col(self, label: int) -> int:
        return int(np.searchsorted(self.labels, label))


def _label_tables(d: RunData) -> _Labels:
    labels = np.unique(d.track_label)
    col = np.searchsorted(labels, d.track_label)
    shape = (len(d.t), len(labels))
    present = np.zeros(shape, dtype=bool)
    xy = np.full((*shape, 2), np.nan)
    truth = np.full(shape, -2, dtype=int)
    keys, counts = np.unique(d.track_frame * max(len(labels), 1) + col, return_counts=True)
    if np.any(counts > 1):
        k = int(keys[np.argmax(counts)])
        raise InspectError(f"tracks.csv reports label {int(labels[k % len(labels)])} twice at t = {d.t[k // len(labels)]!r} s")
    present[d.track_frame, col] = True
    xy[d.track_frame, col] = d.track_xy
    truth[d.track_frame, col] = d.track_truth
    any_present = present.any(axis=0)
    first = np.where(any_present, np.argmax(present, axis=0), -1)
    last = np.where(any_present, len(d.t) - 1 - np.argmax(present[::-1], axis=0), -1)
    return _Labels(labels, present, xy, truth, first, last)


def _assigned_labels(d: RunData) -> np.ndarray:
    assigned = np.full(d.scored.shape, -1, dtype=int)
    hit = d.track_truth >= 0
    assigned[d.track_frame[hit], np.searchsorted(d.vehicle_ids, d.track_truth[hit])] = d.track_label[hit]
    return assigned


def vehicle_states(d: RunData, assigned: np.ndarray) -> np.ndarray:
    """States (F, V) of every vehicle in every frame (``STATE_NAMES`` codes; module docstring)."""
    tracked = d.scored & (assigned >= 0)
    states = np.full(d.scored.shape, OUT_OF_RANGE, dtype=np.int8)
    states[tracked & d.visible] = TRACKED
    states[tracked & ~d.visible] = TRACKED_OCCLUDED
    states[d.scored & ~tracked & d.visible] = VISIBLE_UNTRACKED
    states[d.scored & ~tracked & ~d.visible] = OCCLUDED_UNTRACKED
    return states


class _EventFinder:
    """Walks each vehicle's frames and explains its transitions (module docstring rules)."""

    def __init__(self, d: RunData, lab: _Labels, assigned: np.ndarray) -> None:
        self.d, self.lab, self.assigned = d, lab, assigned
        self.dt = d.dt
        self.context = max(1, int(round(LOSS_CONTEXT_S / self.dt)) + 1)
        self.merged: dict[int, list[tuple[int, int]]] = {}  # absorbed label -> [(frame, kept)]
        self.tracker_kind: dict[tuple[int, int], set[str]] = {}  # (frame, label) -> kinds
        for frame, label, kind, other in d.tracker_events or ():
            self.tracker_kind.setdefault((frame, label), set()).add(kind)
            if kind == "merged":
                self.merged.setdefault(label, []).append((frame, other))

    # -- helpers
    def _t(self, k: int) -> float:
        return float(self.d.t[k])

    def _vid_at(self, k: int, label: int) -> int:
        """Vehicle id ``label`` is assigned to at frame ``k`` (-1 false, -2 absent)."""
        return int(self.lab.truth[k, self.lab.col(label)])

    def _occluded_before(self, v: int, k: int) -> tuple[bool, str]:
        lo = max(0, k - self.context + 1)
        sc = self.d.scored[lo : k + 1, v]
        vis = self.d.visible[lo : k + 1, v]
        n = int(sc.sum())
        hidden = int((sc & ~vis).sum())
        pts = int(self.d.points[k, v])
        text = f"{pts} lidar point{'s' if pts != 1 else ''} now, hidden in {hidden} of the last {n} frames"
        return bool(not self.d.visible[k, v] or (n > 0 and hidden >= OCCLUDED_FRACTION * n)), text

    def _tracker_note(self, label: int, k: int) -> str:
        if self.d.tracker_events is None:
            return ""
        kinds = [kind for j in range(max(0, k - 1), min(len(self.d.t), k + self._window())) for kind in
                 sorted(self.tracker_kind.get((j, label), ())) if kind in ("missed", "dropped")]
        return f"; tracker: {', '.join(dict.fromkeys(kinds))}" if kinds else "; tracker: no missed/dropped event"

    def _window(self) -> int:
        return max(1, int(round(TRACKER_EVENT_WINDOW_S / self.dt)) + 1)

    def _merge(self, v: int, label: int, k_vanish: int, allowed: int | None = None) -> str | None:
        """Detail if ``label`` (last reported at ``k_vanish - 1``) merged into another track."""
        for frame, kept in self.merged.get(label, ()):
            if k_vanish - 1 <= frame < k_vanish + self._window():
                vid = self._vid_at(min(frame, len(self.d.t) - 1), kept) if kept in self.lab.labels else -2
                on = f" (on vehicle {vid})" if vid >= 0 else ""
                return f"tracker merged label {label} into label {kept}{on} at {self._t(frame):.1f} s"
        k0 = k_vanish - 1
        if k0 < 0 or k_vanish >= len(self.d.t):
            return None
        c = self.lab.col(label)
        alive = self.lab.present[k0] & self.lab.present[k_vanish]
        alive[c] = False
        other = self.lab.truth[k0]
        vid = int(self.d.vehicle_ids[v])
        cand = alive & (other >= 0) & (other != vid)
        if allowed is not None:
            cand &= self.lab.labels == allowed
        if not cand.any():
            return None
        dist = np.linalg.norm(self.lab.xy[k0] - self.lab.xy[k0, c], axis=1)
        dist = np.where(cand, dist, np.inf)
        j = int(np.argmin(dist))
        if dist[j] > MERGE_RADIUS_M:
            return None
        return (f"label {label} vanished {dist[j]:.1f} m from label {int(self.lab.labels[j])} of vehicle "
                f"{int(other[j])}, which went on")

    def _newborn(self, label_new: int, k_old_last: int) -> bool:
        """Whether ``label_new`` was first reported within ``REPLACE_WINDOW_S`` of frame ``k_old_last``."""
        first = int(self.lab.first[self.lab.col(label_new)])
        return abs(self._t(first) - self._t(k_old_last)) <= REPLACE_WINDOW_S + 1e-9

    def _next_assignment(self, v: int, k: int) -> int:
        """First frame >= ``k`` where vehicle ``v`` is scored and assigned (-1: none)."""
        hit = np.flatnonzero(self.d.scored[k:, v] & (self.assigned[k:, v] >= 0))
        return int(k + hit[0]) if hit.size else -1

    def loss_cause(self, v: int, k: int, label: int) -> tuple[str, str]:
        """Cause and detail of vehicle ``v`` losing ``label`` at frame ``k`` (still scored)."""
        d, c = self.d, self.lab.col(label)
        vid = int(d.vehicle_ids[v])
        if not self.lab.present[k, c]:  # the label vanished
            merge = self._merge(v, label, k)
            if merge:
                return MERGED, merge
            nxt = self._next_assignment(v, k)
            if nxt >= 0:
                new = int(self.assigned[nxt, v])
                if new != label and self._t(nxt) - self._t(k) <= REPLACE_WINDOW_S + 1e-9 and self._newborn(new, k - 1):
                    return NEWBORN, (f"label {label} vanished; newborn label {new} on it "
                                     f"{self._t(nxt) - self._t(k - 1):.1f} s later")
            occluded, vis = self._occluded_before(v, k)
            note = self._tracker_note(label, k)
            if occluded:
                return OCCLUDED, f"label {label} vanished; {vis}{note}"
            return FAILED_GATE, f"label {label} vanished while visible; {vis}{note}"
        other = int(self.lab.truth[k, c])
        dist = float(np.linalg.norm(self.lab.xy[k, c] - d.xy[k, v]))
        if other >= 0 and other != vid:
            return MOVED, f"label {label} now on vehicle {other} ({dist:.1f} m from this one)"
        occluded, vis = self._occluded_before(v, k)
        note = self._tracker_note(label, k)
        if occluded:
            return OCCLUDED, f"label {label} coasted {dist:.1f} m off (beyond c = {d.c:g} m); {vis}{note}"
        return FAILED_GATE, f"label {label} still reported {dist:.1f} m off (beyond c = {d.c:g} m): not updated; {vis}{note}"

    def change_cause(self, v: int, k: int, old: int, new: int, k_last: int) -> tuple[str, str]:
        """Cause and detail of vehicle ``v`` assigned ``new`` at frame ``k`` after ``old`` (last
        assigned at frame ``k_last``)."""
        co = self.lab.col(old)
        gap = self._t(k) - self._t(k_last) - self.dt
        gap_text = f" after {gap:.1f} s untracked" if gap > 1e-9 else ""
        vid = int(self.d.vehicle_ids[v])
        if self.lab.present[k, co]:
            other = int(self.lab.truth[k, co])
            if other >= 0 and other != vid:
                return MOVED, f"label {old} now on vehicle {other}; label {new} took this one{gap_text}"
            dist = float(np.linalg.norm(self.lab.xy[k, co] - self.d.xy[k, v]))
            if gap <= REPLACE_WINDOW_S + 1e-9 and self._newborn(new, k_last):
                return NEWBORN, f"label {old} drifted {dist:.1f} m off; newborn label {new} on it{gap_text}"
            occluded, vis = self._occluded_before(v, k_last + 1 if k_last + 1 < len(self.d.t) else k)
            return (OCCLUDED if occluded else FAILED_GATE), f"label {old} drifted {dist:.1f} m off; label {new} took over{gap_text}"
        # the old label's disappearance: its first absent frame after it was last on this vehicle
        k_vanish = k_last + 1 + int(np.argmin(self.lab.present[k_last + 1 : k + 1, co]))
        merge = self._merge(v, old, k_vanish)
        if merge:
            return MERGED, merge + f"; label {new} on it{gap_text}"
        if self._newborn(new, k_vanish - 1) and gap <= REPLACE_WINDOW_S + 1e-9:
            born = self._t(int(self.lab.first[self.lab.col(new)]))
            return NEWBORN, f"label {old} vanished at {self._t(k_vanish):.1f} s; label {new} born at {born:.1f} s{gap_text}"
        return REACQUIRED, f"label {old} gone since {self._t(k_vanish):.1f} s; label {new}{gap_text}"


def find_events(d: RunData, lab: _Labels, assigned: np.ndarray) -> list[Event]:
    """Every vehicle's events (module docstring), sorted by time then vehicle."""
    finder = _EventFinder(d, lab, assigned)
    events: list[Event] = []
    n = len(d.t)
    missed_map: dict[int, set[int]] = {}
    if d.tracker_events is not None:
        for frame, label, kind, _ in d.tracker_events:
            if kind == "missed":
                missed_map.setdefault(frame, set()).add(label)
    for v in np.flatnonzero(d.scored.any(axis=0)):
        vid = int(d.vehicle_ids[v])
        sc, lbl = d.scored[:, v], assigned[:, v]
        tracked = sc & (lbl >= 0)
        seen = np.flatnonzero(d.points[:, v] > 0)
        t_lidar = float(d.t[seen[0]]) if seen.size else None
        if seen.size:
            k0 = int(seen[0])
            events.append(Event(t_lidar, vid, -1, "first_lidar", "",
                                f"{int(d.points[k0, v])} lidar points{_range_text(d, k0, v)}"))
        if not tracked.any():
            k0 = int(np.argmax(sc))
            n_vis = int((sc & d.visible[:, v]).sum())
            cause = FAILED_GATE if n_vis else OCCLUDED
            text = (f"visible in {n_vis} of {int(sc.sum())} frames in range (up to {int(d.points[:, v].max())} "
                    "lidar points) but never tracked" if n_vis else "never seen by the lidar while in range")
            events.append(Event(float(d.t[k0]), vid, -1, "never_tracked", cause, text))
        last_label, k_last = -1, -1
        coast_run = 0
        for k in range(n):
            prev_sc = bool(sc[k - 1]) if k else False
            prev_tr = bool(tracked[k - 1]) if k else False
            if sc[k] and not prev_sc:
                events.append(Event(float(d.t[k]), vid, int(lbl[k]) if tracked[k] else -1, "entered", "",
                                    ("in range from the start" if k == 0 else "entered the scored truth set")
                                    + _range_text(d, k, v)))
            if tracked[k]:
                label = int(lbl[k])
                if last_label < 0:
                    first_seen = float(d.t[lab.first[lab.col(label)]])
                    older = f" (reported since {first_seen:.1f} s)" if first_seen < d.t[k] - 1e-9 else ""
                    delay_s = None if t_lidar is None else float(d.t[k] - t_lidar)
                    if delay_s is None or delay_s < 0:
                        text = f"label {label}{older}, before any lidar point on the vehicle"
                    else:
                        text = f"label {label}{older}, {delay_s:.1f} s after the first lidar point"
                    events.append(Event(float(d.t[k]), vid, label, "confirmed", "", text, delay_s))
                elif label != last_label:
                    cause, text = finder.change_cause(int(v), k, last_label, label, k_last)
                    events.append(Event(float(d.t[k]), vid, label, "label_change", cause, f"{last_label} -> {label}: {text}"))
                elif not prev_tr:
                    gap = d.t[k] - d.t[k_last] - d.dt
                    events.append(Event(float(d.t[k]), vid, label, "reacquired", "", f"label {label} after {gap:.1f} s untracked"))
                # coasting: with tracker events, its label missed while the vehicle is visible
                if d.tracker_events is not None and d.visible[k, v] and label in missed_map.get(k, ()):
                    coast_run += 1
                    if coast_run == COAST_MIN_FRAMES:
                        k0 = k - COAST_MIN_FRAMES + 1
                        events.append(Event(float(d.t[k0]), vid, label, "coasting", FAILED_GATE,
                                            f"label {label} not updated for {COAST_MIN_FRAMES} frames while visible "
                                            f"({int(d.points[k0, v])} lidar points)"))
                else:
                    coast_run = 0
                last_label, k_last = label, k
            else:
                coast_run = 0
            if prev_tr and not tracked[k]:
                label = int(lbl[k - 1])
                if not sc[k]:
                    events.append(Event(float(d.t[k]), vid, label, "lost", OUT_OF_RANGE_CAUSE,
                                        f"label {label}: the vehicle left the scored truth set" + _range_text(d, k, v)))
                else:
                    cause, text = finder.loss_cause(int(v), k, label)
                    events.append(Event(float(d.t[k]), vid, label, "lost", cause, text))
            elif prev_sc and not sc[k] and not prev_tr:
                events.append(Event(float(d.t[k]), vid, -1, "left", OUT_OF_RANGE_CAUSE,
                                    "left the scored truth set untracked" + _range_text(d, k, v)))
    order = {"entered": 0, "first_lidar": 1, "never_tracked": 2, "confirmed": 3, "lost": 4, "left": 5,
             "label_change": 6, "reacquired": 7, "coasting": 8}
    events.sort(key=lambda e: (e.t, e.truth_id, order.get(e.event, 9)))
    return events


def _range_text(d: RunData, k: int, v: int) -> str:
    if d.ego_xy is None or not np.isfinite(d.xy[k, v]).all():
        return ""
    return f" at {float(np.linalg.norm(d.xy[k, v] - d.ego_xy[k])):.0f} m from the ego"


def attribute_gospa(d: RunData, assigned: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per frame the GOSPA^p cost per cause (F, C; m^p) and the items ``(frame, cause, vehicle id,
    label, cost, distance)`` (module docstring rules)."""
    half = 0.5 * d.c**d.p
    n = len(d.t)
    cost = np.zeros((n, len(GOSPA_CAUSES)))
    items: list[tuple[float, ...]] = []
    bounds = np.searchsorted(d.track_frame, np.arange(n + 1))
    for k in range(n):
        rows = slice(bounds[k], bounds[k + 1])
        labels, txy, truth = d.track_label[rows], d.track_xy[rows], d.track_truth[rows]
        hit = truth >= 0
        vcol = np.searchsorted(d.vehicle_ids, truth[hit])
        dist = np.linalg.norm(txy[hit] - d.xy[k, vcol], axis=1)
        for vc, lb, dd in zip(vcol.tolist(), labels[hit].tolist(), dist.tolist()):
            items.append((k, C_LOCALISATION, int(d.vehicle_ids[vc]), lb, dd**d.p, dd))
        has_track = np.zeros(len(d.vehicle_ids), dtype=bool)
        has_track[vcol] = True
        displaced = np.zeros(len(d.vehicle_ids), dtype=bool)
        free = ~hit
        if free.any():
            dd = d.body_distance(k, txy[free])  # (U, V), inf absent
            near = np.argmin(dd, axis=1) if dd.shape[1] else np.zeros(len(dd), dtype=int)
            near_d = dd[np.arange(len(dd)), near] if dd.shape[1] else np.full(len(dd), np.inf)
            for lb, j, dj in zip(labels[free].tolist(), near.tolist(), near_d.tolist()):
                if dj > NEAR_VEHICLE_M:
                    cause, vid = C_CLUTTER, -1
                elif not d.scored[k, j]:
                    cause, vid = C_OUTSIDE, int(d.vehicle_ids[j])
                elif has_track[j]:
                    cause, vid = C_DUPLICATE, int(d.vehicle_ids[j])
                else:
                    cause, vid = C_DISPLACED, int(d.vehicle_ids[j])
                    displaced[j] = True
                items.append((k, cause, vid, lb, half, dj if math.isfinite(dj) else -1.0))
        for j in np.flatnonzero(d.scored[k] & ~has_track).tolist():
            cause = C_DISPLACED if displaced[j] else (C_MISSED_VISIBLE if d.visible[k, j] else C_MISSED_OCCLUDED)
            items.append((k, cause, int(d.vehicle_ids[j]), -1, half, -1.0))
    arr = np.array(items, dtype=float).reshape(-1, 6)
    np.add.at(cost, (arr[:, 0].astype(int), arr[:, 1].astype(int)), arr[:, 4])
    return cost, arr


def vehicle_costs(insp: Inspection, leave_out: Sequence[int] = ()) -> list[tuple[int, float, np.ndarray]]:
    """The vehicles that carry the run's GOSPA cost: per vehicle id, the cost ``sum GOSPA^p dt`` (m^p s)
    of the attribution items charged to it (``attribute_gospa``: its localisation and missed parts, and
    the duplicate, displaced and outside-truth-set tracks nearest it) and that cost per cause (C,),
    costliest first; the causes ``leave_out`` (indices into ``GOSPA_CAUSES``) count as 0 and vehicles
    left with none are dropped. Clutter (a track near no vehicle) is no vehicle's, so the vehicles'
    costs and the clutter's add up to the run's."""
    mine = insp.items[insp.items[:, 2] >= 0]
    vids, row = np.unique(mine[:, 2].astype(int), return_inverse=True)
    table = np.zeros((len(vids), len(GOSPA_CAUSES)))
    np.add.at(table, (row, mine[:, 1].astype(int)), mine[:, 4] * insp.data.dt)
    table[:, list(leave_out)] = 0.0
    totals = table.sum(axis=1)
    order = np.lexsort((vids, -totals))  # costliest first, ties by id
    return [(int(vids[i]), float(totals[i]), table[i]) for i in order if totals[i] > 0.0]


def default_threshold(gospa: np.ndarray) -> float:
    """The worst-interval threshold (m): ``max(WORST_FLOOR_M, WORST_QUANTILE quantile of gospa)``."""
    return max(WORST_FLOOR_M, float(np.quantile(gospa, WORST_QUANTILE))) if len(gospa) else WORST_FLOOR_M


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Runs of True in ``mask`` as ``(first, last)`` index pairs (inclusive)."""
    m = np.concatenate([[False], np.asarray(mask, dtype=bool), [False]])
    edges = np.flatnonzero(m[1:] != m[:-1])
    return [(int(a), int(b) - 1) for a, b in zip(edges[::2], edges[1::2])]


def worst_intervals(insp: Inspection, top: int = WORST_COUNT) -> list[Interval]:
    """The ``top`` worst GOSPA intervals of ``insp`` above ``insp.threshold`` (module docstring)."""
    d = insp.data
    above = d.gospa >= insp.threshold
    runs = _runs(above)
    joined: list[list[int]] = []
    for a, b in runs:
        if joined and a - joined[-1][1] - 1 <= WORST_GAP_FRAMES:
            joined[-1][1] = b
        else:
            joined.append([a, b])
    dt = d.dt
    scored = []
    for a, b in joined:
        cc = insp.cause_cost[a : b + 1].sum(axis=0) * dt
        scored.append((float(cc.sum()), a, b, cc))
    scored.sort(key=lambda x: (-x[0], x[1]))
    out = []
    for rank, (cost, a, b, cc) in enumerate(scored[: max(0, int(top))], start=1):
        dom = int(np.argmax(cc))
        detail = _interval_detail(insp, a, b, cc)
        t0, t1 = float(d.t[a]), float(d.t[b])
        evs = [e for e in insp.events if t0 - EVENT_LEAD_S - 1e-9 <= e.t <= t1 + 1e-9
               and (e.event in ("lost", "label_change", "coasting", "never_tracked")
                    or (e.event == "confirmed" and (e.delay_s or 0.0) >= SLOW_CONFIRM_S))]
        ev_text = "; ".join(f"{e.t:.1f} s vehicle {e.truth_id} {e.event.replace('_', ' ')}"
                            + (f" ({e.cause})" if e.cause else "") for e in evs)
        g = d.gospa[a : b + 1]
        out.append(Interval(rank, a, b, t0, t1, float(g.mean()), float(g.max()), cost, cc, GOSPA_CAUSES[dom], detail,
                            ev_text))
    return out


def _interval_detail(insp: Inspection, a: int, b: int, cc: np.ndarray) -> str:
    """Who carries the main causes (those with >= 20 % of the cost, at least the dominant one)."""
    items, dt = insp.items, insp.data.dt
    total = float(cc.sum())
    parts = []
    for cause in np.argsort(-cc):
        share = cc[cause] / total if total > 0 else 0.0
        if parts and share < 0.2:
            break
        sel = items[(items[:, 0] >= a) & (items[:, 0] <= b) & (items[:, 1] == cause)]
        if not len(sel):
            continue
        keys, inv = np.unique(sel[:, 2:4], axis=0, return_inverse=True)
        inv = inv.reshape(-1)
        sums = np.bincount(inv, weights=sel[:, 4])
        frames = np.bincount(inv)
        mean_d = np.bincount(inv, weights=sel[:, 5]) / frames
        who = []
        for j in np.argsort(-sums)[:3]:
            vid, lb = int(keys[j, 0]), int(keys[j, 1])
            span = f"{frames[j] * dt:.1f} s"
            if cause in (C_MISSED_OCCLUDED, C_MISSED_VISIBLE):
                who.append(f"vehicle {vid} {span}")
            elif cause == C_LOCALISATION:
                who.append(f"vehicle {vid}/label {lb} mean error {mean_d[j]:.1f} m")
            elif cause == C_CLUTTER:
                who.append(f"label {lb} {span}")
            elif cause == C_DISPLACED:
                who.append(f"vehicle {vid}" + (f"/label {lb}" if lb >= 0 else "") + f" {span}")
            else:
                who.append(f"label {lb} on vehicle {vid} {span}")
        parts.append(f"{GOSPA_CAUSES[cause]} {100 * share:.0f} % ({', '.join(who)})")
    return "; ".join(parts)


def analyse(d: RunData, *, top: int = WORST_COUNT, threshold: float | None = None) -> Inspection:
    """The diagnostics of the run ``d``: states, events, GOSPA attribution and the ``top`` worst
    intervals above ``threshold`` (m; default ``default_threshold``)."""
    if threshold is not None and not (math.isfinite(threshold) and threshold >= 0):
        raise InspectError(f"threshold must be a finite number of metres >= 0; got {threshold!r}")
    if top < 0:
        raise InspectError(f"top must be >= 0; got {top}")
    lab = _label_tables(d)
    assigned = _assigned_labels(d)
    states = vehicle_states(d, assigned)
    events = find_events(d, lab, assigned)
    cost, items = attribute_gospa(d, assigned)
    thr = default_threshold(d.gospa) if threshold is None else float(threshold)
    insp = Inspection(d, lab.labels, assigned, states, events, cost, items, thr)
    insp.intervals = worst_intervals(insp, top)
    return insp


def inspect_run(folder: str | Path, *, top: int = WORST_COUNT, threshold: float | None = None) -> Inspection:
    """``analyse(load_run(folder))``: the diagnostics of the run folder ``folder``."""
    return analyse(load_run(folder), top=top, threshold=threshold)


# -- text ------------------------------------------------------------------------------------------
def vehicle_line(insp: Inspection, v: int) -> str:
    """One line on vehicle column ``v``: time in range, shares of the states, first lidar point,
    confirmation delay, labels and its losses and label changes."""
    d = insp.data
    vid = int(d.vehicle_ids[v])
    st = insp.states[:, v]
    n_in = int((st != OUT_OF_RANGE).sum())
    rng = np.flatnonzero(st != OUT_OF_RANGE)
    parts = [f"in range {n_in * d.dt:.1f} s ({d.t[rng[0]]:.1f}-{d.t[rng[-1]]:.1f} s)"]
    pct = {s: 100.0 * float((st == s).sum()) / n_in for s in range(1, 5)}
    parts.append(f"tracked {pct[TRACKED] + pct[TRACKED_OCCLUDED]:.0f} % ({pct[TRACKED_OCCLUDED]:.0f} % while occluded), "
                 f"untracked visible {pct[VISIBLE_UNTRACKED]:.0f} %, untracked occluded {pct[OCCLUDED_UNTRACKED]:.0f} %")
    evs = [e for e in insp.events if e.truth_id == vid]
    first = next((e for e in evs if e.event == "first_lidar"), None)
    conf = next((e for e in evs if e.event == "confirmed"), None)
    parts.append(f"first lidar {first.t:.1f} s" if first else "never seen by the lidar")
    if conf:
        if conf.delay_s is None or conf.delay_s < 0:
            delay = ", before any lidar point"
        else:
            delay = f", +{conf.delay_s:.1f} s"
        parts.append(f"confirmed {conf.t:.1f} s (label {conf.label}{delay})")
    labels = [int(x) for x in insp.assigned[:, v][insp.assigned[:, v] >= 0]]
    if labels:
        seq = [labels[0]] + [b for a, b in zip(labels, labels[1:]) if a != b]
        parts.append("labels " + " -> ".join(str(x) for x in seq))
    notes = []
    for e in evs:
        if e.event == "lost":
            notes.append(f"{e.t:.1f} s lost label {e.label} ({e.cause})")
        elif e.event == "label_change":
            notes.append(f"{e.t:.1f} s label {e.detail.split(':')[0]} ({e.cause})")
        elif e.event in ("coasting", "never_tracked"):
            notes.append(f"{e.t:.1f} s {e.event.replace('_', ' ')} ({e.cause})")
        elif e.event == "reacquired":
            notes.append(f"{e.t:.1f} s re-acquired label {e.label}")
    if notes:
        parts.append("; ".join(notes))
    return f"vehicle {vid:>3}: " + "; ".join(parts)


def summary_text(insp: Inspection) -> str:
    """The human summary: a header, one line per vehicle in range, then the worst intervals."""
    d = insp.data
    m = d.metrics
    lines = [f"{d.title}: {len(d.t)} frames, {len(insp.vehicles_in_range())} vehicles in range, "
             f"{len(insp.labels)} track labels, GOSPA mean {float(np.mean(d.gospa)) if len(d.gospa) else 0.0:.2f} m, "
             f"ID switches {m.get('id_switches', '-')}"
             + ("" if d.tracker_events is not None else " (no tracker events: causes from geometry only)")]
    counts: dict[str, int] = {}
    for e in insp.events:
        if e.event in ("lost", "label_change", "never_tracked", "coasting") and e.cause != OUT_OF_RANGE_CAUSE:
            counts[f"{e.event.replace('_', ' ')}: {e.cause}"] = counts.get(f"{e.event.replace('_', ' ')}: {e.cause}", 0) + 1
    lines.append("events: " + (", ".join(f"{k} x{v}" for k, v in sorted(counts.items())) or "no losses or label changes"))
    lines.append("vehicles:")
    lines += ["  " + vehicle_line(insp, int(v)) for v in insp.vehicles_in_range()]
    p = f"{d.p:g}"
    total = float(insp.cause_cost.sum()) * d.dt
    hidden = float(insp.cause_cost[:, C_MISSED_OCCLUDED].sum()) * d.dt
    lines.append(f"costliest vehicles while seen (share of the run's cost sum GOSPA^{p} dt = {total:.1f} m^{p} s; "
                 f"missed while occluded, {100.0 * hidden / total if total > 0 else 0.0:.0f} % of it, left out):")
    costly = vehicle_costs(insp, leave_out=(C_MISSED_OCCLUDED,))[:COSTLIEST_COUNT]
    if not costly:
        lines.append("  none: no vehicle carries any cost while seen")
    for vid, cost, by_cause in costly:
        order = np.argsort(-by_cause, kind="stable")
        causes = ", ".join(f"{GOSPA_CAUSES[i]} {100.0 * by_cause[i] / cost:.0f} %" for i in order
                           if by_cause[i] >= 0.01 * cost)  # the causes of at least 1 % of its cost
        lines.append(f"  vehicle {vid:>3}: {100.0 * cost / total:.0f} % ({causes})")
    lines.append(f"worst GOSPA intervals (frames with GOSPA >= {insp.threshold:.2f} m; ranked by cost = sum GOSPA^{p} dt, "
                 f"m^{p} s):")
    if not insp.intervals:
        lines.append("  none: no frame reaches the threshold")
    for iv in insp.intervals:
        lines.append(f"  #{iv.rank} {iv.t_start:.1f}-{iv.t_end:.1f} s ({iv.last - iv.first + 1} frames): mean "
                     f"{iv.gospa_mean:.2f} m, peak {iv.gospa_peak:.2f} m, cost {iv.cost:.1f} -- {iv.detail}")
        if iv.events:
            lines.append(f"      events: {iv.events}")
    return "\n".join(lines)


def headline(insp: Inspection) -> str:
    """One line for ``eot run``: losses and label changes by cause and the worst interval."""
    counts: dict[str, int] = {}
    for e in insp.events:
        if e.event in ("lost", "label_change") and e.cause != OUT_OF_RANGE_CAUSE:
            counts[e.cause] = counts.get(e.cause, 0) + 1
    why = ", ".join(f"{k} {v}" for k, v in sorted(counts.items())) or "none"
    worst = ""
    if insp.intervals:
        iv = insp.intervals[0]
        worst = f"; worst interval {iv.t_start:.1f}-{iv.t_end:.1f} s ({iv.dominant})"
    return f"losses and label changes by cause: {why}{worst}"


# -- files -----------------------------------------------------------------------------------------
def plot_events(insp: Inspection, path: str | Path) -> Path:
    """``events_figure(insp)`` written to ``path`` (``events.png``)."""
    events_figure(insp).savefig(path)
    return Path(path)


def events_figure(insp: Inspection) -> Any:
    """The figure of ``events.png`` (a ``matplotlib.figure.Figure``): per vehicle a timeline bar coloured by state with markers for the first lidar
    point, confirmation, label changes, losses and coasting (the vehicle names in the vehicle's colour
    of ``sim.evaluation.plots.vehicle_color``, as in the run's other figures); GOSPA over time with the worst
    intervals shaded (when any frame reaches the threshold); the GOSPA^p cost per cause, stacked.
    Legends sit outside the panels. Drawn on matplotlib's Agg canvas (no pyplot)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    from sim.evaluation.plots import vehicle_color

    d = insp.data
    cols = insp.vehicles_in_range()
    nv = max(len(cols), 1)
    dt = d.dt
    fig = Figure(figsize=(13.0, 4.8 + 0.4 * nv), dpi=100)
    FigureCanvasAgg(fig)
    gs = fig.add_gridspec(3, 1, height_ratios=[max(2.2, 0.4 * nv), 1.3, 1.3], hspace=0.38)
    ax = fig.add_subplot(gs[0])
    ax_g = fig.add_subplot(gs[1], sharex=ax)
    ax_c = fig.add_subplot(gs[2], sharex=ax)
    t_end = float(d.t[-1] + dt) if len(d.t) else 1.0
    span = t_end - (float(d.t[0]) if len(d.t) else 0.0)
    y_of = {int(v): i for i, v in enumerate(cols)}
    for v, y in y_of.items():
        st = insp.states[:, v]
        for s, color in enumerate(STATE_COLORS):
            spans = [(float(d.t[a]), float(d.t[b] - d.t[a] + dt)) for a, b in _runs(st == s)]
            if spans:
                ax.broken_barh(spans, (y - 0.3, 0.6), facecolors=color, edgecolors="none")
        # the label on each tracked segment
        lbl = np.where(d.scored[:, v], insp.assigned[:, v], -1)
        change = np.flatnonzero(np.diff(np.concatenate([[-1], lbl])) != 0)
        for k in change:
            if lbl[k] >= 0:
                ax.text(float(d.t[k]) + 0.012 * span, y, str(int(lbl[k])), fontsize=7, va="center", ha="left",
                        color="white", fontweight="bold", clip_on=True, zorder=4)
    marks = {
        "first_lidar": dict(marker="|", color="k", ms=9, mew=1.5),
        "confirmed": dict(marker="^", color="#2ca02c", mec="k", ms=7),
        "label_change": dict(marker="D", color="#1f77b4", mec="k", ms=6),
        "lost": dict(marker="X", color="#d62728", mec="k", ms=8),
        "coasting": dict(marker="v", color="#ff7f0e", mec="k", ms=7),
        "never_tracked": dict(marker="s", color="#d62728", mec="k", ms=6),
    }
    short = {OCCLUDED: "occl", FAILED_GATE: "gate", MERGED: "merge", NEWBORN: "newborn", MOVED: "moved",
             REACQUIRED: "re-acq", OUT_OF_RANGE_CAUSE: "range"}
    notes: dict[int, list[tuple[float, list[str]]]] = {}
    for e in insp.events:
        if e.event not in marks:
            continue
        v = int(np.searchsorted(d.vehicle_ids, e.truth_id))
        y = y_of[v]
        style = dict(marks[e.event])
        if e.event == "lost" and e.cause == OUT_OF_RANGE_CAUSE:
            style.update(color="0.6", mec="0.4", ms=6)
        ax.plot([e.t], [y], ls="none", zorder=5, **style)
        if e.event in ("lost", "label_change") and e.cause != OUT_OF_RANGE_CAUSE:
            text = short.get(e.cause, e.cause) if e.event == "lost" else f"→{e.label} {short.get(e.cause, e.cause)}"
            group = notes.setdefault(y, [])
            if group and e.t - group[-1][0] < 0.06 * span:  # close events share one annotation
                group[-1][1].append(text)
            else:
                group.append((e.t, [text]))
    for y, group in notes.items():
        for j, (t0, texts) in enumerate(group):
            below = j % 2 == 0  # alternate below / above the bar
            ax.text(t0, y + (0.34 if below else -0.34), ", ".join(dict.fromkeys(texts)), fontsize=6.5, ha="center",
                    va="top" if below else "bottom", color="#222222", clip_on=True, zorder=6)
    ax.set_yticks(range(len(cols)), [f"vehicle {int(d.vehicle_ids[v])}" for v in cols], fontsize=8)
    for tick, v in zip(ax.get_yticklabels(), cols):
        tick.set_color(vehicle_color(int(d.vehicle_ids[v])))
        tick.set_fontweight("bold")
    ax.set_ylim(len(cols) - 0.4, -0.9)
    t_start = float(d.t[0]) if len(d.t) else 0.0
    pad = 0.012 * span  # room for the markers at the first and last frame
    ax.set_xlim(t_start - pad, t_end + pad)
    ax.grid(axis="x", alpha=0.3)
    ax.tick_params(labelbottom=False)
    ax.set_ylabel("vehicle (id)", fontsize=8)
    if len(cols) == 0:
        ax.text(0.5, 0.5, "no vehicle was in range", transform=ax.transAxes, ha="center", va="center")
    ax.set_title(f"{d.title}: vehicle timelines (bar = state, white number = track label)", fontsize=10)
    handles = [Patch(facecolor=c, label=n) for n, c in zip(STATE_NAMES, STATE_COLORS)]
    handles += [Line2D([], [], ls="none", label=k.replace("_", " "), **v) for k, v in marks.items()]
    fig.legend(handles=handles, loc="upper center", ncol=6, fontsize=7.5, frameon=False, bbox_to_anchor=(0.5, 1.0))

    ax_g.plot(d.t, d.gospa, color="k", lw=1.2, label="GOSPA")
    ax_g.axhline(insp.threshold, color="0.4", ls="--", lw=0.8, label=f"worst-interval\nthreshold {insp.threshold:.2f} m")
    top = max(float(np.max(d.gospa, initial=1.0)) * 1.15 + 0.1, 1.1 * insp.threshold)
    for iv in insp.intervals:
        ax_g.axvspan(iv.t_start, iv.t_end + dt, color=CAUSE_COLORS[GOSPA_CAUSES.index(iv.dominant)], alpha=0.25)
        ax_g.text(iv.t_start, top * 0.97, f"#{iv.rank}", fontsize=7, va="top")
    ax_g.set_ylim(0.0, top)
    ax_g.set_ylabel("GOSPA (m)")
    outside = dict(loc="upper left", bbox_to_anchor=(1.005, 1.0), fontsize=7, frameon=False)
    ax_g.legend(**outside)
    ax_g.grid(alpha=0.3)
    ax_g.tick_params(labelbottom=False)
    gospa_text = f"GOSPA (alpha 2, p {d.p:g}, c {d.c:g} m) per frame"
    if insp.intervals:
        shaded = f"{len(insp.intervals)} worst interval{'s' if len(insp.intervals) != 1 else ''} shaded (#rank; colour = dominant cause)"
    else:
        shaded = f"no frame reaches the threshold {insp.threshold:.2f} m: no worst interval"
    ax_g.set_title(f"{gospa_text}; {shaded}", fontsize=8.5)
    if len(d.t):
        ax_c.stackplot(d.t, insp.cause_cost.T, colors=CAUSE_COLORS, labels=GOSPA_CAUSES, step="post", alpha=0.85)
    ax_c.set_ylim(bottom=0.0)
    ax_c.set_ylabel(f"GOSPA^{d.p:g} (m^{d.p:g})", fontsize=8)
    ax_c.set_xlabel("t (s)")
    ax_c.set_title(f"GOSPA^{d.p:g} per frame split by cause (stacked)", fontsize=8.5)
    ax_c.legend(**outside)
    ax_c.grid(alpha=0.3)
    fig.subplots_adjust(left=0.07, right=0.85, top=1.0 - 0.8 / fig.get_figheight(), bottom=0.55 / fig.get_figheight() + 0.02)
    return fig


def write_inspection(insp: Inspection, out: str | Path) -> dict[str, Path]:
    """Write ``events.csv``, ``worst_intervals.csv`` and ``events.png`` of ``insp`` into ``out``
    (created if needed); returns the paths by name."""
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    paths = {"events": folder / "events.csv", "worst_intervals": folder / "worst_intervals.csv",
             "events_png": folder / "events.png"}
    with open(paths["events"], "w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        writer.writerow(EVENT_COLUMNS)
        writer.writerows(e.row() for e in insp.events)
    with open(paths["worst_intervals"], "w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        writer.writerow(INTERVAL_COLUMNS)
        writer.writerows(iv.row() for iv in insp.intervals)
    plot_events(insp, paths["events_png"])
    return paths


__all__ = [
    "COAST_MIN_FRAMES",
    "COSTLIEST_COUNT",
    "EVENT_COLUMNS",
    "GOSPA_CAUSES",
    "INTERVAL_COLUMNS",
    "Event",
    "InspectError",
    "Inspection",
    "Interval",
    "LOSS_CONTEXT_S",
    "MERGE_RADIUS_M",
    "NEAR_VEHICLE_M",
    "REPLACE_WINDOW_S",
    "RunData",
    "STATE_NAMES",
    "analyse",
    "attribute_gospa",
    "default_threshold",
    "events_figure",
    "find_events",
    "headline",
    "inspect_run",
    "load_run",
    "plot_events",
    "summary_text",
    "vehicle_costs",
    "vehicle_line",
    "vehicle_states",
    "worst_intervals",
    "write_inspection",
]
