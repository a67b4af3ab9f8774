"""The lane graph: lanelets (lane pieces bounded by two polylines) and how they connect.

Every map reader (CommonRoad, Lanelet2, OpenDRIVE) returns a ``LaneGraph``. Coordinates are metres in
one Cartesian map frame. A lanelet's ``left`` and ``right`` boundaries are polylines ordered in its
driving direction (first point at its entry); ``left`` is on the left of a vehicle driving it.

Topology:

- ``successors`` / ``predecessors``: lanelets a vehicle drives into at the exit / came from at the entry;
- ``left_neighbor`` / ``right_neighbor``: the lanelet beside it sharing its left / right boundary, with
  ``left_same_direction`` / ``right_same_direction`` telling whether its traffic drives the same way
  (False: oncoming). Lanes crossing in an intersection are never neighbours.

Pure numpy (scipy for the k-d tree); no map library is imported here.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

#: Kinds of lanelet. ``driving`` covers every lane motor vehicles drive in (urban, highway, ramps,
#: bus lanes); ``parking`` and ``shoulder`` are drivable surface beside them; the rest are not road.
KINDS = ("driving", "parking", "shoulder", "sidewalk", "bicycle", "crosswalk", "other")
#: Kinds a route's corridor (``tracker.maps.route``) may hold: the lane kinds of ``tracker.lanes.LaneLayout``.
ROAD_KINDS = ("driving", "parking", "shoulder")


def _polyline_lengths(xy: np.ndarray) -> np.ndarray:
    """Cumulative arc length (P,) m of a polyline (P, 2), starting at 0."""
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])


def resample(xy: np.ndarray, count: int) -> np.ndarray:
    """``count`` points at equal arc-length fractions along the polyline ``xy`` (P, 2), ends kept."""
    cum = _polyline_lengths(xy)
    if cum[-1] <= 0.0:
        return np.repeat(xy[:1], count, axis=0)
    t = np.linspace(0.0, cum[-1], count)
    return np.column_stack([np.interp(t, cum, xy[:, 0]), np.interp(t, cum, xy[:, 1])])


def densify(xy: np.ndarray, spacing: float) -> np.ndarray:
    """The polyline ``xy`` (P, 2) with points added so that no segment exceeds ``spacing`` m; every
    original vertex is kept."""
    seg = np.hypot(*np.diff(xy, axis=0).T)
    pieces = np.maximum(np.ceil(seg / spacing).astype(int), 1)
    frac = np.concatenate([np.arange(p) / p for p in pieces])  # one short array per segment, not per point
    start = np.repeat(np.arange(len(seg)), pieces)
    out = xy[start] + frac[:, None] * (xy[start + 1] - xy[start])
    return np.vstack([out, xy[-1:]])


def centerline_of(left: np.ndarray, right: np.ndarray) -> np.ndarray:
    """The centerline of a lanelet: midpoints of its two boundaries taken at equal arc-length
    fractions (vertex by vertex when both have the same number of points)."""
    if len(left) != len(right):
        count = max(len(left), len(right))
        left, right = resample(left, count), resample(right, count)
    return 0.5 * (left + right)


@dataclass(frozen=True, eq=False)
class Lanelet:
    """One lanelet: a lane piece between a ``left`` and a ``right`` boundary polyline ((P, 2) and
    (Q, 2) m, ordered in the driving direction), with its topology and kind (one of ``KINDS``).
    ``center`` (R, 2) m is computed from the boundaries when not given. ``source`` names the map
    element it came from (e.g. ``"lanelet 3021"`` or ``"road 5 section 0 lane -1"``)."""

    id: int
    left: np.ndarray
    right: np.ndarray
    predecessors: tuple[int, ...] = ()
    successors: tuple[int, ...] = ()
    left_neighbor: int | None = None
    left_same_direction: bool = True
    right_neighbor: int | None = None
    right_same_direction: bool = True
    kind: str = "driving"
    center: np.ndarray | None = None
    source: str = ""

    def __post_init__(self) -> None:
        for name in ("left", "right"):
            object.__setattr__(self, name, np.asarray(getattr(self, name), dtype=float))
        if self.center is None and self.left.ndim == 2 and self.right.ndim == 2 and min(len(self.left), len(self.right)) >= 2:
            object.__setattr__(self, "center", centerline_of(self.left, self.right))
        elif self.center is not None:
            object.__setattr__(self, "center", np.asarray(self.center, dtype=float))
        if not self.source:
            object.__setattr__(self, "source", f"lanelet {self.id}")

    @property
    def length(self) -> float:
        """Length of the centerline (m)."""
        return float(_polyline_lengths(self.center)[-1])

    def polygon(self) -> np.ndarray:
        """The lanelet's outline (P + Q, 2) m: left boundary forward, right boundary backward."""
        return np.vstack([self.left, self.right[::-1]])


@dataclass(eq=False)
class LaneGraph:
    """Lanelets of a map and their connections; validated when built.

    ``source`` names the map (a file name) in error messages. Look-ups: ``lanelet(id)``,
    ``locate(xy)`` (which lanelet holds each point), ``contains(xy, ids)``, ``heading_at(id, xy)``.
    """

    lanelets: Sequence[Lanelet]
    source: str = "map"
    _by_id: dict[int, Lanelet] = field(init=False, repr=False)
    _position: dict[int, int] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.lanelets = tuple(self.lanelets)
        self._by_id = {}
        for ll in self.lanelets:
            if ll.id in self._by_id:
                raise ValueError(f"{self.source}: two lanelets have the id {ll.id}")
            self._by_id[ll.id] = ll
        self._position = {ll.id: k for k, ll in enumerate(self.lanelets)}
        for ll in self.lanelets:
            self._check(ll)
        self._index_ids = np.array([ll.id for ll in self.lanelets], dtype=np.int64)
        self._polygons = [ll.polygon() for ll in self.lanelets]
        self._boxes = np.array([[*p.min(axis=0), *p.max(axis=0)] for p in self._polygons])

    def _check(self, ll: Lanelet) -> None:
        where = f"{self.source}: {ll.source}"
        for name in ("left", "right"):
            pts = getattr(ll, name)
            if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2:
                count = 0 if pts.ndim != 2 else len(pts)
                raise ValueError(f"{where} has a {name} boundary of {count} point{'s' if count != 1 else ''}; need at least 2")
            if not np.isfinite(pts).all():
                raise ValueError(f"{where} has a non-finite point in its {name} boundary")
        if ll.kind not in KINDS:
            raise ValueError(f"{where} has kind {ll.kind!r}; expected one of {', '.join(KINDS)}")
        for relation in ("successors", "predecessors"):
            for other in getattr(ll, relation):
                if other not in self._by_id:
                    raise ValueError(f"{where} names {relation[:-1]} {other}, which is not in the map")
        for side in ("left", "right"):
            other = getattr(ll, f"{side}_neighbor")
            if other is not None and other not in self._by_id:
                raise ValueError(f"{where} names {side} neighbour {other}, which is not in the map")

    # -- look-ups ---------------------------------------------------------------------------------
    def __len__(self) -> int:
        return len(self.lanelets)

    def __iter__(self):
        return iter(self.lanelets)

    @property
    def ids(self) -> np.ndarray:
        """Lanelet ids (L,) in the order of ``lanelets``."""
        return self._index_ids.copy()

    def lanelet(self, lanelet_id: int) -> Lanelet:
        """The lanelet with this id (KeyError naming the map if absent)."""
        try:
            return self._by_id[int(lanelet_id)]
        except KeyError:
            raise KeyError(f"{self.source}: no lanelet {lanelet_id}") from None

    def contains(self, xy: np.ndarray, ids: Iterable[int] | None = None) -> np.ndarray:
        """(N, L') bool: whether each point ``xy`` (N, 2) m lies inside each lanelet of ``ids``
        (default: all, in the order of ``lanelets``). Even-odd rule on the lanelet outlines."""
        pts = np.atleast_2d(np.asarray(xy, dtype=float))
        order = range(len(self.lanelets)) if ids is None else [self._position[int(i)] for i in ids]
        out = np.zeros((len(pts), len(order)), dtype=bool)
        for col, k in enumerate(order):  # a loop over lanelets; each test is vectorised over points
            x0, y0, x1, y1 = self._boxes[k]
            near = np.flatnonzero((pts[:, 0] >= x0) & (pts[:, 0] <= x1) & (pts[:, 1] >= y0) & (pts[:, 1] <= y1))
            if len(near):
                out[near, col] = points_in_polygon(pts[near], self._polygons[k])
        return out

    def locate(self, xy: np.ndarray, yaw: np.ndarray | None = None, max_turn: float = 0.5 * np.pi) -> np.ndarray:
        """Id (N,) of a lanelet holding each point ``xy`` (N, 2) m, -1 where none does. With ``yaw``
        (N,) rad, only lanelets whose local heading is within ``max_turn`` rad (default 90 deg) count,
        and of several the one whose heading is closest wins; without, the first in map order."""
        pts = np.atleast_2d(np.asarray(xy, dtype=float))
        inside = self.contains(pts)
        if yaw is None:
            first = np.argmax(inside, axis=1)
            return np.where(inside.any(axis=1), self._index_ids[first], -1)
        yaw = np.broadcast_to(np.asarray(yaw, dtype=float), (len(pts),))
        cost = np.full(inside.shape, np.inf)
        rows, cols = np.nonzero(inside)
        for k in np.unique(cols):  # per lanelet holding a point: its heading at those points
            sel = rows[cols == k]
            heading = self.heading_at(self.lanelets[k].id, pts[sel])
            turn = np.abs(np.angle(np.exp(1j * (heading - yaw[sel]))))
            cost[sel, k] = np.where(turn <= max_turn, turn, np.inf)
        best = np.argmin(cost, axis=1)
        return np.where(np.isfinite(cost[np.arange(len(pts)), best]), self._index_ids[best], -1)

    def heading_at(self, lanelet_id: int, xy: np.ndarray) -> np.ndarray:
        """Driving direction (N,) rad of lanelet ``lanelet_id`` at the centerline segment nearest to
        each point ``xy`` (N, 2) m."""
        c = self.lanelet(lanelet_id).center
        a, d = c[:-1], np.diff(c, axis=0)
        seg = _nearest_segment(np.atleast_2d(xy), a, d)
        return np.arctan2(d[seg, 1], d[seg, 0])


def _nearest_segment(pts: np.ndarray, a: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Index (N,) of the segment ``a + t d`` (S segments) nearest to each point (N, 2)."""
    dd = np.maximum(np.einsum("ij,ij->i", d, d), 1e-12)
    rel = pts[:, None, :] - a[None, :, :]
    t = np.clip(np.einsum("nsj,sj->ns", rel, d) / dd, 0.0, 1.0)
    gap = rel - t[..., None] * d[None]
    return np.argmin(np.einsum("nsj,nsj->ns", gap, gap), axis=1)


def point_polyline_distance(pts: np.ndarray, line: np.ndarray, chunk: int = 4096) -> np.ndarray:
    """Distance (N,) m from each point (N, 2) to the polyline ``line`` (P, 2)."""
    a, d = line[:-1], np.diff(line, axis=0)
    dd = np.maximum(np.einsum("ij,ij->i", d, d), 1e-12)
    out = np.empty(len(pts))
    for lo in range(0, len(pts), chunk):  # chunks bound the (N, S) work arrays
        rel = pts[lo:lo + chunk, None, :] - a[None]
        t = np.clip(np.einsum("nsj,sj->ns", rel, d) / dd, 0.0, 1.0)
        gap = rel - t[..., None] * d[None]
        out[lo:lo + chunk] = np.sqrt(np.einsum("nsj,nsj->ns", gap, gap).min(axis=1))
    return out


def points_in_polygon(pts: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """(N,) bool: each point (N, 2) inside the closed polygon (V, 2) by the even-odd rule."""
    x1, y1 = polygon[:, 0], polygon[:, 1]
    x2, y2 = np.roll(x1, -1), np.roll(y1, -1)
    px, py = pts[:, 0:1], pts[:, 1:2]
    straddle = (y1 > py) != (y2 > py)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_cross = x1 + (py - y1) * (x2 - x1) / (y2 - y1)
    return (np.count_nonzero(straddle & (px < x_cross), axis=1) % 2) == 1


def xml_root(path: Path, tag: str | None = None) -> ET.Element:
    """The root element of the XML map file ``path`` (standard library), or a one-line ``ValueError``
    naming the file: not well-formed, or a root other than ``<tag>``."""
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as err:
        raise ValueError(f"{path.name}: not well-formed XML ({err})") from None
    if tag is not None and root.tag != tag:
        raise ValueError(f"{path.name}: root element is <{root.tag}>, not <{tag}>")
    return root
