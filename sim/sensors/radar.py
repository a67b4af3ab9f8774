"""Object-level automotive radar (after the paper's two Continental ARS 408-21): front and rear units.

A unit is mounted on the ego's bumper centre, ``(+L/2, 0)`` facing forward (``mount="front"``) or
``(-L/2, 0)`` facing backward (``mount="rear"``), with ``L`` the ego length from the snapshot. Each
cycle (at ``t0 + phase_s + k / rate_hz``) it reports:

- one detection per *visible* vehicle, kept with ``detection_probability``. Visibility is decided by
  ray casting from the mount over the field of view (rays every ``visibility_resolution_deg``) against
  the vehicles and the roadside objects: a vehicle is visible when at least one ray's first hit is on
  it within ``[min_range, max_range]`` (scene, cast and nearest hits in one compiled call,
  ``visible_kernel``), so a fully hidden vehicle (no line of sight to any part) is never detected,
  and a vehicle outside the field of view or range is not either. The detection's
  position is the nearest visible point of the vehicle (the nearest first-hit point) plus isotropic
  Gaussian noise ``position_noise_std`` (0.5 m) per axis; its velocity is the vehicle's absolute
  velocity in G rotated into E's axes plus Gaussian noise ``velocity_noise_std`` (0.2 m/s) per axis;
- false alarms: a Poisson number (mean ``false_alarm_rate`` per cycle) of detections uniformly
  distributed over the area of the field-of-view sector between ``min_range`` and ``max_range``, with
  velocity components drawn from ``N(0, false_alarm_velocity_std^2)``.

Positions and velocities come out in E at the detection time (``RadarScan``); ``sim.sensors.rig``
moves them into E at the frame time. Stationary roadside objects occlude but are not reported.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from sim.sensors.clutter import RoadsideObjects
from sim.sensors.raycast import RayGrid, cast_kernel
from sim.sensors.scene import scene_kernel, static_arrays
from sim.world.truth import Snapshot
from tracker.jit import njit
from tracker.transforms import rotate, to_global

MOUNTS = ("front", "rear")


def _number(owner: str, name: str, value: float, low: float, *, strict: bool) -> None:
    ok = isinstance(value, (int, float)) and math.isfinite(value) and (value > low if strict else value >= low)
    if not ok:
        raise ValueError(f"{owner}.{name} must be a finite number {'>' if strict else '>='} {low}; got {value!r}")


@dataclass(frozen=True)
class RadarUnitConfig:
    """One radar unit (SI units; angles in degrees where the name says so). Defaults are the front
    unit's: ``mount`` "front" (or "rear"), ``half_fov_deg`` 45 (field of view +-45 deg about the
    boresight), ``max_range`` 150 m, ``min_range`` 0.2 m, ``rate_hz`` 14 Hz, ``phase_s`` 0.023 s
    (cycle times ``t0 + phase_s + k / rate_hz``, not in phase with the 10 Hz lidar),
    ``detection_probability`` 0.9, ``position_noise_std`` 0.5 m, ``velocity_noise_std`` 0.2 m/s,
    ``false_alarm_rate`` 0.5 (mean false alarms per cycle), ``false_alarm_velocity_std`` 10 m/s,
    ``visibility_resolution_deg`` 0.1 (ray spacing of the visibility test). ``name`` labels the unit."""

    name: str = "front"
    mount: str = "front"
    half_fov_deg: float = 45.0
    max_range: float = 150.0
    min_range: float = 0.2
    rate_hz: float = 14.0
    phase_s: float = 0.023
    detection_probability: float = 0.9
    position_noise_std: float = 0.5
    velocity_noise_std: float = 0.2
    false_alarm_rate: float = 0.5
    false_alarm_velocity_std: float = 10.0
    visibility_resolution_deg: float = 0.1

    def __post_init__(self) -> None:
        who = f"RadarUnitConfig({self.name!r})"
        if self.mount not in MOUNTS:
            raise ValueError(f"{who}.mount must be one of {MOUNTS}; got {self.mount!r}")
        if not (isinstance(self.half_fov_deg, (int, float)) and 0.0 < self.half_fov_deg < 180.0):
            raise ValueError(f"{who}.half_fov_deg must be in (0, 180) degrees; got {self.half_fov_deg!r}")
        _number(who, "max_range", self.max_range, 0.0, strict=True)
        _number(who, "min_range", self.min_range, 0.0, strict=False)
        if self.min_range >= self.max_range:
            raise ValueError(f"{who}.min_range ({self.min_range}) must be below max_range ({self.max_range})")
        _number(who, "rate_hz", self.rate_hz, 0.0, strict=True)
        _number(who, "phase_s", self.phase_s, 0.0, strict=False)
        p = self.detection_probability
        if not (isinstance(p, (int, float)) and 0.0 <= p <= 1.0):
            raise ValueError(f"{who}.detection_probability must be in [0, 1]; got {p!r}")
        for name in ("position_noise_std", "velocity_noise_std", "false_alarm_rate", "false_alarm_velocity_std"):
            _number(who, name, getattr(self, name), 0.0, strict=False)
        _number(who, "visibility_resolution_deg", self.visibility_resolution_deg, 0.0, strict=True)
        if self.visibility_resolution_deg > self.half_fov_deg:
            raise ValueError(f"{who}.visibility_resolution_deg must not exceed half_fov_deg")

    @property
    def boresight(self) -> float:
        """Boresight bearing in E (rad): 0 for the front unit, pi for the rear one."""
        return 0.0 if self.mount == "front" else math.pi

    def mount_position(self, ego_length: float) -> np.ndarray:
        """Mount point in E (m) for an ego of length ``ego_length`` (m): the bumper centre."""
        return np.array([0.5 * ego_length if self.mount == "front" else -0.5 * ego_length, 0.0])


FRONT_RADAR = RadarUnitConfig()
REAR_RADAR = RadarUnitConfig(name="rear", mount="rear", max_range=80.0, phase_s=0.059)


@dataclass(frozen=True)
class RadarConfig:
    """The radar units of the rig: front (+-45 deg, 150 m) and rear (+-45 deg, 80 m) by default.
    An empty tuple means no radar. Unit names must be unique."""

    units: tuple[RadarUnitConfig, ...] = (FRONT_RADAR, REAR_RADAR)

    def __post_init__(self) -> None:
        units = tuple(self.units)
        for u in units:
            if not isinstance(u, RadarUnitConfig):
                raise ValueError(f"RadarConfig.units must hold RadarUnitConfig; got {type(u).__name__}")
        names = [u.name for u in units]
        if len(set(names)) != len(names):
            raise ValueError(f"RadarConfig.units need unique names; got {names}")
        object.__setattr__(self, "units", units)


@dataclass(frozen=True, eq=False)
class RadarScan:
    """Radar detections, ``N`` rows: ``t`` (s), ``xy`` (N, 2) position (m) and ``velocity`` (N, 2)
    absolute velocity (m/s), both in E at the time ``frame_t`` (the detection time for a single unit's
    cycle, the frame time once the rig has compensated ego motion); ``target_id`` the truth id of the
    detected vehicle (-1 for a false alarm); ``unit`` the index of the unit in ``RadarConfig.units``."""

    t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    xy: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    velocity: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    target_id: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    unit: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    def __len__(self) -> int:
        return int(self.t.shape[0])

    @classmethod
    def concatenate(cls, parts: list[RadarScan]) -> RadarScan:
        """All rows of ``parts``, in order."""
        if not parts:
            return cls()
        return cls(
            np.concatenate([p.t for p in parts]),
            np.concatenate([p.xy for p in parts]).reshape(-1, 2),
            np.concatenate([p.velocity for p in parts]).reshape(-1, 2),
            np.concatenate([p.target_id for p in parts]),
            np.concatenate([p.unit for p in parts]),
        )


class RadarUnit:
    """One radar unit of ``config``; ``detect`` makes one cycle's detections. ``index`` is written
    into ``RadarScan.unit``."""

    def __init__(self, config: RadarUnitConfig | None = None, index: int = 0) -> None:
        config = FRONT_RADAR if config is None else config
        if not isinstance(config, RadarUnitConfig):
            raise ValueError(f"RadarUnit needs a RadarUnitConfig; got {type(config).__name__}")
        self.config = config
        self.index = int(index)

    @cached_property
    def grid(self) -> RayGrid:
        """Visibility rays, in the sensor frame (x along the boresight)."""
        cfg = self.config
        return RayGrid.fan(0.0, math.radians(cfg.half_fov_deg), math.radians(cfg.visibility_resolution_deg))

    def visible(self, snapshot: Snapshot, roadside: RoadsideObjects | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Visible vehicles of ``snapshot``: their rows (K,) (ascending) and their nearest visible
        points (K, 2) in E (m), by ray casting from the mount (see the module docstring)."""
        cfg = self.config
        ego = snapshot.ego
        mount_e = cfg.mount_position(ego.length)
        mount_g = to_global(mount_e, (ego.x, ego.y), ego.yaw)
        grid = self.grid
        rows, rays, ranges = visible_kernel(
            snapshot.xy, snapshot.yaw, snapshot.length, snapshot.width, *static_arrays(roadside, len(snapshot)),
            float(mount_g[0]), float(mount_g[1]), ego.yaw + cfg.boresight, float(cfg.max_range), float(cfg.min_range),
            math.remainder(grid.start, 2.0 * math.pi), float(grid.resolution), grid.cos, grid.sin)
        if rows.size == 0:
            return np.zeros(0, dtype=np.int64), np.zeros((0, 2))
        return rows, rotate(grid.directions[rays] * ranges[:, None], cfg.boresight) + mount_e

    def detect(self, snapshot: Snapshot, roadside: RoadsideObjects | None = None, *, rng: np.random.Generator) -> RadarScan:
        """One cycle at the snapshot time: detections of the visible vehicles (each kept with the
        detection probability) and the false alarms, in E at that time; randomness from ``rng``."""
        if not isinstance(snapshot, Snapshot):
            raise ValueError(f"RadarUnit.detect needs a sim.world.truth.Snapshot; got {type(snapshot).__name__}")
        if not isinstance(rng, np.random.Generator):
            raise ValueError(f"RadarUnit.detect needs rng, a numpy.random.Generator; got {type(rng).__name__}")
        cfg = self.config
        ego = snapshot.ego
        rows, nearest = self.visible(snapshot, roadside)
        kept = rng.random(rows.size) < cfg.detection_probability
        rows, nearest = rows[kept], nearest[kept]
        xy = nearest + cfg.position_noise_std * rng.standard_normal((rows.size, 2))
        vel = rotate(snapshot.velocity[rows], -ego.yaw) + cfg.velocity_noise_std * rng.standard_normal((rows.size, 2))
        # false alarms: uniform over the sector's area
        n_fa = int(rng.poisson(cfg.false_alarm_rate))
        half = math.radians(cfg.half_fov_deg)
        bearing = rng.uniform(-half, half, n_fa)
        r = np.sqrt(rng.uniform(cfg.min_range**2, cfg.max_range**2, n_fa))
        fa_local = np.stack([r * np.cos(bearing), r * np.sin(bearing)], axis=1)
        fa_xy = rotate(fa_local, cfg.boresight) + cfg.mount_position(ego.length)
        fa_vel = cfg.false_alarm_velocity_std * rng.standard_normal((n_fa, 2))
        count = rows.size + n_fa
        return RadarScan(
            t=np.full(count, float(snapshot.t)),
            xy=np.concatenate([xy, fa_xy]).reshape(-1, 2),
            velocity=np.concatenate([vel, fa_vel]).reshape(-1, 2),
            target_id=np.concatenate([snapshot.ids[rows], np.full(n_fa, -1, dtype=np.int64)]).astype(np.int64),
            unit=np.full(count, self.index, dtype=np.int64),
        )


# --------------------------------------------------------------------------------------------------
# The compiled kernels of this stage.


@njit(error_model="numpy")
def visible_kernel(xy, yaw, length, width, static_edges, static_owner, static_mid, static_half, ox, oy, sensor_yaw,
                   max_range, min_range, start, resolution, cos, sin):  # pragma: no cover - compiled
    """The radar's visibility test (``RadarUnit.visible``): the scene of ``scene_kernel`` seen from the
    mount ``(ox, oy)`` with heading ``sensor_yaw``, cast on the fan (``cast_kernel``, culled: the
    scene is closed polygons), then per vehicle the nearest ray that hits it at ``>= min_range`` (of
    equal ranges, the lowest ray). Returns the visible vehicles' rows (ascending), their rays and
    ranges (m)."""
    count = xy.shape[0]
    a, b, owner = scene_kernel(xy, yaw, length, width, static_edges, static_owner, static_mid, static_half, ox, oy,
                               sensor_yaw, max_range)
    ranges, owners = cast_kernel(a, b, owner, start, resolution, cos, sin, False, max_range, True)
    best = np.full(count, np.inf)
    best_ray = np.full(count, -1, dtype=np.int64)
    for r in range(ranges.shape[0]):  # rays ascending: the first of equal ranges wins
        o = owners[r]
        if 0 <= o < count and ranges[r] >= min_range and ranges[r] < best[o]:
            best[o] = ranges[r]
            best_ray[o] = r
    k = 0
    for v in range(count):
        if best_ray[v] >= 0:
            k += 1
    rows = np.empty(k, dtype=np.int64)
    rays = np.empty(k, dtype=np.int64)
    hit = np.empty(k)
    k = 0
    for v in range(count):
        if best_ray[v] >= 0:
            rows[k] = v
            rays[k] = best_ray[v]
            hit[k] = best[v]
            k += 1
    return rows, rays, hit


def _warm_up_visible() -> None:
    """Compile (or load) this module's kernels (registered with ``tracker.warmup`` by ``sim.sensors``)."""
    fan = RayGrid.fan(0.0, 0.5, math.radians(1.0))
    visible_kernel(np.array([[6.0, 0.0]]), np.zeros(1), np.full(1, 4.5), np.full(1, 1.9),
                   np.zeros((1, 4)) + [9.0, 1.0, 9.0, -1.0], np.ones(1, dtype=np.int64), np.array([[9.0, 0.0]]),
                   np.ones(1), 0.0, 0.0, 0.0, 50.0, 0.5, math.remainder(fan.start, 2.0 * math.pi), fan.resolution,
                   fan.cos, fan.sin)
