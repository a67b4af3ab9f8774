"""Ground truth passed from the world to the sensors and the evaluator (never to the tracker).

A ``Snapshot`` is the truth at one time: the ego pose and every other vehicle, as arrays with one row
per vehicle (vectorised consumers: sensors ray-cast all rectangles at once, metrics assign them).
Units: SI (m, s, rad, m/s); poses in the global frame G; angles wrapped to (-pi, pi].
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from tracker.measurement import rectangle_corners as tracker_rectangle_corners

#: Default heights (m) of vehicle classes, for the 3-D lidar (``sim.sensors.lidar3d``): car 1.5, van
#: 2.0, truck 3.5, bus 3.2 and motorcycle 1.2 m.
CLASS_HEIGHTS = {"car": 1.5, "van": 2.0, "truck": 3.5, "bus": 3.2, "motorcycle": 1.2}


def default_height(length: float | np.ndarray, name: str | None = None) -> float | np.ndarray:
    """A vehicle's height (m) when the scenario gives none: its class's (``CLASS_HEIGHTS``) when
    ``name`` is a known class, else by length: below 3 m a motorcycle (1.2 m), below 5.6 m a car
    (1.5 m), below 8 m a van (2.0 m), else a truck (3.5 m)."""
    if name is not None and name in CLASS_HEIGHTS:
        return CLASS_HEIGHTS[name]
    length_arr = np.asarray(length, dtype=float)
    out = np.select([length_arr < 3.0, length_arr < 5.6, length_arr < 8.0], [1.2, 1.5, 2.0], 3.5)
    return float(out) if out.ndim == 0 else out


@dataclass(frozen=True)
class EgoPose:
    """Ego pose in G: centre ``x, y`` (m), ``yaw`` (rad), speed ``v`` (m/s), ``yaw_rate`` (rad/s),
    the ego's own rectangle ``length, width`` (m), ``z`` the ground height under its centre (m) and
    its ``height`` (m; its own body, which a 3-D lidar on its roof sees)."""

    x: float
    y: float
    yaw: float
    v: float = 0.0
    yaw_rate: float = 0.0
    length: float = 4.8
    width: float = 2.0
    z: float = 0.0
    height: float = 1.5


@dataclass(frozen=True)
class Snapshot:
    """Truth at time ``t`` (s) for the ego and ``N`` other vehicles.

    Arrays, one row per other vehicle, all of length ``N``:
    ``ids`` (int), ``xy`` (N, 2) rectangle centres in G (m), ``yaw`` (rad), ``v`` speed (m/s),
    ``yaw_rate`` (rad/s), ``length``, ``width`` (m), and the road coordinates ``s``, ``n`` (m),
    ``xi`` heading relative to the road tangent (rad), ``xi_dot`` (rad/s). Road coordinates may be
    NaN when a snapshot is built without a road (e.g. sensor tests on bare rectangles). For the 3-D
    lidar: ``height`` (m; default ``default_height(length)``) and ``z`` (m; the ground height under
    the centre, default 0).
    """

    t: float
    ego: EgoPose
    ids: np.ndarray
    xy: np.ndarray
    yaw: np.ndarray
    v: np.ndarray
    yaw_rate: np.ndarray
    length: np.ndarray
    width: np.ndarray
    s: np.ndarray = field(default=None)  # type: ignore[assignment]
    n: np.ndarray = field(default=None)  # type: ignore[assignment]
    xi: np.ndarray = field(default=None)  # type: ignore[assignment]
    xi_dot: np.ndarray = field(default=None)  # type: ignore[assignment]
    height: np.ndarray = field(default=None)  # type: ignore[assignment]
    z: np.ndarray = field(default=None)  # type: ignore[assignment]

    def __post_init__(self) -> None:
        count = len(self.ids)
        xy = np.asarray(self.xy, dtype=float).reshape(-1, 2)
        if xy.shape[0] != count:
            raise ValueError(f"Snapshot: xy has {xy.shape[0]} rows but ids has {count}")
        object.__setattr__(self, "ids", np.asarray(self.ids, dtype=int))
        object.__setattr__(self, "xy", xy)
        for name in ("yaw", "v", "yaw_rate", "length", "width", "s", "n", "xi", "xi_dot"):
            value = getattr(self, name)
            arr = np.full(count, np.nan) if value is None else np.asarray(value, dtype=float)
            if arr.shape != (count,):
                raise ValueError(f"Snapshot: {name} has shape {arr.shape}, expected ({count},)")
            object.__setattr__(self, name, arr)
        for name, default in (("height", default_height(self.length) if count else np.zeros(0)), ("z", np.zeros(count))):
            value = getattr(self, name)
            arr = np.broadcast_to(np.asarray(default, dtype=float), (count,)).copy() if value is None else np.asarray(value, dtype=float)
            if arr.shape != (count,):
                raise ValueError(f"Snapshot: {name} has shape {arr.shape}, expected ({count},)")
            object.__setattr__(self, name, arr)

    def __len__(self) -> int:
        return len(self.ids)

    @property
    def velocity(self) -> np.ndarray:
        """Absolute velocity of each vehicle in G, (N, 2) m/s (speed along its heading)."""
        return self.v[:, None] * np.stack([np.cos(self.yaw), np.sin(self.yaw)], axis=1)

    def corners(self) -> np.ndarray:
        """Rectangle corners in G, (N, 4, 2): front-right, front-left, rear-left, rear-right."""
        return rectangle_corners(self.xy, self.yaw, self.length, self.width)


def rectangle_corners(xy: np.ndarray, yaw: np.ndarray, length: np.ndarray, width: np.ndarray) -> np.ndarray:
    """Corners (N, 4, 2) of rectangles with centres ``xy`` (N, 2), heading ``yaw`` (N,) and size (m),
    ordered front-right, front-left, rear-left, rear-right (counter-clockwise); the tracker's own
    ``tracker.measurement.rectangle_corners`` on (N,) arrays."""
    return tracker_rectangle_corners(
        np.asarray(xy, dtype=float).reshape(-1, 2),
        np.asarray(yaw, dtype=float).reshape(-1),
        np.asarray(length, dtype=float).reshape(-1),
        np.asarray(width, dtype=float).reshape(-1),
    )
