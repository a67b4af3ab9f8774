"""A route through a lane graph and the road a vehicle driving it perceives.

``route_lanelets`` finds the route: the lanelet holding the start pose (heading within 90 deg of the
lanelet's), then successors: a shortest path (by centerline length, a lane change costing
``LANE_CHANGE_COST`` m) to the goal or through the ``via`` points, or, without either, the straightest
successor at every join until the map ends. The route may begin in any same-direction lane beside the
start lanelet; a lane change later on is a step to a same-direction neighbour, and the centerline
moves across over that lanelet's length.

``route_corridor`` turns the route into arrays: the centerline (the route lanelets' centerlines
chained, resampled every ``spacing`` m and smoothed with a Gaussian of ``smoothing`` m so that a C1
spline through it has no kinks at the joins), and at stations every ``station_spacing`` m along it the
lateral offsets of the lane boundaries: the route lanelet and every lanelet chained to it by
left/right neighbour relations (same and opposite direction), each a lane whose two boundaries are
projected to ``(s, n)`` on the centerline. A lane that does not exist at a station (an auxiliary lane
before it begins, a turning pocket) has zero width there. Crossing lanes in an intersection are not
neighbours and stay off the road. ``route_road`` returns the ``tracker.Road``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from tracker.maps.graph import ROAD_KINDS, LaneGraph, _polyline_lengths, densify, resample
from tracker.lanes import LaneLayout
from tracker.road import Road

#: Spacing (m) of the chained centerline's samples, the spline's waypoints.
CENTERLINE_SPACING = 2.0
#: Standard deviation (m) of the Gaussian that smooths the chained centerline.
CENTERLINE_SMOOTHING = 2.0
#: Spacing (m) of the stations of the lane layout.
STATION_SPACING = 1.0
#: Spacing (m) to which boundary polylines are densified before they are projected.
BOUNDARY_SPACING = 1.0
#: A neighbour lanelet counts as present this far (m) beyond its projected ends (joins of lanelets
#: beside each other rarely project to exactly the same ``s``).
END_TOLERANCE = 1.0
#: Distance (m) between the two stations placed at every join of route lanelets.
JOIN_GAP = 0.01
#: Cost (m of driving) of one lane change in the route search: a lane change is taken where it saves
#: more than this.
LANE_CHANGE_COST = 20.0
#: Longest route followed without a goal (m).
MAX_ROUTE_LENGTH = 5000.0


@dataclass(frozen=True)
class Corridor:
    """The road of a route, as arrays.

    ``route`` (R,) lanelet ids driven, in order; ``centerline`` (P, 2) m the smoothed waypoints of the
    road's centerline; ``stations`` (K,) m arc lengths along it; ``boundaries`` (K, M+1) m lateral
    offsets (positive left) of the lane boundaries, rightmost first; ``directions`` (M,) +1 along the
    route, -1 oncoming; ``kinds`` (M,) lane kinds; ``lanes`` (K, M) id of the lanelet forming each lane
    at each station (-1 where the lane is absent); ``members`` every lanelet in the corridor;
    ``route_starts`` (R,) m the station where each route lanelet begins.
    """

    route: tuple[int, ...]
    centerline: np.ndarray
    stations: np.ndarray
    boundaries: np.ndarray
    directions: np.ndarray
    kinds: tuple[str, ...]
    lanes: np.ndarray
    members: frozenset[int]
    route_starts: np.ndarray
    road: Road


# -- route -------------------------------------------------------------------------------------------
def _start_lanelet(graph: LaneGraph, start: Sequence[float]) -> int:
    x, y, yaw = (float(v) for v in start)
    found = int(graph.locate(np.array([[x, y]]), np.array([yaw]))[0])
    if found < 0:
        raise ValueError(f"{graph.source}: the start ({x:.2f}, {y:.2f}) m, yaw {yaw:.3f} rad lies on no lanelet driven within 90 deg of that yaw")
    return found


def _same_direction_group(graph: LaneGraph, lanelet_id: int) -> list[int]:
    """The lanelet and every lanelet beside it reached through same-direction neighbours."""
    group, stack = [lanelet_id], [lanelet_id]
    while stack:
        ll = graph.lanelet(stack.pop())
        for other, same in ((ll.left_neighbor, ll.left_same_direction), (ll.right_neighbor, ll.right_same_direction)):
            if other is not None and same and other not in group:
                group.append(other)
                stack.append(other)
    return group


def _successor_matrix(graph: LaneGraph) -> csr_matrix:
    """Sparse (L, L) matrix of the route search: entry (i, j) = length of lanelet j (m) when j succeeds
    i, ``LANE_CHANGE_COST`` when j is a same-direction neighbour of i (a lane change)."""
    pos = {int(i): k for k, i in enumerate(graph.ids)}
    rows, cols, w = [], [], []
    for k, ll in enumerate(graph.lanelets):
        for nxt in ll.successors:
            rows.append(k)
            cols.append(pos[nxt])
            w.append(max(graph.lanelet(nxt).length, 1e-3))
        for other, same in ((ll.left_neighbor, ll.left_same_direction), (ll.right_neighbor, ll.right_same_direction)):
            if other is not None and same and graph.lanelet(other).kind == "driving":
                rows.append(k)
                cols.append(pos[other])
                w.append(LANE_CHANGE_COST)
    n = len(graph.lanelets)
    return csr_matrix((w, (rows, cols)), shape=(n, n))


def _shortest(graph: LaneGraph, matrix: csr_matrix, sources: list[int], targets: list[int], what: str) -> list[int]:
    """Lanelet ids of the shortest successor path from any of ``sources`` to any of ``targets``."""
    pos = {int(i): k for k, i in enumerate(graph.ids)}
    src = [pos[s] for s in sources]
    dist, pred, origin = dijkstra(matrix, indices=src, min_only=True, return_predecessors=True)
    tgt = [pos[t] for t in targets]
    best = min(tgt, key=lambda t: dist[t])
    if not np.isfinite(dist[best]):
        raise ValueError(f"{graph.source}: no route along successors from lanelet {sources[0]} to {what}")
    path = [best]
    while path[-1] != origin[best]:
        path.append(pred[path[-1]])
    return [int(graph.ids[k]) for k in path[::-1]]


def _straightest(graph: LaneGraph, first: int, max_length: float) -> list[int]:
    route, length = [first], graph.lanelet(first).length
    while length < max_length:
        ll = graph.lanelet(route[-1])
        options = [s for s in ll.successors if s not in route]
        if not options:
            break
        end = ll.center[-1] - ll.center[-2]
        heading = np.arctan2(end[1], end[0])

        def turn(sid: int) -> float:
            c = graph.lanelet(sid).center
            d = c[-1] - c[0]
            return abs(float(np.angle(np.exp(1j * (np.arctan2(d[1], d[0]) - heading)))))

        route.append(min(options, key=turn))
        length += graph.lanelet(route[-1]).length
    return route


def _straightest_back(graph: LaneGraph, first: int, length: float) -> list[int]:
    """Lanelets before ``first`` along the straightest predecessors, for ``length`` m or to the start of
    the map (nearest last; ``first`` not included)."""
    back: list[int] = []
    covered, current = 0.0, first
    while covered < length:
        ll = graph.lanelet(current)
        options = [p for p in ll.predecessors if p not in back and p != first]
        if not options:
            break
        start = ll.center[1] - ll.center[0]
        heading = np.arctan2(start[1], start[0])

        def turn(pid: int) -> float:
            c = graph.lanelet(pid).center
            d = c[-1] - c[0]
            return abs(float(np.angle(np.exp(1j * (np.arctan2(d[1], d[0]) - heading)))))

        current = min(options, key=turn)
        back.append(current)
        covered += graph.lanelet(current).length
    return back[::-1]


def route_lanelets(
    graph: LaneGraph,
    start: Sequence[float],
    goal: Sequence[float] | None = None,
    *,
    via: Sequence[Sequence[float]] | None = None,
    max_length: float = MAX_ROUTE_LENGTH,
    onward: float = 0.0,
    behind: float = 0.0,
) -> list[int]:
    """Ids of the lanelets a vehicle drives from ``start`` = (x m, y m, yaw rad) through the ``via``
    points (x, y) m to ``goal`` (x, y) m; without goal and via, the straightest way on until the
    map ends or ``max_length`` m. ``onward`` (m, default 0): after the last point, on along the
    straightest way for that far beyond the end of its lanelet, or to the end of the map (the road a
    sensor at the goal still sees ahead). ``behind`` (m, default 0): the route begins that far before
    the start of the route's first lanelet (``start``'s, or the same-direction lane beside it where the
    route begins), along the straightest predecessors where the map has them (the road a sensor at the
    start sees behind it)."""
    first = _start_lanelet(graph, start)
    after = _route_from(graph, first, goal, via, max_length, onward)
    before = _straightest_back(graph, after[0], behind) if behind > 0.0 else []
    return before + after


def _route_from(graph: LaneGraph, first: int, goal: Sequence[float] | None, via: Sequence[Sequence[float]] | None,
                max_length: float, onward: float) -> list[int]:
    points = [tuple(p) for p in (via or ())] + ([tuple(goal)] if goal is not None else [])
    if not points:
        return _straightest(graph, first, max_length)
    matrix = _successor_matrix(graph)
    route: list[int] = []
    sources = _same_direction_group(graph, first)
    for x, y in points:
        inside = graph.contains(np.array([[x, y]]))[0]
        targets = [int(i) for i in graph.ids[inside]]
        if not targets:
            raise ValueError(f"{graph.source}: the route point ({x:.2f}, {y:.2f}) m lies on no lanelet")
        if route and route[-1] in targets:
            continue
        leg = _shortest(graph, matrix, sources, targets, f"the point ({x:.2f}, {y:.2f}) m")
        route.extend(leg if not route else leg[1:])
        sources = [route[-1]]
    if onward > 0.0:
        route.extend(_straightest(graph, route[-1], graph.lanelet(route[-1]).length + onward)[1:])
    return route


# -- corridor ----------------------------------------------------------------------------------------
def _is_lateral(graph: LaneGraph, a: int, b: int) -> bool:
    """Whether ``b`` is a same-direction neighbour of ``a`` (a lane change), not its successor."""
    ll = graph.lanelet(a)
    return b not in ll.successors and b in _same_direction_group(graph, a)


def _blend(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """A lane change along a lanelet: from centerline ``a`` to centerline ``b`` beside it, with a
    weight rising as ``(1 - cos)/2`` over the lanelet (both resampled to equal arc-length fractions)."""
    count = max(len(a), len(b), 20)
    a, b = resample(a, count), resample(b, count)
    w = 0.5 - 0.5 * np.cos(np.linspace(0.0, np.pi, count))
    return (1.0 - w[:, None]) * a + w[:, None] * b


def _chained_centerline(graph: LaneGraph, route: list[int], spacing: float, smoothing: float) -> np.ndarray:
    parts: list[np.ndarray] = []
    i = 0
    while i < len(route):
        j = i
        while j + 1 < len(route) and _is_lateral(graph, route[j], route[j + 1]):
            j += 1
        c = graph.lanelet(route[i]).center if j == i else _blend(graph.lanelet(route[i]).center, graph.lanelet(route[j]).center)
        # drop a first point that repeats the end of the last piece (the shared join)
        parts.append(c[1:] if parts and np.hypot(*(c[0] - parts[-1][-1])) < 0.5 else c)
        i = j + 1
    pts = np.vstack(parts)
    keep = np.concatenate([[True], np.hypot(*np.diff(pts, axis=0).T) > 1e-6])
    pts = pts[keep]
    cum = _polyline_lengths(pts)
    count = max(int(np.ceil(cum[-1] / spacing)) + 1, 3)
    t = np.linspace(0.0, cum[-1], count)
    xy = np.column_stack([np.interp(t, cum, pts[:, 0]), np.interp(t, cum, pts[:, 1])])
    if smoothing > 0 and count > 4:
        sigma = smoothing / (t[1] - t[0])
        pad = int(np.ceil(4 * sigma))
        # point-reflected ends keep the ends and their tangents in place
        head = 2 * xy[0] - xy[1:pad + 1][::-1]
        tail = 2 * xy[-1] - xy[-pad - 1:-1][::-1]
        ext = np.vstack([head, xy, tail])
        xy = gaussian_filter1d(ext, sigma, axis=0, mode="nearest")[pad:pad + count]
    return xy


def _lateral_chain(graph: LaneGraph, route_id: int) -> list[tuple[int, tuple, int]]:
    """(lanelet id, column key, direction) of the route lanelet and every road lanelet chained to it
    sideways. Keys: ("C",), (side, "same", rank) for same-direction lanes next to the route, and
    (side, "outer", rank) for the lanes from the first oncoming one outward."""
    out = [(route_id, ("C",), 1)]
    seen = {route_id}
    for side in ("L", "R"):
        cur, rel, block, rank = graph.lanelet(route_id), 1, "same", 0
        while True:
            # the route's left is the current lanelet's left when it drives along, its right when oncoming
            go_left = (side == "L") == (rel == 1)
            nxt, same = (cur.left_neighbor, cur.left_same_direction) if go_left else (cur.right_neighbor, cur.right_same_direction)
            if nxt is None or nxt in seen:
                break
            nll = graph.lanelet(nxt)
            if nll.kind not in ROAD_KINDS:
                break
            rel = rel if same else -rel
            if block == "same" and rel == -1:
                block, rank = "outer", 0
            rank += 1
            out.append((nxt, (side, block, rank), rel))
            seen.add(nxt)
            cur = nll
    return out


def _continued_boundaries(graph: LaneGraph, lanelet_id: int) -> tuple[np.ndarray, np.ndarray]:
    """The lanelet's left and right boundaries, each continued by the same-side boundary of the
    predecessor that ends where it starts and of the successor that starts where it ends (nearest
    first point; none when the lanelet has none)."""
    ll = graph.lanelet(lanelet_id)
    out = []
    for side in ("left", "right"):
        own = getattr(ll, side)
        parts = [own]
        if ll.predecessors:
            before = min((getattr(graph.lanelet(p), side) for p in ll.predecessors), key=lambda b: np.hypot(*(b[-1] - own[0])))
            parts.insert(0, before[:-1])
        if ll.successors:
            after = min((getattr(graph.lanelet(q), side) for q in ll.successors), key=lambda b: np.hypot(*(b[0] - own[-1])))
            parts.append(after[1:])
        out.append(np.vstack(parts))
    return out[0], out[1]


def _column_order(keys: set) -> list[tuple]:
    def place(key: tuple) -> tuple:
        if key == ("C",):
            return (0, 0)
        side, block, rank = key
        sign = 1 if side == "L" else -1
        return (sign * (1 if block == "same" else 2), sign * rank)

    return sorted(keys, key=place)


def route_corridor(
    graph: LaneGraph,
    start: Sequence[float],
    goal: Sequence[float] | None = None,
    *,
    via: Sequence[Sequence[float]] | None = None,
    route: Sequence[int] | None = None,
    spacing: float = CENTERLINE_SPACING,
    smoothing: float = CENTERLINE_SMOOTHING,
    station_spacing: float = STATION_SPACING,
    max_length: float = MAX_ROUTE_LENGTH,
    onward: float = 0.0,
    behind: float = 0.0,
) -> Corridor:
    """The corridor of the route from ``start`` (x m, y m, yaw rad) to ``goal`` (x, y) m through
    ``via``, with ``onward`` and ``behind`` (see ``route_lanelets``), or of the given lanelet ids ``route``."""
    ids = list(route) if route is not None else route_lanelets(graph, start, goal, via=via, max_length=max_length,
                                                               onward=onward, behind=behind)
    for a, b in zip(ids[:-1], ids[1:]):
        if b not in graph.lanelet(a).successors and not _is_lateral(graph, a, b):
            raise ValueError(f"{graph.source}: lanelet {b} neither succeeds lanelet {a} nor lies beside it")
    xy = _chained_centerline(graph, ids, spacing, smoothing)
    road = Road.from_waypoints(xy)
    length = road.length
    # the station range of every route lanelet: from the projection of its entry
    entries = np.array([graph.lanelet(i).center[0] for i in ids])
    s_entry, _ = road.to_frenet(entries)
    s_entry[0] = -np.inf
    for k in range(1, len(ids)):
        if _is_lateral(graph, ids[k - 1], ids[k]):  # a lane change: the new lane owns the whole lanelet
            s_entry[k] = s_entry[k - 1]
    s_entry = np.maximum.accumulate(s_entry)
    # a regular grid plus a pair of stations JOIN_GAP apart at every join, so that lanes beginning or
    # ending there change within JOIN_GAP
    joins = s_entry[1:][(s_entry[1:] > JOIN_GAP) & (s_entry[1:] < length - JOIN_GAP)]
    grid = np.linspace(0.0, length, max(int(np.ceil(length / station_spacing)) + 1, 2))
    near = np.zeros(len(grid), dtype=bool)
    if len(joins):
        pos = np.clip(np.searchsorted(joins, grid), 1, len(joins)) - 1
        gap = np.minimum(np.abs(grid - joins[pos]), np.abs(grid - joins[np.minimum(pos + 1, len(joins) - 1)]))
        near = gap < 0.25 * station_spacing
        near[[0, -1]] = False
    stations = np.unique(np.concatenate([grid[~near], joins - JOIN_GAP, joins]))
    count = len(stations)
    owner = np.searchsorted(s_entry, stations, side="right") - 1

    owning = set(owner.tolist())  # a lanelet left by a lane change at its start owns no station
    chains = [_lateral_chain(graph, i) if r in owning else [] for r, i in enumerate(ids)]
    keys = {key for chain in chains for _, key, _ in chain}
    columns = _column_order(keys)
    col_of = {key: j for j, key in enumerate(columns)}
    m = len(columns)
    directions = np.zeros(m, dtype=int)
    kinds = [""] * m

    # project every member lanelet's boundaries (continued into the lanelets before and after it, so
    # that a join cut at a slant still has both boundaries) and centerline, in one to_frenet call
    members = sorted({lid for chain in chains for lid, _, _ in chain})
    lines = []
    for lid in members:
        lines.extend(densify(line, BOUNDARY_SPACING) for line in _continued_boundaries(graph, lid))
        lines.append(graph.lanelet(lid).center[[0, -1]])
    s_all, n_all = road.to_frenet(np.vstack(lines))
    cut = np.cumsum([len(p) for p in lines])[:-1]
    s_lines, n_lines = np.split(s_all, cut), np.split(n_all, cut)

    def profile(k: int, side: int, at: np.ndarray) -> np.ndarray:
        """Offset (m) of member k's boundary ``side`` (0 left, 1 right) at ``at``; NaN beyond the
        member's ends (its centerline's projected ends, widened by END_TOLERANCE)."""
        s, n = s_lines[3 * k + side], n_lines[3 * k + side]
        order = np.argsort(s)
        val = np.interp(at, s[order], n[order])
        lo, hi = np.sort(s_lines[3 * k + 2])
        return np.where((at >= lo - END_TOLERANCE) & (at <= hi + END_TOLERANCE), val, np.nan)

    lower = np.full((count, m), np.nan)
    upper = np.full((count, m), np.nan)
    lanes = np.full((count, m), -1, dtype=np.int64)
    index_of = {lid: k for k, lid in enumerate(members)}
    for r, chain in enumerate(chains):
        rows = np.flatnonzero(owner == r)
        if not len(rows):
            continue
        at = stations[rows]
        for lid, key, rel in chain:
            j = col_of[key]
            if not directions[j]:
                directions[j] = rel
                kinds[j] = graph.lanelet(lid).kind
            k = index_of[lid]
            a, b = profile(k, 0, at), profile(k, 1, at)
            ok = np.isfinite(a) & np.isfinite(b)
            lower[rows[ok], j] = np.minimum(a, b)[ok]
            upper[rows[ok], j] = np.maximum(a, b)[ok]
            lanes[rows[ok], j] = lid

    boundaries = _stack_boundaries(lower, upper, col_of[("C",)])
    layout = LaneLayout(stations, boundaries, directions, tuple(kinds))
    road = Road.from_waypoints(xy, layout=layout)
    return Corridor(
        route=tuple(ids),
        centerline=xy,
        stations=stations,
        boundaries=boundaries,
        directions=directions,
        kinds=tuple(kinds),
        lanes=lanes,
        members=frozenset(members),
        route_starts=np.maximum(s_entry, 0.0),
        road=road,
    )


def _stack_boundaries(lower: np.ndarray, upper: np.ndarray, center: int) -> np.ndarray:
    """(K, M+1) boundaries from the lanes' lower and upper offsets (K, M), NaN where a lane is absent.
    A boundary shared by two present lanes is the mean of their two values; an absent lane gets zero
    width at the edge of the present lanes on the route's side of it; each row is made non-decreasing."""
    k, m = lower.shape
    left_val = np.column_stack([np.full(k, np.nan), upper])  # boundary j as the upper of lane j-1
    right_val = np.column_stack([lower, np.full(k, np.nan)])  # boundary j as the lower of lane j
    both = np.stack([left_val, right_val])
    count = np.isfinite(both).sum(axis=0)
    b = np.where(count > 0, np.nansum(both, axis=0) / np.maximum(count, 1), np.nan)
    # fill absent boundaries outward from the route lane (always present)
    for j in range(center + 2, m + 1):
        b[:, j] = np.where(np.isnan(b[:, j]), b[:, j - 1], b[:, j])
    for j in range(center - 1, -1, -1):
        b[:, j] = np.where(np.isnan(b[:, j]), b[:, j + 1], b[:, j])
    # rows where even the route lane is missing (should not happen) take the nearest row's values
    bad = np.isnan(b).any(axis=1)
    if bad.any() and (~bad).any():
        good = np.flatnonzero(~bad)
        near = good[np.clip(np.searchsorted(good, np.flatnonzero(bad)), 0, len(good) - 1)]
        b[bad] = b[near]
    left_part = np.maximum.accumulate(b[:, center + 1:], axis=1)  # boundaries left of the route lane's right one
    right_part = np.minimum.accumulate(b[:, : center + 1][:, ::-1], axis=1)[:, ::-1]
    return np.column_stack([right_part, np.maximum(left_part, right_part[:, -1:])])


def route_road(graph: LaneGraph, start: Sequence[float], goal: Sequence[float] | None = None, **kwargs) -> Road:
    """The ``tracker.Road`` of the route from ``start`` (x m, y m, yaw rad) to ``goal`` (x, y) m
    (keywords: see ``route_corridor``)."""
    return route_corridor(graph, start, goal, **kwargs).road
