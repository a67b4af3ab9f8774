"""The tracker's input: one ``Frame`` per lidar scan (docs/architecture.md, "tracker.Frame").

A ``Frame(t, ego, lidar, radar)`` holds

- ``t``: the frame time (s), the time of the lidar scan;
- ``ego``: the ego pose in the global frame G at ``t`` (``EgoState``: ``x, y`` m, ``yaw`` rad,
  ``v`` m/s, ``yaw_rate`` rad/s);
- ``lidar``: ``(N, 2)`` points (m) in the vehicle reference frame E at ``t`` (origin at the ego's
  geometric centre, x forward, y left), or ``(N, 3)``: a raw 3-D cloud (x, y, z, m) in the lidar's
  own frame, which the tracker first takes through the paper's 3-D pipeline (``tracker.cloud``:
  the mount transform, RANSAC ground removal, projection to the road plane; the mount pose is
  ``TrackerConfig.cloud``; ``CloudConfig.frame = "vehicle"`` for a cloud already in E, such as a
  rig's merged one). Non-finite points are allowed here (real drivers emit them); the tracker drops
  and counts them. A driver's ``(N, 4)`` cloud (x, y, z, intensity) and an organized ``(rows,
  columns, 3 or 4)`` one are taken as they come: flattened row by row, the intensity kept in
  ``lidar_intensity`` (``(N,)``, the driver's units; ``None`` without one), which the tracker does not
  use;
- ``radar``: ``RadarDetections``, arrays ``t, x, y, vx, vy``, one entry per detection received since
  the previous frame, each with its own timestamp ``t <= frame.t``. Positions ``x, y`` (m) are the
  detected point **expressed in E at the frame time** (ego motion between the detection and the frame
  compensated, as a fusion stack does with odometry); ``vx, vy`` (m/s) are the target's *absolute*
  velocity (its velocity in G) expressed in the axes of E at the frame time. The target itself may
  have moved between ``radar.t`` and ``frame.t``; the timestamp lets the tracker account for it.

Either sensor part may be empty. Arrays are float64 and read-only (the frame is immutable); the
constructor copies its inputs. Bad input raises ``ValueError`` naming the field.
This module is numpy only and imports nothing of ``sim``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tracker.angles import wrap_angle

#: Slack (s) allowed when checking that radar detections are not later than their frame.
TIME_TOLERANCE = 1e-9


def _finite_scalar(value: Any, name: str) -> float:
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a real number; got {value!r}") from None
    if not math.isfinite(out):
        raise ValueError(f"{name} must be finite; got {out!r}")
    return out


def _readonly(arr: np.ndarray) -> np.ndarray:
    arr.flags.writeable = False
    return arr


@dataclass(frozen=True)
class EgoState:
    """Ego pose in G at a frame time: centre ``x, y`` (m), ``yaw`` (rad, wrapped to (-pi, pi]),
    speed ``v`` (m/s) along the heading, ``yaw_rate`` (rad/s). All finite."""

    x: float
    y: float
    yaw: float
    v: float = 0.0
    yaw_rate: float = 0.0

    def __post_init__(self) -> None:
        for name in ("x", "y", "yaw", "v", "yaw_rate"):
            object.__setattr__(self, name, _finite_scalar(getattr(self, name), f"EgoState.{name}"))
        object.__setattr__(self, "yaw", float(wrap_angle(self.yaw)))

    @classmethod
    def coerce(cls, ego: Any) -> EgoState:
        """An ``EgoState`` from ``ego``: an ``EgoState``, any object with attributes
        ``x, y, yaw`` (and optionally ``v, yaw_rate``), or a sequence ``(x, y, yaw[, v[, yaw_rate]])``."""
        if isinstance(ego, cls):
            return ego
        if all(hasattr(ego, name) for name in ("x", "y", "yaw")):
            return cls(ego.x, ego.y, ego.yaw, getattr(ego, "v", 0.0), getattr(ego, "yaw_rate", 0.0))
        try:
            values = [float(v) for v in ego]
        except (TypeError, ValueError):
            raise ValueError(
                f"Frame.ego must be an EgoState, an object with x, y, yaw (v, yaw_rate), or a sequence "
                f"(x, y, yaw[, v[, yaw_rate]]); got {type(ego).__name__}"
            ) from None
        if not 3 <= len(values) <= 5:
            raise ValueError(f"Frame.ego as a sequence needs 3 to 5 numbers (x, y, yaw, v, yaw_rate); got {len(values)}")
        return cls(*values)


_RADAR_FIELDS = ("t", "x", "y", "vx", "vy")


@dataclass(frozen=True, eq=False)
class RadarDetections:
    """Radar detections, one entry per detection, as 1-D float64 arrays of equal length ``N``:
    ``t`` timestamp (s), ``x, y`` position (m) in E at the frame time, ``vx, vy`` the target's
    absolute velocity (m/s) in E's axes at the frame time. All values must be finite."""

    t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    x: np.ndarray = field(default_factory=lambda: np.zeros(0))
    y: np.ndarray = field(default_factory=lambda: np.zeros(0))
    vx: np.ndarray = field(default_factory=lambda: np.zeros(0))
    vy: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def __post_init__(self) -> None:
        count = None
        for name in _RADAR_FIELDS:
            try:
                arr = np.array(getattr(self, name), dtype=float)
            except (TypeError, ValueError):
                raise ValueError(f"RadarDetections.{name} must be numeric") from None
            if arr.ndim == 0:
                arr = arr.reshape(1)
            if arr.ndim != 1:
                raise ValueError(f"RadarDetections.{name} must be 1-D; got shape {arr.shape}")
            if count is None:
                count = arr.shape[0]
            elif arr.shape[0] != count:
                raise ValueError(
                    f"RadarDetections.{name} has {arr.shape[0]} entries but RadarDetections.t has {count}"
                )
            bad = ~np.isfinite(arr)
            if bad.any():
                i = int(np.argmax(bad))
                raise ValueError(f"RadarDetections.{name}[{i}] must be finite; got {arr[i]!r}")
            object.__setattr__(self, name, _readonly(arr))

    @classmethod
    def empty(cls) -> RadarDetections:
        """No detections."""
        return cls()

    @classmethod
    def from_array(cls, rows: np.ndarray) -> RadarDetections:
        """Detections from an ``(N, 5)`` array with columns ``t, x, y, vx, vy``."""
        arr = np.asarray(rows, dtype=float)
        if arr.size == 0:
            return cls()
        if arr.ndim != 2 or arr.shape[1] != 5:
            raise ValueError(f"RadarDetections.from_array needs shape (N, 5) (t, x, y, vx, vy); got {arr.shape}")
        return cls(*(arr[:, i] for i in range(5)))

    def __len__(self) -> int:
        return int(self.t.shape[0])

    @property
    def xy(self) -> np.ndarray:
        """Positions (N, 2) in E (m)."""
        return np.stack([self.x, self.y], axis=1)

    @property
    def velocity(self) -> np.ndarray:
        """Absolute velocities (N, 2) in E's axes (m/s)."""
        return np.stack([self.vx, self.vy], axis=1)

    def positions_at(self, t: float, rows: np.ndarray | None = None) -> np.ndarray:
        """Positions (N, 2) in E (m) moved to time ``t`` (s) with each detection's own velocity (a
        radar cycle is up to one lidar period older than the frame); ``rows``: only those detections."""
        sel = slice(None) if rows is None else rows
        lag = t - self.t[sel]
        return np.column_stack([self.x[sel] + self.vx[sel] * lag, self.y[sel] + self.vy[sel] * lag])

    def as_array(self) -> np.ndarray:
        """The detections as an ``(N, 5)`` array with columns ``t, x, y, vx, vy``."""
        return np.stack([getattr(self, name) for name in _RADAR_FIELDS], axis=1).reshape(-1, 5)


@dataclass(frozen=True, eq=False)
class Frame:
    """One tracker input at time ``t`` (s): the ego pose in G (``EgoState``, or anything
    ``EgoState.coerce`` accepts), the lidar scan as ``(N, 2)`` points in E (m; ``None`` or an empty
    array for no points) or an ``(N, 3)`` cloud in the lidar's frame (module docstring), and the radar detections received since the previous frame
    (``RadarDetections``, an ``(N, 5)`` array ``t, x, y, vx, vy``, or ``None``); see the module
    docstring for the frames the values are expressed in."""

    t: float
    ego: EgoState
    lidar: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    radar: RadarDetections = field(default_factory=RadarDetections)
    lidar_intensity: np.ndarray | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "t", _finite_scalar(self.t, "Frame.t"))
        object.__setattr__(self, "ego", EgoState.coerce(self.ego))
        lidar = np.zeros((0, 2)) if self.lidar is None else self.lidar
        try:
            pts = np.array(lidar, dtype=float)
        except (TypeError, ValueError):
            raise ValueError("Frame.lidar must be a numeric (N, 2) array of points in E (or an (N, 3) cloud)") from None
        if pts.ndim == 3 and pts.shape[2] in (3, 4):  # an organized cloud: rows x columns
            pts = pts.reshape(-1, pts.shape[2])
        if pts.size == 0:
            pts = pts.reshape(0, pts.shape[1] if pts.ndim == 2 and pts.shape[1] in (3, 4) else 2)
        if pts.ndim != 2 or pts.shape[1] not in (2, 3, 4):
            raise ValueError(
                f"Frame.lidar must have shape (N, 2) (x, y in E, m), (N, 3) (a cloud x, y, z, m), (N, 4) (x, y, z, "
                f"intensity) or (rows, columns, 3 or 4) (an organized cloud); got {pts.shape}"
            )
        intensity = self.lidar_intensity
        if pts.shape[1] == 4:
            if intensity is not None:
                raise ValueError("Frame.lidar_intensity: given twice, as lidar's fourth column and on its own; give one")
            pts, intensity = pts[:, :3], pts[:, 3]
        if intensity is not None:
            intensity = np.array(intensity, dtype=float).reshape(-1)
            if pts.shape[1] != 3 or len(intensity) != len(pts):
                raise ValueError(f"Frame.lidar_intensity has {len(intensity)} values for a lidar of shape {pts.shape}; "
                                 "one per point of a 3-D cloud")
            intensity = _readonly(intensity)
        object.__setattr__(self, "lidar", _readonly(np.ascontiguousarray(pts)))
        object.__setattr__(self, "lidar_intensity", intensity)
        radar = self.radar
        if radar is None:
            radar = RadarDetections()
        elif not isinstance(radar, RadarDetections):
            radar = RadarDetections.from_array(radar)
        if len(radar) and float(radar.t.max()) > self.t + TIME_TOLERANCE:
            raise ValueError(
                f"Frame.radar has a detection at t={float(radar.t.max())!r} s, after the frame time "
                f"t={self.t!r} s; a frame carries only detections received up to its own time"
            )
        object.__setattr__(self, "radar", radar)
