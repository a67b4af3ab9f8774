"""3-D lidar preprocessing: a roof lidar's point cloud to 2-D points on the road plane.

The paper's car carries a Velodyne VLP-16 on its roof; the tracker's 2-D code (clustering, the
rectangle measurement model) takes points ``(x, y)`` in the vehicle frame E. This module turns one
3-D scan into those points:

1. **Mount transform** (:func:`mount_transform`): sensor frame S -> vehicle frame E,
   ``p_E = R(roll, pitch, yaw) p_S + t``.
2. **Non-finite points** dropped (counted); **the ego's own body** (points inside its box, grown by a
   margin: a roof lidar's lowest beams land on the roof and bonnet) dropped (counted).
3. **Ground fit** (:func:`fit_ground`): a piecewise-planar ground, one plane per *patch* of a polar
   grid around the sensor (a disc under the ego, then concentric rings cut into sectors, after the
   concentric zones of Patchwork, Lim et al. 2021, "Patchwork: concentric zone-based region-wise
   ground segmentation", RA-L), fitted from the inside out. A patch's plane is, in this order:

   - its **free** fit, after Zermas et al. 2017 ("Fast segmentation of 3D point clouds: a paradigm
     on LiDAR data for autonomous vehicle applications", ICRA): seeds near the lowest point
     representative, RANSAC planes through 3 seeds scored by their inliers less the points under
     them, the best refined by PCA fits on its inliers; taken when its inliers cover an area (not
     one scan ring), it continues the inner neighbour's plane (no step, no kink) and it explains
     clearly more points than the hinged fit below (``CloudConfig.hinged_share``);
   - else its **hinged** fit: a plane through the inner neighbour's ground where that one's
     support ends, its gradient fitted to the patch (RANSAC, then ridge regression pulled towards
     the neighbour's gradient). This is what a patch that sees the ground along one scan ring gets,
     the common case: beyond ~10 m a VLP-16 leaves one ring per patch, and beyond ~36 m on level
     ground none, but a climbing road meets its upper beams again far away (on a 4 % grade the
     +1 deg beam at ~84 m). Anchored on the last supported ground and with its slope measured
     from there, such a ring gets its own plane instead of a neighbour's extrapolated tens of metres;
   - else the inner neighbour's plane, borrowed.

   Sectors follow lateral changes of the ground (a banked road and the level terrain beside it, a
   grade turning with a curving road) that one plane per distance cannot. Points at the foot of
   something steep (a vehicle's side, a wall: another return right above them in their azimuth
   column) take no part in the fits.
4. **Classification** against each point's patch plane, by the signed height ``h`` above it:
   ground ``|h| <= distance_threshold``; below ground ``h < -distance_threshold`` (multipath
   reflections, puddles, noise); above the ceiling ``h > height_ceiling`` (bridges, signs, canopies);
   low objects, the points of ``low_object_cell`` square cells of E that hold no point (of those
   left) higher than ``low_object_height`` (kerbs, debris: no vehicle is so low, and a vehicle's
   lowest returns share their cells with the returns of its side above them); the rest is kept.
5. **Projection** of the kept points onto their patch's plane along its normal; their ``(x, y)``
   in E are the 2-D points, less the returns **seen over a nearer object** (``CloudConfig.seen_over_gap``:
   a lone return in its azimuth column behind a nearer return beneath its ray, mostly a roof's far
   end seen over a roadside hedge, which a 2-D scan cannot see and the rectangle model would read as
   an outline).

Frames and units: E has its origin at the ego's geometric centre on the ground (z = 0 on the ground
under the ego centre when the ground is level), x forward, y left, z up. The sensor frame S is the
lidar's own (x forward, y left, z up). SI units throughout (m, rad); degrees only in names ending in
``_deg``.

Entry points: :func:`to_ground_plane` (2-D points and :class:`CloudStats`) and
:func:`process_cloud` (a :class:`CloudResult` with everything a figure of "raw cloud / without
ground / projected points" needs). Everything is vectorised with numpy: the fits of all patches run
at once as padded ``(patches, points)`` arrays; the only Python loops run over the rings (the hinged
fits of a ring need the planes of the ring inside) and the refinement iterations. Two steps are
compiled kernels, one pass each over a cloud's 10^4-10^5 points where numpy would take a dozen: the
wall-feet tests over the sorted columns (``wall_feet_kernel``) and the classification, low objects
and projection (``classify_kernel``). Deterministic:
every random draw comes from generators seeded with ``CloudConfig.seed``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from tracker.checks import check_real
from tracker.jit import njit

__all__ = [
    "CLOUD_FRAMES",
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

#: The frames a cloud may come in (``CloudConfig.frame``): one lidar's own, or the vehicle frame E.
CLOUD_FRAMES = ("sensor", "vehicle")
#: The frame check (``CloudConfig.frame``): the ground within this band of horizontal distances from
#: the lidar (m), its height the lower quartile (FRAME_CHECK_QUANTILE) over FRAME_CHECK_SECTORS equal
#: azimuth sectors around the lidar of each sector's lowest point (sectors of at least 3 points: the
#: ego's body hides the ground ahead and behind, and a truck alongside hides it on a whole side
#: behind a face whose lowest return, above its wheels, stands a metre up; a wall or hedge beside the
#: road stands on the ground, its lowest return near it; a stray return below the ground moves one
#: sector's, not the quartile), checked with at least FRAME_CHECK_POINTS of them and a lidar at least
#: FRAME_CHECK_MOUNT_Z high (m). A cloud in the other frame moves every sector's ground by the
#: lidar's height.
FRAME_CHECK_BAND = (3.0, 8.0)
FRAME_CHECK_POINTS = 30
FRAME_CHECK_MOUNT_Z = 1.0
FRAME_CHECK_SECTORS = 16
FRAME_CHECK_QUANTILE = 0.25
#: The frame check looks at about this many of a cloud's points (a stride through it).
FRAME_CHECK_SAMPLE = 8192

#: The spread check (``CloudConfig.min_spread``) takes half the distance between these quantiles of the
#: inliers' offsets across their main direction: stray inliers (under 10 % each side) do not make a line
#: a plane.
_SPREAD_QUANTILES = (0.1, 0.9)

#: A 3-point sample with ``|(p1 - p0) x (p2 - p0)|`` (twice its triangle's area, m^2) below this is
#: degenerate (repeated or collinear points).
_DEGENERATE_AREA = 1e-6

#: A hinged-fit sample (the hinge point and 2 seeds) whose two x-y offsets from the hinge point make an
#: angle with a sine below this is degenerate (the three nearly in a line).
_HINGE_MIN_SINE = 0.02

#: RANSAC hypotheses are scored on an even stride subsample of at most this many of a patch's fit points
#: (the best one's inliers are then refitted on all of them).
_SCORE_POINTS = 64

#: Limits of the 16-bit integer keys that numpy sorts stably in linear time (radix sort).
_INT16_MAX = 32767
_UINT16_MAX = 65535

#: The fewest RANSAC hypotheses of a hinged fit (it uses half of ``ransac_iterations``, 2 seeds each).
_MIN_HYPOTHESES = 8


# --------------------------------------------------------------------------------------------------
# configuration


def _real(name: str, value: Any, *, low: float | None = None, high: float | None = None,
          low_open: bool = False, high_open: bool = False, unit: str = "") -> float:
    """``value`` as a float, or ``ValueError`` naming ``CloudConfig.<name>`` and the allowed range
    (``tracker.checks.check_real``; numpy scalars are taken as Python numbers)."""
    if isinstance(value, (np.integer, np.floating)):
        value = value.item()
    check_real("CloudConfig", name, value, low=low, high=high, low_open=low_open, high_open=high_open, unit=unit)
    return float(value)


def _integer(name: str, value: Any, low: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise ValueError(f"CloudConfig.{name} must be an integer >= {low}; got {value!r}")
    return int(value)


@dataclass(frozen=True)
class CloudConfig:
    """Every number of the 3-D preprocessing, with its unit; validated on construction.

    The cloud's frame:

    - ``frame`` (``"sensor"`` or ``"vehicle"``): ``"sensor"``, one lidar's cloud in its own frame, moved
      into E by the mount pose below; ``"vehicle"``, a cloud already in E, e.g. the merged cloud of a
      rig of several lidars (stacked on the roof, on the bumpers) as real drivers deliver it; the mount
      pose is then the primary lidar's, whose position centres the patch layout. Default ``"sensor"``.
      A cloud whose ground near the lidar lies where the other frame would put it (within 3-8 m of
      ``(mount_x, mount_y)``, its height, the lower quartile over 16 azimuth sectors of each one's lowest
      point, more than ``mount_z / 2`` off 0 in E, among about 8,192 points strided
      through the cloud) is refused with a ``ValueError`` that says so (checked where ``mount_z >= 1``
      m and 30 such points exist).

    Mount pose of the lidar in E (the sensor frame's origin and orientation):

    - ``mount_x, mount_y, mount_z`` (m): the sensor origin in E. Default ``(0, 0, 1.9)``: on the roof,
      1.9 m above the ground, above the ego centre.
    - ``mount_roll_deg, mount_pitch_deg, mount_yaw_deg`` (deg, within +-360): intrinsic z-y'-x''
      (aerospace) Euler angles, ``R = Rz(yaw) Ry(pitch) Rx(roll)``; see :func:`mount_rotation` for
      the signs. Default 0.

    The patch layout (see :class:`GroundModel`), centred on the sensor's position ``(mount_x,
    mount_y)`` in E, around which its scan rings lie:

    - ``ring_edges`` (m, > 0, strictly increasing): the radii of the ring boundaries: ring 0 is the
      disc ``rho <= e_0`` (one patch), ring ``j`` the annulus ``e_{j-1} < rho <= e_j``, the last one
      unbounded; ``()`` is one plane for the whole cloud. Default ``(10, 14, 19, 27, 40, 55, 70,
      85)``. Why: the disc holds the VLP-16's three lowest rings on level ground (7.1, 8.2 and 9.8 m
      from 1.9 m up), enough for a free plane under the ego; the next annuli hold about one ring each
      (12.0, 15.5, 21.7 and 36.3 m on level ground, nearer uphill, farther downhill), so a vehicle's
      lowest scan line seldom shares a patch with a ground ring outside it and tilts a free plane
      into itself (the hinged fit ties a lone ring to the ground inside instead); beyond 40 m, where
      only climbing ground is hit, 15 m annuli keep the planes local. Wider rings hold more vehicle
      returns beside the ground and lose more of them as ground.
    - ``ring_sectors`` (integers >= 1, one per ring outside the disc, or one for all of them; a
      tuple after construction): the sectors of each ring, equal in azimuth, sector 0 centred on
      E's +x. Default 16 (22.5 deg: 4 to 5.5 m wide at 10-14 m, 33 m at 85 m). Sectors follow the
      ground's lateral changes (a banked road and the level terrain beside it, the grade turning
      with a curving road); narrower ones hold fewer points, which a vehicle's returns can
      outnumber.

    Fits, per patch (after Zermas et al. 2017):

    - ``seed_fraction`` (0-1]: the fraction of a patch's fit points (at least one), lowest first,
      whose mean height is its lowest point representative (LPR). Default 0.1 (Zermas's ``N_LPR`` as
      a fraction, since patches hold from a few to thousands of points).
    - ``seed_height`` (m): seeds are the points less than this above their patch's LPR. Default 0.4
      (Zermas's ``Th_seeds``).
    - ``ransac_iterations``: hypotheses per patch of a free fit, each through 3 random seeds (a
      hinged fit draws half as many, at least 8, through 2 seeds and the hinge point, and tries the
      neighbour's gradient too), scored all at once. Default 32: with half the seeds on the ground
      ``P(no all-ground sample) = (1 - 0.5^3)^32 ~ 1.4 %`` (and its refit may still recover); seeds
      are the lowest points of a patch, mostly ground.
    - ``distance_threshold`` (m): point-to-plane distance within which a point is ground (RANSAC
      inlier, refit inlier, final classification). Default 0.15: vehicle sills and bumpers start
      0.2-0.3 m above the road; the VLP-16's +-3 cm range noise is < 1 cm vertically on the ground
      (grazing beams, <= 15 deg); a plane over a change of grade or bank of ``dg`` across ``L`` m
      misses by ``dg L / 8``, 4 cm for 3 % over a 10 m patch.
    - ``refine_iterations``: refits of the best hypothesis on its inliers, the inliers recomputed
      after each (free fits by total least squares, Zermas's ``N_iter``; hinged fits by ridge
      regression, at least 1). Default 3.
    - ``max_slope_deg`` (deg): a plane whose normal is more than this from vertical is rejected.
      Default 15 deg (27 %): steeper than any road grade plus bank plus mount error, flatter than
      vehicle sides, walls and embankments.
    - ``min_spread`` (m): a free fit is rejected when its inliers spread less than this across their
      main direction: half the distance between the 10 % and 90 % quantiles of their offsets across
      it (a few stray inliers, under 10 %, do not count). Inliers along one scan ring leave the
      plane's tilt about the ring undetermined (a ring arc of sagitta ``S`` spreads ``~0.4 S``, 0.7 m
      across a 16th of a circle 85 m out); two rings ``D`` apart spread ``~D / 2``. Default 1.0.
      Lower values let free planes tilt on nearly straight arcs.
    - ``max_step`` (m): continuity of the ground. A free fit is rejected unless its plane and its
      inner neighbour's meet (differ by at most this) somewhere between where the neighbour's
      inliers end and where the patch's begin, along the patch's inliers' mean azimuth. Default
      0.25: below a car body's 0.3 m ground clearance, so a "ground" fitted to a vehicle's lowest
      scan lines or a raised load is rejected, while a true change of grade between the two meets
      the neighbour at the change.
    - ``max_slope_change_deg`` (deg): smoothness of the ground: a free or hinged plane whose normal
      is more than this from its inner neighbour's is rejected. Default 5 deg (an 8.7 % change of
      grade or bank between adjacent patches; vertical curves change the grade by about 1 % per
      10 m, ramps and entrances by a few %; a banked road's level verge by its bank): a plane
      through a ground ring that tilts up into a vehicle's lowest scan line a few metres on is
      rejected. A sharper change is not followed (the patch borrows its neighbour's plane; a
      rising ground's returns stay in, a falling one's are below ground and removed).
    - ``hinge_prior_length`` (m): how strongly a hinged fit's gradient is pulled towards its inner
      neighbour's: the ridge weight is ``(number of inliers) x hinge_prior_length^2``, so the data
      move the gradient along a direction only as far as the inliers reach out from the hinge
      point along it, compared with this length. The hinge point is known to a few cm, gradients
      change by a few % between patches: ``~0.05 m / 0.025 = 2 m`` is where a ring's height and the
      prior carry equal weight. Default 2.0. Larger, a patch cannot bend away from its neighbour's
      slope, as the level verge of a banked road does; smaller, a ring next to the hinge point tilts
      the plane by its height error over its short lever.
    - ``min_points``: a fit needs at least this many inliers among the patch's points taking part
      (estimated from the fit subsample), and a patch with fewer such points is not fitted. Default
      30: a vehicle side seen at 60-80 m gives 20-60 returns on one beam, all on the beam's cone,
      which a plane through the hinge point can take for a climbing ground.
    - ``hinged_share`` (0-1, or None): a free fit that passes the tests above is still not taken
      where the patch's hinged fit (below) explains at least this share of the free fit's inliers
      (counted on the same subsample); the hinged plane is taken instead. Default 0.8. Why: a
      free plane is fixed by its own inliers alone. Where these are one scan ring and a few low
      returns of the road's edge beside it (a kerb's top, a hedge's or a wall's lowest returns),
      its tilt about the ring is set by those few points, and the patches further out that borrow
      it carry the tilt tens of metres: 1.6 deg at 55-70 m puts the ground 0.46 m above the plane
      at 80 m, where its returns are taken for objects. A plane that continues the ground inside
      and explains nearly as many points is the better-supported of the two. ``None``: the free
      fit whenever it passes (then hinged fits run only where there is none).
    - ``max_fit_points``: a patch with more points taking part is fitted on a random subsample of
      this many (every point is still classified; a random draw, because an even stride aliases
      with the scan order: a VLP-16 interleaves its beams, so every other point of a patch can lie
      on the same ring). Default 128: a plane has 3 parameters; 128 points fix it to well under a
      tenth of a degree, and keep the padded ``(patches, points, hypotheses)`` arrays small.
    - ``column_width_deg`` (deg): the azimuth columns of the steep-rise test: of two returns next to
      each other (outwards) in a column ``floor(phi / w + 1/2)`` that differ in height by more than
      ``distance_threshold`` and lie at most that far apart horizontally (45 deg or steeper), the
      lower one is at the foot of something (a vehicle's side, a wall, a pole) and takes no part in
      the fits; so is a return with another more than ``distance_threshold`` higher in its column
      within about ``distance_threshold`` in ``rho`` (a dense lidar's neighbouring beams climb a near
      face a few centimetres apart, no rise between any two). Default 0.2 (the VLP-16's azimuth step
      at 10 Hz: each column one firing of its 16 beams). Without the test, the lowest scan line
      across a vehicle's rear, which lies as flat as a ground ring, 2 deg above the ground's plane
      from where the ground is last seen, is taken for a climbing ground by a hinged fit
      (``tests/test_cloud.py``).
    - ``seed`` (int >= 0): seed of the random draws (the fit subsample, the RANSAC samples): the
      same cloud and configuration give the same result.

    The ego's own body: points in E with ``|x| <= ego_length / 2 + ego_margin``, ``|y| <= ego_width / 2
    + ego_margin`` and ``z <= ego_height + ego_margin`` are returns from the ego itself (its roof, bonnet
    and boot under a roof lidar's lowest beams, its mirrors) and are dropped before the ground fit:

    - ``ego_length``, ``ego_width``, ``ego_height`` (m, >= 0): the ego's box, centred on E's origin
      (the ego's centre on the ground). Default 4.8 x 2.0 x 1.5 m (a car; ``sim`` sets the scenario's
      ego). ``ego_length = 0`` turns the crop off.
    - ``ego_margin`` (m, >= 0): grows the box on every side but the bottom. Default 0.3: the mirrors
      (0.2-0.25 m beyond the body), the range noise and a box that is not quite the body.

    Classification:

    - ``height_ceiling`` (m above the patch's plane): higher points are dropped. Default 4.0 (the
      EU vehicle height limit): bridges, gantries, signs and tree canopies above a road are gone.
    - ``low_object_height`` (m above the patch's plane; None: off): a point whose cell holds no point
      higher than this is a low object and dropped. Default 0.3: a kerb (0.10-0.20 m) stands just
      above ``distance_threshold``, its returns lie within the road's margin, and they line up along
      the edge into clusters that seed tracks; a vehicle's returns reach 1.2 m and more.
    - ``low_object_cell`` (m, > 0): the side of those cells in E. Default 0.5: a vertical side's
      returns from every beam of a firing lie one above the other, in one cell; a kerb's top lies in
      cells of its own, though a guard-rail post or a wall may stand in the next one (the cell's
      neighbours are not asked: a kerb's top beside a post, taken as an object, joins the post's
      returns in a cluster at the road's edge).

    Outlines (after the classification; the returns stay kept, as occluders, but are not 2-D points):

    - ``seen_over_gap`` (m, >= 0; None: off): a kept return is *seen over* something where its azimuth
      column (``column_width_deg``, about the lidar at ``(mount_x, mount_y)``) holds a kept return more
      than this nearer in ``rho`` and beneath its ray (a lower elevation from the lidar at ``mount_z``):
      the ray passed over a nearer object (a hedge, a wall, another vehicle) and hit what stands behind
      it above that object's top, and no other return of the column lies within this of it in ``rho``
      (the ray grazed a roof: at long range the window of elevations that reach a roof's far end
      over a nearer object holds one beam; a face seen over a post or a low bush returns two beams or
      more at one ``rho``, and stays). A 2-D scan cannot see a roof's return, and
      the rectangle model takes a projected one for the outline the sensor faces: a car's roof end seen
      over a roadside hedge lies a body length behind its rear face, and the cut between the two
      (``tracker.clustering.along_cuts_kernel``) bounds the car at its rear face. Such returns are left
      out of ``CloudResult.outline_2d``; within the road they are the ones the bearing filter drops
      anyway (a nearer return in their bin), so what changes is the returns seen over objects beside
      the road, which the road filter removes before the bearing filter. A return beneath a nearer one
      (a canopy, a sign) stays. Default 0.5 (a vehicle's face: its beams' returns within centimetres
      of each other in ``rho``; a sloping bonnet or windscreen seen over its bumper is dropped by the
      bearing filter as well). For a rig's merged cloud the columns and elevations are taken about the
      primary lidar (the mount pose), an approximation for the others.

    A patch with no plane of its own borrows its inner neighbour's (the patch of the ring inside
    holding its sector's axis, whatever plane that one uses); the disc uses the level plane ``z = 0``
    when its free fit fails or the ego could not stand on it (more than ``max_step`` from a corner of
    its footprint at z = 0 in E); see :class:`GroundModel` and :func:`fit_ground`.
    """

    frame: str = "sensor"
    mount_x: float = 0.0
    mount_y: float = 0.0
    mount_z: float = 1.9
    mount_roll_deg: float = 0.0
    mount_pitch_deg: float = 0.0
    mount_yaw_deg: float = 0.0
    ring_edges: tuple[float, ...] = (10.0, 14.0, 19.0, 27.0, 40.0, 55.0, 70.0, 85.0)
    ring_sectors: int | tuple[int, ...] = 16
    seed_fraction: float = 0.1
    seed_height: float = 0.4
    ransac_iterations: int = 32
    distance_threshold: float = 0.15
    refine_iterations: int = 3
    max_slope_deg: float = 15.0
    min_spread: float = 1.0
    max_step: float = 0.25
    max_slope_change_deg: float = 5.0
    hinge_prior_length: float = 2.0
    min_points: int = 30
    hinged_share: float | None = 0.8
    max_fit_points: int = 128
    column_width_deg: float = 0.2
    height_ceiling: float = 4.0
    low_object_height: float | None = 0.3
    low_object_cell: float = 0.5
    seen_over_gap: float | None = 0.5
    ego_length: float = 4.8
    ego_width: float = 2.0
    ego_height: float = 1.5
    ego_margin: float = 0.3
    seed: int = 0

    def __post_init__(self) -> None:
        if self.frame not in CLOUD_FRAMES:
            raise ValueError(f"CloudConfig.frame must be one of {list(CLOUD_FRAMES)}; got {self.frame!r}")
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
            raise ValueError(f"CloudConfig.ring_sectors must be an integer or a sequence of integers; "
                             f"got {self.ring_sectors!r}")
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
        _real("max_slope_change_deg", self.max_slope_change_deg, low=0.0, high=180.0, low_open=True, unit="deg")
        _real("hinge_prior_length", self.hinge_prior_length, low=0.0, low_open=True, unit="m")
        _integer("min_points", self.min_points, 3)
        if self.hinged_share is not None:
            _real("hinged_share", self.hinged_share, low=0.0, high=1.0)
        _integer("max_fit_points", self.max_fit_points, self.min_points)
        _real("column_width_deg", self.column_width_deg, low=0.0, high=360.0, low_open=True, unit="deg")
        ceiling = _real("height_ceiling", self.height_ceiling, low=0.0, low_open=True, unit="m")
        if ceiling <= self.distance_threshold:
            raise ValueError(f"CloudConfig.height_ceiling must be > distance_threshold "
                             f"({self.distance_threshold!r} m); got {self.height_ceiling!r}")
        if self.low_object_height is not None:
            low = _real("low_object_height", self.low_object_height, low=0.0, unit="m")
            if not self.distance_threshold <= low < ceiling:
                raise ValueError(f"CloudConfig.low_object_height must be within [distance_threshold, height_ceiling) "
                                 f"([{self.distance_threshold!r}, {self.height_ceiling!r}) m) or None; got {low!r}")
        _real("low_object_cell", self.low_object_cell, low=0.0, low_open=True, unit="m")
        if self.seen_over_gap is not None:
            _real("seen_over_gap", self.seen_over_gap, low=0.0, unit="m")
        for name in ("ego_length", "ego_width", "ego_height", "ego_margin"):
            _real(name, getattr(self, name), low=0.0, unit="m")
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
    return _patch_of_polar(np.hypot(dx, dy), np.arctan2(dy, dx), edges, sectors, first)


def _patch_of_polar(rho: np.ndarray, phi: np.ndarray, edges: np.ndarray, sectors: np.ndarray,
                    first: np.ndarray) -> np.ndarray:
    """The patch of each point at distance ``rho`` (m) and azimuth ``phi`` (rad) from the centre."""
    ring = np.searchsorted(edges, rho, side="left")
    s = sectors[ring]
    k = np.floor(phi * (s / (2.0 * math.pi)) + 0.5).astype(np.intp)
    k %= s
    return first[ring] + k


def _wall_feet(rho: np.ndarray, z: np.ndarray, columns: tuple[np.ndarray, np.ndarray],
               cfg: CloudConfig) -> np.ndarray:
    """Which points (N,) stand at the foot of something steep. The returns are grouped in azimuth
    columns ``floor(phi / w + 1/2)`` (``w = column_width_deg``) and ordered outwards in each; of two
    returns next to each other in a column that differ in height by more than ``distance_threshold``
    and lie at most that far apart horizontally (a rise of 45 deg or more), the lower one is a foot
    (either may be the nearer: range noise shuffles a vertical face's returns in ``rho``); and a
    return is a foot where its column holds another more than ``distance_threshold`` higher in its
    bin of that width in ``rho`` or the bins either side (a dense lidar's neighbouring beams climb a
    near face centimetres apart: no rise between any two, yet all but the top at its foot). A
    vehicle's side, a wall or a pole returns a column of points one above the other; the ground's
    returns in one column lie rings apart (metres out, centimetres up). Feet take no part in the
    fits (they are still classified against the planes). ``columns``: ``(col, order)``,
    ``_column_order``'s result for these returns (the ground fit's: one sort serves both passes)."""
    n = len(rho)
    if n < 2:
        return np.zeros(n, dtype=bool)
    col, order = columns
    c, r, h = col[order], rho[order], z[order]
    out = np.zeros(n, dtype=bool)
    out[order] = wall_feet_kernel(c, r, h, cfg.distance_threshold)
    return out


def _column_order(rho: np.ndarray, phi: np.ndarray, width_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """The azimuth column ``floor(phi / w + 1/2)`` (``w = width_deg`` in rad) of each return (N,), and
    the order (N,) that sorts the returns by column, then outwards by ``rho`` (to the centimetre: two
    stable radix sorts where the columns fit 16 bits)."""
    col = np.floor(phi / math.radians(width_deg) + 0.5)
    if 180.0 / width_deg < _INT16_MAX - 1:  # by column, then outwards: two radix sorts
        order = np.argsort(np.minimum(rho * 100.0, _UINT16_MAX).astype(np.uint16), kind="stable")  # cm
        order = order[np.argsort(col[order].astype(np.int16), kind="stable")]
    else:
        order = np.argsort(col * (2.0 * (float(rho.max()) + 1.0)) + rho)
    return col, order


def _seen_over(points: np.ndarray, kept: np.ndarray, columns: tuple[np.ndarray, np.ndarray, np.ndarray],
               cfg: CloudConfig) -> np.ndarray:
    """Which of a cloud's returns ``points`` (N, 3) in E were seen over a nearer object, of the kept
    ones ``kept`` (N,) (the others False; all False when ``CloudConfig.seen_over_gap`` is None): in
    its azimuth column about the lidar ``(mount_x, mount_y)`` (``column_width_deg``), a return more
    than ``seen_over_gap`` nearer in ``rho`` lies beneath its ray, at an elevation from the lidar
    (``mount_z``) lower by more than ``SEEN_OVER_ELEVATION`` (rad): the ray passed over that return's
    object; and no other return of the column lies within ``seen_over_gap`` of it in ``rho`` (a face
    that two beams or more hit above the nearer object stays). ``columns``: ``(col, order, rho)``,
    ``_column_order``'s result for ``points`` and their horizontal distances from the lidar (the
    ground fit's: no second sort)."""
    if cfg.seen_over_gap is None or len(points) < 2:
        return np.zeros(len(points), dtype=bool)
    col, order, rho = columns
    return seen_over_kernel(order, kept, col, rho, points[:, 2], float(cfg.mount_z), float(cfg.seen_over_gap),
                            math.tan(SEEN_OVER_ELEVATION))


#: ``_seen_over``: a nearer return is beneath a ray where its elevation from the lidar is lower by more
#: than this (rad; 0.06 deg: a fifth of the finest beam spacing of the lidars modelled, 0.33 deg, and
#: well above the elevation that range noise moves a return by).
SEEN_OVER_ELEVATION = 1e-3


@njit
def seen_over_kernel(order, take, col, rho, z, lidar_z, gap, tol):  # pragma: no cover - compiled
    """:func:`_seen_over`'s test on the returns ``take`` (N,) of ``order`` (N,), which sorts them by
    column ``col`` (N,), then outwards by ``rho`` (N,); ``z`` (N,) their heights in E, ``lidar_z`` the
    lidar's. With ``slope = (z - lidar_z) / rho``, the tangent of a return's elevation: a return is
    seen over something where a return of its column with ``rho < rho_i - gap`` has ``slope <
    slope_i - tol`` (a running minimum of the nearer returns' slopes: one pass) and no other return of
    its column lies within ``gap`` of it in ``rho`` (its neighbours in the order); a return at ``rho =
    0`` takes no part. Returns the flags (N,) in input order."""
    n = order.shape[0]
    out = np.zeros(n, dtype=np.bool_)
    idx = np.empty(n, dtype=np.int64)  # the returns taken, in order
    m = 0
    for k in range(n):
        if take[order[k]]:
            idx[m] = order[k]
            m += 1
    start = 0
    while start < m:
        c = col[idx[start]]
        stop = start
        while stop < m and col[idx[stop]] == c:
            stop += 1
        lowest = np.inf
        j = start
        for a in range(start, stop):
            i = idx[a]
            r = rho[i]
            while j < a and rho[idx[j]] < r - gap:
                q = idx[j]
                if rho[q] > 0.0:  # a return right above or below the lidar has no elevation to compare
                    slope = (z[q] - lidar_z) / rho[q]
                    if slope < lowest:
                        lowest = slope
                j += 1
            if r > 0.0 and lowest < (z[i] - lidar_z) / r - tol:
                face = (a > start and r - rho[idx[a - 1]] <= gap) or (a + 1 < stop and rho[idx[a + 1]] - r <= gap)
                out[i] = not face
        start = stop
    return out


@njit
def wall_feet_kernel(c, r, h, tau):  # pragma: no cover - compiled
    """:func:`_wall_feet`'s tests on returns sorted by column ``c`` (N,), then outwards by ``rho`` ``r``
    (N,), heights ``h`` (N,) in that order; ``tau = distance_threshold``. Returns the feet (N,) in that
    order. Two returns next to each other in a column, ``rise = |h_i+1 - h_i| > tau`` and ``r_i+1 -
    r_i <= rise``: the lower is a foot (the first of the two where they are equal). Groups: a column's
    returns in one bin ``floor(r / tau)``; a return is a foot where its group, or the column's group in
    the bin next out or next in, holds a return higher than ``h + tau``."""
    n = c.shape[0]
    out = np.zeros(n, dtype=np.bool_)
    for i in range(n - 1):
        if c[i + 1] == c[i]:
            rise = abs(h[i + 1] - h[i])
            if rise > tau and r[i + 1] - r[i] <= rise:
                if h[i + 1] < h[i]:
                    out[i + 1] = True
                else:
                    out[i] = True
    # the groups (column, bin) in order, each one's highest return
    group = np.empty(n, dtype=np.int64)
    top = np.empty(n)
    gc = np.empty(n)
    gb = np.empty(n)
    g = -1
    for i in range(n):
        b = math.floor(r[i] / tau)
        if g < 0 or c[i] != gc[g] or b != gb[g]:
            g += 1
            gc[g], gb[g], top[g] = c[i], b, h[i]
        elif h[i] > top[g]:
            top[g] = h[i]
        group[i] = g
    count = g + 1
    above = top[:count].copy()
    for k in range(count - 1):  # the next group is the next bin out of the same column
        if gc[k + 1] == gc[k] and gb[k + 1] == gb[k] + 1:
            above[k] = max(above[k], top[k + 1])
            above[k + 1] = max(above[k + 1], top[k])
    for i in range(n):
        if h[i] < above[group[i]] - tau:
            out[i] = True
    return out


@dataclass(frozen=True, eq=False)
class GroundModel:
    """Piecewise-planar ground in E: one plane per patch of a polar grid around the sensor.

    The layout (after Patchwork's concentric zones, Lim et al. 2021): with ``centre = (c_x, c_y)``
    (m, the sensor's position in E, around which its scan rings lie), a point's horizontal distance
    ``rho = |(x - c_x, y - c_y)|`` and azimuth ``phi = atan2(y - c_y, x - c_x)``, and
    ``ring_edges = (e_0, ..., e_{R-1})`` (m): ring 0 is the disc ``rho <= e_0`` (the ego's patch,
    ``sectors[0] == 1``), ring ``j`` the annulus ``e_{j-1} < rho <= e_j`` (``e_R = inf``), cut into
    ``S_j = sectors[j]`` equal sectors; sector ``k`` of ring ``j`` is centred on the azimuth
    ``phi_k = 2 pi k / S_j`` (``k = 0`` along E's +x: straight ahead) and holds the points with
    ``floor(phi S_j / (2 pi) + 1/2) mod S_j = k``. Patches are numbered ring by ring,
    ``p = S_0 + ... + S_{j-1} + k`` (:attr:`ring_starts`); ``ring_edges = ()`` is one plane for the
    whole cloud. A patch's *inner neighbour* is the patch of the ring inside holding its sector's
    axis.

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
    - ``inlier_counts`` (P,): the final plane's inliers among the patch's fit points (the random
      subsample of at most ``max_fit_points`` of its points taking part), 0 for a fallback.
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
            raise ValueError(f"GroundModel.sectors must hold one count >= 1 per ring, 1 for the disc; "
                             f"got {self.sectors!r}")
        if any(b <= a for a, b in zip(edges, edges[1:])) or not all(math.isfinite(e) for e in edges):
            raise ValueError(f"GroundModel.ring_edges must be finite and strictly increasing; "
                             f"got {self.ring_edges!r}")
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
    """The fit points of the patches with a row (``rows[p] >= 0``): a random subsample of at most
    ``cap`` of each patch's points (all of them when it has no more), in random order. Random, not an
    even stride or the input order, because those alias with the scan order: a VLP-16 interleaves its
    beams, so every other point of a patch may lie on the same ring (the hypotheses are scored on an
    even stride over the fit points). Returns the point indices, their rows and slots (columns of the
    padded ``(rows, C, .)`` arrays, each row's points first) and ``C``."""
    perm = rng.permutation(len(patch))
    key = patch[perm]
    order = perm[np.argsort(key.astype(np.int16) if len(counts) <= _INT16_MAX else key, kind="stable")]  # radix
    p_sorted = patch[order]
    slot = np.arange(len(order)) - np.concatenate(([0], np.cumsum(counts)[:-1]))[p_sorted]
    keep = (rows[p_sorted] >= 0) & (slot < cap)
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


def _sample_seeds(seeds: tuple[np.ndarray, np.ndarray], k: int, rng: np.random.Generator) -> np.ndarray:
    """``k`` random seed slots per row (m, k) (uniform, with repetition; 0 for a row without seeds),
    of ``seeds = (slots, count)``: each row's seed slots first (m, C) and their number (m,)."""
    slots, count = seeds
    idx = (rng.random((len(count), k)) * count[:, None]).astype(np.intp)
    np.minimum(idx, np.maximum(count - 1, 0)[:, None], out=idx)
    return np.take_along_axis(slots, idx, axis=1)


def _spreads(xy: np.ndarray, inl: np.ndarray, centroid: np.ndarray, scatter: np.ndarray) -> np.ndarray:
    """The spread (m,) (m) of each row's inliers ``inl`` (m, C) in x-y ``xy`` (m, C, 2), given their
    centroid ``c`` (m, 2) and scatter ``[[a, b], [b, e]] = sum (p - c)(p - c)^T`` (m, 2, 2): half the
    interdecile range of their offsets ``o_i = (p_i - c) . v`` along their minor axis ``v`` (at the
    angle ``atan2(2 b, a - e) / 2 + pi / 2``), ``(o_(90 %) - o_(10 %)) / 2``; 0 without inliers.

    One scan-ring arc gives about 0.4 times its sagitta (a few stray inliers, under 10 %, do not
    count); two rings ``D`` apart (each with over 10 % of the inliers) about ``D / 2``; a patch
    covered evenly ``W`` wide across its minor axis ``0.4 W``."""
    m = len(xy)
    rows = np.arange(m)
    count = inl.sum(axis=1)
    k = np.maximum(count, 1)
    a, b, e = scatter[:, 0, 0], scatter[:, 0, 1], scatter[:, 1, 1]
    theta = 0.5 * np.arctan2(2.0 * b, a - e) + 0.5 * math.pi
    off = ((xy[..., 0] - centroid[:, :1]) * np.cos(theta)[:, None]
           + (xy[..., 1] - centroid[:, 1:]) * np.sin(theta)[:, None])
    off = np.sort(np.where(inl, off, np.inf).astype(np.float32), axis=1)
    lo = off[rows, np.floor(_SPREAD_QUANTILES[0] * (k - 1)).astype(np.intp)]
    hi = off[rows, np.ceil(_SPREAD_QUANTILES[1] * (k - 1)).astype(np.intp)]
    return np.where(count > 0, 0.5 * (hi.astype(float) - lo), 0.0)


def _normal_of_scatter(s: np.ndarray, n0: np.ndarray) -> np.ndarray:
    """The unit eigenvectors (m, 3) of the smallest eigenvalues of symmetric 3 x 3 scatters ``s``
    (m, 3, 3), pointing up, from guesses ``n0`` (m, 3) (the planes being refitted).

    With ``s = sum_i lambda_i v_i v_i^T`` (``lambda_1 <= lambda_2 <= lambda_3``) the adjugate is
    ``adj(s) = lambda_2 lambda_3 v_1 v_1^T + lambda_1 lambda_3 v_2 v_2^T + lambda_1 lambda_2 v_3 v_3^T``:
    ``adj(s) n0`` is ``v_1`` up to components ``lambda_1 / lambda_2`` and ``lambda_1 / lambda_3`` as
    large (relative), and two steps square that. For a plane's inliers ``lambda_1`` is their
    thickness's variance (noise, mm^2 to cm^2) and ``lambda_2`` their extent's (m^2): the result
    agrees with an eigen-decomposition to ~1e-8 rad, at a fraction of its cost; exactly coplanar
    points (``lambda_1 = 0``) give ``v_1`` exactly; collinear ones (``adj(s) = 0``) keep ``n0``."""
    a, b, c = s[:, 0, 0], s[:, 0, 1], s[:, 0, 2]
    d, e, f = s[:, 1, 1], s[:, 1, 2], s[:, 2, 2]
    adj = np.empty_like(s)  # the cofactors of a symmetric matrix
    adj[:, 0, 0] = d * f - e * e
    adj[:, 0, 1] = adj[:, 1, 0] = c * e - b * f
    adj[:, 0, 2] = adj[:, 2, 0] = b * e - c * d
    adj[:, 1, 1] = a * f - c * c
    adj[:, 1, 2] = adj[:, 2, 1] = b * c - a * e
    adj[:, 2, 2] = a * d - b * b
    n = n0
    for _ in range(2):
        v = (adj @ n[:, :, None])[..., 0]
        norm = np.linalg.norm(v, axis=1)
        n = np.where((norm > 0.0)[:, None], v / np.where(norm > 0.0, norm, 1.0)[:, None], n)  # collinear: keep
    return n * np.where(n[:, 2] < 0.0, -1.0, 1.0)[:, None]


def _free_fits(ph: np.ndarray, valid: np.ndarray, seeds: tuple[np.ndarray, np.ndarray], scale: np.ndarray,
               cfg: CloudConfig,
               rng: np.random.Generator, cos_max: float
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Free RANSAC planes of padded patches, all at once: ``ph`` (m, C, 4) the fit points ``[q 1]``
    (relative to an origin per row; ``valid`` (m, C), each row's points first; padding rows 0),
    ``seeds`` (each row's seed slots first, and their number: :func:`_sample_seeds`), ``scale`` (m,)
    the patch's points taking part per fit point (an inlier count times it is the estimated count
    among all of them, held against ``min_points``).

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
    eigenvector of the smallest eigenvalue of their scatter ``sum (q - c)(q - c)^T``, pointing up:
    :func:`_normal_of_scatter`), the inliers recomputed after each refit. Returns
    ``(n, d, inliers, ok, c)``: ``ok`` when the plane has ``n_z >= cos(max_slope)``, at least
    ``min_points`` inliers and a spread (:func:`_spreads`) of at least ``min_spread``; ``c`` the
    inliers' centroid.
    """
    m, c, _ = ph.shape
    rows = np.arange(m)
    tau = cfg.distance_threshold
    h = cfg.ransac_iterations
    flat = (rows[:, None] * c + _sample_seeds(seeds, 3 * h, rng)).ravel()
    sample = np.take(ph.reshape(-1, 4), flat, axis=0)[:, :3].reshape(m, h, 3, 3)
    a = sample[:, :, 0]
    e1 = sample[:, :, 1] - a
    e2 = sample[:, :, 2] - a
    normals = np.empty_like(a)  # e1 x e2
    normals[..., 0] = e1[..., 1] * e2[..., 2] - e1[..., 2] * e2[..., 1]
    normals[..., 1] = e1[..., 2] * e2[..., 0] - e1[..., 0] * e2[..., 2]
    normals[..., 2] = e1[..., 0] * e2[..., 1] - e1[..., 1] * e2[..., 0]
    norm = np.sqrt(np.einsum("phi,phi->ph", normals, normals))
    good = (norm > _DEGENERATE_AREA) & (seeds[1] >= 3)[:, None]
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
        scatter = mom[:, :3, :3] - count[:, None, None] * centroid[:, :, None] * centroid[:, None, :]
        if it == cfg.refine_iterations:
            break
        refit = found & (count >= 3)
        if not refit.any():
            break
        n = _normal_of_scatter(scatter[refit], plane[refit, :3])
        plane[refit, :3] = n
        plane[refit, 3] = -np.einsum("pi,pi->p", n, centroid[refit])
        inl = valid & (np.abs((ph @ plane[:, :, None])[..., 0]) <= tau)
    ok = found & (plane[:, 2] >= cos_max) & (inl.sum(axis=1) * scale >= cfg.min_points) & (inl.sum(axis=1) >= 3)
    if ok.any():
        ok[ok] = _spreads(ph[ok][..., :2], inl[ok], centroid[ok, :2], scatter[ok, :2, :2]) >= cfg.min_spread
    return plane[:, :3], plane[:, 3], inl, ok, centroid


def _hinged_fits(ph: np.ndarray, valid: np.ndarray, seeds: tuple[np.ndarray, np.ndarray], scale: np.ndarray,
                 hinge: np.ndarray,
                 prior: np.ndarray, cfg: CloudConfig, rng: np.random.Generator,
                 tan_max: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Hinged planes of padded patches (``ph``, ``valid``, ``seeds``, ``scale`` as :func:`_free_fits`;
    ``hinge`` (m, 3) in the same coordinates): each through its hinge point, its gradient
    ``g = (dz/dx, dz/dy)`` fitted and pulled towards ``prior`` (m, 2).

    With ``d_i = (x_i - x_h, y_i - y_h)`` and ``v_i = z_i - z_h`` relative to the hinge point, the plane
    is ``v = g . d``. RANSAC over ``max(8, ransac_iterations / 2)`` hypotheses: the first is
    ``g = prior``, the others the planes through the hinge point and 2 random seeds (a 2 x 2 solve;
    invalid when the three are nearly in a line in x-y or the plane is steeper than
    ``max_slope_deg``), scored as in :func:`_free_fits` with the point-to-plane distance
    ``(v_i - g . d_i) / sqrt(1 + |g|^2)``. The best is refined ``max(1, refine_iterations)`` times by
    ridge regression on its ``m`` inliers,

    .. math::  g = \\Big(\\sum_i d_i d_i^T + \\lambda I\\Big)^{-1}
                   \\Big(\\sum_i v_i d_i + \\lambda g_0\\Big), \\qquad \\lambda = m L^2,

    ``L = hinge_prior_length`` (m), ``g_0 = prior``: the data move the gradient along a direction
    as far as the inliers reach out from the hinge point along it compared with ``L`` (a ring far
    out fixes the slope out to it; a short arc next to the hinge point, whose heights are uncertain
    by the hinge point's few centimetres, barely does), and the prior's slope stays where they do
    not reach. The inliers are then recomputed. Returns ``(g, inliers, ok)``, ``ok`` when the plane
    has at least ``min_points`` inliers (counted as in :func:`_free_fits`) and
    ``|g| <= tan(max_slope)``.
    """
    c = int(valid.sum(axis=1).max()) if valid.size else 0  # the slots in use (each row's points come first)
    ph, valid, seeds = ph[:, :c], valid[:, :c], (seeds[0][:, :c], seeds[1])
    m = len(ph)
    rows = np.arange(m)
    tau = cfg.distance_threshold
    h = max(_MIN_HYPOTHESES, cfg.ransac_iterations // 2)  # 2 seeds a sample: fewer needed
    rel = ph[..., :3] - hinge[:, None, :]  # (m, C, 3): d_i and v_i (the padding is masked below)
    flat = (rows[:, None] * c + _sample_seeds(seeds, 2 * h, rng)).ravel()
    s = np.take(rel.reshape(-1, 3), flat, axis=0).reshape(m, h, 2, 3)
    ui, wi, vi = s[:, :, 0, 0], s[:, :, 0, 1], s[:, :, 0, 2]
    uj, wj, vj = s[:, :, 1, 0], s[:, :, 1, 1], s[:, :, 1, 2]
    det = ui * wj - wi * uj
    good = np.abs(det) > _HINGE_MIN_SINE * np.sqrt((ui * ui + wi * wi) * (uj * uj + wj * wj))
    det[~good] = 1.0
    hyp = np.empty((m, 3, h), dtype=np.float32)  # rows (-g_x, -g_y, 1): [d v] . hyp = v - g . d
    hyp[:, 0] = (vj * wi - vi * wj) / det
    hyp[:, 1] = (uj * vi - ui * vj) / det
    hyp[:, :2, 0] = -prior
    hyp[:, 2] = 1.0
    good[:, 0] = True
    slope2 = hyp[:, 0] ** 2 + hyp[:, 1] ** 2
    good &= slope2 <= tan_max * tan_max
    lim = tau * np.sqrt(1.0 + slope2)
    sub = slice(None, None, -(-c // _SCORE_POINTS))
    rs = rel[:, sub].astype(np.float32)
    rs[..., 2][~valid[:, sub]] = 1e6  # padding: far above any plane
    res = rs @ hyp  # v_i - g . d_i, (m, C', H)
    score = np.add.reduce((res < -lim[:, None, :]).view(np.uint8), axis=1, dtype=np.int32)
    np.abs(res, out=res)
    score = np.add.reduce((res <= lim[:, None, :]).view(np.uint8), axis=1, dtype=np.int32) - score
    score[~good] = -1 - c
    best = np.argmax(score, axis=1)
    vec = hyp[rows, :, best].astype(float)  # (m, 3)
    lever2 = cfg.hinge_prior_length ** 2
    for it in range(max(1, cfg.refine_iterations) + 1):
        lim = tau * np.sqrt(1.0 + vec[:, 0] ** 2 + vec[:, 1] ** 2)
        inl = valid & (np.abs((rel @ vec[:, :, None])[..., 0]) <= lim[:, None])
        if it == max(1, cfg.refine_iterations):
            break
        mom = (rel * inl[..., None]).transpose(0, 2, 1) @ rel  # sum [d v][d v]^T over the inliers
        lam = np.maximum(inl.sum(axis=1), 1) * lever2
        a, b, e = mom[:, 0, 0] + lam, mom[:, 0, 1], mom[:, 1, 1] + lam  # [[a, b], [b, e]] g = r
        ru, rw = mom[:, 0, 2] + lam * prior[:, 0], mom[:, 1, 2] + lam * prior[:, 1]
        det = a * e - b * b  # > 0: lam > 0
        vec[:, 0] = (b * rw - e * ru) / det
        vec[:, 1] = (b * ru - a * rw) / det
    g = -vec[:, :2]
    count = inl.sum(axis=1)
    ok = (count * scale >= cfg.min_points) & (count >= 3) & ((g * g).sum(axis=1) <= tan_max * tan_max)
    return g, inl, ok


def _plane_z(n: np.ndarray, d: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Heights ``z = -(n_x x + n_y y + d) / n_z`` of planes (rows of ``n``, ``d``) at ``(x, y)``."""
    return -(n[:, 0] * x + n[:, 1] * y + d) / n[:, 2]


def _fit_ground(pts: np.ndarray, cfg: CloudConfig) -> tuple[GroundModel, np.ndarray,
                                                             tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The ground model of finite points ``pts`` (N, 3) in E, each point's patch (N,) (see
    :func:`fit_ground` for the method), and the azimuth columns of the points about the lidar,
    ``(col, order, rho)`` (``_column_order``, with the horizontal distances ``rho``)."""
    edges = np.asarray(cfg.ring_edges, dtype=float)
    sectors = np.asarray((1,) + tuple(cfg.ring_sectors), dtype=np.intp)
    first = _ring_starts(sectors)
    centre = (cfg.mount_x, cfg.mount_y)
    n_patch = int(sectors.sum())
    rho = np.hypot(pts[:, 0] - centre[0], pts[:, 1] - centre[1])
    phi = np.arctan2(pts[:, 1] - centre[1], pts[:, 0] - centre[0])
    patch = _patch_of_polar(rho, phi, edges, sectors, first)
    counts = np.bincount(patch, minlength=n_patch)
    col, order = _column_order(rho, phi, cfg.column_width_deg)
    eligible = np.flatnonzero(~_wall_feet(rho, pts[:, 2], (col, order), cfg))  # the points that may be fitted
    fit_counts = np.bincount(patch[eligible], minlength=n_patch)
    cos_max = math.cos(math.radians(cfg.max_slope_deg))
    tan_max = math.tan(math.radians(cfg.max_slope_deg))
    cos_change = math.cos(math.radians(cfg.max_slope_change_deg))

    # the fit points of every patch with enough of them, padded to (rows, C, .), relative to an
    # origin per row (one of them: keeps the moments' cancellation small)
    cand = np.flatnonzero(fit_counts >= max(cfg.min_points, 3))
    row = np.full(n_patch, -1, dtype=np.intp)
    row[cand] = np.arange(len(cand))
    idx, r_of, slot, c = _fit_slots(patch[eligible], fit_counts, row, cfg.max_fit_points,
                                    np.random.default_rng((cfg.seed, 0)))
    idx = eligible[idx]
    valid = np.zeros((len(cand), c), dtype=bool)
    valid[r_of, slot] = True
    origin = np.zeros((len(cand), 3))
    origin[r_of[slot == 0]] = pts[idx[slot == 0]]  # one point of each row
    ph = np.zeros((len(cand), c, 4))
    ph[r_of, slot, :3] = pts[idx] - origin[r_of]
    ph[r_of, slot, 3] = 1.0
    seed_mask = _seed_mask(ph[..., 2], valid, cfg)
    seeds = (np.argsort(~seed_mask, axis=1, kind="stable"), seed_mask.sum(axis=1))  # each row's seeds first
    scale = fit_counts[cand] / np.maximum(valid.sum(axis=1), 1)  # points per fit point
    radius = np.where(valid, np.hypot(ph[..., 0] + (origin[:, 0] - centre[0])[:, None],
                                      ph[..., 1] + (origin[:, 1] - centre[1])[:, None]), np.nan)
    if len(cand):
        free_n, free_d, free_inl, free_ok, free_c = _free_fits(ph, valid, seeds, scale, cfg,
                                                               np.random.default_rng((cfg.seed, 1)), cos_max)
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

    hinge_rng = np.random.default_rng((cfg.seed, 2))  # drawn from ring by ring
    # the disc: its free fit where the ego could stand on it, or the level plane. The ego's wheels
    # are on the ground at z = 0 in E: the plane passes within max_step of the corners of its
    # footprint (ego_length x ego_width about the origin; the origin alone with the crop off). A
    # wall or hedge beside the ego tilts a fit through its foot up to it
    if row[0] >= 0 and free_ok[row[0]] and _stands_on(free_n[row[0]], free_d[row[0]], cfg):
        r0 = row[[0]]
        own(np.array([0]), r0, free_n[r0], free_d[r0], free_inl[r0])
    for j in range(1, len(sectors)):  # then ring by ring outwards, all sectors of a ring at once
        s_j, s_in = int(sectors[j]), int(sectors[j - 1])
        ps = first[j] + np.arange(s_j)
        axis = 2.0 * math.pi * np.arange(s_j) / s_j  # each sector's axis (azimuth)
        qs = first[j - 1] + np.mod(np.floor(axis * (s_in / (2.0 * math.pi)) + 0.5).astype(np.intp), s_in)
        nq, dq = normals[qs], offsets[qs]  # the inner neighbours' planes
        rp = row[ps]
        todo = rp >= 0
        # free fits: no kink to the inner neighbour's plane, and the two planes meet (within
        # max_step) somewhere between where the neighbour's support ends and where this one's begins
        free = (todo & free_ok[np.maximum(rp, 0)]) if len(cand) else todo
        free_count = np.zeros(s_j, dtype=int)  # the inliers of the free fits that pass
        if free.any():
            f = np.flatnonzero(free)
            rf = rp[f]
            n, d, inl = free_n[rf], free_d[rf], free_inl[rf]
            az = np.arctan2(free_c[rf, 1] - centre[1], free_c[rf, 0] - centre[0])
            cx, cy = np.cos(az), np.sin(az)
            gap = [_plane_z(n, d, centre[0] + r * cx, centre[1] + r * cy)
                   - _plane_z(nq[f], dq[f], centre[0] + r * cx, centre[1] + r * cy)
                   for r in (reach[qs[f]], np.where(inl, radius[rf], np.inf).min(axis=1))]
            step = np.where(gap[0] * gap[1] <= 0.0, 0.0, np.minimum(np.abs(gap[0]), np.abs(gap[1])))
            accept = (np.einsum("pi,pi->p", n, nq[f]) >= cos_change) & (step <= cfg.max_step)
            free[f[~accept]] = False
            free_count[f[accept]] = inl[accept].sum(axis=1)
            if cfg.hinged_share is None and accept.any():  # taken as it is: no hinged fit to weigh
                a = f[accept]
                own(ps[a], rp[a], n[accept], d[accept], inl[accept])
                todo[a] = False
        # hinged fits: through the inner neighbour's plane where its support ends, on the sector's
        # axis; with hinged_share, also where a free fit passed, which stays only where the hinged
        # one explains fewer than that share of its inliers
        if todo.any():
            f = np.flatnonzero(todo)
            rf = rp[f]
            hx = centre[0] + reach[qs[f]] * np.cos(axis[f])
            hy = centre[1] + reach[qs[f]] * np.sin(axis[f])
            hinge = np.column_stack([hx, hy, _plane_z(nq[f], dq[f], hx, hy)])
            prior = -nq[f, :2] / nq[f, 2:]  # the neighbour's gradient (dz/dx, dz/dy)
            g, inl, ok = _hinged_fits(ph[rf], valid[rf], (seeds[0][rf], seeds[1][rf]), scale[rf],
                                      hinge - origin[rf], prior, cfg, hinge_rng, tan_max)
            n = np.column_stack([-g, np.ones(len(f))]) / np.sqrt(1.0 + (g * g).sum(axis=1))[:, None]
            ok &= np.einsum("pi,pi->p", n, nq[f]) >= cos_change
            if cfg.hinged_share is not None:
                keep_free = free[f] & ~(ok & (inl.sum(axis=1) >= cfg.hinged_share * free_count[f]))
                if keep_free.any():
                    a = f[keep_free]
                    own(ps[a], rp[a], free_n[rp[a]], free_d[rp[a]], free_inl[rp[a]])
                ok &= ~keep_free
            if ok.any():
                a = f[ok]
                own(ps[a], rp[a], n[ok], -np.einsum("pi,pi->p", n[ok], hinge[ok]), inl[ok])
                hinged[ps[a]] = True
        # the rest borrow the inner neighbour's plane (and where that is supported)
        b = ~fitted[ps]
        normals[ps[b]], offsets[ps[b]], source[ps[b]], reach[ps[b]] = nq[b], dq[b], source[qs[b]], reach[qs[b]]
    model = GroundModel(ring_edges=tuple(edges.tolist()), sectors=tuple(sectors.tolist()), centre=centre,
                        normals=normals, offsets=offsets, fallback=~fitted, hinged=hinged, source=source,
                        point_counts=counts, inlier_counts=inlier_counts)
    return model, patch, (col, order, rho)


def fit_ground(points_e: Any, config: CloudConfig | None = None) -> GroundModel:
    """Piecewise-planar ground of a cloud ``(N, 3)`` in E, one plane per patch of a polar grid.

    The patches (:class:`GroundModel`): the disc ``rho <= e_0`` around the sensor's position and the
    rings of ``config.ring_edges``, each cut into ``ring_sectors`` sectors. Points at the foot of
    something steep (``column_width_deg``) take no part in the fits. In each patch with at least
    ``min_points`` points taking part, fitted on a random subsample of at most ``max_fit_points``:

    1. seeds: the points less than ``seed_height`` above the patch's lowest point representative
       (the mean height of its lowest ``seed_fraction``);
    2. the **free** fit: RANSAC, ``ransac_iterations`` planes through 3 random seeds, degenerate
       ones and ones steeper than ``max_slope_deg`` invalid, scored at once by their inliers less
       the points under them, ``#{i : |n . q_i + d| <= tau} - #{i : n . q_i + d < -tau}``
       (``tau = distance_threshold``; the ground is the lowest surface), and the best refitted
       ``refine_iterations`` times by total least squares on its inliers. Rejected when steeper
       than ``max_slope_deg``, with fewer than ``min_points`` inliers, or with inliers along a line
       (spread below ``min_spread``).

    Then, from the disc outwards: the disc takes its free fit where the ego could stand on it (the
    plane within ``max_step`` of the corners of the ego's footprint, ``ego_length x ego_width`` at
    z = 0 in E), or the level plane ``z = 0``. A
    patch ``k`` of ring ``j >= 1`` has as inner neighbour ``k'`` the patch of ring ``j - 1`` holding
    its sector's axis ``phi_k``; the neighbour's plane is supported by inliers out to the radius
    ``r'`` (the largest radius of its inliers, or of its source's if it borrowed its plane). In
    order:

    - its free fit, if accepted: no kink and no step to the neighbour (below), and, with
      ``hinged_share``, its hinged fit (next) fails or explains fewer than ``hinged_share`` of the
      free fit's inliers,

      .. math::  \\arccos(n_k \\cdot n_{k'}) \\le \\text{max\\_slope\\_change}, \\qquad
                 \\min_{r' \\le r \\le r_k} |z_k(r u) - z_{k'}(r u)| \\le \\text{max\\_step},

      with ``r_k`` the radius of its nearest inlier, ``u`` the direction of its inliers' centroid
      from the centre and ``z(x, y) = -(n_x x + n_y y + d) / n_z`` (the difference is linear in
      ``r``: 0 if it changes sign, else the smaller end). The two planes must meet where the
      ground is not seen, as they do at a change of grade, but not at a raised load or a vehicle's
      lowest scan lines;
    - else its **hinged** fit, if it has ``min_points`` inliers, is no steeper than
      ``max_slope_deg`` and has no kink to the neighbour: the plane through the hinge point
      ``h = (c + r' (cos phi_k, sin phi_k), z_{k'}(...))``, the neighbour's ground where its support
      ends on the sector's axis, with the gradient ``g`` of ``z - z_h = g . ((x, y) - (x_h, y_h))``
      fitted by RANSAC (the neighbour's gradient ``g_0``, and planes through ``h`` and 2 random
      seeds, scored as above) and ridge regression on the inliers,

      .. math::  g = \\Big(\\sum_i d_i d_i^T + m L^2 I\\Big)^{-1}
                     \\Big(\\sum_i v_i d_i + m L^2 g_0\\Big),

      ``d_i, v_i`` the inliers' x-y and height offsets from ``h``, ``m`` their number,
      ``L = hinge_prior_length``. One scan ring's heights fix the slope from ``h`` out to the ring,
      and its extent the slope along it; where the inliers do not reach, the neighbour's slope
      stays;
    - else the neighbour's plane (and its support radius).

    Non-finite rows are ignored. Deterministic given ``config.seed``.
    """
    cfg = CloudConfig() if config is None else config
    pts = _as_points(points_e, "points_e")
    pts = pts[np.isfinite(pts).all(axis=1)]
    return _fit_ground(pts, cfg)[0]


# --------------------------------------------------------------------------------------------------
# the pipeline


@dataclass(frozen=True)
class CloudStats:
    """What each stage of :func:`process_cloud` did to one cloud (counts of points).

    ``kept + ground + below_ground + above_ceiling + low_object + non_finite + ego_body == points_in``;
    ``seen_over`` counts the kept returns seen over a nearer object (``CloudConfig.seen_over_gap``).
    ``segments_fallback`` counts the patches (:class:`GroundModel`) holding finite points whose plane
    was borrowed (their own fits failed or were rejected), ``segments_hinged`` those whose plane is
    their own hinged fit; empty patches are not counted (``GroundModel.fallback`` and ``hinged``
    have them all).
    """

    points_in: int = 0
    non_finite: int = 0
    ego_body: int = 0
    ground: int = 0
    below_ground: int = 0
    above_ceiling: int = 0
    low_object: int = 0
    kept: int = 0
    seen_over: int = 0
    segments_fallback: int = 0
    segments_hinged: int = 0

    def as_dict(self) -> dict[str, int]:
        return {f.name: int(getattr(self, f.name)) for f in fields(self)}


@dataclass(frozen=True, eq=False)
class CloudResult:
    """Everything :func:`process_cloud` computed for one cloud of ``N`` points.

    Per input row (length ``N``, input order): ``points_e`` (N, 3) the points in E (non-finite rows
    as given, transformed); ``finite`` (N,); ``heights`` (N,) the signed height above the patch's
    plane (m, NaN where not finite or on the ego's body); ``ego_body`` (N,) the returns from the ego's
    own box (``CloudConfig.ego_length`` ...); the disjoint masks ``ground``, ``below_ground``,
    ``above_ceiling``, ``low_object``, ``kept`` (all False on non-finite and ego-body rows), and
    ``seen_over`` (N,), the kept returns seen over a nearer object (``CloudConfig.seen_over_gap``).
    ``points_2d`` (M, 2) are the kept points projected onto their plane along its normal, ``(x, y)``
    in E, in input order (``M = kept.sum()``); ``outline_2d`` those of them not seen over anything,
    in the same order: the 2-D points the tracker takes. ``model`` is the fitted
    :class:`GroundModel`, ``stats`` the counts.

    A figure of the pipeline: ``points_e[finite]`` (raw cloud), ``points_e[kept]`` (without ground,
    below-ground, above-ceiling and low-object points), ``points_2d`` (projected), ``model.ground_z``
    (the fitted ground).
    """

    points_e: np.ndarray
    finite: np.ndarray
    ego_body: np.ndarray
    heights: np.ndarray
    ground: np.ndarray
    below_ground: np.ndarray
    above_ceiling: np.ndarray
    low_object: np.ndarray
    kept: np.ndarray
    seen_over: np.ndarray
    points_2d: np.ndarray
    outline_2d: np.ndarray
    model: GroundModel
    stats: CloudStats


def _check_frame(pe: np.ndarray, cfg: CloudConfig) -> None:
    """``ValueError`` when the cloud ``pe`` (N, 3), taken to be in E, has its ground near the lidar
    where the other frame of ``CloudConfig.frame`` would put it (``CloudConfig``'s docstring)."""
    if cfg.mount_z < FRAME_CHECK_MOUNT_Z or len(pe) < FRAME_CHECK_POINTS:
        return
    sample = pe[::max(1, len(pe) // FRAME_CHECK_SAMPLE)]  # a stride through the scan order: every azimuth
    with np.errstate(invalid="ignore"):
        dx, dy = sample[:, 0] - cfg.mount_x, sample[:, 1] - cfg.mount_y
        rho = np.hypot(dx, dy)
        band = (rho >= FRAME_CHECK_BAND[0]) & (rho <= FRAME_CHECK_BAND[1]) & np.isfinite(sample[:, 2])
    near = sample[band, 2]
    if len(near) < FRAME_CHECK_POINTS:
        return
    sector = ((np.arctan2(dy[band], dx[band]) + np.pi) * (FRAME_CHECK_SECTORS / (2.0 * np.pi))).astype(np.int64)
    sector = np.minimum(sector, FRAME_CHECK_SECTORS - 1)
    lows = [near[sector == k].min() for k in range(FRAME_CHECK_SECTORS) if np.count_nonzero(sector == k) >= 3]
    ground = float(np.quantile(lows, FRAME_CHECK_QUANTILE))
    if abs(ground) > 0.5 * cfg.mount_z:
        said = "a lidar's own frame" if cfg.frame == "sensor" else "the vehicle frame E"
        other = "vehicle" if cfg.frame == "sensor" else "sensor"
        raise ValueError(
            f"lidar cloud: CloudConfig.frame = {cfg.frame!r} takes it in {said}, but then the ground "
            f"{FRAME_CHECK_BAND[0]:g}-{FRAME_CHECK_BAND[1]:g} m from the lidar lies at z = {ground:+.2f} m in E, "
            f"not near 0 (mount_z {cfg.mount_z:g} m): is it in the {other} frame? set CloudConfig.frame = {other!r}"
        )


def _stands_on(normal: np.ndarray, offset: float, cfg: CloudConfig) -> bool:
    """Whether the ego, its footprint ``ego_length x ego_width`` about E's origin at z = 0, could
    stand on the plane ``normal . p + offset = 0`` (m): the plane within ``max_step`` of each corner."""
    half = np.array([[0.5 * cfg.ego_length * sx, 0.5 * cfg.ego_width * sy] for sx in (-1, 1) for sy in (-1, 1)])
    return bool(np.all(np.abs(half @ normal[:2] + offset) <= cfg.max_step * abs(normal[2])))


#: The classes of :func:`classify_kernel`, per point.
GROUND, BELOW_GROUND, ABOVE_CEILING, LOW_OBJECT, KEPT = 0, 1, 2, 3, 4


@njit
def classify_kernel(pts, patch, normals, offsets, tau, ceiling, low_height, cell):  # pragma: no cover - compiled
    """Steps 4 and 5 of :func:`process_cloud` in one pass over the points ``pts`` (N, 3) in E of patches
    ``patch`` (N,), whose planes are ``normals`` (P, 3), ``offsets`` (P,): the height above the plane
    ``h = n . p + d``; the class, ``GROUND`` ``|h| <= tau``, ``BELOW_GROUND`` ``h < -tau``,
    ``ABOVE_CEILING`` ``h > ceiling``, else ``KEPT``, and of those ``LOW_OBJECT`` where
    ``low_height >= 0`` (negative: off): no higher than it, and no kept point higher than it in its
    ``cell`` square cell of E (``floor(x / cell)``, ``floor(y / cell)``); and the kept points'
    projections onto their planes along the normals, ``q = p - h n``.
    Returns ``(h (N,), classes (N,) int8, xy (M, 2))``, ``xy`` of the kept points in input order.
    Linear in the points and in the cells over the kept points' extent."""
    n = pts.shape[0]
    h = np.empty(n)
    cls = np.empty(n, dtype=np.int8)
    cx = np.empty(n, dtype=np.int64)  # the kept points' cells
    cy = np.empty(n, dtype=np.int64)
    kept = 0
    lo_x, lo_y, hi_x, hi_y = 0, 0, 0, 0
    for i in range(n):
        k = patch[i]
        v = pts[i, 0] * normals[k, 0]
        v += pts[i, 1] * normals[k, 1]
        v += pts[i, 2] * normals[k, 2]
        v += offsets[k]
        h[i] = v
        if abs(v) <= tau:
            cls[i] = GROUND
        elif v < -tau:
            cls[i] = BELOW_GROUND
        elif v > ceiling:
            cls[i] = ABOVE_CEILING
        else:
            cls[i] = KEPT
            if low_height >= 0.0:
                a = int(math.floor(pts[i, 0] / cell))
                b = int(math.floor(pts[i, 1] / cell))
                cx[i], cy[i] = a, b
                if kept == 0:
                    lo_x, lo_y, hi_x, hi_y = a, b, a, b
                else:
                    lo_x, lo_y = min(lo_x, a), min(lo_y, b)
                    hi_x, hi_y = max(hi_x, a), max(hi_y, b)
            kept += 1
    if low_height >= 0.0 and kept > 0:
        # the cells holding a kept point higher than low_height
        high = np.zeros((hi_x - lo_x + 1, hi_y - lo_y + 1), dtype=np.bool_)
        for i in range(n):
            if cls[i] == KEPT and h[i] > low_height:
                high[cx[i] - lo_x, cy[i] - lo_y] = True
        for i in range(n):
            if cls[i] == KEPT and h[i] <= low_height and not high[cx[i] - lo_x, cy[i] - lo_y]:
                cls[i] = LOW_OBJECT
                kept -= 1
    xy = np.empty((kept, 2))
    j = 0
    for i in range(n):
        if cls[i] == KEPT:
            k = patch[i]
            xy[j, 0] = pts[i, 0] - h[i] * normals[k, 0]
            xy[j, 1] = pts[i, 1] - h[i] * normals[k, 1]
            j += 1
    return h, cls, xy


def _ego_body(pe: np.ndarray, cfg: CloudConfig) -> np.ndarray:
    """Which rows of ``pe`` (N, 3) in E lie in the ego's box grown by ``ego_margin`` (``CloudConfig``);
    none when ``ego_length`` is 0. (A row with an infinite coordinate may pass; the caller masks them.)"""
    if cfg.ego_length <= 0.0 or len(pe) == 0:
        return np.zeros(len(pe), dtype=bool)
    m = cfg.ego_margin
    with np.errstate(invalid="ignore"):
        return ((np.abs(pe[:, 0]) <= 0.5 * cfg.ego_length + m) & (np.abs(pe[:, 1]) <= 0.5 * cfg.ego_width + m)
                & (pe[:, 2] <= cfg.ego_height + m))


def process_cloud(points_sensor: Any, config: CloudConfig | None = None) -> CloudResult:
    """One lidar cloud ``(N, 3)`` in the sensor frame (or, with ``CloudConfig.frame = "vehicle"``, in
    E) through the whole pipeline.

    1. ``p_E = R p_S + t`` (:func:`mount_transform`; none for a cloud in E); the frame checked
       (``CloudConfig``'s docstring);
    2. rows with a non-finite coordinate are dropped (``non_finite``), then the rows inside the ego's
       box (``CloudConfig``: ``|x| <= L/2 + m``, ``|y| <= W/2 + m``, ``z <= H + m`` in E) (``ego_body``);
    3. the ground model is fitted (:func:`fit_ground`) and each point's height above its patch's
       plane computed, ``h = n_k . p + d_k``;
    4. with ``tau = distance_threshold`` and ``c = height_ceiling``: ``|h| <= tau`` is ground,
       ``h < -tau`` below ground, ``h > c`` above the ceiling, ``tau < h <= c`` kept;
    5. the kept points are projected along their plane's normal, ``q = p - h n_k``, and ``(q_x, q_y)``
       returned (``points_2d``; ``outline_2d`` without the returns seen over a nearer object,
       ``CloudConfig.seen_over_gap``, whose azimuth columns come from the ground fit's sort).

    ``ValueError`` when ``points_sensor`` is not an ``(N, 3)`` array of real numbers; ``(0, 3)``
    gives ``(0, 2)`` points and a level ground model.
    """
    cfg = CloudConfig() if config is None else config
    if not isinstance(cfg, CloudConfig):
        raise TypeError(f"config must be a CloudConfig or None; got {type(cfg).__name__}")
    pts_s = _as_points(points_sensor, "points_sensor")
    n = len(pts_s)
    pe = _transform(pts_s, cfg) if cfg.frame == "sensor" else pts_s
    _check_frame(pe, cfg)
    # a row with a NaN or inf has a non-finite sum (the exact test only runs when one is found)
    all_finite = bool(np.isfinite(pe @ np.ones(3)).all())
    finite = np.ones(n, dtype=bool) if all_finite else np.isfinite(pe).all(axis=1)
    body = _ego_body(pe, cfg)
    if not all_finite:
        body &= finite
    has_body = bool(body.any())
    every = all_finite and not has_body  # every row goes on
    use = finite & ~body if has_body else finite
    pts = pe if every else pe[use]
    model, patch, columns = _fit_ground(pts, cfg)
    low = -1.0 if cfg.low_object_height is None else float(cfg.low_object_height)
    h, cls, points_2d = classify_kernel(np.ascontiguousarray(pts, dtype=float), patch, model.normals, model.offsets,
                                        float(cfg.distance_threshold), float(cfg.height_ceiling), low,
                                        float(cfg.low_object_cell))
    ground_f, below_f, above_f = cls == GROUND, cls == BELOW_GROUND, cls == ABOVE_CEILING
    low_f, kept_f = cls == LOW_OBJECT, cls == KEPT
    over_f = _seen_over(pts, kept_f, columns, cfg)
    over_kept = over_f[kept_f]  # per kept point, in input order (as points_2d)

    def full(mask: np.ndarray) -> np.ndarray:
        if every:
            return mask
        out = np.zeros(n, dtype=bool)
        out[use] = mask
        return out

    if every:
        heights = h
    else:
        heights = np.full(n, np.nan)
        heights[use] = h
    occupied = np.zeros(model.n_patches, dtype=bool)
    occupied[patch] = True
    stats = CloudStats(
        points_in=n,
        non_finite=int(n - np.count_nonzero(finite)),
        ego_body=int(np.count_nonzero(body)),
        ground=int(np.count_nonzero(ground_f)),
        below_ground=int(np.count_nonzero(below_f)),
        above_ceiling=int(np.count_nonzero(above_f)),
        low_object=int(np.count_nonzero(low_f)),
        kept=int(np.count_nonzero(kept_f)),
        seen_over=int(np.count_nonzero(over_kept)),
        segments_fallback=int(np.count_nonzero(model.fallback & occupied)),
        segments_hinged=int(np.count_nonzero(model.hinged & occupied)),
    )
    return CloudResult(points_e=pe, finite=finite, ego_body=body, heights=heights, ground=full(ground_f),
                       below_ground=full(below_f), above_ceiling=full(above_f), low_object=full(low_f), kept=full(kept_f),
                       seen_over=full(over_f), points_2d=points_2d,
                       outline_2d=points_2d[~over_kept] if over_kept.any() else points_2d, model=model, stats=stats)


def to_ground_plane(points_sensor: Any, config: CloudConfig | None = None) -> tuple[np.ndarray, CloudStats]:
    """The 2-D points ``(M, 2)`` (``x, y`` in E, m) of a lidar cloud ``(N, 3)`` in the sensor frame,
    with ground, below-ground, above-ceiling and non-finite points removed, and the counts.

    The kept points are projected onto the fitted road plane along its normal (see
    :func:`process_cloud`, which also returns the masks and the ground model).
    """
    result = process_cloud(points_sensor, config)
    return result.points_2d, result.stats

