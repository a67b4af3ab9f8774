"""The road: a centerline parameterised by arc length, lanes, bounds and Frenet conversions.

Conventions (docs/architecture.md): ``s`` is arc length along the centerline in ``[0, length)`` (wrapping on a
closed road); ``n`` is the signed lateral offset, **positive to the left** of the driving direction;
lane 0 is the rightmost lane. The lanes (``tracker.lanes.LaneLayout``) lie side by side; their count, widths and
edges may change along ``s`` (lanes that begin and end, merges, a shoulder) and each has a direction (+1
along ``s``, -1 against it: the oncoming lanes of a two-way road). By default a road has ``lanes`` lanes
of ``lane_width`` between ``right_edge`` and ``left_edge`` everywhere, the centerline down the middle.

Off the ends of an open road:

- ``position``, ``heading``, ``curvature``, ``frame`` and ``to_cartesian`` raise ``ValueError``
  naming the offending ``s`` unless ``extrapolate=True``, which continues the end tangents as
  straight lines (heading constant, curvature 0);
- ``to_frenet`` projects onto those straight extensions, so a point beyond an end gets ``s < 0`` or
  ``s > length``; ``on_road`` reports such points as off the road.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Literal

import numpy as np
from scipy.spatial import cKDTree

from tracker.angles import wrap_angle
from tracker.checks import finite_array
from tracker.lanes import MIN_LANE_WIDTH, LaneLayout
from tracker.centerline import ClothoidCenterline, HermiteCenterline, node_seed_kernel, project_kernel, seed_kernel

ArrayLike = float | Sequence[float] | np.ndarray

#: Newton iterations allowed when projecting a point on the centerline (then: bisection).
PROJECTION_MAX_ITERATIONS = 8
#: Bisection iterations of the robust projection fallback (bracket of ~4 m -> 4e-15 m).
BISECTION_ITERATIONS = 50
#: Convergence test of the projection: stop once the Newton step is below this (m). Newton converges
#: quadratically, so the error left after such a step is ~kappa * step^2 < 1e-11 m.
PROJECTION_TOLERANCE = 1e-5
#: Resolution (m) of the lookup grid that gives every point near the road its nearest curve sample.
SEED_GRID_RESOLUTION = 2.0
#: The seed grid is built only when it has at most this many cells (else the k-d tree alone is used).
SEED_GRID_MAX_CELLS = 2_000_000
#: Largest Newton step of the projection (m); larger moves take several iterations.
PROJECTION_MAX_STEP = 20.0
#: Smallest allowed ``1 - kappa * n`` in the projection's Newton step (points near the centre of
#: curvature are badly conditioned; they are never on a road whose radius exceeds its half-width).
PROJECTION_MIN_DENOMINATOR = 0.2
#: Default horizon (m) of the paper's local heading/curvature polynomials.
POLY_HORIZON = 30.0
#: Samples used to fit the local polynomials.
POLY_SAMPLES = 61


def _is_point(xy: object) -> bool:
    """Whether ``xy`` is one point given as a length-2 tuple or list of numbers."""
    return isinstance(xy, (tuple, list)) and len(xy) == 2 and all(isinstance(v, (int, float)) for v in xy)


class Road:
    """A road: centerline, lanes and bounds, with vectorised Frenet <-> Cartesian conversions.

    Build it with ``Road.from_waypoints`` (cubic Hermite spline through points) or
    ``Road.from_curvature`` (straights, arcs and clothoid ramps), and give its lanes either as a
    ``layout`` (``tracker.lanes.LaneLayout``: lanes varying along ``s``, with directions and kinds) or as
    ``lanes`` lanes (default 2) of ``lane_width`` metres (default 3.5) from ``right_edge`` (offset ``n``, m;
    default ``-lanes * lane_width / 2``: the centerline in the middle), the ``oncoming`` leftmost of them
    (rightmost with ``drive_on = "left"``) carrying traffic against ``s``. ``right_edge`` and
    ``left_edge`` are the outermost edges over the whole road; ``edges(s)`` gives them at ``s``.
    """

    def __init__(
        self,
        centerline: HermiteCenterline | ClothoidCenterline,
        *,
        lanes: int | None = None,
        lane_width: float | None = None,
        right_edge: float | None = None,
        oncoming: int = 0,
        drive_on: Literal["right", "left"] = "right",
        layout: LaneLayout | None = None,
    ) -> None:
        if layout is None:
            layout = LaneLayout.uniform(2 if lanes is None else lanes, 3.5 if lane_width is None else lane_width,
                                        right_edge, oncoming=oncoming, drive_on=drive_on)
        elif not isinstance(layout, LaneLayout):
            raise ValueError(f"layout must be a tracker.lanes.LaneLayout; got {type(layout).__name__}")
        elif lanes is not None or lane_width is not None or right_edge is not None or oncoming or drive_on != "right":
            raise ValueError("give either a layout or lanes/lane_width/right_edge/oncoming/drive_on, not both: the "
                             "layout holds the lanes and their directions")
        self._curve = centerline
        self.closed: bool = bool(centerline.closed)
        self.length: float = float(centerline.length)
        self._set_layout(layout)
        if self.closed and layout.varies:
            ends = layout.boundaries_at(np.array([0.0, self.length]))
            if not np.allclose(ends[0], ends[1], atol=1e-6):
                raise ValueError("a closed road's lanes must meet themselves: the layout's boundaries at s = 0 "
                                 f"({np.round(ends[0], 3).tolist()}) and at s = length ({np.round(ends[1], 3).tolist()}) differ")
        self._nodes = centerline.nodes()
        node_xy, _, _ = centerline.frame(self._nodes)
        if self.closed:  # the last node repeats the first
            self._nodes, node_xy = self._nodes[:-1], node_xy[:-1]
        self._tree = cKDTree(node_xy)
        self._node_xy = node_xy
        _, node_t, node_k = centerline.frame(self._nodes)
        self._node_frame = np.column_stack([node_xy, node_t, node_k])  # x, y, tx, ty, kappa per node
        self._build_seed_grid(node_xy)
        x0, y0, c0, s0, _ = centerline.frame1(0.0)
        x1, y1, c1, s1, _ = centerline.frame1(self.length)
        self._ends = ((x0, y0, c0, s0), (x1, y1, c1, s1))
        self._ends_array = np.array(self._ends, dtype=float)  # the same, for the projection's kernels

    # -- construction ---------------------------------------------------------------------------
    @classmethod
    def from_waypoints(
        cls,
        xy: ArrayLike,
        headings: ArrayLike | None = None,
        *,
        lane_width: float | None = None,
        lanes: int | None = None,
        closed: bool = False,
        right_edge: float | None = None,
        oncoming: int = 0,
        drive_on: Literal["right", "left"] = "right",
        layout: LaneLayout | None = None,
    ) -> Road:
        """A road whose centerline is the cubic Hermite spline through ``xy`` (M, 2) metres in G.

        ``headings`` (M,) rad give the tangent direction at each waypoint; when absent they are those
        of the C2 (curvature-continuous) cubic spline in the chord-length parameter. On a closed road
        the spline is periodic; a last waypoint equal to the first is dropped.
        """
        pts = finite_array(xy, "waypoints xy")
        if pts.ndim != 2 or pts.shape[1] != 2:
            raise ValueError(f"waypoints xy must have shape (M, 2); got {pts.shape}")
        if closed and len(pts) > 1 and np.allclose(pts[0], pts[-1], atol=1e-9):
            pts = pts[:-1]
            if headings is not None:
                headings = np.asarray(headings, dtype=float)[:-1]
        need = 3 if closed else 2
        if len(pts) < need:
            raise ValueError(f"need at least {need} waypoints for {'a closed' if closed else 'an open'} road; got {len(pts)}")
        ring = np.vstack([pts, pts[:1]]) if closed else pts
        gaps = np.linalg.norm(np.diff(ring, axis=0), axis=1)
        if np.any(gaps < 1e-6):
            i = int(np.argmax(gaps < 1e-6))
            j = (i + 1) % len(pts)
            raise ValueError(f"repeated consecutive waypoints: waypoints {i} and {j} coincide at {pts[i].tolist()}")
        th = None
        if headings is not None:
            th = finite_array(headings, "headings")
            if th.shape != (len(pts),):
                raise ValueError(f"headings must have shape ({len(pts)},) like the waypoints; got {th.shape}")
        curve = HermiteCenterline.through(pts, th, closed)
        return cls(curve, lanes=lanes, lane_width=lane_width, right_edge=right_edge, oncoming=oncoming, drive_on=drive_on,
                   layout=layout)

    @classmethod
    def from_curvature(
        cls,
        segments: Sequence[tuple[float, float, float]] | np.ndarray,
        *,
        start: tuple[float, float, float] = (0.0, 0.0, 0.0),
        lane_width: float | None = None,
        lanes: int | None = None,
        closed: bool = False,
        right_edge: float | None = None,
        closure_tolerance: float = 0.05,
        oncoming: int = 0,
        drive_on: Literal["right", "left"] = "right",
        layout: LaneLayout | None = None,
    ) -> Road:
        """A road from a curvature profile: rows ``(length m, kappa_start 1/m, kappa_end 1/m)``.

        Curvature varies linearly inside a segment: ``(L, 0, 0)`` is a straight, ``(L, k, k)`` an arc
        of radius ``1/k`` (positive turns left), ``(L, k0, k1)`` a clothoid ramp. ``start`` is
        ``(x, y, heading)`` of ``s = 0`` in G. A closed road must end where it starts, within
        ``closure_tolerance`` metres and ``closure_tolerance / 10`` rad.
        """
        seg = finite_array(segments, "segments")
        if seg.ndim != 2 or seg.shape[1] != 3 or len(seg) == 0:
            raise ValueError(f"segments must be rows of (length, kappa_start, kappa_end); got shape {seg.shape}")
        if np.any(seg[:, 0] <= 0):
            i = int(np.argmax(seg[:, 0] <= 0))
            raise ValueError(f"segment {i} has non-positive length {seg[i, 0]!r}; lengths must be > 0 m")
        st = finite_array(start, "start")
        if st.shape != (3,):
            raise ValueError(f"start must be (x, y, heading); got shape {st.shape}")
        curve = ClothoidCenterline(seg, (float(st[0]), float(st[1]), float(st[2])), closed)
        if closed:
            gap = float(np.hypot(*(curve.end_xy - st[:2])))
            turn = abs(wrap_angle(curve.end_heading - st[2]))
            if gap > closure_tolerance or turn > closure_tolerance / 10.0:
                raise ValueError(
                    f"closed road does not close: its end is {gap:.3f} m from its start and its heading "
                    f"differs by {turn:.4f} rad (tolerance {closure_tolerance} m); adjust the segments"
                )
        return cls(curve, lanes=lanes, lane_width=lane_width, right_edge=right_edge, oncoming=oncoming, drive_on=drive_on,
                   layout=layout)

    # -- lanes and bounds -----------------------------------------------------------------------
    def _set_layout(self, layout: LaneLayout) -> None:
        """Store ``layout`` and what is derived from it: the edge table, the envelope of the edges, the
        nominal lane width."""
        self.layout: LaneLayout = layout
        self.lanes: int = layout.lanes
        inv_step, right, left = layout.edge_table(self.length, self.closed)
        self._edge_inv_step, self._edge_right, self._edge_left = float(inv_step), right, left
        #: Outermost right and left edges over the whole road (m); where the lanes vary, ``edges(s)`` gives them at ``s``.
        self.right_edge: float = float(right.min())
        self.left_edge: float = float(left.max())
        uniform = getattr(layout, "_uniform", None)
        if uniform is not None:
            self.lane_width: float = uniform[1]
        else:  # the median width of the lanes present at the layout's stations
            widths = np.diff(layout.boundaries, axis=1)
            present = widths[widths >= MIN_LANE_WIDTH]
            self.lane_width = float(np.median(present)) if len(present) else float(widths.max())

    @property
    def uniform(self) -> bool:
        """Whether the lanes are the same at every ``s`` (then ``lane_centers`` and ``lane_index(n)`` apply)."""
        return not self.layout.varies

    @property
    def two_way(self) -> bool:
        """Whether some lane carries traffic against ``s`` (``lane_directions``)."""
        return self.layout.two_way

    @property
    def lane_directions(self) -> np.ndarray:
        """Per lane, +1 when its traffic drives along ``s``, -1 against it (read-only)."""
        return self.layout.directions

    def edges(self, s: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """The right and left road edges (m, offsets ``n``) at arc lengths ``s``: the outermost boundaries of
        the lanes present there (on a closed road ``s`` wraps; on an open one the end values hold beyond)."""
        s_arr = self.wrap_s(finite_array(s, "s"))
        # edge_at's interpolation, vectorised; exactly the table's value where neighbouring entries are equal
        last = len(self._edge_right) - 1
        u = np.clip(s_arr * self._edge_inv_step, 0.0, float(last))
        i = np.minimum(u.astype(int), last - 1)
        t = u - i
        r, lf = self._edge_right, self._edge_left
        return r[i] + t * (r[i + 1] - r[i]), lf[i] + t * (lf[i + 1] - lf[i])

    def edge_kernel_args(self) -> tuple[float, np.ndarray, np.ndarray]:
        """``(inv_step, right, left)``: the edge tables that compiled stages read with ``tracker.lanes.edge_at``."""
        return self._edge_inv_step, self._edge_right, self._edge_left

    @property
    def lane_centers(self) -> np.ndarray:
        """Lateral offset ``n`` (m) of every lane's centre, lane 0 (rightmost) first (read-only), on a road
        whose lanes are the same everywhere; ``lane_centers_at(s)`` where they vary."""
        cached = self.__dict__.get("_lane_centers")
        if cached is None:
            if self.layout.varies:
                raise ValueError("this road's lanes vary along s; use lane_centers_at(s)")
            b = self.layout.boundaries[0]
            centers = 0.5 * (b[1:] + b[:-1])
            uniform = getattr(self.layout, "_uniform", None)
            if uniform is not None:  # the same numbers as right_edge + (k + 1/2) * lane_width
                centers = uniform[2] + (np.arange(uniform[0]) + 0.5) * uniform[1]
            centers.flags.writeable = False
            cached = self.__dict__["_lane_centers"] = centers
        return cached

    def lane_centers_at(self, s: ArrayLike) -> np.ndarray:
        """Every lane's centre offset ``n`` (m) at arc lengths ``s``: shape ``s.shape + (lanes,)``, NaN where
        the lane is absent (narrower than ``tracker.lanes.MIN_LANE_WIDTH``)."""
        return self.layout.centers_at(self.wrap_s(finite_array(s, "s")))

    def lane_center(self, lane: int, s: float | None = None) -> float:
        """Lateral offset ``n`` (m) of lane ``lane``'s centre (at ``s`` where the lanes vary); lane 0 is the
        rightmost."""
        if not 0 <= lane < self.lanes:
            raise ValueError(f"lane {lane} does not exist; this road has lanes 0..{self.lanes - 1}")
        if s is None:
            return float(self.lane_centers[lane])
        return float(self.lane_centers_at(float(s))[lane])

    def lane_index(self, n: ArrayLike, s: ArrayLike | None = None) -> np.ndarray:
        """Lane index of lateral offsets ``n`` (m) (at arc lengths ``s`` where the lanes vary); -1 right of
        the road, ``lanes`` left of it. Where lanes vary, a point between boundaries takes the lane whose
        span holds it (a lane of zero width holds nothing)."""
        n_arr = finite_array(n, "n")
        if getattr(self.layout, "_uniform", None) is not None:  # equal lanes: one division
            idx = np.floor((n_arr - self.right_edge) / self.lane_width).astype(int)
            return np.clip(idx, -1, self.lanes)
        if s is None:
            if self.layout.varies:
                raise ValueError("this road's lanes vary along s; pass s to lane_index")
            s = 0.0
        b = self.layout.boundaries_at(self.wrap_s(np.broadcast_to(finite_array(s, "s"), n_arr.shape)))
        return (n_arr[..., None] >= b).sum(axis=-1) - 1

    def lane_direction(self, s: ArrayLike, n: ArrayLike) -> np.ndarray:
        """The direction (+1 along ``s``, -1 against) of the lane nearest each road point ``(s, n)`` (m)
        among the lanes present at ``s`` (a point off the road takes its nearest lane's)."""
        s_arr, n_arr = np.broadcast_arrays(finite_array(s, "s"), finite_array(n, "n"))
        if not self.two_way:
            return np.ones(n_arr.shape, dtype=int)
        centres = self.lane_centers_at(s_arr)
        gap = np.abs(np.where(np.isnan(centres), np.inf, centres - n_arr[..., None]))
        return self.layout.directions[np.argmin(gap, axis=-1)]

    def on_road(self, xy: ArrayLike, margin: float = 0.0) -> np.ndarray:
        """Whether points ``xy`` (N, 2) lie within the road bounds widened by ``margin`` metres."""
        s, n = self.to_frenet(xy)
        return self.within_bounds(s, n, margin)

    def within_bounds(self, s: np.ndarray, n: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Whether road coordinates ``(s, n)`` (m) lie within the road edges at ``s`` (``edges``) widened by
        ``margin`` metres (``on_road`` for points already projected)."""
        right, left = self.edges(s)
        inside = (n >= right - margin) & (n <= left + margin)
        if not self.closed:
            inside &= (s >= 0.0) & (s <= self.length)
        return inside

    def boundaries(self, step: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
        """Right and left road edges as polylines ``(K, 2)`` sampled every ``step`` metres (for plots)."""
        s = np.linspace(0.0, self.length, max(2, int(math.ceil(self.length / step)) + 1))
        if self.closed:
            s[-1] = 0.0
        right, left = self.edges(s)
        return self.to_cartesian(s, right), self.to_cartesian(s, left)

    @property
    def joins(self) -> np.ndarray:
        """Arc length (m) of every waypoint or curvature-segment start along the centerline."""
        return self._curve.joins.copy()

    # -- the curve ------------------------------------------------------------------------------
    def wrap_s(self, s: ArrayLike) -> np.ndarray:
        """``s`` wrapped into ``[0, length)`` on a closed road; unchanged on an open one."""
        s_arr = np.asarray(s, dtype=float)
        return np.mod(s_arr, self.length) if self.closed else s_arr

    def s_difference(self, s_to: ArrayLike, s_from: ArrayLike) -> np.ndarray:
        """``s_to - s_from`` (m) along the road: on a closed road the short way round, in
        ``[-length/2, length/2)``; on an open one as it is."""
        d = np.asarray(s_to, dtype=float) - np.asarray(s_from, dtype=float)
        return np.mod(d + 0.5 * self.length, self.length) - 0.5 * self.length if self.closed else d

    def _frame_flat(self, s: np.ndarray, extrapolate: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position (N, 2), unit tangent (N, 2) and curvature (N,) at 1-D finite ``s``: wraps on
        closed roads, extends (``extrapolate``) or rejects the ends of open ones."""
        if self.closed:
            return self._curve.frame(np.mod(s, self.length))
        low, high = s < 0.0, s > self.length
        if not extrapolate:
            tol = 1e-9 * max(1.0, self.length)
            out = (s < -tol) | (s > self.length + tol)
            if out.any():
                bad = float(s[np.argmax(out)])
                raise ValueError(
                    f"s = {bad!r} m is off the open road [0, {self.length!r}]; "
                    "pass extrapolate=True to continue the end tangents as straight lines"
                )
        xy, tangent, kappa = self._curve.frame(np.clip(s, 0.0, self.length))
        if low.any() or high.any():
            for mask, (x, y, c, sn), ref in ((low, self._ends[0], 0.0), (high, self._ends[1], self.length)):
                if extrapolate and mask.any():
                    d = s[mask] - ref
                    xy[mask] = np.column_stack([x + d * c, y + d * sn])
                    kappa[mask] = 0.0
        return xy, tangent, kappa

    def frame(self, s: ArrayLike, *, extrapolate: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Centerline position (..., 2) m in G, heading (...) rad and curvature (...) 1/m at ``s``."""
        s_arr = finite_array(s, "s")
        xy, tangent, kappa = self._frame_flat(s_arr.reshape(-1), extrapolate)
        theta = np.arctan2(tangent[:, 1], tangent[:, 0])
        return xy.reshape(s_arr.shape + (2,)), theta.reshape(s_arr.shape), kappa.reshape(s_arr.shape)

    def position(self, s: ArrayLike, *, extrapolate: bool = False) -> np.ndarray:
        """Centerline position at ``s``: shape ``s.shape + (2,)``, metres in G."""
        return self.frame(s, extrapolate=extrapolate)[0]

    def heading(self, s: ArrayLike, *, extrapolate: bool = False) -> np.ndarray:
        """Centerline heading theta(s), rad in (-pi, pi], counter-clockwise from +x."""
        return self.frame(s, extrapolate=extrapolate)[1]

    def curvature(self, s: ArrayLike, *, extrapolate: bool = False) -> np.ndarray:
        """Centerline curvature kappa(s), 1/m, positive when the road turns left."""
        return self.frame(s, extrapolate=extrapolate)[2]

    def frame1(self, s: float) -> tuple[float, float, float, float, float]:
        """The frame at one ``s`` (m) as plain floats: ``(x, y, cos theta, sin theta, kappa)``.

        The pure-Python fast path for single queries (no numpy overhead, ~2-5 us); wraps on closed
        roads and extrapolates open ends along the end tangents (no range check: callers that need
        one use ``frame``)."""
        if self.closed:
            return self._curve.frame1(s % self.length)
        if s < 0.0:
            x, y, c, sn = self._ends[0]
            return x + s * c, y + s * sn, c, sn, 0.0
        if s > self.length:
            x, y, c, sn = self._ends[1]
            d = s - self.length
            return x + d * c, y + d * sn, c, sn, 0.0
        return self._curve.frame1(s)

    # -- conversions ----------------------------------------------------------------------------
    def to_cartesian(
        self,
        s: ArrayLike,
        n: ArrayLike,
        *,
        method: Literal["exact", "euler"] = "exact",
        s0: float | None = None,
        step: float = 0.5,
        horizon: float = POLY_HORIZON,
        extrapolate: bool = False,
    ) -> np.ndarray:
        """Road coordinates ``(s, n)`` (m) to points in G, shape ``s.shape + (2,)``.

        ``method="exact"`` evaluates the centerline: ``c(s) + n * (-sin theta, cos theta)``.
        ``method="euler"`` is the paper's Algorithm 1: from the centerline point at ``s0`` (the ego's
        arc length), integrate the local cubic heading polynomial (``heading_poly``, fitted over
        ``[s0 - horizon, s0 + horizon]``) in Euler steps of ``step`` metres up to ``s``, then offset by
        ``n`` along the normal of the polynomial heading. Its error is O(step) (see tests).
        Departure from the paper's text: its normal ``(cos(pi/2 - theta), sin(pi/2 - theta))`` points
        right; here ``n`` is positive to the left, so the normal is ``(-sin theta, cos theta)``.
        """
        if method == "exact" and isinstance(s, (float, int)) and isinstance(n, (float, int)):
            sf, nf = float(s), float(n)
            if math.isfinite(sf) and math.isfinite(nf) and (self.closed or extrapolate or 0.0 <= sf <= self.length):
                x, y, c, sn, _ = self.frame1(sf)
                return np.array([x - nf * sn, y + nf * c])
        s_arr = finite_array(s, "s")
        n_arr = finite_array(n, "n")
        if n_arr.shape != s_arr.shape:
            if n_arr.ndim == 0:
                n_arr = np.broadcast_to(n_arr, s_arr.shape)
            else:
                raise ValueError(f"s and n must have the same shape; got s {s_arr.shape} and n {n_arr.shape}")
        if method == "euler":
            if s0 is None:
                raise ValueError("method='euler' needs s0, the arc length where the integration starts (m)")
            if not step > 0:
                raise ValueError(f"step must be > 0 m; got {step!r}")
            out = self._to_cartesian_euler(s_arr.reshape(-1), n_arr.reshape(-1), float(s0), step, horizon)
            return out.reshape(s_arr.shape + (2,))
        if method != "exact":
            raise ValueError(f"method must be 'exact' or 'euler'; got {method!r}")
        if s_arr.ndim == 0 and (self.closed or extrapolate or 0.0 <= s_arr <= self.length):
            x, y, c, sn, _ = self.frame1(float(s_arr))
            nv = float(n_arr)
            return np.array([x - nv * sn, y + nv * c])
        xy, tangent, _ = self._frame_flat(s_arr.reshape(-1), extrapolate)
        nf = n_arr.reshape(-1)
        out = xy + nf[:, None] * np.column_stack([-tangent[:, 1], tangent[:, 0]])
        return out.reshape(s_arr.shape + (2,))

    def to_frenet(self, xy: ArrayLike, s_hint: ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Points ``xy`` (..., 2) in G to road coordinates ``(s, n)``, each of shape ``xy.shape[:-1]``.

        Returns the nearest projection on the centerline (Newton's method on
        ``(p - c(s)) . t(s) = 0`` from the nearest curve sample, spaced <= 2 m). With ``s_hint`` (a
        scalar or one per point, e.g. the previous ``s`` of a moving vehicle) the search starts there
        instead, which keeps the answer continuous under small motion where a tight curve offers
        several projections; if it fails to converge it falls back to the global search. A single
        point takes a pure-Python fast path whatever its shape: given as a tuple or shape (2,) it
        returns two floats, given as (1, 2) (or (1, ..., 1, 2)) two arrays of shape ``xy.shape[:-1]``.
        """
        if s_hint is None or isinstance(s_hint, (float, int)):
            # one point, as a tuple or an array of any shape (..., 2) holding two numbers: pure Python
            # (the same cost for a tuple and a (1, 2) array; the array answer wraps the two floats)
            if isinstance(xy, np.ndarray):
                one = xy.size == 2 and xy.ndim >= 1 and xy.shape[-1] == 2 and xy.dtype.kind in "fiu"
                if one:
                    x, y = float(xy.item(0)), float(xy.item(1))
            else:
                one = _is_point(xy)
                if one:
                    x, y = float(xy[0]), float(xy[1])  # type: ignore[index]
            if one:
                hint = None if s_hint is None else float(s_hint)
                if math.isfinite(x) and math.isfinite(y) and (hint is None or math.isfinite(hint)):
                    result = self._to_frenet1(x, y, hint)
                    if result is not None:
                        if not isinstance(xy, np.ndarray) or xy.ndim == 1:
                            return result  # type: ignore[return-value]
                        both = np.empty(2)
                        both[0], both[1] = result
                        if xy.ndim == 2:  # (1, 2): two (1,) views of one buffer, the cheapest wrapping
                            return both[0:1], both[1:2]
                        both = both.reshape((2,) + xy.shape[:-1])
                        return both[0], both[1]
        pts = finite_array(xy, "xy")
        if pts.ndim == 0 or pts.shape[-1] != 2:
            raise ValueError(f"xy must have shape (..., 2); got {pts.shape}")
        if pts.size == 2:  # one point, as (2,), (1, 2), (1, 1, 2), ...: the pure-Python fast path
            hint = None
            if s_hint is not None:
                h = finite_array(s_hint, "s_hint")
                if h.size != 1:
                    raise ValueError(f"s_hint for one point must be a scalar; got shape {h.shape}")
                hint = float(h.reshape(-1)[0])
            flat1 = pts.reshape(2)
            result = self._to_frenet1(float(flat1[0]), float(flat1[1]), hint)
            if result is not None:
                if pts.shape == (2,):
                    return result  # type: ignore[return-value]
                return np.full(pts.shape[:-1], result[0]), np.full(pts.shape[:-1], result[1])
        flat = pts.reshape(-1, 2)
        if s_hint is None:
            s_start = None
        else:
            h = finite_array(s_hint, "s_hint")
            if h.ndim == 0:
                s_start = np.full(len(flat), float(h))
            elif h.shape == pts.shape[:-1]:
                s_start = h.reshape(-1).copy()
            else:
                raise ValueError(f"s_hint must be a scalar or have shape {pts.shape[:-1]}; got {h.shape}")
        s, n = self._project(flat, s_start)
        if pts.shape == (2,):
            return float(s[0]), float(n[0])  # type: ignore[return-value]
        return s.reshape(pts.shape[:-1]), n.reshape(pts.shape[:-1])

    def _build_seed_grid(self, node_xy: np.ndarray) -> None:
        """A grid over the road's neighbourhood whose cells store the curve sample nearest to their
        centre: a start for the projection that costs one gather instead of a k-d tree query.
        Points off the grid use the tree."""
        margin = max(abs(self.right_edge), abs(self.left_edge)) + 20.0
        lo = node_xy.min(axis=0) - margin
        shape = np.ceil((node_xy.max(axis=0) + margin - lo) / SEED_GRID_RESOLUTION).astype(int) + 1
        self._grid_origin = lo
        if int(shape[0]) * int(shape[1]) > SEED_GRID_MAX_CELLS:
            self._grid = None
            return
        gx, gy = np.meshgrid(np.arange(shape[0]), np.arange(shape[1]), indexing="ij")
        centres = lo + (np.column_stack([gx.ravel(), gy.ravel()]) + 0.5) * SEED_GRID_RESOLUTION
        dist, idx = self._tree.query(centres, workers=-1)
        idx = np.where(dist <= margin, idx, -1)  # far from the road: defer to the tree
        self._grid = idx.reshape(shape).astype(np.int32)
        # the least distance from the centerline of any point of a cell: its centre's distance to the
        # nearest curve sample, less half the cell's diagonal and half the longest arc between samples
        # (the foot of the point lies within that of a sample); of a point off the grid, or in a cell
        # beyond ``margin``, at least ``margin`` less the same
        arcs = np.diff(self._nodes)
        if self.closed and len(self._nodes):
            arcs = np.append(arcs, self.length - self._nodes[-1] + self._nodes[0])
        slack = SEED_GRID_RESOLUTION * math.sqrt(0.5) + 0.5 * (float(arcs.max()) if len(arcs) else 0.0)
        self._grid_clearance = (np.minimum(dist, margin) - slack).reshape(shape)
        self._offgrid_clearance = float(margin - slack)

    def projection_kernel_args(self) -> tuple | None:
        """The arguments of ``tracker.preprocess.road_filter_kernel`` that describe this road's
        projection without a hint (as ``_project``'s: the seed grid, the stored curve samples, the curve
        kernels' arrays, Newton's constants), from the seed grid's origin to ``min_denominator``; None
        when the road has no seed grid (the k-d tree seeds every point)."""
        if self._grid is None:
            return None
        args = self.__dict__.get("_projection_kernel_args")
        if args is None:
            kind, *curve = self._curve.kernel_args()
            args = self.__dict__["_projection_kernel_args"] = (
                self._grid_origin, 1.0 / SEED_GRID_RESOLUTION, self._grid, self._node_frame, self._nodes, kind,
                self.closed, self.length, self._ends_array, *curve, PROJECTION_MAX_ITERATIONS, PROJECTION_TOLERANCE,
                PROJECTION_MAX_STEP, PROJECTION_MIN_DENOMINATOR)
        return args

    def clearance_kernel_args(self) -> tuple[np.ndarray, float, float] | None:
        """``(clearance, offgrid, extent)`` for ``tracker.preprocess.road_filter_kernel``: per seed-grid
        cell the least distance (m) from the centerline of any point in it, the same for points off the
        grid (or in its cells beyond its margin), and the largest ``|n|`` of an edge (m). A point whose
        clearance exceeds ``extent`` plus a road margin lies off the road: it needs no projection. None
        when the road has no seed grid."""
        if self._grid is None:
            return None
        extent = max(abs(self.right_edge), abs(self.left_edge))
        return self._grid_clearance, self._offgrid_clearance, float(extent)

    def seed_missing(self, pts: np.ndarray, s: np.ndarray, missing: np.ndarray) -> None:
        """Newton's starts ``s`` (in place) of the points ``pts (N, 2)`` in G that the seed grid does not
        cover (``missing``): the first step from the k-d tree's nearest curve sample."""
        if missing.any():
            node = self._tree.query(pts[missing], workers=-1 if missing.sum() > 2000 else 1)[1]
            s[missing] = node_seed_kernel(np.ascontiguousarray(pts[missing]), node, self._node_frame, self._nodes,
                                          PROJECTION_MIN_DENOMINATOR)

    def _project(self, pts: np.ndarray, s_start: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """``(s, n)`` of points ``pts (N, 2)`` in G: Newton's iterations (``project_kernel``) from the
        starts ``s_start``, or without them from the seed grid's curve sample (``seed_kernel``; the k-d
        tree's off the grid). Points where Newton does not converge are retried from the global search
        (a bad hint) or found by bisection (``_project_bracketed``)."""
        pts = np.ascontiguousarray(pts, dtype=float)
        if s_start is not None:
            s = np.array(s_start, dtype=float)
        elif self._grid is not None:
            s, missing = seed_kernel(pts, self._grid_origin, 1.0 / SEED_GRID_RESOLUTION, self._grid, self._node_frame,
                                     self._nodes, PROJECTION_MIN_DENOMINATOR)
            self.seed_missing(pts, s, missing)
        else:
            s = np.empty(len(pts))
            self.seed_missing(pts, s, np.ones(len(pts), dtype=bool))
        kind, *curve = self._curve.kernel_args()
        s, lateral, pending = project_kernel(
            kind, pts, s, self.closed, self.length, self._ends_array, *curve, PROJECTION_MAX_ITERATIONS,
            PROJECTION_TOLERANCE, PROJECTION_MAX_STEP, PROJECTION_MIN_DENOMINATOR)
        if not pending.any():
            return s, lateral
        if s_start is not None:  # a bad hint: retry these points from the global search
            s[pending], lateral[pending] = self._project(pts[pending], None)
        else:  # near a centre of curvature Newton may wander: bracket the nearest sample instead
            s[pending], lateral[pending] = self._project_bracketed(pts[pending])
        return s, lateral

    def _project_bracketed(self, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Robust projection: bisection for ``(p - c(s)) . t(s) = 0`` within one cell length of the
        nearest curve sample (the k-d tree's exact answer). Used where Newton did not converge."""
        half = float(np.max(np.diff(self._curve.starts))) * 1.01
        centre = self._nodes[self._tree.query(pts)[1]].astype(float)
        lo, hi = centre - half, centre + half
        if not self.closed:
            lo, hi = np.maximum(lo, 0.0), np.minimum(hi, self.length)

        def along_and_distance(s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            xy, tangent, _ = self._frame_flat(self.wrap_s(s), extrapolate=True)
            d = pts - xy
            return (d * tangent).sum(axis=1), np.hypot(d[:, 0], d[:, 1]), d[:, 1] * tangent[:, 0] - d[:, 0] * tangent[:, 1]

        g_lo = along_and_distance(lo)[0]
        for _ in range(BISECTION_ITERATIONS):
            mid = 0.5 * (lo + hi)
            g_mid = along_and_distance(mid)[0]
            right = (g_mid > 0) == (g_lo > 0)
            lo, g_lo = np.where(right, mid, lo), np.where(right, g_mid, g_lo)
            hi = np.where(right, hi, mid)
        # no sign change in the bracket (minimum at an end of it): keep the nearest of the candidates
        cands = np.stack([0.5 * (lo + hi), centre - half, centre + half])
        if not self.closed:
            cands = np.clip(cands, 0.0, self.length)
        results = [along_and_distance(c) for c in cands]
        best = np.argmin(np.stack([r[1] for r in results]), axis=0)
        rows = np.arange(len(pts))
        s_best = cands[best, rows]
        n_best = np.stack([r[2] for r in results])[best, rows]
        return self.wrap_s(s_best), n_best

    def _to_frenet1(self, x: float, y: float, hint: float | None) -> tuple[float, float] | None:
        """Pure-Python projection of one point; ``None`` if it did not converge (caller falls back)."""
        if hint is None:
            node = -1
            if self._grid is not None:
                gi = math.floor((x - self._grid_origin[0]) * (1.0 / SEED_GRID_RESOLUTION))
                gj = math.floor((y - self._grid_origin[1]) * (1.0 / SEED_GRID_RESOLUTION))
                if 0 <= gi < self._grid.shape[0] and 0 <= gj < self._grid.shape[1]:
                    node = int(self._grid[gi, gj])
            if node < 0:
                node = int(self._tree.query((x, y))[1])
            s = float(self._nodes[node])
        else:
            s = hint
        length = self.length
        for _ in range(PROJECTION_MAX_ITERATIONS):
            px, py, c, sn, kappa = self.frame1(s)
            dx, dy = x - px, y - py
            along = dx * c + dy * sn
            lateral = dy * c - dx * sn
            denom = 1.0 - kappa * lateral
            if denom < PROJECTION_MIN_DENOMINATOR:
                denom = PROJECTION_MIN_DENOMINATOR
            ds = along / denom
            if ds > PROJECTION_MAX_STEP:
                ds = PROJECTION_MAX_STEP
            elif ds < -PROJECTION_MAX_STEP:
                ds = -PROJECTION_MAX_STEP
            s += ds
            if self.closed:
                s %= length
            if -PROJECTION_TOLERANCE < ds < PROJECTION_TOLERANCE:
                return s, lateral
        return None

    # -- the paper's local polynomials and Euler conversion -------------------------------------
    def _local_fit(self, s0: float, quantity: int, ahead: float, behind: float) -> np.ndarray:
        d = np.linspace(-behind, ahead, POLY_SAMPLES)
        _, tangent, kappa = self._frame_flat(float(s0) + d, extrapolate=True)
        if quantity == 1:
            _, t0, _ = self._frame_flat(np.array([float(s0)]), extrapolate=True)
            theta0 = float(np.arctan2(t0[0, 1], t0[0, 0]))
            theta = np.arctan2(tangent[:, 1], tangent[:, 0])
            values = theta0 + np.unwrap(wrap_angle(theta - theta0))
        else:
            values = kappa
        return np.polyfit(d, values, 3)

    def heading_poly(self, s0: float, horizon: float = POLY_HORIZON, behind: float = 0.0) -> np.ndarray:
        """The paper's local heading polynomial around ``s0``: coefficients ``[a, b, c, d]`` with
        ``theta(s) ~= a u^3 + b u^2 + c u + d``, ``u = s - s0`` (m), least-squares over
        ``u in [-behind, horizon]`` (default: the 30 m ahead, as in the paper). Unwrapped angles (rad)."""
        return self._local_fit(s0, 1, horizon, behind)

    def curvature_poly(self, s0: float, horizon: float = POLY_HORIZON, behind: float = 0.0) -> np.ndarray:
        """The paper's local curvature polynomial around ``s0``, like ``heading_poly`` (1/m)."""
        return self._local_fit(s0, 2, horizon, behind)

    def frame_euler(self, s: ArrayLike, s0: float, step: float = 0.5, horizon: float = POLY_HORIZON) -> tuple[np.ndarray, np.ndarray]:
        """The paper's Algorithm 1 without the lateral offset: centerline points ``s.shape + (2,)`` in G
        and headings ``s.shape`` (rad) at arc lengths ``s``, integrated in Euler steps of ``step`` metres
        from the centerline point at ``s0`` along the local cubic heading polynomial (``heading_poly``
        fitted over ``[s0 - horizon, s0 + horizon]``); the heading is the polynomial's. Vectorised."""
        s_arr = finite_array(s, "s")
        if not step > 0:
            raise ValueError(f"step must be > 0 m; got {step!r}")
        shape = s_arr.shape
        s = s_arr.reshape(-1)
        s0 = float(s0)
        d = s - s0
        if self.closed:
            d = wrap_angle(d * (2.0 * np.pi / self.length)) * (self.length / (2.0 * np.pi))
        poly = self.heading_poly(s0, horizon, behind=horizon)
        start = self._frame_flat(np.array([s0]), extrapolate=True)[0][0]
        k_max = int(math.ceil(float(np.max(np.abs(d), initial=0.0)) / step)) + 1
        nodes = step * np.arange(1, k_max + 1)
        # right-Riemann Euler sums along the node grid, forward and backward from s0 (Algorithm 1)
        cum = {}
        for sign in (1.0, -1.0):
            th = np.polyval(poly, sign * nodes)
            steps = sign * step * np.column_stack([np.cos(th), np.sin(th)])
            cum[sign] = np.vstack([[0.0, 0.0], np.cumsum(steps, axis=0)])
        sign = np.where(d >= 0.0, 1.0, -1.0)
        k = np.floor(np.abs(d) / step).astype(int)
        rem = np.abs(d) - k * step
        base = np.where(sign[:, None] > 0, cum[1.0][k], cum[-1.0][k])
        theta_end = np.polyval(poly, d)
        tail = (sign * rem)[:, None] * np.column_stack([np.cos(theta_end), np.sin(theta_end)])
        center = start + base + tail
        return center.reshape(shape + (2,)), theta_end.reshape(shape)

    def _to_cartesian_euler(self, s: np.ndarray, n: np.ndarray, s0: float, step: float, horizon: float) -> np.ndarray:
        center, theta = self.frame_euler(s, s0, step, horizon)
        return center + n[:, None] * np.column_stack([-np.sin(theta), np.cos(theta)])
