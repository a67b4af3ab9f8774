"""Sensor models of the testbed: a ray-cast 2-D lidar, object-level radars, roadside clutter, and
the rig that turns truth over time into the tracker's ``Frame``s.

Modules: ``raycast`` (numpy caster + pymunk oracle), ``scene`` (vehicles and roadside objects as
segments in a sensor frame), ``lidar``, ``radar``, ``clutter`` (roadside objects) and ``rig`` (timing
and frames); frame transforms G <-> sensor frames are ``tracker.transforms``. Conventions: DESIGN.md (SI units, E = ego frame,
x forward, y left; angles wrapped to (-pi, pi]).
"""

from sim.sensors.clutter import ClutterConfig, RoadsideObjects, generate_roadside
from sim.sensors.lidar import Lidar, LidarConfig, LidarScan
from sim.sensors.radar import FRONT_RADAR, REAR_RADAR, RadarConfig, RadarScan, RadarUnit, RadarUnitConfig
from sim.sensors.raycast import CastResult, RayGrid, Segments, cast_numpy, cast_pymunk
from sim.sensors.rig import RigConfig, SensorFrame, SensorRig

__all__ = [
    "FRONT_RADAR",
    "REAR_RADAR",
    "CastResult",
    "ClutterConfig",
    "Lidar",
    "LidarConfig",
    "LidarScan",
    "RadarConfig",
    "RadarScan",
    "RadarUnit",
    "RadarUnitConfig",
    "RayGrid",
    "RigConfig",
    "RoadsideObjects",
    "Segments",
    "SensorFrame",
    "SensorRig",
    "cast_numpy",
    "cast_pymunk",
    "generate_roadside",
]
