"""The ray-casting scene seen from a sensor: vehicle rectangles and roadside polygons as segments.

Owners: the vehicles of a ``Snapshot`` are owners ``0 .. V-1`` (their row in the snapshot); roadside
object ``j`` is owner ``V + j``. The ego itself is not part of the scene. With ``max_range`` given,
vehicles wholly beyond it (bounding circle) and roadside edges wholly beyond it are left out.

``scene_segments`` builds the 2-D scene in one compiled call (``scene_kernel``): the vehicles' edges
first (four per vehicle, counter-clockwise from the front-right corner, in snapshot order), then the
roadside edges, all in the sensor frame. ``vehicle_prisms`` gives the 3-D lidar's boxes.
"""

from __future__ import annotations

import math

import numpy as np

from sim.sensors.clutter import RoadsideObjects
from sim.sensors.lidar3d import Prisms
from sim.sensors.raycast import Segments
from sim.world.truth import Snapshot
from tracker.geometry import corner_offset
from tracker.jit import njit

_NO_STATIC = (np.zeros((0, 4)), np.zeros(0, dtype=np.int64), np.zeros((0, 2)), np.zeros(0))


def static_arrays(roadside: RoadsideObjects | None, count: int) -> tuple:
    """The roadside edges as ``scene_kernel`` takes them: ``[ax, ay, bx, by]`` in G, owners (after the
    ``count`` vehicles), midpoints and half-lengths (empty without roadside objects)."""
    if roadside is None or len(roadside) == 0:
        return _NO_STATIC
    return roadside._edges, roadside.segments.owner + count, roadside._edge_mid, roadside._edge_half


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
    a, b, owner = scene_kernel(snapshot.xy, snapshot.yaw, snapshot.length, snapshot.width,
                               *static_arrays(roadside, len(snapshot)), float(origin[0]), float(origin[1]), float(yaw),
                               math.inf if max_range is None else float(max_range))
    return Segments(a, b, owner)


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


# --------------------------------------------------------------------------------------------------
# The compiled kernels of this stage.


@njit(error_model="numpy")
def scene_kernel(xy, yaw, length, width, static_edges, static_owner, static_mid, static_half, ox, oy, sensor_yaw,
                 max_range):  # pragma: no cover - compiled
    """The edges ``a (M, 2)``, ``b (M, 2)`` and owners ``(M,)`` of ``scene_segments``: the vehicles'
    rectangles (centres ``xy``, headings ``yaw``, ``length``, ``width``; owners the rows ``0 .. V-1``),
    each kept when its bounding circle reaches within ``max_range`` of the sensor at ``(ox, oy)``
    (``|c - o| - sqrt(L^2 + W^2) / 2 <= max_range``), with corners ``c + R(yaw) (+-L/2, +-W/2)``
    counter-clockwise from the front right and edges from each corner to the next; then the roadside
    edges (``static_*``: ``[ax, ay, bx, by]`` in G, owners, midpoints, half-lengths), each kept when
    ``|mid - o| - half <= max_range``. Every end point ``p`` comes out in the sensor frame (heading
    ``sensor_yaw``): ``R(-sensor_yaw) (p - o)``."""
    count = xy.shape[0]
    n_static = static_edges.shape[0]
    a = np.empty((4 * count + n_static, 2))
    b = np.empty((4 * count + n_static, 2))
    owner = np.empty(4 * count + n_static, dtype=np.int64)
    c2 = np.cos(sensor_yaw)
    s2 = np.sin(sensor_yaw)
    m = 0
    cx = np.empty(4)
    cy = np.empty(4)
    for v in range(count):
        dx = xy[v, 0] - ox
        dy = xy[v, 1] - oy
        if np.sqrt(dx * dx + dy * dy) - 0.5 * np.sqrt(length[v] ** 2 + width[v] ** 2) > max_range:
            continue
        c = np.cos(yaw[v])
        s = np.sin(yaw[v])
        hl = 0.5 * length[v]
        hw = 0.5 * width[v]
        for k in range(4):
            lx, ly = corner_offset(k, hl, hw)
            cx[k] = xy[v, 0] + c * lx - s * ly - ox
            cy[k] = xy[v, 1] + s * lx + c * ly - oy
        for k in range(4):
            j = (k + 1) % 4
            a[m, 0] = cx[k] * c2 + cy[k] * s2
            a[m, 1] = -cx[k] * s2 + cy[k] * c2
            b[m, 0] = cx[j] * c2 + cy[j] * s2
            b[m, 1] = -cx[j] * s2 + cy[j] * c2
            owner[m] = v
            m += 1
    for e in range(n_static):
        dx = static_mid[e, 0] - ox
        dy = static_mid[e, 1] - oy
        if np.sqrt(dx * dx + dy * dy) - static_half[e] > max_range:
            continue
        ax = static_edges[e, 0] - ox
        ay = static_edges[e, 1] - oy
        bx = static_edges[e, 2] - ox
        by = static_edges[e, 3] - oy
        a[m, 0] = ax * c2 + ay * s2
        a[m, 1] = -ax * s2 + ay * c2
        b[m, 0] = bx * c2 + by * s2
        b[m, 1] = -bx * s2 + by * c2
        owner[m] = static_owner[e]
        m += 1
    return a[:m].copy(), b[:m].copy(), owner[:m].copy()


def _warm_up_scene() -> None:
    """Compile (or load) this module's kernels (registered with ``tracker.warmup`` by ``sim.sensors``)."""
    one = np.array([[6.0, 0.0]])
    scene_kernel(one, np.zeros(1), np.full(1, 4.5), np.full(1, 1.9), *static_arrays(None, 1), 0.0, 0.0, 0.0, 50.0)
    scene_kernel(one, np.zeros(1), np.full(1, 4.5), np.full(1, 1.9), *static_arrays(None, 1), 0.0, 0.0, 0.0, math.inf)
