"""The rectangle measurement model (lidar, after Granström 2011 / MATLAB ``ctrectmeas``) and the radar
velocity rows, vectorised over sigma points and over (component, cluster) pairs.

Geometry. A state goes to the vehicle frame E: curvilinear ``(s, n)`` -> G through the road
(``c(s) + n (-sin theta, cos theta)``, heading ``psi = theta(s) + xi``), or a Cartesian state directly;
then ``p_E = R(-yaw_ego) (p_G - p_ego)``, ``psi_E = psi - yaw_ego``. The rectangle's corners, counter-
clockwise around the object, are ``K0`` front-right, ``K1`` front-left, ``K2`` rear-left, ``K3`` rear-right;
side ``k`` runs ``K_k -> K_{k+1}`` (0 front, 1 left, 2 rear, 3 right) with outward normal at
``psi + k pi/2``. A side is visible from the lidar (the E origin) when the origin lies on its outer side.

Data (per cluster, once: ``prepare_cluster``). Points are sorted by bearing about the lidar,
ascending (counter-clockwise seen from the sensor), as the paper says; MATLAB sorts a two-sided cell
by azimuth about its bounding-box centre and rotates the circular order to start at an extreme point,
which for the visible (convex) contour of a rectangle is the same scan order. Seen from outside, counter-clockwise around the
sensor is clockwise around the object, so the points run along a visible side ``k`` from ``K_{k+1}`` to
``K_k``, and a two-sided cluster covers side ``j`` then side ``j - 1`` through the corner ``K_j``. The
cluster is two-sided in the data when it has at least ``min_points_two_sided`` points and the
eigenvalue ratio ``lambda_max / lambda_min`` of its points' covariance is below
``two_side_eigen_ratio`` (50). Its corner index is the split minimising the total least-squares
line-fit residual of the two parts (the paper: "least squares fitting lines"; the corner point belongs
to both fits; all splits at once from prefix sums). Each part (or the whole cluster) gets a
total-least-squares line; its *chord* is the extent of the points' projections on that line, and
for a two-sided cluster the chords meet at the intersection of the two lines (the corner, less noisy
than any single point). A point's position along its part is its projection on the line, in metres
from the chord's start (``proj``). Departures from MATLAB, which spaces points by cumulative polyline
length between the first and last points: with noise that length grows with the number of points
(zig-zag), and a single noisy extreme point shifts every generating point of the side; fitted lines,
projections and a fitted corner do not. Lines and extents use all points; then clusters above
``max_cluster_points`` are thinned evenly in bearing order, keeping the extreme points and the corner.

End gaps (``end_gap_correction``, default on). A scanning lidar's extreme return on a side lies
somewhere within one ray gap of the side's free end (uniformly, for a random ray phase). The gap is
``g = r^2 db / d`` (range ``r`` of the end, median bearing step ``db`` of the cluster, distance ``d`` of
the line from the sensor), large on far or grazing sides. With the correction the chord is extended
by ``e = g / 2`` at each free end (never at a fitted corner), which removes the length bias, and the
remaining uncertainty ``eps ~ U(-e, e)`` (variance ``e^2 / 3``) enters the measurement noise as one
rank-one term per free end, ``f f^T`` with ``f`` the points' displacement per unit end shift (e.g.
``(1 - t_i) u`` over a fully visible side): the filter does not take the extreme points for the corners.
Without it the extreme points are taken to be the corners, as in MATLAB.

Structure (per pair, from the component's predicted *mean*, shared by all its sigma points so the
model is a smooth function of the state): two-sided only if the data say so *and* the predicted
rectangle shows two sides; each part is matched to the side whose outward normal is closest to the
part's line direction turned by +90 deg (``argmax n_k . rot90(u)``; the paper writes the test as
``argmin |alpha_i - beta + pi/2|`` with its own normal convention); a two-sided cluster takes the best
adjacent pair ``(j, j - 1)``. Visibility ``a = (chord + end margins) / predicted side length``; a side
with ``a <= partial_visibility`` (0.9) is *partially visible*, unless the data show where it ends
(departures from the paper, ``MeasurementConfig``): a one-sided cluster with both ends sharp (half a
ray gap at most ``shadow_free_gap``) and free (no nearer return beyond it, ``occluded_end``; no return
continuing its line, ``continued_end``) is the whole side (``sharp_side_whole``), and so is a part of a
two-sided cluster from the fitted corner to a sharp, free far end, when both parts have enough points
and the side shrinks by no more than the extent's uncertainty allows (``sharp_parts_whole``); a side
with an end in a shadow is partially visible whatever its extent (one-sided, when its other end is
sharp; a part of a two-sided cluster, ``shadowed_parts_partial``, unless its chord is longer than the
predicted side: then it is measured whole to its last return, no end-gap margin at the shadowed end).

Measurement generating points (one per point, in the same order, so no association is needed), with
``e_lo``, ``e_hi`` the end margins of the part (0 without the correction or at a fitted corner):

- fully visible side from ``P = K_{k+1}`` to ``Q = K_k``:
  ``y_i = P + (proj_i + e_lo) / (chord + e_lo + e_hi) (Q - P)`` (spread over the whole side, spacing
  proportional to the measured gaps);
- partially visible, two-sided: anchored at the observed corner with the measured spacing in metres,
  ``y_i = K_j - (chord_0 - proj_i) u`` on the first side, ``y_i = K_j + proj_i u`` on the second
  (``u`` the unit side direction of the sigma point): the side's length is not pulled to the visible
  extent (no shrinking);
- partially visible, one-sided: anchored like MATLAB at whichever of (first point <-> ``P``, last
  point <-> ``Q``, centroid <-> side centre) is closest in the predicted mean, spacing in metres;
- a single point (or a zero-length chord): on the nearest visible side of the mean that does not face
  the sensor at grazing incidence (apparent width at least ``single_point_min_apparent`` of the widest
  visible side's), at the fraction of that side where the point projects (fixed across sigma points). MATLAB uses the nearest side's
  midpoint, which pulls the target along the side by up to half its length.

Radar (fused cluster), ``MeasurementConfig.radar_rows``: ``"speed"`` (default) one row, the radar's
velocity along the predicted mean's heading ``u`` against ``u . v (cos psi_E, sin psi_E)`` (linear in the
same features), with ``radar_velocity_sigma^2``; ``"velocity"`` (the paper) two rows
``v (cos psi_E, sin psi_E)``, the target's absolute velocity in E's axes, against the radar's
``(vx, vy)``, with ``radar_velocity_sigma^2 I2``; the lidar rows have
``lidar_sigma^2 I2`` per point (``shadowed_lidar_sigma^2 I2`` in the update of a pair whose part is
partially visible and whose cluster borders a shadow; its weight keeps ``lidar_sigma``:
``tracker.update.likelihood_variances``). The radar's timestamp is not used: the velocity of a vehicle
changes little within one lidar period.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from tracker import jit as compiled_kernels
from tracker.config import MeasurementConfig
from tracker.frame import EgoState
from tracker.road import Road
from tracker.centerline import rectangles_kernel

Coordinates = Literal["curvilinear", "cartesian"]

#: Smallest rectangle side (m) used when a sigma point carries a tiny or negative L or W.
MIN_EXTENT = 1e-2
#: Chords shorter than this (m) are treated as a single point.
MIN_CHORD = 1e-6
#: The corner of a two-sided cluster is the intersection of the two parts' fitted lines when they
#: meet at least at this angle (rad) and within ``CORNER_MAX_SHIFT`` (m) of the corner point; else the
#: corner point itself.
CORNER_MIN_ANGLE = np.radians(30.0)
CORNER_MAX_SHIFT = 0.5
#: Largest end gap (m) the end-gap correction assumes (a side seen at a grazing angle can have metres
#: between rays; beyond this the correction is capped).
MAX_END_GAP = 2.0

#: A side's chord must exceed its predicted length by more than ``GROWTH_MIN_EXCESS`` (m) and by more
#: than ``GROWTH_SIGMAS`` standard deviations of the extent to be evidence of a longer side, not noise:
#: ``tracker.update.grow_extent`` then widens the prior, and a one-sided part with an end in a shadow
#: is taken whole (``MeasurementConfig.shadowed_longer_whole``).
GROWTH_MIN_EXCESS = 0.5
GROWTH_SIGMAS = 2.0
#: The widest and the longest road vehicle (m; EU limits): a chord beyond them is not one vehicle's
#: side (two vehicles' points in one cluster, or a vehicle and a roadside object), so it is no lower
#: bound of one vehicle's extent (``MeasurementConfig.shadowed_longer_whole``).
WIDEST_VEHICLE = 2.55
LONGEST_VEHICLE = 25.25

#: A part's far end is also sharp (``MeasurementConfig.sharp_parts_whole``) when the predicted side goes
#: on beyond its last return for at least this many ray gaps: so many rays along it returned nothing.
MISSED_RAYS_SHARP = 2.0

# structure modes of a part
FULL, FROM_A, FROM_B, CENTRE, FIXED = range(5)
# corner k = centre + SX[k] L/2 e_x + SY[k] W/2 e_y (e_x the heading, e_y its left normal)
SX = np.array([1.0, 1.0, -1.0, -1.0])
SY = np.array([-1.0, 1.0, 1.0, -1.0])
#: index of each corner's successor (counter-clockwise): ``corners[..., NEXT_CORNER, :]`` is
#: ``np.roll(corners, -1, axis=-2)`` at a quarter of its cost
NEXT_CORNER = np.array([1, 2, 3, 0])


# -- geometry ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Rectangles:
    """Rectangles in E: ``center (..., 2)`` m, heading ``psi (...)`` rad, speed ``v (...)`` m/s, extent
    ``length``, ``width`` (...) m (floored at ``MIN_EXTENT``)."""

    center: np.ndarray
    psi: np.ndarray
    v: np.ndarray
    length: np.ndarray
    width: np.ndarray

    def corners(self) -> np.ndarray:
        """Corners ``(..., 4, 2)``: front-right, front-left, rear-left, rear-right (counter-clockwise).
        Computed once per ``Rectangles`` and returned read-only (the detection model, clustering and the
        update all ask for them)."""
        cached = self.__dict__.get("_corners")
        if cached is None:
            cached = rectangle_corners(self.center, self.psi, self.length, self.width)
            cached.flags.writeable = False
            object.__setattr__(self, "_corners", cached)
        return cached

    @classmethod
    def of_states(cls, states: np.ndarray, center: np.ndarray, psi: np.ndarray, corners: np.ndarray) -> Rectangles:
        """The rectangles of states ``(..., 7 or 8)`` whose centres ``(..., 2)``, headings ``(...)`` and
        corners ``(..., 4, 2)`` in E a compiled kernel computed: the speed from the states, the extent
        floored at ``MIN_EXTENT`` (as ``to_vehicle``)."""
        rect = cls(center, psi, states[..., 2], np.maximum(states[..., 5], MIN_EXTENT),
                   np.maximum(states[..., 6], MIN_EXTENT))
        return rect.with_corners(corners)

    @classmethod
    def computed(cls, center: np.ndarray, psi: np.ndarray, v: np.ndarray, length: np.ndarray, width: np.ndarray,
                 corners: np.ndarray) -> Rectangles:
        """Rectangles whose fields and corners a compiled kernel computed (``to_vehicle``'s compiled
        path: the extent already floored), built without the dataclass's per-field checks of a frozen
        ``__init__`` (the tracker builds several per frame). The corners are returned read-only."""
        rect = object.__new__(cls)
        corners.flags.writeable = False
        rect.__dict__.update(center=center, psi=psi, v=v, length=length, width=width, _corners=corners)
        return rect

    def with_corners(self, corners: np.ndarray) -> Rectangles:
        """These rectangles with their corners already computed (``corners()`` then returns them,
        read-only): for a producer that computes them anyway (the compiled ``to_vehicle``)."""
        corners.flags.writeable = False
        object.__setattr__(self, "_corners", corners)
        return self

    def velocity(self) -> np.ndarray:
        """Absolute velocity in E's axes ``(..., 2)``: ``v (cos psi_E, sin psi_E)``."""
        return self.v[..., None] * np.stack([np.cos(self.psi), np.sin(self.psi)], axis=-1)

    def take(self, index: np.ndarray) -> Rectangles:
        """The rectangles at ``index`` along the first axis (their corners too, when computed)."""
        cached = self.__dict__.get("_corners")
        if cached is None:
            return Rectangles(self.center[index], self.psi[index], self.v[index], self.length[index], self.width[index])
        return Rectangles.computed(self.center[index], self.psi[index], self.v[index], self.length[index],
                                   self.width[index], cached[index])


def rectangle_corners(center: np.ndarray, psi: np.ndarray, length: np.ndarray, width: np.ndarray) -> np.ndarray:
    """Corners ``(..., 4, 2)`` of rectangles with centre ``(..., 2)``, heading ``psi`` and extent
    ``length``, ``width`` (m): front-right, front-left, rear-left, rear-right."""
    c, s = np.cos(psi), np.sin(psi)
    hl, hw = 0.5 * np.asarray(length, dtype=float), 0.5 * np.asarray(width, dtype=float)
    lx = SX * hl[..., None]  # (..., 4) local x
    ly = SY * hw[..., None]
    x = center[..., None, 0] + c[..., None] * lx - s[..., None] * ly
    y = center[..., None, 1] + s[..., None] * lx + c[..., None] * ly
    return np.stack([x, y], axis=-1)


def side_normals(corners: np.ndarray) -> np.ndarray:
    """Unit outward normals ``(..., 4, 2)`` of sides ``K_k -> K_{k+1}`` (corners counter-clockwise)."""
    d = corners[..., NEXT_CORNER, :] - corners
    nrm = np.stack([d[..., 1], -d[..., 0]], axis=-1)  # direction turned by -90 deg
    return nrm / np.maximum(np.linalg.norm(nrm, axis=-1, keepdims=True), 1e-12)


def visible_sides(corners: np.ndarray, sensor: np.ndarray | None = None) -> np.ndarray:
    """Which sides ``(..., 4)`` of the rectangles face ``sensor`` (default: the E origin)."""
    sensor = np.zeros(2) if sensor is None else np.asarray(sensor, dtype=float)
    mid = 0.5 * (corners + corners[..., NEXT_CORNER, :])
    return np.einsum("...kd,...kd->...k", sensor - mid, side_normals(corners)) > 0.0


def to_vehicle(
    states: np.ndarray, ego: EgoState | tuple, road: Road | None = None, coordinates: Coordinates = "curvilinear",
    euler_s0: float | None = None,
) -> Rectangles:
    """States ``(..., 7)`` as rectangles in E (module docstring). ``ego`` is an ``EgoState`` or
    ``(x, y, yaw[, v, yaw_rate])`` in G. Curvilinear states need ``road`` (open roads extrapolate along
    their end tangents) and use the exact conversion ``c(s) + n (-sin theta, cos theta)``: ``n`` positive
    to the left (the paper's Algorithm 1 writes the normal as ``(cos(pi/2 - theta), sin(pi/2 - theta))``,
    which points right). With ``euler_s0`` (the ego's arc length, m) a curvilinear state goes through
    the paper's Euler conversion instead (``Road.frame_euler``: Algorithm 1, the local cubic heading
    polynomial around ``euler_s0``), the ``paper`` variant's measurement model."""
    ego = EgoState.coerce(ego)
    x = np.asarray(states, dtype=float)
    if x.shape[-1] not in (7, 8):
        raise ValueError(f"states must have shape (..., 7) (or (..., 8) with the acceleration state); got {x.shape}")
    if coordinates == "curvilinear":
        if road is None:
            raise ValueError("curvilinear states need the road to go to E")
        if euler_s0 is None and compiled_kernels.enabled() and x.size:
            flat = x if x.ndim == 2 and x.flags.c_contiguous else np.ascontiguousarray(x.reshape(-1, x.shape[-1]))
            kind, *curve = road._curve.kernel_args()
            center, psi, corners, length, width, finite = rectangles_kernel(
                kind, flat, float(ego.x), float(ego.y), float(ego.yaw), road.closed, road.length, road._ends_array,
                *curve, MIN_EXTENT)
            if not finite:
                raise ValueError(f"s must be finite; got {flat[np.argmin(np.isfinite(flat[:, 0])), 0]!r}")
            if x.ndim != 2:
                lead = x.shape[:-1]
                center, psi, corners = center.reshape(lead + (2,)), psi.reshape(lead), corners.reshape(lead + (4, 2))
                length, width = length.reshape(lead), width.reshape(lead)
            return Rectangles.computed(center, psi, x[..., 2], length, width, corners)
        if euler_s0 is None:
            xy, theta, _ = road.frame(x[..., 0], extrapolate=True)
        else:
            xy, theta = road.frame_euler(x[..., 0], euler_s0)
        n = x[..., 1]
        gx = xy[..., 0] - n * np.sin(theta) - ego.x
        gy = xy[..., 1] + n * np.cos(theta) - ego.y
        psi = theta + x[..., 3] - ego.yaw
    elif coordinates == "cartesian":
        gx, gy = x[..., 0] - ego.x, x[..., 1] - ego.y
        psi = x[..., 3] - ego.yaw
    else:
        raise ValueError(f"coordinates must be 'curvilinear' or 'cartesian'; got {coordinates!r}")
    c, s = np.cos(ego.yaw), np.sin(ego.yaw)
    center = np.stack([c * gx + s * gy, -s * gx + c * gy], axis=-1)
    return Rectangles(center, psi, x[..., 2], np.maximum(x[..., 5], MIN_EXTENT), np.maximum(x[..., 6], MIN_EXTENT))


def rectangle_scan(corners: np.ndarray, bearings: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact lidar returns of one rectangle ``corners (4, 2)`` in E for rays from the E origin at
    ``bearings (R,)`` rad: the nearest intersection of each ray with the rectangle's sides. Returns the
    points ``(H, 2)`` of the rays that hit, in ray order, and the hit mask ``(R,)``. (For building
    synthetic clusters without a simulator.)"""
    corners = np.asarray(corners, dtype=float)
    b = np.asarray(bearings, dtype=float).reshape(-1)
    d = np.stack([np.cos(b), np.sin(b)], axis=-1)  # (R, 2)
    a = corners  # side starts (4, 2)
    e = corners[NEXT_CORNER] - corners  # (4, 2)
    cross = lambda p, q: p[..., 0] * q[..., 1] - p[..., 1] * q[..., 0]  # noqa: E731
    de = cross(d[:, None, :], e[None, :, :])  # (R, 4)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = cross(a, e)[None, :] / de
        u = cross(a[None, :, :], d[:, None, :]) / de
    ok = (np.abs(de) > 1e-12) & (r > 0) & (u >= -1e-12) & (u <= 1 + 1e-12)
    r = np.where(ok, r, np.inf)
    best = r.min(axis=1)
    hit = np.isfinite(best)
    return best[hit, None] * d[hit], hit


# -- clusters ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Cluster:
    """A cluster of lidar points prepared for the rectangle model (see the module docstring).

    ``points (M, 2)`` in E sorted by bearing (after downsampling). Chords, indexed by *slot*: 0 the
    whole cluster (used when a pair is treated as one-sided), 1 and 2 the parts before and after the
    corner of a two-sided split: ``chord_start (3, 2)``, ``chord_dir (3, 2)`` (unit), ``chord_len (3,)``,
    ``chord_end (3, 2)`` (first and last point of each). ``part (M,)`` 0 or 1 (1: after the corner);
    ``proj (2, M)`` metres along the chord from its start: row 0 on the whole-cluster chord, row 1 on the
    point's part chord. ``two_sided`` is the data's verdict; ``corner`` the index of the corner point in
    ``points`` (-1 if one-sided); ``eigen_ratio``; ``end_margin (3, 2)`` per slot, the distance (m)
    assumed between the chord's start / end and the side's corner (half the expected gap between rays
    at a free end, at most half the chord; 0 at the corner of a split; all 0 without
    ``end_gap_correction``); ``end_gap (3, 2)`` the same half ray gap before the cap at half the chord
    (how sharp an end is: a short chord on a grazing side is not a sharp one; also 0 at the corner of a
    split and without the correction); ``velocity (2,)`` the radar's absolute velocity in E
    (m/s) or ``None``; ``raw_count`` points before downsampling; ``dropped`` non-finite points removed;
    ``order`` the input index of each kept point.
    """

    points: np.ndarray
    part: np.ndarray
    proj: np.ndarray
    chord_start: np.ndarray
    chord_end: np.ndarray
    chord_dir: np.ndarray
    chord_len: np.ndarray
    two_sided: bool
    corner: int
    eigen_ratio: float
    end_margin: np.ndarray = field(default_factory=lambda: np.zeros((3, 2)))
    velocity: np.ndarray | None = None
    end_gap: np.ndarray = field(default_factory=lambda: np.zeros((3, 2)))
    raw_count: int = 0
    dropped: int = 0
    order: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))

    @property
    def size(self) -> int:
        """Number of points used by the update."""
        return int(self.points.shape[0])

    @property
    def fused(self) -> bool:
        """Whether the cluster carries a radar velocity."""
        return self.velocity is not None


def _lambda_min(sxx: np.ndarray, syy: np.ndarray, sxy: np.ndarray) -> np.ndarray:
    """Smallest eigenvalue of symmetric 2x2 matrices ``[[sxx, sxy], [sxy, syy]]``."""
    return 0.5 * (sxx + syy) - np.sqrt(0.25 * (sxx - syy) ** 2 + sxy**2)


def corner_index(points: np.ndarray) -> int:
    """Corner index of bearing-sorted points ``(N, 2)``, ``N >= 3``: the split ``k`` in ``1..N-2``
    minimising the summed total-least-squares residuals of lines fitted to ``points[:k+1]`` and
    ``points[k:]`` (the corner point in both). All splits at once from prefix sums: O(N)."""
    p = np.asarray(points, dtype=float)
    n = len(p)
    if n < 3:
        raise ValueError(f"corner_index needs at least 3 points; got {n}")
    p = p - p.mean(axis=0)
    x, y = p[:, 0], p[:, 1]
    cs = [np.concatenate([[0.0], np.cumsum(v)]) for v in (np.ones(n), x, y, x * x, y * y, x * y)]
    k = np.arange(1, n - 1)

    def residual(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:  # points lo..hi inclusive
        cnt, sx, sy, sxx, syy, sxy = (c[hi + 1] - c[lo] for c in cs)
        return np.maximum(_lambda_min(sxx - sx * sx / cnt, syy - sy * sy / cnt, sxy - sx * sy / cnt), 0.0)

    cost = residual(np.zeros_like(k), k) + residual(k, np.full_like(k, n - 1))
    return int(k[np.argmin(cost)])


def _even(lo: int, hi: int, count: int) -> np.ndarray:
    """``count`` indices evenly spread over ``lo..hi`` inclusive (both ends kept)."""
    return np.unique(np.round(np.linspace(lo, hi, max(count, 2))).astype(int))


def _scatter(pts: np.ndarray) -> tuple[np.ndarray, float, float, float]:
    """Centroid and the (biased) covariance entries ``sxx, syy, sxy`` of ``pts (K, 2)``."""
    c = pts.mean(axis=0)
    d = pts - c
    return c, float(d[:, 0] @ d[:, 0]) / len(pts), float(d[:, 1] @ d[:, 1]) / len(pts), float(d[:, 0] @ d[:, 1]) / len(pts)


def _line_fit(pts: np.ndarray, fallback: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # noqa: D401
    """Total-least-squares line through ``pts (K, 2)``: a point on it (the centroid) and its unit
    direction (the major axis of the scatter, angle ``atan2(2 sxy, sxx - syy) / 2``), oriented from the
    first point towards the last; ``fallback`` direction if the points have no extent."""
    c, sxx, syy, sxy = _scatter(pts)
    if len(pts) < 2 or sxx + syy <= MIN_CHORD**2:
        return c, fallback
    phi = 0.5 * np.arctan2(2.0 * sxy, sxx - syy)
    u = np.array([np.cos(phi), np.sin(phi)])
    return c, (u if float(u @ (pts[-1] - pts[0])) >= 0.0 else -u)


def _intersect(o1: np.ndarray, u1: np.ndarray, o2: np.ndarray, u2: np.ndarray) -> np.ndarray | None:
    """Intersection of the lines ``o1 + a u1`` and ``o2 + b u2``; ``None`` if they meet at less than
    ``CORNER_MIN_ANGLE``."""
    den = u1[0] * u2[1] - u1[1] * u2[0]
    if abs(den) < np.sin(CORNER_MIN_ANGLE):
        return None
    w = o2 - o1
    a = (w[0] * u2[1] - w[1] * u2[0]) / den
    return o1 + a * u1


def prepare_cluster(
    points: np.ndarray, config: MeasurementConfig | None = None, velocity: np.ndarray | None = None
) -> Cluster:
    """Prepare lidar ``points (N, 2)`` in E (m) for the rectangle model: drop non-finite points
    (counted in ``dropped``), sort by bearing, decide one/two-sided from the eigenvalue ratio, find the
    corner, downsample to ``config.max_cluster_points`` and compute each point's chord coordinates.
    ``velocity`` is an associated radar detection's absolute velocity ``(vx, vy)`` in E (m/s)."""
    config = config if config is not None else MeasurementConfig()
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ValueError(f"cluster points must have shape (N, 2) (x, y in E, m); got {pts.shape}")
    finite = np.isfinite(pts).all(axis=1)
    dropped = int((~finite).sum())
    index = np.flatnonzero(finite)
    pts = pts[finite]
    if len(pts) == 0:
        raise ValueError(f"a cluster needs at least one finite point; got none ({dropped} non-finite dropped)")
    if velocity is not None:
        velocity = np.asarray(velocity, dtype=float).reshape(-1)
        if velocity.shape != (2,) or not np.isfinite(velocity).all():
            raise ValueError(f"cluster velocity must be a finite (vx, vy) in m/s; got {velocity!r}")
    centroid, sxx, syy, sxy = _scatter(pts)
    cx, cy = float(centroid[0]), float(centroid[1])
    ref = math.atan2(cy, cx) if math.hypot(cx, cy) > 1e-9 else 0.0
    rel = np.arctan2(pts[:, 1], pts[:, 0]) - ref
    rel -= 2.0 * np.pi * np.round(rel / (2.0 * np.pi))
    order = np.argsort(rel, kind="stable")
    pts, index, rel = pts[order], index[order], rel[order]
    n = len(pts)
    ratio = math.inf
    if n >= 2:
        root = math.sqrt(0.25 * (sxx - syy) ** 2 + sxy**2)
        lam_min, lam_max = 0.5 * (sxx + syy) - root, 0.5 * (sxx + syy) + root
        ratio = lam_max / lam_min if lam_min > 1e-15 * max(lam_max, 1e-300) else math.inf
    two = n >= config.min_points_two_sided and ratio < config.two_side_eigen_ratio
    keep = np.arange(n)
    corner = -1
    if two:
        k = corner_index(pts)
        if n > config.max_cluster_points:
            bound = config.max_cluster_points  # the corner is shared: m0 + m1 - 1 = bound points
            m0 = min(max(2, int(round(bound * (k + 1) / (n + 1)))), bound - 1)
            m1 = bound + 1 - m0
            keep = np.unique(np.concatenate([_even(0, k, m0), _even(k, n - 1, m1)]))
        corner = int(np.searchsorted(keep, k))
    elif n > config.max_cluster_points:
        keep = _even(0, n - 1, config.max_cluster_points)
    # lines and extents from all the points, before downsampling
    norm = max(math.hypot(cx, cy), 1e-12)
    fallback = np.array([-cy / norm, cx / norm])  # no extent: the line-of-sight normal
    corner_full = int(keep[corner]) if two else -1
    # slot 0: the whole cluster; slots 1, 2: before / after the corner (the corner point in both fits)
    members = [pts, pts[: corner_full + 1], pts[corner_full:]] if two else [pts]
    fits = [_line_fit(q, fallback) for q in members]
    lo, hi = np.zeros(len(fits)), np.zeros(len(fits))
    for i, (q, (o, u)) in enumerate(zip(members, fits)):
        a = (q - o) @ u
        lo[i], hi[i] = a.min(), a.max()
    if not two:  # one part: slots 1 and 2 repeat slot 0
        fits, lo, hi = fits * 3, np.repeat(lo, 3), np.repeat(hi, 3)
    if two:  # the corner: where the two fitted lines meet, if they meet near the corner point
        x = _intersect(fits[1][0], fits[1][1], fits[2][0], fits[2][1])
        if x is None or np.hypot(*(x - pts[corner_full])) > CORNER_MAX_SHIFT:
            x = pts[corner_full]
        hi[1] = (x - fits[1][0]) @ fits[1][1]
        lo[2] = (x - fits[2][0]) @ fits[2][1]
        hi[1], lo[2] = max(hi[1], lo[1]), min(lo[2], hi[2])
    origin = np.stack([o for o, _ in fits])
    direction = np.stack([u for _, u in fits])
    starts = origin + lo[:, None] * direction
    ends = origin + hi[:, None] * direction
    length = hi - lo
    margin, half_gap = np.zeros((3, 2)), np.zeros((3, 2))
    if config.end_gap_correction and n >= 2:
        # half the gap between rays at each free end: along a line at distance d from the sensor a
        # bearing step db moves the hit point by r^2 db / d (r: range of the end point)
        gaps = np.diff(rel)
        db = float(np.partition(gaps, len(gaps) // 2)[len(gaps) // 2])  # the median bearing step
        dist = np.abs(origin[:, 0] * direction[:, 1] - origin[:, 1] * direction[:, 0])  # (3,) line to sensor
        r2 = np.column_stack([(starts * starts).sum(axis=1), (ends * ends).sum(axis=1)])
        gap = r2 * db / np.maximum(dist, 1e-3)[:, None]
        half_gap = 0.5 * np.minimum(gap, MAX_END_GAP)
        margin = np.minimum(half_gap, 0.5 * length[:, None])
        if two:
            margin[1, 1] = margin[2, 0] = 0.0  # the corner of a split is observed
            half_gap[1, 1] = half_gap[2, 0] = 0.0
    pts, index = pts[keep], index[keep]
    m = len(pts)
    part = np.zeros(m, dtype=np.intp)
    if two:
        part[corner + 1:] = 1
    proj = np.stack([
        (pts - starts[0]) @ direction[0],
        np.einsum("md,md->m", pts - starts[1 + part], direction[1 + part]),
    ])
    return Cluster(
        points=pts, part=part, proj=proj, chord_start=starts, chord_end=ends, chord_dir=direction,
        chord_len=length, two_sided=bool(two), corner=corner, eigen_ratio=ratio, end_margin=margin, velocity=velocity,
        raw_count=n, dropped=dropped, order=index, end_gap=half_gap,
    )


@dataclass(frozen=True)
class ClusterBatch:
    """Clusters padded to a common size ``M`` for batched pairs: ``points (K, M, 2)``, ``valid (K, M)``,
    ``part (K, M)``, ``proj (K, 2, M)``, ``chord_start``, ``chord_end``, ``chord_dir (K, 3, 2)``,
    ``chord_len (K, 3)``, ``end_margin``, ``end_gap (K, 3, 2)`` (slots as in ``Cluster``), ``two_sided``, ``single``,
    ``fused (K,)``, ``velocity (K, 2)``, ``centroid (K, 2)``; ``occluded_end (K, 2)`` (None: no end occluded)
    whether the first / last point in bearing borders another object's shadow
    (``tracker.clustering.occluded_ends``); ``continued_end (K, 2)`` (None: none) whether the side goes on
    beyond it in another cluster (``tracker.clustering.continued_ends``)."""

    points: np.ndarray
    valid: np.ndarray
    part: np.ndarray
    proj: np.ndarray
    chord_start: np.ndarray
    chord_end: np.ndarray
    chord_dir: np.ndarray
    chord_len: np.ndarray
    end_margin: np.ndarray
    end_gap: np.ndarray
    two_sided: np.ndarray
    single: np.ndarray
    fused: np.ndarray
    velocity: np.ndarray
    centroid: np.ndarray
    occluded_end: np.ndarray | None = None
    continued_end: np.ndarray | None = None

    def bearing_ends(self) -> np.ndarray:
        """Each cluster's first and last point in bearing order (``K, 2, 2``; the points are kept in
        that order, extremes included): the ends whose shadows ``tracker.clustering.occluded_ends``
        looks for."""
        last = np.maximum(self.valid.sum(axis=1) - 1, 0)
        return np.stack([self.points[:, 0], self.points[np.arange(len(self.points)), last]], axis=1)

    def side_ends(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Where each cluster's side ends at its first and last point in bearing (``K, 2, 2``: the start
        of the first part's chord, the end of the last part's), the unit direction pointing on beyond
        each (``K, 2, 2``) and half the expected ray gap there (``K, 2``, m): what
        ``tracker.clustering.continued_ends`` takes (slots 1, 2 repeat slot 0 for a one-sided cluster)."""
        ends = np.stack([self.chord_start[:, 1], self.chord_end[:, 2]], axis=1)
        outward = np.stack([-self.chord_dir[:, 1], self.chord_dir[:, 2]], axis=1)
        return ends, outward, np.stack([self.end_gap[:, 1, 0], self.end_gap[:, 2, 1]], axis=1)

    @classmethod
    def of(cls, clusters: list[Cluster]) -> ClusterBatch:
        """Pack ``clusters`` (at least one)."""
        if not clusters:
            raise ValueError("ClusterBatch needs at least one cluster")
        k, m = len(clusters), max(c.size for c in clusters)
        points = np.zeros((k, m, 2))
        valid = np.zeros((k, m), dtype=bool)
        part = np.zeros((k, m), dtype=np.intp)
        proj = np.zeros((k, 2, m))
        for i, c in enumerate(clusters):
            points[i, : c.size] = c.points
            valid[i, : c.size] = True
            part[i, : c.size] = c.part
            proj[i, :, : c.size] = c.proj
        chord_len = np.stack([c.chord_len for c in clusters])
        return cls(
            points=points, valid=valid, part=part, proj=proj,
            chord_start=np.stack([c.chord_start for c in clusters]),
            chord_end=np.stack([c.chord_end for c in clusters]),
            chord_dir=np.stack([c.chord_dir for c in clusters]),
            chord_len=chord_len,
            end_margin=np.stack([c.end_margin for c in clusters]),
            end_gap=np.stack([c.end_gap for c in clusters]),
            two_sided=np.array([c.two_sided for c in clusters]),
            single=chord_len[:, 0] <= MIN_CHORD,
            fused=np.array([c.fused for c in clusters]),
            velocity=np.stack([c.velocity if c.fused else np.zeros(2) for c in clusters]),
            centroid=np.stack([c.points.mean(axis=0) for c in clusters]),
        )


# -- structure and prediction --------------------------------------------------------------------
@dataclass(frozen=True)
class Structure:
    """Per (pair, point) recipe ``y = K[a] + c1 (K[b] - K[a]) + c2 unit(K[b] - K[a])`` (corner indices
    ``a``, ``b`` (P, M); coefficients ``c1``, ``c2`` (P, M)), the same in the rectangle's own axes,
    ``y = centre + (ax L + gx) e_x + (ay W + gy) e_y`` (``coef (P, M, 4)`` = ``ax, gx, ay, gy``; every
    corner is ``centre +- L/2 e_x +- W/2 e_y`` and every side direction is ``+-e_x`` or ``+-e_y``, so the
    recipe is linear in ``L``, ``W`` and needs no gather per sigma point), and the whole predicted
    measurement as ``features(sigma) @ matrix`` (``matrix (P, 10, D)``, see ``predict_measurements``),
    the point mask ``valid (P, M)``, per pair
    ``two_sided``, ``sides (P, 2)`` (side of each part), ``mode (P, 2)``, ``radar (P,)`` (velocity rows
    on), the stacked measurement ``z (P, D)``, its noise variances ``r (P, D)`` and row mask ``mask (P, D)``
    with ``D = 2 M + 2`` (points ``x0, y0, x1, y1, ...``, then ``vx, vy``), and ``factors (P, 2, D)``:
    the end-gap uncertainty as low-rank noise, ``R = diag(r) + sum_e f_e f_e^T`` (module docstring);
    ``excess (P, 2)`` (m): how far each part's chord (the points' extent, without the end margins)
    exceeds the predicted length of its side (negative when shorter; ``tracker.update.grow_extent``)."""

    a: np.ndarray
    b: np.ndarray
    c1: np.ndarray
    c2: np.ndarray
    coef: np.ndarray
    matrix: np.ndarray
    valid: np.ndarray
    two_sided: np.ndarray
    sides: np.ndarray
    mode: np.ndarray
    radar: np.ndarray
    z: np.ndarray
    r: np.ndarray
    mask: np.ndarray
    factors: np.ndarray
    excess: np.ndarray


def _sharp_side_whole(config: MeasurementConfig, shadows: bool) -> bool:
    """Whether ``MeasurementConfig.sharp_side_whole`` applies: it needs the shadow flags (without them
    nothing says an end is free)."""
    return bool(config.sharp_side_whole and shadows)


def _sharp_parts_whole(config: MeasurementConfig, shadows: bool, has_extent_sd: bool) -> bool:
    """Whether ``MeasurementConfig.sharp_parts_whole`` applies: it needs the shadow flags and the
    predicted extent's standard deviations (its consistency gate)."""
    return bool(config.sharp_parts_whole and shadows and has_extent_sd)


def _shadowed_longer_whole(config: MeasurementConfig, shadows: bool, has_extent_sd: bool) -> bool:
    """Whether ``MeasurementConfig.shadowed_longer_whole`` applies: it needs the shadow flags, the
    predicted extent's standard deviations and the extent growth it goes with (``grow_extent``)."""
    return bool(config.shadowed_longer_whole and config.grow_extent and shadows and has_extent_sd)


def _shadowed_parts_partial(config: MeasurementConfig, shadows: bool) -> bool:
    """Whether ``MeasurementConfig.shadowed_parts_partial`` applies: it needs the shadow flags."""
    return bool(config.shadowed_parts_partial and shadows)


def shows_longer_side(excess: np.ndarray, sd: np.ndarray, width_side: np.ndarray | bool,
                      settled_width_std: float | None) -> np.ndarray:
    """Whether a chord ``excess`` (m) longer than its predicted side is evidence of a longer side, not
    noise: more than ``max(GROWTH_MIN_EXCESS, GROWTH_SIGMAS sd)`` (``sd`` that extent's standard
    deviation), and not a short side (``width_side``) longer than a settled width (its sd below
    ``settled_width_std``: the track's heading lagging a lane change, the side next to it in the
    chord). Used by ``tracker.update.grow_extent`` and ``MeasurementConfig.shadowed_longer_whole``."""
    longer = excess > np.maximum(GROWTH_MIN_EXCESS, GROWTH_SIGMAS * sd)
    if settled_width_std is not None:
        longer &= ~np.asarray(width_side) | (sd >= settled_width_std)
    return longer


def _longer_than_predicted(chord: np.ndarray, predicted: np.ndarray, side: np.ndarray, extent_sd: np.ndarray,
                           settled_width_std: float | None) -> np.ndarray:
    """Whether a one-sided chord ``(P,)`` on side ``side`` shows its side longer than ``predicted``
    (``shows_longer_side``, ``sd`` of ``L`` for the odd, long sides, of ``W`` for the others, from
    ``extent_sd (P, 2)``), and no longer or wider than one vehicle."""
    long_side = side % 2 == 1
    sd = np.where(long_side, extent_sd[:, 0], extent_sd[:, 1])
    return (shows_longer_side(chord - predicted, sd, ~long_side, settled_width_std)
            & (chord <= np.where(long_side, LONGEST_VEHICLE, WIDEST_VEHICLE)))  # one vehicle's side


def _free_ends(batch: ClusterBatch, ci: np.ndarray) -> np.ndarray:
    """``(P, 2)``: whether each bearing end of the pairs' clusters is free (in no shadow, not continued)."""
    free = np.ones((len(ci), 2), dtype=bool)
    for flags in (batch.occluded_end, batch.continued_end):
        if flags is not None:
            free &= ~flags[ci]
    return free


def _lidar_variance(config: MeasurementConfig, mode: np.ndarray, shadowed: np.ndarray) -> np.ndarray:
    """Per pair, the variance of each lidar coordinate in the update: ``shadowed_lidar_sigma^2`` for a
    pair with a part partially visible (``mode (P, 2)`` anchored) whose cluster borders a shadow
    (``shadowed (P,)``), ``lidar_sigma^2`` otherwise."""
    base = np.full(len(mode), config.lidar_sigma**2)
    if config.shadowed_lidar_sigma is None:
        return base
    anchored = ((mode == FROM_A) | (mode == FROM_B) | (mode == CENTRE)).any(axis=1)
    return np.where(anchored & shadowed, config.shadowed_lidar_sigma**2, base)


def build_structure(
    batch: ClusterBatch,
    cluster_index: np.ndarray,
    mean_corners: np.ndarray,
    config: MeasurementConfig,
    use_radar: bool = True,
    *,
    extent_sd: np.ndarray | None = None,
    compiled: bool | None = None,
) -> Structure:
    """The measurement structure of pairs (cluster ``cluster_index (P,)``, predicted mean rectangle
    ``mean_corners (P, 4, 2)`` in E): one/two-sided, side matching, partial visibility and anchoring,
    as in the module docstring. ``extent_sd (P, 2)``: the predicted standard deviations of ``L`` and
    ``W`` (m), for ``MeasurementConfig.sharp_parts_whole`` (None: that rule off). Vectorised over
    pairs; by the compiled kernel (``tracker.structure``) when ``compiled`` (default:
    ``tracker.compiled.enabled()``)."""
    ci = np.asarray(cluster_index, dtype=np.intp)
    if extent_sd is not None:
        extent_sd = np.asarray(extent_sd, dtype=float).reshape(len(ci), 2)
    if compiled is None:
        compiled = compiled_kernels.enabled()
    if compiled and len(ci):
        compiled_kernels.require()
        return _build_structure_compiled(batch, ci, mean_corners, config, use_radar, extent_sd)
    p_count = len(ci)
    rows = np.arange(p_count)
    nrm = side_normals(mean_corners)  # (P, 4, 2)
    vis = visible_sides(mean_corners)  # (P, 4)
    side_len = np.linalg.norm(mean_corners[..., NEXT_CORNER, :] - mean_corners, axis=-1)  # (P, 4)
    cdir = batch.chord_dir[ci]  # (P, 3, 2)
    normal_of_chord = np.stack([-cdir[..., 1], cdir[..., 0]], axis=-1)  # chord turned by +90 deg
    score = np.einsum("pkd,pqd->pqk", nrm, normal_of_chord)  # (P, slot, side)
    two = batch.two_sided[ci] & (vis.sum(axis=1) == 2)
    single = batch.single[ci] & ~two
    k_one = np.argmax(score[:, 0, :], axis=1)
    j_two = np.argmax(score[:, 1, :] + np.roll(score[:, 2, :], 1, axis=1), axis=1)  # sides j and j - 1
    # single point: the visible side of the mean rectangle nearest to the point
    z0 = batch.points[ci, 0]  # (P, 2)
    e = mean_corners[..., NEXT_CORNER, :] - mean_corners
    t_seg = np.clip(np.einsum("pkd,pkd->pk", z0[:, None, :] - mean_corners, e) / np.maximum(side_len**2, 1e-12), 0, 1)
    dist = np.linalg.norm(mean_corners + t_seg[..., None] * e - z0[:, None, :], axis=-1)
    # ... among the visible sides that look wide enough from the sensor (not seen at grazing incidence)
    mid = mean_corners + 0.5 * e
    apparent = side_len * np.einsum("pkd,pkd->pk", -mid, nrm) / np.maximum(np.linalg.norm(mid, axis=-1), 1e-12)
    eligible = vis & (apparent >= config.single_point_min_apparent * apparent.max(axis=1, keepdims=True))
    dist = np.where(eligible, dist, np.inf)
    k_single = np.where(eligible.any(axis=1), np.argmin(dist, axis=1), k_one)
    side0 = np.where(two, j_two, np.where(single, k_single, k_one))
    sides = np.stack([side0, np.where(two, (j_two - 1) % 4, side0)], axis=1)  # (P, 2) side of each part
    start_c, end_c = (sides + 1) % 4, sides  # side k is traversed from K_{k+1} to K_k
    # chords of the two parts as this pair sees them: slots 1, 2 if two-sided, else slot 0 twice
    slots = np.where(two[:, None], np.array([1, 2]), np.array([0, 0]))  # (P, 2)
    chord_len = np.take_along_axis(batch.chord_len[ci], slots, axis=1)
    margin = np.take_along_axis(batch.end_margin[ci], slots[..., None], axis=1)  # (P, 2 parts, 2 ends)
    occ = batch.occluded_end[ci] if batch.occluded_end is not None else np.zeros((p_count, 2), dtype=bool)
    shadowed_parts = _shadowed_parts_partial(config, batch.occluded_end is not None)
    if shadowed_parts:
        # a two-sided part's far end (part 0: the first point, part 1: the last) in a shadow is no end of
        # the side: no end-gap margin there, the chord reaches at least to the last return
        margin[:, 0, 0] = np.where(two & occ[:, 0], 0.0, margin[:, 0, 0])
        margin[:, 1, 1] = np.where(two & occ[:, 1], 0.0, margin[:, 1, 1])
    covered = chord_len + margin.sum(axis=2)
    predicted = side_len[rows[:, None], sides]  # (P, 2) the predicted length of each part's side
    alpha = covered / np.maximum(predicted, 1e-12)
    partial = alpha <= config.partial_visibility
    # a part with an end in another object's shadow goes on behind it: partially visible
    # one-sided only (a corner anchors the two-sided), and only when the other end is sharp (its
    # end-gap margin at most shadow_free_gap: not a far or grazing side whose next ray skips metres)
    sharp_end = batch.end_gap[ci] <= config.shadow_free_gap  # (P, 3 slots, 2 ends): half a ray gap at most
    sharp = sharp_end[:, 0]  # (P, 2 ends) of the one-sided chord
    free = _free_ends(batch, ci)  # (P, 2) the bearing ends: in no shadow, not continued
    if _sharp_side_whole(config, batch.occluded_end is not None):
        # a one-sided part with both ends sharp and free is the whole side, however much shorter than
        # predicted (a convex rectangle shows each visible side whole): a motorcycle's rear is 0.8 m,
        # not the visible part of a car's 1.8 m
        whole = ~two & ~single & sharp[:, 0] & sharp[:, 1] & free[:, 0] & free[:, 1]
        partial &= ~whole[:, None]
    if _sharp_parts_whole(config, batch.occluded_end is not None, extent_sd is not None):
        # each part of a two-sided cluster runs from the fitted corner to a far end, the cluster's first
        # (part 0, slot 1's start) or last point (part 1, slot 2's end): whole if that end is sharp and
        # free, both parts have enough points (the corner is where two well-fitted lines meet: with two
        # points on the other side it is the last return before the corner, up to a ray gap short of it),
        # and the side it would shrink is within the gate
        part_pts = np.stack([(batch.valid[ci] & (batch.part[ci] == 0)).sum(axis=1),
                             (batch.valid[ci] & (batch.part[ci] == 1)).sum(axis=1) + 1], axis=1)  # the corner in both
        # ... a far end is sharp by its ray gap, or because the predicted side goes on beyond it for
        # MISSED_RAYS_SHARP whole gaps (2 half gaps each) where the rays found nothing
        far_gap = np.stack([batch.end_gap[ci, 1, 0], batch.end_gap[ci, 2, 1]], axis=1)
        far_sharp = (far_gap <= config.shadow_free_gap) | (predicted - chord_len >= MISSED_RAYS_SHARP * 2.0 * far_gap)
        sd = np.where(sides % 2 == 1, extent_sd[:, :1], extent_sd[:, 1:])  # odd sides are the length
        shrink = predicted - covered
        consistent = shrink <= config.whole_gate_sigmas * sd + config.whole_gate_slack
        enough = part_pts.min(axis=1, keepdims=True) >= config.whole_min_points
        partial &= ~(two[:, None] & far_sharp & free & enough & consistent)
    if shadowed_parts:
        # ... and the side goes on behind it: partially visible, anchored at the corner, unless the chord
        # is longer than its predicted side (a lower bound: measured whole, to the last return); taken
        # whole, a side that an occluder hides a little more every frame would shrink with what shows
        partial |= two[:, None] & occ & (covered < predicted)
    shadowed = ~two & (occ[:, 1] & ~occ[:, 0] & sharp[:, 0] | occ[:, 0] & ~occ[:, 1] & sharp[:, 1])
    if _shadowed_longer_whole(config, batch.occluded_end is not None, extent_sd is not None):
        # ... unless it is longer than predicted: the vehicle is at least that long (or wide), a lower
        # bound the prediction falls short of, so the part is measured whole (kept partial, a truck's
        # rear half-hidden by a car would keep a car's width, and so never take the long-vehicle prior)
        shadowed &= ~_longer_than_predicted(chord_len[:, 0], predicted[:, 0], sides[:, 0], extent_sd,
                                            config.settled_width_std)
    partial |= shadowed[:, None]
    if config.two_sided_data_partial:
        # the data say two sides, the prediction shows one: what is seen is not one whole side
        partial |= (batch.two_sided[ci] & ~two & ~single)[:, None]
    # one-sided partial: anchored by the closest of first <-> P, last <-> Q, centroid <-> centre
    p_start = mean_corners[rows, start_c[:, 0]]
    q_end = mean_corners[rows, end_c[:, 0]]
    d_a = np.linalg.norm(batch.chord_start[ci, 0] - p_start, axis=-1)
    d_b = np.linalg.norm(batch.chord_end[ci, 0] - q_end, axis=-1)
    d_c = np.linalg.norm(batch.centroid[ci] - 0.5 * (p_start + q_end), axis=-1)
    anchor = np.array([FROM_A, FROM_B, CENTRE])[np.argmin(np.stack([d_a, d_b, d_c], axis=1), axis=1)]
    # ... unless exactly one end is in a shadow: the other is the vehicle's corner
    anchor = np.where(shadowed, np.where(occ[:, 1], FROM_A, FROM_B), anchor)
    mode_one = np.where(single, FIXED, np.where(partial[:, 0], anchor, FULL))
    mode = np.stack([
        np.where(two, np.where(partial[:, 0], FROM_B, FULL), mode_one),  # first part: anchored at the corner
        np.where(two, np.where(partial[:, 1], FROM_A, FULL), mode_one),  # second part: starts at the corner
    ], axis=1)
    # per point
    valid = batch.valid[ci]
    part = np.where(two[:, None], batch.part[ci], 0)  # (P, M)
    proj = np.where(two[:, None], batch.proj[ci, 1], batch.proj[ci, 0])
    mp = np.take_along_axis(mode, part, axis=1)
    sc = np.take_along_axis(start_c, part, axis=1)
    ec = np.take_along_axis(end_c, part, axis=1)
    ln = np.take_along_axis(chord_len, part, axis=1)
    e_lo = np.take_along_axis(margin[..., 0], part, axis=1)
    e_hi = np.take_along_axis(margin[..., 1], part, axis=1)
    frac = (proj + e_lo) / np.maximum(ln + e_lo + e_hi, MIN_CHORD)
    pts = batch.points[ci]
    p_m = mean_corners[rows[:, None], sc]  # (P, M, 2)
    pq = mean_corners[rows[:, None], ec] - p_m
    fixed_frac = np.clip(
        np.einsum("pmd,pmd->pm", pts - p_m, pq) / np.maximum(np.einsum("pmd,pmd->pm", pq, pq), 1e-12), 0.0, 1.0
    )
    a = np.where(mp == FROM_B, ec, sc)
    b = np.where(mp == FROM_B, sc, ec)
    full, from_a, from_b, centre = mp == FULL, mp == FROM_A, mp == FROM_B, mp == CENTRE
    c1 = np.where(full, frac, np.where(centre, 0.5, np.where(mp == FIXED, fixed_frac, 0.0)))
    c2 = np.where(from_a, proj + e_lo, np.where(from_b, ln - proj + e_hi,
                                                np.where(centre, proj - 0.5 * ln + 0.5 * (e_lo - e_hi), 0.0)))
    c1, c2 = np.where(valid, c1, 0.0), np.where(valid, c2, 0.0)
    dx, dy = SX[b] - SX[a], SY[b] - SY[a]  # one of them is 0 (adjacent corners)
    coef = np.stack([0.5 * (SX[a] + c1 * dx), c2 * np.sign(dx), 0.5 * (SY[a] + c1 * dy), c2 * np.sign(dy)], axis=-1)
    coef = np.where(valid[..., None], coef, 0.0)
    # end-gap noise: the free ends' unknown offsets eps ~ U(-e, e) (var e^2 / 3) move the points along
    # their side by k_lo eps_lo + k_hi eps_hi, with (k_lo, k_hi) = (1 - t, -t) spread over a fully
    # visible side, (1, 0) / (0, -1) anchored at the start / end, (1/2, -1/2) centred, (0, 0) fixed
    t = np.where(full, c1, 0.0)
    k_lo = np.where(full, 1.0 - t, np.where(from_a, 1.0, np.where(centre, 0.5, 0.0)))
    k_hi = np.where(full, -t, np.where(from_b, -1.0, np.where(centre, -0.5, 0.0)))
    unit = pq / np.maximum(np.linalg.norm(pq, axis=-1, keepdims=True), 1e-12)  # (P, M, 2) side direction P -> Q
    last_part = np.where(two, 1, 0)[:, None]
    std_lo = np.where(part == 0, e_lo, 0.0) / np.sqrt(3.0)  # the first part's free start
    std_hi = np.where(part == last_part, e_hi, 0.0) / np.sqrt(3.0)  # the last part's free end
    f_lo = np.where(valid[..., None], (k_lo * std_lo)[..., None] * unit, 0.0).reshape(p_count, -1)
    f_hi = np.where(valid[..., None], (k_hi * std_hi)[..., None] * unit, 0.0).reshape(p_count, -1)
    factors = np.stack([f_lo, f_hi], axis=1)  # (P, 2, 2M)
    # stacked measurement: x0, y0, x1, y1, ..., vx, vy
    m = pts.shape[1]
    radar = batch.fused[ci] & bool(use_radar)
    mask = np.concatenate([np.repeat(valid, 2, axis=1), np.repeat(radar[:, None], 2, axis=1)], axis=1)
    z = np.concatenate([pts.reshape(p_count, 2 * m), batch.velocity[ci]], axis=1)
    r = np.concatenate(
        [np.repeat(_lidar_variance(config, mode, occ.any(axis=1))[:, None], 2 * m, axis=1),
         np.full((p_count, 2), config.radar_velocity_sigma**2)],
        axis=1,
    )
    factors = np.concatenate([factors, np.zeros((p_count, 2, 2))], axis=2)  # no end noise on radar rows
    # features (cx, cy, L cos, L sin, cos, sin, W sin, W cos, v cos, v sin) -> stacked measurement
    ax, gx, ay, gy = (coef[..., i] for i in range(4))
    vf = valid.astype(float)
    matrix = np.zeros((p_count, 10, 2 * m + 2))
    xs, ys = matrix[:, :, 0 : 2 * m : 2], matrix[:, :, 1 : 2 * m : 2]
    xs[:, 0], xs[:, 2], xs[:, 4], xs[:, 5], xs[:, 6] = vf, ax, gx, -gy, -ay
    ys[:, 1], ys[:, 3], ys[:, 5], ys[:, 4], ys[:, 7] = vf, ax, gx, gy, ay
    if config.radar_rows == "speed":  # one row: the component along the predicted mean heading
        heading = mean_corners[:, 0] - mean_corners[:, 3]  # rear-right -> front-right corner
        u = heading / np.maximum(np.linalg.norm(heading, axis=-1, keepdims=True), 1e-12)
        z[:, -2] = np.einsum("pd,pd->p", batch.velocity[ci], u)
        mask[:, -1] = False
        matrix[:, 8, -2], matrix[:, 9, -2] = u[:, 0] * radar, u[:, 1] * radar
    else:
        matrix[:, 8, -2] = matrix[:, 9, -1] = radar
    return Structure(a=a, b=b, c1=c1, c2=c2, coef=coef, matrix=matrix, valid=valid, two_sided=two, sides=sides, mode=mode, radar=radar,
                     z=np.where(mask, z, 0.0), r=np.where(mask, r, 1.0), mask=mask, factors=factors,
                     excess=np.where(single[:, None], -np.inf, chord_len - predicted))


def structure_batch_args(batch: ClusterBatch) -> tuple[np.ndarray, ...]:
    """The clusters' arguments of the compiled structure kernel (``tracker.structure``), in its
    order: the batch's arrays (C-contiguous: one compiled signature), its shadow flags (none: no end in
    a shadow) and whether each bearing end is in a shadow or continues."""
    c = np.ascontiguousarray
    return (c(batch.points), c(batch.valid), c(batch.part), c(batch.proj), c(batch.chord_start), c(batch.chord_end),
            c(batch.chord_dir), c(batch.chord_len), c(batch.end_margin), c(batch.end_gap), c(batch.two_sided),
            c(batch.single), c(batch.fused), c(batch.velocity), c(batch.centroid),
            c(batch.occluded_end if batch.occluded_end is not None else np.zeros((len(batch.points), 2), dtype=bool)),
            c(~_free_ends(batch, np.arange(len(batch.points)))))


def structure_config_args(config: MeasurementConfig, shadows: bool, use_radar: bool,
                          has_extent_sd: bool) -> tuple[tuple, tuple]:
    """The settings' arguments of the compiled structure kernel, those before its ``extent_sd`` and
    those after it (``shadows``: the clusters have their shadow flags, ``ClusterBatch.occluded_end``;
    ``has_extent_sd``: the pairs' predicted extent sd are known, so the rules that need them apply)."""
    head = (float(config.single_point_min_apparent), float(config.partial_visibility), float(config.shadow_free_gap),
            float(config.lidar_sigma) ** 2, float(config.radar_velocity_sigma) ** 2, bool(use_radar),
            config.radar_rows == "speed", MIN_CHORD, _sharp_side_whole(config, shadows),
            _sharp_parts_whole(config, shadows, has_extent_sd))
    tail = (int(config.whole_min_points), float(config.whole_gate_sigmas), float(config.whole_gate_slack),
            MISSED_RAYS_SHARP, _shadowed_longer_whole(config, shadows, has_extent_sd), GROWTH_MIN_EXCESS, GROWTH_SIGMAS,
            WIDEST_VEHICLE, LONGEST_VEHICLE, -1.0 if config.settled_width_std is None else float(config.settled_width_std),
            _shadowed_parts_partial(config, shadows), bool(config.two_sided_data_partial),
            -1.0 if config.shadowed_lidar_sigma is None else float(config.shadowed_lidar_sigma) ** 2)
    return head, tail


def _build_structure_compiled(batch: ClusterBatch, ci: np.ndarray, mean_corners: np.ndarray, config: MeasurementConfig,
                              use_radar: bool, extent_sd: np.ndarray | None) -> Structure:
    from tracker.structure import structure_kernel

    head, tail = structure_config_args(config, batch.occluded_end is not None, use_radar, extent_sd is not None)
    sd = np.ascontiguousarray(extent_sd if extent_sd is not None else np.zeros((len(ci), 2)), dtype=float)
    fields = structure_kernel(*structure_batch_args(batch), ci, np.ascontiguousarray(mean_corners, dtype=float), *head,
                              sd, *tail)
    return Structure(*fields)


def predict_measurements(rect: Rectangles, structure: Structure) -> np.ndarray:
    """Predicted measurements ``(P, S, D)`` of pairs from sigma-point rectangles in E (``rect`` arrays of
    shape ``(P, S)``): the generating points of ``structure`` stacked (``x0, y0, x1, y1, ...``; padding
    0), then the radar rows ``v (cos psi_E, sin psi_E)`` (0 where masked).

    Every generating point is ``centre + (ax L + gx) e_x + (ay W + gy) e_y`` (``Structure.coef``), i.e.
    linear in the per-sigma-point features ``(cx, cy, L cos psi, L sin psi, cos psi, sin psi, W sin psi,
    W cos psi, v cos psi, v sin psi)``: the whole prediction is one batched product
    ``features (P, S, 10) @ Structure.matrix (P, 10, D)``."""
    c, s = np.cos(rect.psi), np.sin(rect.psi)
    feats = np.stack(
        [rect.center[..., 0], rect.center[..., 1], rect.length * c, rect.length * s, c, s,
         rect.width * s, rect.width * c, rect.v * c, rect.v * s],
        axis=-1,
    )
    return feats @ structure.matrix


def generating_points(
    state: np.ndarray,
    cluster: Cluster,
    ego: EgoState | tuple,
    road: Road | None = None,
    config: MeasurementConfig | None = None,
    coordinates: Coordinates = "curvilinear",
) -> np.ndarray:
    """The measurement generating points ``(M, 2)`` in E of one state ``(7,)`` for ``cluster`` (the
    state is its own predicted mean), in the cluster's point order. For inspection and tests."""
    config = config if config is not None else MeasurementConfig()
    rect = to_vehicle(np.asarray(state, dtype=float)[None, None], ego, road, coordinates)  # (1, 1)
    st = build_structure(ClusterBatch.of([cluster]), np.zeros(1, dtype=int), rect.corners()[:, 0], config,
                         use_radar=False)
    y = predict_measurements(rect, st)
    return y[0, 0, : 2 * cluster.size].reshape(-1, 2)
