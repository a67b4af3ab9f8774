"""3-D lidar speed, per model: one scan of each 3-D lidar (``sim.sensors.lidar3d.LIDAR3D_MODELS``:
VLP-16, VLP-32C, HDL-64E, OS1-128) over a sloped road with traffic and roadside clutter, the tracker's
preprocessing of that cloud and its whole step on it.

The scene (``lidar3d_scene``): a curved 3-lane road (3.5 m lanes; 150 m straight, a 60 m clothoid
into a 300 m radius left bend of 250 m, a 60 m clothoid out and 150 m straight) on a ``RoadGround``
with grade 0.04 and bank 0.03; the ego in lane 1 at the middle of the bend; 20 vehicles in random
lane slots within +-90 m of it (boxes 4-5 x 1.7-2.1 m, 0.25 m ground clearance, 1.3-2.6 m tall);
and the 300 roadside objects nearest to the ego from ``generate_roadside`` (guard-rail posts every
4 m on both sides, 0.8 m tall; trees 6-10 m tall; parked cars 1.5 m tall), standing on the ground
(their base 0.3 m below the ground under their centre so no ray passes under them on the slope).

``bench_lidar3d(repeats, model=...)`` times ``Lidar3D.scan`` of one model (its beams and azimuth step,
100 m) and ``cast_3d`` alone, reporting the median and 95th percentile in ms after a warm-up scan
(which also builds the ground's casting grid, timed separately as ``ground_grid_build_s``), plus what
the scan saw; the tracker's cloud preprocessing (``tracker.cloud.process_cloud``: mount transform,
ground removal, height ceiling) with its ground-removal recall and precision and the share of vehicle
returns kept; and ``tracker_step``: ``Tracker.step`` on frames of that cloud 0.1 s apart (the scene
standing still, the ego at rest), the first ``TRACKER_WARM_UP`` steps (births) not timed; and
Patchwork++ (``pypatchworkpp``, when installed: the ``baselines`` extra) on the same cloud, timed and
scored the same way.
``bench_lidar3d_models`` runs every model; ``bench_rig`` a rig of two lidars (``RIG``: a VLP-32C on
the roof at 1.9 m and an OS1-128 above it at 2.2 m) whose clouds are merged in the vehicle frame, as a
real rig's driver delivers them, and go to the tracker as one cloud in E (``CloudConfig.frame =
"vehicle"``); ``bench_all`` both. ``eot bench lidar3d`` runs it pinned to one core; set
``OMP_NUM_THREADS=1`` too (numpy's element-wise work is single-threaded anyway). The simulator's scan
target is 15 ms on one core for the VLP-16; the tracker's step target is 30 ms (p95) on one core.
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import numpy as np

from sim.benchmarks._machine import one_core
from sim.benchmarks._patchwork import MISSING, Patchwork
from sim.sensors.clutter import ClutterConfig, generate_roadside
from sim.sensors.lidar3d import (
    LIDAR3D_MODELS,
    Lidar3D,
    Lidar3DConfig,
    Prisms,
    cast_3d,
    merge_scans,
)
from sim.evaluation.runner import told_lidar
from sim.world.ground import RoadGround
from tracker import EgoState, Frame, Tracker, TrackerConfig
from tracker.cloud import CloudConfig, process_cloud
from tracker.road import Road

TARGET_MS = 15.0
#: The tracker's whole step on one sweep, p95, one core (ms).
TRACKER_TARGET_MS = 30.0
#: Tracker steps not timed at the start (the births of the vehicles in view).
TRACKER_WARM_UP = 5
LANES = 3
LANE_WIDTH = 3.5
GRADE = 0.04
BANK = 0.03


def lidar3d_scene(seed: int = 0, vehicles: int = 20, roadside: int = 300) -> dict:
    """The benchmark scene (module docstring): ``road``, ``ground``, ``prisms`` (vehicles first, then
    roadside objects), ``vehicle_ids``, the ego ``origin`` (3,) and ``yaw``, and counts."""
    rng = np.random.default_rng(seed)
    k = 1.0 / 300.0
    road = Road.from_curvature(
        [(150.0, 0.0, 0.0), (60.0, 0.0, k), (250.0, k, k), (60.0, k, 0.0), (150.0, 0.0, 0.0)],
        lanes=LANES,
        lane_width=LANE_WIDTH,
    )
    ground = RoadGround(road, grade=GRADE, bank=BANK)
    ego_s = 150.0 + 60.0 + 125.0
    lanes = road.lane_centers
    ego_xy = road.to_cartesian(ego_s, float(lanes[1]))
    ego_z = float(ground.height(ego_xy[None])[0])
    ego_yaw = float(road.heading(ego_s))

    offsets = np.arange(-90.0, 91.0, 10.0)
    slots = [(lane, ds) for lane in range(LANES) for ds in offsets if not (lane == 1 and ds == 0.0)]
    if vehicles > len(slots):
        raise ValueError(f"the benchmark scene has room for {len(slots)} vehicles; asked for {vehicles}")
    pick = rng.choice(len(slots), vehicles, replace=False)
    s = np.array([ego_s + slots[i][1] + rng.uniform(-2.0, 2.0) for i in pick])
    n = np.array([lanes[slots[i][0]] for i in pick])
    xy = road.to_cartesian(s, n).reshape(-1, 2)
    gz = ground.height(xy)
    cars = Prisms.from_rectangles(
        xy,
        road.heading(s) + rng.normal(0.0, 0.03, vehicles),
        rng.uniform(4.0, 5.0, vehicles),
        rng.uniform(1.7, 2.1, vehicles),
        gz + 0.25,
        gz + 0.25 + rng.uniform(1.3, 2.6, vehicles),
        np.arange(vehicles),
    )

    config = ClutterConfig(post_spacing=4.0, tree_density=45.0, parked_car_density=12.0)
    objects = generate_roadside(road, config, rng=rng)
    near = np.argsort(np.hypot(*(objects.centre - ego_xy).T))[:roadside]
    objects = objects.select(np.sort(near))
    kind = objects.kind
    height = np.where(kind == "post", 0.8, np.where(kind == "tree", rng.uniform(6.0, 10.0, len(objects)), 1.5))
    base = ground.height(objects.centre) - 0.3
    owners = vehicles + np.arange(len(objects))  # the owner convention of Lidar3D.scan
    clutter = Prisms.from_polygons(objects.vertices, objects.offsets, base, base + 0.3 + height, owners)
    return {
        "road": road,
        "ground": ground,
        "prisms": Prisms.concatenate([cars, clutter]),
        "vehicle_ids": np.arange(1, vehicles + 1),
        "origin": np.array([ego_xy[0], ego_xy[1], ego_z]),
        "yaw": ego_yaw,
        "vehicles": vehicles,
        "roadside_objects": len(objects),
        "farthest_vehicle_m": float(np.hypot(*(xy - ego_xy).T).max()),
        "farthest_roadside_m": float(np.hypot(*(objects.centre - ego_xy).T).max()),
    }


def _times_ms(fn, repeats: int) -> list[float]:
    out = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        out.append(1e3 * (time.perf_counter() - t0))
    return out


def _stats(times: list[float]) -> dict[str, float]:
    ordered = sorted(times)
    p95 = ordered[min(len(ordered) - 1, math.ceil(0.95 * len(ordered)) - 1)]
    return {"median_ms": round(statistics.median(ordered), 3), "p95_ms": round(p95, 3), "min_ms": round(ordered[0], 3)}


def bench_lidar3d(repeats: int = 50, seed: int = 0, *, model: str = "vlp16", pin: bool = True,
                  verbose: bool = True) -> dict:
    """Time one scan of the 3-D lidar ``model`` over the benchmark scene (module docstring) ``repeats``
    times, the tracker's preprocessing of it and its whole step on it; returns (and with ``verbose``
    prints) the median / p95 ms of ``Lidar3D.scan``, ``cast_3d``, ``process_cloud`` and ``Tracker.step``."""
    if isinstance(repeats, bool) or not isinstance(repeats, int) or repeats < 1:
        raise ValueError(f"bench_lidar3d: repeats must be a positive integer; got {repeats!r}")
    scene = lidar3d_scene(seed)
    lidar = Lidar3D(Lidar3DConfig.of_model(model))
    rng = np.random.default_rng(seed)
    prisms, ground = scene["prisms"], scene["ground"]
    origin, yaw, ids = scene["origin"], scene["yaw"], scene["vehicle_ids"]
    position, rotation = lidar.pose(origin, yaw)
    directions = lidar.config.directions @ rotation.T
    with one_core(pin) as cpu:
        t0 = time.perf_counter()
        scan = lidar.scan(origin, yaw, prisms, ground, vehicle_ids=ids, rng=rng)  # warm-up; builds the grid
        build_s = time.perf_counter() - t0
        scan_ms = _times_ms(lambda: lidar.scan(origin, yaw, prisms, ground, vehicle_ids=ids, rng=rng), repeats)
        cast_ms = _times_ms(lambda: cast_3d(position, directions, prisms, ground, lidar.config.max_range), repeats)
        cloud = process_cloud(scan.points)  # the tracker's 3-D pipeline (its default mount is the models' 1.9 m roof)
        cloud_ms = _times_ms(lambda: process_cloud(scan.points), repeats)
        step_ms, tracks = _tracker_steps(scene, scan.points, repeats, [lidar.config])
        patchwork = _patchwork(scan, lidar.config.mount_z, lidar.config.max_range, repeats)
    removed = cloud.ground | cloud.below_ground
    result = {
        "model": model,
        "scene": {
            "rays": lidar.config.rays,
            "vehicles": scene["vehicles"],
            "roadside_objects": scene["roadside_objects"],
            "farthest_vehicle_m": round(scene["farthest_vehicle_m"], 1),
            "farthest_roadside_m": round(scene["farthest_roadside_m"], 1),
            "grade": GRADE,
            "bank": BANK,
            "points": len(scan),
            "ground_points": int(scan.ground.sum()),
            "vehicle_points": int((scan.vehicle_id >= 0).sum()),
            "roadside_points": int((scan.roadside_index >= 0).sum()),
        },
        "scan": _stats(scan_ms),
        "cast": _stats(cast_ms),
        "preprocess": _stats(cloud_ms),
        "tracker_step": {**_stats(step_ms), "tracks": tracks, "target_p95_ms": TRACKER_TARGET_MS},
        "ground_removal": _scores(removed, scan, cloud.kept),
        "patchworkpp": patchwork,
        "ground_grid_build_s": round(build_s, 3),
        "repeats": repeats,
        "pinned_cpu": cpu,
        "target_ms": TARGET_MS,
    }
    if verbose:
        print(_line(result))
    return result


#: The two-lidar rig of ``bench_rig``: (model, mount height in m) per lidar, both over the ego's centre,
#: the first the primary one; their clouds merged in the vehicle frame as a rig's driver delivers them.
RIG = (("vlp32c", 1.9), ("os1-128", 2.2))


def bench_rig(repeats: int = 50, seed: int = 0, *, pin: bool = True, verbose: bool = True) -> dict:
    """``bench_lidar3d`` for the two-lidar rig ``RIG``: both scans of the benchmark scene merged into
    one cloud in E (``CloudConfig.frame = "vehicle"``, the primary lidar's mount), the tracker's
    preprocessing of it and its whole step on it, and the ground removal's scores; Patchwork++, which
    takes one sensor's cloud, on each lidar's own points (``_patchwork_rig``)."""
    if isinstance(repeats, bool) or not isinstance(repeats, int) or repeats < 1:
        raise ValueError(f"bench_rig: repeats must be a positive integer; got {repeats!r}")
    scene = lidar3d_scene(seed)
    lidars = [Lidar3D(Lidar3DConfig.of_model(model, mount_z=z)) for model, z in RIG]
    rng = np.random.default_rng(seed)
    prisms, ground = scene["prisms"], scene["ground"]
    origin, yaw, ids = scene["origin"], scene["yaw"], scene["vehicle_ids"]
    config = CloudConfig(frame="vehicle", mount_z=RIG[0][1])

    mounts = [(lidar.config.mount_rotation, lidar.config.mount_translation) for lidar in lidars]

    def sweep():  # as sim.sensors.rig.SceneLidar3D scans a rig
        scans = [lidar.scan(origin, yaw, prisms, ground, vehicle_ids=ids, rng=rng) for lidar in lidars]
        return merge_scans(scans, mounts, origin, yaw)

    with one_core(pin) as cpu:
        sweep()  # warm-up; builds the grid
        scan_ms = _times_ms(sweep, repeats)
        merged = sweep()
        cloud = merged.points
        result_cloud = process_cloud(cloud, config)
        cloud_ms = _times_ms(lambda: process_cloud(cloud, config), repeats)
        step_ms, tracks = _tracker_steps(scene, cloud, repeats, [lidar.config for lidar in lidars], config)
    removed = result_cloud.ground | result_cloud.below_ground
    result = {
        "model": "+".join(model for model, _ in RIG),
        "scene": {"rays": sum(lidar.config.rays for lidar in lidars), "vehicles": scene["vehicles"],
                  "roadside_objects": scene["roadside_objects"], "grade": GRADE, "bank": BANK, "points": len(cloud),
                  "ground_points": int(merged.ground.sum()), "vehicle_points": int((merged.vehicle_id >= 0).sum()),
                  "mounts_z_m": [z for _, z in RIG]},
        "scan": _stats(scan_ms),
        "preprocess": _stats(cloud_ms),
        "tracker_step": {**_stats(step_ms), "tracks": tracks, "target_p95_ms": TRACKER_TARGET_MS},
        "ground_removal": _scores(removed, merged, result_cloud.kept),
        "patchworkpp": _patchwork_rig(merged, lidars, repeats),
        "repeats": repeats,
        "pinned_cpu": cpu,
    }
    if verbose:
        print(_line(result))
    return result


def _tracker_steps(scene: dict, cloud: np.ndarray, repeats: int, lidars: list[Lidar3DConfig],
                   cloud_config: CloudConfig | None = None) -> tuple[list[float], int]:
    """``Tracker.step`` times (ms) on ``repeats`` frames of ``cloud`` (the lidar's frame, or E with a
    ``cloud_config`` that says so) 0.1 s apart after ``TRACKER_WARM_UP`` untimed ones, the ego at rest
    at the scene's pose; and the tracks at the end. The tracker is told the ``lidars``' range and finest
    azimuth step (``sim.evaluation.runner.told_lidar``, as a scenario's run is)."""
    config = TrackerConfig() if cloud_config is None else TrackerConfig(cloud=cloud_config)
    config = told_lidar(config, float(max(c.max_range for c in lidars)),
                        math.radians(min(c.resolution_deg for c in lidars)))
    tracker = Tracker(scene["road"], config)
    ego = EgoState(x=float(scene["origin"][0]), y=float(scene["origin"][1]), yaw=float(scene["yaw"]), v=0.0)
    times, tracks = [], []
    for k in range(TRACKER_WARM_UP + repeats):
        frame = Frame(t=0.1 * k, ego=ego, lidar=cloud)
        t0 = time.perf_counter()
        tracks = tracker.step(frame)
        if k >= TRACKER_WARM_UP:
            times.append(1e3 * (time.perf_counter() - t0))
    return times, len(tracks)


def _scores(removed: np.ndarray, scan, kept: np.ndarray | None = None) -> dict[str, float]:
    """Ground removal against the scan's labels: recall of the ground returns, precision of the removed
    ones, and the share of vehicle returns ``kept`` (default: those not removed)."""
    ground, vehicle = scan.ground, scan.vehicle_id >= 0
    kept = ~removed if kept is None else kept
    return {"recall": round(float((removed & ground).sum() / max(int(ground.sum()), 1)), 5),
            "precision": round(float((removed & ground).sum() / max(int(removed.sum()), 1)), 5),
            "vehicle_points_kept": round(float((kept & vehicle).sum() / max(int(vehicle.sum()), 1)), 5)}


def _patchwork(scan, sensor_height: float, max_range: float, repeats: int) -> dict:
    """Patchwork++ (``sim.benchmarks._patchwork``) on the same cloud in the sensor frame: the median /
    p95 ms of one segmentation and its ground-removal scores; ``{"skipped": ...}`` without the package."""
    segmenter = Patchwork.create(sensor_height, max_range)
    if segmenter is None:
        return {"skipped": MISSING}
    segmenter.ground(scan.points)
    times = _times_ms(lambda: segmenter.ground(scan.points), repeats)
    return {**_stats(times), **_scores(segmenter.ground(scan.points), scan)}


def _patchwork_rig(merged, lidars: list, repeats: int) -> dict:
    """Patchwork++ on a rig's merged cloud the only way it can: on each lidar's own points, back in that
    lidar's frame, with a segmenter for its height; the time is the sum over the lidars (median / p95 ms
    of the whole), the scores those of the union of their ground masks."""
    segmenters = [Patchwork.create(lidar.config.mount_z, lidar.config.max_range) for lidar in lidars]
    if any(seg is None for seg in segmenters):
        return {"skipped": MISSING}
    own = [merged.sensor == k for k in range(len(lidars))]
    clouds = [(merged.points[m] - lidar.config.mount_translation) @ lidar.config.mount_rotation
              for m, lidar in zip(own, lidars)]  # p_S = R^T (p_E - t)

    def segment() -> np.ndarray:
        removed = np.zeros(len(merged), dtype=bool)
        for seg, m, cloud in zip(segmenters, own, clouds):
            removed[m] = seg.ground(cloud)
        return removed

    segment()
    times = _times_ms(segment, repeats)
    return {**_stats(times), **_scores(segment(), merged), "per_lidar": True}


def bench_lidar3d_models(repeats: int = 50, seed: int = 0, *, models: list[str] | None = None, pin: bool = True,
                         verbose: bool = True) -> dict:
    """``bench_lidar3d`` of each of ``models`` (default: every one of ``LIDAR3D_MODELS``), by name."""
    names = list(LIDAR3D_MODELS) if models is None else list(models)
    unknown = [m for m in names if m not in LIDAR3D_MODELS]
    if unknown or not names:
        raise ValueError(f"bench_lidar3d_models: models must be some of {list(LIDAR3D_MODELS)}; got {models!r}")
    return {name: bench_lidar3d(repeats, seed, model=name, pin=pin, verbose=verbose) for name in names}


def bench_all(repeats: int = 50, seed: int = 0, *, models: list[str] | None = None, rig: bool = True,
              pin: bool = True, verbose: bool = True) -> dict:
    """``bench_lidar3d_models`` and, with ``rig``, ``bench_rig`` under the key ``"rig"``."""
    out = bench_lidar3d_models(repeats, seed, models=models, pin=pin, verbose=verbose)
    if rig:
        out["rig"] = bench_rig(repeats, seed, pin=pin, verbose=verbose)
    return out


def _line(result: dict) -> str:
    s, g, st = result["scan"], result["ground_removal"], result["tracker_step"]
    return (f"{result['model']} scan ({result['scene']['rays']} rays, {result['scene']['points']} points): median "
            f"{s['median_ms']:.2f} ms, p95 {s['p95_ms']:.2f} ms; the tracker: preprocessing (tracker.cloud) median "
            f"{result['preprocess']['median_ms']:.2f} ms, whole step median {st['median_ms']:.2f} ms, p95 "
            f"{st['p95_ms']:.2f} ms ({st['tracks']} tracks; target p95 {TRACKER_TARGET_MS:g} ms); ground removal "
            f"recall {g['recall']:.4f}, precision {g['precision']:.4f}, vehicle points kept {g['vehicle_points_kept']:.4f}"
            + _patchwork_line(result["patchworkpp"]))


def _patchwork_line(p: dict) -> str:
    if "skipped" in p:
        return f"; Patchwork++ skipped ({p['skipped']})"
    where = "on each lidar's points, summed" if p.get("per_lidar") else "on the same cloud"
    return (f"; Patchwork++ {where} {p['median_ms']:.2f} ms median, recall {p['recall']:.4f}, precision "
            f"{p['precision']:.4f}, vehicle points kept {p['vehicle_points_kept']:.4f}")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``eot bench lidar3d``."""
    parser.add_argument("--repeats", type=int, default=50, help="timed scans and tracker steps per model (default 50)")
    parser.add_argument("--seed", type=int, default=0, help="scene seed (default 0)")
    parser.add_argument("--model", action="append", choices=list(LIDAR3D_MODELS),
                        help="3-D lidar model, repeatable (default: every one, and the two-lidar rig)")


def run(args: argparse.Namespace) -> dict:
    """``bench_all`` with the command line's options (the JSON is printed by ``eot bench``): the models
    named, else every model and the two-lidar rig."""
    models = getattr(args, "model", None)
    return bench_all(int(getattr(args, "repeats", 50)), int(getattr(args, "seed", 0)), models=models,
                     rig=models is None, verbose=False)


def summary(result: dict) -> str:
    """One line per model after the JSON."""
    return "\n".join(_line(r) for r in result.values())
