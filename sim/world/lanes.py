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
        self.offset = road.lane_center(self.index)
        self.width = lane_width(road, self.index)
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
        if self.direction < 0:
            return self.road.to_cartesian(self.length - float(longitudinal), float(self.offset - lateral), extrapolate=True)
        return self.road.to_cartesian(float(longitudinal), float(self.offset + lateral), extrapolate=True)

    def local_coordinates(self, position: np.ndarray) -> tuple[float, float]:
        """``(s, n - n_k)`` (m) of a point in G (``(length - s, n_k - n)`` in a lane against ``s``); ``s``
        wraps into ``[0, length)`` on a closed road."""
        s, n = self.projector.project(position)
        if self.direction < 0:
            return self.length - s, self.offset - n
        return s, n - self.offset

    def heading_at(self, longitudinal: float) -> float:
        """Lane heading (rad) at local ``longitudinal``: the centerline's (lanes are parallel), turned by
        pi in a lane against ``s``."""
        if self.direction < 0:
            _, _, c, sn, _ = self.road.frame1(self.length - float(longitudinal))
            return math.atan2(-sn, -c)
        _, _, c, sn, _ = self.road.frame1(float(longitudinal))  # scalar fast path of tracker.Road
        return math.atan2(sn, c)

    def width_at(self, longitudinal: float) -> float:
        """Lane width (m), constant."""
        return self.width

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


def lane_width(road: Road, index: int) -> float:
    """Width (m) of lane ``index`` of ``road``: ``road.lane_width`` on a road of equal lanes, else its
    layout's (lanes that do not vary along ``s``)."""
    if getattr(road.layout, "_uniform", None) is not None:
        return float(road.lane_width)
    b = road.layout.boundaries[0]
    return float(b[index + 1] - b[index])


def build_network(road: Road, road_config: dict[str, Any] | None = None) -> tuple[RoadNetwork, FrenetProjector]:
    """A ``RoadNetwork`` with one ``FrenetLane`` per lane of ``road`` (index k = our lane k) on the
    edge ``(NODE_FROM, NODE_TO)``, and the projector they share."""
    if road.layout.varies:
        raise ValueError("the simulator's traffic needs lanes that do not vary along s; this road's do")
    projector = FrenetProjector(road)
    network = FrenetNetwork()
    for k in range(road.lanes):
        network.add_lane(NODE_FROM, NODE_TO, FrenetLane(road, k, projector, road_config))
    return network, projector


def lane_index(k: int) -> tuple[str, str, int]:
    """highway-env lane index of our lane ``k``."""
    return (NODE_FROM, NODE_TO, int(k))
