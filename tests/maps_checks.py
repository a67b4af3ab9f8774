"""Checks of a route's road against its lane map, shared by tests/test_maps.py and tests/maps_bench.py.

- ``edge_deviation``: the outermost lanelet boundaries beside every route lanelet (found by walking the
  neighbour relations here, independently of tracker.maps.route), sampled every 0.5 m, against the
  road's edge polylines: the largest distance (m).
- ``on_road_fraction``: of the recorded vehicle centres (all time steps) that lie inside the corridor's
  lanelets, the fraction the road calls on the road.
"""

from __future__ import annotations

import contextlib
import functools
import io
import logging

import numpy as np

from tracker.maps.graph import ROAD_KINDS, LaneGraph, densify, point_polyline_distance


def outer_boundaries(graph: LaneGraph, route_id: int) -> tuple[np.ndarray, np.ndarray]:
    """The right and left outer boundary polylines (in the route lanelet's frame) of the road lanelets
    chained sideways to lanelet ``route_id``."""
    out = []
    for side in ("right", "left"):
        cur, along = graph.lanelet(route_id), True
        seen = {route_id}
        while True:
            look = side if along else ("left" if side == "right" else "right")
            nxt = getattr(cur, f"{look}_neighbor")
            if nxt is None or nxt in seen or graph.lanelet(nxt).kind not in ROAD_KINDS:
                break
            along = along == getattr(cur, f"{look}_same_direction")
            seen.add(nxt)
            cur = graph.lanelet(nxt)
        look = side if along else ("left" if side == "right" else "right")
        out.append(getattr(cur, look))
    return out[0], out[1]


def road_edges_xy(road, stations: np.ndarray, right: np.ndarray, left: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The road's right and left edge polylines (K, 2) m from the edge offsets at ``stations``."""
    return road.to_cartesian(stations, right), road.to_cartesian(stations, left)


def edge_deviation(graph: LaneGraph, corridor, road=None, margin: float = 2.0, join_margin: float = 0.0) -> float:
    """Largest distance (m) from the route lanelets' outermost boundaries to the road's edges: each
    route lanelet's chained outer boundaries over the stretch of road it owns, points within ``margin``
    m of the road's ends and within ``join_margin`` m of a join of route lanelets left out (where a
    lane begins or ends at a join, the road's edges step across ``tracker.lanes.EDGE_TABLE_STEP``)."""
    road = corridor.road if road is None else road
    s = np.linspace(0.0, road.length, max(int(road.length / 0.25), 2))
    right_n, left_n = edges_at(road, corridor, s)
    right_xy, left_xy = road_edges_xy(road, s, right_n, left_n)
    worst = 0.0
    # each route lanelet owns the stretch from the projection of its entry to that of the next one's
    ends = np.append(corridor.route_starts[1:], road.length)
    for lid, lo, hi in zip(corridor.route, corridor.route_starts, ends):
        for line, edge in zip(outer_boundaries(graph, lid), (right_xy, left_xy)):
            pts = densify(line, 0.5)
            ps, _ = road.to_frenet(pts)
            keep = (ps > max(margin, lo + join_margin)) & (ps < min(road.length - margin, hi - join_margin))
            pts = pts[keep]
            if len(pts):
                worst = max(worst, float(point_polyline_distance(pts, edge).max()))
    return worst


def edges_at(road, corridor, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Right and left edge offsets (m) of the road at ``s``: ``road.edges`` when the road has a lane
    layout, else the corridor's outer boundaries interpolated."""
    if hasattr(road, "edges"):
        return road.edges(s)
    return np.interp(s, corridor.stations, corridor.boundaries[:, 0]), np.interp(s, corridor.stations, corridor.boundaries[:, -1])


@functools.lru_cache(maxsize=4)
def open_scenario(path):
    """The CommonRoad scenario and planning problems of ``path`` (read once, kept for the next asks)."""
    from commonroad.common.file_reader import CommonRoadFileReader

    logging.getLogger("commonroad").setLevel(logging.ERROR)
    with contextlib.redirect_stdout(io.StringIO()):
        return CommonRoadFileReader(str(path)).open()


def vehicle_centres(path) -> np.ndarray:
    """Centres (N, 2) m of every recorded vehicle of a CommonRoad scenario at every time step."""
    scenario, _ = open_scenario(path)
    pts = []
    for ob in scenario.dynamic_obstacles:
        pts.append(ob.initial_state.position)
        traj = getattr(ob.prediction, "trajectory", None)
        if traj is not None:
            pts.extend(st.position for st in traj.state_list)
    return np.array(pts, dtype=float).reshape(-1, 2)


def planning_start(path) -> tuple[float, float, float]:
    """(x, y, yaw) of the first planning problem's initial state of a CommonRoad scenario."""
    _, problems = open_scenario(path)
    state = next(iter(problems.planning_problem_dict.values())).initial_state
    return float(state.position[0]), float(state.position[1]), float(state.orientation)


def on_road_fraction(graph: LaneGraph, corridor, centres: np.ndarray, road=None) -> tuple[float, int]:
    """(fraction on the road, count) of the ``centres`` that lie inside the corridor's lanelets."""
    road = corridor.road if road is None else road
    inside = graph.contains(centres, sorted(corridor.members)).any(axis=1)
    pts = centres[inside]
    if not len(pts):
        return 1.0, 0
    if hasattr(road, "edges"):
        on = road.on_road(pts)
    else:
        s, n = road.to_frenet(pts)
        right, left = edges_at(road, corridor, s)
        on = (s >= 0) & (s <= road.length) & (n >= right) & (n <= left)
    return float(np.mean(on)), int(len(pts))


def longest_route_start(graph: LaneGraph) -> tuple[float, float, float]:
    """A start pose (x, y, yaw) at the entry of the lanelet without predecessors whose straightest
    route is the longest (on an urban map: a route across an intersection)."""
    from tracker.maps.route import route_lanelets

    best, pose = -1.0, None
    for ll in graph.lanelets:
        if ll.predecessors or ll.kind != "driving":
            continue
        c = ll.center
        d = c[1] - c[0]
        start = (float(0.9 * c[0, 0] + 0.1 * c[1, 0]), float(0.9 * c[0, 1] + 0.1 * c[1, 1]), float(np.arctan2(d[1], d[0])))
        try:
            length = sum(graph.lanelet(i).length for i in route_lanelets(graph, start))
        except ValueError:
            continue
        if length > best:
            best, pose = length, start
    return pose
