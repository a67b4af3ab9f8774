"""2-D ray casting against line segments: a vectorised numpy caster and a pymunk oracle.

Rays start at the origin of the caster's frame and fan out at bearings ``start + k * resolution``
(``RayGrid``). The scene is a set of ``Segments`` (edges of convex polygons, in the same frame, m),
each with an integer ``owner`` (the object it belongs to). Both casters return, per ray, the range
(m) to the first hit (``inf`` when the ray hits nothing within ``max_range``) and the hit owner (-1).

``cast_numpy`` (the default, see ``sim/benchmarks/sensors.py`` for the numbers):

1. cull: drop edges facing away from the origin (edges of counter-clockwise polygons whose
   ``cross(a, b) >= 0``; the first hit on a closed convex polygon seen from outside is always on an
   edge facing the origin). Range culling is left to the caller (``sim.sensors.scene`` drops objects
   wholly out of range); edges beyond ``max_range`` only cost a few rejected pairs;
2. angular broad phase: each edge subtends the bearing interval between its end points (less than pi
   for an edge not through the origin); the rays inside it are a contiguous index range of the grid,
   taken modulo the ray count on a full circle; on a fan, the interval and its copy one turn lower
   are each clipped to the fan. One extra ray on each side guards rounding;
3. narrow phase, batched over all (ray, edge) pairs: with ``d`` the ray direction,
   ``ca = d x a`` and ``cb = d x b``, the ray's line crosses the edge iff ``ca * cb <= 0``, at range
   ``t = (a x b) / (cb - ca)``; a hit needs ``0 < t <= max_range``;
4. per ray, the smallest ``t`` wins (occlusion); ``np.minimum.at`` reduces the pairs.

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

from sim.sensors.cast_kernel import cast_kernel, visible_kernel
from tracker import jit as compiled

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


def cast_numpy(segments: Segments, grid: RayGrid, max_range: float, *, cull_back_faces: bool = True) -> CastResult:
    """First hit of every ray of ``grid`` on ``segments`` within ``max_range`` (m), vectorised
    (see the module docstring). ``cull_back_faces`` assumes the segments are edges of
    counter-clockwise convex polygons not containing the origin; pass ``False`` for loose segments."""
    max_range = _check_range(max_range)
    count = grid.count
    ranges = np.full(count, np.inf)
    owners = np.full(count, -1, dtype=np.int64)
    if len(segments) == 0:
        return CastResult(ranges, owners)
    a, b = segments.a, segments.b
    cr = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]  # a x b: < 0 when the edge faces the origin (CCW polygon)
    idx = np.flatnonzero(cr < 0.0 if cull_back_faces else cr != 0.0)  # cr == 0: edge on a line through the origin
    if idx.size == 0:
        return CastResult(ranges, owners)
    a, b, cr = a[idx], b[idx], cr[idx]
    ax, ay, bx, by = a[:, 0], a[:, 1], b[:, 0], b[:, 1]
    # angular broad phase: the edge subtends [lo, hi] (rad, relative to the grid start), < pi wide;
    # with cr < 0 the end b is clockwise of a, so the interval runs from b to a
    start = math.remainder(grid.start, TWO_PI)  # in [-pi, pi]: the same rays modulo a turn
    rel_a = np.arctan2(ay, ax) - start  # in (-2 pi, 2 pi]
    rel_b = np.arctan2(by, bx) - start
    if cull_back_faces:
        lo, hi = rel_b, rel_a
    else:
        ccw = cr > 0.0
        lo, hi = np.where(ccw, rel_a, rel_b), np.where(ccw, rel_b, rel_a)
    hi[hi < lo] += TWO_PI
    inv_res = 1.0 / grid.resolution
    if grid.is_full_circle:
        # lo + 2 pi > 0, so truncation is floor; the extra turn (count rays) goes with the modulo,
        # and so does the shift of the start by whole turns. One extra ray each side guards rounding.
        k0 = ((lo + TWO_PI) * inv_res).astype(np.int64)
        k1 = ((hi + TWO_PI) * inv_res).astype(np.int64) + 1
        owner_of_range = np.arange(idx.size)
    else:  # a fan: the interval as is and one turn lower, each clipped to the fan's rays
        span = hi - lo
        lo = np.mod(lo, TWO_PI)
        lo = np.concatenate([lo, lo - TWO_PI])
        hi = lo + np.concatenate([span, span])
        k0 = np.maximum(np.floor(lo * inv_res), 0.0).astype(np.int64)
        k1 = np.minimum(np.floor(hi * inv_res) + 1.0, count - 1.0).astype(np.int64)
        owner_of_range = np.tile(np.arange(idx.size), 2)
    sizes = np.maximum(k1 - k0 + 1, 0)
    seg = np.repeat(owner_of_range, sizes)
    if seg.size == 0:
        return CastResult(ranges, owners)
    ray = np.arange(seg.size) + np.repeat(k0 - (np.cumsum(sizes) - sizes), sizes)
    if grid.is_full_circle:
        ray %= count
    # narrow phase over all (ray, edge) pairs: the ray's line crosses the edge iff ca * cb <= 0
    dx, dy = grid.cos[ray], grid.sin[ray]
    sax, say, sbx, sby = ax[seg], ay[seg], bx[seg], by[seg]
    ca = dx * say - dy * sax
    cb = dx * sby - dy * sbx
    with np.errstate(divide="ignore", invalid="ignore"):
        t = cr[seg] / (cb - ca)
    t[~((ca * cb <= 0.0) & (t > 0.0) & (t <= max_range))] = np.inf
    # the nearest hit per ray wins
    np.minimum.at(ranges, ray, t)
    win = np.flatnonzero((t == ranges[ray]) & (t < np.inf))
    owners[ray[win]] = segments.owner[idx[seg[win]]]
    return CastResult(ranges, owners)


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
    builds a ``PymunkScene`` and casts (see there). Same contract as ``cast_numpy``."""
    max_range = _check_range(max_range)
    if len(segments) == 0:
        return CastResult(np.full(grid.count, np.inf), np.full(grid.count, -1, dtype=np.int64))
    return PymunkScene(segments).cast(grid, max_range)


def cast(segments: Segments, grid: RayGrid, max_range: float, *, cull_back_faces: bool = True) -> CastResult:
    """``cast_numpy``'s answer, from its compiled twin (``sim.sensors.cast_kernel``) when the compiled
    kernels are on (numba installed, ``EOT_NUMBA`` not ``0``; see ``tracker.compiled``), else from
    ``cast_numpy`` itself."""
    if not compiled.enabled():
        return cast_numpy(segments, grid, max_range, cull_back_faces=cull_back_faces)
    max_range = _check_range(max_range)
    ranges, owners = cast_kernel(
        np.ascontiguousarray(segments.a, dtype=float), np.ascontiguousarray(segments.b, dtype=float),
        np.ascontiguousarray(segments.owner, dtype=np.int64), math.remainder(grid.start, TWO_PI),
        float(grid.resolution), grid.cos, grid.sin, bool(grid.is_full_circle), max_range, bool(cull_back_faces),
    )
    return CastResult(ranges, owners)


def _warm_up_cast() -> None:
    square = Segments.from_polygons(np.array([[5.0, -1.0], [7.0, -1.0], [7.0, 1.0], [5.0, 1.0]]), np.array([0, 4]),
                                    np.array([0]))
    cast(square, RayGrid.full_circle(math.radians(1.0)), 50.0)
    fan = RayGrid.fan(0.0, 0.5, math.radians(1.0))
    cast(square, fan, 50.0)
    one = np.array([[6.0, 0.0]])
    visible_kernel(one, np.zeros(1), np.full(1, 4.5), np.full(1, 1.9), np.zeros((1, 4)) + [9.0, 1.0, 9.0, -1.0],
                   np.ones(1, dtype=np.int64), np.array([[9.0, 0.0]]), np.ones(1), 0.0, 0.0, 0.0, 50.0, 0.5,
                   math.remainder(fan.start, TWO_PI), fan.resolution, fan.cos, fan.sin)


from tracker.warmup import register_warm_up  # noqa: E402

register_warm_up(_warm_up_cast)

#: The casters by name (``LidarConfig.caster``): "numpy" is the vectorised caster (``cast``: compiled
#: when the kernels are on), "pymunk" the oracle.
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
    ``sim.sensors.lidar.LidarConfig`` or the ``sim.sensors.lidar3d.Vlp16Config``)."""
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
