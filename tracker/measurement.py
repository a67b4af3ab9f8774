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
cluster is two-sided in the data when it has at least ``min_points_two_sided`` points, the
eigenvalue ratio ``lambda_max / lambda_min`` of its points' covariance is below
``two_side_eigen_ratio`` (50) or ``sqrt(lambda_min)``, the points' RMS distance from one fitted line,
exceeds ``two_side_line_residual`` (0.15 m: a long dense side and a few returns across a face seen
edge-on; only where the corner split is a near corner, ``SPLIT_MIN_SIN`` and ``SPLIT_MAX_SPACING``),
and ``sqrt(lambda_min)`` exceeds ``two_side_min_residual`` (0.05 m: a few noisy returns on a short face
are not a corner). Its corner index is the split minimising the total least-squares line-fit residual
of the two parts (the paper: "least squares fitting lines"; the corner point belongs to both fits; all
splits at once from prefix sums). Each part (or the whole cluster) gets a total-least-squares line; its
*chord* is the extent of the points' projections on that line, and
for a two-sided cluster the chords meet at the intersection of the two lines (the corner, less noisy
than any single point). A point's position along its part is its projection on the line, in metres
from the chord's start (``proj``). Departures from MATLAB, which spaces points by cumulative polyline
length between the first and last points: with noise that length grows with the number of points
(zig-zag), and a single noisy extreme point shifts every generating point of the side; fitted lines,
projections and a fitted corner do not. Lines and extents use all points; then clusters above
``max_cluster_points`` are thinned evenly in bearing order, keeping the extreme points and the corner.

End gaps. A scanning lidar's extreme return on a side lies
somewhere within one ray gap of the side's free end (uniformly, for a random ray phase). The gap is
``g = r^2 db / d`` (range ``r`` of the end, median bearing step ``db`` of the cluster, distance ``d`` of
the line from the sensor), large on far or grazing sides. With the correction the chord is extended
by ``e = g / 2`` at each free end (never at a fitted corner), which removes the length bias, and the
remaining uncertainty ``eps ~ U(-e, e)`` (variance ``e^2 / 3``) enters the measurement noise as one
rank-one term per free end, ``f f^T`` with ``f`` the points' displacement per unit end shift (e.g.
``(1 - t_i) u`` over a fully visible side): the filter does not take the extreme points for the corners,
as MATLAB does.

Structure (per pair, from the component's predicted *mean*, shared by all its sigma points so the
model is a smooth function of the state): two-sided only if the data say so *and* the predicted
rectangle shows two sides; each part is matched to the side whose outward normal is closest to the
part's line direction turned by +90 deg (``argmax n_k . rot90(u)``; the paper writes the test as
``argmin |alpha_i - beta + pi/2|`` with its own normal convention); a two-sided cluster takes the best
adjacent pair ``(j, j - 1)``. Visibility ``a = (chord + end margins) / predicted side length``; a side
with ``a <= partial_visibility`` (0.9) is *partially visible*, unless the data show where it ends
(departures from the paper, ``MeasurementConfig``): a one-sided cluster with both ends sharp (half a
ray gap at most ``shadow_free_gap``) and free (no nearer return beyond it, ``occluded_end``; no return
continuing its line, ``continued_end``) is the whole side, and so is a part of a
two-sided cluster from the fitted corner to a sharp, free far end, when both parts have enough points
and the side shrinks by no more than the extent's uncertainty allows; a side
with an end in a shadow is partially visible whatever its extent (one-sided, when its other end is
sharp; a part of a two-sided cluster, unless its chord is longer than the
predicted side: then it is measured whole to its last return, no end-gap margin at the shadowed end);
a one-sided cluster with both ends in shadows of nearer objects (not the range limit) is a window onto
the side: partially visible, and its points share one more shift along the side, of standard deviation
``(side - chord) / sqrt(12)`` (a low-rank noise term, as the end gaps').

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

from tracker.centerline import rectangles_kernel
from tracker.config import MeasurementConfig
from tracker.frame import EgoState
from tracker.jit import njit
from tracker.kalman import predict_measurements_kernel
from tracker.road import Road
from tracker.structure import structure_kernel

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
#: A cluster two-sided by ``MeasurementConfig.two_side_line_residual`` alone needs its two parts' fitted
#: lines to meet at least this steeply (sine of 60 deg): a rectangle's corner, not two vehicles' sides
#: one behind the other, offset across (parked cars in a row) ...
SPLIT_MIN_SIN = math.sin(math.radians(60.0))
#: ... and rays at most this far apart at the corner (m; the corner's range times the cluster's median
#: bearing step: 45 m with a 0.2 deg lidar): farther, the sides of vehicles in a row seen at grazing
#: incidence join into one cluster, and one vehicle's face with the next one's side looks like a corner.
SPLIT_MAX_SPACING = 0.16
#: Largest end gap (m) the end-gap correction assumes (a side seen at a grazing angle can have metres
#: between rays; beyond this the correction is capped).
MAX_END_GAP = 2.0

#: A side's chord must exceed its predicted length by more than ``GROWTH_MIN_EXCESS`` (m) and by more
#: than ``GROWTH_SIGMAS`` standard deviations of the extent to be evidence of a longer side, not noise:
#: ``tracker.update.grow_extent`` then widens the prior. The chord runs between returns on the side, so
#: it is a lower bound of the side up to the range noise (a few centimetres); a quarter metre and one
#: standard deviation of the prior are evidence enough to let the update learn the extent (the widening
#: moves nothing by itself).
GROWTH_MIN_EXCESS = 0.25
GROWTH_SIGMAS = 1.0

#: A part's far end is also sharp (a part shown whole to a sharp, free far end) when the predicted side goes
#: on beyond its last return for at least this many ray gaps: the next ray along it would have hit it and
#: returned nothing there (a dropped return is no free end: a return further along the side's line makes
#: the end continue, ``MeasurementConfig.continuation_rays``).
MISSED_RAYS_SHARP = 1.0

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
        """Rectangles whose fields and corners a compiled kernel computed (``to_vehicle``'s kernel: the
        extent already floored), built without the dataclass's per-field checks of a frozen
        ``__init__`` (the tracker builds several per frame). The corners are returned read-only."""
        rect = object.__new__(cls)
        corners.flags.writeable = False
        rect.__dict__.update(center=center, psi=psi, v=v, length=length, width=width, _corners=corners)
        return rect

    def with_corners(self, corners: np.ndarray) -> Rectangles:
        """These rectangles with their corners already computed (``corners()`` then returns them,
        read-only): for a producer that computes them anyway (``to_vehicle``'s kernel)."""
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


def to_vehicle(
    states: np.ndarray, ego: EgoState | tuple, road: Road | None = None, coordinates: Coordinates = "curvilinear",
    euler_s0: float | None = None,
) -> Rectangles:
    """States ``(..., 7)`` as rectangles in E (module docstring). ``ego`` is an ``EgoState`` or
    ``(x, y, yaw[, v, yaw_rate])`` in G. Curvilinear states need ``road`` (open roads extrapolate along
    their end tangents) and use the exact conversion ``c(s) + n (-sin theta, cos theta)``: ``n`` positive
    to the left (the paper's Algorithm 1 writes the normal as ``(cos(pi/2 - theta), sin(pi/2 - theta))``,
    which points right), by one call of ``tracker.centerline.rectangles_kernel``. With ``euler_s0`` (the
    ego's arc length, m) a curvilinear state goes through the paper's Euler conversion instead
    (``Road.frame_euler``: Algorithm 1, the local cubic heading polynomial around ``euler_s0``), the
    ``paper`` variant's measurement model."""
    ego = EgoState.coerce(ego)
    x = np.asarray(states, dtype=float)
    if x.shape[-1] not in (7, 8):
        raise ValueError(f"states must have shape (..., 7) (or (..., 8) with the acceleration state); got {x.shape}")
    if coordinates == "curvilinear":
        if road is None:
            raise ValueError("curvilinear states need the road to go to E")
        if euler_s0 is None:
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
    at a free end, at most half the chord; 0 at the corner of a split; all 0 for a single point);
    ``end_gap (3, 2)`` the same half ray gap before the cap at half the chord (how sharp an end is: a
    short chord on a grazing side is not a sharp one; also 0 at the corner of a split); ``velocity
    (2,)`` the radar's absolute velocity in E (m/s) or ``None``; ``raw_count`` points before downsampling; ``dropped`` non-finite points removed;
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


def prepare_settings(config: MeasurementConfig) -> tuple:
    """``prepare_kernel``'s settings, the arguments after its points and offsets."""
    line_residual = math.inf if config.two_side_line_residual is None else float(config.two_side_line_residual)
    return (int(config.max_cluster_points), int(config.min_points_two_sided), float(config.two_side_eigen_ratio),
            float(config.two_side_min_residual), line_residual, MIN_CHORD, math.sin(CORNER_MIN_ANGLE), CORNER_MAX_SHIFT,
            MAX_END_GAP)


def finite_cluster_points(points: np.ndarray, velocity: np.ndarray | None = None
                          ) -> tuple[np.ndarray, np.ndarray, int, np.ndarray | None]:
    """A cluster's checked input: its finite points ``(N', 2)`` (C-contiguous), their indices in
    ``points``, how many non-finite points were dropped, and ``velocity`` as a finite ``(2,)`` (or None).
    A clear ``ValueError`` for points not of shape ``(N, 2)``, no finite point, or a bad velocity."""
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ValueError(f"cluster points must have shape (N, 2) (x, y in E, m); got {pts.shape}")
    finite = np.isfinite(pts).all(axis=1)
    dropped = int((~finite).sum())
    if dropped == len(pts):
        raise ValueError(f"a cluster needs at least one finite point; got none ({dropped} non-finite dropped)")
    if velocity is not None:
        velocity = np.asarray(velocity, dtype=float).reshape(-1)
        if velocity.shape != (2,) or not np.isfinite(velocity).all():
            raise ValueError(f"cluster velocity must be a finite (vx, vy) in m/s; got {velocity!r}")
    return np.ascontiguousarray(pts[finite]), np.flatnonzero(finite), dropped, velocity


def prepare_cluster(
    points: np.ndarray, config: MeasurementConfig | None = None, velocity: np.ndarray | None = None
) -> Cluster:
    """Prepare lidar ``points (N, 2)`` in E (m) for the rectangle model: drop non-finite points
    (counted in ``dropped``), then ``prepare_kernel`` (module docstring): sort by bearing, decide
    one/two-sided from the eigenvalue ratio, find the corner, downsample to ``config.max_cluster_points``
    and compute each point's chord coordinates. ``velocity`` is an associated radar detection's absolute
    velocity ``(vx, vy)`` in E (m/s)."""
    config = config if config is not None else MeasurementConfig()
    pts, index, dropped, velocity = finite_cluster_points(points, velocity)
    (kept, _, part, proj, starts, ends, direction, length, margin, half_gap, two, corner, ratio, order,
     kept_count) = prepare_kernel(pts, np.array([0, len(pts)], dtype=np.intp), *prepare_settings(config))
    m = int(kept_count[0])
    return Cluster(
        points=kept[0, :m], part=part[0, :m], proj=proj[0, :, :m], chord_start=starts[0], chord_end=ends[0],
        chord_dir=direction[0], chord_len=length[0], two_sided=bool(two[0]), corner=int(corner[0]),
        eigen_ratio=float(ratio[0]), end_margin=margin[0], velocity=velocity, raw_count=len(pts), dropped=dropped,
        order=index[order[0, :m]], end_gap=half_gap[0],
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


def _free_ends(batch: ClusterBatch, ci: np.ndarray) -> np.ndarray:
    """``(P, 2)``: whether each bearing end of the pairs' clusters is free (in no shadow, not continued)."""
    free = np.ones((len(ci), 2), dtype=bool)
    for flags in (batch.occluded_end, batch.continued_end):
        if flags is not None:
            free &= ~flags[ci]
    return free


def build_structure(
    batch: ClusterBatch,
    cluster_index: np.ndarray,
    mean_corners: np.ndarray,
    config: MeasurementConfig,
    use_radar: bool = True,
    *,
    extent_sd: np.ndarray | None = None,
    lidar_range: float = math.inf,
) -> Structure:
    """The measurement structure of pairs (cluster ``cluster_index (P,)``, predicted mean rectangle
    ``mean_corners (P, 4, 2)`` in E): one/two-sided, side matching, partial visibility and anchoring,
    as in the module docstring, by ``tracker.structure.structure_kernel``. ``extent_sd (P, 2)``: the
    predicted standard deviations of ``L`` and ``W`` (m), for the rule that needs them (a part shown
    whole to a sharp, free far end, within a gate; None: that rule does not apply). ``lidar_range`` (m;
    default: none): the lidar's range, whose limit flags ends as a shadow does (``structure_config_args``)."""
    ci = np.asarray(cluster_index, dtype=np.intp)
    if extent_sd is not None:
        extent_sd = np.asarray(extent_sd, dtype=float).reshape(len(ci), 2)
    head, tail = structure_config_args(config, use_radar, lidar_range)
    sd = np.ascontiguousarray(extent_sd if extent_sd is not None else np.zeros((len(ci), 2)), dtype=float)
    fields = structure_kernel(*structure_batch_args(batch), ci, np.ascontiguousarray(mean_corners, dtype=float), *head,
                              batch.occluded_end is not None, extent_sd is not None, sd, *tail)
    return Structure(*fields)


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


def structure_config_args(config: MeasurementConfig, use_radar: bool,
                          lidar_range: float = math.inf) -> tuple[tuple, tuple]:
    """The settings' arguments of the compiled structure kernel, those before its ``shadows`` (whether
    the clusters have their shadow flags, ``ClusterBatch.occluded_end``) and those after its
    ``extent_sd``; ``lidar_range`` (m): ends within ``shadow_range_margin`` of it are flagged for the
    range limit, not for a nearer object's shadow."""
    head = (float(config.single_point_min_apparent), float(config.partial_visibility), float(config.shadow_free_gap),
            float(config.lidar_sigma) ** 2, float(config.radar_velocity_sigma) ** 2, bool(use_radar),
            config.radar_rows == "speed", MIN_CHORD)
    tail = (int(config.whole_min_points), float(config.whole_gate_sigmas), float(config.whole_gate_slack),
            MISSED_RAYS_SHARP,
            -1.0 if config.shadowed_lidar_sigma is None else float(config.shadowed_lidar_sigma) ** 2,
            float(lidar_range) - float(config.shadow_range_margin))
    return head, tail


def predict_measurements(rect: Rectangles, structure: Structure) -> np.ndarray:
    """Predicted measurements ``(P, S, D)`` of pairs from sigma-point rectangles in E (``rect`` arrays of
    shape ``(P, S)``): the generating points of ``structure`` stacked (``x0, y0, x1, y1, ...``; padding
    0), then the radar rows ``v (cos psi_E, sin psi_E)`` (0 where masked).

    Every generating point is ``centre + (ax L + gx) e_x + (ay W + gy) e_y`` (``Structure.coef``), i.e.
    linear in the per-sigma-point features ``(cx, cy, L cos psi, L sin psi, cos psi, sin psi, W sin psi,
    W cos psi, v cos psi, v sin psi)``: the whole prediction is one batched product
    ``features (P, S, 10) @ Structure.matrix (P, 10, D)`` (``tracker.kalman.predict_measurements_kernel``,
    the model the update's kernels evaluate)."""
    shape = rect.center.shape[:2]
    c = np.ascontiguousarray
    return predict_measurements_kernel(
        c(rect.center, dtype=float),
        *(c(np.broadcast_to(a, shape), dtype=float) for a in (rect.psi, rect.v, rect.length, rect.width)),
        c(structure.matrix, dtype=float))


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


# --------------------------------------------------------------------------------------------------
# The compiled kernels of this stage.
#
# Cluster preparation (module docstring, "Data"), one cluster after the other: centroid and biased
# scatter, the points sorted by bearing about the centroid's bearing (a stable sort), one or two sides
# from the scatter's eigenvalue ratio, the corner split minimising the two line fits' total-least-squares
# residuals (prefix sums over every split), even downsampling (indices rounded half to even, the corner
# kept in both parts), the chords of slots 0, 1, 2 (all points; before and after the corner, the corner
# point in both), the corner where the two fitted lines meet, the end-gap margins and each kept point's
# chord coordinates.
# --------------------------------------------------------------------------------------------------


@njit(inline="always")
def _lambda_min_scalar(sxx: float, syy: float, sxy: float) -> float:
    """Smallest eigenvalue of the symmetric 2x2 matrix ``[[sxx, sxy], [sxy, syy]]``."""
    return 0.5 * (sxx + syy) - math.sqrt(0.25 * (sxx - syy) ** 2 + sxy * sxy)


@njit(inline="always")
def _residual(cnt: float, sx: float, sy: float, sxx: float, syy: float, sxy: float) -> float:
    """The summed squared distances of ``cnt`` points from their total-least-squares line (the smallest
    eigenvalue of their scatter matrix, at least 0), from the sums of their ``x``, ``y``, ``x^2``,
    ``y^2`` and ``x y``."""
    cnt = max(cnt, 1.0)
    return max(_lambda_min_scalar(sxx - sx * sx / cnt, syy - sy * sy / cnt, sxy - sx * sy / cnt), 0.0)


@njit(inline="always")
def _even(keep: np.ndarray, lo: int, hi: int, count: int) -> None:
    """Mark in ``keep`` ``count`` indices (at least 2) evenly spread over ``lo..hi``, both ends kept
    (``j (hi - lo) / (count - 1) + lo`` rounded half to even)."""
    count = max(count, 2)
    step = (hi - lo) / (count - 1)
    for j in range(count):
        pos = float(hi) if j == count - 1 else j * step + lo
        keep[int(np.rint(pos))] = True


@njit(inline="always")
def _mean_scatter(pts, j0, j1):
    """Centroid and biased scatter ``(cx, cy, sxx, syy, sxy)`` of ``pts[j0:j1 + 1]``."""
    cnt = j1 - j0 + 1
    cx = 0.0
    cy = 0.0
    for j in range(j0, j1 + 1):
        cx += pts[j, 0]
        cy += pts[j, 1]
    cx /= cnt
    cy /= cnt
    sxx = 0.0
    syy = 0.0
    sxy = 0.0
    for j in range(j0, j1 + 1):
        dx = pts[j, 0] - cx
        dy = pts[j, 1] - cy
        sxx += dx * dx
        syy += dy * dy
        sxy += dx * dy
    return cx, cy, sxx / cnt, syy / cnt, sxy / cnt


@njit(inline="always")
def _corner_split(pts: np.ndarray, n: int) -> int:
    """The corner of the bearing-sorted ``pts[:n]`` (``n >= 3``): the split ``k`` in ``1..n-2`` minimising
    the summed total-least-squares residuals of the points ``0..k`` and ``k..n-1`` (the corner point in
    both), every split from prefix sums of the centred coordinates (the first of equal minima)."""
    cx, cy, _, _, _ = _mean_scatter(pts, 0, n - 1)
    c = np.zeros((n + 1, 6))
    for j in range(n):
        x = pts[j, 0] - cx
        y = pts[j, 1] - cy
        c[j + 1, 0] = c[j, 0] + 1.0
        c[j + 1, 1] = c[j, 1] + x
        c[j + 1, 2] = c[j, 2] + y
        c[j + 1, 3] = c[j, 3] + x * x
        c[j + 1, 4] = c[j, 4] + y * y
        c[j + 1, 5] = c[j, 5] + x * y
    best = np.inf
    k_best = 1
    for k in range(1, n - 1):
        head = _residual(c[k + 1, 0], c[k + 1, 1], c[k + 1, 2], c[k + 1, 3], c[k + 1, 4], c[k + 1, 5])
        tail = _residual(c[n, 0] - c[k, 0], c[n, 1] - c[k, 1], c[n, 2] - c[k, 2],
                         c[n, 3] - c[k, 3], c[n, 4] - c[k, 4], c[n, 5] - c[k, 5])
        if head + tail < best:
            best = head + tail
            k_best = k
    return k_best


@njit(inline="always")
def _split_turns(pts: np.ndarray, n: int, k: int, min_sin: float) -> bool:
    """Whether the total-least-squares lines of the bearing-sorted ``pts[0..k]`` and ``pts[k..n-1]``
    meet at an angle whose sine is at least ``min_sin``."""
    _, _, axx, ayy, axy = _mean_scatter(pts, 0, k)
    _, _, bxx, byy, bxy = _mean_scatter(pts, k, n - 1)
    phi = 0.5 * math.atan2(2.0 * axy, axx - ayy) - 0.5 * math.atan2(2.0 * bxy, bxx - byy)
    return abs(math.sin(phi)) >= min_sin


@njit
def prepare_kernel(flat, offsets, bound, min_two, ratio_max, min_residual, line_residual, min_chord, sin_min_angle,
                   max_shift, max_end_gap):
    """The clusters ``flat[offsets[i]:offsets[i + 1]]`` (finite, non-empty) prepared, in padded arrays
    (kept points padded to the largest count a cluster may keep): ``(points, valid, part, proj,
    chord_start, chord_end, chord_dir, chord_len, end_margin, end_gap, two_sided, corner, eigen_ratio,
    order, kept_count)``, ``Cluster``'s fields of each cluster, ``order`` the index of each kept point in
    its cluster's input. The settings after ``offsets`` are ``prepare_settings``'."""
    count = len(offsets) - 1
    width = 0
    for i in range(count):
        width = max(width, min(offsets[i + 1] - offsets[i], bound + 2))
    points = np.zeros((count, width, 2))
    valid = np.zeros((count, width), dtype=np.bool_)
    part = np.zeros((count, width), dtype=np.intp)
    proj = np.zeros((count, 2, width))
    order_out = np.zeros((count, width), dtype=np.intp)
    chord_start = np.zeros((count, 3, 2))
    chord_end = np.zeros((count, 3, 2))
    chord_dir = np.zeros((count, 3, 2))
    chord_len = np.zeros((count, 3))
    end_margin = np.zeros((count, 3, 2))
    end_gap = np.zeros((count, 3, 2))
    two_sided = np.zeros(count, dtype=np.bool_)
    corner_out = np.full(count, -1, dtype=np.intp)
    eigen_ratio = np.zeros(count)
    kept_count = np.zeros(count, dtype=np.intp)
    for i in range(count):
        o = offsets[i]
        n = offsets[i + 1] - o
        raw = flat[o : o + n]
        cx, cy, sxx, syy, sxy = _mean_scatter(raw, 0, n - 1)  # centroid, biased scatter
        # bearing order about the centroid's bearing
        ref = math.atan2(cy, cx) if math.hypot(cx, cy) > 1e-9 else 0.0
        rel0 = np.empty(n)
        for j in range(n):
            a = math.atan2(raw[j, 1], raw[j, 0]) - ref
            rel0[j] = a - 2.0 * np.pi * np.rint(a / (2.0 * np.pi))
        order = np.argsort(rel0, kind="mergesort")
        pts = np.empty((n, 2))
        rel = np.empty(n)
        for j in range(n):
            pts[j, 0] = raw[order[j], 0]
            pts[j, 1] = raw[order[j], 1]
            rel[j] = rel0[order[j]]
        # one or two sides
        root = math.sqrt(0.25 * (sxx - syy) ** 2 + sxy * sxy)
        lam_min = 0.5 * (sxx + syy) - root
        lam_max = 0.5 * (sxx + syy) + root
        ratio = np.inf
        if n >= 2 and lam_min > 1e-15 * max(lam_max, 1e-300):
            ratio = lam_max / lam_min
        db = 0.0  # the median bearing step between neighbouring points (rad)
        if n >= 2:
            gaps = rel[1:] - rel[:-1]
            gaps = gaps[np.argsort(gaps, kind="mergesort")]  # numpy.sort's values
            db = gaps[(n - 1) // 2]
        two = n >= min_two and lam_min > min_residual * min_residual
        k = -1
        if two and ratio >= ratio_max:  # a line by the ratio: a corner only if no line fits and the split is one
            two = lam_min > line_residual * line_residual
            if two:
                k = _corner_split(pts, n)
                two = (_split_turns(pts, n, k, SPLIT_MIN_SIN)
                       and math.hypot(pts[k, 0], pts[k, 1]) * db <= SPLIT_MAX_SPACING)
        if two and k < 0:
            k = _corner_split(pts, n)
        # downsampling
        keep = np.zeros(n, dtype=np.bool_)
        if n > bound:
            if two:
                m0 = min(max(2, int(np.rint(bound * (k + 1) / (n + 1)))), bound - 1)
                _even(keep, 0, k, m0)
                _even(keep, k, n - 1, bound + 1 - m0)
            else:
                _even(keep, 0, n - 1, bound)
        else:
            keep[:] = True
        # chords: slot 0 all points, slot 1 = 0..k, slot 2 = k..n-1 (two-sided)
        norm = max(math.hypot(cx, cy), 1e-12)
        origin = np.zeros((3, 2))
        direction = np.zeros((3, 2))
        lo = np.zeros(3)
        hi = np.zeros(3)
        for s in range(3):
            j0 = 0
            j1 = n - 1
            if two and s == 1:
                j1 = k
            if two and s == 2:
                j0 = k
            cnt = j1 - j0 + 1
            ox, oy, mxx, myy, mxy = _mean_scatter(pts, j0, j1)
            if cnt < 2 or mxx + myy <= min_chord * min_chord:
                ux = -cy / norm
                uy = cx / norm
            else:
                phi = 0.5 * math.atan2(2.0 * mxy, mxx - myy)
                ux = math.cos(phi)
                uy = math.sin(phi)
                if ux * (pts[j1, 0] - pts[j0, 0]) + uy * (pts[j1, 1] - pts[j0, 1]) < 0.0:
                    ux = -ux
                    uy = -uy
            low = np.inf
            high = -np.inf
            for j in range(j0, j1 + 1):
                t = (pts[j, 0] - ox) * ux + (pts[j, 1] - oy) * uy
                low = min(low, t)
                high = max(high, t)
            origin[s, 0] = ox
            origin[s, 1] = oy
            direction[s, 0] = ux
            direction[s, 1] = uy
            lo[s] = low
            hi[s] = high
        if two:  # the corner: where the two fitted lines meet, if they meet near the corner point
            u1x, u1y, u2x, u2y = direction[1, 0], direction[1, 1], direction[2, 0], direction[2, 1]
            den = u1x * u2y - u1y * u2x
            ok = abs(den) >= sin_min_angle
            wx = origin[2, 0] - origin[1, 0]
            wy = origin[2, 1] - origin[1, 1]
            a = (wx * u2y - wy * u2x) / (den if ok else 1.0)
            xx = origin[1, 0] + a * u1x
            xy = origin[1, 1] + a * u1y
            ok = ok and math.hypot(xx - pts[k, 0], xy - pts[k, 1]) <= max_shift
            if not ok:
                xx = pts[k, 0]
                xy = pts[k, 1]
            h1 = (xx - origin[1, 0]) * u1x + (xy - origin[1, 1]) * u1y
            l2 = (xx - origin[2, 0]) * u2x + (xy - origin[2, 1]) * u2y
            hi[1] = max(h1, lo[1])
            lo[2] = min(l2, hi[2])
        starts = np.empty((3, 2))
        ends = np.empty((3, 2))
        length = np.empty(3)
        for s in range(3):
            for d in range(2):
                starts[s, d] = origin[s, d] + lo[s] * direction[s, d]
                ends[s, d] = origin[s, d] + hi[s] * direction[s, d]
            length[s] = hi[s] - lo[s]
        margin = np.zeros((3, 2))
        half_gap = np.zeros((3, 2))
        if n >= 2:
            for s in range(3):
                dist = abs(origin[s, 0] * direction[s, 1] - origin[s, 1] * direction[s, 0])
                r2s = starts[s, 0] * starts[s, 0] + starts[s, 1] * starts[s, 1]
                r2e = ends[s, 0] * ends[s, 0] + ends[s, 1] * ends[s, 1]
                half_gap[s, 0] = 0.5 * min(r2s * db / max(dist, 1e-3), max_end_gap)
                half_gap[s, 1] = 0.5 * min(r2e * db / max(dist, 1e-3), max_end_gap)
                margin[s, 0] = min(half_gap[s, 0], 0.5 * length[s])
                margin[s, 1] = min(half_gap[s, 1], 0.5 * length[s])
            if two:
                margin[1, 1] = 0.0  # the corner of a split is observed
                margin[2, 0] = 0.0
                half_gap[1, 1] = 0.0
                half_gap[2, 0] = 0.0
        # the kept points, compacted, with their part and chord coordinates
        corner = -1
        if two:
            corner = 0
            for j in range(k):
                if keep[j]:
                    corner += 1
        m = 0
        for j in range(n):
            if not keep[j]:
                continue
            points[i, m, 0] = pts[j, 0]
            points[i, m, 1] = pts[j, 1]
            valid[i, m] = True
            p = 1 if (two and m > corner) else 0
            part[i, m] = p
            proj[i, 0, m] = (pts[j, 0] - starts[0, 0]) * direction[0, 0] + (pts[j, 1] - starts[0, 1]) * direction[0, 1]
            proj[i, 1, m] = ((pts[j, 0] - starts[1 + p, 0]) * direction[1 + p, 0]
                             + (pts[j, 1] - starts[1 + p, 1]) * direction[1 + p, 1])
            order_out[i, m] = order[j]
            m += 1
        for s in range(3):
            src = s if two else 0  # one part: slots 1 and 2 repeat slot 0
            for d in range(2):
                chord_start[i, s, d] = starts[src, d]
                chord_end[i, s, d] = ends[src, d]
                chord_dir[i, s, d] = direction[src, d]
                end_margin[i, s, d] = margin[src, d]
                end_gap[i, s, d] = half_gap[src, d]
            chord_len[i, s] = length[src]
        two_sided[i] = two
        corner_out[i] = corner
        eigen_ratio[i] = ratio
        kept_count[i] = m
    return (points, valid, part, proj, chord_start, chord_end, chord_dir, chord_len, end_margin, end_gap, two_sided,
            corner_out, eigen_ratio, order_out, kept_count)
