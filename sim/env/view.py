"""``EnvView``: what the observation (``sim.env.observation``) and the renderer (``sim.env.render``) read
of the environment, so that they need not import ``sim.env.core``, which builds them.

``TrackedRoadEnv`` has every member; the two read them afresh at each ``observe()`` / ``draw()``.
"""

from __future__ import annotations

from typing import Protocol

from sim.env.config import EnvConfig
from sim.sensors.rig import SensorFrame, SensorRig
from sim.world.world import World
from tracker import Track


class EnvView(Protocol):
    """The environment's state after ``reset`` (``world`` and ``rig`` are ``None`` before it):
    ``settings`` (its ``EnvConfig``), ``lidar_range`` (the scenario's lidar ``max_range``, m),
    ``world``, ``rig``, the tracks of the last lidar frame (``tracks``), that frame (``last_frame``,
    ``None`` before the first) and the episode's simulated time (``sim_time``, s)."""

    @property
    def settings(self) -> EnvConfig: ...

    @property
    def lidar_range(self) -> float: ...

    @property
    def world(self) -> World | None: ...

    @property
    def rig(self) -> SensorRig | None: ...

    @property
    def tracks(self) -> list[Track]: ...

    @property
    def last_frame(self) -> SensorFrame | None: ...

    @property
    def sim_time(self) -> float: ...


__all__ = ["EnvView"]
