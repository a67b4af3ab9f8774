"""Sensor models: lidar ray casting (the compiled caster vs pymunk), radar cycles and rig frames.

The scene: the ego in lane 1 of a straight 200 m, 4-lane road (3.5 m lanes) at its middle, 20 other
vehicles in random lane slots within +-75 m, and 300 roadside objects (guard-rail posts every 4 m on
both sides, trees and parked cars), seen by an 1800-ray (0.2 deg) lidar with a 100 m range. Reports the
median wall-clock milliseconds of:

- ``cast_ms``: ``sim.sensors.raycast.cast`` on the scene already in E (the caster alone);
- ``scan_ms``: ``Lidar.scan`` with the default caster (scene to E, cast, noise, points);
- ``pymunk_cast_ms``: ``cast_pymunk`` (build the pymunk space, then one query per ray);
- ``pymunk_query_ms``: the pymunk queries alone on a prebuilt space;
- ``pymunk_scan_ms``: ``Lidar.scan`` with the pymunk caster;
- ``radar_cycle_ms``: one front-radar cycle (visibility fan of 901 rays + detections);
- ``rig_frame_ms``: one ``SensorRig`` frame (one scan plus ~2.8 radar cycles on average);

and the agreement of the two casters on the benchmark scan (rays both hit, max range difference,
hit/miss and owner mismatches).
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from sim.benchmarks._timing import median_seconds
from sim.sensors.clutter import ClutterConfig, RoadsideObjects, generate_roadside
from sim.sensors.lidar import Lidar, LidarConfig
from sim.sensors.radar import FRONT_RADAR, RadarUnit
from sim.sensors.raycast import PymunkScene, RayGrid, cast, cast_pymunk
from sim.sensors.rig import RigConfig, SensorRig
from sim.sensors.scene import scene_segments
from sim.world.truth import EgoPose, Snapshot

LANE_WIDTH = 3.5
LANES = 4
ROAD_LENGTH = 200.0


class _StraightRoad:
    """A straight road along +x (the small interface ``generate_roadside`` needs)."""

    length = ROAD_LENGTH
    closed = False
    right_edge = -0.5 * LANES * LANE_WIDTH
    left_edge = 0.5 * LANES * LANE_WIDTH

    def to_cartesian(self, s: np.ndarray, n: np.ndarray) -> np.ndarray:
        return np.stack([np.asarray(s, dtype=float), np.asarray(n, dtype=float)], axis=-1)

    def heading(self, s: np.ndarray) -> np.ndarray:
        return np.zeros(np.shape(s))


def scene(seed: int = 0, vehicles: int = 20, roadside: int = 300) -> tuple[Snapshot, RoadsideObjects]:
    """The benchmark scene (see the module docstring): a snapshot at t = 0 and the roadside objects."""
    rng = np.random.default_rng(seed)
    road = _StraightRoad()
    config = ClutterConfig(post_spacing=4.0, tree_density=45.0, parked_car_density=12.0)
    objects = generate_roadside(road, config, rng=rng)
    if len(objects) < roadside:
        raise ValueError(f"the benchmark scene has only {len(objects)} roadside objects; asked for {roadside}")
    objects = objects.select(np.sort(rng.choice(len(objects), roadside, replace=False)))
    lanes = road.right_edge + (np.arange(LANES) + 0.5) * LANE_WIDTH
    ego_s, ego_lane = 0.5 * ROAD_LENGTH, 1
    slots = [(lane, ds) for lane in range(LANES) for ds in np.arange(-75.0, 76.0, 10.0) if not (lane == ego_lane and ds == 0)]
    if vehicles > len(slots):
        raise ValueError(f"the benchmark scene has room for {len(slots)} vehicles; asked for {vehicles}")
    pick = rng.choice(len(slots), vehicles, replace=False)
    xy = np.array([[ego_s + slots[i][1] + rng.uniform(-2, 2), lanes[slots[i][0]]] for i in pick]).reshape(-1, 2)
    snapshot = Snapshot(
        t=0.0,
        ego=EgoPose(ego_s, lanes[ego_lane], 0.0, 25.0),
        ids=np.arange(1, vehicles + 1),
        xy=xy,
        yaw=rng.normal(0.0, 0.03, vehicles),
        v=rng.uniform(20.0, 30.0, vehicles),
        yaw_rate=np.zeros(vehicles),
        length=rng.uniform(4.0, 5.0, vehicles),
        width=rng.uniform(1.7, 2.1, vehicles),
    )
    return snapshot, objects


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``eot bench sensors``."""
    parser.add_argument("--repeats", type=int, default=200, help="timed repeats of the caster, scans, radar cycles and rig frames (default 200)")
    parser.add_argument("--pymunk-repeats", type=int, default=15, help="timed repeats of the pymunk casts (default 15)")
    parser.add_argument("--seed", type=int, default=0, help="scene seed (default 0)")
    parser.add_argument("--vehicles", type=int, default=20, help="other vehicles (default 20)")
    parser.add_argument("--roadside", type=int, default=300, help="roadside objects (default 300)")
    parser.add_argument("--resolution-deg", type=float, default=0.2, help="lidar azimuth step (default 0.2 -> 1800 rays)")


def run(args: argparse.Namespace) -> dict:
    """Measure the sensor models on the benchmark scene; returns the numbers (see the module docstring)."""
    repeats = int(getattr(args, "repeats", 200))
    pm_repeats = int(getattr(args, "pymunk_repeats", 15))
    seed = int(getattr(args, "seed", 0))
    vehicles = int(getattr(args, "vehicles", 20))
    roadside = int(getattr(args, "roadside", 300))
    resolution = float(getattr(args, "resolution_deg", 0.2))
    if repeats < 1 or pm_repeats < 1:
        raise ValueError("--repeats and --pymunk-repeats must be >= 1")

    snapshot, objects = scene(seed, vehicles, roadside)
    ego = snapshot.ego
    lidar = Lidar(LidarConfig(resolution_deg=resolution))
    lidar_pm = Lidar(LidarConfig(resolution_deg=resolution, caster="pymunk"))
    grid = RayGrid.full_circle(math.radians(resolution))
    max_range = lidar.config.max_range
    segments = scene_segments(snapshot, objects, (ego.x, ego.y), ego.yaw)
    rng = np.random.default_rng(seed)

    res = cast(segments, grid, max_range)
    res_pm = cast_pymunk(segments, grid, max_range)
    both = res.hit & res_pm.hit
    pm_scene = PymunkScene(segments)

    radar = RadarUnit(FRONT_RADAR)
    rig = SensorRig(RigConfig(lidar=lidar.config), objects)
    frames = rig.frames(lambda t: _moved(snapshot, t), None, seed=seed)

    result = {
        "scene": {
            "rays": grid.count,
            "vehicles": vehicles,
            "roadside_objects": len(objects),
            "segments": len(segments),
            "rays_hit": int(res.hit.sum()),
            "max_range_m": max_range,
        },
        "cast_ms": 1e3 * median_seconds(lambda: cast(segments, grid, max_range), repeats),
        "scan_ms": 1e3 * median_seconds(lambda: lidar.scan(snapshot, objects, rng=rng), repeats),
        "pymunk_cast_ms": 1e3 * median_seconds(lambda: cast_pymunk(segments, grid, max_range), pm_repeats),
        "pymunk_query_ms": 1e3 * median_seconds(lambda: pm_scene.cast(grid, max_range), pm_repeats),
        "pymunk_scan_ms": 1e3 * median_seconds(lambda: lidar_pm.scan(snapshot, objects, rng=rng), pm_repeats),
        "radar_cycle_ms": 1e3 * median_seconds(lambda: radar.detect(snapshot, objects, rng=rng), repeats),
        "rig_frame_ms": 1e3 * median_seconds(lambda: next(frames), repeats),
        "agreement": {
            "rays_both_hit": int(both.sum()),
            "hit_mismatches": int((res.hit != res_pm.hit).sum()),
            "owner_mismatches": int((res.owner[both] != res_pm.owner[both]).sum()),
            "max_range_diff_m": float(np.max(np.abs(res.range[both] - res_pm.range[both]), initial=0.0)),
        },
        "repeats": {"cast": repeats, "pymunk": pm_repeats},
    }
    result["default_caster"] = LidarConfig().caster
    result["speedup_over_pymunk"] = result["pymunk_cast_ms"] / result["cast_ms"]
    return result


def _moved(snapshot: Snapshot, t: float) -> Snapshot:
    """The benchmark snapshot advanced to time ``t`` (s) at constant velocity (ego too)."""
    ego = snapshot.ego
    return Snapshot(
        t=t,
        ego=EgoPose(ego.x + ego.v * math.cos(ego.yaw) * t, ego.y + ego.v * math.sin(ego.yaw) * t, ego.yaw, ego.v),
        ids=snapshot.ids,
        xy=snapshot.xy + snapshot.velocity * t,
        yaw=snapshot.yaw,
        v=snapshot.v,
        yaw_rate=snapshot.yaw_rate,
        length=snapshot.length,
        width=snapshot.width,
    )
