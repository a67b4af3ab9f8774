"""Road centerlines parameterised by arc length: a cubic Hermite spline and a curvature profile.

Both curves are cut into *cells* a metre or two long. A cell stores what is needed to evaluate the
curve anywhere inside it in closed form, so one query costs a cell lookup plus a few polynomial or
trigonometric evaluations:

- ``HermiteCenterline``: per cell, a cubic ``tau(s)`` (Hermite interpolation of the inverse of the
  arc length, with exact end slopes ``1/|r'(tau)|``) and the spline segment's cubic coefficients.
  Positions are always exactly on the spline; heading and curvature come from the spline's first and
  second derivatives. Cell ends are placed by Gauss-Legendre quadrature of ``|r'|``.
- ``ClothoidCenterline``: per cell, the start position, heading, curvature and curvature rate.
  Heading is the exact quadratic, curvature the exact linear function of ``s``; the position inside
  a cell is the Gauss-Legendre integral of ``(cos theta, sin theta)``.

Every curve offers ``frame(s)`` for an array of ``s`` (one call of the compiled kernel ``curve_frame``)
and a pure-Python ``frame1(s)`` for one point (a call's overhead would dominate single queries, which
highway-env makes ~170 times per frame). ``s`` must already lie in ``[0, length]``: wrapping and
extrapolation are the Road's job.

The module also holds the compiled kernels that evaluate the road on these curves: its frame beyond
an open road's ends, the projection of points on the centerline (``Road.to_frenet``) and a state's
rectangle in the ego's frame (``tracker.measurement``).
"""

from __future__ import annotations

import bisect
import math

import numpy as np
from scipy.interpolate import CubicSpline

from tracker.jit import njit
from tracker.geometry import corner_offset
from tracker.ukf import all_finite, sigma_kernel

#: Gauss-Legendre nodes and weights on [0, 1] used to integrate inside one cell.
_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)
GL_NODES = 0.5 * (_GL_X + 1.0)
GL_WEIGHTS = 0.5 * _GL_W
#: Fewer nodes inside a clothoid cell (<= CLOTHOID_CELL_LENGTH): the 4-point rule's error bound
#: ``h^9 (4!)^4 / (9 (8!)^3) max|f^(8)|`` with ``|f^(8)| <= (|kappa| + h |dkappa/ds|)^8`` is below
#: 1e-12 m for h = 2 m and curvature radii down to 5 m.
_GL4_X, _GL4_W = np.polynomial.legendre.leggauss(4)
GL4_NODES = 0.5 * (_GL4_X + 1.0)
GL4_WEIGHTS = 0.5 * _GL4_W
_GL4_NODES = tuple(float(v) for v in GL4_NODES)
_GL4_WEIGHTS = tuple(float(v) for v in GL4_WEIGHTS)

#: Largest heading change (rad) inside one clothoid cell; cells shrink on tight curves to keep it.
CLOTHOID_MAX_TURN = 0.25
#: Bucket length (m) of the cell lookup table.
BUCKET_LENGTH = 0.5
#: Target cell length (m) of a Hermite centerline; cells are uniform in the spline parameter.
HERMITE_CELL_LENGTH = 1.0
#: Target cell length (m) of a curvature-profile centerline.
CLOTHOID_CELL_LENGTH = 2.0


class _Cells:
    """Cell lookup shared by both curves: ``starts`` (K+1,) cell boundaries in arc length."""

    starts: np.ndarray
    _starts_list: list[float]
    length: float

    def _set_starts(self, starts: np.ndarray) -> None:
        self.starts = starts
        self._starts_list = starts[:-1].tolist()
        self.length = float(starts[-1])
        # bucket table: uniform buckets of BUCKET_LENGTH m, each mapped to the cell holding its start;
        # a query then needs one gather plus a few comparisons instead of a binary search
        n_buckets = int(math.ceil(self.length / BUCKET_LENGTH)) + 1
        self._bucket = self.length / (n_buckets - 1) if n_buckets > 1 else 1.0
        edges = np.arange(n_buckets + 1) * self._bucket
        first = np.clip(np.searchsorted(starts, edges, side="right") - 1, 0, len(starts) - 2)
        self._bucket_cell = first[:-1]
        self._bucket_hops = int(np.max(first[1:] - first[:-1])) if n_buckets > 0 else 0
        self._starts_next = np.append(starts[1:], np.inf)

    def _lookup(self) -> tuple:
        """The bucket lookup's arrays and numbers, for the compiled kernels."""
        return (self._bucket_cell, self._starts_next, 1.0 / self._bucket, self._bucket_hops)

    def kernel_args(self) -> tuple:
        """``(kind, table, bucket_cell, starts_next, inv_bucket, hops, nodes, weights)``: the
        arguments of ``tracker.centerline``'s curve kernels around ``s`` (``kind``: its
        ``CLOTHOID`` or ``HERMITE``). Built once (a centerline does not change after construction):
        the tracker asks for them several times per frame."""
        args = self.__dict__.get("_kernel_args")
        if args is None:
            kind = CLOTHOID if isinstance(self, ClothoidCenterline) else HERMITE
            args = self.__dict__["_kernel_args"] = (kind, self._table, *self._lookup(), GL4_NODES, GL4_WEIGHTS)
        return args

    def frame(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position (N, 2) m, unit tangent (N, 2) and curvature (N,) 1/m at ``s`` in [0, length]
        (``curve_frame``: per ``s`` its cell's closed form)."""
        kind, *rest = self.kernel_args()
        return curve_frame(kind, np.ascontiguousarray(s, dtype=float), *rest)

    def locate(self, s: np.ndarray) -> np.ndarray:
        """Cell index of each ``s`` in [0, length] (vectorised)."""
        k = np.minimum((s * (1.0 / self._bucket)).astype(np.intp), len(self._bucket_cell) - 1)
        idx = self._bucket_cell[np.maximum(k, 0)]
        last = len(self.starts) - 2
        for _ in range(self._bucket_hops):
            idx = idx + (s >= self._starts_next[idx])
        return np.minimum(idx, last)

    def locate1(self, s: float) -> int:
        """Cell index of one ``s`` in [0, length]."""
        idx = bisect.bisect_right(self._starts_list, s) - 1
        return 0 if idx < 0 else idx

    def nodes(self) -> np.ndarray:
        """Arc length of every cell boundary, (K+1,) m: the curve's sample points."""
        return self.starts.copy()


class HermiteCenterline(_Cells):
    """A piecewise cubic centerline ``r_k(tau) = sum_j c_kj tau^j``, ``tau`` in [0, 1] per segment.

    ``coeffs`` has shape (M, 4, 2): for each of the M segments, the power-basis coefficients of x and
    y in the local parameter. The curve is re-parameterised by arc length ``s`` in [0, length].
    """

    def __init__(self, coeffs: np.ndarray, closed: bool) -> None:
        self.closed = closed
        self.coeffs = np.asarray(coeffs, dtype=float)
        seg_len = self._segment_lengths(self.coeffs)
        cells_per_seg = np.maximum(1, np.ceil(seg_len / HERMITE_CELL_LENGTH).astype(int))
        seg_of_cell = np.repeat(np.arange(len(seg_len)), cells_per_seg)
        first = np.concatenate([[0], np.cumsum(cells_per_seg)[:-1]])
        local = np.arange(len(seg_of_cell)) - np.repeat(first, cells_per_seg)
        tau_a = local / cells_per_seg[seg_of_cell]
        tau_b = (local + 1) / cells_per_seg[seg_of_cell]
        c = self.coeffs[seg_of_cell]  # (K, 4, 2)
        cell_len = self._arc_length(c, tau_a, tau_b)
        starts = np.concatenate([[0.0], np.cumsum(cell_len)])
        self._set_starts(starts)
        #: arc length of each waypoint, (M,) m (an open road's last waypoint is at ``length``)
        self.joins = starts[first] if closed else np.append(starts[first], starts[-1])
        speed_a = np.linalg.norm(self._d1(c, tau_a), axis=1)
        speed_b = np.linalg.norm(self._d1(c, tau_b), axis=1)
        if np.any(speed_a <= 1e-12) or np.any(speed_b <= 1e-12):
            raise ValueError("waypoints give a spline with a cusp (zero speed); check headings and spacing")
        # tau(d) on d in [0, h]: cubic Hermite with tau(0)=ta, tau(h)=tb, tau'(0)=1/|r'(ta)|, tau'(h)=1/|r'(tb)|
        h = cell_len
        m0, m1 = 1.0 / speed_a, 1.0 / speed_b
        dtau = tau_b - tau_a
        q0 = tau_a
        q1 = m0
        q2 = (3.0 * dtau / h - 2.0 * m0 - m1) / h
        q3 = (m0 + m1 - 2.0 * dtau / h) / h**2
        self.tau_poly = np.stack([q0, q1, q2, q3], axis=1)  # (K, 4)
        self.cell_coeffs = c
        self.segment_of_cell = seg_of_cell
        # plain-Python copies for frame1
        self._tau_list = self.tau_poly.tolist()
        self._coef_list = [tuple(row) for row in c.reshape(len(c), 8).tolist()]
        self._table = np.column_stack([starts[:-1], self.tau_poly, c.reshape(len(c), 8)])

    # -- spline algebra -------------------------------------------------------------------------
    @staticmethod
    def _d1(c: np.ndarray, t: np.ndarray) -> np.ndarray:
        t = t[:, None]
        return (3.0 * c[:, 3] * t + 2.0 * c[:, 2]) * t + c[:, 1]

    @classmethod
    def _arc_length(cls, c: np.ndarray, ta: np.ndarray, tb: np.ndarray) -> np.ndarray:
        """Arc length of each piece ``c[i]`` between ``ta[i]`` and ``tb[i]`` (8-point Gauss-Legendre)."""
        span = tb - ta
        t = ta[:, None] + span[:, None] * GL_NODES[None, :]  # (K, G)
        k, g = t.shape
        d1 = cls._d1(np.repeat(c, g, axis=0), t.reshape(-1)).reshape(k, g, 2)
        return span * (np.linalg.norm(d1, axis=2) @ GL_WEIGHTS)

    @classmethod
    def _segment_lengths(cls, coeffs: np.ndarray, pieces: int = 32) -> np.ndarray:
        m = len(coeffs)
        edges = np.linspace(0.0, 1.0, pieces + 1)
        c = np.repeat(coeffs, pieces, axis=0)
        ta = np.tile(edges[:-1], m)
        tb = np.tile(edges[1:], m)
        return cls._arc_length(c, ta, tb).reshape(m, pieces).sum(axis=1)

    def parameter(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Spline segment index and local parameter ``tau`` in [0, 1] of arc lengths ``s``."""
        cell = self.locate(s)
        q = self.tau_poly[cell]
        d = s - self.starts[cell]
        return self.segment_of_cell[cell], ((q[:, 3] * d + q[:, 2]) * d + q[:, 1]) * d + q[:, 0]

    # -- evaluation -----------------------------------------------------------------------------
    def frame1(self, s: float) -> tuple[float, float, float, float, float]:
        """One point: ``(x, y, cos theta, sin theta, kappa)`` at ``s`` (pure Python)."""
        cell = self.locate1(s)
        d = s - self._starts_list[cell]
        q0, q1, q2, q3 = self._tau_list[cell]
        t = ((q3 * d + q2) * d + q1) * d + q0
        x0, y0, x1, y1, x2, y2, x3, y3 = self._coef_list[cell]
        x = ((x3 * t + x2) * t + x1) * t + x0
        y = ((y3 * t + y2) * t + y1) * t + y0
        dx = (3.0 * x3 * t + 2.0 * x2) * t + x1
        dy = (3.0 * y3 * t + 2.0 * y2) * t + y1
        ddx = 6.0 * x3 * t + 2.0 * x2
        ddy = 6.0 * y3 * t + 2.0 * y2
        speed = math.hypot(dx, dy)
        return x, y, dx / speed, dy / speed, (dx * ddy - dy * ddx) / speed**3

    # -- construction ---------------------------------------------------------------------------
    @classmethod
    def through(cls, xy: np.ndarray, headings: np.ndarray | None, closed: bool) -> HermiteCenterline:
        """The cubic Hermite spline through waypoints ``xy`` (M, 2).

        Without ``headings`` the tangents are those of the C2 cubic spline in the chord-length
        parameter ("not-a-knot" ends on an open road, periodic on a closed one): curvature is continuous.
        With ``headings`` (M,) rad the tangent directions are given; their magnitudes are chosen by
        regularised least squares so that the curvature is continuous across joins where the data
        allow it (``_g2_magnitudes``).
        """
        pts = np.vstack([xy, xy[:1]]) if closed else xy
        chord = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        if headings is None:
            t = np.concatenate([[0.0], np.cumsum(chord)])
            spline = CubicSpline(t, pts, axis=0, bc_type="periodic" if closed else "not-a-knot")
            # spline.c: (4, M-1, 2), highest power first in (t - t_k); rescale to tau = (t - t_k) / h_k
            h = chord[None, :, None]
            powers = np.arange(3, -1, -1)[:, None, None]
            c = spline.c * h**powers  # now in tau, highest power first
            coeffs = np.transpose(c[::-1], (1, 0, 2))  # (M-1, 4, 2) lowest power first
            return cls(coeffs, closed)
        th = np.concatenate([headings, headings[:1]]) if closed else np.asarray(headings, dtype=float)
        tangents = np.stack([np.cos(th), np.sin(th)], axis=1)
        a = _g2_magnitudes(pts, tangents, chord, closed)
        p0, p1 = pts[:-1], pts[1:]
        d0 = (a[:-1] * chord)[:, None] * tangents[:-1]
        d1 = (a[1:] * chord)[:, None] * tangents[1:]
        coeffs = np.stack([p0, d0, 3.0 * (p1 - p0) - 2.0 * d0 - d1, 2.0 * (p0 - p1) + d0 + d1], axis=1)
        return cls(coeffs, closed)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


#: Weight of the pull of each tangent magnitude toward the chord length in ``_g2_magnitudes``.
G2_REGULARISATION = 1e-3
#: Bounds on the tangent magnitude relative to the chord length.
G2_MAGNITUDE_BOUNDS = (0.25, 4.0)


def _g2_magnitudes(pts: np.ndarray, tangents: np.ndarray, chord: np.ndarray, closed: bool) -> np.ndarray:
    """Tangent magnitudes ``a_i`` (relative to the chord) for a G2 Hermite spline with given headings.

    With ``r'`` = ``a_i T_i`` per metre at knot i, the curvature from the left and right segments is
    ``cross(T_i, r'')/a_i^2``; equality is linear in ``a_{i-1}, a_{i+1}``:
    ``2 a_{i-1} T_i x T_{i-1} / h_{i-1} + 2 a_{i+1} T_i x T_{i+1} / h_i
    = 6 T_i x dP_{i-1} / h_{i-1}^2 + 6 T_i x dP_i / h_i^2``.
    Solved in the least-squares sense with a small pull toward ``a = 1``; clipped to
    ``G2_MAGNITUDE_BOUNDS``. Where the headings admit no G2 spline, curvature jumps remain.
    """
    m = len(pts)  # knots (closed: last == first)
    dp = np.diff(pts, axis=0)
    scale = float(np.mean(chord))
    rows, rhs = [], []
    knots = range(1, m - 1) if not closed else range(0, m - 1)
    nvar = m if not closed else m - 1
    for i in knots:  # one equation per interior knot: O(M) setup, solved once at construction
        im1 = (i - 1) % (m - 1) if closed else i - 1
        ip1 = (i + 1) % (m - 1) if closed else i + 1
        h_l, h_r = chord[im1], chord[i]
        row = np.zeros(nvar)
        row[im1 % nvar] += 2.0 * _cross(tangents[i], tangents[im1]) / h_l * scale
        row[ip1 % nvar] += 2.0 * _cross(tangents[i], tangents[ip1]) / h_r * scale
        rows.append(row)
        rhs.append((6.0 * _cross(tangents[i], dp[im1]) / h_l**2 + 6.0 * _cross(tangents[i], dp[i]) / h_r**2) * scale)
    lam = math.sqrt(G2_REGULARISATION)
    a_mat = np.vstack([np.array(rows).reshape(-1, nvar), lam * np.eye(nvar)])
    b_vec = np.concatenate([np.array(rhs), lam * np.ones(nvar)])
    a = np.linalg.lstsq(a_mat, b_vec, rcond=None)[0]
    a = np.clip(a, *G2_MAGNITUDE_BOUNDS)
    return np.concatenate([a, a[:1]]) if closed else a


class ClothoidCenterline(_Cells):
    """A centerline from a curvature profile: pieces of linearly varying curvature (clothoids).

    ``segments`` rows are ``(length m, kappa_start 1/m, kappa_end 1/m)``; ``start`` is
    ``(x, y, heading)`` of the first point. Straights (0, 0), arcs (k, k) and ramps (k0 != k1).
    """

    def __init__(self, segments: np.ndarray, start: tuple[float, float, float], closed: bool) -> None:
        self.closed = closed
        seg = np.asarray(segments, dtype=float)
        lengths, k0, k1 = seg[:, 0], seg[:, 1], seg[:, 2]
        rate = (k1 - k0) / lengths  # dkappa/ds per segment
        k_max = np.maximum(np.abs(k0), np.abs(k1))
        cell_len = np.minimum(CLOTHOID_CELL_LENGTH, CLOTHOID_MAX_TURN / np.maximum(k_max, 1e-12))
        n_cells = np.maximum(1, np.ceil(lengths / cell_len).astype(int))
        seg_of_cell = np.repeat(np.arange(len(seg)), n_cells)
        first = np.concatenate([[0], np.cumsum(n_cells)[:-1]])
        local = np.arange(len(seg_of_cell)) - np.repeat(first, n_cells)
        h = lengths[seg_of_cell] / n_cells[seg_of_cell]
        d_in_seg = local * h  # distance from segment start to cell start
        kap = k0[seg_of_cell] + rate[seg_of_cell] * d_in_seg
        # heading at each segment start: theta0 + integral of kappa over preceding segments
        seg_turn = 0.5 * (k0 + k1) * lengths
        seg_theta = start[2] + np.concatenate([[0.0], np.cumsum(seg_turn)[:-1]])
        kr = rate[seg_of_cell]
        theta = (
            seg_theta[seg_of_cell]
            + k0[seg_of_cell] * d_in_seg
            + 0.5 * kr * d_in_seg**2
        )
        # cell displacement by Gauss-Legendre, then cumulative positions
        d = h[:, None] * GL_NODES[None, :]
        th = theta[:, None] + kap[:, None] * d + 0.5 * kr[:, None] * d**2
        disp = h[:, None] * np.stack([np.cos(th) @ GL_WEIGHTS, np.sin(th) @ GL_WEIGHTS], axis=1)
        pos = np.vstack([[start[0], start[1]], start[:2] + np.cumsum(disp, axis=0)])
        self.cell_xy = pos[:-1]
        self.end_xy = pos[-1]
        self.end_heading = float(seg_theta[-1] + seg_turn[-1])
        self.cell_theta = theta
        self.cell_cos, self.cell_sin = np.cos(theta), np.sin(theta)
        self.cell_kappa = kap
        self.cell_rate = kr
        self._set_starts(np.concatenate([[0.0], np.cumsum(h)]))
        #: arc length of each segment start, (M,) m
        self.joins = np.concatenate([[0.0], np.cumsum(lengths)[:-1]])
        self._cell_list = np.column_stack([self.cell_xy, theta, kap, kr]).tolist()
        self._table = np.column_stack([self.starts[:-1], self.cell_xy, self.cell_cos, self.cell_sin, kap, kr])

    def frame1(self, s: float) -> tuple[float, float, float, float, float]:
        """One point: ``(x, y, cos theta, sin theta, kappa)`` at ``s`` (pure Python)."""
        cell = self.locate1(s)
        d = s - self._starts_list[cell]
        x, y, th0, k0, kr = self._cell_list[cell]
        cx = sx = 0.0
        for node, weight in zip(_GL4_NODES, _GL4_WEIGHTS):
            u = d * node
            th = th0 + (k0 + 0.5 * kr * u) * u
            cx += weight * math.cos(th)
            sx += weight * math.sin(th)
        th = th0 + (k0 + 0.5 * kr * d) * d
        return x + d * cx, y + d * sx, math.cos(th), math.sin(th), k0 + kr * d


# --------------------------------------------------------------------------------------------------
# The compiled kernels of this stage.
#
# The curve at arc length ``s``: its cell by the bucket lookup, then the cell's closed form (a
# clothoid cell's heading quadratic, curvature line and Gauss-Legendre position integral; a Hermite
# cell's cubic ``tau(s)`` and the spline's derivatives): ``curve_frame`` for ``frame``. The road's
# frame beyond an open road's ends and across a closed road's seam (``road_frame_at``); the projection
# of points on the centerline (``seed_kernel``, ``node_seed_kernel``, ``project_kernel``); a state's
# rectangle in the ego's frame E (``to_vehicle_kernel``, ``rectangles_kernel``,
# ``sigma_rectangles_kernel``).
# --------------------------------------------------------------------------------------------------


@njit(inline="always")
def _locate(s, bucket_cell, starts_next, inv_bucket, hops, last):
    """Index of the cell holding ``s``: the cell of ``s``'s bucket, then at most ``hops`` cells on
    while ``s`` lies at or beyond the next cell's start; at most ``last``."""
    k = min(int(s * inv_bucket), len(bucket_cell) - 1)
    idx = bucket_cell[max(k, 0)]
    for _ in range(hops):
        if s >= starts_next[idx]:
            idx += 1
    return min(idx, last)


@njit(inline="always")
def _cos_sin_small_scalar(phi):
    """``cos`` and ``sin`` of a small angle (``|phi| <= CLOTHOID_MAX_TURN`` plus rounding) by their
    Taylor series to ``phi^10`` and ``phi^11``: error below 1e-14 for ``|phi| <= 0.3`` rad."""
    p2 = phi * phi
    cos = 1.0 + p2 * (-1 / 2 + p2 * (1 / 24 + p2 * (-1 / 720 + p2 * (1 / 40320 - p2 / 3628800))))
    sin = phi * (1.0 + p2 * (-1 / 6 + p2 * (1 / 120 + p2 * (-1 / 5040 + p2 * (1 / 362880 - p2 / 39916800)))))
    return cos, sin


@njit(inline="always")
def _frame_arrays(count):
    """Empty outputs of a frame kernel: positions and unit tangents ``(count, 2)``, curvatures ``(count,)``."""
    return np.empty((count, 2)), np.empty((count, 2)), np.empty(count)


@njit(inline="always")
def clothoid_at(s, table, bucket_cell, starts_next, inv_bucket, hops, nodes, weights):
    """Position, unit tangent and curvature ``(x, y, tx, ty, kappa)`` of a clothoid centerline at one
    ``s`` in [0, length]; ``table`` rows ``(start, x, y, cos0, sin0, kappa0, rate)`` per cell.

    At ``d = s - start`` into the cell the heading is ``theta0 + phi(d)``, ``phi(u) = kappa0 u + rate u^2
    / 2``, the curvature ``kappa0 + rate d``, and the position ``(x, y) + d * R(theta0) mean_u (cos phi,
    sin phi)`` over ``[0, d]`` (the Gauss-Legendre rule ``nodes``, ``weights`` on [0, 1]). Cells are
    short enough that ``|phi| <= CLOTHOID_MAX_TURN``: ``cos phi`` and ``sin phi`` come from their Taylor
    series (``_cos_sin_small_scalar``), rotated by ``theta0``."""
    row = table[_locate(s, bucket_cell, starts_next, inv_bucket, hops, len(table) - 1)]
    d = s - row[0]
    cos0, sin0, k0, kr = row[3], row[4], row[5], row[6]
    ic = 0.0
    is_ = 0.0
    for g in range(len(nodes)):
        dd = d * nodes[g]
        c, sn = _cos_sin_small_scalar((k0 + 0.5 * kr * dd) * dd)
        ic += c * weights[g]
        is_ += sn * weights[g]
    ce, se = _cos_sin_small_scalar((k0 + 0.5 * kr * d) * d)
    return (row[1] + d * (cos0 * ic - sin0 * is_), row[2] + d * (sin0 * ic + cos0 * is_),
            cos0 * ce - sin0 * se, sin0 * ce + cos0 * se, k0 + kr * d)


@njit(inline="always")
def hermite_at(s, table, bucket_cell, starts_next, inv_bucket, hops, nodes, weights):
    """``(x, y, tx, ty, kappa)`` of a Hermite centerline at one ``s`` in [0, length]; ``table`` rows
    ``(start, q0..q3, x0, y0, x1, y1, x2, y2, x3, y3)`` per cell. The spline parameter is the cell's
    cubic ``tau(d) = q0 + q1 d + q2 d^2 + q3 d^3`` at ``d = s - start``; the position is the segment's
    cubic ``r(tau)``, the tangent ``r'/|r'|``, the curvature ``(r' x r'') / |r'|^3``. (``nodes`` and
    ``weights`` unused: the signature of ``clothoid_at``.)"""
    row = table[_locate(s, bucket_cell, starts_next, inv_bucket, hops, len(table) - 1)]
    d = s - row[0]
    tau = ((row[4] * d + row[3]) * d + row[2]) * d + row[1]
    x0, y0, x1, y1, x2, y2, x3, y3 = row[5], row[6], row[7], row[8], row[9], row[10], row[11], row[12]
    dx = (3.0 * x3 * tau + 2.0 * x2) * tau + x1
    dy = (3.0 * y3 * tau + 2.0 * y2) * tau + y1
    ddx = 6.0 * x3 * tau + 2.0 * x2
    ddy = 6.0 * y3 * tau + 2.0 * y2
    speed = np.hypot(dx, dy)
    return (((x3 * tau + x2) * tau + x1) * tau + x0, ((y3 * tau + y2) * tau + y1) * tau + y0,
            dx / speed, dy / speed, (dx * ddy - dy * ddx) / speed**3)


#: curve kinds of the kernels' ``kind`` argument
CLOTHOID, HERMITE = 0, 1


@njit(inline="always")
def curve_at(kind, s, table, bucket_cell, starts_next, inv_bucket, hops, nodes, weights):
    """``clothoid_at`` or ``hermite_at`` by ``kind`` (``CLOTHOID`` or ``HERMITE``)."""
    if kind == CLOTHOID:
        return clothoid_at(s, table, bucket_cell, starts_next, inv_bucket, hops, nodes, weights)
    return hermite_at(s, table, bucket_cell, starts_next, inv_bucket, hops, nodes, weights)


@njit
def curve_frame(kind, s, table, bucket_cell, starts_next, inv_bucket, hops, nodes, weights):
    """Position ``(N, 2)``, unit tangent ``(N, 2)``, curvature ``(N,)`` at ``s (N,)`` in [0, length]."""
    count = len(s)
    p, tangent, kappa = _frame_arrays(count)
    for i in range(count):
        p[i, 0], p[i, 1], tangent[i, 0], tangent[i, 1], kappa[i] = curve_at(
            kind, s[i], table, bucket_cell, starts_next, inv_bucket, hops, nodes, weights)
    return p, tangent, kappa


@njit(inline="always")
def road_frame_at(kind, s, closed, length, ends, table, bucket_cell, starts_next, inv_bucket, hops, nodes, weights):
    """The road's frame ``(x, y, tx, ty, kappa)`` at one ``s`` (``Road.frame(..., extrapolate=True)``):
    wrapped on a closed road; on an open one the frame at ``s`` clipped to [0, length], its position
    moved along the end tangent (``ends`` rows ``(x, y, cos, sin)`` at 0 and at ``length``) and its
    curvature 0 beyond an end."""
    at = s % length if closed else min(max(s, 0.0), length)
    x, y, tx, ty, kappa = curve_at(kind, at, table, bucket_cell, starts_next, inv_bucket, hops, nodes, weights)
    if closed:
        return x, y, tx, ty, kappa
    if s < 0.0:
        return ends[0, 0] + s * ends[0, 2], ends[0, 1] + s * ends[0, 3], tx, ty, 0.0
    if s > length:
        d = s - length
        return ends[1, 0] + d * ends[1, 2], ends[1, 1] + d * ends[1, 3], tx, ty, 0.0
    return x, y, tx, ty, kappa


@njit
def project_kernel(kind, pts, s, closed, length, ends, table, bucket_cell, starts_next, inv_bucket, hops, nodes, weights,
                   max_iterations, tolerance, max_step, min_denominator):
    """The projection of points ``pts (N, 2)`` in G on the centerline: Newton's iterations on
    ``g(s) = (p - c(s)) . t(s) = 0`` from the starts ``s (N,)`` (changed in place). A step is
    ``ds = (d . t) / max(1 - kappa (d x t), min_denominator)`` (``d = p - c(s)``; ``d x t`` is the
    lateral offset ``n``), clipped to ``+-max_step``; ``s`` wraps on a closed road and follows the end
    tangents beyond an open road's ends (``road_frame_at``). Every point takes a step while any point's
    last step was at least ``tolerance`` (lock-step), at most ``max_iterations`` times. Returns ``(s,
    lateral, pending)``: ``lateral`` the ``n`` of the last step's start, ``pending`` the points whose
    last step was not below ``tolerance`` (not converged: the caller's fallback)."""
    count = len(s)
    lateral = np.zeros(count)
    pending = np.ones(count, dtype=np.bool_)
    for _ in range(max_iterations):
        any_pending = False
        for i in range(count):
            x, y, tx, ty, kappa = road_frame_at(kind, s[i] % length if closed else s[i], closed, length, ends, table,
                                                bucket_cell, starts_next, inv_bucket, hops, nodes, weights)
            dx = pts[i, 0] - x
            dy = pts[i, 1] - y
            along = dx * tx + dy * ty
            lat = dy * tx - dx * ty
            denom = max(1.0 - kappa * lat, min_denominator)
            ds = min(max(along / denom, -max_step), max_step)
            s[i] = (s[i] + ds) % length if closed else s[i] + ds
            lateral[i] = lat
            pending[i] = abs(ds) >= tolerance
            any_pending = any_pending or pending[i]
        if not any_pending:
            break
    return s, lateral, pending


@njit
def to_vehicle_kernel(kind, states, ego_x, ego_y, ego_yaw, closed, length, ends, table, bucket_cell, starts_next,
                      inv_bucket, hops, nodes, weights, min_extent):
    """``tracker.measurement.to_vehicle``'s curvilinear exact conversion of ``states (N, 7 or 8)``:
    rectangle centres ``(N, 2)``, headings ``(N,)`` and corners ``(N, 4, 2)`` (of the extent floored
    at ``min_extent``) in E (the frame extrapolated beyond an open road's ends, as
    ``Road.frame(..., extrapolate=True)``)."""
    count = states.shape[0]
    center = np.empty((count, 2))
    psi = np.empty(count)
    corners = np.empty((count, 4, 2))
    c = np.cos(ego_yaw)
    sn = np.sin(ego_yaw)
    for i in range(count):
        x, y, tx, ty, _ = road_frame_at(kind, states[i, 0], closed, length, ends, table, bucket_cell, starts_next,
                                        inv_bucket, hops, nodes, weights)
        theta = np.arctan2(ty, tx)
        n = states[i, 1]
        gx = x - n * np.sin(theta) - ego_x
        gy = y + n * np.cos(theta) - ego_y
        center[i, 0] = c * gx + sn * gy
        center[i, 1] = -sn * gx + c * gy
        psi[i] = theta + states[i, 3] - ego_yaw
        # rectangle_corners of the floored extent
        cp, sp = np.cos(psi[i]), np.sin(psi[i])
        hl, hw = 0.5 * max(states[i, 5], min_extent), 0.5 * max(states[i, 6], min_extent)
        for k in range(4):
            lx, ly = corner_offset(k, hl, hw)
            corners[i, k, 0] = center[i, 0] + cp * lx - sp * ly
            corners[i, k, 1] = center[i, 1] + sp * lx + cp * ly
    return center, psi, corners


@njit
def rectangles_kernel(kind, states, ego_x, ego_y, ego_yaw, closed, length, ends, table, bucket_cell, starts_next,
                      inv_bucket, hops, nodes, weights, min_extent):  # pragma: no cover - compiled
    """``to_vehicle_kernel`` with the rest of ``tracker.measurement.to_vehicle``'s conversion: the
    extent floored at ``min_extent`` (``numpy.maximum``: a NaN stays NaN) and whether every ``s`` is
    finite (checked first; nothing else computed when one is not). Returns ``(center, psi, corners,
    length, width, finite)``."""
    count = states.shape[0]
    for i in range(count):
        if not np.isfinite(states[i, 0]):
            return np.empty((0, 2)), np.empty(0), np.empty((0, 4, 2)), np.empty(0), np.empty(0), False
    center, psi, corners = to_vehicle_kernel(kind, states, ego_x, ego_y, ego_yaw, closed, length, ends, table,
                                             bucket_cell, starts_next, inv_bucket, hops, nodes, weights, min_extent)
    floored_length = np.empty(count)
    floored_width = np.empty(count)
    for i in range(count):
        a, b = states[i, 5], states[i, 6]
        floored_length[i] = a if (a >= min_extent or a != a) else min_extent
        floored_width[i] = b if (b >= min_extent or b != b) else min_extent
    return center, psi, corners, floored_length, floored_width, True


@njit
def sigma_rectangles_kernel(means, covs, scale, angles, period_index, period, kind, ego_x, ego_y, ego_yaw, closed,
                            length, ends, table, bucket_cell, starts_next, inv_bucket, hops, nodes, weights,
                            min_extent):  # pragma: no cover - compiled
    """The sigma points of ``N(means, covs)`` (``tracker.ukf.sigma_kernel``) and their
    rectangles in E (``to_vehicle_kernel``) in one call: ``tracker.update.update_pairs``' first step.
    Returns ``(sigma (C, S, D), center (C, S, 2), psi (C, S), corners (C, S, 4, 2), finite)``;
    ``finite`` False (nothing computed) when a mean or covariance holds a NaN or an infinity."""
    count, dim = means.shape
    if not all_finite(means, covs):
        return np.empty((0, 0, dim)), np.empty((0, 0, 2)), np.empty((0, 0)), np.empty((0, 0, 4, 2)), False
    sigma = sigma_kernel(means, covs, scale, angles, period_index, period)
    points = sigma.shape[1]
    center, psi, corners = to_vehicle_kernel(kind, sigma.reshape(count * points, dim), ego_x, ego_y, ego_yaw, closed,
                                             length, ends, table, bucket_cell, starts_next, inv_bucket, hops, nodes,
                                             weights, min_extent)
    return (sigma, center.reshape(count, points, 2), psi.reshape(count, points),
            corners.reshape(count, points, 4, 2), True)


@njit(inline="always")
def _node_start(x, y, node, node_frame, nodes, min_denominator):  # pragma: no cover - compiled
    """The projection's start for the point ``(x, y)`` from the curve sample ``node``: one Newton step
    from the sample's stored frame (``node_frame`` rows ``(x, y, tx, ty, kappa)``), ``s = s_node + (d .
    t) / max(1 - kappa (d x t), min_denominator)``, ``d`` the point less the sample."""
    dx = x - node_frame[node, 0]
    dy = y - node_frame[node, 1]
    tx, ty, kappa = node_frame[node, 2], node_frame[node, 3], node_frame[node, 4]
    denom = max(1.0 - kappa * (dy * tx - dx * ty), min_denominator)
    return nodes[node] + (dx * tx + dy * ty) / denom


@njit
def seed_kernel(pts, origin, inv_resolution, grid, node_frame, nodes, min_denominator):  # pragma: no cover - compiled
    """The projection's starts of points ``pts (N, 2)`` in G without a hint: per point the curve sample
    its seed-grid cell stores (the sample nearest to the cell's centre; ``grid`` cells of ``1 /
    inv_resolution`` m from ``origin``) and one Newton step from it (``_node_start``). Returns ``(s,
    missing)``: ``missing`` where the point is off the grid or its cell holds no sample (the caller
    seeds those from the k-d tree: ``node_seed_kernel``)."""
    count = pts.shape[0]
    s = np.zeros(count)
    missing = np.zeros(count, dtype=np.bool_)
    for i in range(count):
        cx = np.floor((pts[i, 0] - origin[0]) * inv_resolution)
        cy = np.floor((pts[i, 1] - origin[1]) * inv_resolution)
        node = -1
        if cx >= 0.0 and cy >= 0.0 and cx < grid.shape[0] and cy < grid.shape[1]:
            node = grid[int(cx), int(cy)]
        if node < 0:
            missing[i] = True
            continue
        s[i] = _node_start(pts[i, 0], pts[i, 1], node, node_frame, nodes, min_denominator)
    return s, missing


@njit
def node_seed_kernel(pts, node, node_frame, nodes, min_denominator):  # pragma: no cover - compiled
    """The projection's starts ``(N,)`` of points ``pts (N, 2)`` in G from given curve samples
    ``node (N,)`` (the k-d tree's nearest, for points ``seed_kernel`` leaves ``missing``): one Newton
    step from each (``_node_start``)."""
    count = pts.shape[0]
    s = np.empty(count)
    for i in range(count):
        s[i] = _node_start(pts[i, 0], pts[i, 1], node[i], node_frame, nodes, min_denominator)
    return s
