"""How the tracker lives through a lidar dropout (a scenario's ``[faults]`` ``lidar_dropout``
intervals, applied by ``sim.sensors.faults.FaultInjector``), measured from a run's scored frames.

**Dropout measures** (``dropout_outcomes``; for each ``lidar_dropout`` interval ``[a, b)``): the
vehicles *tracked before* are those GOSPA-assigned to a track in the last frame before ``a``; of
those, the *eligible* ones are still in the scored truth set at the end of the re-acquisition window,
the first frame at or after ``b + window_s``. A vehicle *coasted* when its track's label is still
reported in the last frame before ``b``; it was *re-acquired with its label* when, in that
end-of-window frame, it is GOSPA-assigned to a track with the same label as before the dropout.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from sim.evaluation.records import FrameRecord

#: Default re-acquisition window (s) after a lidar dropout ends.
REACQUIRE_WINDOW_S = 1.0


@dataclass(frozen=True)
class DropoutOutcome:
    """One vehicle across one lidar dropout ``[start, end)`` (s): its truth ``vehicle_id``, the
    ``label`` of its track before the dropout, whether that track ``coasted`` (still reported at the
    dropout's last frame) and whether it was ``reacquired`` with that label at ``check_t`` (s), the
    end of the re-acquisition window; ``label_after`` is the label assigned to it then (-1: none)."""

    start: float
    end: float
    vehicle_id: int
    label: int
    coasted: bool
    reacquired: bool
    label_after: int
    check_t: float


def dropout_outcomes(records: Sequence[FrameRecord], intervals: Sequence[tuple[float, float]],
                     window_s: float = REACQUIRE_WINDOW_S) -> list[DropoutOutcome]:
    """Per lidar dropout interval and eligible vehicle, what happened (module docstring). Intervals
    without a frame before them or without a frame at or after ``end + window_s`` are skipped."""
    if not window_s >= 0.0:
        raise ValueError(f"window_s must be >= 0 s; got {window_s!r}")
    times = np.array([r.t for r in records])
    out: list[DropoutOutcome] = []
    for start, end in intervals:
        before = np.flatnonzero(times < start - 1e-9)
        during = np.flatnonzero((times >= start - 1e-9) & (times < end - 1e-9))
        after = np.flatnonzero(times >= end + window_s - 1e-9)
        if not len(before) or not len(after):
            continue
        rec_before = records[before[-1]]
        rec_check = records[after[0]]
        rec_last = records[during[-1]] if len(during) else rec_before
        reported_last = {tr.label for tr in rec_last.tracks}
        check_scored = set(int(i) for i in rec_check.truth.ids[rec_check.scored])
        check_label = {int(vid): int(tr.label) for tr, vid in zip(rec_check.tracks, rec_check.track_truth_id) if vid >= 0}
        for tr, vid in zip(rec_before.tracks, rec_before.track_truth_id):
            if vid < 0 or int(vid) not in check_scored:
                continue
            after_label = check_label.get(int(vid), -1)
            out.append(DropoutOutcome(
                start=float(start), end=float(end), vehicle_id=int(vid), label=int(tr.label),
                coasted=int(tr.label) in reported_last, reacquired=after_label == int(tr.label),
                label_after=after_label, check_t=float(rec_check.t),
            ))
    return out


def dropout_metrics(outcomes: Sequence[DropoutOutcome]) -> dict[str, Any]:
    """``fault_dropout_vehicles`` (eligible vehicles over all dropouts), ``fault_dropout_coasted``,
    ``fault_dropout_reacquired`` (counts) and ``fault_dropout_reacquired_fraction`` (``None`` when no
    vehicle was eligible)."""
    n = len(outcomes)
    reacquired = sum(o.reacquired for o in outcomes)
    return {
        "fault_dropout_vehicles": n,
        "fault_dropout_coasted": sum(o.coasted for o in outcomes),
        "fault_dropout_reacquired": reacquired,
        "fault_dropout_reacquired_fraction": reacquired / n if n else None,
    }


__all__ = ["REACQUIRE_WINDOW_S", "DropoutOutcome", "dropout_metrics", "dropout_outcomes"]
