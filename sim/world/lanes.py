"""highway-env lanes over our ``tracker.Road``: one ``FrenetLane`` per lane in a ``RoadNetwork``.

Lane mapping: our lane ``k`` (0 = rightmost, smallest ``n``) is highway-env's lane index
``(NODE_FROM, NODE_TO, k)``. highway-env's lateral coordinate has our sign (positive to the left of
the driving direction, toward +y for a lane heading +x), so its lane ids grow leftward exactly like
ours; its words "LANE_LEFT"/"LANE_RIGHT" are screen-flipped (it draws y downward): "LANE_RIGHT" is
id + 1, i.e. our next lane to the left. A lane's local coordinates are ``(s, n - n_k)``: the longitudinal
coordinate is the centerline arc length ``s`` (shared by all lanes, so gaps between vehicles in
different lanes compare directly) and the lateral one is the offset from the lane centre ``n_k``.

Two-way roads: a lane whose direction is -1 (``Road.lane_directions``; the oncoming lanes) runs its local
frame against ``s``: longitudinal ``length - s``, lateral ``n_k - n`` (still positive to the left of
its driving direction), heading the centerline's + pi; so highway-env's controllers and IDM/MOBIL work
unchanged in the lane's own frame. ``sim.world.traffic`` measures gaps along each vehicle's own
direction, and MOBIL only considers adjacent driving lanes of the same direction
(``FrenetNetwork.side_lanes``). Parking lanes (kind ``"parking"``) are lanes like the others, of their
own width; MOBIL never enters them.

Closed roads: each lane is one segment whose ``after_end`` is never true, and ``s`` wraps in
``[0, length)``; the wrap of distances between vehicles is handled by ``sim.world.traffic``. Open roads:
positions beyond an end extrapolate along the end tangent (``tracker.Road``'s documented behaviour);
``after_end`` keeps highway-env's meaning and there is no next lane (highway-env then keeps the current
one); ``sim.world.world`` removes vehicles that pass the end.

Speed: highway-env projects vehicle positions onto lanes hundreds of times per step. All lanes share
one ``FrenetProjector`` that memoises the projection of each position (a point has the same ``s`` and
centerline ``n`` on every lane); vehicles prime it after each step with a warm start from their
previous ``s`` (``Road.to_frenet``'s fast single-point path).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from highway_env.road.lane import AbstractLane, LineType
from highway_env.road.road import RoadNetwork
from highway_env.utils import get_class_path

from tracker import Road

#: Nodes of the single road segment in the RoadNetwork (a closed road connects ``b`` back to ``a``
#: only conceptually: its lanes never end).
NODE_FROM, NODE_TO = "a", "b"


class FrenetProjector:
    """Memoised projection of points in G onto the road: ``(x, y) -> (s, n)`` (m).

    ``clear()`` drops the memo (the world does so before every step); ``prime(x, y, s_hint)`` projects
    with a warm start and stores the answer; ``project(position)`` answers from the memo or projects
    without a hint (the road's seed grid)."""

    def __init__(self, road: Road) -> None:
        self.road = road
        self._memo: dict[tuple[float, float], tuple[float, float]] = {}

    def clear(self) -> None:
        """Forget every stored projection."""
        self._memo.clear()

    def prime(self, x: float, y: float, s_hint: float | None) -> tuple[float, float]:
        """Project ``(x, y)`` starting from ``s_hint`` (m) and remember it; returns ``(s, n)``."""
        key = (x, y)
        s, n = self.road.to_frenet(key, s_hint=s_hint)
        result = (float(s), float(n))
        self._memo[key] = result
        return result

    def project(self, position: Any) -> tuple[float, float]:
        """``(s, n)`` of a point ``position`` (a length-2 array or tuple, m in G)."""
        key = (float(position[0]), float(position[1]))
        hit = self._memo.get(key)
        if hit is not None:
            return hit
        s, n = self.road.to_frenet(key)
        result = (float(s), float(n))
        self._memo[key] = result
        return result


class FrenetLane(AbstractLane):
    """Lane ``index`` of a ``tracker.Road`` as a highway-env lane (see the module notes for the
    coordinate mapping). ``road_config`` is the plain-data road description kept for
    ``to_config``/``from_config`` (a ``sim.world.scenario.RoadSpec`` dump)."""

    def __init__(
        self,
        road: Road | None = None,
        index: int = 0,
        projector: FrenetProjector | None = None,
        road_config: dict[str, Any] | None = None,
        speed_limit: float | None = None,
    ) -> None:
        if road is None:
            if road_config is None:
                raise ValueError("FrenetLane needs a road or a road_config (a sim.world.scenario.RoadSpec dump)")
            from sim.world.scenario import RoadSpec

            road = RoadSpec.model_validate(road_config).build()
        self.road = road
        self.index = int(index)
        self.table = LaneTable.of(road)
        self.offset = self.table.centre(self.index, 0.0)  # the centre's offset n (m); on a varying road at s = 0
        self.width = self.table.width(self.index, 0.0)
        self._varies = self.table.varies
        self.length = road.length
        self.closed = road.closed
        #: +1: traffic along ``s``; -1: against it (the local frame runs the other way, module notes)
        self.direction = int(road.lane_directions[self.index])
        self.kind = road.layout.kinds[self.index]
        self.projector = projector or FrenetProjector(road)
        self.road_config = road_config
        self.line_types = [
            LineType.CONTINUOUS_LINE if index == 0 else LineType.STRIPED,
            LineType.CONTINUOUS_LINE if index == road.lanes - 1 else LineType.NONE,
        ]
        self.forbidden = False
        self.priority = 0
        self.speed_limit = speed_limit

    def position(self, longitudinal: float, lateral: float) -> np.ndarray:
        """Point in G (m) at local ``longitudinal`` (the arc length ``s``; ``length - s`` against ``s``) and
        ``lateral`` offset from the lane centre (to the left of the lane's driving direction)."""
        s = self.length - float(longitudinal) if self.direction < 0 else float(longitudinal)
        offset = self.table.centre(self.index, s) if self._varies else self.offset
        if self.direction < 0:
            return self.road.to_cartesian(s, float(offset - lateral), extrapolate=True)
        return self.road.to_cartesian(s, float(offset + lateral), extrapolate=True)

    def local_coordinates(self, position: np.ndarray) -> tuple[float, float]:
        """``(s, n - n_k)`` (m) of a point in G (``(length - s, n_k - n)`` in a lane against ``s``); ``s``
        wraps into ``[0, length)`` on a closed road."""
        s, n = self.projector.project(position)
        offset = self.table.centre(self.index, s) if self._varies else self.offset
        if self.direction < 0:
            return self.length - s, offset - n
        return s, n - offset

    def heading_at(self, longitudinal: float) -> float:
        """Lane heading (rad) at local ``longitudinal``: the centerline's (lanes are parallel), turned by
        pi in a lane against ``s``."""
        if self.direction < 0:
            _, _, c, sn, _ = self.road.frame1(self.length - float(longitudinal))
            return math.atan2(-sn, -c)
        _, _, c, sn, _ = self.road.frame1(float(longitudinal))  # scalar fast path of tracker.Road
        return math.atan2(sn, c)

    def width_at(self, longitudinal: float) -> float:
        """Lane width (m) at local ``longitudinal``."""
        if not self._varies:
            return self.width
        s = self.length - float(longitudinal) if self.direction < 0 else float(longitudinal)
        return self.table.width(self.index, s)

    def after_end(self, position: np.ndarray, longitudinal: float | None = None, lateral: float | None = None) -> bool:
        """Never on a closed road (the lane continues into itself); else highway-env's rule."""
        if self.closed:
            return False
        return super().after_end(position, longitudinal, lateral)

    def to_config(self) -> dict:
        """``{"class_path", "config"}`` as highway-env's ``lane_from_config`` expects."""
        return {
            "class_path": get_class_path(self.__class__),
            "config": {"road_config": self.road_config, "index": self.index, "speed_limit": self.speed_limit},
        }

    @classmethod
    def from_config(cls, config: dict) -> FrenetLane:
        """Rebuild a lane from ``to_config()["config"]`` (needs its ``road_config``)."""
        return cls(**config)


class FrenetNetwork(RoadNetwork):
    """highway-env's ``RoadNetwork`` whose side lanes (MOBIL's candidates) are the adjacent driving
    lanes of the same direction: no lane change into oncoming traffic or a parking lane."""

    def side_lanes(self, lane_index: tuple[str, str, int]) -> list[tuple[str, str, int]]:
        _from, _to, _id = lane_index
        lanes = self.graph[_from][_to]
        own = lanes[_id]
        return [(_from, _to, k) for k in (_id - 1, _id + 1)
                if 0 <= k < len(lanes) and lanes[k].direction == own.direction and lanes[k].kind == "driving"]


#: Station spacing (m) of ``LaneTable``'s tables of a road whose lanes vary along ``s``.
LANE_TABLE_STEP = 1.0


class LaneTable:
    """Each lane's centre offset and width (m) as functions of ``s``, in plain Python for the traffic's
    hot path: constants on a road whose lanes do not vary (``road.lane_centers``, exactly), else linear
    in tables every ``LANE_TABLE_STEP`` metres (held beyond the ends). A lane where it is absent (zero
    width: before it begins, after it ends) has its centre on the boundary it tapers to, so a vehicle
    left in a lane that ends is squeezed onto that boundary: scenarios place vehicles where their lane
    exists (``sim.world.scenario``) and traffic does not merge out of ending lanes by itself."""

    def __init__(self, road: Road) -> None:
        self.varies = bool(road.layout.varies)
        self.lanes = road.lanes
        if not self.varies:
            b = road.layout.boundaries[0]
            #: equal lanes: ``(right_edge, lane_width)`` for the lane of an offset by one division
            self._equal = None if getattr(road.layout, "_uniform", None) is None else (road.right_edge, road.lane_width)
            self.centres = [float(c) for c in road.lane_centers]
            self.widths = ([float(road.lane_width)] * road.lanes if self._equal is not None
                           else [float(b[k + 1] - b[k]) for k in range(road.lanes)])
            self.bounds = [float(x) for x in b]
            return
        count = max(2, math.ceil(road.length / LANE_TABLE_STEP) + 1)
        s = np.linspace(0.0, road.length, count)
        b = road.layout.boundaries_at(s)
        self._inv = (count - 1) / road.length
        self._last = count - 1
        self._centre = (0.5 * (b[:, 1:] + b[:, :-1])).T.tolist()  # per lane, per station
        self._width = (b[:, 1:] - b[:, :-1]).T.tolist()
        self._bounds = b.tolist()  # per station, the lane boundaries

    @classmethod
    def of(cls, road: Road) -> LaneTable:
        """The road's table (built once per road and shared by its lanes)."""
        table = road.__dict__.get("_sim_lane_table")
        if table is None:
            table = road.__dict__["_sim_lane_table"] = cls(road)
        return table

    def _at(self, s: float) -> tuple[int, float]:
        u = min(max(s * self._inv, 0.0), float(self._last))
        i = min(int(u), self._last - 1)
        return i, u - i

    def _read(self, row: list[float], s: float) -> float:
        i, t = self._at(s)
        return row[i] + t * (row[i + 1] - row[i])

    def centre(self, lane: int, s: float) -> float:
        """Offset ``n`` (m) of lane ``lane``'s centre at ``s``."""
        return self.centres[lane] if not self.varies else self._read(self._centre[lane], s)

    def width(self, lane: int, s: float) -> float:
        """Width (m) of lane ``lane`` at ``s`` (0 where it does not exist)."""
        return self.widths[lane] if not self.varies else self._read(self._width[lane], s)

    def lane_of(self, n: float, s: float) -> int:
        """The lane (0..lanes-1) whose span at ``s`` holds the offset ``n`` (clamped at the edges; a lane of
        zero width holds nothing)."""
        if not self.varies:
            if self._equal is not None:
                right, width = self._equal
                return min(max(math.floor((n - right) / width), 0), self.lanes - 1)
            bounds = self.bounds
        else:
            i, t = self._at(s)
            lo, hi = self._bounds[i], self._bounds[i + 1]
            bounds = [a + t * (b - a) for a, b in zip(lo, hi)]
        k = sum(1 for b in bounds[1:-1] if n >= b)
        if bounds[k + 1] - bounds[k] <= 0.0:  # a lane of zero width: the nearest lane that exists
            present = [j for j in range(len(bounds) - 1) if bounds[j + 1] - bounds[j] > 0.0]
            if present:
                k = min(present, key=lambda j: abs(0.5 * (bounds[j] + bounds[j + 1]) - n))
        return k


def build_network(road: Road, road_config: dict[str, Any] | None = None) -> tuple[RoadNetwork, FrenetProjector]:
    """A ``RoadNetwork`` with one ``FrenetLane`` per lane of ``road`` (index k = our lane k) on the
    edge ``(NODE_FROM, NODE_TO)``, and the projector they share."""
    projector = FrenetProjector(road)
    network = FrenetNetwork()
    for k in range(road.lanes):
        network.add_lane(NODE_FROM, NODE_TO, FrenetLane(road, k, projector, road_config))
    return network, projector


def lane_index(k: int) -> tuple[str, str, int]:
    """highway-env lane index of our lane ``k``."""
    return (NODE_FROM, NODE_TO, int(k))
