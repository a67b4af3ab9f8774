"""A 3-D ray-cast spinning lidar over upright prisms and a ground surface: the Velodyne VLP-16, VLP-32C
and HDL-64E and the Ouster OS1-128 (``LIDAR3D_MODELS``), or any evenly spaced beam grid.

Frames: G is the global frame (x, y in m, z up, m; angles counter-clockwise). The ego frame E has its
origin at the ego's centre on the ground, x forward, y left, z up; the ego stands upright (yaw only,
no pitch or roll with the road), at the ground height under its centre. The sensor frame S is the
lidar's own (x forward, y left, z up), mounted at ``(mount_x, mount_y, mount_z)`` (m) in E with
``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``: ``p_E = R @ p_S + t``. So ``p_G = Rz(ego_yaw) @ p_E + origin``.

The scan (``Lidar3D.scan``) is instantaneous (no motion distortion): ``beams`` lasers at elevations
evenly spaced from ``elevation_min_deg`` to ``elevation_max_deg`` (16 from -15 to 15 deg, 2 deg
apart), or at the model's table ``elevations_deg``, fire at every azimuth ``-180 + res .. 180`` deg (``res = resolution_deg``, 0.2 -> 1800
azimuths, 28,800 rays). Ray ``i = a * beams + b`` is azimuth ``a`` and beam ``b`` (beam 0 the lowest),
with direction ``(cos el cos az, cos el sin az, sin el)`` in S. Each ray's first hit within
``max_range`` (slant) returns a point at the true range plus Gaussian noise along the ray
(``range_noise_std``), unless it drops out (``dropout_probability``) or the true range is below
``min_range``. Every scan draws two random numbers per ray (a normal, then a uniform), whatever the
scene, so the random stream does not depend on it (as ``sim.sensors.lidar.Lidar.scan``).

The scene (``Prisms``): upright convex prisms in G, each a counter-clockwise polygon footprint
extruded from ``base`` to ``top`` (m), with an integer ``owner``. Owner convention of ``Lidar3D.scan``
(as ``sim.sensors.scene``): owners ``0 .. V-1`` are the vehicles ``vehicle_ids[0 .. V-1]``, owners
``V + j`` the roadside object ``j``; the ego is not in the scene. The ground (``sim.world.ground``) is the
other thing a ray can hit (owner -1, ``ground`` True).

``cast_3d`` (vectorised, no per-ray Python loop): with ``d`` a unit ray direction, ``rho = |d_xy|``,
``u = d_xy / rho`` its horizontal direction and ``k = d_z / rho`` its slope, the ray is
``(o_xy + u t, o_z + k t)`` in the horizontal distance ``t``; slant range ``= t sqrt(1 + k^2) = t /
rho``; ``max_range`` is ``t_max = max_range * rho``.

1. cull prisms: bounding circle (centre, radius) wholly beyond ``max_range``, or the slab
   ``[base, top]`` out of vertical reach;
2. angular broad phase (as ``sim.sensors.raycast``): the rays are sorted by azimuth once (a stable
   sort: a yaw-rotated VLP-16 grid is two sorted runs, linear time); each prism's footprint subtends
   a bearing interval (< pi: the vertex bearings relative to the centre's), wrapped to ``[-pi, pi)``;
   ``searchsorted`` gives the rays inside as one index range, plus a second one where it wraps past
   +-pi (the full circle when ``o_xy`` is inside the footprint). 1e-9 rad of slack each side;
3. slope cull per (ray, prism) pair: over ``t`` in ``[d_min, d_max]`` (footprint distance bounds)
   the ray must pass ``[base, top]``: ``k`` in ``[min((base - o_z) / d), max((top - o_z) / d)]``;
4. narrow phase per pair (batched per footprint vertex count), Cyrus-Beck clipping of the ray's
   horizontal line by the footprint's edges: edge ``e`` with outward normal ``nu_e`` through ``a_e``
   keeps ``t den_e <= num_e`` with ``num_e = nu_e . (a_e - o_xy)``, ``den_e = nu_e . u``. Per scan
   and prism, the *front* edges (``num_e < 0``: ``o_xy`` outside their half-plane) are the ones the
   ray must enter through, the others are *back* edges; with ``p_e = nu_e / num_e`` per edge and
   ``w_e = p_e . u = den_e / num_e`` per pair (two products and a sum, no branches):
   ``t_in = 1 / min_front w`` if every front ``w > 0`` (else the ray misses the footprint), and
   ``t_out = 1 / max_back w`` (``inf`` when that max is <= 0). (``num_e = 0``, ``o_xy`` on an edge's
   line, counts as a tiny positive ``num``; ``o_xy`` inside the footprint has no front edge:
   ``t_in = 0``.) The vertical slab ``[base, top]`` gives ``[tz_lo, tz_hi]`` from
   ``(base - o_z) / k`` and ``(top - o_z) / k``; the hit is ``t = max(t_in, tz_lo)`` when
   ``t <= t_out`` (as ``t max_back w <= 1``), ``t <= tz_hi`` and ``t <= t_max``: a side hit at
   ``t_in``, a roof hit when the ray comes down through the top, a bottom hit going up under a
   raised base;
5. the nearest pair per ray wins (``np.minimum.at``);
6. the ground (``GroundSurface`` from ``ground.surface(o_xy, max_range)``), searched only up to the
   object hit: ``f(t) = o_z + k t - h(o_xy + u t)``, ``f(0) = c > 0`` (the sensor's clearance; a
   sensor on or under the ground raises). Flat ground: ``t = c / -k`` for ``k < 0`` (exact). Else
   the surface bounds how fast the ground can rise along each ray (``rise``, per azimuth sector),
   so ``f' >= k - rise = -closing``: rays with ``closing <= 0`` never meet the ground, and past a
   point with ``f > 0`` the next ``safe = f / closing`` m are certified free of it. The march starts
   with ``[0, c / closing]`` certified and steps to the predicted crossing (first where the ground's
   tangent plane at the sensor's foot puts it, then the secant through the last two points), kept
   within ``[safe, safe + GROUND_MIN_STEP]``: no stretch longer than ``GROUND_MIN_STEP`` (1 m) is
   left unchecked. A crossing is missed only if the ray dips under the ground and comes out again
   within such a stretch; the dip is then at most ``GROUND_MIN_STEP * dg / 4`` deep, ``dg`` the
   change of the ground's slope along the ray there (on ``RoadGround`` a road-edge kink,
   ``dg <= |bank|``: <= 7.5 mm at bank 0.03, a quarter of the range noise). A point with
   ``|f| <= GROUND_TOLERANCE`` is the crossing; a point below brackets it, and a safeguarded secant
   (regula falsi when the secant leaves the bracket; exact in one step on a plane) narrows the
   bracket to that tolerance. The last few marching rays (``GROUND_TAIL_RAYS``, mostly grazing
   ones) are probed ``GROUND_TAIL_PROBES`` points at a time, ``GROUND_MIN_STEP`` apart, to save
   iterations. (``tests/test_lidar3d.py`` checks the march against 2 cm sampling on a curved road.)
7. the nearer of object and ground wins (ties to the object).

The sensor must be outside every prism (it may stand under a raised one).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from sim.sensors.raycast import RayGrid, ray_returns
from sim.world.ground import Ground
from tracker.cloud import mount_rotation

TWO_PI = 2.0 * math.pi
#: Smallest step (m, horizontal) of the ground march; see the module docstring (step 6).
GROUND_MIN_STEP = 1.0
#: Below this many marching rays, the march evaluates GROUND_TAIL_PROBES points per ray at a time.
GROUND_TAIL_RAYS = 256
#: Points per ray and iteration in the march's tail (GROUND_MIN_STEP apart).
GROUND_TAIL_PROBES = 8
#: The ground crossing is accepted when ``|f| <=`` this (m, vertical): a range error below
#: ``GROUND_TOLERANCE / |f'|``, e.g. 1e-8 m for a ray closing on the ground at 1 cm per m.
GROUND_TOLERANCE = 1e-10
#: Most refinement iterations of a ground crossing (the secant converges superlinearly: a handful).
GROUND_MAX_REFINE = 60
#: Most march iterations (a safety net: every step is at least GROUND_MIN_STEP unless the crossing
#: is predicted nearer, so marches end within about max_range / GROUND_MIN_STEP iterations).
GROUND_MAX_MARCH = 1000
#: Slack (rad) added to each side of a prism's bearing interval in the broad phase.
BEARING_SLACK = 1e-9


@dataclass(frozen=True)
class Lidar3DModel:
    """A spinning lidar's beam layout: its ``elevations_deg`` (deg in its own frame, ascending), its
    azimuth step ``resolution_deg`` (deg) between firings at 10 Hz, and the ``source`` of both."""

    #: Model name, as ``LidarConfig.model`` and ``--lidar-model`` take it (no default).
    name: str
    #: The beams' elevations, lowest first (deg; no default).
    elevations_deg: tuple[float, ...]
    #: Azimuth step at 10 Hz; divides 360 (deg; no default).
    resolution_deg: float
    #: Where the layout comes from (no default).
    source: str

    @property
    def rays(self) -> int:
        """Rays per revolution."""
        return len(self.elevations_deg) * round(360.0 / self.resolution_deg)


def _even(low: float, high: float, count: int) -> tuple[float, ...]:
    return tuple(float(x) for x in np.round(np.linspace(low, high, count), 4))


#: The 3-D lidar models (``LidarConfig.model``): beam tables of the data sheets and manuals.
LIDAR3D_MODELS: dict[str, Lidar3DModel] = {m.name: m for m in (
    Lidar3DModel("vlp16", _even(-15.0, 15.0, 16), 0.2,
                 "Velodyne VLP-16 data sheet: 16 beams, -15 to +15 deg every 2 deg; 0.2 deg at 600 rpm (10 Hz)"),
    Lidar3DModel("vlp32c", (-25.0, -15.639, -11.31, -8.843, -7.254, -6.148, -5.333, -4.667, -4.0, -3.667, -3.333,
                            -3.0, -2.667, -2.333, -2.0, -1.667, -1.333, -1.0, -0.667, -0.333, 0.0, 0.333, 0.667, 1.0,
                            1.333, 1.667, 2.333, 3.333, 4.667, 7.0, 10.333, 15.0), 0.2,
                 "Velodyne VLP-32C user manual, laser elevation table: 32 beams, -25 to +15 deg, densest (1/3 deg) "
                 "around the horizon; 0.2 deg at 600 rpm (10 Hz)"),
    Lidar3DModel("hdl64e", _even(-24.9, -8.87, 32) + _even(-8.33, 2.0, 32), 0.18,
                 "Velodyne HDL-64E S2 data sheet: 64 beams over +2 to -24.9 deg, an upper block of 32 about 1/3 deg "
                 "apart above -8.33 deg and a lower block of 32 about 1/2 deg apart (evenly spaced here; a unit's "
                 "calibration differs by about 0.1 deg); 0.18 deg (the sheet's 0.17, rounded to divide 360) at 10 Hz"),
    Lidar3DModel("os1-128", _even(-22.5, 22.5, 128), 360.0 / 1024,
                 "Ouster OS1-128 data sheet: 128 beams evenly over a 45 deg vertical field of view; 1024 columns "
                 "per revolution at 10 Hz (0.35 deg)"),
)}


def _number(owner: str, name: str, value: float, *, low: float | None = None, allow_equal: bool = True) -> None:
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    if ok and low is not None:
        ok = value >= low if allow_equal else value > low
    if not ok:
        bound = "" if low is None else (f" >= {low}" if allow_equal else f" > {low}")
        raise ValueError(f"{owner}.{name} must be a finite number{bound}; got {value!r}")


@dataclass(frozen=True)
class Lidar3DConfig:
    """3-D lidar settings (SI units; angles in degrees where the name says so); the defaults are a
    VLP-16, ``Lidar3DConfig.of_model`` gives another model of ``LIDAR3D_MODELS``.

    - ``beams`` (16): lasers, at elevations evenly spaced from ``elevation_min_deg`` (-15) to
      ``elevation_max_deg`` (15) (2 deg apart); one beam needs the two equal;
    - ``elevations_deg`` (None): the beams' elevations as a table instead (ascending, ``beams`` of them,
      from ``elevation_min_deg`` to ``elevation_max_deg``: ``of_model`` fills all four);
    - ``resolution_deg`` (0.2): azimuth step; must divide 360 (0.2 -> 1800 azimuths, 28,800 rays);
    - ``rate_hz`` (10 Hz) and ``phase_s`` (0 s): scans at ``t0 + phase_s + k / rate_hz``;
    - ``max_range`` (100 m, slant) and ``min_range`` (0.5 m): returns beyond / nearer are not reported;
    - ``range_noise_std`` (0.03 m): Gaussian noise on each range, along the ray;
    - ``dropout_probability`` (0.01): chance that a ray which hits returns nothing;
    - ``mount_x``, ``mount_y``, ``mount_z`` (0, 0, 1.9 m: on the roof) and ``mount_roll_deg``,
      ``mount_pitch_deg``, ``mount_yaw_deg`` (0): the sensor's pose in E (module docstring);
    - ``organized`` (False): deliver every ray in firing order (azimuth-major), a NaN point and range
      where the ray returned nothing (the sky, a dropout, beyond range), as the organized clouds of
      Ouster's and Velodyne's drivers do; False: the returns only.
    """

    beams: int = 16
    elevation_min_deg: float = -15.0
    elevation_max_deg: float = 15.0
    elevations_deg: tuple[float, ...] | None = None
    resolution_deg: float = 0.2
    rate_hz: float = 10.0
    phase_s: float = 0.0
    max_range: float = 100.0
    min_range: float = 0.5
    range_noise_std: float = 0.03
    dropout_probability: float = 0.01
    mount_x: float = 0.0
    mount_y: float = 0.0
    mount_z: float = 1.9
    mount_roll_deg: float = 0.0
    mount_pitch_deg: float = 0.0
    mount_yaw_deg: float = 0.0
    organized: bool = False

    def __post_init__(self) -> None:
        name = "Lidar3DConfig"
        if not isinstance(self.organized, (bool, np.bool_)):
            raise ValueError(f"{name}.organized must be true or false; got {self.organized!r}")
        if isinstance(self.beams, bool) or not isinstance(self.beams, (int, np.integer)) or self.beams < 1:
            raise ValueError(f"{name}.beams must be a positive integer; got {self.beams!r}")
        for field_name in ("elevation_min_deg", "elevation_max_deg"):
            value = getattr(self, field_name)
            _number(name, field_name, value)
            if not -90.0 < value < 90.0:
                raise ValueError(f"{name}.{field_name} must be strictly between -90 and 90 deg; got {value!r}")
        if self.beams == 1 and self.elevation_min_deg != self.elevation_max_deg:
            raise ValueError(
                f"{name}.elevation_min_deg ({self.elevation_min_deg}) must equal elevation_max_deg "
                f"({self.elevation_max_deg}) with one beam"
            )
        if self.beams > 1 and not self.elevation_min_deg < self.elevation_max_deg:
            raise ValueError(
                f"{name}.elevation_min_deg ({self.elevation_min_deg}) must be below elevation_max_deg "
                f"({self.elevation_max_deg})"
            )
        if self.elevations_deg is not None:
            table = np.asarray(self.elevations_deg, dtype=float).reshape(-1)
            if (len(table) != self.beams or not np.all(np.isfinite(table)) or np.any(np.diff(table) <= 0.0)
                    or table[0] != self.elevation_min_deg or table[-1] != self.elevation_max_deg):
                raise ValueError(
                    f"{name}.elevations_deg must hold beams ({self.beams}) ascending elevations from elevation_min_deg "
                    f"({self.elevation_min_deg}) to elevation_max_deg ({self.elevation_max_deg}); got {self.elevations_deg!r}"
                )
            object.__setattr__(self, "elevations_deg", tuple(float(x) for x in table))
        _number(name, "resolution_deg", self.resolution_deg, low=0.0, allow_equal=False)
        _number(name, "rate_hz", self.rate_hz, low=0.0, allow_equal=False)
        _number(name, "phase_s", self.phase_s, low=0.0)
        _number(name, "max_range", self.max_range, low=0.0, allow_equal=False)
        _number(name, "min_range", self.min_range, low=0.0)
        _number(name, "range_noise_std", self.range_noise_std, low=0.0)
        if self.min_range >= self.max_range:
            raise ValueError(f"{name}.min_range ({self.min_range}) must be below max_range ({self.max_range})")
        p = self.dropout_probability
        if not (isinstance(p, (int, float)) and not isinstance(p, bool) and 0.0 <= p <= 1.0):
            raise ValueError(f"{name}.dropout_probability must be in [0, 1]; got {p!r}")
        for field_name in ("mount_x", "mount_y", "mount_z", "mount_roll_deg", "mount_pitch_deg", "mount_yaw_deg"):
            _number(name, field_name, getattr(self, field_name))
        try:
            RayGrid.full_circle(math.radians(self.resolution_deg))
        except ValueError as err:
            raise ValueError(f"{name}.resolution_deg: {err}") from None

    @classmethod
    def of_model(cls, model: str, **settings: object) -> Lidar3DConfig:
        """The settings of ``LIDAR3D_MODELS[model]`` (its beams and azimuth step) with ``settings`` (the
        other fields, e.g. ``max_range``, ``mount_z``; ``resolution_deg`` replaces the model's)."""
        if model not in LIDAR3D_MODELS:
            raise ValueError(f"3-D lidar model must be one of {sorted(LIDAR3D_MODELS)}; got {model!r}")
        m = LIDAR3D_MODELS[model]
        layout = {"beams": len(m.elevations_deg), "elevation_min_deg": m.elevations_deg[0],
                  "elevation_max_deg": m.elevations_deg[-1], "elevations_deg": m.elevations_deg,
                  "resolution_deg": m.resolution_deg}
        clash = sorted(set(settings) & {"beams", "elevation_min_deg", "elevation_max_deg", "elevations_deg"})
        if clash:
            raise ValueError(f"Lidar3DConfig.of_model({model!r}): {clash[0]} is the model's; got {settings[clash[0]]!r}")
        return cls(**{**layout, **settings})

    @property
    def azimuth_count(self) -> int:
        """Azimuths per scan (1800 at 0.2 deg)."""
        return round(360.0 / self.resolution_deg)

    @property
    def rays(self) -> int:
        """Rays per scan (``beams * azimuth_count``: 28,800 by default)."""
        return int(self.beams) * self.azimuth_count

    @cached_property
    def azimuths(self) -> np.ndarray:
        """The azimuths (A,) in rad in the sensor frame, ``-pi + res .. pi`` ascending."""
        return RayGrid.full_circle(math.radians(self.resolution_deg)).angles

    @cached_property
    def elevations(self) -> np.ndarray:
        """The beams' elevations (B,) in rad, lowest first."""
        if self.elevations_deg is not None:
            return np.radians(np.asarray(self.elevations_deg, dtype=float))
        return np.radians(np.linspace(self.elevation_min_deg, self.elevation_max_deg, int(self.beams)))

    @cached_property
    def directions(self) -> np.ndarray:
        """Unit ray directions (rays, 3) in the sensor frame; ray ``a * beams + b`` is azimuth ``a``,
        beam ``b``."""
        az = np.repeat(self.azimuths, int(self.beams))
        el = np.tile(self.elevations, self.azimuth_count)
        ce = np.cos(el)
        return np.column_stack([ce * np.cos(az), ce * np.sin(az), np.sin(el)])

    @cached_property
    def mount_rotation(self) -> np.ndarray:
        """``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)`` (3, 3): sensor frame to E."""
        return mount_rotation(
            math.radians(self.mount_roll_deg), math.radians(self.mount_pitch_deg), math.radians(self.mount_yaw_deg)
        )

    @property
    def mount_translation(self) -> np.ndarray:
        """The sensor's origin (3,) in E (m)."""
        return np.array([self.mount_x, self.mount_y, self.mount_z], dtype=float)


def _column(value: object, count: int, name: str, dtype: type = float) -> np.ndarray:
    arr = np.asarray(value, dtype=dtype)
    if arr.ndim == 0:
        arr = np.full(count, arr.item(), dtype=dtype)
    arr = arr.reshape(-1)
    if arr.shape[0] != count:
        raise ValueError(f"Prisms: {name} must be a scalar or have {count} entries; got {arr.shape[0]}")
    return arr


@dataclass(frozen=True, eq=False)
class Prisms:
    """``N`` upright convex prisms in G: prism ``i`` has the footprint ``vertices[i, :sizes[i]]``
    (m, counter-clockwise, convex; padded to a common ``V`` by repeating the last vertex), spans
    ``base[i] <= z <= top[i]`` (m) and belongs to ``owner[i]`` (int). Derived: the footprint's
    ``centre`` (vertex mean) and ``radius`` (largest centre-to-vertex distance), and per edge the
    outward normal ``normals`` (N, V, 2) (not unit) and ``offsets`` ``normal . a`` (N, V) (padding
    edges: normal 0, offset 1, a constraint every point meets). Build with ``from_rectangles``,
    ``from_polygons`` or ``concatenate``."""

    vertices: np.ndarray
    sizes: np.ndarray
    base: np.ndarray
    top: np.ndarray
    owner: np.ndarray
    centre: np.ndarray = field(init=False)
    radius: np.ndarray = field(init=False)
    normals: np.ndarray = field(init=False, repr=False)
    offsets: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        vertices = np.asarray(self.vertices, dtype=float)
        if vertices.ndim != 3 or vertices.shape[2] != 2 or (vertices.shape[0] and vertices.shape[1] < 3):
            raise ValueError(f"Prisms: vertices must have shape (N, V >= 3, 2); got {vertices.shape}")
        count, width = vertices.shape[0], vertices.shape[1]
        sizes = _column(self.sizes, count, "sizes", np.int64)
        base = _column(self.base, count, "base")
        top = _column(self.top, count, "top")
        owner = _column(self.owner, count, "owner", np.int64)
        if np.any(sizes < 3) or np.any(sizes > width):
            raise ValueError(f"Prisms: sizes must be in [3, {width}]")
        if not (np.all(np.isfinite(vertices)) and np.all(np.isfinite(base)) and np.all(np.isfinite(top))):
            raise ValueError("Prisms: vertices, base and top must be finite")
        if np.any(top <= base):
            i = int(np.argmax(top <= base))
            raise ValueError(f"Prisms: top must be above base; prism {i} has base {base[i]!r} and top {top[i]!r}")
        slot = np.arange(width)
        real = slot[None, :] < sizes[:, None]  # (N, V)
        # pad: repeat the last real vertex
        last = vertices[np.arange(count), sizes - 1]
        vertices = np.where(real[..., None], vertices, last[:, None, :])
        nxt = np.where(slot[None, :] + 1 < sizes[:, None], slot[None, :] + 1, 0)  # successor of each real vertex
        b = np.take_along_axis(vertices, nxt[..., None], axis=1)
        edge = b - vertices
        centre = (vertices * real[..., None]).sum(axis=1) / np.maximum(sizes, 1)[:, None]
        rel = vertices - centre[:, None, :]
        # convex and counter-clockwise: every edge turns left around the centre, and so does every
        # pair of consecutive edges
        around = rel[..., 0] * edge[..., 1] - rel[..., 1] * edge[..., 0]
        edge_next = np.take_along_axis(edge, nxt[..., None], axis=1)
        turn = edge[..., 0] * edge_next[..., 1] - edge[..., 1] * edge_next[..., 0]
        bad = real & ((around <= 0.0) | (turn <= 0.0))
        if np.any(bad):
            i = int(np.argmax(bad.any(axis=1)))
            raise ValueError(f"Prisms: footprints must be convex and counter-clockwise; prism {i} is not")
        normals = np.stack([edge[..., 1], -edge[..., 0]], axis=-1) * real[..., None]
        offsets = np.where(real, (normals * vertices).sum(axis=-1), 1.0)
        radius = np.where(real, np.hypot(rel[..., 0], rel[..., 1]), 0.0).max(axis=1) if count else np.zeros(0)
        for name, value in (("vertices", vertices), ("sizes", sizes), ("base", base), ("top", top), ("owner", owner)):
            object.__setattr__(self, name, value)
        object.__setattr__(self, "centre", centre)
        object.__setattr__(self, "radius", radius)
        object.__setattr__(self, "normals", normals)
        object.__setattr__(self, "offsets", offsets)

    def __len__(self) -> int:
        return int(self.vertices.shape[0])

    @classmethod
    def empty(cls) -> Prisms:
        """No prisms."""
        none = np.zeros(0, dtype=np.int64)
        return cls(np.zeros((0, 3, 2)), none, np.zeros(0), np.zeros(0), none)

    @classmethod
    def from_rectangles(
        cls,
        center: np.ndarray,
        yaw: np.ndarray | float,
        length: np.ndarray | float,
        width: np.ndarray | float,
        base: np.ndarray | float,
        top: np.ndarray | float,
        owner: np.ndarray | int | None = None,
    ) -> Prisms:
        """Upright boxes (vehicles): footprint centre ``center`` (N, 2) m in G, heading ``yaw`` (rad),
        ``length`` x ``width`` (m), from ``base`` to ``top`` (m); ``owner`` defaults to ``0 .. N-1``.
        Scalars broadcast."""
        center = np.asarray(center, dtype=float).reshape(-1, 2)
        count = center.shape[0]
        yaw = _column(yaw, count, "yaw")
        half_l = 0.5 * _column(length, count, "length")
        half_w = 0.5 * _column(width, count, "width")
        if np.any(~(half_l > 0.0)) or np.any(~(half_w > 0.0)):
            raise ValueError("Prisms.from_rectangles: length and width must be > 0")
        c, s = np.cos(yaw), np.sin(yaw)
        sx = np.array([1.0, 1.0, -1.0, -1.0])  # front-right, front-left, rear-left, rear-right: CCW
        sy = np.array([-1.0, 1.0, 1.0, -1.0])
        lx, ly = sx[None, :] * half_l[:, None], sy[None, :] * half_w[:, None]
        x = center[:, 0, None] + c[:, None] * lx - s[:, None] * ly
        y = center[:, 1, None] + s[:, None] * lx + c[:, None] * ly
        owner = np.arange(count) if owner is None else owner
        return cls(np.stack([x, y], axis=-1), np.full(count, 4), base, top, owner)

    @classmethod
    def from_polygons(
        cls,
        vertices: np.ndarray,
        offsets: np.ndarray,
        base: np.ndarray | float,
        top: np.ndarray | float,
        owner: np.ndarray | int | None = None,
    ) -> Prisms:
        """Prisms over ``K`` convex counter-clockwise polygons stored back to back as in
        ``sim.sensors.clutter.RoadsideObjects``: polygon ``k`` is ``vertices[offsets[k]:offsets[k + 1]]``
        (m, G); ``owner`` defaults to ``0 .. K-1``. Scalars broadcast."""
        vertices = np.asarray(vertices, dtype=float).reshape(-1, 2)
        offsets = np.asarray(offsets, dtype=np.int64).reshape(-1)
        count = offsets.shape[0] - 1
        if count < 0 or (count and (offsets[0] != 0 or offsets[-1] != vertices.shape[0])):
            raise ValueError("Prisms.from_polygons: offsets must start at 0 and end at the vertex count")
        sizes = np.diff(offsets)
        if count == 0:
            return cls.empty()
        if np.any(sizes < 3):
            raise ValueError("Prisms.from_polygons: every polygon needs >= 3 vertices")
        width = int(sizes.max())
        slot = np.minimum(np.arange(width)[None, :], (sizes - 1)[:, None])
        padded = vertices[offsets[:-1, None] + slot]
        owner = np.arange(count) if owner is None else owner
        return cls(padded, sizes, base, top, owner)

    @classmethod
    def _checked(cls, **fields: np.ndarray) -> Prisms:
        """An instance from already validated and derived arrays (no checks, no recomputation)."""
        out = object.__new__(cls)
        for name, value in fields.items():
            object.__setattr__(out, name, value)
        return out

    def relabel(self, owner: np.ndarray | int) -> Prisms:
        """The same prisms with other owners (an array of ``len(self)``, or a scalar for all); cheap:
        nothing is validated or derived again."""
        owner = _column(owner, len(self), "owner", np.int64)
        return Prisms._checked(
            vertices=self.vertices, sizes=self.sizes, base=self.base, top=self.top, owner=owner,
            centre=self.centre, radius=self.radius, normals=self.normals, offsets=self.offsets,
        )

    @classmethod
    def concatenate(cls, parts: Sequence[Prisms]) -> Prisms:
        """All prisms of ``parts``, in order (footprints re-padded to the widest); cheap: the parts
        are valid already, so nothing is validated or derived again."""
        parts = [p for p in parts if len(p)]
        if not parts:
            return cls.empty()
        if len(parts) == 1:
            return parts[0]
        width = max(p.vertices.shape[1] for p in parts)

        def pad(p: Prisms, name: str, fill: float | None) -> np.ndarray:
            value = getattr(p, name)
            extra = width - value.shape[1]
            if not extra:
                return value
            if fill is None:  # vertices: repeat the last one
                tail = np.repeat(value[:, -1:], extra, axis=1)
            else:
                tail = np.full(value.shape[:1] + (extra,) + value.shape[2:], fill)
            return np.concatenate([value, tail], axis=1)

        return cls._checked(
            vertices=np.concatenate([pad(p, "vertices", None) for p in parts]),
            sizes=np.concatenate([p.sizes for p in parts]),
            base=np.concatenate([p.base for p in parts]),
            top=np.concatenate([p.top for p in parts]),
            owner=np.concatenate([p.owner for p in parts]),
            centre=np.concatenate([p.centre for p in parts]),
            radius=np.concatenate([p.radius for p in parts]),
            normals=np.concatenate([pad(p, "normals", 0.0) for p in parts]),
            offsets=np.concatenate([pad(p, "offsets", 1.0) for p in parts]),
        )


@dataclass(frozen=True, eq=False)
class CastResult3D:
    """Per ray: ``range`` (slant, m; ``inf`` when nothing within ``max_range``), ``owner`` of the hit
    prism (-1 for none or the ground) and ``ground`` (the ground was the first hit)."""

    range: np.ndarray
    owner: np.ndarray
    ground: np.ndarray

    @property
    def hit(self) -> np.ndarray:
        """Rays (mask) that hit something (a prism or the ground)."""
        return np.isfinite(self.range)


def _check_range(max_range: float) -> float:
    if not (isinstance(max_range, (int, float)) and math.isfinite(max_range) and max_range > 0.0):
        raise ValueError(f"max_range must be a positive finite distance in m; got {max_range!r}")
    return float(max_range)


def _prism_hits(
    o: np.ndarray,
    ux: np.ndarray,
    uy: np.ndarray,
    k: np.ndarray,
    t_max: np.ndarray,
    azimuth: np.ndarray,
    prisms: Prisms,
    max_range: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Steps 1-5 of the module docstring: per ray the horizontal distance of the nearest prism hit
    (``inf``) and the index of that prism (-1)."""
    count = ux.shape[0]
    best = np.full(count, np.inf)
    which = np.full(count, -1, dtype=np.int64)
    ox, oy, oz = float(o[0]), float(o[1]), float(o[2])
    # 1. cull by range
    cx = prisms.centre[:, 0] - ox
    cy = prisms.centre[:, 1] - oy
    dist = np.hypot(cx, cy)
    keep = (dist - prisms.radius <= max_range) & (prisms.base <= oz + max_range) & (prisms.top >= oz - max_range)
    kept = np.flatnonzero(keep)
    if kept.size == 0:
        return best, which
    # group the kept prisms by footprint size (the narrow phase is batched per size)
    sizes = prisms.sizes[kept]
    kept = kept[np.argsort(sizes, kind="stable")]
    sizes = prisms.sizes[kept]
    cx, cy, dist = cx[kept], cy[kept], dist[kept]
    radius, base, top = prisms.radius[kept], prisms.base[kept], prisms.top[kept]
    width = int(sizes.max())
    nrm = prisms.normals[kept, :width]
    num = prisms.offsets[kept, :width] - (nrm[..., 0] * ox + nrm[..., 1] * oy)  # nu . (a - o)
    real = np.arange(width)[None, :] < sizes[:, None]
    front = real & (num < 0.0)  # edges whose half-plane excludes o_xy: the ray must enter through one
    n_front = front.sum(axis=1)
    inside = n_front == 0  # o_xy in the footprint (a raised prism overhead): every bearing, t_in = 0
    # 2. bearing intervals
    vx = prisms.vertices[kept, :width, 0] - ox
    vy = prisms.vertices[kept, :width, 1] - oy
    centre_bearing = np.arctan2(cy, cx)
    rel = np.mod(np.arctan2(vy, vx) - centre_bearing[:, None] + math.pi, TWO_PI) - math.pi
    lo = centre_bearing + rel.min(axis=1) - BEARING_SLACK
    span = rel.max(axis=1) - rel.min(axis=1) + 2.0 * BEARING_SLACK
    lo = np.mod(lo + math.pi, TWO_PI) - math.pi  # [-pi, pi)
    hi = lo + span
    a0 = np.searchsorted(azimuth, lo, side="left")
    a1 = np.searchsorted(azimuth, hi, side="right")
    w1 = np.where(hi > math.pi, np.searchsorted(azimuth, hi - TWO_PI, side="right"), 0)
    a0 = np.where(inside, 0, a0)
    a1 = np.where(inside, count, a1)
    w1 = np.where(inside, 0, w1)
    local = np.arange(kept.size)
    starts = np.concatenate([a0, np.zeros(kept.size, dtype=a0.dtype)])
    stops = np.concatenate([a1, w1])
    owner_of_range = np.concatenate([local, local])
    order_ranges = np.argsort(owner_of_range, kind="stable")  # keep pairs grouped by prism (and size)
    starts, stops, owner_of_range = starts[order_ranges], stops[order_ranges], owner_of_range[order_ranges]
    lengths = np.maximum(stops - starts, 0)
    total = int(lengths.sum())
    if total == 0:
        return best, which
    pid = np.repeat(owner_of_range, lengths)
    # the rays (indices into the caller's arrays, which are sorted by azimuth)
    ray = np.arange(total) + np.repeat(starts - (np.cumsum(lengths) - lengths), lengths)
    # 3. slope cull
    d_min = np.maximum(dist - radius, 1e-9)
    d_max = dist + radius
    k_lo = np.minimum((base - oz) / d_min, (base - oz) / d_max)
    k_hi = np.maximum((top - oz) / d_min, (top - oz) / d_max)
    kr = k[ray]
    ok = (kr >= k_lo[pid]) & (kr <= k_hi[pid])
    ray = ray[ok]
    pid = pid[ok]
    if ray.size == 0:
        return best, which
    # 4. narrow phase (module docstring), batched per footprint size (pid ascends, and so do sizes).
    # Per prism edge p = nu / num, front edges first
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = np.where(real, 1.0 / np.where(num == 0.0, 1e-300, num), 0.0)
    px, py = nrm[..., 0] * scale, nrm[..., 1] * scale  # padding edges: p = 0, a neutral back edge
    order = np.argsort(~front, axis=1, kind="stable")
    px, py = np.take_along_axis(px, order, axis=1), np.take_along_axis(py, order, axis=1)
    inv_k = np.divide(1.0, k, out=np.full(k.shape, np.inf), where=k != 0.0)
    # the groups: runs of equal size among the kept prisms (sorted by size), and their pairs
    group_start = np.flatnonzero(np.r_[True, sizes[1:] != sizes[:-1]]).tolist() + [kept.size]
    pair_start = np.searchsorted(pid, group_start).tolist()
    for m0, m1, g0, g1 in zip(group_start[:-1], group_start[1:], pair_start[:-1], pair_start[1:]):
        if g1 <= g0:
            continue
        q = pid[g0:g1]
        r = ray[g0:g1]
        members = np.arange(m0, m1)
        nf = n_front[members]
        slots_f = max(int(nf.max()), 1)
        slots_b = int((width - nf).max())
        # per member prism: front slots (the last front edge repeated: min is unchanged) and back
        # slots (then padding edges, p = 0: max over back edges only matters when positive)
        jf = np.minimum(np.arange(slots_f)[None, :], np.maximum(nf - 1, 0)[:, None])
        jb = np.minimum(nf[:, None] + np.arange(slots_b)[None, :], width - 1)
        pad_b = (nf[:, None] + np.arange(slots_b)[None, :]) >= width
        fx = np.zeros((slots_f, kept.size))
        fy = np.zeros((slots_f, kept.size))
        bx = np.zeros((slots_b, kept.size))
        by = np.zeros((slots_b, kept.size))
        m = members[:, None]
        fx[:, members] = px[m, jf].T
        fy[:, members] = py[m, jf].T
        bx[:, members] = np.where(pad_b, 0.0, px[m, jb]).T
        by[:, members] = np.where(pad_b, 0.0, py[m, jb]).T
        uxr, uyr = ux[r], uy[r]
        # w_e = p_e . u = den_e / num_e: the ray enters (front) at t = 1 / w, needs every w_front > 0;
        # it leaves (back) at 1 / max w_back when that is positive
        w_front = fx[0][q] * uxr + fy[0][q] * uyr
        for j in range(1, slots_f):
            np.minimum(w_front, fx[j][q] * uxr + fy[j][q] * uyr, out=w_front)
        w_back = bx[0][q] * uxr + by[0][q] * uyr
        for j in range(1, slots_b):
            np.maximum(w_back, bx[j][q] * uxr + by[j][q] * uyr, out=w_back)
        if inside[members].any():
            w_front[inside[q]] = np.inf
        with np.errstate(divide="ignore"):
            t_in = 1.0 / w_front  # +inf w -> 0
        ik = inv_k[r]
        with np.errstate(invalid="ignore"):
            z_a = (base[q] - oz) * ik
            z_b = (top[q] - oz) * ik
            t_hit = np.maximum(t_in, np.minimum(z_a, z_b))
            good = (
                (w_front > 0.0)
                & (t_hit * w_back <= 1.0)
                & (t_hit <= np.maximum(z_a, z_b))
                & (t_hit <= t_max[r])
            )
        hit = np.flatnonzero(good)
        if hit.size == 0:
            continue
        r_hit, t_val, q_hit = r[hit], t_hit[hit], q[hit]
        np.minimum.at(best, r_hit, t_val)
        win = t_val == best[r_hit]
        which[r_hit[win]] = kept[q_hit[win]]
    return best, which


def _ground_hits(
    o: np.ndarray,
    ux: np.ndarray,
    uy: np.ndarray,
    k: np.ndarray,
    t_end: np.ndarray,
    ground: Ground,
    max_range: float,
) -> np.ndarray:
    """Step 6 of the module docstring: per ray the horizontal distance of the first ground crossing
    within ``t_end`` (``inf`` when none)."""
    count = ux.shape[0]
    out = np.full(count, np.inf)
    ox, oy, oz = float(o[0]), float(o[1]), float(o[2])
    surface = ground.surface((ox, oy), max_range)
    height = surface.height
    clearance = oz - float(height(np.array([ox]), np.array([oy]))[0])
    if not clearance > 0.0:
        raise ValueError(f"cast_3d: the origin must be above the ground; it is {clearance!r} m above it")
    if surface.flat is not None:
        down = np.flatnonzero(k < 0.0)
        t = clearance / -k[down]
        sel = t <= t_end[down]
        out[down[sel]] = t[sel]
        return out
    # the steepest rise of the ground along each ray's horizontal direction
    idx = np.flatnonzero(k < surface.max_rise)
    closing = surface.rise(ux[idx], uy[idx]) - k[idx]  # f falls at most this fast (m per m)
    sel = np.flatnonzero(closing > 0.0)
    idx, closing = idx[sel], closing[sel]
    t0 = clearance / closing  # the first possible contact
    live = t0 <= t_end[idx]
    idx, closing, t0 = idx[live], closing[live], t0[live]
    # the first point: where the ground's tangent plane at the sensor's foot predicts the crossing,
    # kept within [t0, t0 + GROUND_MIN_STEP] (the march's rule, below)
    e = 0.5
    hx = height(np.array([ox + e, ox - e, ox, ox]), np.array([oy, oy, oy + e, oy - e]))
    gx, gy = (hx[0] - hx[1]) / (2.0 * e), (hx[2] - hx[3]) / (2.0 * e)
    rate = k[idx] - gx * ux[idx] - gy * uy[idx]  # f' on that plane
    with np.errstate(divide="ignore"):
        predicted = np.where(rate < 0.0, clearance / -rate, np.inf)
    t1 = np.minimum(np.clip(predicted, t0, t0 + GROUND_MIN_STEP), t_end[idx])
    # march state, one row per quantity so that one take compacts it: ray, closing, k, ux, uy, t_end,
    # t (the point to evaluate), t_prev and f_prev (the last point known above the ground)
    state = np.empty((9, idx.size))
    state[0] = idx
    state[1] = closing
    state[2] = k[idx]
    state[3] = ux[idx]
    state[4] = uy[idx]
    state[5] = t_end[idx]
    state[6] = t1
    state[7] = 0.0
    state[8] = clearance
    brackets = []  # rows (ray, a, f(a), b, f(b)) with f(a) > 0 > f(b)
    for _ in range(GROUND_MAX_MARCH):
        if state.shape[1] <= GROUND_TAIL_RAYS:
            break
        _, cl, rk, rx, ry, te, t, tp, fp = state
        f = oz + rk * t - height(ox + rx * t, oy + ry * t)
        found = np.abs(f) <= GROUND_TOLERANCE
        crossed = f < -GROUND_TOLERANCE
        if found.any():
            c = np.flatnonzero(found)
            out[state[0, c].astype(np.intp)] = t[c]
        if crossed.any():
            c = np.flatnonzero(crossed)
            brackets.append(np.stack([state[0, c], tp[c], fp[c], t[c], f[c]]))
        go = np.flatnonzero((f > GROUND_TOLERANCE) & (t < te))
        state = state[:, go]
        f = f[go]
        _, cl, rk, rx, ry, te, t, tp, fp = state
        # the next point: the secant's predicted crossing, kept within [safe, safe + GROUND_MIN_STEP]
        # with safe = f / closing (no crossing can come sooner)
        with np.errstate(divide="ignore", invalid="ignore"):
            predicted = np.where(fp > f, f * (t - tp) / (fp - f), np.inf)
        safe = f / cl
        step = np.minimum(np.maximum(predicted, safe), safe + GROUND_MIN_STEP)
        state[7] = t
        state[8] = f
        state[6] = np.minimum(t + step, te)
    # the tail (few rays, mostly grazing ones crawling at GROUND_MIN_STEP): GROUND_TAIL_PROBES points
    # per ray and iteration, GROUND_MIN_STEP apart (never farther apart than the march would step)
    probes = np.arange(GROUND_TAIL_PROBES)
    for _ in range(GROUND_MAX_MARCH):
        if state.shape[1] == 0:
            break
        _, cl, rk, rx, ry, te, t, tp, fp = state
        ts = np.minimum(t[:, None] + GROUND_MIN_STEP * probes, te[:, None])
        hs = height((ox + rx[:, None] * ts).ravel(), (oy + ry[:, None] * ts).ravel()).reshape(ts.shape)
        fs = oz + rk[:, None] * ts - hs
        low = fs <= GROUND_TOLERANCE
        hit = low.any(axis=1)
        rows = np.flatnonzero(hit)
        if rows.size:
            j = np.argmax(low[rows], axis=1)
            b, fb = ts[rows, j], fs[rows, j]
            a = np.where(j > 0, ts[rows, j - 1], tp[rows])
            fa = np.where(j > 0, fs[rows, j - 1], fp[rows])
            found = np.abs(fb) <= GROUND_TOLERANCE
            out[state[0, rows[found]].astype(np.intp)] = b[found]
            c = np.flatnonzero(~found)
            brackets.append(np.stack([state[0, rows[c]], a[c], fa[c], b[c], fb[c]]))
        go = np.flatnonzero(~hit & (ts[:, -1] < te))
        state = state[:, go]
        t_last, f_last = ts[go, -1], fs[go, -1]
        t_before, f_before = ts[go, -2], fs[go, -2]
        with np.errstate(divide="ignore", invalid="ignore"):
            predicted = np.where(f_before > f_last, f_last * (t_last - t_before) / (f_before - f_last), np.inf)
        safe = f_last / state[1]
        step = np.minimum(np.maximum(predicted, safe), safe + GROUND_MIN_STEP)
        state[7] = t_last
        state[8] = f_last
        state[6] = np.minimum(t_last + step, state[5])
    if not brackets:
        return out
    ray_f, a, fa, b, fb = np.concatenate(brackets, axis=1)
    ray = ray_f.astype(np.intp)
    rk, rx, ry = k[ray], ux[ray], uy[ray]
    # safeguarded secant: the secant through the last two iterates (superlinear), regula falsi on the
    # bracket when that leaves the bracket (and on the first step)
    x0, f0, x1, f1 = a, fa, b, fb
    for _ in range(GROUND_MAX_REFINE):
        if ray.size == 0:
            break
        with np.errstate(divide="ignore", invalid="ignore"):
            c = x1 - f1 * (x1 - x0) / (f1 - f0)
        falsi = b - fb * (b - a) / (fb - fa)
        c = np.where((c > a) & (c < b), c, falsi)
        fc = oz + rk * c - height(ox + rx * c, oy + ry * c)
        conv = (np.abs(fc) <= GROUND_TOLERANCE) | (b - a <= 1e-12 * (1.0 + b))
        out[ray[conv]] = c[conv]
        below = fc <= 0.0
        b = np.where(below, c, b)
        fb = np.where(below, fc, fb)
        a = np.where(below, a, c)
        fa = np.where(below, fa, fc)
        x0, f0, x1, f1 = x1, f1, c, fc
        go = np.flatnonzero(~conv)
        if go.size < ray.size:
            ray, a, fa, b, fb, x0, f0, x1, f1, rk, rx, ry = (
                v[go] for v in (ray, a, fa, b, fb, x0, f0, x1, f1, rk, rx, ry)
            )
    out[ray] = b  # not converged (never in practice): the bracket's end under the ground
    return out


def cast_3d(
    origin: np.ndarray,
    directions: np.ndarray,
    prisms: Prisms,
    ground: Ground,
    max_range: float,
) -> CastResult3D:
    """First hit of every ray from ``origin`` (3,) (m, G) along ``directions`` (R, 3) (unit vectors
    in G; none vertical) on ``prisms`` and ``ground`` within the slant range ``max_range`` (m); see
    the module docstring for the algorithm."""
    max_range = _check_range(max_range)
    o = np.asarray(origin, dtype=float).reshape(-1)
    if o.shape != (3,) or not np.all(np.isfinite(o)):
        raise ValueError(f"cast_3d: origin must be 3 finite numbers; got {origin!r}")
    d = np.asarray(directions, dtype=float)
    if d.ndim != 2 or d.shape[1] != 3:
        raise ValueError(f"cast_3d: directions must have shape (R, 3); got {d.shape}")
    if not isinstance(prisms, Prisms):
        raise ValueError(f"cast_3d: prisms must be a Prisms; got {type(prisms).__name__}")
    if not isinstance(ground, Ground):
        raise ValueError(f"cast_3d: ground must be a sim.world.ground.Ground; got {type(ground).__name__}")
    count = d.shape[0]
    dx, dy, dz = d[:, 0], d[:, 1], d[:, 2]
    rho = np.hypot(dx, dy)
    norm = np.sqrt(rho * rho + dz * dz)
    if not np.all(np.abs(norm - 1.0) <= 1e-6):
        raise ValueError("cast_3d: directions must be unit vectors")
    if not np.all(rho > 1e-9):
        raise ValueError("cast_3d: vertical rays are not supported (|horizontal part| <= 1e-9)")
    inv_rho = 1.0 / rho
    ux, uy, k = dx * inv_rho, dy * inv_rho, dz * inv_rho
    t_max = max_range * rho  # horizontal distance at the slant max_range
    best = np.full(count, np.inf)
    which = np.full(count, -1, dtype=np.int64)
    if len(prisms):
        azimuth = np.arctan2(dy, dx)
        order = np.argsort(azimuth, kind="stable")
        sorted_az = azimuth[order]
        ux_s, uy_s, k_s, tm_s = ux[order], uy[order], k[order], t_max[order]
        best_s, which_s = _prism_hits(o, ux_s, uy_s, k_s, tm_s, sorted_az, prisms, max_range)
        best[order] = best_s
        which[order] = which_s
    t_ground = _ground_hits(o, ux, uy, k, np.minimum(t_max, best), ground, max_range)
    on_ground = t_ground < best
    t = np.where(on_ground, t_ground, best)
    owner = np.where(on_ground | (which < 0), -1, prisms.owner[np.maximum(which, 0)] if len(prisms) else -1)
    return CastResult3D(range=t * inv_rho, owner=owner.astype(np.int64), ground=on_ground)


#: ``LidarScan3D.vehicle_id`` of a return from the ego's own body (never a vehicle's id, which are >= 0).
EGO_BODY_ID = -2


@dataclass(frozen=True, eq=False)
class LidarScan3D:
    """One scan at time ``t`` (s): ``M`` points, with per point ``points`` (M, 3) in the scan's ``frame``
    (m): ``"sensor"``, the lidar's own, or ``"vehicle"``, the ego frame E (a rig of several lidars merged,
    ``merge_scans``), the ray's ``azimuth`` and ``elevation`` (rad, its lidar's frame) and ``beam`` (0 =
    lowest; with ``sensor`` the ring), the measured ``range`` (m), and what it hit: ``vehicle_id`` (-1
    unless a vehicle; ``EGO_BODY_ID`` the ego's own body, when the scene holds it:
    ``sim.sensors.rig.SceneLidar3D``), ``roadside_index`` (-1 unless a roadside object) and ``ground``.
    ``rays`` is the number of rays cast; ``origin`` (3,) and ``rotation`` (3, 3) are the pose of the
    points' frame in G (``p_G = rotation @ p + origin``). ``sensor`` (M,): the index of the lidar each
    point came from in its rig (``None``: one lidar, all 0); ``ray_origins`` (K, 3): each lidar's
    position in the points' frame (``None``: the frame's origin, a lidar's own frame)."""

    t: float
    points: np.ndarray
    azimuth: np.ndarray
    elevation: np.ndarray
    beam: np.ndarray
    range: np.ndarray
    vehicle_id: np.ndarray
    roadside_index: np.ndarray
    ground: np.ndarray
    rays: int
    origin: np.ndarray
    rotation: np.ndarray
    frame: str = "sensor"
    sensor: np.ndarray | None = None
    ray_origins: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.range.shape[0])

    def points_on(self, vehicle_id: int) -> np.ndarray:
        """The points (K, 3) in the scan's frame that hit the vehicle with this id."""
        return self.points[self.vehicle_id == vehicle_id]

    def points_global(self) -> np.ndarray:
        """All points (M, 3) in G (m)."""
        return self.points @ self.rotation.T + self.origin

    def sensors(self) -> np.ndarray:
        """Each point's lidar index in the rig (M,), 0 for a single lidar's scan."""
        return np.zeros(len(self), dtype=np.int64) if self.sensor is None else self.sensor

    def point_origins(self) -> np.ndarray:
        """Where each point's ray starts (M, 3), in the scan's frame: its lidar's position."""
        if self.ray_origins is None:
            return np.zeros((len(self), 3))
        return self.ray_origins[self.sensors()]


def merge_scans(scans: Sequence[LidarScan3D], mounts: Sequence[tuple[np.ndarray, np.ndarray]], ego_origin: np.ndarray,
                ego_yaw: float) -> LidarScan3D:
    """The scans of a rig's lidars (each in its own frame) as one scan in the ego frame E, as a rig's
    driver delivers them: ``p_E = R_k p_S + t_k`` with lidar ``k``'s mount ``(R_k, t_k)`` (rotation (3, 3),
    translation (3,) in E); ``sensor`` says which lidar each point came from, ``ray_origins`` are the
    ``t_k``, and the frame's pose in G is the ego's ground point ``ego_origin`` (3,) and heading
    ``ego_yaw`` (rad)."""
    if len(scans) != len(mounts) or not scans:
        raise ValueError(f"merge_scans: {len(scans)} scans for {len(mounts)} mounts; one mount per scan, at least one")
    points = np.concatenate([s.points @ r.T + t for s, (r, t) in zip(scans, mounts)])

    def cat(name: str) -> np.ndarray:
        return np.concatenate([getattr(s, name) for s in scans])

    return LidarScan3D(
        t=float(scans[0].t), points=points, azimuth=cat("azimuth"), elevation=cat("elevation"), beam=cat("beam"),
        range=cat("range"), vehicle_id=cat("vehicle_id"), roadside_index=cat("roadside_index"), ground=cat("ground"),
        rays=int(sum(s.rays for s in scans)), origin=np.asarray(ego_origin, dtype=float).reshape(3),
        rotation=mount_rotation(0.0, 0.0, float(ego_yaw)), frame="vehicle",
        sensor=np.concatenate([np.full(len(s), k, dtype=np.int64) for k, s in enumerate(scans)]),
        ray_origins=np.array([np.asarray(t, dtype=float).reshape(3) for _, t in mounts]),
    )


class Lidar3D:
    """The 3-D lidar of ``config`` (``Lidar3DConfig()``, a VLP-16, by default); ``scan`` makes one scan."""

    def __init__(self, config: Lidar3DConfig | None = None) -> None:
        config = Lidar3DConfig() if config is None else config
        if not isinstance(config, Lidar3DConfig):
            raise ValueError(f"Lidar3D needs a Lidar3DConfig; got {type(config).__name__}")
        self.config = config

    @cached_property
    def _directions_ego(self) -> np.ndarray:
        """Ray directions (rays, 3) in E."""
        return self.config.directions @ self.config.mount_rotation.T

    @cached_property
    def _ray_angles(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        cfg = self.config
        beams = int(cfg.beams)
        return (
            np.repeat(cfg.azimuths, beams),
            np.tile(cfg.elevations, cfg.azimuth_count),
            np.tile(np.arange(beams, dtype=np.int64), cfg.azimuth_count),
        )

    def pose(self, origin: np.ndarray, ego_yaw: float) -> tuple[np.ndarray, np.ndarray]:
        """The sensor's position (3,) and rotation (3, 3) in G for the ego ground point ``origin``
        (3,) (m, G) and heading ``ego_yaw`` (rad)."""
        o = np.asarray(origin, dtype=float).reshape(-1)
        if o.shape != (3,) or not np.all(np.isfinite(o)):
            raise ValueError(f"Lidar3D: origin must be 3 finite numbers (x, y, z in G); got {origin!r}")
        if not (isinstance(ego_yaw, (int, float, np.floating)) and math.isfinite(ego_yaw)):
            raise ValueError(f"Lidar3D: ego_yaw must be a finite angle in rad; got {ego_yaw!r}")
        rz = mount_rotation(0.0, 0.0, float(ego_yaw))
        return o + rz @ self.config.mount_translation, rz @ self.config.mount_rotation

    def scan(
        self,
        origin: np.ndarray,
        ego_yaw: float,
        prisms: Prisms,
        ground: Ground,
        *,
        vehicle_ids: np.ndarray | Sequence[int],
        rng: np.random.Generator,
        t: float = 0.0,
    ) -> LidarScan3D:
        """One scan at time ``t`` (s) from the ego whose ground point under its centre is ``origin``
        (3,) (m, G) with heading ``ego_yaw`` (rad), of ``prisms`` over ``ground``; prism owners
        ``0 .. V-1`` are the vehicles ``vehicle_ids`` (V,), owners ``V + j`` roadside object ``j``.
        Noise and dropout from ``rng`` (two draws per ray)."""
        if not isinstance(rng, np.random.Generator):
            raise ValueError(f"Lidar3D.scan needs rng, a numpy.random.Generator; got {type(rng).__name__}")
        cfg = self.config
        position, rotation = self.pose(origin, ego_yaw)
        rz = mount_rotation(0.0, 0.0, float(ego_yaw))
        directions = self._directions_ego @ rz.T
        cast = cast_3d(position, directions, prisms, ground, cfg.max_range)
        idx, measured, vehicle_id, roadside_index = ray_returns(cast.hit, cast.range, cast.owner, vehicle_ids, cfg, rng)
        azimuth, elevation, beam = self._ray_angles
        if cfg.organized:  # every ray, NaN where nothing returned
            rays = len(cast.hit)
            rng_full = np.full(rays, np.nan)
            rng_full[idx] = measured
            vid, rid = np.full(rays, -1, dtype=np.int64), np.full(rays, -1, dtype=np.int64)
            vid[idx], rid[idx] = vehicle_id, roadside_index
            on_ground = np.zeros(rays, dtype=bool)
            on_ground[idx] = cast.ground[idx]
            return LidarScan3D(t=float(t), points=cfg.directions * rng_full[:, None], azimuth=azimuth, elevation=elevation,
                               beam=beam, range=rng_full, vehicle_id=vid, roadside_index=rid, ground=on_ground,
                               rays=cfg.rays, origin=position, rotation=rotation)
        return LidarScan3D(
            t=float(t),
            points=cfg.directions[idx] * measured[:, None],
            azimuth=azimuth[idx],
            elevation=elevation[idx],
            beam=beam[idx],
            range=measured,
            vehicle_id=vehicle_id,
            roadside_index=roadside_index,
            ground=cast.ground[idx],
            rays=cfg.rays,
            origin=position,
            rotation=rotation,
        )
