"""The sensor rig: lidar + radar units on the ego, producing the tracker's ``Frame``s over time.

Timing (all relative to ``t0``): lidar scans at ``lidar.phase_s + k / lidar.rate_hz`` (10 Hz), each
radar unit cycles at ``phase_s + j / rate_hz`` (14 Hz, phases 0.023 s and 0.059 s by default, so not in
phase with the lidar). Every lidar time yields one ``SensorFrame``: a ``tracker.Frame`` with that scan
and the radar detections of the cycles in ``(previous lidar time, this lidar time]`` (the first frame
takes those from ``t0``), each keeping its own timestamp; positions and velocities are moved from E at
the detection time into E at the frame time with the true ego poses (perfect odometry). Radar cycles
after the last frame are not delivered. The truth ``Snapshot`` at the frame time travels beside the
frame, never inside it.

The lidar is the 2-D scan of ``sim.sensors.lidar`` or, with a 3-D ``lidar.model`` (``"vlp16"``,
``"vlp32c"``, ``"hdl64e"``, ``"os1-128"``), the 3-D lidar of ``sim.sensors.lidar3d`` over the rig's
``ground`` (``sim.world.ground``; level by default): the frame then carries the raw cloud ``(N, 3)``
in the lidar's frame, as a real driver delivers it, and
the tracker's own 3-D pipeline (``tracker.cloud``) removes the ground.

``truth_at(t)`` is called with non-decreasing times, once per distinct time, so a world that can
only advance forward can serve it. Randomness: one ``numpy.random.SeedSequence(seed)`` spawns an
independent generator for the lidar and for each radar unit, so the same seed gives identical
output, and changing one sensor's settings leaves the other sensors' noise unchanged.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import numpy as np

from sim.sensors.clutter import RoadsideObjects
from sim.sensors.lidar import Lidar, LidarConfig, LidarScan
from sim.sensors.lidar3d import EGO_BODY_ID, Lidar3D, LidarScan3D, Prisms, merge_scans
from sim.sensors.radar import RadarConfig, RadarScan, RadarUnit
from sim.sensors.scene import VEHICLE_CLEARANCE, vehicle_prisms
from sim.world.ground import FlatGround, Ground
from sim.world.truth import EgoPose, Snapshot
from tracker.frame import EgoState, Frame, RadarDetections
from tracker.transforms import rotate, to_global, to_local

#: Slack (s) when comparing event times and the time of a snapshot returned by ``truth_at``.
TIME_TOLERANCE = 1e-9


@dataclass(frozen=True)
class RigConfig:
    """The rig's sensors: ``lidar`` (``LidarConfig()``: 10 Hz, 0.2 deg, 100 m) and ``radar``
    (``RadarConfig()``: front and rear units at 14 Hz)."""

    lidar: LidarConfig = field(default_factory=LidarConfig)
    radar: RadarConfig = field(default_factory=RadarConfig)

    def __post_init__(self) -> None:
        if not isinstance(self.lidar, LidarConfig):
            raise ValueError(f"RigConfig.lidar must be a LidarConfig; got {type(self.lidar).__name__}")
        if not isinstance(self.radar, RadarConfig):
            raise ValueError(f"RigConfig.radar must be a RadarConfig; got {type(self.radar).__name__}")


@dataclass(frozen=True, eq=False)
class SensorFrame:
    """One frame: ``frame`` (the tracker's input), ``truth`` (the snapshot at ``frame.t``), and the
    labelled sensor data behind the frame: ``lidar`` (the scan, points in E) and ``radar`` (the
    detections in ``frame.radar`` order, in E at the frame time, with truth ids and units)."""

    frame: Frame
    truth: Snapshot
    lidar: LidarScan | LidarScan3D
    radar: RadarScan


class SceneLidar3D:
    """The 3-D lidar (a 3-D ``LidarConfig.model``), or a rig of several (``LidarConfig.rig``), seeing a
    snapshot's vehicles (upright boxes, ``sim.sensors.scene.vehicle_prisms``) and the static ``roadside``
    objects (prisms of their ``height`` standing on the ground at their centre) over ``ground``; ``scan``
    has the 2-D ``Lidar.scan``'s signature (the roadside objects are fixed at construction). One lidar
    gives its points in its own frame; a rig's lidars scan in order (each its two draws per ray from the
    one stream) and their points are merged in E (``sim.sensors.lidar3d.merge_scans``)."""

    def __init__(self, config: LidarConfig, roadside: RoadsideObjects | None, ground: Ground) -> None:
        self.config = config
        self.sensors = [Lidar3D(c) for c in config.lidar3d_configs()]
        self.sensor = self.sensors[0]
        self.ground = ground
        self.roadside_count = 0 if roadside is None else len(roadside)
        if self.roadside_count:
            base = ground.height(roadside.centre)
            self._static = Prisms.from_polygons(roadside.vertices, roadside.offsets, base, base + roadside.height)
        else:
            self._static = Prisms.empty()

    @property
    def frame(self) -> str:
        """The frame of the scans' points: ``"sensor"`` (one lidar) or ``"vehicle"`` (a rig, merged in E)."""
        return "vehicle" if len(self.sensors) > 1 else "sensor"

    def sees_own_body(self, ego: EgoPose, sensor: Lidar3D | None = None) -> bool:
        """Whether the lidar (``sensor``; default the first) sits outside the ego's box (above its roof, or
        beyond its footprint), so that its rays can return from the ego's own body; a lidar inside the box
        (a sensor set into a bumper) does not see it."""
        x, y, z = (sensor or self.sensor).config.mount_translation
        return bool(z > ego.height or abs(x) > 0.5 * ego.length or abs(y) > 0.5 * ego.width)

    def scan(self, snapshot: Snapshot, roadside: RoadsideObjects | None = None, *, rng: np.random.Generator) -> LidarScan3D:
        """One scan of ``snapshot`` from the ego pose at its ground height ``ego.z`` (``roadside`` is
        ignored: the objects given at construction are seen). The ego's own body (its box, from
        ``VEHICLE_CLEARANCE`` up to ``ego.height``) is in the scene of each lidar that sits outside it
        (``sees_own_body``): its returns have ``vehicle_id`` ``EGO_BODY_ID``."""
        ego = snapshot.ego
        vehicles = vehicle_prisms(snapshot, (ego.x, ego.y), self.config.max_range)
        origin = np.array([ego.x, ego.y, ego.z])
        scenes: dict[bool, tuple[Prisms, np.ndarray]] = {}  # the frame's scene with and without the ego's body

        def scene(with_body: bool) -> tuple[Prisms, np.ndarray]:
            if with_body not in scenes:
                parts = [vehicles]
                ids = snapshot.ids
                if with_body:  # owner V, its "vehicle id" EGO_BODY_ID
                    base = ego.z + min(VEHICLE_CLEARANCE, 0.5 * ego.height)
                    parts.append(Prisms.from_rectangles([[ego.x, ego.y]], ego.yaw, ego.length, ego.width, base,
                                                        ego.z + ego.height, owner=np.array([len(snapshot)])))
                    ids = np.append(np.asarray(snapshot.ids, dtype=np.int64), EGO_BODY_ID)
                if self.roadside_count:
                    st = self._static  # roadside object j is owner len(ids) + j
                    parts.append(st.relabel(st.owner + len(ids)))
                scenes[with_body] = (Prisms.concatenate(parts), ids)
            return scenes[with_body]

        scans = []
        for sensor in self.sensors:
            prisms, ids = scene(self.sees_own_body(ego, sensor))
            scans.append(sensor.scan(origin, ego.yaw, prisms, self.ground, vehicle_ids=ids, rng=rng, t=float(snapshot.t)))
        if len(scans) == 1:
            return scans[0]
        mounts = [(s.config.mount_rotation, s.config.mount_translation) for s in self.sensors]
        return merge_scans(scans, mounts, origin, ego.yaw)


def _seed_sequence(seed: int | np.random.SeedSequence) -> np.random.SeedSequence:
    if isinstance(seed, np.random.SeedSequence):  # a copy: spawning children must not change the caller's
        return np.random.SeedSequence(seed.entropy, spawn_key=seed.spawn_key, pool_size=seed.pool_size)
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer or a numpy.random.SeedSequence; got {seed!r}")
    return np.random.SeedSequence(int(seed))


class SensorRig:
    """Lidar and radar units of ``config`` (``RigConfig()`` by default) seeing the vehicles of the
    truth and the static ``roadside`` objects (may be ``None``; the radar and a 2-D lidar only those
    at least ``sim.sensors.clutter.FLAT_SCENE_MIN_HEIGHT`` tall); ``ground`` (``sim.world.ground``,
    level by default) is seen by the 3-D lidar only."""

    def __init__(self, config: RigConfig | None = None, roadside: RoadsideObjects | None = None,
                 ground: Ground | None = None) -> None:
        config = RigConfig() if config is None else config
        if not isinstance(config, RigConfig):
            raise ValueError(f"SensorRig needs a RigConfig; got {type(config).__name__}")
        if roadside is not None and not isinstance(roadside, RoadsideObjects):
            raise ValueError(f"SensorRig.roadside must be RoadsideObjects or None; got {type(roadside).__name__}")
        if ground is not None and not isinstance(ground, Ground):
            raise ValueError(f"SensorRig.ground must be a sim.world.ground.Ground or None; got {type(ground).__name__}")
        self.config = config
        self.roadside = roadside
        # the radar and a 2-D lidar pass over the objects lower than their beams (curbs)
        self._flat_roadside = None if roadside is None else roadside.flat_scene()
        self._lidar_roadside = roadside if config.lidar.model != "2d" else self._flat_roadside
        self.ground = FlatGround() if ground is None else ground
        self.lidar: Lidar | SceneLidar3D = (
            Lidar(config.lidar) if config.lidar.model == "2d" else SceneLidar3D(config.lidar, roadside, self.ground)
        )
        self.radars = [RadarUnit(unit, index) for index, unit in enumerate(config.radar.units)]

    def frame_times(self, duration: float, t0: float = 0.0) -> np.ndarray:
        """The lidar (frame) times (s) in ``[t0, t0 + duration]``."""
        cfg = self.config.lidar
        count = math.floor((duration - cfg.phase_s) * cfg.rate_hz + 1e-9) + 1
        return t0 + cfg.phase_s + np.arange(max(count, 0)) / cfg.rate_hz

    def frames(
        self,
        truth_at: Callable[[float], Snapshot],
        duration: float | None = None,
        *,
        seed: int | np.random.SeedSequence = 0,
        t0: float = 0.0,
        lidar_delay: float = 0.0,
        poses_at: Callable[[float], Snapshot] | None = None,
    ) -> Iterator[SensorFrame]:
        """Yield a ``SensorFrame`` at every lidar time from ``t0`` up to ``t0 + duration`` (s;
        forever when ``None``), lazily: ``truth_at`` is called only as far as the frame being made.

        ``lidar_delay`` (s, 0 by default, below the lidar's period) is a fault: the scan delivered
        with the frame stamped ``t`` is measured at ``t - lidar_delay`` (``SensorFrame.lidar.t``),
        while the ego pose, the truth and the radar keep their true times (``sim.sensors.faults``); a scan
        that would fall before ``t0`` is measured at ``t0``.

        ``poses_at`` (optional, e.g. ``World.poses_at``): a cheaper ``truth_at`` for the radar cycles
        between frames, whose snapshots need the vehicles' poses only (road coordinates may be NaN);
        the frames' truth and the lidar always come from ``truth_at``."""
        if not callable(truth_at):
            raise ValueError("SensorRig.frames needs truth_at, a callable t -> sim.world.truth.Snapshot")
        if poses_at is not None and not callable(poses_at):
            raise ValueError("SensorRig.frames: poses_at must be None or a callable t -> sim.world.truth.Snapshot")
        if duration is not None and not (isinstance(duration, (int, float)) and math.isfinite(duration) and duration >= 0):
            raise ValueError(f"duration must be a finite number of seconds >= 0 (or None); got {duration!r}")
        if not (isinstance(t0, (int, float)) and math.isfinite(t0)):
            raise ValueError(f"t0 must be a finite time in s; got {t0!r}")
        period = 1.0 / self.config.lidar.rate_hz
        if not (isinstance(lidar_delay, (int, float)) and 0.0 <= lidar_delay < period):
            raise ValueError(f"lidar_delay must be in [0, {period:g}) s (below the lidar's period); got {lidar_delay!r}")
        children = _seed_sequence(seed).spawn(1 + len(self.radars))
        lidar_rng = np.random.default_rng(children[0])
        radar_rngs = [np.random.default_rng(c) for c in children[1:]]
        lidar_cfg = self.config.lidar
        cycles = [0] * len(self.radars)
        last: list = [None, None]  # time, snapshot of the latest truth_at call

        last_pose: list = [None, None]  # time, snapshot of the latest poses_at call

        def fetch(source: Callable[[float], Snapshot], name: str, cache: list, t: float) -> Snapshot:
            if cache[0] is not None and t <= cache[0]:
                return cache[1]
            snap = source(t)
            if not isinstance(snap, Snapshot):
                raise ValueError(f"{name}({t!r}) must return a sim.world.truth.Snapshot; got {type(snap).__name__}")
            if abs(float(snap.t) - t) > 1e-6:
                raise ValueError(f"{name}({t!r}) returned a snapshot at t={snap.t!r}")
            cache[0], cache[1] = t, snap
            return snap

        def truth(t: float) -> Snapshot:
            return fetch(truth_at, "truth_at", last, t)

        def pose(t: float) -> Snapshot:
            if poses_at is None or (last[0] is not None and t <= last[0]):
                return truth(t)
            return fetch(poses_at, "poses_at", last_pose, t)

        def radar_time(i: int) -> float:
            unit = self.radars[i].config
            return t0 + unit.phase_s + cycles[i] / unit.rate_hz

        k = 0
        while True:
            t_frame = t0 + lidar_cfg.phase_s + k / lidar_cfg.rate_hz
            if duration is not None and t_frame > t0 + duration + TIME_TOLERANCE:
                return
            pending: list[tuple[RadarScan, np.ndarray, np.ndarray]] = []  # scan, xy in G, velocity in G
            t_scan = max(t_frame - lidar_delay, t0)  # the world does not exist before t0
            lidar_scan: LidarScan | LidarScan3D | None = None
            while self.radars:
                times = [radar_time(i) for i in range(len(self.radars))]
                i = int(np.argmin(times))  # ties: the lower unit index first
                if times[i] > t_frame + TIME_TOLERANCE:
                    break
                if lidar_scan is None and times[i] > t_scan + TIME_TOLERANCE:  # a delayed scan comes first
                    lidar_scan = self.lidar.scan(truth(t_scan), self._lidar_roadside, rng=lidar_rng)
                snap = pose(times[i])
                scan = self.radars[i].detect(snap, self._flat_roadside, rng=radar_rngs[i])
                ego = snap.ego
                pending.append((scan, to_global(scan.xy, (ego.x, ego.y), ego.yaw), rotate(scan.velocity, ego.yaw)))
                cycles[i] += 1
            if lidar_scan is None:
                lidar_scan = self.lidar.scan(truth(t_scan), self._lidar_roadside, rng=lidar_rng)
            snap = truth(t_frame)
            ego = snap.ego
            radar = RadarScan.concatenate(
                [
                    RadarScan(
                        t=scan.t,
                        xy=to_local(xy_g, (ego.x, ego.y), ego.yaw).reshape(-1, 2),
                        velocity=rotate(vel_g, -ego.yaw).reshape(-1, 2),
                        target_id=scan.target_id,
                        unit=scan.unit,
                    )
                    for scan, xy_g, vel_g in pending
                ]
            )
            frame = Frame(
                t=t_frame,
                ego=EgoState(ego.x, ego.y, ego.yaw, ego.v, ego.yaw_rate),
                lidar=lidar_scan.points,
                radar=RadarDetections(radar.t, radar.xy[:, 0], radar.xy[:, 1], radar.velocity[:, 0], radar.velocity[:, 1]),
            )
            yield SensorFrame(frame=frame, truth=snap, lidar=lidar_scan, radar=radar)
            k += 1

    def run(
        self,
        truth_at: Callable[[float], Snapshot],
        duration: float,
        *,
        seed: int | np.random.SeedSequence = 0,
        t0: float = 0.0,
    ) -> list[SensorFrame]:
        """All frames from ``t0`` to ``t0 + duration`` (s) as a list (see ``frames``)."""
        if duration is None:
            raise ValueError("SensorRig.run needs a finite duration; use SensorRig.frames for an endless stream")
        return list(self.frames(truth_at, duration, seed=seed, t0=t0))
