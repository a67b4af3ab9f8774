"""The ray-casting scene of a sensor (``sim.sensors.scene.scene_segments``) in vectorised numpy.

The vehicles' rectangles first (owners their snapshot rows ``0 .. V-1``): corners
``c + R(yaw) (+-L/2, +-W/2)`` front-right, front-left, rear-left, rear-right (counter-clockwise),
four edges per vehicle from each corner to the next; then the roadside edges (owners ``V + j``).
With ``max_range``, a vehicle is kept when ``|c - o| - sqrt(L^2 + W^2) / 2 <= max_range`` and a
roadside edge when ``|mid - o| - half_length <= max_range``. End points ``p`` go into the sensor
frame at ``o`` with heading ``yaw``: ``R(-yaw) (p - o)``.
"""

from __future__ import annotations

import numpy as np

from sim.sensors.raycast import Segments

#: Corner signs along (length, width): front-right, front-left, rear-left, rear-right.
ALONG = np.array([1.0, 1.0, -1.0, -1.0])
ACROSS = np.array([-1.0, 1.0, 1.0, -1.0])


def vehicle_edges(xy: np.ndarray, yaw: np.ndarray, length: np.ndarray, width: np.ndarray) -> np.ndarray:
    """Edges (4 V, 4) ``[ax, ay, bx, by]`` of the rectangles, counter-clockwise from the front right."""
    c, s = np.cos(yaw)[:, None], np.sin(yaw)[:, None]
    along = 0.5 * length[:, None] * ALONG
    across = 0.5 * width[:, None] * ACROSS
    corners = np.stack([xy[:, :1] + c * along - s * across, xy[:, 1:] + s * along + c * across], axis=-1)
    return np.concatenate([corners, np.roll(corners, -1, axis=1)], axis=-1).reshape(-1, 4)


def scene_segments(snapshot, roadside, origin: tuple[float, float], yaw: float,
                   max_range: float | None = None) -> Segments:
    """The edges of the snapshot's vehicles and of ``roadside`` (``RoadsideObjects`` or ``None``) seen
    from ``origin`` (m, G) with heading ``yaw`` (rad), as the module docstring says."""
    ox, oy = float(origin[0]), float(origin[1])
    count = len(snapshot)
    rows = np.arange(count, dtype=np.int64)
    if max_range is not None and count:
        reach = np.hypot(snapshot.xy[:, 0] - ox, snapshot.xy[:, 1] - oy) \
            - 0.5 * np.sqrt(snapshot.length**2 + snapshot.width**2)
        rows = rows[reach <= max_range]
    edges = [vehicle_edges(snapshot.xy[rows], snapshot.yaw[rows], snapshot.length[rows], snapshot.width[rows])]
    owner = [np.repeat(rows, 4)]
    if roadside is not None and len(roadside):
        polygons = [roadside.polygon(k) for k in range(len(roadside))]
        static = np.concatenate([np.concatenate([p, np.roll(p, -1, axis=0)], axis=1) for p in polygons])
        static_owner = np.concatenate([np.full(len(p), count + k, dtype=np.int64) for k, p in enumerate(polygons)])
        if max_range is not None:
            mid = 0.5 * (static[:, :2] + static[:, 2:])
            half = 0.5 * np.hypot(static[:, 2] - static[:, 0], static[:, 3] - static[:, 1])
            keep = np.hypot(mid[:, 0] - ox, mid[:, 1] - oy) - half <= max_range
            static, static_owner = static[keep], static_owner[keep]
        edges.append(static)
        owner.append(static_owner)
    rel = np.concatenate(edges) - np.array([ox, oy, ox, oy])
    c, s = np.cos(yaw), np.sin(yaw)
    x, y = rel[:, 0::2], rel[:, 1::2]  # (M, 2): the end points a and b
    local_x, local_y = x * c + y * s, -x * s + y * c
    return Segments(np.stack([local_x[:, 0], local_y[:, 0]], axis=1), np.stack([local_x[:, 1], local_y[:, 1]], axis=1),
                    np.concatenate(owner))
