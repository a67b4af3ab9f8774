"""The radar's visibility test (``sim.sensors.radar.RadarUnit.visible``) in numpy, from the scene and
caster oracles: the scene seen from the mount (heading ego yaw + boresight) within ``max_range``,
cast on the unit's fan with back faces culled; per vehicle the nearest ray that hits it at
``>= min_range`` (of equal ranges the lowest ray); its hit point, rotated by the boresight and moved
to the mount, is the vehicle's nearest visible point in E.
"""

from __future__ import annotations

import numpy as np

from oracles.raycast import cast_numpy
from oracles.scene import scene_segments


def _rotate(points: np.ndarray, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([c * points[:, 0] - s * points[:, 1], s * points[:, 0] + c * points[:, 1]], axis=1)


def visible(unit, snapshot, roadside=None) -> tuple[np.ndarray, np.ndarray]:
    """Rows (K,) (ascending) of the vehicles ``unit`` (a ``RadarUnit``) sees and their nearest visible
    points (K, 2) in E (m)."""
    cfg, ego, grid = unit.config, snapshot.ego, unit.grid
    mount_e = cfg.mount_position(ego.length)
    mount_g = np.array([ego.x, ego.y]) + _rotate(mount_e[None, :], ego.yaw)[0]
    segments = scene_segments(snapshot, roadside, (float(mount_g[0]), float(mount_g[1])), ego.yaw + cfg.boresight,
                              cfg.max_range)
    cast = cast_numpy(segments, grid, cfg.max_range)
    on_vehicle = np.flatnonzero((cast.owner >= 0) & (cast.owner < len(snapshot)) & (cast.range >= cfg.min_range))
    if on_vehicle.size == 0:
        return np.zeros(0, dtype=np.int64), np.zeros((0, 2))
    owner, reach = cast.owner[on_vehicle], cast.range[on_vehicle]
    order = np.lexsort((reach, owner))  # by vehicle, then range; stable: the lowest ray of equal ranges
    first = order[np.concatenate([[True], np.diff(owner[order]) != 0])]
    rays = on_vehicle[first]
    local = grid.directions[rays] * cast.range[rays][:, None]
    return owner[first], _rotate(local, cfg.boresight) + mount_e
