"""Sensor models of the testbed: a ray-cast 2-D lidar and a 3-D VLP-16, object-level radars,
roadside clutter, sensor faults, and the rig that turns truth over time into the tracker's ``Frame``s.

Above ``sim.world`` (truth, ground, scenario settings); below ``sim.evaluation``. Modules:

- ``sim.sensors.raycast``: 2-D ray casting (the compiled caster + a pymunk oracle); a lidar's returns of a cast;
- ``sim.sensors.lidar3d``: the 3-D ray-cast VLP-16 over upright prisms and the ground;
- ``sim.sensors.scene``: vehicles and roadside objects as segments (2-D) or prisms (3-D) for a sensor;
- ``sim.sensors.clutter``: roadside objects beside the road (posts, trees, parked cars);
- ``sim.sensors.lidar``: ``LidarConfig`` (2-D or VLP-16) and the 2-D lidar;
- ``sim.sensors.radar``: the front and rear object-level radars;
- ``sim.sensors.rig``: the rig: timing, and the frames the tracker gets;
- ``sim.sensors.faults``: sensor faults applied to the rig's frames (dropouts, spikes, duplicates).

Frame transforms G <-> sensor frames are ``tracker.transforms``. Conventions: docs/architecture.md (SI units,
E = ego frame, x forward, y left; angles wrapped to (-pi, pi]).
"""

from sim.sensors.clutter import ClutterConfig, RoadsideObjects, generate_roadside
from sim.sensors.lidar import Lidar, LidarConfig, LidarScan
from sim.sensors.radar import FRONT_RADAR, REAR_RADAR, RadarConfig, RadarScan, RadarUnit, RadarUnitConfig
from sim.sensors.raycast import CastResult, RayGrid, Segments, cast, cast_pymunk
from sim.sensors.rig import RigConfig, SensorFrame, SensorRig
from tracker.warmup import register_warm_up

from sim.sensors import radar as _radar, raycast as _raycast, scene as _scene

# tracker.warmup.warm_up() also compiles the sensors' kernels (registered here, not in the kernels' own
# modules: a kernel's cache key covers the modules its module imports, and warmup imports the tracker)
for _warm in (_raycast._warm_up_cast, _scene._warm_up_scene, _radar._warm_up_visible):
    register_warm_up(_warm)

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
    "cast",
    "cast_pymunk",
    "generate_roadside",
]
