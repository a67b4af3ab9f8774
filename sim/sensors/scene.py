"""The ray-casting scene seen from a sensor: vehicle rectangles and roadside polygons as segments.

Owners: the vehicles of a ``Snapshot`` are owners ``0 .. V-1`` (their row in the snapshot); roadside
object ``j`` is owner ``V + j``. The ego itself is not part of the scene. With ``max_range`` given,
vehicles wholly beyond it (bounding circle) and roadside edges wholly beyond it are left out.
"""

from __future__ import annotations

import math

import numpy as np

from sim.sensors.cast_kernel import scene_kernel
from sim.sensors.clutter import RoadsideObjects
from sim.sensors.lidar3d import Prisms
from sim.sensors.raycast import Segments
from sim.world.truth import Snapshot, rectangle_corners
from tracker import jit as compiled
from tracker.measurement import NEXT_CORNER

_NO_STATIC = (np.zeros((0, 4)), np.zeros(0, dtype=np.int64), np.zeros((0, 2)), np.zeros(0))


def static_arrays(roadside: RoadsideObjects | None, count: int) -> tuple:
    """The roadside edges as the compiled scene kernels take them: ``[ax, ay, bx, by]`` in G, owners
    (after the ``count`` vehicles), midpoints and half-lengths (empty without roadside objects)."""
    if roadside is None or len(roadside) == 0:
        return _NO_STATIC
    return roadside._edges, roadside.segments.owner + count, roadside._edge_mid, roadside._edge_half


# corner signs along (length, width) of the corners front-right, front-left, rear-left, rear-right
# (counter-clockwise), and of each corner's successor (the edge's end point)


def _vehicle_edges(snapshot: Snapshot, rows: np.ndarray) -> np.ndarray:
    """Edges (4 V, 4) ``[ax, ay, bx, by]`` in G of the vehicles ``rows``, counter-clockwise."""
    corners = rectangle_corners(snapshot.xy[rows], snapshot.yaw[rows], snapshot.length[rows], snapshot.width[rows])
    return np.concatenate([corners, corners[:, NEXT_CORNER]], axis=-1).reshape(-1, 4)


def scene_segments(
    snapshot: Snapshot,
    roadside: RoadsideObjects | None,
    origin: tuple[float, float],
    yaw: float,
    max_range: float | None = None,
) -> Segments:
    """Every edge of the snapshot's vehicles and of ``roadside`` (may be ``None``) within
    ``max_range`` (m; all when ``None``) of the sensor, expressed in the sensor frame at ``origin``
    (m, G) with heading ``yaw`` (rad); owners as in the module docstring."""
    ox, oy = float(origin[0]), float(origin[1])
    count = len(snapshot)
    if compiled.enabled():  # the same edges in one compiled call (sim.sensors.cast_kernel)
        a, b, owner = scene_kernel(snapshot.xy, snapshot.yaw, snapshot.length, snapshot.width,
                                   *static_arrays(roadside, count), ox, oy, float(yaw),
                                   math.inf if max_range is None else float(max_range))
        return Segments(a, b, owner)
    rows = np.arange(count, dtype=np.int64)
    if max_range is not None and count:
        dx, dy = snapshot.xy[:, 0] - ox, snapshot.xy[:, 1] - oy
        reach = np.sqrt(dx * dx + dy * dy) - 0.5 * np.sqrt(snapshot.length**2 + snapshot.width**2)
        rows = rows[reach <= max_range]
    edges = [_vehicle_edges(snapshot, rows)]
    owner = [np.repeat(rows, 4)]
    if roadside is not None and len(roadside):
        static_edges = roadside._edges
        static_owner = roadside.segments.owner + count
        if max_range is not None:
            mid = roadside._edge_mid
            dx, dy = mid[:, 0] - ox, mid[:, 1] - oy
            keep = np.sqrt(dx * dx + dy * dy) - roadside._edge_half <= max_range
            static_edges, static_owner = static_edges[keep], static_owner[keep]
        edges.append(static_edges)
        owner.append(static_owner)
    all_edges = np.concatenate(edges) - np.array([ox, oy, ox, oy])
    c, s = math.cos(yaw), math.sin(yaw)
    # row vectors [x, y] @ [[c, -s], [s, c]] = rotation by -yaw, for both end points at once
    rot = np.array([[c, -s, 0.0, 0.0], [s, c, 0.0, 0.0], [0.0, 0.0, c, -s], [0.0, 0.0, s, c]])
    local = all_edges @ rot
    return Segments(local[:, :2], local[:, 2:], np.concatenate(owner))


#: The open gap (m) under every vehicle's box for the 3-D lidar: wheels and underbody are not
#: modelled, so beams below it pass under the vehicle (as they do under a truck's chassis).
VEHICLE_CLEARANCE = 0.25


def vehicle_prisms(snapshot: Snapshot, origin: tuple[float, float], max_range: float | None = None) -> Prisms:
    """The snapshot's vehicles as upright boxes (``sim.sensors.lidar3d.Prisms``) for the 3-D lidar:
    footprint = the rectangle, from ``z + VEHICLE_CLEARANCE`` to ``z + height`` (m, G; ``Snapshot.z``
    the ground under the centre). Owners are the snapshot rows ``0 .. V-1``; with ``max_range`` the
    vehicles wholly beyond it from ``origin`` (m, G) are left out."""
    rows = np.arange(len(snapshot), dtype=np.int64)
    if max_range is not None and len(rows):
        dx, dy = snapshot.xy[:, 0] - float(origin[0]), snapshot.xy[:, 1] - float(origin[1])
        reach = np.sqrt(dx * dx + dy * dy) - 0.5 * np.sqrt(snapshot.length**2 + snapshot.width**2)
        rows = rows[reach <= max_range]
    base = snapshot.z[rows] + np.minimum(VEHICLE_CLEARANCE, 0.5 * snapshot.height[rows])
    return Prisms.from_rectangles(snapshot.xy[rows], snapshot.yaw[rows], snapshot.length[rows], snapshot.width[rows],
                                  base, snapshot.z[rows] + snapshot.height[rows], owner=rows)
