"""3-D lidar preprocessing: a roof lidar's point cloud to 2-D points on the road plane.

The paper's car carries a Velodyne VLP-16 on its roof; the tracker's 2-D code (clustering, the
rectangle measurement model) takes points ``(x, y)`` in the vehicle frame E. This module turns one
3-D scan into those points:

1. **Mount transform** (:func:`mount_transform`): sensor frame S -> vehicle frame E,
   ``p_E = R(roll, pitch, yaw) p_S + t``.
2. **Non-finite points** dropped (counted).
3. **Ground fit** (:func:`fit_ground`), after Zermas et al. 2017 ("Fast segmentation of 3D point
   clouds: a paradigm on LiDAR data for autonomous vehicle applications", ICRA): the cloud is cut
   into segments along the driving direction x and one ground plane is estimated per segment, so
   that a change of grade (a crest, a sag, a ramp) is followed piecewise. Per segment: seeds are the
   points near the lowest point representative (LPR), hypotheses are RANSAC planes through 3 seeds,
   scored all at once, and the best is refined by PCA fits on its inliers.
4. **Classification** against each point's segment plane, by the signed height ``h`` above it:
   ground ``|h| <= distance_threshold``; below ground ``h < -distance_threshold`` (multipath
   reflections, puddles, noise); above the ceiling ``h > height_ceiling`` (bridges, signs, canopies);
   the rest is kept.
5. **Projection** of the kept points onto their segment's plane along its normal; their ``(x, y)``
   in E are the 2-D points.

Frames and units: E has its origin at the ego's geometric centre on the ground (z = 0 on the ground
under the ego centre when the ground is level), x forward, y left, z up. The sensor frame S is the
lidar's own (x forward, y left, z up). SI units throughout (m, rad); degrees only in names ending in
``_deg``.

Entry points: :func:`to_ground_plane` (2-D points and :class:`CloudStats`) and
:func:`process_cloud` (a :class:`CloudResult` with everything a figure of "raw cloud / without
ground / projected points" needs). Everything is vectorised with numpy; the only Python loops run
over the handful of segments and the refinement iterations.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

__all__ = [
    "CloudConfig",
    "CloudResult",
    "CloudStats",
    "GroundModel",
    "fit_ground",
    "mount_rotation",
    "mount_transform",
    "process_cloud",
    "to_ground_plane",
]

#: The spread check (``CloudConfig.min_spread``) looks at this percentage of a plane's inliers, the
#: ones nearest (in x-y) to their median: a few stray inliers far away do not make a line a plane.
_CORE_PERCENT = 80.0
#: ... on an even stride subsample of at most this many of them.
_SPREAD_POINTS = 256

#: A 3-point sample with ``|(p1 - p0) x (p2 - p0)|`` (twice its triangle's area, m^2) below this is
#: degenerate (repeated or collinear points).
_DEGENERATE_AREA = 1e-6

#: A hinged-fit sample (the hinge point and 2 seeds) whose two x-y offsets from the hinge point make an
#: angle with a sine below this is degenerate (the three nearly in a line).
_HINGE_MIN_SINE = 0.02

#: RANSAC hypotheses are scored on an even stride subsample of at most this many of a patch's fit points
#: (the best one's inliers are then refitted on all of them).
_SCORE_POINTS = 64


# --------------------------------------------------------------------------------------------------
# configuration


def _real(name: str, value: Any, *, low: float | None = None, high: float | None = None,
          low_open: bool = False, high_open: bool = False, unit: str = "") -> float:
    """``value`` as a float, or ``ValueError`` naming ``CloudConfig.<name>`` and the allowed range."""
    where = f"CloudConfig.{name}"
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{where} must be a real number{(' in ' + unit) if unit else ''}; got {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise ValueError(f"{where} must be finite; got {value!r}")
    bad_low = low is not None and (v <= low if low_open else v < low)
    bad_high = high is not None and (v >= high if high_open else v > high)
    if bad_low or bad_high:
        lo = "" if low is None else (f"> {low}" if low_open else f">= {low}")
        hi = "" if high is None else (f"< {high}" if high_open else f"<= {high}")
        rng = " and ".join(part for part in (lo, hi) if part)
        raise ValueError(f"{where} must be {rng}{(' ' + unit) if unit else ''}; got {value!r}")
    return v


def _integer(name: str, value: Any, low: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise ValueError(f"CloudConfig.{name} must be an integer >= {low}; got {value!r}")
    return int(value)


@dataclass(frozen=True)
class CloudConfig:
    """Every number of the 3-D preprocessing, with its unit; validated on construction.

    CONFIG_DOC
    """

    mount_x: float = 0.0
    mount_y: float = 0.0
    mount_z: float = 1.9
    mount_roll_deg: float = 0.0
    mount_pitch_deg: float = 0.0
    mount_yaw_deg: float = 0.0
    ring_edges: tuple[float, ...] = (10.0, 14.0, 19.0, 27.0, 40.0, 55.0, 70.0, 85.0)
    ring_sectors: tuple[int, ...] = (16, 16, 16, 16, 16, 16, 16, 16)
    seed_fraction: float = 0.1
    seed_height: float = 0.4
    ransac_iterations: int = 64
    distance_threshold: float = 0.15
    refine_iterations: int = 3
    max_slope_deg: float = 15.0
    min_spread: float = 1.0
    max_step: float = 0.25
    max_slope_change_deg: float = 5.0
    hinge_prior_length: float = 2.0
    min_points: int = 30
    max_fit_points: int = 128
    height_ceiling: float = 4.0
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("mount_x", "mount_y", "mount_z"):
            _real(name, getattr(self, name), unit="m")
        for name in ("mount_roll_deg", "mount_pitch_deg", "mount_yaw_deg"):
            _real(name, getattr(self, name), low=-360.0, high=360.0, unit="deg")
        edges = self.ring_edges
        if isinstance(edges, (str, bytes)) or not hasattr(edges, "__iter__"):
            raise ValueError(f"CloudConfig.ring_edges must be a sequence of radii in m; got {edges!r}")
        edges = tuple(_real(f"ring_edges[{i}]", e, low=0.0, low_open=True, unit="m") for i, e in enumerate(edges))
        if any(b <= a for a, b in zip(edges, edges[1:])):
            raise ValueError(f"CloudConfig.ring_edges must be strictly increasing; got {self.ring_edges!r}")
        object.__setattr__(self, "ring_edges", edges)
        sectors = self.ring_sectors
        if isinstance(sectors, (int, np.integer)) and not isinstance(sectors, bool):
            sectors = (sectors,) * len(edges)  # one count for every ring
        if isinstance(sectors, (str, bytes)) or not hasattr(sectors, "__iter__"):
            raise ValueError(f"CloudConfig.ring_sectors must be a sequence of integers; got {self.ring_sectors!r}")
        sectors = tuple(_integer(f"ring_sectors[{i}]", s, 1) for i, s in enumerate(sectors))
        if len(sectors) != len(edges):
            raise ValueError(f"CloudConfig.ring_sectors must hold one count per ring outside the disc "
                             f"({len(edges)}, as ring_edges); got {self.ring_sectors!r}")
        object.__setattr__(self, "ring_sectors", sectors)
        _real("seed_fraction", self.seed_fraction, low=0.0, high=1.0, low_open=True)
        _real("seed_height", self.seed_height, low=0.0, low_open=True, unit="m")
        _integer("ransac_iterations", self.ransac_iterations, 1)
        _real("distance_threshold", self.distance_threshold, low=0.0, low_open=True, unit="m")
        _integer("refine_iterations", self.refine_iterations, 0)
        _real("max_slope_deg", self.max_slope_deg, low=0.0, high=90.0, low_open=True, high_open=True, unit="deg")
        _real("min_spread", self.min_spread, low=0.0, unit="m")
        _real("max_step", self.max_step, low=0.0, low_open=True, unit="m")
        _real("max_slope_change_deg", self.max_slope_change_deg, low=0.0, high=90.0, low_open=True, high_open=True, unit="deg")
        _real("hinge_prior_length", self.hinge_prior_length, low=0.0, low_open=True, unit="m")
        _integer("min_points", self.min_points, 3)
        _integer("max_fit_points", self.max_fit_points, self.min_points)
        ceiling = _real("height_ceiling", self.height_ceiling, low=0.0, low_open=True, unit="m")
        if ceiling <= self.distance_threshold:
            raise ValueError(f"CloudConfig.height_ceiling must be > distance_threshold "
                             f"({self.distance_threshold!r} m); got {self.height_ceiling!r}")
        _integer("seed", self.seed, 0)

    @property
    def mount_translation(self) -> np.ndarray:
        """``t = (mount_x, mount_y, mount_z)`` (m), the sensor origin in E."""
        return np.array([self.mount_x, self.mount_y, self.mount_z], dtype=float)


# --------------------------------------------------------------------------------------------------
# input checks and the mount transform


def _as_points(points: Any, name: str) -> np.ndarray:
    """``points`` as a float ``(N, 3)`` array, or ``ValueError`` saying what is wrong."""
    try:
        arr = np.asarray(points)
    except (ValueError, TypeError) as exc:  # ragged nested sequences
        raise ValueError(f"{name} must be an (N, 3) array of real numbers; "
                         f"got an unreadable sequence ({exc})") from None
    if arr.dtype == bool or not (np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)):
        raise ValueError(f"{name} must hold real numbers; got dtype {arr.dtype}")
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"{name} must have shape (N, 3); got {arr.shape}")
    return arr.astype(float, copy=False)


def mount_rotation(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """The rotation ``R`` (3, 3) taking sensor-frame vectors to E; angles in rad.

    Intrinsic z-y'-x'' (aerospace, Tait-Bryan) convention: yaw about z, then pitch about the new y,
    then roll about the newest x, i.e. ``R = Rz(yaw) Ry(pitch) Rx(roll)`` with::

        Rz(a) = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
        Ry(a) = [[c, 0, s], [0, 1, 0], [-s, 0, c]]
        Rx(a) = [[1, 0, 0], [0, c, -s], [0, s, c]]

    Each is a right-handed rotation about its axis in E's z-up frame, so: positive yaw turns the
    sensor's x-axis left (towards +y); positive pitch turns it *down* (``R e_x = (cos p, 0, -sin p)``
    at zero yaw); positive roll lifts the sensor's y-axis (its left side up, right side down).
    """
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return rz @ ry @ rx


def _config_rotation(config: CloudConfig) -> np.ndarray:
    return mount_rotation(math.radians(config.mount_roll_deg), math.radians(config.mount_pitch_deg),
                          math.radians(config.mount_yaw_deg))


def mount_transform(points_sensor: Any, config: CloudConfig | None = None) -> np.ndarray:
    """Points ``(N, 3)`` in the sensor frame expressed in E (m).

    .. math::  p_E = R(\\phi, \\theta, \\psi)\\, p_S + t, \\qquad
               R = R_z(\\psi) R_y(\\theta) R_x(\\phi), \\quad t = (x_m, y_m, z_m)

    with the mount pose of ``config`` (:func:`mount_rotation` gives ``R`` and its signs). The
    inverse is ``p_S = R^T (p_E - t)``. Non-finite rows stay non-finite.
    """
    cfg = CloudConfig() if config is None else config
    return _transform(_as_points(points_sensor, "points_sensor"), cfg)


def _transform(pts: np.ndarray, cfg: CloudConfig) -> np.ndarray:
    if cfg.mount_roll_deg == cfg.mount_pitch_deg == cfg.mount_yaw_deg == 0.0:
        return pts + cfg.mount_translation  # R = I
    out = pts @ _config_rotation(cfg).T
    out += cfg.mount_translation
    return out


# --------------------------------------------------------------------------------------------------
# the patch layout and the ground model


def _ring_starts(sectors: np.ndarray) -> np.ndarray:
    """Index of each ring's first patch: ``first_j = S_0 + ... + S_{j-1}``."""
    return np.concatenate(([0], np.cumsum(sectors)[:-1])).astype(np.intp)


def _patch_index(x: np.ndarray, y: np.ndarray, centre: tuple[float, float], edges: np.ndarray,
                 sectors: np.ndarray, first: np.ndarray) -> np.ndarray:
    """The patch of each point ``(x, y)`` (arrays, m in E); see :class:`GroundModel`."""
    dx = x - centre[0]
    dy = y - centre[1]
    ring = np.searchsorted(edges, np.hypot(dx, dy), side="left")
    s = sectors[ring]
    k = np.floor(np.arctan2(dy, dx) * (s / (2.0 * math.pi)) + 0.5).astype(np.intp)
    k %= s
    return first[ring] + k


@dataclass(frozen=True, eq=False)
class GroundModel:
    """Piecewise-planar ground in E: one plane per patch of a polar grid around the sensor.

    The layout (after Patchwork's concentric zones, Lim et al. 2021): with ``centre = (c_x, c_y)``
    (m, the sensor's position in E, around which its scan rings lie), a point's horizontal distance
    ``rho = |(x - c_x, y - c_y)|`` and azimuth ``phi = atan2(y - c_y, x - c_x)``, and
    ``ring_edges = (e_0, ..., e_{R-1})`` (m): ring 0 is the disc ``rho <= e_0`` (the ego's patch,
    ``sectors[0] == 1``), ring ``j`` the annulus ``e_{j-1} < rho <= e_j`` (``e_R = inf``), cut into
    ``S_j = sectors[j]`` equal sectors; sector ``k`` of ring ``j`` is centred on the azimuth
    ``phi_k = 2 pi k / S_j`` (``k = 0`` straight ahead along the sensor's x... along E's x) and holds
    the points with ``floor(phi S_j / (2 pi) + 1/2) mod S_j = k``. Patches are numbered ring by ring,
    ``p = S_0 + ... + S_{j-1} + k``; ``ring_edges = ()`` is one plane for the whole cloud.

    Patch ``p``'s plane is ``{q : n_p . q + d_p = 0}`` with a unit normal ``n_p`` (``n_{p,z} > 0``,
    pointing up) and offset ``d_p`` (m); the signed height of a point above it, along the normal, is

    .. math::  h(q) = n_p \\cdot q + d_p

    and its projection onto the plane along the normal is ``q - h(q) n_p``.

    Fields (arrays are read-only, one entry per patch; normals are scaled to unit length and turned
    up, with their offsets, on construction):

    - ``ring_edges`` (m), ``sectors`` (int, one per ring, ``sectors[0] == 1``), ``centre`` (m): the
      layout;
    - ``normals`` (P, 3), ``offsets`` (P,) (m): the planes used;
    - ``fallback`` (P,) bool: the patch has no plane of its own (its fits failed or were rejected,
      see :class:`CloudConfig`) and borrowed its inner neighbour's;
    - ``hinged`` (P,) bool: the patch's plane is its own *hinged* fit (a plane through its inner
      neighbour's supported ground, see :func:`fit_ground`), not a free one;
    - ``source`` (P,) int: the patch whose fit the plane is (``p`` itself when fitted, free or
      hinged), or -1 for the level plane ``z = 0`` (``n = (0, 0, 1)``, ``d = 0``) when the disc was
      not fitted;
    - ``point_counts`` (P,): the finite points in each patch;
    - ``inlier_counts`` (P,): the final plane's inliers among the patch's fit points (the stride
      subsample of at most ``max_fit_points``), 0 for a fallback.
    """

    ring_edges: tuple[float, ...]
    sectors: tuple[int, ...]
    centre: tuple[float, float]
    normals: np.ndarray
    offsets: np.ndarray
    fallback: np.ndarray
    hinged: np.ndarray
    source: np.ndarray
    point_counts: np.ndarray
    inlier_counts: np.ndarray

    def __post_init__(self) -> None:
        edges = tuple(float(e) for e in self.ring_edges)
        sectors = tuple(int(s) for s in self.sectors)
        if len(sectors) != len(edges) + 1 or sectors[0] != 1 or min(sectors) < 1:
            raise ValueError(f"GroundModel.sectors must hold one count >= 1 per ring, 1 for the disc; got {self.sectors!r}")
        if any(b <= a for a, b in zip(edges, edges[1:])) or not all(math.isfinite(e) for e in edges):
            raise ValueError(f"GroundModel.ring_edges must be finite and strictly increasing; got {self.ring_edges!r}")
        centre = tuple(float(c) for c in self.centre)
        if len(centre) != 2 or not all(math.isfinite(c) for c in centre):
            raise ValueError(f"GroundModel.centre must be 2 finite numbers (m); got {self.centre!r}")
        k = sum(sectors)
        normals = np.array(self.normals, dtype=float).reshape(k, 3)
        offsets = np.array(self.offsets, dtype=float).reshape(k)
        norm = np.linalg.norm(normals, axis=1)
        if not np.all(np.isfinite(normals)) or not np.all(np.isfinite(offsets)) or np.any(norm == 0.0):
            raise ValueError("GroundModel planes must have finite, non-zero normals and finite offsets")
        sign = np.where(normals[:, 2] < 0.0, -1.0, 1.0)  # normals point up
        normals = normals * (sign / norm)[:, None]
        offsets = offsets * sign / norm
        arrays = {
            "normals": normals,
            "offsets": offsets,
            "fallback": np.array(self.fallback, dtype=bool).reshape(k),
            "hinged": np.array(self.hinged, dtype=bool).reshape(k),
            "source": np.array(self.source, dtype=int).reshape(k),
            "point_counts": np.array(self.point_counts, dtype=int).reshape(k),
            "inlier_counts": np.array(self.inlier_counts, dtype=int).reshape(k),
        }
        object.__setattr__(self, "ring_edges", edges)
        object.__setattr__(self, "sectors", sectors)
        object.__setattr__(self, "centre", centre)
        for name, arr in arrays.items():
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "_edges", np.asarray(edges, dtype=float))
        object.__setattr__(self, "_sectors", np.asarray(sectors, dtype=np.intp))
        object.__setattr__(self, "_first", _ring_starts(np.asarray(sectors, dtype=np.intp)))

    @classmethod
    def level(cls, ring_edges: tuple[float, ...] = (), sectors: tuple[int, ...] | None = None,
              centre: tuple[float, float] = (0.0, 0.0)) -> "GroundModel":
        """The level plane ``z = 0`` in every patch (all fallbacks, source -1); ``sectors`` defaults
        to one per ring."""
        sectors = (1,) * (len(ring_edges) + 1) if sectors is None else tuple(sectors)
        k = sum(sectors)
        return cls(ring_edges=tuple(ring_edges), sectors=sectors, centre=centre,
                   normals=np.tile([0.0, 0.0, 1.0], (k, 1)), offsets=np.zeros(k), fallback=np.ones(k, bool),
                   hinged=np.zeros(k, bool), source=np.full(k, -1), point_counts=np.zeros(k, int),
                   inlier_counts=np.zeros(k, int))

    @property
    def n_patches(self) -> int:
        return len(self.normals)

    @property
    def ring_starts(self) -> np.ndarray:
        """The index of each ring's first patch (R + 1,)."""
        return self._first.copy()

    @property
    def slopes_deg(self) -> np.ndarray:
        """Each plane's inclination from level, ``arccos(n_z)`` (deg)."""
        return np.degrees(np.arccos(np.clip(self.normals[:, 2], -1.0, 1.0)))

    def patch_of(self, points: Any) -> np.ndarray:
        """The patch index (N,) of each point (N, 3), from its ``(x, y)``."""
        pts = _as_points(points, "points")
        return _patch_index(pts[:, 0], pts[:, 1], self.centre, self._edges, self._sectors, self._first)

    def _height(self, pts: np.ndarray, patch: np.ndarray) -> np.ndarray:
        n = self.normals[patch]
        h = pts[:, 0] * n[:, 0]
        h += pts[:, 1] * n[:, 1]
        h += pts[:, 2] * n[:, 2]
        h += self.offsets[patch]
        return h

    def height(self, points: Any) -> np.ndarray:
        """Signed distance (N,) (m) of each point above its patch's plane, ``h = n_p . q + d_p``
        (negative below)."""
        pts = _as_points(points, "points")
        return self._height(pts, self.patch_of(pts))

    def project(self, points: Any) -> np.ndarray:
        """Each point (N, 3) projected onto its patch's plane along the normal, ``q - h(q) n_p``."""
        pts = _as_points(points, "points")
        patch = self.patch_of(pts)
        return pts - self._height(pts, patch)[:, None] * self.normals[patch]

    def ground_z(self, x: Any, y: Any) -> np.ndarray:
        """Height ``z`` (m) of the ground at ``(x, y)`` in E (arrays broadcast), on the plane of the
        patch holding ``(x, y)``: ``z = -(n_x x + n_y y + d) / n_z``. For drawing the fitted ground."""
        x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
        patch = _patch_index(x, y, self.centre, self._edges, self._sectors, self._first)
        n = self.normals[patch]
        return -(n[..., 0] * x + n[..., 1] * y + self.offsets[patch]) / n[..., 2]


def _fit_slots(patch: np.ndarray, counts: np.ndarray, rows: np.ndarray, cap: int, rng: np.random.Generator
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """The fit points of the patches with a row (``rows[p] >= 0``): all of a patch's ``m_p`` points
    when ``m_p <= cap``, else a random subsample (each point drawn with probability ``cap / m_p``, at
    most ``cap`` kept; not an even stride, which aliases with the scan order: a VLP-16 interleaves its
    beams, so every other point of a patch may lie on the same ring). Returns the point indices
    (by patch, in input order within one), their rows and slots (columns of the padded
    ``(rows, C, .)`` arrays, each row's points first) and ``C``."""
    order = np.argsort(patch, kind="stable")
    p_sorted = patch[order]
    keep = rows[p_sorted] >= 0
    big = counts[p_sorted] > cap
    if big.any():
        keep &= ~big | (rng.random(len(order)) * counts[p_sorted] < cap)
    order, p_sorted = order[keep], p_sorted[keep]
    starts = np.concatenate(([0], np.cumsum(np.bincount(p_sorted, minlength=len(counts)))[:-1]))
    slot = np.arange(len(order)) - starts[p_sorted]
    keep = slot < cap
    order, p_sorted, slot = order[keep], p_sorted[keep], slot[keep]
    return order, rows[p_sorted], slot, int(slot.max()) + 1 if len(slot) else 0


def _seed_mask(z: np.ndarray, valid: np.ndarray, cfg: CloudConfig) -> np.ndarray:
    """The seeds (m, C) of padded patches (Zermas's lowest point representative, per patch).

    In a patch of ``m_p`` fit points with heights sorted ``z_(1) <= z_(2) <= ...``, the lowest point
    representative is the mean of the lowest ``n_p = max(1, round(f m_p))`` (``f = seed_fraction``),

    .. math::  LPR_p = \\frac{1}{n_p} \\sum_{i \\le n_p} z_{(i)},

    and the seeds are the points with ``z < LPR_p + seed_height``.
    """
    zs = np.sort(np.where(valid, z, np.inf), axis=1)
    count = valid.sum(axis=1)
    n_low = np.maximum(1, np.rint(cfg.seed_fraction * count)).astype(np.intp)
    csum = np.cumsum(np.where(np.isfinite(zs), zs, 0.0), axis=1)
    lpr = csum[np.arange(len(z)), np.minimum(n_low, z.shape[1]) - 1] / n_low
    return valid & (z < (lpr + cfg.seed_height)[:, None])


def _sample_seeds(seeds: np.ndarray, k: int, rng: np.random.Generator) -> np.ndarray:
    """``k`` random seed slots per row (m, k) (uniform, with repetition; 0 for a row without seeds)."""
    count = seeds.sum(axis=1)
    seed_slots = np.argsort(~seeds, axis=1, kind="stable")  # the seeds first, in slot order
    idx = (rng.random((len(seeds), k)) * count[:, None]).astype(np.intp)
    np.minimum(idx, np.maximum(count - 1, 0)[:, None], out=idx)
    return np.take_along_axis(seed_slots, idx, axis=1)


def _spreads(xy: np.ndarray, inl: np.ndarray) -> np.ndarray:
    """The spread (m,) (m) of each row's inliers ``inl`` (m, C) in x-y ``xy`` (m, C, 2): half the
    interdecile range of their offsets ``o_i = (p_i - c) . v`` along their minor axis ``v`` (the
    eigenvector of the smaller eigenvalue of their x-y scatter about their centroid ``c``),
    ``(o_(90 %) - o_(10 %)) / 2``; 0 without inliers.

    One scan-ring arc gives about its sagitta's 0.4 (a few stray inliers, under 10 %, do not count);
    two rings ``D`` apart (each with over 10 % of the inliers) about ``D / 2``; a patch covered evenly
    ``W`` wide across its minor axis ``0.4 W``."""
    m, c, _ = xy.shape
    rows = np.arange(m)
    count = inl.sum(axis=1)
    k = np.maximum(count, 1)
    q = np.where(inl[..., None], xy - (np.where(inl[..., None], xy, 0.0).sum(axis=1) / k[:, None])[:, None, :], 0.0)
    s = q.transpose(0, 2, 1) @ q  # (m, 2, 2) scatter
    a, b, e = s[:, 0, 0], s[:, 0, 1], s[:, 1, 1]
    lam = 0.5 * (a + e) - np.sqrt(0.25 * (a - e) ** 2 + b * b)  # its smaller eigenvalue
    v = np.stack([b, lam - a], axis=1)  # its eigenvector ...
    v = np.where((np.abs(b) > 1e-12 * (a + e + 1e-300))[:, None], v, np.where((a <= e)[:, None], [1.0, 0.0], [0.0, 1.0]))
    v /= np.linalg.norm(v, axis=1)[:, None]  # ... (axis-aligned when the scatter is diagonal)
    off = np.sort(np.where(inl, (q @ v[:, :, None])[..., 0], np.inf), axis=1)
    lo = off[rows, np.floor(0.1 * (k - 1)).astype(np.intp)]
    hi = off[rows, np.ceil(0.9 * (k - 1)).astype(np.intp)]
    return np.where(count > 0, 0.5 * (hi - lo), 0.0)


def _free_fits(ph: np.ndarray, valid: np.ndarray, seeds: np.ndarray, scale: np.ndarray, cfg: CloudConfig,
               rng: np.random.Generator, cos_max: float
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Free RANSAC planes of padded patches, all at once: ``ph`` (m, C, 4) the fit points ``[q 1]``
    (``valid`` (m, C); padding rows 0), ``seeds`` (m, C).

    Per patch, ``H`` hypotheses through 3 random seeds ``(a, b, c)``:
    ``n = (b - a) x (c - a) / |(b - a) x (c - a)|`` (pointing up), ``d = -n . a``; a hypothesis is
    invalid when degenerate or steeper than ``max_slope_deg`` (``n_z < cos(max_slope)``). Each is
    scored on an even subsample of at most ``_SCORE_POINTS`` fit points, by its inliers less the
    points below it,

    .. math::  \\text{score}_h = \\#\\{i : |n_h \\cdot q_i + d_h| \\le \\tau\\}
                               - \\#\\{i : n_h \\cdot q_i + d_h < -\\tau\\}

    (the ground is the lowest surface: a plane tilted up into a vehicle's lowest scan line leaves
    ground returns under it). The best hypothesis's inliers among all fit points are refitted by
    total least squares ``refine_iterations`` times (through their centroid ``c``, normal the
    eigenvector of the smallest eigenvalue of their scatter ``sum (q - c)(q - c)^T``, pointing up),
    the inliers recomputed after each refit. Returns ``(n, d, inliers, ok, c)``: ``ok`` when the
    plane has ``n_z >= cos(max_slope)``, at least ``min_points`` inliers and a spread
    (:func:`_spreads`) of at least ``min_spread``; ``c`` the inliers' centroid.
    """
    m, c, _ = ph.shape
    rows = np.arange(m)
    tau = cfg.distance_threshold
    h = cfg.ransac_iterations
    sample = ph[rows[:, None], _sample_seeds(seeds, 3 * h, rng), :3].reshape(m, h, 3, 3)
    a = sample[:, :, 0]
    e1 = sample[:, :, 1] - a
    e2 = sample[:, :, 2] - a
    normals = np.empty_like(a)  # e1 x e2
    normals[..., 0] = e1[..., 1] * e2[..., 2] - e1[..., 2] * e2[..., 1]
    normals[..., 1] = e1[..., 2] * e2[..., 0] - e1[..., 0] * e2[..., 2]
    normals[..., 2] = e1[..., 0] * e2[..., 1] - e1[..., 1] * e2[..., 0]
    norm = np.sqrt(np.einsum("phi,phi->ph", normals, normals))
    good = (norm > _DEGENERATE_AREA) & (seeds.sum(axis=1) >= 3)[:, None]
    normals /= np.where(good, norm, 1.0)[..., None]
    normals *= np.where(normals[..., 2] < 0.0, -1.0, 1.0)[..., None]
    good &= normals[..., 2] >= cos_max
    offsets = -np.einsum("phi,phi->ph", normals, a)
    # scores of all hypotheses at once: [q 1] [n; d], (m, C', H) in float32 (mm accuracy at 100 m)
    hyp = np.empty((m, 4, h), dtype=np.float32)
    hyp[:, :3, :] = normals.transpose(0, 2, 1)
    hyp[:, 3, :] = offsets
    sub = slice(None, None, -(-c // _SCORE_POINTS))
    ps = ph[:, sub].astype(np.float32)
    ps[..., 2][~valid[:, sub]] = 1e6  # padding: far above any plane
    dist = ps @ hyp
    score = np.add.reduce((dist < -tau).view(np.uint8), axis=1, dtype=np.int32)
    np.abs(dist, out=dist)
    score = np.add.reduce((dist <= tau).view(np.uint8), axis=1, dtype=np.int32) - score
    score[~good] = -1 - c
    best = np.argmax(score, axis=1)
    found = good[rows, best]
    plane = np.concatenate([normals[rows, best], offsets[rows, best][:, None]], axis=1)  # (m, 4)
    inl = valid & (np.abs((ph @ plane[:, :, None])[..., 0]) <= tau)
    centroid = np.zeros((m, 3))
    for it in range(cfg.refine_iterations + 1):
        mom = (ph * inl[..., None]).transpose(0, 2, 1) @ ph  # sum [q 1][q 1]^T over the inliers
        count = mom[:, 3, 3]
        centroid = mom[:, :3, 3] / np.maximum(count, 1.0)[:, None]
        if it == cfg.refine_iterations:
            break
        refit = found & (count >= 3)
        if not refit.any():
            break
        scatter = mom[:, :3, :3] - count[:, None, None] * centroid[:, :, None] * centroid[:, None, :]
        n = np.linalg.eigh(scatter[refit])[1][:, :, 0]
        n *= np.where(n[:, 2] < 0.0, -1.0, 1.0)[:, None]
        plane[refit, :3] = n
        plane[refit, 3] = -np.einsum("pi,pi->p", n, centroid[refit])
        inl = valid & (np.abs((ph @ plane[:, :, None])[..., 0]) <= tau)
    ok = found & (plane[:, 2] >= cos_max) & (inl.sum(axis=1) * scale >= cfg.min_points) & (inl.sum(axis=1) >= 3)
    if ok.any():
        ok[ok] = _spreads(ph[ok][..., :2], inl[ok]) >= cfg.min_spread
    return plane[:, :3], plane[:, 3], inl, ok, centroid


def _hinged_fits(ph: np.ndarray, valid: np.ndarray, seeds: np.ndarray, scale: np.ndarray, hinge: np.ndarray,
                 prior: np.ndarray, cfg: CloudConfig, rng: np.random.Generator,
                 tan_max: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Hinged planes of padded patches (``ph``, ``valid``, ``seeds`` as :func:`_free_fits`): each
    through its hinge point ``hinge`` (m, 3), its gradient ``g = (dz/dx, dz/dy)`` free, pulled
    towards ``prior`` (m, 2).

    With ``d_i = (x_i - x_h, y_i - y_h)`` and ``v_i = z_i - z_h`` relative to the hinge point, the plane
    is ``v = g . d``. RANSAC: hypothesis 0 is ``g = prior``, the others the planes through the hinge
    point and 2 random seeds (a 2 x 2 solve; invalid when the three are nearly in a line in x-y or the
    plane is steeper than ``max_slope_deg``), scored as in :func:`_free_fits` with the point-to-plane
    distance ``(v_i - g . d_i) / sqrt(1 + |g|^2)``. The best is refined ``max(1, refine_iterations)``
    times by ridge regression on its inliers,

    .. math::  g = \\Big(\\sum_i d_i d_i^T + \\lambda I\\Big)^{-1}
                   \\Big(\\sum_i v_i d_i + \\lambda g_0\\Big),

    ``lambda = hinge_prior`` (m^2), ``g_0 = prior``: a direction in which the inliers do not reach
    out from the hinge point (along a ring arc seen end-on, or all of them for a short arc) keeps the
    prior's slope. Returns ``(g, inliers, ok)``, ``ok`` when the plane has at least ``min_points``
    inliers and ``|g| <= tan(max_slope)``.
    """
    c = int(valid.sum(axis=1).max()) if valid.size else 0  # the slots in use (each row's points come first)
    ph, valid, seeds = ph[:, :c], valid[:, :c], seeds[:, :c]
    m = len(ph)
    rows = np.arange(m)
    tau = cfg.distance_threshold
    h = cfg.ransac_iterations
    rel = np.where(valid[..., None], ph[..., :3] - hinge[:, None, :], 0.0)  # (m, C, 3): d_i and v_i
    pair = _sample_seeds(seeds, 2 * h, rng)
    s = rel[rows[:, None], pair].reshape(m, h, 2, 3)
    ui, wi, vi = s[:, :, 0, 0], s[:, :, 0, 1], s[:, :, 0, 2]
    uj, wj, vj = s[:, :, 1, 0], s[:, :, 1, 1], s[:, :, 1, 2]
    det = ui * wj - wi * uj
    good = np.abs(det) > _HINGE_MIN_SINE * np.hypot(ui, wi) * np.hypot(uj, wj)
    det = np.where(good, det, 1.0)
    grad = np.empty((m, h, 2))
    grad[..., 0] = np.where(good, (vi * wj - vj * wi) / det, 0.0)
    grad[..., 1] = np.where(good, (ui * vj - uj * vi) / det, 0.0)
    grad[:, 0] = prior
    good[:, 0] = True
    slope2 = np.einsum("phi,phi->ph", grad, grad)
    good &= slope2 <= tan_max * tan_max
    lim = (tau * np.sqrt(1.0 + slope2)).astype(np.float32)
    sub = slice(None, None, -(-c // _SCORE_POINTS))
    rs = rel[:, sub].astype(np.float32)
    rs[..., 2][~valid[:, sub]] = 1e6  # padding: far above any plane
    hyp = np.empty((m, 3, h), dtype=np.float32)
    hyp[:, :2, :] = -grad.transpose(0, 2, 1)
    hyp[:, 2, :] = 1.0
    res = rs @ hyp  # v_i - g . d_i, (m, C', H)
    score = np.add.reduce((res < -lim[:, None, :]).view(np.uint8), axis=1, dtype=np.int32)
    np.abs(res, out=res)
    score = np.add.reduce((res <= lim[:, None, :]).view(np.uint8), axis=1, dtype=np.int32) - score
    score[~good] = -1 - c
    best = np.argmax(score, axis=1)
    g = grad[rows, best]
    lever2 = cfg.hinge_prior_length ** 2
    for it in range(max(1, cfg.refine_iterations) + 1):
        vec = np.concatenate([-g, np.ones((m, 1))], axis=1)
        inl = valid & (np.abs((rel @ vec[:, :, None])[..., 0]) <= (tau * np.sqrt(1.0 + (g * g).sum(axis=1)))[:, None])
        if it == max(1, cfg.refine_iterations):
            break
        mom = (rel * inl[..., None]).transpose(0, 2, 1) @ rel  # sum [d v][d v]^T over the inliers
        lam = np.maximum(inl.sum(axis=1), 1) * lever2
        a, b, e = mom[:, 0, 0] + lam, mom[:, 0, 1], mom[:, 1, 1] + lam
        ru, rw = mom[:, 0, 2] + lam * prior[:, 0], mom[:, 1, 2] + lam * prior[:, 1]
        det2 = a * e - b * b
        g = np.column_stack([(e * ru - b * rw) / det2, (a * rw - b * ru) / det2])
    ok = (inl.sum(axis=1) * scale >= cfg.min_points) & (inl.sum(axis=1) >= 3) & ((g * g).sum(axis=1) <= tan_max * tan_max)
    return g, inl, ok


def _plane_z(n: np.ndarray, d: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Heights ``z = -(n_x x + n_y y + d) / n_z`` of planes (rows of ``n``, ``d``) at ``(x, y)``."""
    return -(n[:, 0] * x + n[:, 1] * y + d) / n[:, 2]


def _fit_ground(pts: np.ndarray, cfg: CloudConfig) -> tuple[GroundModel, np.ndarray]:
    """The ground model of finite points ``pts`` (N, 3) in E, and each point's patch (N,)
    (see :func:`fit_ground` for the method)."""
    edges = np.asarray(cfg.ring_edges, dtype=float)
    sectors = np.asarray((1,) + tuple(cfg.ring_sectors), dtype=np.intp)
    first = _ring_starts(sectors)
    centre = (cfg.mount_x, cfg.mount_y)
    n_patch = int(sectors.sum())
    patch = _patch_index(pts[:, 0], pts[:, 1], centre, edges, sectors, first)
    counts = np.bincount(patch, minlength=n_patch)
    cos_max = math.cos(math.radians(cfg.max_slope_deg))
    tan_max = math.tan(math.radians(cfg.max_slope_deg))
    cos_change = math.cos(math.radians(cfg.max_slope_change_deg))

    # the fit points of every patch with enough of them, padded to (rows, C, .), relative to an
    # origin per row (their mean: keeps the moments' cancellation small)
    cand = np.flatnonzero(counts >= max(cfg.min_points, 3))
    row = np.full(n_patch, -1, dtype=np.intp)
    row[cand] = np.arange(len(cand))
    idx, r_of, slot, c = _fit_slots(patch, counts, row, cfg.max_fit_points, np.random.default_rng((cfg.seed, 0)))
    valid = np.zeros((len(cand), c), dtype=bool)
    valid[r_of, slot] = True
    origin = np.zeros((len(cand), 3))
    np.add.at(origin, r_of, pts[idx])  # few rows: cheap
    origin /= np.maximum(valid.sum(axis=1), 1)[:, None]
    ph = np.zeros((len(cand), c, 4))
    ph[r_of, slot, :3] = pts[idx] - origin[r_of]
    ph[r_of, slot, 3] = 1.0
    seeds = _seed_mask(ph[..., 2], valid, cfg)
    scale = counts[cand] / np.maximum(valid.sum(axis=1), 1)  # points per fit point
    radius = np.where(valid, np.hypot(ph[..., 0] + (origin[:, 0] - centre[0])[:, None],
                                      ph[..., 1] + (origin[:, 1] - centre[1])[:, None]), np.nan)
    if len(cand):
        free_n, free_d, free_inl, free_ok, free_c = _free_fits(ph, valid, seeds, scale, cfg, np.random.default_rng((cfg.seed, 1)), cos_max)
        free_d = free_d - np.einsum("pi,pi->p", free_n, origin)  # back to E
        free_c = free_c + origin
    else:
        free_n, free_d, free_c = np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3))
        free_inl, free_ok = np.zeros((0, c), dtype=bool), np.zeros(0, dtype=bool)

    normals = np.tile([0.0, 0.0, 1.0], (n_patch, 1))
    offsets = np.zeros(n_patch)
    source = np.full(n_patch, -1)
    fitted = np.zeros(n_patch, dtype=bool)
    hinged = np.zeros(n_patch, dtype=bool)
    inlier_counts = np.zeros(n_patch, dtype=int)
    reach = np.zeros(n_patch)  # how far out from the centre a patch's plane is supported by inliers

    def own(p: np.ndarray, rp: np.ndarray, n: np.ndarray, d: np.ndarray, inl: np.ndarray) -> None:
        normals[p], offsets[p], source[p], fitted[p] = n, d, p, True
        inlier_counts[p] = inl.sum(axis=1)
        reach[p] = np.where(inl, radius[rp, :inl.shape[1]], -np.inf).max(axis=1)

    if row[0] >= 0 and free_ok[row[0]]:
        r0 = row[[0]]
        own(np.array([0]), r0, free_n[r0], free_d[r0], free_inl[r0])
    for j in range(1, len(sectors)):
        s_j, s_in = int(sectors[j]), int(sectors[j - 1])
        ps = first[j] + np.arange(s_j)
        phi = 2.0 * math.pi * np.arange(s_j) / s_j
        qs = first[j - 1] + np.mod(np.floor(phi * (s_in / (2.0 * math.pi)) + 0.5).astype(np.intp), s_in)
        nq, dq = normals[qs], offsets[qs]
        rp = row[ps]
        todo = rp >= 0
        # free fits: no kink to the inner neighbour's plane, and the two meet (within max_step)
        # between where the neighbour's support ends and where this patch's begins
        free = todo & free_ok[np.maximum(rp, 0)] if len(cand) else todo
        if free.any():
            f = np.flatnonzero(free)
            rf = rp[f]
            n, d, inl = free_n[rf], free_d[rf], free_inl[rf]
            az = np.arctan2(free_c[rf, 1] - centre[1], free_c[rf, 0] - centre[0])
            ends = [reach[qs[f]], np.where(inl, radius[rf], np.inf).min(axis=1)]
            gap = [_plane_z(n, d, centre[0] + e * np.cos(az), centre[1] + e * np.sin(az))
                   - _plane_z(nq[f], dq[f], centre[0] + e * np.cos(az), centre[1] + e * np.sin(az)) for e in ends]
            step = np.where(gap[0] * gap[1] <= 0.0, 0.0, np.minimum(np.abs(gap[0]), np.abs(gap[1])))
            accept = (np.einsum("pi,pi->p", n, nq[f]) >= cos_change) & (step <= cfg.max_step)
            if accept.any():
                a = f[accept]
                own(ps[a], rp[a], n[accept], d[accept], inl[accept])
                todo[a] = False
        # hinged fits where there is none: through the inner neighbour's plane where its support
        # ends, on the sector's axis
        if todo.any():
            f = np.flatnonzero(todo)
            rf = rp[f]
            hx = centre[0] + reach[qs[f]] * np.cos(phi[f])
            hy = centre[1] + reach[qs[f]] * np.sin(phi[f])
            hinge = np.column_stack([hx, hy, _plane_z(nq[f], dq[f], hx, hy)])
            prior = -nq[f, :2] / nq[f, 2:]
            g, inl, ok = _hinged_fits(ph[rf], valid[rf], seeds[rf], scale[rf], hinge - origin[rf], prior, cfg,
                                      np.random.default_rng((cfg.seed, j + 1)), tan_max)
            n = np.column_stack([-g, np.ones(len(f))]) / np.sqrt(1.0 + (g * g).sum(axis=1))[:, None]
            ok &= np.einsum("pi,pi->p", n, nq[f]) >= cos_change
            if ok.any():
                a = f[ok]
                own(ps[a], rp[a], n[ok], -np.einsum("pi,pi->p", n[ok], hinge[ok]), inl[ok])
                hinged[ps[a]] = True
        # the rest borrow the inner neighbour's plane (and where it is supported)
        b = ~fitted[ps]
        normals[ps[b]], offsets[ps[b]], source[ps[b]], reach[ps[b]] = nq[b], dq[b], source[qs[b]], reach[qs[b]]
    model = GroundModel(ring_edges=tuple(edges.tolist()), sectors=tuple(sectors.tolist()), centre=centre,
                        normals=normals, offsets=offsets, fallback=~fitted, hinged=hinged, source=source,
                        point_counts=counts, inlier_counts=inlier_counts)
    return model, patch


def fit_ground(points_e: Any, config: CloudConfig | None = None) -> GroundModel:
    """FIT_GROUND_DOC"""
    cfg = CloudConfig() if config is None else config
    pts = _as_points(points_e, "points_e")
    pts = pts[np.isfinite(pts).all(axis=1)]
    return _fit_ground(pts, cfg)[0]


# --------------------------------------------------------------------------------------------------
# the pipeline


@dataclass(frozen=True)
class CloudStats:
    """What each stage of :func:`process_cloud` did to one cloud (counts of points).

    ``kept + ground + below_ground + above_ceiling + non_finite == points_in``.
    ``segments_fallback`` counts the segments holding finite points whose plane was borrowed (their
    own fit failed or was rejected); empty segments are not counted (``GroundModel.fallback`` has
    them all).
    """

    points_in: int = 0
    non_finite: int = 0
    ground: int = 0
    below_ground: int = 0
    above_ceiling: int = 0
    kept: int = 0
    segments_fallback: int = 0
    segments_hinged: int = 0

    def as_dict(self) -> dict[str, int]:
        return {f.name: int(getattr(self, f.name)) for f in fields(self)}


@dataclass(frozen=True, eq=False)
class CloudResult:
    """Everything :func:`process_cloud` computed for one cloud of ``N`` points.

    Per input row (length ``N``, input order): ``points_e`` (N, 3) the points in E (non-finite rows
    as given, transformed); ``finite`` (N,); ``heights`` (N,) the signed height above the segment's
    plane (m, NaN where not finite); the disjoint masks ``ground``, ``below_ground``,
    ``above_ceiling``, ``kept`` (all False on non-finite rows). ``points_2d`` (M, 2) are the kept
    points projected onto their plane along its normal, ``(x, y)`` in E, in input order
    (``M = kept.sum()``). ``model`` is the fitted :class:`GroundModel`, ``stats`` the counts.

    A figure of the pipeline: ``points_e[finite]`` (raw cloud), ``points_e[kept]`` (without ground and
    above-ceiling points), ``points_2d`` (projected), ``model.ground_z`` (the fitted ground).
    """

    points_e: np.ndarray
    finite: np.ndarray
    heights: np.ndarray
    ground: np.ndarray
    below_ground: np.ndarray
    above_ceiling: np.ndarray
    kept: np.ndarray
    points_2d: np.ndarray
    model: GroundModel
    stats: CloudStats


def process_cloud(points_sensor: Any, config: CloudConfig | None = None) -> CloudResult:
    """One lidar cloud ``(N, 3)`` in the sensor frame through the whole pipeline.

    1. ``p_E = R p_S + t`` (:func:`mount_transform`);
    2. rows with a non-finite coordinate are dropped (``non_finite``);
    3. the ground model is fitted (:func:`fit_ground`) and each point's height above its segment's
       plane computed, ``h = n_k . p + d_k``;
    4. with ``tau = distance_threshold`` and ``c = height_ceiling``: ``|h| <= tau`` is ground,
       ``h < -tau`` below ground, ``h > c`` above the ceiling, ``tau < h <= c`` kept;
    5. the kept points are projected along their plane's normal, ``q = p - h n_k``, and ``(q_x, q_y)``
       returned.

    ``ValueError`` when ``points_sensor`` is not an ``(N, 3)`` array of real numbers; ``(0, 3)``
    gives ``(0, 2)`` points and a level ground model.
    """
    cfg = CloudConfig() if config is None else config
    if not isinstance(cfg, CloudConfig):
        raise TypeError(f"config must be a CloudConfig or None; got {type(cfg).__name__}")
    pts_s = _as_points(points_sensor, "points_sensor")
    n = len(pts_s)
    pe = _transform(pts_s, cfg)
    # a row with a NaN or inf has a non-finite sum (the exact test only runs when one is found)
    all_finite = bool(np.isfinite(pe @ np.ones(3)).all())
    finite = np.ones(n, dtype=bool) if all_finite else np.isfinite(pe).all(axis=1)
    pts = pe if all_finite else pe[finite]
    model, patch = _fit_ground(pts, cfg)
    h = model._height(pts, patch)
    tau = cfg.distance_threshold
    ground_f = np.abs(h) <= tau
    below_f = h < -tau
    above_f = h > cfg.height_ceiling
    kept_f = ~(ground_f | below_f | above_f)
    projected = pts[kept_f] - h[kept_f, None] * model.normals[patch[kept_f]]
    points_2d = np.ascontiguousarray(projected[:, :2])

    def full(mask: np.ndarray) -> np.ndarray:
        if all_finite:
            return mask
        out = np.zeros(n, dtype=bool)
        out[finite] = mask
        return out

    if all_finite:
        heights = h
    else:
        heights = np.full(n, np.nan)
        heights[finite] = h
    occupied = np.zeros(model.n_patches, dtype=bool)
    occupied[patch] = True
    stats = CloudStats(
        points_in=n,
        non_finite=int(n - np.count_nonzero(finite)),
        ground=int(np.count_nonzero(ground_f)),
        below_ground=int(np.count_nonzero(below_f)),
        above_ceiling=int(np.count_nonzero(above_f)),
        kept=int(np.count_nonzero(kept_f)),
        segments_fallback=int(np.count_nonzero(model.fallback & occupied)),
        segments_hinged=int(np.count_nonzero(model.hinged & occupied)),
    )
    return CloudResult(points_e=pe, finite=finite, heights=heights, ground=full(ground_f),
                       below_ground=full(below_f), above_ceiling=full(above_f), kept=full(kept_f),
                       points_2d=points_2d, model=model, stats=stats)


def to_ground_plane(points_sensor: Any, config: CloudConfig | None = None) -> tuple[np.ndarray, CloudStats]:
    """The 2-D points ``(M, 2)`` (``x, y`` in E, m) of a lidar cloud ``(N, 3)`` in the sensor frame,
    with ground, below-ground, above-ceiling and non-finite points removed, and the counts.

    The kept points are projected onto the fitted road plane along its normal (see
    :func:`process_cloud`, which also returns the masks and the ground model).
    """
    result = process_cloud(points_sensor, config)
    return result.points_2d, result.stats

