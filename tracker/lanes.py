"""Lanes across a road as functions of arc length: ``LaneLayout``, and the kernel that reads its edges.

A layout holds ``M`` lanes side by side across the road. At each of ``K`` stations ``s_k`` (m along the
centerline) it gives the lateral offsets ``n`` (m, positive to the left of the centerline's direction)
of the ``M + 1`` lane boundaries, rightmost first; lane ``j`` lies between boundaries ``j`` and
``j + 1``. Between stations the boundaries are linear in ``s``; before the first station and after the
last they hold their end values. A lane of zero width at a station does not exist there: lanes that
begin and end (an auxiliary lane, a turning pocket, a merge) taper to zero width.

Each lane has a direction, ``+1`` when its traffic drives along ``s`` and ``-1`` against it (the
oncoming lanes of a two-way road), and a kind: ``"driving"``, ``"parking"`` or ``"shoulder"``. Every
kind is road surface (``Road.on_road``); road births are placed in driving lanes only.

``Road`` resamples a layout on a uniform table of edges (``edge_table``) that the compiled stages read
with ``edge_at``: one multiply, one floor and one linear interpolation per point.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Literal

import numpy as np

from tracker.checks import finite_array
from tracker.jit import njit

#: The lane kinds a layout knows; all are road surface, road births use ``"driving"`` lanes only.
KINDS = ("driving", "parking", "shoulder")
#: A lane narrower than this at a station is absent there (m): it begins, ends or is a taper's tip.
MIN_LANE_WIDTH = 0.5
#: Station spacing of the edge table a ``Road`` samples from a layout whose lanes vary along ``s`` (m).
EDGE_TABLE_STEP = 0.1


class LaneLayout:
    """``M`` lanes across a road, their boundaries functions of ``s`` (module docstring).

    ``stations (K,)`` arc lengths (m, strictly increasing; one station: the same lanes everywhere);
    ``boundaries (K, M + 1)`` lateral offsets (m) of the lane boundaries, rightmost first and
    non-decreasing across each row; ``directions (M,)`` +1 along ``s``, -1 against (default all +1);
    ``kinds (M,)`` from ``KINDS`` (default all ``"driving"``).
    """

    def __init__(self, stations: Sequence[float] | np.ndarray, boundaries: Sequence[Sequence[float]] | np.ndarray,
                 directions: Sequence[int] | np.ndarray | None = None, kinds: Sequence[str] | None = None) -> None:
        st = finite_array(stations, "LaneLayout.stations").reshape(-1)
        bd = finite_array(boundaries, "LaneLayout.boundaries")
        if bd.ndim == 1:
            bd = bd[None, :]
        if len(st) == 0:
            raise ValueError("LaneLayout.stations must hold at least one arc length; got none")
        if bd.ndim != 2 or bd.shape[0] != len(st) or bd.shape[1] < 2:
            raise ValueError(f"LaneLayout.boundaries must have shape ({len(st)}, M + 1) with M >= 1 lanes, one row "
                             f"per station; got {bd.shape}")
        if len(st) > 1 and np.any(np.diff(st) <= 0.0):
            i = int(np.argmax(np.diff(st) <= 0.0))
            raise ValueError(f"LaneLayout.stations must increase strictly; station {i + 1} ({st[i + 1]!r} m) does not "
                             f"follow station {i} ({st[i]!r} m)")
        crossed = np.diff(bd, axis=1) < -1e-9
        if crossed.any():
            k, j = (int(i) for i in np.argwhere(crossed)[0])
            raise ValueError(f"LaneLayout.boundaries must not decrease across a row: at station {k} ({st[k]!r} m) "
                             f"boundary {j + 1} ({bd[k, j + 1]!r} m) lies right of boundary {j} ({bd[k, j]!r} m)")
        lanes = bd.shape[1] - 1
        if directions is None:
            dirs = np.ones(lanes, dtype=np.int64)
        else:
            dirs = np.asarray(directions).reshape(-1)
            if dirs.shape != (lanes,) or dirs.dtype.kind not in "iu" or not np.isin(dirs, (-1, 1)).all():
                raise ValueError(f"LaneLayout.directions must be {lanes} values of +1 (along s) or -1 (against s); "
                                 f"got {np.asarray(directions).tolist()!r}")
            dirs = dirs.astype(np.int64)
        if kinds is None:
            kind_t = ("driving",) * lanes
        else:
            kind_t = tuple(kinds)
            if len(kind_t) != lanes:
                raise ValueError(f"LaneLayout.kinds must name {lanes} lanes; got {len(kind_t)}")
            for j, k in enumerate(kind_t):
                if k not in KINDS:
                    raise ValueError(f"LaneLayout.kinds[{j}] must be one of {', '.join(KINDS)}; got {k!r}")
        if not (np.diff(bd, axis=1) >= MIN_LANE_WIDTH).any(axis=1).any():
            raise ValueError(f"LaneLayout.boundaries hold no lane at least {MIN_LANE_WIDTH} m wide anywhere")
        self.stations = st
        self.boundaries = np.maximum.accumulate(bd, axis=1)
        self.directions = dirs
        self.kinds = kind_t
        for arr in (self.stations, self.boundaries, self.directions):
            arr.flags.writeable = False

    @classmethod
    def uniform(cls, lanes: int = 2, lane_width: float = 3.5, right_edge: float | None = None, *, oncoming: int = 0,
                drive_on: Literal["right", "left"] = "right") -> LaneLayout:
        """``lanes`` lanes of ``lane_width`` metres from ``right_edge`` (m; default ``-lanes * lane_width / 2``:
        the centerline down the middle), the same everywhere. ``oncoming`` of them carry traffic against
        ``s``: the leftmost ones for right-hand traffic (``drive_on = "right"``), the rightmost for
        left-hand traffic."""
        if isinstance(lanes, bool) or not isinstance(lanes, (int, np.integer)) or lanes < 1:
            raise ValueError(f"lanes must be a positive integer; got {lanes!r}")
        if not (isinstance(lane_width, (int, float, np.floating)) and math.isfinite(lane_width)) or lane_width <= 0:
            raise ValueError(f"lane_width must be a positive finite number of metres; got {lane_width!r}")
        if right_edge is not None and not math.isfinite(right_edge):
            raise ValueError(f"right_edge must be finite; got {right_edge!r}")
        if isinstance(oncoming, bool) or not isinstance(oncoming, (int, np.integer)) or not 0 <= oncoming <= lanes:
            raise ValueError(f"oncoming must be an integer number of lanes in 0..{lanes}; got {oncoming!r}")
        if drive_on not in ("right", "left"):
            raise ValueError(f"drive_on must be 'right' or 'left'; got {drive_on!r}")
        right = -0.5 * lanes * lane_width if right_edge is None else float(right_edge)
        bounds = right + np.arange(lanes + 1) * float(lane_width)
        dirs = np.ones(lanes, dtype=np.int64)
        if oncoming:
            if drive_on == "right":
                dirs[lanes - oncoming:] = -1
            else:
                dirs[:oncoming] = -1
        layout = cls([0.0], bounds[None, :], dirs)
        layout._uniform = (int(lanes), float(lane_width), right)
        return layout

    # -- what the layout holds --------------------------------------------------------------------
    @property
    def lanes(self) -> int:
        """Number of lane slots ``M`` (the most lanes side by side anywhere)."""
        return self.boundaries.shape[1] - 1

    @property
    def varies(self) -> bool:
        """Whether the boundaries change along ``s`` (False: the same lanes everywhere)."""
        return bool(len(self.stations) > 1 and np.ptp(self.boundaries, axis=0).max() > 0.0)

    @property
    def two_way(self) -> bool:
        """Whether some lane carries traffic against ``s``."""
        return bool((self.directions < 0).any())

    def boundaries_at(self, s: np.ndarray | Sequence[float] | float) -> np.ndarray:
        """The lane boundaries at arc lengths ``s``: shape ``s.shape + (M + 1,)`` (m), linear between stations."""
        s_arr = np.asarray(s, dtype=float)
        flat = s_arr.reshape(-1)
        if len(self.stations) == 1:
            out = np.broadcast_to(self.boundaries[0], (len(flat), self.lanes + 1)).copy()
        else:
            out = np.column_stack([np.interp(flat, self.stations, self.boundaries[:, j]) for j in range(self.lanes + 1)])
        return out.reshape(s_arr.shape + (self.lanes + 1,))

    def centers_at(self, s: np.ndarray | Sequence[float] | float) -> np.ndarray:
        """Each lane's centre offset at arc lengths ``s``: shape ``s.shape + (M,)`` (m), NaN where the lane
        is narrower than ``MIN_LANE_WIDTH`` (absent)."""
        b = self.boundaries_at(s)
        centre = 0.5 * (b[..., 1:] + b[..., :-1])
        return np.where(b[..., 1:] - b[..., :-1] >= MIN_LANE_WIDTH, centre, np.nan)

    def edge_table(self, length: float, closed: bool) -> tuple[float, np.ndarray, np.ndarray]:
        """The outermost edges of the lanes present, sampled uniformly over ``[0, length]``: ``(inv_step,
        right (T,), left (T,))`` for ``edge_at`` (``inv_step`` in 1/m; ``T = 2`` when nothing varies).
        A station's edges span the lanes at least ``MIN_LANE_WIDTH`` wide there, or all of them where
        none is (the road's full width, never empty)."""
        if not self.varies:
            b = self.boundaries[0]
            count = 2
            right, left = np.full(count, b[0]), np.full(count, b[-1])
        else:
            count = max(2, math.ceil(length / EDGE_TABLE_STEP) + 1)
            s = np.linspace(0.0, length, count)
            if closed:
                s[-1] = 0.0  # the table's last station is the first one again
            b = self.boundaries_at(s)
            present = (b[:, 1:] - b[:, :-1]) >= MIN_LANE_WIDTH
            none = ~present.any(axis=1)
            present[none] = True
            lo = np.where(present, b[:, :-1], np.inf).min(axis=1)
            hi = np.where(present, b[:, 1:], -np.inf).max(axis=1)
            right, left = lo, hi
        right.flags.writeable = False
        left.flags.writeable = False
        return (count - 1) / length, right, left


@njit(inline="always")
def edge_at(s, inv_step, table):  # pragma: no cover - compiled
    """The edge ``table (T,)`` (``LaneLayout.edge_table``) at arc length ``s`` (m): linear between its
    stations, held at the ends; exactly the table's value where neighbouring entries are equal."""
    u = s * inv_step
    last = table.shape[0] - 1
    if u <= 0.0:
        return table[0]
    if u >= last:
        return table[last]
    i = int(u)
    if i >= last:
        i = last - 1
    t = u - i
    return table[i] + t * (table[i + 1] - table[i])
