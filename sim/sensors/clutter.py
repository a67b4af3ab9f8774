"""Roadside clutter: static objects beside the road that the lidar and radar see (and that occlude).

They exist to exercise the tracker's road-bound filter: every object lies wholly outside the road
bounds. Six kinds, each a convex counter-clockwise polygon in G:

- ``"post"``: guard-rail posts, small squares at a fixed spacing along a side of the road;
- ``"tree"``: octagons (circle-like trunks) scattered at random along both sides;
- ``"parked_car"``: rectangles roughly aligned with the road, scattered along both sides;
- ``"wall"``: a noise barrier or building front along a side, a chain of ``EDGE_SEGMENT`` long quads;
- ``"hedge"``: vegetation along a side, a chain of ``HEDGE_SEGMENT`` long quads whose road-facing
  side steps in and out at random (a hedge's ragged face);
- ``"curb"``: a kerb along a side, its face on the road's edge, a chain of ``EDGE_SEGMENT`` long quads.

Walls, hedges and curbs are off by default (``ClutterConfig.wall_sides`` ...). Curbs are lower than
the 2-D lidar's scan plane and the radar's beam (``FLAT_SCENE_MIN_HEIGHT``): only the 3-D lidar sees
them (``RoadsideObjects.flat_scene``).

``generate_roadside(road, config, rng)`` needs only a small road interface (``tracker.road.Road``
provides it): ``length`` (m), ``closed`` (bool), ``to_cartesian(s, n) -> (N, 2)`` (m, G),
``heading(s) -> (N,)`` (rad), and the bounds ``left_edge``, ``right_edge`` (lateral offsets ``n`` of
the road bounds, m, ``n`` positive to the left; floats, or callables of ``s``); a road with ``edges(s)``
(a ``tracker.Road``, whose lanes may begin and end) places the objects beside its edges at each ``s``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from sim.sensors.raycast import Segments
from sim.world.truth import rectangle_corners

KINDS = ("post", "tree", "parked_car", "wall", "hedge", "curb")
#: Height (m) of each kind above the ground, for the 3-D lidar (``sim.sensors.lidar3d``): a guard-rail
#: post 1.0 m, a tree (its trunk's octagon, crown not modelled) 6.0 m, a parked car 1.5 m, a noise
#: barrier 3.0 m, a hedge 1.6 m, a kerb 0.15 m (urban kerbs are 0.10-0.20 m).
KIND_HEIGHTS = {"post": 1.0, "tree": 6.0, "parked_car": 1.5, "wall": 3.0, "hedge": 1.6, "curb": 0.15}
#: Objects lower than this (m) are under the 2-D lidar's scan plane and the radar's beam: only the
#: 3-D lidar sees them (curbs).
FLAT_SCENE_MIN_HEIGHT = 0.3
#: Length (m) of one quad of a wall's or curb's chain (short enough that a quad on a 50 m radius
#: curve bends from its chord by 1 cm).
EDGE_SEGMENT = 2.0
#: Length (m) of one quad of a hedge's chain, each with its own depth of face.
HEDGE_SEGMENT = 1.0
SIDES = ("left", "right")
#: The kinds that line the road's edge (scored as road-edge returns: ``sim.evaluation.runner.CloudScore``).
EDGE_KINDS = ("wall", "hedge", "curb")


class RoadLike(Protocol):
    """What the clutter generator needs of a road (``tracker.road.Road`` satisfies it)."""

    length: float
    closed: bool
    left_edge: Any
    right_edge: Any

    def to_cartesian(self, s: np.ndarray, n: np.ndarray) -> np.ndarray: ...

    def heading(self, s: np.ndarray) -> np.ndarray: ...


@dataclass(frozen=True, eq=False)
class RoadsideObjects:
    """``K`` static convex polygons in G. Polygon ``k`` has the vertices
    ``vertices[offsets[k]:offsets[k + 1]]`` (m, counter-clockwise), kind ``kind[k]`` (one of
    ``KINDS``) and centre ``centre[k]`` (m). ``radius[k]`` is the largest centre-to-vertex distance
    (m). ``segments`` holds all edges with owner = object index. Build with ``from_polygons``."""

    kind: np.ndarray
    centre: np.ndarray
    vertices: np.ndarray
    offsets: np.ndarray
    radius: np.ndarray = field(init=False)
    segments: Segments = field(init=False, repr=False)

    def __post_init__(self) -> None:
        kind = np.asarray(self.kind, dtype=object).reshape(-1)
        count = kind.shape[0]
        centre = np.asarray(self.centre, dtype=float).reshape(-1, 2)
        vertices = np.asarray(self.vertices, dtype=float).reshape(-1, 2)
        offsets = np.asarray(self.offsets, dtype=np.int64).reshape(-1)
        if centre.shape[0] != count or offsets.shape[0] != count + 1:
            raise ValueError(
                f"RoadsideObjects: {count} kinds, {centre.shape[0]} centres and {offsets.shape[0]} offsets "
                f"(need kinds + 1)"
            )
        if count and (offsets[0] != 0 or offsets[-1] != vertices.shape[0] or np.any(np.diff(offsets) < 3)):
            raise ValueError(
                "RoadsideObjects: offsets must start at 0, end at the vertex count and give >= 3 vertices per polygon"
            )
        if not np.all(np.isfinite(vertices)) or not np.all(np.isfinite(centre)):
            raise ValueError("RoadsideObjects: vertices and centres must be finite")
        unknown = sorted(set(kind.tolist()) - set(KINDS))
        if unknown:
            raise ValueError(f"RoadsideObjects: unknown kind(s) {unknown}; known: {KINDS}")
        sizes = np.diff(offsets)
        owner = np.repeat(np.arange(count), sizes)
        dist = np.hypot(*(vertices - centre[owner]).T) if count else np.zeros(0)
        radius = np.zeros(count)
        if count:
            np.maximum.at(radius, owner, dist)
        segments = Segments.from_polygons(vertices, offsets, np.arange(count))
        ex, ey = (segments.b - segments.a).T
        # every polygon must run counter-clockwise: the edges turn left around the centre
        rel = segments.a - centre[segments.owner]
        if count and np.any(rel[:, 0] * ey - rel[:, 1] * ex <= 0.0):
            raise ValueError("RoadsideObjects: polygons must be convex, counter-clockwise and contain their centre")
        for name, value in (("kind", kind), ("centre", centre), ("vertices", vertices), ("offsets", offsets)):
            object.__setattr__(self, name, value)
        object.__setattr__(self, "radius", radius)
        object.__setattr__(self, "segments", segments)
        # per edge, for fast per-scan range culling and transforms: [ax, ay, bx, by], midpoint and half-length
        edges = np.ascontiguousarray(np.concatenate([segments.a, segments.b], axis=1))
        object.__setattr__(self, "_edges", edges)
        object.__setattr__(self, "_edge_mid", 0.5 * (segments.a + segments.b))
        object.__setattr__(self, "_edge_half", 0.5 * np.hypot(ex, ey))

    def __len__(self) -> int:
        return int(self.kind.shape[0])

    @property
    def height(self) -> np.ndarray:
        """Height (m) of each object above the ground (``KIND_HEIGHTS`` by kind), (K,)."""
        return np.array([KIND_HEIGHTS[k] for k in self.kind.tolist()], dtype=float)

    @classmethod
    def empty(cls) -> RoadsideObjects:
        """No objects."""
        return cls(np.zeros(0, dtype=object), np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(1, dtype=np.int64))

    @classmethod
    def from_polygons(cls, kinds: Sequence[str], polygons: Sequence[np.ndarray]) -> RoadsideObjects:
        """Objects from a kind and a ``(V, 2)`` convex polygon (m, G) each; the polygons are turned
        counter-clockwise if needed and their centre is the vertex mean."""
        if len(kinds) != len(polygons):
            raise ValueError(f"from_polygons: {len(kinds)} kinds but {len(polygons)} polygons")
        if not polygons:
            return cls.empty()
        fixed = []
        for i, poly in enumerate(polygons):
            p = np.asarray(poly, dtype=float)
            if p.ndim != 2 or p.shape[1] != 2 or p.shape[0] < 3:
                raise ValueError(f"from_polygons: polygon {i} must have shape (V >= 3, 2); got {p.shape}")
            area2 = np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1])
            fixed.append(p if area2 > 0 else p[::-1])
        sizes = [len(p) for p in fixed]
        return cls(
            np.asarray(kinds, dtype=object),
            np.array([p.mean(axis=0) for p in fixed]),
            np.concatenate(fixed),
            np.concatenate([[0], np.cumsum(sizes)]),
        )

    def flat_scene(self) -> RoadsideObjects:
        """The objects the 2-D lidar and the radar see: those at least ``FLAT_SCENE_MIN_HEIGHT`` tall.
        ``generate_roadside`` makes the low ones (curbs) last, so there an object keeps its index."""
        tall = self.height >= FLAT_SCENE_MIN_HEIGHT
        return self if tall.all() else self.select(tall)

    def polygon(self, k: int) -> np.ndarray:
        """Vertices (V, 2) of object ``k`` (m, G, counter-clockwise)."""
        return self.vertices[self.offsets[k] : self.offsets[k + 1]]

    def select(self, index: np.ndarray | Sequence[int]) -> RoadsideObjects:
        """The objects ``index`` (indices or a boolean mask), in that order."""
        idx = np.arange(len(self))[np.asarray(index)]
        if idx.size == 0:
            return RoadsideObjects.empty()
        return RoadsideObjects.from_polygons(self.kind[idx].tolist(), [self.polygon(int(k)) for k in idx])

    @classmethod
    def concatenate(cls, parts: Sequence[RoadsideObjects]) -> RoadsideObjects:
        """All objects of ``parts``, in order."""
        parts = [p for p in parts if len(p)]
        if not parts:
            return cls.empty()
        shift = np.cumsum([0] + [p.vertices.shape[0] for p in parts[:-1]])
        return cls(
            np.concatenate([p.kind for p in parts]),
            np.concatenate([p.centre for p in parts]),
            np.concatenate([p.vertices for p in parts]),
            np.concatenate([[0]] + [p.offsets[1:] + s for p, s in zip(parts, shift)]),
        )


@dataclass(frozen=True)
class ClutterConfig:
    """How roadside clutter is generated (lengths in m, densities per 100 m of road per side).

    Offsets are measured outward from the road bound (``left_edge`` on the left, ``right_edge`` on
    the right) to the object's centre line; no vertex comes closer to the bound than ``clearance``.

    - guard-rail posts: squares of side ``post_size`` (0.2 m) every ``post_spacing`` (10 m; 0 turns
      them off) on the sides ``guardrail_sides`` (both), centred ``post_offset`` (1.0 m) outside;
    - trees: ``tree_density`` (2 per 100 m per side, Poisson) octagons of circumradius uniform in
      ``tree_radius`` (0.15 .. 0.4 m), centred uniformly ``tree_offset`` (4 .. 12 m) outside;
    - parked cars: ``parked_car_density`` (1 per 100 m per side, Poisson) rectangles of
      ``parked_car_size`` (4.5 x 1.8 m), centred uniformly ``parked_car_offset`` (2.5 .. 3.5 m)
      outside, heading the road's heading (either way) plus normal noise ``parked_car_yaw_std_deg``
      (3 deg, truncated at 3 sigma);
    - walls: on the sides ``wall_sides`` (none), the whole road's length, ``wall_thickness`` (0.3 m)
      thick, their road-facing side ``wall_offset`` (1.5 m) outside;
    - hedges: on the sides ``hedge_sides`` (none), ``hedge_depth`` (1.0 m) deep, their road-facing
      side ``hedge_offset`` (2.0 m) outside, stepping in and out by up to ``hedge_roughness`` (0.3 m)
      per ``HEDGE_SEGMENT``;
    - curbs: on the sides ``curb_sides`` (none), ``curb_width`` (0.15 m) wide, their face on the
      edge (the clearance does not apply to them).
    """

    post_spacing: float = 10.0
    post_size: float = 0.2
    post_offset: float = 1.0
    guardrail_sides: tuple[str, ...] = SIDES
    tree_density: float = 2.0
    tree_radius: tuple[float, float] = (0.15, 0.4)
    tree_offset: tuple[float, float] = (4.0, 12.0)
    parked_car_density: float = 1.0
    parked_car_size: tuple[float, float] = (4.5, 1.8)
    parked_car_offset: tuple[float, float] = (2.5, 3.5)
    parked_car_yaw_std_deg: float = 3.0
    clearance: float = 0.3
    wall_sides: tuple[str, ...] = ()
    wall_offset: float = 1.5
    wall_thickness: float = 0.3
    hedge_sides: tuple[str, ...] = ()
    hedge_offset: float = 2.0
    hedge_depth: float = 1.0
    hedge_roughness: float = 0.3
    curb_sides: tuple[str, ...] = ()
    curb_width: float = 0.15

    def __post_init__(self) -> None:
        def nonneg(name: str) -> None:
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0.0):
                raise ValueError(f"ClutterConfig.{name} must be a finite number >= 0; got {value!r}")

        for name in ("post_spacing", "tree_density", "parked_car_density", "parked_car_yaw_std_deg", "clearance"):
            nonneg(name)
        for name in ("post_size", "post_offset"):
            nonneg(name)
            if getattr(self, name) <= 0.0:
                raise ValueError(f"ClutterConfig.{name} must be > 0; got {getattr(self, name)!r}")
        for name in ("tree_radius", "tree_offset", "parked_car_size", "parked_car_offset"):
            pair = getattr(self, name)
            if (
                len(pair) != 2
                or not all(isinstance(v, (int, float)) and math.isfinite(v) and v > 0.0 for v in pair)
                or (name != "parked_car_size" and pair[0] > pair[1])
            ):
                raise ValueError(f"ClutterConfig.{name} must be two positive numbers (low <= high); got {pair!r}")
        for name in ("guardrail_sides", "wall_sides", "hedge_sides", "curb_sides"):
            sides = getattr(self, name)
            if isinstance(sides, str):
                raise ValueError(f"ClutterConfig.{name} must be a list of sides drawn from {SIDES}; got {sides!r}")
            bad = [s for s in sides if s not in SIDES]
            if bad:
                raise ValueError(f"ClutterConfig.{name} must be drawn from {SIDES}; got {bad}")
            object.__setattr__(self, name, tuple(sides))
        for name in ("wall_thickness", "hedge_depth", "curb_width"):
            nonneg(name)
            if getattr(self, name) <= 0.0:
                raise ValueError(f"ClutterConfig.{name} must be > 0; got {getattr(self, name)!r}")
        nonneg("hedge_roughness")
        checks = [
            ("post_offset", self.post_offset - 0.5 * self.post_size),
            ("tree_offset", self.tree_offset[0] - self.tree_radius[1]),
            ("parked_car_offset", self.parked_car_offset[0] - self.parked_car_half_extent),
            ("wall_offset", self.wall_offset),
            ("hedge_offset", self.hedge_offset - self.hedge_roughness),
        ]
        for name, gap in checks:
            if gap < self.clearance:
                raise ValueError(
                    f"ClutterConfig.{name} puts objects within {gap:.3f} m of the road bound; "
                    f"the clearance is {self.clearance} m: increase the offset"
                )


    @property
    def parked_car_half_extent(self) -> float:
        """Largest lateral half-extent (m) of a parked car, across the road, at the largest yaw
        deviation (3 sigma; the deviation is truncated there)."""
        dev = math.radians(3.0 * self.parked_car_yaw_std_deg)
        car_l, car_w = self.parked_car_size
        if dev >= math.atan2(car_l, car_w):  # the diagonal turns across the road
            return 0.5 * math.hypot(car_l, car_w)
        return 0.5 * (car_l * math.sin(dev) + car_w * math.cos(dev))


def _edge(road: RoadLike, name: str, s: np.ndarray) -> np.ndarray:
    value = getattr(road, name)
    out = np.asarray(value(s) if callable(value) else value, dtype=float)
    return np.broadcast_to(out, s.shape).astype(float)


def _check_road(road: Any) -> float:
    for name in ("length", "closed", "left_edge", "right_edge", "to_cartesian", "heading"):
        if not hasattr(road, name):
            raise ValueError(f"generate_roadside: the road has no attribute {name!r} (see RoadLike)")
    length = float(road.length)
    if not (math.isfinite(length) and length > 0.0):
        raise ValueError(f"generate_roadside: road.length must be a positive number of metres; got {road.length!r}")
    return length


def _place(road: RoadLike, s: np.ndarray, side: np.ndarray, offset: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centres (N, 2) and headings (N,) of objects at arc length ``s``, ``offset`` m outside the bound
    on ``side`` (+1 left, -1 right)."""
    if callable(getattr(road, "edges", None)):  # a tracker.Road: its edges at s (lanes may begin and end)
        right, left = (np.asarray(e, dtype=float) for e in road.edges(s))
    else:
        right, left = _edge(road, "right_edge", s), _edge(road, "left_edge", s)
    n = np.where(side > 0, left + offset, right - offset)
    centre = np.asarray(road.to_cartesian(s, n), dtype=float).reshape(-1, 2)
    heading = np.asarray(road.heading(s), dtype=float).reshape(-1)
    return centre, heading


def _edge_quads(road: RoadLike, ends: np.ndarray, side: float, near: np.ndarray, depth: float) -> np.ndarray:
    """Quads (N, 4, 2) along a side (+1 left, -1 right) between consecutive arc lengths ``ends``
    (N + 1,): quad ``i`` spans ``ends[i] .. ends[i + 1]`` along the road and ``near[i] .. near[i] +
    depth`` m outward from the edge, the edge taken at each end (lanes may begin and end)."""
    s = np.concatenate([ends[:-1], ends[1:]])
    sides = np.full(s.shape, side)
    out = np.concatenate([near, near])
    inner, _ = _place(road, s, sides, out)
    outer, _ = _place(road, s, sides, out + depth)
    count = len(ends) - 1
    a0, a1, b0, b1 = inner[:count], inner[count:], outer[:count], outer[count:]
    return np.stack([a0, a1, b1, b0], axis=1)  # turned counter-clockwise by from_polygons


def _octagons(centre: np.ndarray, radius: np.ndarray, phase: np.ndarray) -> np.ndarray:
    """Counter-clockwise regular octagons (N, 8, 2) of circumradius ``radius``."""
    ang = phase[:, None] + np.arange(8)[None, :] * (np.pi / 4.0)
    return np.stack(
        [centre[:, None, 0] + radius[:, None] * np.cos(ang), centre[:, None, 1] + radius[:, None] * np.sin(ang)],
        axis=-1,
    )


def generate_roadside(
    road: RoadLike, config: ClutterConfig | None = None, *, rng: np.random.Generator
) -> RoadsideObjects:
    """Roadside clutter along ``road`` (see ``RoadLike``), drawn from ``rng``: guard-rail posts,
    trees, parked cars, walls, hedges and curbs outside the road bounds as described by ``config``
    (``ClutterConfig()`` by default). Objects are ordered posts, trees, parked cars, walls, hedges,
    curbs (each chain from the left side first, along the road); positions are in G (m). On a curved
    road the offsets must stay well below the radius of curvature (objects are placed by offset
    along the normal)."""
    config = ClutterConfig() if config is None else config
    if not isinstance(config, ClutterConfig):
        raise ValueError(f"generate_roadside: config must be a ClutterConfig; got {type(config).__name__}")
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"generate_roadside: rng must be a numpy.random.Generator; got {type(rng).__name__}")
    length = _check_road(road)
    parts: list[tuple[str, np.ndarray]] = []  # (kind, polygons (N, V, 2))

    if config.post_spacing > 0.0 and config.guardrail_sides:
        s_posts = np.arange(0.0, length, config.post_spacing)
        if not road.closed:
            s_posts = s_posts[s_posts <= length]
        for side_name in config.guardrail_sides:
            side = np.full(s_posts.shape, 1.0 if side_name == "left" else -1.0)
            centre, heading = _place(road, s_posts, side, np.full(s_posts.shape, config.post_offset))
            size = np.full(s_posts.shape, config.post_size)
            parts.append(("post", rectangle_corners(centre, heading, size, size)))

    for kind, density in (("tree", config.tree_density), ("parked_car", config.parked_car_density)):
        counts = rng.poisson(density * length / 100.0, size=2)
        total = int(counts.sum())
        s = rng.uniform(0.0, length, total)
        side = np.repeat([1.0, -1.0], counts)
        if kind == "tree":
            offset = rng.uniform(*config.tree_offset, total)
            radius = rng.uniform(*config.tree_radius, total)
            phase = rng.uniform(0.0, np.pi / 4.0, total)
            centre, _ = _place(road, s, side, offset)
            polys = _octagons(centre, radius, phase)
        else:
            offset = rng.uniform(*config.parked_car_offset, total)
            flip = np.where(rng.random(total) < 0.5, 0.0, np.pi)
            sigma = np.radians(config.parked_car_yaw_std_deg)
            dyaw = np.clip(sigma * rng.standard_normal(total), -3.0 * sigma, 3.0 * sigma)
            centre, heading = _place(road, s, side, offset)
            car_l, car_w = config.parked_car_size
            polys = rectangle_corners(centre, heading + flip + dyaw, np.full(total, car_l), np.full(total, car_w))
        parts.append((kind, polys))

    # the sides' chains, low kinds last (``RoadsideObjects.flat_scene`` keeps the indices)
    for kind, sides, inner, depth, step in (
        ("wall", config.wall_sides, config.wall_offset, config.wall_thickness, EDGE_SEGMENT),
        ("hedge", config.hedge_sides, config.hedge_offset, config.hedge_depth, HEDGE_SEGMENT),
        ("curb", config.curb_sides, 0.0, config.curb_width, EDGE_SEGMENT),
    ):
        for side_name in sides:
            ends = np.arange(0.0, length + 1e-9, step)
            if ends[-1] < length - 1e-9:
                ends = np.append(ends, length)
            count = len(ends) - 1
            near = np.full(count, inner)
            if kind == "hedge" and config.hedge_roughness > 0.0:
                near = near + rng.uniform(-config.hedge_roughness, config.hedge_roughness, count)
            parts.append((kind, _edge_quads(road, ends, 1.0 if side_name == "left" else -1.0, near, depth)))

    kinds = [kind for kind, polys in parts for _ in range(polys.shape[0])]
    polygons = [p for _, polys in parts for p in polys]
    return RoadsideObjects.from_polygons(kinds, polygons)
