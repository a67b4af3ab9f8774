"""2-D ray casting against line segments: the compiled caster and a pymunk oracle.

Rays start at the origin of the caster's frame and fan out at bearings ``start + k * resolution``
(``RayGrid``). The scene is a set of ``Segments`` (edges of convex polygons, in the same frame, m),
each with an integer ``owner`` (the object it belongs to). Both casters return, per ray, the range
(m) to the first hit (``inf`` when the ray hits nothing within ``max_range``) and the hit owner (-1).

``cast`` (the default; ``cast_kernel``, one compiled call, see ``sim/benchmarks/sensors.py`` for the
numbers), edge by edge:

1. cull: skip edges facing away from the origin (edges of counter-clockwise polygons whose
   ``cross(a, b) >= 0``; the first hit on a closed convex polygon seen from outside is always on an
   edge facing the origin). Range culling is left to the caller (``sim.sensors.scene`` drops objects
   wholly out of range); edges beyond ``max_range`` only cost a few rejected pairs;
2. angular broad phase: each edge subtends the bearing interval between its end points (less than pi
   for an edge not through the origin); the rays inside it are a contiguous index range of the grid,
   taken modulo the ray count on a full circle; on a fan, the interval and its copy one turn lower
   are each clipped to the fan (every edge's interval first, then every edge's copy). One extra ray
   on each side guards rounding;
3. narrow phase, per (ray, edge) pair: with ``d`` the ray direction, ``ca = d x a`` and
   ``cb = d x b``, the ray's line crosses the edge iff ``ca * cb <= 0``, at range
   ``t = (a x b) / (cb - ca)``; a hit needs ``0 < t <= max_range``;
4. per ray, the smallest ``t`` wins (occlusion); of pairs at the same range, the one visited last
   gives the owner.

``cast_pymunk`` builds a pymunk ``Space`` of radius-0 static ``Segment`` shapes from *all* edges (no
culling, no broad phase of ours) and calls ``Space.segment_query_first`` once per ray; it is the
independent oracle the tests compare against. Back-face culling assumes the origin is outside every
polygon (a sensor inside an object sees nothing of that object).

``ray_returns`` turns one cast into a lidar's returns (range noise, dropout, minimum range); the 2-D
lidar (``sim.sensors.lidar``) and the VLP-16 (``sim.sensors.lidar3d``) share it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Protocol

import numpy as np

from tracker.jit import njit

TWO_PI = 2.0 * math.pi


@dataclass(frozen=True)
class RayGrid:
    """Rays from the origin at bearings ``start + k * resolution`` (rad), ``k = 0 .. count - 1``,
    spanning at most one full turn. Use ``RayGrid.full_circle`` or ``RayGrid.fan``."""

    start: float
    resolution: float
    count: int

    def __post_init__(self) -> None:
        if not (math.isfinite(self.start)):
            raise ValueError(f"RayGrid.start must be finite; got {self.start!r}")
        if not (math.isfinite(self.resolution) and self.resolution > 0.0):
            raise ValueError(f"RayGrid.resolution must be a positive angle in rad; got {self.resolution!r}")
        if int(self.count) != self.count or self.count < 1:
            raise ValueError(f"RayGrid.count must be a positive integer; got {self.count!r}")
        if (self.count - 1) * self.resolution >= TWO_PI:
            raise ValueError(
                f"RayGrid spans {(self.count - 1) * self.resolution:.6f} rad; at most one turn (2 pi) is allowed"
            )
        object.__setattr__(self, "count", int(self.count))

    @classmethod
    def full_circle(cls, resolution: float) -> RayGrid:
        """360 degrees at ``resolution`` (rad), which must divide 2 pi into a whole number of rays;
        bearings ``-pi + resolution, ..., pi`` (ascending, already wrapped to (-pi, pi])."""
        if not (math.isfinite(resolution) and resolution > 0.0):
            raise ValueError(f"ray resolution must be a positive angle; got {resolution!r} rad")
        count = round(TWO_PI / resolution)
        if count < 1 or abs(count * resolution - TWO_PI) > 1e-9 * TWO_PI:
            raise ValueError(
                f"a 360-degree scan needs a resolution that divides 360 degrees into whole rays; "
                f"{math.degrees(resolution)!r} deg gives {TWO_PI / resolution:.6f} rays"
            )
        return cls(-math.pi + resolution, resolution, count)

    @classmethod
    def fan(cls, centre: float, half_width: float, resolution: float) -> RayGrid:
        """Rays from ``centre - half_width`` to ``centre + half_width`` (rad, both included when
        ``2 half_width`` is a multiple of ``resolution``) every ``resolution`` (rad)."""
        if not (math.isfinite(half_width) and 0.0 <= half_width < math.pi):
            raise ValueError(f"fan half-width must be in [0, pi) rad; got {half_width!r}")
        if not (math.isfinite(resolution) and resolution > 0.0):
            raise ValueError(f"ray resolution must be a positive angle; got {resolution!r} rad")
        count = int(math.floor(2.0 * half_width / resolution + 1e-9)) + 1
        return cls(centre - half_width, resolution, count)

    @cached_property
    def angles(self) -> np.ndarray:
        """Bearings (count,) in rad, wrapped to (-pi, pi]."""
        raw = self.start + self.resolution * np.arange(self.count)
        return np.pi - np.mod(np.pi - raw, TWO_PI)

    @cached_property
    def cos(self) -> np.ndarray:
        """Cosines of the bearings (count,)."""
        return np.cos(self.angles)

    @cached_property
    def sin(self) -> np.ndarray:
        """Sines of the bearings (count,)."""
        return np.sin(self.angles)

    @cached_property
    def directions(self) -> np.ndarray:
        """Unit direction vectors (count, 2)."""
        return np.stack([self.cos, self.sin], axis=1)

    @property
    def is_full_circle(self) -> bool:
        """Whether the rays go all the way round (``count * resolution == 2 pi``)."""
        return abs(self.count * self.resolution - TWO_PI) <= 1e-9 * TWO_PI


@dataclass(frozen=True, eq=False)
class Segments:
    """Line segments from ``a`` (M, 2) to ``b`` (M, 2) in metres, each belonging to the object
    ``owner`` (M,) (int). Edges of a polygon run counter-clockwise (interior on the left)."""

    a: np.ndarray
    b: np.ndarray
    owner: np.ndarray

    def __post_init__(self) -> None:
        a = np.asarray(self.a, dtype=float).reshape(-1, 2)
        b = np.asarray(self.b, dtype=float).reshape(-1, 2)
        owner = np.asarray(self.owner).reshape(-1).astype(np.int64, copy=False)
        if a.shape != b.shape or owner.shape[0] != a.shape[0]:
            raise ValueError(
                f"Segments: a {a.shape}, b {b.shape} and owner {owner.shape} must describe the same number of segments"
            )
        object.__setattr__(self, "a", a)
        object.__setattr__(self, "b", b)
        object.__setattr__(self, "owner", owner)

    def __len__(self) -> int:
        return int(self.a.shape[0])

    @classmethod
    def from_polygons(cls, vertices: np.ndarray, offsets: np.ndarray, owners: np.ndarray) -> Segments:
        """Edges of ``K`` polygons stored back to back: polygon ``k`` has the vertices
        ``vertices[offsets[k]:offsets[k + 1]]`` (m, counter-clockwise) and owner ``owners[k]``."""
        vertices = np.asarray(vertices, dtype=float).reshape(-1, 2)
        offsets = np.asarray(offsets, dtype=np.int64)
        owners = np.asarray(owners, dtype=np.int64)
        sizes = np.diff(offsets)
        if sizes.shape[0] != owners.shape[0]:
            raise ValueError(f"from_polygons: {sizes.shape[0]} polygons but {owners.shape[0]} owners")
        nxt = np.arange(1, vertices.shape[0] + 1)
        nonempty = sizes > 0
        nxt[offsets[1:][nonempty] - 1] = offsets[:-1][nonempty]
        return cls(vertices, vertices[nxt], np.repeat(owners, sizes))

    @classmethod
    def concatenate(cls, parts: list[Segments]) -> Segments:
        """All segments of ``parts``, in order."""
        if not parts:
            return cls(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0, dtype=np.int64))
        return cls(
            np.concatenate([p.a for p in parts]),
            np.concatenate([p.b for p in parts]),
            np.concatenate([p.owner for p in parts]),
        )


@dataclass(frozen=True, eq=False)
class CastResult:
    """Per ray of a ``RayGrid``: ``range`` (count,) to the first hit in m (``inf`` for none) and the
    hit segment's ``owner`` (count,) (-1 for none)."""

    range: np.ndarray
    owner: np.ndarray

    @property
    def hit(self) -> np.ndarray:
        """Boolean mask (count,) of the rays that hit something."""
        return self.owner >= 0


def _check_range(max_range: float) -> float:
    if not (math.isfinite(max_range) and max_range > 0.0):
        raise ValueError(f"max_range must be a positive finite distance in m; got {max_range!r}")
    return float(max_range)


# --------------------------------------------------------------------------------------------------
# The compiled kernels of this stage.
#
# The caster of the module docstring in one numba call: the ranges are the floating-point
# expressions of steps 3 and 4, computed pair by pair in the order of step 2.


@njit(error_model="numpy", inline="always")
def _narrow(k_from, k_to, count, wrap, ax, ay, bx, by, cr, owner, cos, sin, max_range, ranges, owners):  # pragma: no cover - compiled
    """Narrow phase of one edge ``a -> b`` (``cr = a x b``) on the rays ``k_from .. k_to`` (modulo
    ``count`` when ``wrap``): the ray's line crosses the edge iff ``ca * cb <= 0`` (``ca = d x a``,
    ``cb = d x b``), at ``t = cr / (cb - ca)``; a hit in ``(0, max_range]`` no farther than the ray's
    best so far takes the ray (``ranges``, ``owners``: updated in place)."""
    for k in range(k_from, k_to + 1):
        ray = k % count if wrap else k
        dx, dy = cos[ray], sin[ray]
        ca = dx * ay - dy * ax
        cb = dx * by - dy * bx
        t = cr / (cb - ca)
        if ca * cb <= 0.0 and t > 0.0 and t <= max_range and t <= ranges[ray]:
            ranges[ray] = t
            owners[ray] = owner


@njit(error_model="numpy")
def cast_kernel(a, b, owner, start, resolution, cos, sin, full_circle, max_range, cull_back_faces):  # pragma: no cover - compiled
    """Per ray: range (count,) to the first hit (``inf`` for none) and the hit edge's owner (-1), for
    the edges ``a (M, 2) -> b (M, 2)`` with ``owner (M,)`` and the grid given by its start bearing
    (wrapped to ``[-pi, pi]``), ``resolution`` and the rays' direction cosines and sines. Culling,
    broad and narrow phase as the module docstring's steps 1-4: an edge subtends ``[lo, hi]`` (rad,
    relative to the start, ``hi - lo < pi``; with ``a x b < 0`` the end ``b`` is clockwise of ``a``),
    the rays ``floor(lo / res) .. floor(hi / res) + 1`` (a turn added on a full circle, so the
    truncation is a floor; modulo the ray count), on a fan that interval and its copy one turn lower,
    each clipped to the fan."""
    count = cos.shape[0]
    ranges = np.full(count, np.inf)
    owners = np.full(count, -1, dtype=np.int64)
    n = a.shape[0]
    inv_res = 1.0 / resolution
    keep = np.zeros(n, dtype=np.bool_)
    crs = np.empty(n)
    los = np.empty(n)
    spans = np.empty(n)
    for i in range(n):
        ax, ay, bx, by = a[i, 0], a[i, 1], b[i, 0], b[i, 1]
        cr = ax * by - ay * bx
        if cull_back_faces:
            if not cr < 0.0:
                continue
        elif cr == 0.0:  # an edge on a line through the origin
            continue
        rel_a = math.atan2(ay, ax) - start
        rel_b = math.atan2(by, bx) - start
        if cull_back_faces or not cr > 0.0:
            lo, hi = rel_b, rel_a
        else:
            lo, hi = rel_a, rel_b
        if hi < lo:
            hi += TWO_PI
        keep[i] = True
        crs[i] = cr
        los[i] = lo
        spans[i] = hi - lo
        if full_circle:
            k0 = int((lo + TWO_PI) * inv_res)
            k1 = int((hi + TWO_PI) * inv_res) + 1
            _narrow(k0, k1, count, True, ax, ay, bx, by, cr, owner[i], cos, sin, max_range, ranges, owners)
    if full_circle:
        return ranges, owners
    for turn in range(2):  # a fan: every edge's interval, then every edge's copy one turn lower
        for i in range(n):
            if not keep[i]:
                continue
            lo = los[i] % TWO_PI  # Python's float modulo: fmod, then the divisor's sign
            if turn == 1:
                lo -= TWO_PI
            hi = lo + spans[i]
            k0 = max(int(math.floor(lo * inv_res)), 0)
            k1 = min(math.floor(hi * inv_res) + 1.0, count - 1.0)
            _narrow(k0, int(k1), count, False, a[i, 0], a[i, 1], b[i, 0], b[i, 1], crs[i], owner[i], cos, sin,
                    max_range, ranges, owners)
    return ranges, owners


# -- the casters ----------------------------------------------------------------------------------


class PymunkScene:
    """The segments as a pymunk ``Space`` of radius-0 static ``Segment`` shapes (all of them: no
    culling, no broad phase of ours), built once and queried with ``cast``."""

    def __init__(self, segments: Segments) -> None:
        import pymunk

        self._pymunk = pymunk
        self.space = pymunk.Space()
        body = self.space.static_body
        shapes = [
            pymunk.Segment(body, (a[0], a[1]), (b[0], b[1]), 0.0)
            for a, b in zip(segments.a.tolist(), segments.b.tolist())
        ]
        if shapes:
            self.space.add(*shapes)
        self._owner_of = {id(shape): int(o) for shape, o in zip(shapes, segments.owner.tolist())}

    def cast(self, grid: RayGrid, max_range: float) -> CastResult:
        """First hit of every ray of ``grid`` within ``max_range`` (m): one
        ``Space.segment_query_first`` from the origin to ``max_range`` along the ray per ray (a Python
        loop; this is the oracle, not the hot path); range = ``alpha * max_range``."""
        max_range = _check_range(max_range)
        ranges = np.full(grid.count, np.inf)
        owners = np.full(grid.count, -1, dtype=np.int64)
        query = self.space.segment_query_first
        everything = self._pymunk.ShapeFilter()
        owner_of = self._owner_of
        for k, (ex, ey) in enumerate((grid.directions * max_range).tolist()):
            info = query((0.0, 0.0), (ex, ey), 0.0, everything)
            if info is not None:
                ranges[k] = info.alpha * max_range
                owners[k] = owner_of[id(info.shape)]
        return CastResult(ranges, owners)


def cast_pymunk(segments: Segments, grid: RayGrid, max_range: float) -> CastResult:
    """First hit of every ray of ``grid`` on ``segments`` within ``max_range`` (m), with pymunk:
    builds a ``PymunkScene`` and casts (see there). Same contract as ``cast``."""
    max_range = _check_range(max_range)
    if len(segments) == 0:
        return CastResult(np.full(grid.count, np.inf), np.full(grid.count, -1, dtype=np.int64))
    return PymunkScene(segments).cast(grid, max_range)


def cast(segments: Segments, grid: RayGrid, max_range: float, *, cull_back_faces: bool = True) -> CastResult:
    """First hit of every ray of ``grid`` on ``segments`` within ``max_range`` (m), in one call of
    ``cast_kernel`` (see the module docstring). ``cull_back_faces`` assumes the segments are edges of
    counter-clockwise convex polygons not containing the origin; pass ``False`` for loose segments."""
    max_range = _check_range(max_range)
    ranges, owners = cast_kernel(
        np.ascontiguousarray(segments.a, dtype=float), np.ascontiguousarray(segments.b, dtype=float),
        np.ascontiguousarray(segments.owner, dtype=np.int64), math.remainder(grid.start, TWO_PI),
        float(grid.resolution), grid.cos, grid.sin, bool(grid.is_full_circle), max_range, bool(cull_back_faces),
    )
    return CastResult(ranges, owners)


def _warm_up_cast() -> None:
    """Compile (or load) this module's kernels (registered with ``tracker.warmup`` by ``sim.sensors``)."""
    square = Segments.from_polygons(np.array([[5.0, -1.0], [7.0, -1.0], [7.0, 1.0], [5.0, 1.0]]), np.array([0, 4]),
                                    np.array([0]))
    cast(square, RayGrid.full_circle(math.radians(1.0)), 50.0)
    cast(square, RayGrid.fan(0.0, 0.5, math.radians(1.0)), 50.0)


#: The casters by name (``LidarConfig.caster``): "numpy" is ``cast`` (the compiled caster, the
#: default), "pymunk" the oracle.
CASTERS = {"numpy": cast, "pymunk": cast_pymunk}


# -- the returns of a cast ------------------------------------------------------------------------
class ReturnSettings(Protocol):
    """What ``ray_returns`` reads of a lidar configuration (m; a probability)."""

    @property
    def dropout_probability(self) -> float: ...

    @property
    def min_range(self) -> float: ...

    @property
    def range_noise_std(self) -> float: ...


def ray_returns(hit: np.ndarray, true_range: np.ndarray, owner: np.ndarray, vehicle_ids: np.ndarray,
                config: ReturnSettings, rng: np.random.Generator) -> tuple[np.ndarray, ...]:
    """The returns of one cast of ``R`` rays (``hit``, ``true_range`` m, ``owner`` per ray: owners
    ``0 .. V-1`` the vehicles ``vehicle_ids``, ``V + j`` roadside object ``j``, -1 none or the ground):
    two draws per ray (a normal, then a uniform), whatever the scene; a ray that hits returns unless it
    drops out (``dropout_probability``) or is nearer than ``min_range``, at the true range plus
    Gaussian noise (``range_noise_std``). Returns the returning rays' indices, their measured ranges,
    ``vehicle_id`` (-1 unless a vehicle) and ``roadside_index`` (-1 unless a roadside object).
    ``config`` is any lidar configuration with those three fields (``ReturnSettings``: the 2-D
    ``sim.sensors.lidar.LidarConfig`` or the ``sim.sensors.lidar3d.Lidar3DConfig``)."""
    count = len(hit)
    noise = rng.standard_normal(count)
    dropped = rng.random(count) < config.dropout_probability
    idx = np.flatnonzero(hit & ~dropped & (true_range >= config.min_range))
    measured = true_range[idx] + config.range_noise_std * noise[idx]
    ids = np.asarray(vehicle_ids, dtype=np.int64).reshape(-1)
    own = owner[idx]
    vehicles = ids.shape[0]
    is_vehicle = (own >= 0) & (own < vehicles)
    vehicle_id = np.full(idx.size, -1, dtype=np.int64)
    vehicle_id[is_vehicle] = ids[own[is_vehicle]]
    return idx, measured, vehicle_id, np.where(own >= vehicles, own - vehicles, -1).astype(np.int64)
