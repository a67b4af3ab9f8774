"""The ground surface: its height ``z`` (m, up) over the global x-y plane G.

A ``Ground`` answers, exactly, ``height(xy)`` ((N, 2) m in G -> (N,) m) and ``gradient(xy)``
((N, 2) -> (N, 2) = (dz/dx, dz/dy)), and hands ray casters (``sim.sensors.lidar3d.cast_3d``) a fast
``GroundSurface`` for the disc a sensor can see (``surface(centre, radius)``).

- ``FlatGround``: ``z = 0`` everywhere. Its surface is flagged flat, so casters intersect rays with it
  in closed form (exact): the fast path.
- ``RoadGround(road, grade, bank)``: the road surface rises ``grade`` m per m of arc length ``s``
  (along the driving direction) and ``bank`` m per m of lateral offset ``n`` (positive to the left)::

      h(s, n) = grade * s + bank * clip(n, right_edge, left_edge),   (s, n) = road.to_frenet(xy)

  Beside the road the terrain is flat across the road (it keeps the height of the nearer road edge)
  and still rises with ``grade`` along it. Beyond the ends of an open road ``s`` continues along the
  end tangents (``to_frenet`` projects there), and so does the grade. The gradient is
  ``grade * t / (1 - kappa n) + bank * [right_edge < n < left_edge] * nu`` with ``t`` the road's unit
  tangent, ``nu`` its left normal and ``kappa`` its curvature at ``s``.

The casting surface of ``RoadGround`` (``RoadGroundGrid``, built lazily once) does not call
``to_frenet`` per ray step: it samples ``s`` and ``n`` on a regular x-y grid of ``cell`` m (1 m by
default) over the road's bounding box plus ``margin`` (110 m by default, the lidar's range plus
slack), interpolates both bilinearly, and applies the clip afterwards::

    h~(x, y) = grade * s~(x, y) + bank * clip(n~(x, y), right_edge, left_edge)

So the kinks of ``h`` at the road edges are reproduced exactly (no smoothing over a cell), and on a
straight road ``s~`` and ``n~`` are exact (bilinear interpolation reproduces affine functions): the
surface equals ``h`` to rounding. On a curved road, bilinear interpolation of a smooth ``f`` errs by
at most ``cell^2 / 8 * (max |f_xx| + max |f_yy|) <= cell^2 / 4 * max ||Hess f||``, with
``||Hess n|| ~ |kappa| / (1 - kappa n)`` and ``||Hess s|| ~ 2 |kappa| / (1 - kappa n)^2``::

    |h~ - h| <~ cell^2 / 4 * (|bank| + 2 |grade| / (1 - kappa n)) * |kappa| / (1 - kappa n)

e.g. <= 0.1 mm at ``cell = 1 m``, radius 300 m, grade 0.04, bank 0.03 within 100 m of the road
(measured: 0.04 mm on ``sim.benchmarks.lidar3d``'s road), <= 1 mm at radius 150 m out to
``1 - kappa n = 0.33`` (``tests/test_lidar3d.py``): far below the lidar's 3 cm range noise. One
exception: at the ends of a curved open road ``to_frenet`` switches from the curve to its end
tangent, so ``s`` has a kink there, which the grid smooths over a cell: up to about
``|grade| * cell * |kappa n| / (4 (1 - kappa n))`` (5 mm in the test, 64 m inside a 150 m bend).
Points off the grid take the height of the nearest grid point (the grid is clamped), which only
matters ``margin`` m away from the road. Where ``to_frenet``'s nearest projection jumps (the medial
axis inside a tight bend, far from the road on ordinary roads) ``s`` jumps and so does ``h``; the
grid then holds a steep ramp across one cell instead of a cliff.

Casters also need to know how fast the surface can rise along a ray (``GroundSurface.rise``). The
grid stores, per block of ``BOUND_BLOCK`` x ``BOUND_BLOCK`` cells, bounds of the interpolated
gradient's components (per bilinear cell, ``dh~/dx`` lies between its two x-edge differences over
``cell``, likewise ``dh~/dy``; the clip only switches the bank term off, so both pieces are
covered); a scan's ``rise`` takes, per azimuth sector (``RISE_SECTORS``), the largest directional
derivative over the blocks that the sector's wedge meets within the sensor's range.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

#: Largest allowed |grade| and |bank| of a ``RoadGround`` (m per m; 15 % is a very steep road).
MAX_SLOPE = 0.15
#: Default cell size (m) of a ``RoadGround``'s casting grid.
GRID_CELL = 1.0
#: Default margin (m) of the casting grid around the road's bounding box (the lidar range + slack).
GRID_MARGIN = 110.0
#: Most grid nodes of one casting grid (1 km^2 at 1 m: 64 MB of coefficients, ~200 MB while it is
#: built); beyond, the cell grows, and the interpolation error with its square.
GRID_MAX_NODES = 1_000_000
#: Cells per side of the blocks over which the casting grid's gradient bounds are pre-reduced.
BOUND_BLOCK = 16
#: Azimuth sectors of a casting grid's rise bounds (``RoadGroundGrid.rise_bound``).
RISE_SECTORS = 360
_SECTOR_UX = np.cos(-math.pi + (np.arange(RISE_SECTORS) + 0.5) * (2.0 * math.pi / RISE_SECTORS))
_SECTOR_UY = np.sin(-math.pi + (np.arange(RISE_SECTORS) + 0.5) * (2.0 * math.pi / RISE_SECTORS))
#: Road sampling step (m) used to find the road's bounding box.
BBOX_STEP = 2.0


def _as_xy(xy: Any, owner: str) -> np.ndarray:
    pts = np.asarray(xy, dtype=float)
    if pts.ndim == 1 and pts.shape == (2,):
        pts = pts[None, :]
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ValueError(f"{owner}: xy must have shape (N, 2); got {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise ValueError(f"{owner}: xy must be finite")
    return pts


def _no_rise(ux: np.ndarray, uy: np.ndarray) -> np.ndarray:
    return np.zeros(np.shape(ux))


def _zeros(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    return np.zeros(np.shape(x))


@dataclass(frozen=True)
class GroundSurface:
    """What a ray caster needs of the ground around a sensor (see the module docstring).

    - ``height(x, y) -> z``: heights (m) at the points of the flat arrays ``x``, ``y`` (m, G);
    - ``rise(ux, uy) -> r``: per horizontal unit direction ``(ux, uy)`` (flat arrays) an upper bound
      ``r`` (m per m) of the height's rate of change along the horizontal ray from the centre in that
      direction, out to the radius the surface was made for (``h(c + u t') - h(c + u t) <= r (t' - t)``);
    - ``max_rise``: the largest value ``rise`` returns (rays climbing at least this steeply never
      meet the ground);
    - ``flat``: the constant height (m) when the ground is flat there (casters then intersect in
      closed form), else ``None``.
    """

    height: Callable[[np.ndarray, np.ndarray], np.ndarray]
    rise: Callable[[np.ndarray, np.ndarray], np.ndarray]
    max_rise: float
    flat: float | None = None


class Ground(ABC):
    """The ground surface (module docstring): exact ``height`` and ``gradient``, and ``surface`` for
    casters."""

    @abstractmethod
    def height(self, xy: np.ndarray) -> np.ndarray:
        """Height ``z`` (N,) in m of the points ``xy`` (N, 2) in G."""

    @abstractmethod
    def gradient(self, xy: np.ndarray) -> np.ndarray:
        """``(dz/dx, dz/dy)`` (N, 2) at the points ``xy`` (N, 2) in G."""

    @abstractmethod
    def surface(self, centre: tuple[float, float] | np.ndarray, radius: float) -> GroundSurface:
        """The casting surface valid within ``radius`` m of ``centre`` (x, y in G)."""


class FlatGround(Ground):
    """The plane ``z = 0`` (casters intersect it in closed form)."""

    def height(self, xy: np.ndarray) -> np.ndarray:
        return np.zeros(_as_xy(xy, "FlatGround.height").shape[0])

    def gradient(self, xy: np.ndarray) -> np.ndarray:
        return np.zeros((_as_xy(xy, "FlatGround.gradient").shape[0], 2))

    def surface(self, centre: tuple[float, float] | np.ndarray, radius: float) -> GroundSurface:
        return GroundSurface(height=_zeros, rise=_no_rise, max_rise=0.0, flat=0.0)

    def __repr__(self) -> str:
        return "FlatGround()"


class RoadGroundGrid:
    """The casting grid of a ``RoadGround`` (module docstring): ``s`` and ``n`` at the nodes
    ``origin + (i, j) * cell`` (m, G), ``i < shape[0]``, ``j < shape[1]``, stored per cell as
    bilinear coefficients (``coef``: ``g = grade s + bank n`` and, with a bank, ``n``), and per block
    of ``BOUND_BLOCK`` x ``BOUND_BLOCK`` cells bounds of the interpolated height's gradient
    (``gradient_bounds``: dz/dx min and max, dz/dy min and max)."""

    def __init__(self, ground: RoadGround, cell: float, margin: float, max_nodes: int) -> None:
        road = ground.road
        length = float(road.length)
        count = max(2, int(math.ceil(length / BBOX_STEP)) + 1)
        s = np.linspace(0.0, length, count)
        edges = np.concatenate(
            [
                np.asarray(road.to_cartesian(s, np.full(count, float(road.right_edge))), dtype=float).reshape(-1, 2),
                np.asarray(road.to_cartesian(s, np.full(count, float(road.left_edge))), dtype=float).reshape(-1, 2),
            ]
        )
        lo = edges.min(axis=0) - margin
        hi = edges.max(axis=0) + margin
        extent = hi - lo
        if (extent[0] / cell + 1.0) * (extent[1] / cell + 1.0) > max_nodes:
            cell = float(math.sqrt(extent[0] * extent[1] / max_nodes)) * 1.01
        shape = np.ceil(extent / cell).astype(int) + 1
        self.cell = float(cell)
        self.origin = lo
        self.shape = (int(shape[0]), int(shape[1]))
        nx, ny = self.shape
        gx, gy = np.meshgrid(lo[0] + cell * np.arange(nx), lo[1] + cell * np.arange(ny), indexing="ij")
        s_node, n_node = road.to_frenet(np.column_stack([gx.ravel(), gy.ravel()]))
        s_node = np.asarray(s_node, dtype=float).reshape(nx, ny)
        n_node = np.asarray(n_node, dtype=float).reshape(nx, ny)
        grade, bank = ground.grade, ground.bank
        # the linear part g = grade * s + bank * n; h~ = g~ - bank * (n~ - clip(n~)) (module docstring)
        g_node = grade * s_node + bank * n_node if grade != 0.0 else bank * n_node

        def coefficients(f: np.ndarray) -> list[np.ndarray]:
            f00, f10, f01, f11 = f[:-1, :-1], f[1:, :-1], f[:-1, 1:], f[1:, 1:]
            return [c.ravel() for c in (f00, f10 - f00, f01 - f00, f00 - f10 - f01 + f11)]

        columns = coefficients(g_node) + (coefficients(n_node) if bank != 0.0 else [])
        self.coef = np.ascontiguousarray(np.stack(columns, axis=1))  # (cells, 4 or 8)

        def component_bounds(f: np.ndarray) -> list[np.ndarray]:
            # in a bilinear cell df/dx runs between its bottom- and top-edge differences (linear in
            # wy), df/dy between its left- and right-edge differences
            dx = np.diff(f, axis=0) / cell  # (nx - 1, ny)
            dy = np.diff(f, axis=1) / cell  # (nx, ny - 1)
            x0, x1, y0, y1 = dx[:, :-1], dx[:, 1:], dy[:-1, :], dy[1:, :]
            return [np.minimum(x0, x1), np.maximum(x0, x1), np.minimum(y0, y1), np.maximum(y0, y1)]

        # grad h~ is grad g~ where the clip is idle and grade * grad s~ where it is active: the
        # per-cell bounds of the gradient's components cover both
        bounds = component_bounds(g_node)
        if bank != 0.0:
            along = component_bounds(grade * s_node) if grade != 0.0 else [np.zeros_like(b) for b in bounds]
            bounds = [np.minimum(bounds[0], along[0]), np.maximum(bounds[1], along[1]),
                      np.minimum(bounds[2], along[2]), np.maximum(bounds[3], along[3])]
        slack = 1e-9 * (max(float(np.max(np.abs(b))) for b in bounds) + 1.0)
        bounds = [bounds[0] - slack, bounds[1] + slack, bounds[2] - slack, bounds[3] + slack]
        # per block of BOUND_BLOCK x BOUND_BLOCK cells, so that a scan's window reduces a few hundred
        # blocks instead of ~10^5 cells (the blocks overhang the window: still a valid bound)
        bx, by = -(-(nx - 1) // BOUND_BLOCK), -(-(ny - 1) // BOUND_BLOCK)
        blocks = []
        for which, b in enumerate(bounds):
            fill = np.inf if which % 2 == 0 else -np.inf
            padded = np.full((bx * BOUND_BLOCK, by * BOUND_BLOCK), fill)
            padded[: nx - 1, : ny - 1] = b
            tiles = padded.reshape(bx, BOUND_BLOCK, by, BOUND_BLOCK)
            blocks.append(tiles.min(axis=(1, 3)) if which % 2 == 0 else tiles.max(axis=(1, 3)))
        self.gradient_bounds = blocks  # (dzdx_min, dzdx_max, dzdy_min, dzdy_max) per block
        self.block = BOUND_BLOCK * self.cell  # block side (m); block (I, J) starts at origin + (I, J) * block
        self._banked = bank != 0.0
        self._bank = bank
        self._right = float(road.right_edge)
        self._left = float(road.left_edge)

    def height(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Interpolated heights (m) at the points of the flat arrays ``x``, ``y`` (m, G); off the grid
        the nearest grid point's."""
        nx, ny = self.shape
        inv = 1.0 / self.cell
        fx = (x - self.origin[0]) * inv
        fy = (y - self.origin[1]) * inv
        np.maximum(fx, 0.0, out=fx)
        np.minimum(fx, nx - 1.0, out=fx)
        np.maximum(fy, 0.0, out=fy)
        np.minimum(fy, ny - 1.0, out=fy)
        i = np.minimum(fx.astype(np.intp), nx - 2)
        j = np.minimum(fy.astype(np.intp), ny - 2)
        wx = fx - i
        wy = fy - j
        i *= ny - 1
        i += j
        c = np.take(self.coef, i, axis=0)
        h = c[:, 0] + wx * (c[:, 1] + wy * c[:, 3]) + wy * c[:, 2]
        if self._banked:
            n = c[:, 4] + wx * (c[:, 5] + wy * c[:, 7]) + wy * c[:, 6]
            h -= self._bank * (n - np.clip(n, self._right, self._left))
        return h

    def rise_bound(
        self, centre: np.ndarray, radius: float
    ) -> tuple[Callable[[np.ndarray, np.ndarray], np.ndarray], float]:
        """The ``GroundSurface.rise`` (and its ``max_rise``) of the interpolated height for rays from ``centre`` out to
        ``radius`` m: per azimuth sector (``RISE_SECTORS`` of them) the largest directional
        derivative over the blocks its wedge meets. A block with gradient box
        ``[gx0, gx1] x [gy0, gy1]`` bounds ``grad h . u`` by
        ``max(gx0 ux, gx1 ux) + max(gy0 uy, gy1 uy)`` at the sector's mid direction, plus
        ``|g|max * half-width`` for the rest of the sector. Where the square of half-side ``radius``
        leaves the grid (the clamped surface is flat across the border there) every sector takes the
        bound of the union of the square's boxes, with 0 added to each component."""
        nx, ny = self.shape
        lo = np.floor((centre - radius - self.origin) / self.cell).astype(int)
        hi = np.floor((centre + radius - self.origin) / self.cell).astype(int)
        i0, j0 = int(np.clip(lo[0], 0, nx - 2)), int(np.clip(lo[1], 0, ny - 2))
        i1, j1 = int(np.clip(hi[0], 0, nx - 2)), int(np.clip(hi[1], 0, ny - 2))
        bi = np.arange(i0 // BOUND_BLOCK, i1 // BOUND_BLOCK + 1)
        bj = np.arange(j0 // BOUND_BLOCK, j1 // BOUND_BLOCK + 1)
        gx0, gx1, gy0, gy1 = (b[bi[0] : bi[-1] + 1, bj[0] : bj[-1] + 1].ravel() for b in self.gradient_bounds)
        if lo[0] < 0 or lo[1] < 0 or hi[0] > nx - 2 or hi[1] > ny - 2:
            box = (min(gx0.min(), 0.0), max(gx1.max(), 0.0), min(gy0.min(), 0.0), max(gy1.max(), 0.0))

            def rise_box(ux: np.ndarray, uy: np.ndarray) -> np.ndarray:
                return np.maximum(box[0] * ux, box[1] * ux) + np.maximum(box[2] * uy, box[3] * uy)

            return rise_box, max(abs(box[0]), abs(box[1])) + max(abs(box[2]), abs(box[3]))
        # the window's blocks: their corners relative to the centre, and their bearing intervals
        bx, by = np.meshgrid(bi, bj, indexing="ij")
        x0 = self.origin[0] + bx.ravel() * self.block - centre[0]
        y0 = self.origin[1] + by.ravel() * self.block - centre[1]
        x1, y1 = x0 + self.block, y0 + self.block
        near_x = np.clip(0.0, x0, x1)
        near_y = np.clip(0.0, y0, y1)
        reach = np.hypot(near_x, near_y) <= radius
        contains = (x0 <= 0.0) & (x1 >= 0.0) & (y0 <= 0.0) & (y1 >= 0.0)
        cx, cy = np.stack([x0, x1, x1, x0], axis=1), np.stack([y0, y0, y1, y1], axis=1)
        mid = np.arctan2(0.5 * (y0 + y1), 0.5 * (x0 + x1))
        rel = np.mod(np.arctan2(cy, cx) - mid[:, None] + math.pi, 2.0 * math.pi) - math.pi
        width = 2.0 * math.pi / RISE_SECTORS
        first = np.floor((mid + rel.min(axis=1) + math.pi) / width).astype(np.int64) - 1
        last = np.floor((mid + rel.max(axis=1) + math.pi) / width).astype(np.int64) + 1
        first = np.where(contains, 0, first)
        last = np.where(contains, RISE_SECTORS - 1, last)
        keep = np.flatnonzero(reach)
        first, last = first[keep], last[keep]
        gx0, gx1, gy0, gy1 = gx0[keep], gx1[keep], gy0[keep], gy1[keep]
        counts = last - first + 1
        block = np.repeat(np.arange(keep.size), counts)
        sector = np.mod(np.arange(block.size) + np.repeat(first - (np.cumsum(counts) - counts), counts), RISE_SECTORS)
        ux, uy = _SECTOR_UX[sector], _SECTOR_UY[sector]
        gmax = np.hypot(np.maximum(np.abs(gx0), np.abs(gx1)), np.maximum(np.abs(gy0), np.abs(gy1)))
        value = (
            np.maximum(gx0[block] * ux, gx1[block] * ux)
            + np.maximum(gy0[block] * uy, gy1[block] * uy)
            + gmax[block] * (0.5 * width)
        )
        bound = np.full(RISE_SECTORS, -np.inf)
        np.maximum.at(bound, sector, value)

        def rise(ux: np.ndarray, uy: np.ndarray) -> np.ndarray:
            k = ((np.arctan2(uy, ux) + math.pi) * (1.0 / width)).astype(np.int64)
            return bound[np.mod(k, RISE_SECTORS)]

        return rise, float(bound.max())


class RoadGround(Ground):
    """The road's surface and the terrain beside it (module docstring): ``grade`` (m/m along ``s``)
    and ``bank`` (m/m along ``n``, up to the left), each within +-``MAX_SLOPE``; a closed road needs
    ``grade == 0`` (a loop cannot climb forever). ``road`` needs ``to_frenet``, ``to_cartesian``,
    ``frame``, ``length``, ``closed`` and constant ``left_edge`` / ``right_edge`` (a
    ``tracker.road.Road`` has them). ``cell`` (1 m) and ``margin`` (110 m) shape the casting grid."""

    def __init__(
        self,
        road: Any,
        grade: float = 0.0,
        bank: float = 0.0,
        *,
        cell: float = GRID_CELL,
        margin: float = GRID_MARGIN,
        max_nodes: int = GRID_MAX_NODES,
    ) -> None:
        for name in ("to_frenet", "to_cartesian", "frame", "length", "closed", "left_edge", "right_edge"):
            if not hasattr(road, name):
                raise ValueError(f"RoadGround: the road has no attribute {name!r}")
        for name in ("left_edge", "right_edge"):
            value = getattr(road, name)
            if callable(value) or not (isinstance(value, (int, float)) and math.isfinite(value)):
                raise ValueError(f"RoadGround: road.{name} must be a finite number of metres; got {value!r}")
        for name, value in (("grade", grade), ("bank", bank)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and abs(value) <= MAX_SLOPE):
                raise ValueError(
                    f"RoadGround.{name} must be a finite number in [-{MAX_SLOPE}, {MAX_SLOPE}]; got {value!r}"
                )
        if road.closed and grade != 0.0:
            raise ValueError(
                f"RoadGround.grade must be 0 on a closed road (a loop cannot climb forever); got {grade!r}"
            )
        for name, value in (("cell", cell), ("margin", margin)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0.0):
                raise ValueError(f"RoadGround.{name} must be a finite number of metres > 0; got {value!r}")
        if isinstance(max_nodes, bool) or not isinstance(max_nodes, int) or max_nodes < 4:
            raise ValueError(f"RoadGround.max_nodes must be an integer >= 4; got {max_nodes!r}")
        self.road = road
        self.grade = float(grade)
        self.bank = float(bank)
        self.cell = float(cell)
        self.margin = float(margin)
        self.max_nodes = int(max_nodes)

    def __repr__(self) -> str:
        return f"RoadGround(grade={self.grade!r}, bank={self.bank!r}, cell={self.cell!r}, margin={self.margin!r})"

    def height_at(self, s: np.ndarray, n: np.ndarray) -> np.ndarray:
        """Heights (m) at road coordinates ``s``, ``n`` (m), the formula of the module docstring
        (no projection: for callers that already have them, e.g. the world's vehicles)."""
        s, n = np.asarray(s, dtype=float), np.asarray(n, dtype=float)
        h = self.bank * np.clip(n, float(self.road.right_edge), float(self.road.left_edge))
        if self.grade != 0.0:
            h = h + self.grade * s
        return h

    def height(self, xy: np.ndarray) -> np.ndarray:
        """Exact heights (N,) in m (one ``to_frenet`` of all points)."""
        pts = _as_xy(xy, "RoadGround.height")
        s, n = self.road.to_frenet(pts)
        return self.height_at(np.asarray(s, dtype=float).reshape(-1), np.asarray(n, dtype=float).reshape(-1))

    def gradient(self, xy: np.ndarray) -> np.ndarray:
        """Exact gradients (N, 2) (module docstring); on a road edge the bank term counts as off."""
        pts = _as_xy(xy, "RoadGround.gradient")
        s, n = self.road.to_frenet(pts)
        s = np.asarray(s, dtype=float).reshape(-1)
        n = np.asarray(n, dtype=float).reshape(-1)
        _, theta, kappa = self.road.frame(np.mod(s, self.road.length) if self.road.closed else s, extrapolate=True)
        tangent = np.column_stack([np.cos(theta), np.sin(theta)])
        normal = np.column_stack([-tangent[:, 1], tangent[:, 0]])
        on = (n > float(self.road.right_edge)) & (n < float(self.road.left_edge))
        grad = (self.bank * on)[:, None] * normal
        if self.grade != 0.0:
            grad = grad + (self.grade / (1.0 - kappa * n))[:, None] * tangent
        return grad

    @cached_property
    def grid(self) -> RoadGroundGrid:
        """The casting grid (built on first use)."""
        return RoadGroundGrid(self, self.cell, self.margin, self.max_nodes)

    def surface(self, centre: tuple[float, float] | np.ndarray, radius: float) -> GroundSurface:
        """The interpolated grid and its rise bounds (``RoadGroundGrid.rise_bound``) within
        ``radius`` of ``centre``; flat (exact) when ``grade == bank == 0``."""
        if self.grade == 0.0 and self.bank == 0.0:
            return GroundSurface(height=_zeros, rise=_no_rise, max_rise=0.0, flat=0.0)
        grid = self.grid
        rise, max_rise = grid.rise_bound(np.asarray(centre, dtype=float)[:2], float(radius))
        return GroundSurface(height=grid.height, rise=rise, max_rise=max_rise)
