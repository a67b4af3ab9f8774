"""A 2-D ray-cast lidar at the origin of the vehicle frame E (a VLP-16 projected to the ground).

One scan is instantaneous at the snapshot time (no motion distortion): ``RayGrid.full_circle`` rays
(0.2 deg apart by default, bearings ``-180 + res .. 180`` deg in E) are cast against the other
vehicles' rectangles and the roadside objects; the first hit wins (occlusion). Each ray that hits
within ``max_range`` returns one point at the true range plus Gaussian noise (``range_noise_std``),
unless it drops out (probability ``dropout_probability``, independently per ray) or the true range is
below ``min_range``. Points are returned in E (m). Every scan draws the same number of random numbers
(two per ray), so the random stream does not depend on the scene.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from functools import cached_property

import numpy as np

from sim.sensors.clutter import RoadsideObjects
from sim.sensors.lidar3d import LIDAR3D_MODELS, Lidar3DConfig
from sim.sensors.raycast import CASTERS, RayGrid, ray_returns
from sim.sensors.scene import scene_segments
from sim.world.truth import Snapshot


#: Lidar models: the planar scan of this module, or a 3-D one of ``sim.sensors.lidar3d.LIDAR3D_MODELS``.
LIDAR_MODELS = ("2d",) + tuple(LIDAR3D_MODELS)
#: Azimuth step of the planar scan when ``resolution_deg`` is not set (deg).
PLANAR_RESOLUTION_DEG = 0.2
#: ``LidarConfig`` fields of the evenly spaced beam grid: only ``"vlp16"`` takes them (the others have tables).
GRID_FIELDS = ("beams", "elevation_min_deg", "elevation_max_deg")
#: ``LidarConfig`` fields that only the 3-D models use.
LIDAR3D_FIELDS = GRID_FIELDS + ("mount_x", "mount_y", "mount_z", "mount_roll_deg", "mount_pitch_deg", "mount_yaw_deg",
                                 "organized")


#: Fields of a rig's further lidar (``RigLidar``): its model, azimuth step and mount.
RIG_LIDAR_FIELDS = ("model", "resolution_deg", "mount_x", "mount_y", "mount_z", "mount_roll_deg", "mount_pitch_deg",
                    "mount_yaw_deg")


@dataclass(frozen=True)
class RigLidar:
    """A further lidar of a rig (``LidarConfig.rig``): a 3-D ``model`` of ``sim.sensors.lidar3d.LIDAR3D_MODELS``,
    its azimuth step ``resolution_deg`` (deg; None: the model's) and its mount in E (``mount_x``, ``mount_y``
    m, 0; ``mount_z`` m, 1.9; ``mount_roll_deg``, ``mount_pitch_deg``, ``mount_yaw_deg`` deg, 0), as
    ``LidarConfig``'s. It shares the rig's ranges, noise, dropout, rate and phase."""

    model: str
    resolution_deg: float | None = None
    mount_x: float = 0.0
    mount_y: float = 0.0
    mount_z: float = 1.9
    mount_roll_deg: float = 0.0
    mount_pitch_deg: float = 0.0
    mount_yaw_deg: float = 0.0

    @classmethod
    def of(cls, value: object, where: str) -> RigLidar:
        """A ``RigLidar`` from itself or a table (dict) of its fields; ``ValueError`` naming ``where`` and the key."""
        if isinstance(value, RigLidar):
            return value
        if not isinstance(value, dict):
            raise ValueError(f"{where} must be a table of {', '.join(RIG_LIDAR_FIELDS)}; got {value!r}")
        unknown = sorted(set(value) - set(RIG_LIDAR_FIELDS))
        if unknown:
            raise ValueError(f"{where}.{unknown[0]}: unknown key; allowed keys: {', '.join(RIG_LIDAR_FIELDS)}")
        if "model" not in value:
            raise ValueError(f"{where}.model: missing; a rig's lidar names its 3-D model ({', '.join(LIDAR3D_MODELS)})")
        return cls(**value)


def _positive(owner: str, name: str, value: float, *, allow_zero: bool = False) -> None:
    ok = isinstance(value, (int, float)) and math.isfinite(value) and (value >= 0.0 if allow_zero else value > 0.0)
    if not ok:
        bound = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"{owner}.{name} must be a finite number {bound}; got {value!r}")


@dataclass(frozen=True)
class LidarConfig:
    """Lidar settings (SI units; angles in degrees where the name says so).

    - ``resolution_deg`` (None: the model's, 0.2 for ``"2d"``): azimuth step; must divide 360 into whole
      rays (0.2 -> 1800 rays);
    - ``max_range`` (100 m) and ``min_range`` (0.5 m): returns beyond / nearer are not reported;
    - ``range_noise_std`` (0.03 m): Gaussian noise on each range, along the ray;
    - ``dropout_probability`` (0.01): chance that a ray which hits returns nothing;
    - ``rate_hz`` (10 Hz) and ``phase_s`` (0 s): scans at ``t0 + phase_s + k / rate_hz``;
    - ``caster`` ("numpy"): ``"numpy"`` (``sim.sensors.raycast.cast``, the compiled caster) or
      ``"pymunk"`` (pymunk's segment queries, the oracle);
    - ``model`` ("2d"): ``"2d"``, this planar scan at the E origin, or a 3-D spinning lidar of
      ``sim.sensors.lidar3d.LIDAR3D_MODELS``: ``"vlp16"``, ``"vlp32c"``, ``"hdl64e"`` or ``"os1-128"``
      (its beam table and azimuth step from the data sheet), which shares the fields above (resolution,
      ranges, noise, dropout, rate, phase) and adds the fields below, which only the 3-D models use
      (setting them with ``"2d"`` is an error):
    - ``beams`` (16), ``elevation_min_deg`` (-15) and ``elevation_max_deg`` (15): an evenly spaced beam
      grid (every 2 deg), ``"vlp16"`` only (the other models' tables are fixed);
    - ``mount_x``, ``mount_y`` (0 m), ``mount_z`` (1.9 m, the roof) and ``mount_roll_deg``,
      ``mount_pitch_deg``, ``mount_yaw_deg`` (0): the sensor's pose in E (origin on the ground under the
      ego's centre, z up), ``p_E = Rz(yaw) Ry(pitch) Rx(roll) p_sensor + t``;
    - ``organized`` (False): every ray in the cloud, a NaN point where nothing returned (the organized
      clouds of real drivers: the tracker drops the non-finite rows and counts them);
    - ``rig`` (empty): further lidars of a rig (``RigLidar``: a 3-D model and its mount; in a scenario file
      ``[[sensors.lidar.rig]]`` tables), each sharing the ranges, noise, dropout, rate and phase above;
      their scans and this one's are merged into one cloud in E (``sim.sensors.lidar3d.merge_scans``), as
      a real rig's driver delivers it, each point's lidar known; 3-D models only.
    """

    resolution_deg: float | None = None
    max_range: float = 100.0
    min_range: float = 0.5
    range_noise_std: float = 0.03
    dropout_probability: float = 0.01
    rate_hz: float = 10.0
    phase_s: float = 0.0
    caster: str = "numpy"
    model: str = "2d"
    beams: int = 16
    elevation_min_deg: float = -15.0
    elevation_max_deg: float = 15.0
    mount_x: float = 0.0
    mount_y: float = 0.0
    mount_z: float = 1.9
    mount_roll_deg: float = 0.0
    mount_pitch_deg: float = 0.0
    mount_yaw_deg: float = 0.0
    organized: bool = False
    rig: tuple[RigLidar, ...] = ()

    def __post_init__(self) -> None:
        if not isinstance(self.rig, (tuple, list)):
            raise ValueError(f"LidarConfig.rig must be a list of lidars (tables of {', '.join(RIG_LIDAR_FIELDS)}); "
                             f"got {self.rig!r}")
        object.__setattr__(self, "rig", tuple(RigLidar.of(r, f"LidarConfig.rig[{i}]") for i, r in enumerate(self.rig)))
        if self.model not in LIDAR_MODELS:
            raise ValueError(f"LidarConfig.model must be one of {list(LIDAR_MODELS)}; got {self.model!r}")
        if self.resolution_deg is not None:
            _positive("LidarConfig", "resolution_deg", self.resolution_deg)
        _positive("LidarConfig", "max_range", self.max_range)
        _positive("LidarConfig", "min_range", self.min_range, allow_zero=True)
        _positive("LidarConfig", "range_noise_std", self.range_noise_std, allow_zero=True)
        _positive("LidarConfig", "rate_hz", self.rate_hz)
        _positive("LidarConfig", "phase_s", self.phase_s, allow_zero=True)
        if self.min_range >= self.max_range:
            raise ValueError(f"LidarConfig.min_range ({self.min_range}) must be below max_range ({self.max_range})")
        p = self.dropout_probability
        if not (isinstance(p, (int, float)) and 0.0 <= p <= 1.0):
            raise ValueError(f"LidarConfig.dropout_probability must be in [0, 1]; got {p!r}")
        if self.caster not in CASTERS:
            raise ValueError(f"LidarConfig.caster must be one of {sorted(CASTERS)}; got {self.caster!r}")
        RayGrid.full_circle(math.radians(self.azimuth_step_deg))  # raises if 360 is not a whole number of rays
        if self.model == "2d":
            changed = [f.name for f in fields(self) if f.name in LIDAR3D_FIELDS and getattr(self, f.name) != f.default]
            if changed:
                raise ValueError(
                    f"LidarConfig.{changed[0]} applies to the 3-D lidar only; set model = \"vlp16\" or drop {changed[0]}"
                )
            if self.rig:
                raise ValueError("LidarConfig.rig: a rig of several lidars is of 3-D lidars; set model to one "
                                 f"({', '.join(LIDAR3D_MODELS)}) or drop rig")
        else:
            if self.model != "vlp16":
                changed = [f.name for f in fields(self) if f.name in GRID_FIELDS and getattr(self, f.name) != f.default]
                if changed:
                    raise ValueError(f"LidarConfig.{changed[0]} sets the VLP-16's evenly spaced beams; model "
                                     f"{self.model!r} has its own beam table: drop {changed[0]}")
            for i, extra in enumerate(self.rig):
                if extra.model not in LIDAR3D_MODELS:
                    raise ValueError(f"LidarConfig.rig[{i}].model must be a 3-D model, one of {list(LIDAR3D_MODELS)}; "
                                     f"got {extra.model!r}")
                try:
                    self.rig_config(i).lidar3d_config()
                except ValueError as exc:
                    raise ValueError(f"LidarConfig.rig[{i}]: {exc}") from None
            self.lidar3d_config()  # the 3-D fields' own checks

    def rig_config(self, k: int) -> LidarConfig:
        """The ``LidarConfig`` of the rig's further lidar ``k`` alone: this one's shared settings (ranges,
        noise, dropout, rate, phase, caster) with its model, azimuth step and mount."""
        extra = self.rig[k]
        grid = {f.name: f.default for f in fields(self) if f.name in GRID_FIELDS}
        return replace(self, rig=(), **grid, **{name: getattr(extra, name) for name in RIG_LIDAR_FIELDS})

    def lidar3d_configs(self) -> list[Lidar3DConfig]:
        """Every lidar of the rig as a ``Lidar3DConfig``: this one first, then ``rig`` in order (a 3-D ``model``)."""
        return [self.lidar3d_config()] + [self.rig_config(k).lidar3d_config() for k in range(len(self.rig))]

    def lidar3d_config(self) -> Lidar3DConfig:
        """The ``sim.sensors.lidar3d.Lidar3DConfig`` of these settings (a 3-D ``model``)."""
        shared = ("max_range", "min_range", "range_noise_std", "dropout_probability", "rate_hz", "phase_s")
        step = {"resolution_deg": self.azimuth_step_deg}
        if self.model == "vlp16":  # the evenly spaced grid, which a scenario may change
            return Lidar3DConfig(**step, **{name: getattr(self, name) for name in shared + LIDAR3D_FIELDS})
        mount = tuple(name for name in LIDAR3D_FIELDS if name not in GRID_FIELDS)  # and organized
        return Lidar3DConfig.of_model(self.model, **step, **{name: getattr(self, name) for name in shared + mount})

    @property
    def azimuth_step_deg(self) -> float:
        """The azimuth step (deg): ``resolution_deg``, or the model's own (0.2 for ``"2d"``)."""
        if self.resolution_deg is not None:
            return float(self.resolution_deg)
        return PLANAR_RESOLUTION_DEG if self.model == "2d" else LIDAR3D_MODELS[self.model].resolution_deg

    @property
    def rays(self) -> int:
        """Rays per scan (azimuths; a 3-D model fires ``beams`` at each)."""
        return round(360.0 / self.azimuth_step_deg)


@dataclass(frozen=True, eq=False)
class LidarScan:
    """One scan at time ``t`` (s): ``M`` points, with per point the ray ``azimuth`` (rad, in E), the
    measured ``range`` (m), the point ``points`` (M, 2) in E (m), and what it hit: ``vehicle_id``
    (the snapshot's id, -1 for roadside objects) and ``roadside_index`` (-1 for vehicles).
    ``rays`` is the number of rays cast."""

    t: float
    azimuth: np.ndarray
    range: np.ndarray
    points: np.ndarray
    vehicle_id: np.ndarray
    roadside_index: np.ndarray
    rays: int

    def __len__(self) -> int:
        return int(self.range.shape[0])

    def points_on(self, vehicle_id: int) -> np.ndarray:
        """The points (K, 2) in E that hit the vehicle with this id."""
        return self.points[self.vehicle_id == vehicle_id]


class Lidar:
    """The lidar of ``config`` (``LidarConfig()`` by default); ``scan`` makes one scan."""

    def __init__(self, config: LidarConfig | None = None) -> None:
        config = LidarConfig() if config is None else config
        if not isinstance(config, LidarConfig):
            raise ValueError(f"Lidar needs a LidarConfig; got {type(config).__name__}")
        self.config = config

    @cached_property
    def grid(self) -> RayGrid:
        """The scan's rays (E frame)."""
        return RayGrid.full_circle(math.radians(self.config.azimuth_step_deg))

    def scan(self, snapshot: Snapshot, roadside: RoadsideObjects | None = None, *, rng: np.random.Generator) -> LidarScan:
        """One scan of ``snapshot`` (the other vehicles) and ``roadside`` from the ego pose, at the
        snapshot time; noise and dropout from ``rng``."""
        if not isinstance(snapshot, Snapshot):
            raise ValueError(f"Lidar.scan needs a sim.world.truth.Snapshot; got {type(snapshot).__name__}")
        if not isinstance(rng, np.random.Generator):
            raise ValueError(f"Lidar.scan needs rng, a numpy.random.Generator; got {type(rng).__name__}")
        cfg = self.config
        ego = snapshot.ego
        segments = scene_segments(snapshot, roadside, (ego.x, ego.y), ego.yaw, cfg.max_range)
        cast = CASTERS[cfg.caster](segments, self.grid, cfg.max_range)
        count = self.grid.count
        idx, measured, vehicle_id, roadside_index = ray_returns(cast.hit, cast.range, cast.owner, snapshot.ids, cfg, rng)
        return LidarScan(
            t=float(snapshot.t),
            azimuth=self.grid.angles[idx],
            range=measured,
            points=self.grid.directions[idx] * measured[:, None],
            vehicle_id=vehicle_id,
            roadside_index=roadside_index,
            rays=count,
        )
