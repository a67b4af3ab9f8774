"""Frame transforms between the global frame G and sensor/vehicle frames.

A frame is given by its origin ``(x, y)`` in G (m) and its heading ``yaw`` (rad, CCW from G's +x).
The vehicle reference frame E has its origin at the ego centre, x forward, y left; a radar frame has
its origin at the radar mount and x along the boresight. All functions are vectorised over rows.
"""

from __future__ import annotations

import numpy as np

from tracker.angles import wrap_angle

__all__ = ["rotate", "to_global", "to_local", "wrap_angle"]


def rotate(vectors: np.ndarray, angle: float) -> np.ndarray:
    """Vectors ``(N, 2)`` rotated counter-clockwise by ``angle`` (rad)."""
    c, s = np.cos(angle), np.sin(angle)
    v = np.asarray(vectors, dtype=float)
    return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1]], axis=-1)


def to_local(points: np.ndarray, origin: tuple[float, float], yaw: float) -> np.ndarray:
    """Points ``(..., 2)`` in G (m) expressed in the frame at ``origin`` (m, in G) with heading
    ``yaw`` (rad)."""
    p = np.asarray(points, dtype=float)
    return rotate(p - np.asarray(origin, dtype=float), -yaw)


def to_global(points: np.ndarray, origin: tuple[float, float], yaw: float) -> np.ndarray:
    """Points ``(..., 2)`` given in the frame at ``origin`` (m, in G) with heading ``yaw`` (rad),
    expressed in G (m). Inverse of ``to_local``."""
    return rotate(points, yaw) + np.asarray(origin, dtype=float)
