"""Tests of tracker/cloud.py (3-D lidar preprocessing) on synthetic VLP-16 scans.

The scans are made here: the 16 beams of a VLP-16 (-15 to +15 deg every 2 deg) at a set of
azimuths, from the mount in E, intersected with the ground and with boxes standing on it (their axes
aligned with the local ground plane, as a car on a sloped road); the nearest hit of each ray within
100 m is its return, with Gaussian range noise. The ground is either piecewise planar (a list of
planes ``z = a x + b y + c``, each valid over an x interval; intersected analytically) or a road
surface as ``sim.world.ground.RoadGround`` models it (a road through the origin heading +x, straight or on
a circle, climbing ``grade`` along it, banked ``bank`` across it, the terrain beside level across
the road; intersected by marching along each ray and bisecting).
"""

from __future__ import annotations

import math
import dataclasses
from dataclasses import dataclass

import numpy as np
import pytest

from tracker.cloud import (CloudConfig, CloudStats, GroundModel, fit_ground, mount_rotation,
                           mount_transform, process_cloud, to_ground_plane)

MAX_RANGE = 100.0  # m, the VLP-16's


@dataclass(frozen=True)
class Piece:
    """Ground plane ``z = a x + b y + c`` (E, m) over ``x_lo < x <= x_hi``."""

    a: float
    b: float
    c: float
    x_lo: float = -math.inf
    x_hi: float = math.inf

    def z(self, x, y):
        return self.a * x + self.b * y + self.c


@dataclass(frozen=True)
class Box:
    """A vehicle: footprint centre ``(x, y)`` on the ground, heading ``yaw`` (rad, in the x-y plane),
    ``length x width``, body between ``bottom`` and ``top`` (m above the ground, along its normal)."""

    x: float
    y: float
    yaw: float
    length: float
    width: float
    bottom: float
    top: float


def car(x, y, yaw=0.0):
    return Box(x, y, yaw, 4.8, 2.0, 0.3, 1.5)


def truck(x, y, yaw=0.0):
    return Box(x, y, yaw, 12.0, 2.5, 0.5, 3.5)


def ground_at(pieces, x, y):
    for p in pieces:
        if p.x_lo < x <= p.x_hi:
            return p
    raise AssertionError("no ground piece at x")


def box_frame(box, pieces):
    """Origin (on the ground under the centre) and axes (rows u, v, w) of a box: w the ground normal,
    u the heading projected on the ground plane, v = w x u."""
    p = ground_at(pieces, box.x, box.y)
    w = np.array([-p.a, -p.b, 1.0])
    w /= np.linalg.norm(w)
    h = np.array([math.cos(box.yaw), math.sin(box.yaw), 0.0])
    u = h - (h @ w) * w
    u /= np.linalg.norm(u)
    v = np.cross(w, u)
    return np.array([box.x, box.y, p.z(box.x, box.y)]), np.array([u, v, w])


def footprint_xy(box, pieces):
    """Corners (4, 2) of the box's footprint on the ground, x-y in E, in order around it."""
    origin, axes = box_frame(box, pieces)
    corners = [origin + sl * box.length / 2 * axes[0] + sw * box.width / 2 * axes[1]
               for sl, sw in ((1, 1), (-1, 1), (-1, -1), (1, -1))]
    return np.array(corners)[:, :2]


def vlp16_directions(az_step_deg=0.2):
    """Unit ray directions (K, 3) in the sensor frame: 16 beams x azimuths."""
    elev = np.radians(np.arange(-15.0, 16.0, 2.0))
    az = np.radians(np.arange(0.0, 360.0, az_step_deg))
    e, a = np.meshgrid(elev, az, indexing="ij")
    return np.stack([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)], axis=-1).reshape(-1, 3)


def hit_boxes(boxes, pieces_of, origin, dirs, best_t, label, face):
    """Nearest hits of the rays ``origin + t dirs`` with the boxes (slab method in each box's frame),
    where nearer than ``best_t``; ``pieces_of(box)`` is the ground the box stands on. Updates
    ``best_t``, ``label`` (k + 1 for box k) and ``face`` in place."""
    with np.errstate(divide="ignore", invalid="ignore"):
        for i, box in enumerate(boxes):
            o, axes = box_frame(box, pieces_of(box))
            lo = np.array([-box.length / 2, -box.width / 2, box.bottom])
            hi = np.array([box.length / 2, box.width / 2, box.top])
            ol = axes @ (origin - o)
            dl = dirs @ axes.T
            t1 = (lo - ol) / dl
            t2 = (hi - ol) / dl
            near = np.minimum(t1, t2)
            t_near = near.max(axis=1)
            t_far = np.maximum(t1, t2).min(axis=1)
            hit = (t_near <= t_far) & (t_near > 0) & (t_near < best_t)
            best_t[hit], label[hit], face[hit] = t_near[hit], i + 1, near.argmax(axis=1)[hit]


def returns(best_t, label, face, origin, dirs, rot, noise, seed):
    """The returns within range, with range noise: points (M, 3) in the sensor frame, labels, faces."""
    ok = best_t <= MAX_RANGE
    rng = np.random.default_rng(seed)
    r = best_t[ok] + (rng.normal(0.0, noise, ok.sum()) if noise > 0 else 0.0)
    points_e = origin + r[:, None] * dirs[ok]
    points_s = (points_e - origin) @ rot  # p_S = R^T (p_E - t)
    return points_s, label[ok], face[ok]


def scan(pieces, boxes=(), config=None, noise=0.03, seed=0, az_step_deg=0.2):
    """A synthetic scan: points (M, 3) in the sensor frame, labels (M,) (0 ground, k + 1 box k) and
    the face hit (M,) (box axis 0/1 sides, 2 roof; -1 ground)."""
    cfg = CloudConfig() if config is None else config
    rot = mount_rotation(math.radians(cfg.mount_roll_deg), math.radians(cfg.mount_pitch_deg),
                         math.radians(cfg.mount_yaw_deg))
    origin = cfg.mount_translation
    dirs = vlp16_directions(az_step_deg) @ rot.T  # in E
    k = len(dirs)
    best_t = np.full(k, np.inf)
    label = np.full(k, -1)
    face = np.full(k, -1)
    with np.errstate(divide="ignore", invalid="ignore"):
        for p in pieces:  # first crossing of the height field: the nearest valid piece hit
            den = dirs[:, 2] - p.a * dirs[:, 0] - p.b * dirs[:, 1]
            t = (p.z(origin[0], origin[1]) - origin[2]) / den
            x = origin[0] + t * dirs[:, 0]
            hit = (t > 0) & (x > p.x_lo) & (x <= p.x_hi) & (t < best_t)
            best_t[hit], label[hit], face[hit] = t[hit], 0, -1
    hit_boxes(boxes, lambda box: pieces, origin, dirs, best_t, label, face)
    return returns(best_t, label, face, origin, dirs, rot, noise, seed)


@dataclass(frozen=True)
class RoadSurface:
    """The ground of ``sim.world.ground.RoadGround`` for a road through the origin heading +x: straight, or
    on a circle of radius ``radius`` (m) turning left (centre ``(0, radius)``; negative: turning
    right). With ``(s, n)`` the arc length along the centreline and the offset to its left (m),
    ``h(s, n) = grade * s + bank * clip(n, -half_width, half_width)``: the road climbs ``grade``, is
    banked ``bank`` (up to the left), and beside it the terrain is level across the road (the edge's
    height) and climbs with it."""

    grade: float = 0.0
    bank: float = 0.0
    radius: float = math.inf
    half_width: float = 5.25  # 3 lanes of 3.5 m

    def frenet(self, x, y):
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        if math.isinf(self.radius):
            return x, y
        sign = 1.0 if self.radius > 0 else -1.0  # turning right: the mirror image
        r = abs(self.radius)
        dx, dy = x, sign * y - r
        return r * np.arctan2(dx, -dy), sign * (r - np.hypot(dx, dy))

    def height(self, x, y):
        s, n = self.frenet(x, y)
        return self.grade * s + self.bank * np.clip(n, -self.half_width, self.half_width)

    def tangent_plane(self, x, y):
        """The plane touching the surface at ``(x, y)``, as one :class:`Piece`."""
        e = 0.5
        a = float(self.height(x + e, y) - self.height(x - e, y)) / (2 * e)
        b = float(self.height(x, y + e) - self.height(x, y - e)) / (2 * e)
        return (Piece(a, b, float(self.height(x, y)) - a * x - b * y),)


def scan_road(surface, boxes=(), config=None, noise=0.03, seed=0, az_step_deg=0.2, step=0.5):
    """A synthetic scan (as :func:`scan`) over a :class:`RoadSurface`: each ray marches in ``step``
    (m) along its range to the first point under the surface, then 40 bisections."""
    cfg = CloudConfig() if config is None else config
    rot = mount_rotation(math.radians(cfg.mount_roll_deg), math.radians(cfg.mount_pitch_deg),
                         math.radians(cfg.mount_yaw_deg))
    origin = cfg.mount_translation
    dirs = vlp16_directions(az_step_deg) @ rot.T  # in E
    best_t = np.full(len(dirs), np.inf)
    live = np.flatnonzero(dirs[:, 2] < 0.15)  # steeper rays never meet these grades within range
    for t in np.arange(step, MAX_RANGE + step, step):
        p = origin + t * dirs[live]
        under = p[:, 2] <= surface.height(p[:, 0], p[:, 1])
        if under.any():
            idx = live[under]
            lo, hi = np.full(len(idx), t - step), np.full(len(idx), t)
            for _ in range(40):
                mid = 0.5 * (lo + hi)
                q = origin + mid[:, None] * dirs[idx]
                below = q[:, 2] <= surface.height(q[:, 0], q[:, 1])
                hi, lo = np.where(below, mid, hi), np.where(below, lo, mid)
            best_t[idx] = hi
            live = live[~under]
    label = np.where(np.isfinite(best_t), 0, -1)
    face = np.full(len(dirs), -1)
    hit_boxes(boxes, lambda box: surface.tangent_plane(box.x, box.y), origin, dirs, best_t, label, face)
    return returns(best_t, label, face, origin, dirs, rot, noise, seed)


# the scenes
TILTED = (Piece(0.04, 0.03, 0.0),)  # 4 % grade along x, 3 % bank along y


def piecewise(kink=15.0, grade=0.06):
    """Level up to x = kink, then rising at ``grade``."""
    return (Piece(0.0, 0.0, 0.0, x_hi=kink), Piece(grade, 0.0, -grade * kink, x_lo=kink))


TRAFFIC = (car(12.0, 0.0), car(-14.0, 3.5), car(30.0, -3.5, 0.05), car(4.0, 5.0, 0.1), truck(-4.0, -6.0),
           car(45.0, 3.5, -0.05))


def removal_rates(result, labels):
    """(fraction of ground returns removed, fraction of vehicle returns kept)."""
    ground = labels == 0
    return float(np.mean(~result.kept[ground])), float(np.mean(result.kept[~ground]))


def boundary_distance(points, quad):
    """Distance (M,) of 2-D points to the boundary of the polygon ``quad`` (4, 2)."""
    d = np.full(len(points), np.inf)
    for a, b in zip(quad, np.roll(quad, -1, axis=0)):
        ab = b - a
        t = np.clip((points - a) @ ab / (ab @ ab), 0.0, 1.0)
        d = np.minimum(d, np.linalg.norm(points - (a + t[:, None] * ab), axis=1))
    return d


def inside(points, quad, tol=0.0):
    """Whether 2-D points lie inside the convex polygon ``quad`` (counter-clockwise), within ``tol``."""
    ok = np.ones(len(points), dtype=bool)
    for a, b in zip(quad, np.roll(quad, -1, axis=0)):
        ab = b - a
        cross = ab[0] * (points[:, 1] - a[1]) - ab[1] * (points[:, 0] - a[0])
        ok &= cross / np.linalg.norm(ab) >= -tol
    return ok


# --------------------------------------------------------------------------------------------------
# configuration and mount


def test_config_defaults():
    cfg = CloudConfig()
    assert (cfg.mount_x, cfg.mount_y, cfg.mount_z) == (0.0, 0.0, 1.9)
    assert cfg.ring_edges == (10.0, 14.0, 19.0, 27.0, 40.0, 55.0, 70.0, 85.0)
    assert cfg.ring_sectors == (16,) * 8  # one count for all rings becomes one per ring
    assert 0.15 <= cfg.distance_threshold <= 0.2
    # lists become tuples
    assert CloudConfig(ring_edges=[5, 10], ring_sectors=[8, 12]).ring_edges == (5.0, 10.0)
    assert CloudConfig(ring_edges=[5, 10], ring_sectors=[8, 12]).ring_sectors == (8, 12)
    assert CloudConfig(ring_edges=()).ring_sectors == ()  # one plane for the whole cloud


@pytest.mark.parametrize("kwargs, field", [
    (dict(distance_threshold=-1), "distance_threshold"),
    (dict(distance_threshold=0.0), "distance_threshold"),
    (dict(mount_z=float("nan")), "mount_z"),
    (dict(mount_pitch_deg="2"), "mount_pitch_deg"),
    (dict(ring_edges=(20.0, 10.0)), "ring_edges"),
    (dict(ring_edges=(10.0, 10.0)), "ring_edges"),
    (dict(ring_edges=(0.0, 10.0)), "ring_edges"),
    (dict(ring_edges=(10.0, float("inf"))), "ring_edges"),
    (dict(ring_edges=5.0), "ring_edges"),
    (dict(ring_sectors=(16, 16)), "ring_sectors"),
    (dict(ring_sectors=0), "ring_sectors"),
    (dict(ring_sectors=2.5), "ring_sectors"),
    (dict(ring_sectors=True), "ring_sectors"),
    (dict(ring_edges=(10.0, 20.0), ring_sectors=(8, 0)), "ring_sectors"),
    (dict(seed_fraction=0.0), "seed_fraction"),
    (dict(seed_fraction=1.5), "seed_fraction"),
    (dict(seed_height=0.0), "seed_height"),
    (dict(ransac_iterations=0), "ransac_iterations"),
    (dict(ransac_iterations=6.0), "ransac_iterations"),
    (dict(refine_iterations=-1), "refine_iterations"),
    (dict(max_slope_deg=90.0), "max_slope_deg"),
    (dict(min_spread=-0.1), "min_spread"),
    (dict(max_step=0.0), "max_step"),
    (dict(max_slope_change_deg=0.0), "max_slope_change_deg"),
    (dict(hinge_prior_length=0.0), "hinge_prior_length"),
    (dict(column_width_deg=0.0), "column_width_deg"),
    (dict(min_points=2), "min_points"),
    (dict(max_fit_points=10), "max_fit_points"),
    (dict(height_ceiling=0.1), "height_ceiling"),
    (dict(seed=-1), "seed"),
    (dict(seed=True), "seed"),
    (dict(frame="lidar"), "frame"),
])
def test_config_rejects_bad_values_by_name(kwargs, field):
    with pytest.raises(ValueError, match=f"CloudConfig.{field}"):
        CloudConfig(**kwargs)


def test_mount_rotation_conventions():
    deg = math.radians
    np.testing.assert_allclose(mount_rotation(0, 0, deg(90)) @ [1, 0, 0], [0, 1, 0], atol=1e-15)  # yaw left
    p = deg(10)
    np.testing.assert_allclose(mount_rotation(0, p, 0) @ [1, 0, 0], [math.cos(p), 0, -math.sin(p)], atol=1e-15)
    np.testing.assert_allclose(mount_rotation(p, 0, 0) @ [0, 1, 0], [0, math.cos(p), math.sin(p)], atol=1e-15)
    r = mount_rotation(0.1, -0.2, 2.5)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-14)
    assert np.linalg.det(r) == pytest.approx(1.0)
    # intrinsic z-y'-x'': yaw first, then pitch about the yawed y axis
    np.testing.assert_allclose(r, mount_rotation(0, 0, 2.5) @ mount_rotation(0, -0.2, 0) @ mount_rotation(0.1, 0, 0))


def test_mount_transform_round_trip():
    cfg = CloudConfig(mount_x=1.0, mount_y=-0.2, mount_z=1.7, mount_roll_deg=1.0, mount_pitch_deg=2.0,
                      mount_yaw_deg=5.0)
    rng = np.random.default_rng(1)
    points_e = rng.uniform(-50, 50, size=(500, 3))
    rot = mount_rotation(math.radians(1.0), math.radians(2.0), math.radians(5.0))
    points_s = (points_e - [1.0, -0.2, 1.7]) @ rot  # p_S = R^T (p_E - t)
    np.testing.assert_allclose(mount_transform(points_s, cfg), points_e, atol=1e-12)
    # the default mount only lifts by 1.9 m
    np.testing.assert_allclose(mount_transform(points_s), points_s + [0, 0, 1.9], atol=1e-12)
    # a point straight ahead of a sensor pitched down 2 deg is below the sensor in E
    ahead = mount_transform([[10.0, 0.0, 0.0]], CloudConfig(mount_pitch_deg=2.0))
    assert ahead[0, 2] == pytest.approx(1.9 - 10 * math.sin(math.radians(2.0)))


# --------------------------------------------------------------------------------------------------
# ground removal on synthetic scans


def test_ground_removal_on_graded_banked_road():
    points, labels, _ = scan(TILTED, TRAFFIC)
    assert len(points) > 15_000 and (labels > 0).sum() > 5_000
    res = process_cloud(points)
    removed, kept = removal_rates(res, labels)
    assert removed >= 0.99 and kept >= 0.99
    # every fitted plane is the road's: normal (-0.04, -0.03, 1)/|.| through the origin
    truth = np.array([-0.04, -0.03, 1.0]) / math.hypot(0.04, 0.03, 1.0)
    own = ~res.model.fallback
    assert own.sum() >= 10
    angle = np.degrees(np.arccos(np.clip(res.model.normals[own] @ truth, -1, 1)))
    assert angle.max() < 0.3
    x = np.array([-45.0, -5.0, 5.0, 45.0])
    np.testing.assert_allclose(res.model.ground_z(x, 2.0), 0.04 * x + 0.03 * 2.0, atol=0.05)


@pytest.mark.parametrize("grade, bank", [(0.0, 0.08), (-0.06, 0.10)])
def test_ground_removal_on_steep_banks(grade, bank):
    pieces = (Piece(grade, bank, 0.0),)
    points, labels, _ = scan(pieces, TRAFFIC, az_step_deg=0.4)
    removed, kept = removal_rates(process_cloud(points), labels)
    assert removed >= 0.99 and kept >= 0.99


def test_ground_removal_on_changing_grade_needs_patches():
    pieces = piecewise(kink=15.0, grade=0.06)  # level, then rising 6 % from x = 15 m (inside a ring)
    points, labels, _ = scan(pieces, TRAFFIC)
    removed, kept = removal_rates(process_cloud(points), labels)
    assert removed >= 0.99 and kept >= 0.99
    # one plane for the whole cloud: the rising road ahead is left in as obstacles
    single = process_cloud(points, CloudConfig(ring_edges=()))
    removed_single, kept_single = removal_rates(single, labels)
    assert removed_single < 0.9
    assert kept_single >= 0.99


def test_ground_removal_with_a_pitched_yawed_mount():
    cfg = CloudConfig(mount_x=1.0, mount_pitch_deg=2.0, mount_yaw_deg=5.0)
    points, labels, faces = scan(TILTED, TRAFFIC, config=cfg, noise=0.0, az_step_deg=0.4)  # in the sensor frame
    res = process_cloud(points, cfg)
    removed, kept = removal_rates(res, labels)
    assert removed >= 0.99 and kept >= 0.99
    # the 2-D points are in E: on the footprints with the mount applied, 1 m and 5 deg off without it
    wrong = process_cloud(points, CloudConfig())
    for k, box in enumerate(TRAFFIC[:5]):
        quad = footprint_xy(box, TILTED)
        side = (labels == k + 1) & (faces != 2)
        assert boundary_distance(res.points_2d[side[res.kept]], quad).max() < 0.05
        assert boundary_distance(wrong.points_2d[side[wrong.kept]], quad).max() > 0.5


def test_a_cloud_in_the_vehicle_frame_merged_from_two_lidars():
    """``CloudConfig.frame = "vehicle"``: a cloud already in E (two lidars' clouds, each moved by its
    own mount, merged) gives the same result as each cloud through its own sensor-frame mount, point
    for point; a cloud in the other frame than the config says is refused with a line that names it."""
    roof = CloudConfig(mount_x=1.0, mount_pitch_deg=2.0, mount_yaw_deg=5.0)
    high = CloudConfig(mount_x=1.0, mount_z=2.3)
    a, labels_a, faces_a = scan(TILTED, TRAFFIC, config=roof, noise=0.0, az_step_deg=0.4)
    b, labels_b, faces_b = scan(TILTED, TRAFFIC, config=high, noise=0.0, az_step_deg=0.4)
    merged = np.concatenate([mount_transform(a, roof), mount_transform(b, high)])
    vehicle = CloudConfig(frame="vehicle", mount_x=1.0)
    res = process_cloud(merged, vehicle)
    np.testing.assert_array_equal(res.points_e, merged)
    removed, kept = removal_rates(res, np.concatenate([labels_a, labels_b]))
    assert removed >= 0.99 and kept >= 0.99
    sides = np.concatenate([faces_a, faces_b]) != 2  # not the roofs
    for k, box in enumerate(TRAFFIC[:5]):  # the 2-D points of both lidars on the footprints in E
        quad = footprint_xy(box, TILTED)
        on = (np.concatenate([labels_a, labels_b]) == k + 1) & sides
        assert boundary_distance(res.points_2d[on[res.kept]], quad).max() < 0.05
    one = process_cloud(mount_transform(a, roof), dataclasses.replace(vehicle, mount_pitch_deg=2.0, mount_yaw_deg=5.0))
    np.testing.assert_array_equal(one.kept, process_cloud(a, roof).kept)  # E given, or made from S: the same
    with pytest.raises(ValueError, match=r"CloudConfig.frame = 'vehicle' .* is it in the sensor frame\?"):
        process_cloud(a, vehicle)
    with pytest.raises(ValueError, match=r"CloudConfig.frame = 'sensor' .* is it in the vehicle frame\?"):
        process_cloud(merged, roof)


def test_frame_check_takes_a_truck_alongside_for_what_it_is():
    """A cloud in the lidar's frame whose ground rings 3-8 m out show only to the left (the ego's body
    hides them ahead and behind, a truck alongside on the whole right, its face's lowest return 1.0 m
    up, above its wheels) passes the frame check; the same cloud given as one in E (the ground then
    1.9 m down) is refused."""
    az = np.radians(np.arange(45.0, 135.0, 0.4))  # the left side's ground
    ground = np.concatenate([np.column_stack([r * np.cos(az), r * np.sin(az), np.zeros_like(az)]) for r in (4.1, 6.8)])
    tx = np.linspace(-20.0, 20.0, 800)  # the truck 3 m to the right
    face = np.concatenate([np.column_stack([tx, np.full(800, -3.0), np.full(800, z)]) for z in (1.0, 1.6, 2.4, 3.2)])
    cloud = np.vstack([ground, face]) - [0.0, 0.0, 1.9]
    res = process_cloud(cloud)  # the median of the sectors' lowest returns would say 1.0 m: "in E?"
    assert res.ground[: len(ground)].all() and res.kept[len(ground):].all()
    with pytest.raises(ValueError, match=r"CloudConfig.frame = 'vehicle' .* is it in the sensor frame\?"):
        process_cloud(cloud, CloudConfig(frame="vehicle"))


def test_projected_points_lie_on_the_footprints():
    points, labels, faces = scan(TILTED, TRAFFIC, noise=0.0)
    res = process_cloud(points)
    kept_labels, kept_faces = labels[res.kept], faces[res.kept]
    for k, box in enumerate(TRAFFIC):
        quad = footprint_xy(box, TILTED)
        mine = kept_labels == k + 1
        assert mine.sum() > 10
        xy = res.points_2d[mine]
        assert inside(xy, quad, tol=0.02).all()
        side = kept_faces[mine] != 2  # side and end faces; roof returns project inside the footprint
        assert boundary_distance(xy[side], quad).max() < 0.05


def test_projected_points_with_range_noise():
    points, labels, faces = scan(TILTED, TRAFFIC, noise=0.03, seed=3)
    res = process_cloud(points)
    kept_labels, kept_faces = labels[res.kept], faces[res.kept]
    d = np.concatenate([boundary_distance(res.points_2d[(kept_labels == k + 1) & (kept_faces != 2)],
                                          footprint_xy(box, TILTED)) for k, box in enumerate(TRAFFIC)])
    assert len(d) > 5000
    # the 3 cm range noise, seen across the faces (at most all of it for a face hit head-on)
    assert math.sqrt(np.mean(d ** 2)) < 0.035
    assert np.mean(d < 0.05) > 0.85
    assert d.max() < 0.15


ROAD_TRAFFIC = (car(20.0, 0.0), car(35.0, 3.5, 0.15), truck(-18.0, -3.5), car(-30.0, 0.0))


def road_rates(result, labels, points_e, surface, far=60.0):
    """Fractions of the ground returns removed (all; on the road, +-0.5 m; beyond ``far`` m) and of
    the vehicle returns kept."""
    ground = labels == 0
    _, n = surface.frenet(points_e[:, 0], points_e[:, 1])
    on_road = np.abs(n) <= surface.half_width + 0.5
    beyond = np.hypot(points_e[:, 0], points_e[:, 1]) > far
    removed = ~result.kept
    return (float(removed[ground].mean()), float(removed[ground & on_road].mean()),
            float(removed[ground & beyond].mean()), float(result.kept[labels > 0].mean()))


@pytest.mark.parametrize("bank", [0.0, 0.03])
def test_a_far_ring_on_a_climbing_curve(bank):
    # the hill of scenarios/hill-vlp16.toml: a road climbing 4 % through a left-hand bend of 200 m
    # radius (banked 3 % or not), the terrain beside it climbing with it. Level ground leaves a VLP-16
    # no ground beyond ~36 m; this one meets its upper beams again 60-100 m out, one ring per patch,
    # where the grade has turned with the road. (The x-segment version of this module, which let a
    # lone far ring borrow its inner neighbour's plane extrapolated over the gap, removed 98.7 and
    # 93.5 % of these ground returns and 72 and 33 % of those beyond 60 m.)
    surface = RoadSurface(grade=0.04, bank=bank, radius=200.0)
    points, labels, _ = scan_road(surface, ROAD_TRAFFIC)
    res = process_cloud(points)
    pe = res.points_e
    far = (labels == 0) & (np.hypot(pe[:, 0], pe[:, 1]) > 60.0)
    assert far.sum() > 500 and (points[far, 2] > 0.0).sum() > 200  # many from the +1 deg beam and above
    removed, on_road, beyond, kept = road_rates(res, labels, pe, surface)
    assert removed >= 0.995 and on_road == 1.0 and beyond >= 0.9 and kept == 1.0
    # the far ground has planes of its own, hinged on the ground inside
    assert res.model.hinged[res.model.patch_of(pe[far])].mean() > 0.5


@pytest.mark.parametrize("bank", [0.03, 0.06])
def test_a_banked_road_with_level_verges(bank):
    # a straight level road of 3 lanes banked up to the left; beside it the terrain is level, so
    # right of the road it is above the road's plane and left of it below, by the bank times the
    # distance from the edge: 0.75 m for 6 % 12.5 m off the edge. (The x-segment version removed 97.7
    # and 89.7 % of these ground returns.)
    surface = RoadSurface(bank=bank)
    points, labels, _ = scan_road(surface, ROAD_TRAFFIC)
    res = process_cloud(points)
    removed, on_road, _, kept = road_rates(res, labels, res.points_e, surface)
    assert removed >= 0.999 and on_road == 1.0 and kept == 1.0
    # with one plane for all the verges stay in. One plane per ring all round (no sectors) keeps
    # them where every free fit that passes is taken; hinged planes (hinged_share) follow them
    if bank == 0.06:
        def rates(**fields):
            return road_rates(process_cloud(points, CloudConfig(**fields)), labels, res.points_e, surface)
        assert rates(ring_edges=())[0] < 0.95
        assert rates(ring_sectors=1, hinged_share=None)[0] < 0.97
        assert rates(ring_sectors=1)[0] >= 0.999


def test_a_vehicles_lowest_scan_line_is_not_a_far_ring():
    # ground out to 19.5 m, then nothing but a vehicle's rear 27.6 m ahead, 6 m wide, seen by two
    # beams (0.3 and 1.2 m up, one return each per 0.2 deg column): its lowest line is as flat as a
    # ground ring and 2 deg above the ground's plane from where that ends
    rng = np.random.default_rng(9)
    ground = np.column_stack([rng.uniform(-20, 20, 5000), rng.uniform(-20, 20, 5000), rng.normal(0, 0.01, 5000)])
    ground = ground[np.hypot(ground[:, 0], ground[:, 1]) < 19.5]
    az = np.radians(np.arange(-12.0, 12.01, 0.2))
    az = az[np.abs(27.6 * np.tan(az)) <= 3.0]
    rear = np.concatenate([np.column_stack([27.6 + rng.normal(0, 0.03, len(az)), 27.6 * np.tan(az),
                                            np.full(len(az), z)]) for z in (0.3, 1.2)])
    cloud = np.vstack([ground, rear]) - [0, 0, 1.9]
    res = process_cloud(cloud)
    assert res.kept[len(ground):].all() and not res.kept[:len(ground)].any()
    patch = res.model.patch_of(res.points_e[len(ground):])
    assert (patch == patch[0]).all() and res.model.fallback[patch[0]]
    # the lowest line has a return right above it in its azimuth column: it takes no part in the
    # fits. Without that test (columns too narrow to hold two returns) it is a hinged "ground"
    blind = process_cloud(cloud, CloudConfig(column_width_deg=1e-6))
    assert not blind.kept[len(ground):len(ground) + len(az)].any() and blind.model.hinged[patch[0]]


# --------------------------------------------------------------------------------------------------
# the ground model


def test_fit_ground_recovers_an_exact_plane_and_the_model_math():
    x, y = np.meshgrid(np.linspace(-60, 60, 121), np.linspace(-20, 20, 41))
    x, y = x.ravel(), y.ravel()
    ground = np.column_stack([x, y, 0.04 * x + 0.03 * y - 0.1])
    model = fit_ground(ground)
    assert model.n_patches == 1 + 8 * 16
    fitted = model.point_counts >= 30
    # a hinged plane through the ground inside explains as many points as a free one: it is taken
    assert fitted.sum() >= 40 and not model.fallback[fitted].any() and model.hinged[fitted][1:].all()
    free = fit_ground(ground, CloudConfig(hinged_share=None))
    assert not free.fallback[fitted].any() and not free.hinged.any()
    np.testing.assert_allclose(free.normals, model.normals, atol=1e-9)
    truth = np.array([-0.04, -0.03, 1.0]) / math.hypot(0.04, 0.03, 1.0)
    # every plane is the one plane (borrowed ones too, from the patches inside)
    np.testing.assert_allclose(model.normals, np.tile(truth, (model.n_patches, 1)), atol=1e-9)
    np.testing.assert_allclose(model.offsets, 0.1 * truth[2], atol=1e-9)
    np.testing.assert_allclose(model.slopes_deg, math.degrees(math.atan(0.05)), atol=1e-6)
    # heights along the normal, and projection back onto the plane
    lifted = ground + np.linspace(-1.0, 3.0, len(ground))[:, None] * truth
    np.testing.assert_allclose(model.height(lifted), np.linspace(-1.0, 3.0, len(ground)), atol=1e-9)
    np.testing.assert_allclose(model.project(lifted), ground, atol=1e-9)
    np.testing.assert_allclose(model.ground_z(x, y), ground[:, 2], atol=1e-9)


def test_the_patch_layout():
    model = GroundModel.level((10.0, 14.0, 19.0), (1, 16, 16, 8))
    assert model.n_patches == 41 and model.ring_starts.tolist() == [0, 1, 17, 33]
    # the disc rho <= 10, then ring by ring; sector 0 centred straight ahead, counter-clockwise
    points = [[5, 0, 0], [10, 0, 0], [10.01, 0, 0], [12, 0, 0], [0, 12, 0], [12, 3.0, 0], [12, -3.0, 0],
              [-12, -0.1, 0], [-12, 0.1, 0], [0, -16, 0], [100, 0, 0], [-100, 0, 0]]
    assert model.patch_of(points).tolist() == [0, 0, 1, 1, 5, 2, 16, 9, 9, 29, 33, 37]
    # centred on the sensor
    moved = GroundModel.level((10.0,), (1, 4), centre=(2.0, 0.0))
    assert moved.patch_of([[11.5, 0, 0], [12.5, 0, 0], [2.0, 10.5, 0]]).tolist() == [0, 1, 2]
    with pytest.raises(ValueError, match="sectors"):
        GroundModel.level((10.0,), (2, 4))  # the disc is one patch


def test_patches_without_ground_borrow_their_inner_neighbours_plane():
    rng = np.random.default_rng(2)
    ground = np.column_stack([rng.uniform(-48, 48, 4000), rng.uniform(-15, 15, 4000), np.zeros(4000)])
    wall = np.column_stack([np.full(300, 60.0), rng.uniform(-5, 5, 300), rng.uniform(0.0, 3.0, 300)])
    ramp_x = rng.uniform(-62, -56, 300)  # a 30 deg embankment behind
    ramp = np.column_stack([ramp_x, rng.uniform(-5, 5, 300), np.tan(math.radians(30)) * (-56 - ramp_x)])
    cloud = np.vstack([ground, wall, ramp])
    model = fit_ground(cloud)
    # ring 6 (55-70 m): the wall straight ahead (sector 0), the embankment behind (sector 8); ring 5
    # (40-55 m) holds ground in both directions
    ahead, behind = model.ring_starts[6], model.ring_starts[6] + 8
    assert model.patch_of(wall).tolist() == [ahead] * 300 and model.patch_of(ramp).tolist() == [behind] * 300
    inner = [model.ring_starts[5], model.ring_starts[5] + 8]
    assert not model.fallback[inner].any()
    assert model.fallback[[ahead, behind]].all() and model.source[[ahead, behind]].tolist() == inner
    np.testing.assert_allclose(model.normals[[ahead, behind]], [[0, 0, 1], [0, 0, 1]], atol=1e-9)
    # a steeper max_slope_deg (and room for the kink) accepts the embankment; the wall stays rejected
    steep = fit_ground(cloud, CloudConfig(max_slope_deg=45.0, max_step=2.0, max_slope_change_deg=45.0))
    assert not steep.fallback[behind] and steep.slopes_deg[behind] == pytest.approx(30.0, abs=0.01)
    assert steep.fallback[ahead]
    _, stats = to_ground_plane(cloud - [0, 0, 1.9])
    assert stats.segments_fallback == int((model.fallback & (model.point_counts > 0)).sum()) >= 2
    # nothing but a wall: the level plane z = 0, from no patch
    only_wall = fit_ground(wall)
    assert only_wall.fallback.all() and (only_wall.source == -1).all()
    np.testing.assert_allclose(only_wall.normals, np.tile([0, 0, 1.0], (129, 1)))


def test_a_raised_flat_patch_is_not_ground():
    # the patch 40-55 m ahead holds no ground, only a flat load 0.8 m up (a flat-bed trailer seen from above)
    rng = np.random.default_rng(4)
    ground = np.column_stack([rng.uniform(-40, 40, 4000), rng.uniform(-15, 15, 4000), rng.normal(0, 0.01, 4000)])
    patch = np.column_stack([rng.uniform(41, 49, 400), rng.uniform(-3, 3, 400), np.full(400, 0.8)])
    cloud = np.vstack([ground, patch]) - [0, 0, 1.9]
    res = process_cloud(cloud)
    k, inner = res.model.ring_starts[5], res.model.ring_starts[4]
    assert (res.model.patch_of(res.points_e[len(ground):]) == k).all()
    assert res.model.fallback[k] and res.model.source[k] == inner
    assert res.kept[len(ground):].all() and not res.kept[:len(ground)].any()
    # without the continuity check the load would be taken for the ground
    loose = process_cloud(cloud, CloudConfig(max_step=10.0))
    assert not loose.model.fallback[k] and not loose.kept[len(ground):].any()


def test_ground_along_a_single_line_is_not_a_free_plane():
    # the patch 40-55 m ahead sees the ground only along one scan line at x = 40.5, and a car's sill 0.5 m up
    rng = np.random.default_rng(6)
    ground = np.column_stack([rng.uniform(-40, 40, 4000), rng.uniform(-15, 15, 4000), np.zeros(4000)])
    line = np.column_stack([40.5 + rng.normal(0, 0.05, 60), np.linspace(-6, 6, 60), rng.normal(0, 0.01, 60)])
    sill = np.column_stack([np.linspace(47, 48, 6), np.full(6, 2.0), np.full(6, 0.5)])
    cloud = np.vstack([ground, line, sill])
    model = fit_ground(cloud)
    k = model.ring_starts[5]
    assert (model.patch_of(line) == k).all() and (model.patch_of(sill) == k).all()
    # the line gets a plane hinged on the ground inside: level, through the line, under the sill
    assert model.hinged[k] and not model.fallback[k] and model.slopes_deg[k] < 0.1
    np.testing.assert_allclose(model.height(sill), 0.5, atol=0.01)
    assert np.abs(model.height(line)).max() < 0.05
    # without the spread check: a free plane tilted about the line through the sill (4 deg, no step, no kink)
    loose = fit_ground(cloud, CloudConfig(min_spread=0.0, hinged_share=None))
    assert not loose.fallback[k] and not loose.hinged[k] and 3.0 < loose.slopes_deg[k] < 5.0
    assert np.abs(loose.height(sill)).max() < 0.15


def test_a_plane_tilted_into_a_vehicle_is_not_ground():
    # the patch 40-55 m ahead sees the ground along one scan line at x = 40.5, and a truck's side behind
    # it: a plane through the line tilted 6-8 deg crosses the side in a line, so its inliers are spread
    rng = np.random.default_rng(7)
    ground = np.column_stack([rng.uniform(-40, 40, 4000), rng.uniform(-15, 15, 4000), np.zeros(4000)])
    line = np.column_stack([40.5 + rng.normal(0, 0.05, 60), np.linspace(-6, 6, 60), rng.normal(0, 0.01, 60)])
    side = np.column_stack([rng.uniform(44, 49, 200), np.full(200, 2.0), rng.uniform(0.4, 3.5, 200)])
    cloud = np.vstack([ground, line, side])
    model = fit_ground(cloud)
    k = model.ring_starts[5]
    assert (model.patch_of(side) == k).all()
    assert model.hinged[k] and model.slopes_deg[k] < 0.1
    assert (model.height(side) > 0.35).all()
    # it takes both a loose kink limit and no steep-rise test (the side's returns stand one above
    # the other in their azimuth columns, so they take no part in the fits) to take the side for ground
    assert (fit_ground(cloud, CloudConfig(max_slope_change_deg=45.0)).height(side) > 0.35).all()
    loose = fit_ground(cloud, CloudConfig(max_slope_change_deg=45.0, column_width_deg=1e-6, hinged_share=None))
    assert not loose.fallback[k] and not loose.hinged[k] and loose.slopes_deg[k] > 3.0  # 4-6 deg
    assert (np.abs(loose.height(side)) <= 0.15).sum() > 10  # side returns taken for the ground


# --------------------------------------------------------------------------------------------------
# the pipeline's bookkeeping


def test_stats_add_up_and_masks_partition_the_cloud():
    points, labels, _ = scan(TILTED, TRAFFIC, az_step_deg=0.4)
    clean = process_cloud(points).stats
    assert clean.below_ground == 0 and clean.above_ceiling == 0 and clean.non_finite == 0
    rng = np.random.default_rng(5)
    x, y = rng.uniform(5, 30, 50), rng.uniform(-5, 5, 50)
    below = np.column_stack([x, y, 0.04 * x + 0.03 * y - 1.0]) - [0, 0, 1.9]  # reflections 1 m under
    bridge = np.column_stack([x, y, 0.04 * x + 0.03 * y + 6.0]) - [0, 0, 1.9]  # 6 m up
    bad = np.array([[np.nan, 0, 0], [0, np.inf, 0], [0, 0, -np.inf], [np.nan] * 3])
    # the ego's roof and bonnet (E: within 2.4 + 0.3 m along, 1.0 + 0.3 m across, up to 1.5 + 0.3 m)
    body_e = np.column_stack([rng.uniform(-2.65, 2.65, 30), rng.uniform(-1.25, 1.25, 30), rng.uniform(0.9, 1.75, 30)])
    cloud = np.vstack([points, below, bridge, bad, body_e - [0, 0, 1.9]])
    res = process_cloud(cloud)
    s = res.stats
    assert s.points_in == len(cloud)
    assert s.non_finite == 4 and s.below_ground == 50 and s.above_ceiling == 50 and s.ego_body == 30
    assert res.ego_body[-30:].all() and not res.ego_body[:-30].any()
    assert (s.ground, s.kept, s.low_object) == (clean.ground, clean.kept, clean.low_object)
    assert s.kept + s.ground + s.below_ground + s.above_ceiling + s.low_object + s.non_finite + s.ego_body == s.points_in
    assert s.as_dict() == {"points_in": len(cloud), "non_finite": 4, "ego_body": 30, "ground": s.ground,
                           "below_ground": 50, "above_ceiling": 50, "low_object": s.low_object, "kept": s.kept,
                           "seen_over": s.seen_over, "segments_fallback": s.segments_fallback, "segments_hinged": s.segments_hinged}
    assert process_cloud(cloud, CloudConfig(ego_length=0.0)).stats.ego_body == 0  # the crop off
    assert s.seen_over == np.count_nonzero(res.seen_over) and not (res.seen_over & ~res.kept).any()
    assert len(res.outline_2d) == s.kept - s.seen_over
    occupied = np.bincount(res.model.patch_of(res.points_e[res.finite & ~res.ego_body]), minlength=res.model.n_patches) > 0
    assert s.segments_fallback == (res.model.fallback & occupied).sum()
    assert s.segments_hinged == (res.model.hinged & occupied).sum() > 0
    masks = np.stack([res.ground, res.below_ground, res.above_ceiling, res.low_object, res.kept, ~res.finite, res.ego_body])
    assert (masks.sum(axis=0) == 1).all()
    assert res.points_2d.shape == (s.kept, 2)
    used = res.finite & ~res.ego_body
    assert np.isnan(res.heights[~used]).all() and np.isfinite(res.heights[used]).all()
    # the 2-D points are the kept points' projections, in input order
    np.testing.assert_allclose(res.points_2d, res.model.project(res.points_e[res.kept])[:, :2])


def test_a_kerb_is_a_low_object_and_a_vehicle_s_lowest_returns_are_not():
    """Level ground seen from 1.9 m, a kerb 0.18 m high along y = -5.9 m, a guard-rail post 0.8 m
    tall in the next cell out (y = -6.3 m, x = 5 m) and a car's side (0.25 to 1.45 m up, 12 m ahead,
    y = -3 m): ``CloudConfig.low_object_height`` (0.3 m) drops every kerb return above
    ``distance_threshold``, those beside the post included, and keeps all of the car's, its 0.25 m
    line included (the side above it shares its cells), and the post's; with it off, the kerb is
    kept."""
    rng = np.random.default_rng(3)
    ground = np.column_stack([rng.uniform(-30, 30, 40000), rng.uniform(-30, 30, 40000), rng.normal(0, 0.01, 40000)])
    kx = np.arange(-20.0, 20.0, 0.4)
    kerb = np.column_stack([kx, np.full(len(kx), -5.9), np.full(len(kx), 0.18)])
    post = np.column_stack([np.full(4, 5.0), np.full(4, -6.3), [0.2, 0.4, 0.6, 0.8]])
    cx = np.arange(10.0, 14.5, 0.1)
    side = np.concatenate([np.column_stack([cx, np.full(len(cx), -3.0), np.full(len(cx), z)])
                           for z in (0.25, 0.45, 0.8, 1.1, 1.45)])
    cloud = np.vstack([ground, kerb, post, side]) - [0, 0, 1.9]
    res = process_cloud(cloud)
    k = slice(len(ground), len(ground) + len(kerb))
    assert res.low_object[k].all() and not res.kept[k].any()
    assert res.kept[len(ground) + len(kerb):].all() and not res.low_object[len(ground) + len(kerb):].any()
    assert res.stats.low_object == len(kerb)
    off = process_cloud(cloud, CloudConfig(low_object_height=None))
    assert off.kept[k].all() and off.stats.low_object == 0
    with pytest.raises(ValueError, match="low_object_height must be within"):
        CloudConfig(low_object_height=0.1)


def _ray_points(azimuth_deg: float, elevation_deg: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """Returns in the frame of a lidar 1.9 m up: the ray of one azimuth and elevation each, ending at
    the horizontal distance ``rho``."""
    a, e = np.radians(azimuth_deg), np.radians(elevation_deg)
    return np.column_stack([rho * np.cos(a), rho * np.sin(a), rho * np.tan(e)])


def _level_ground() -> np.ndarray:
    az = np.radians(np.arange(-180.0, 180.0, 0.5))
    ring = np.stack([np.cos(az), np.sin(az), np.zeros_like(az)], axis=1)
    return np.concatenate([ring * [r, r, 1.0] for r in (8.0, 12.0, 20.0)]) - [0, 0, 1.9]


def test_returns_seen_over_a_nearer_object_are_not_outline_points():
    """A column of a 1.5 m hedge beside the road at 30 m whose top beam passes over it and ends on a car
    roof's far end at 65 m (1.5 m up): the roof return is kept (an occluder) but is no 2-D point;
    a car's rear face at 40 m beneath a canopy return 3 m up at 10 m, a car's rear face whose two upper
    beams pass over a 1.5 m post at 20 m, and a car's rear face alone keep every return; with
    ``seen_over_gap=None`` nothing is left out."""
    beams = np.array([-2.0, -1.33, -1.0, -0.67])
    hedge = _ray_points(5.0, beams[:3], np.full(3, 30.0))  # 0.85, 1.20, 1.38 m up
    roof = _ray_points(5.0, np.degrees(np.arctan([-0.4 / 65.0])), np.array([65.0]))  # 1.5 m up
    face = _ray_points(-10.0, beams, np.full(4, 40.0))  # 0.50 .. 1.43 m up
    canopy = _ray_points(-10.0, np.degrees(np.arctan([1.1 / 10.0])), np.array([10.0]))  # 3.0 m up
    alone = _ray_points(20.0, beams, np.full(4, 25.0))
    post = _ray_points(30.0, beams[:2], np.full(2, 20.0))  # 1.20, 1.44 m up
    over_post = _ray_points(30.0, beams[2:], np.full(2, 45.0))  # 1.11, 1.37 m up
    objects = np.vstack([hedge, roof, face, canopy, alone, post, over_post])
    cloud = np.vstack([_level_ground(), objects])
    res = process_cloud(cloud)
    first = len(cloud) - len(objects)
    assert res.kept[first:].all()
    over = np.flatnonzero(res.seen_over)
    assert over.tolist() == [first + 3]  # the roof return only
    assert res.stats.seen_over == 1 and res.stats.kept == len(objects)
    np.testing.assert_allclose(res.outline_2d, np.delete(res.points_2d, 3, axis=0))
    np.testing.assert_allclose(res.points_2d[3], roof[0, :2], atol=1e-9)
    off = process_cloud(cloud, CloudConfig(seen_over_gap=None))
    assert not off.seen_over.any() and off.stats.seen_over == 0 and off.outline_2d.shape == (len(objects), 2)
    # a face's returns within the gap of each other in rho are not over one another
    tilted = _ray_points(-10.0, beams, 40.0 + np.array([0.0, 0.1, 0.2, 0.45]))
    res = process_cloud(np.vstack([_level_ground(), tilted]))
    assert res.kept[-4:].all() and not res.seen_over.any()
    with pytest.raises(ValueError, match="seen_over_gap"):
        CloudConfig(seen_over_gap=-0.1)


def test_seen_over_kernel_against_all_pairs():
    """``seen_over_kernel`` (a running minimum per column) against the test of every pair: same column,
    nearer by more than the gap, and lower in elevation by more than the tolerance; and no other
    return of the column within the gap."""
    from tracker.cloud import SEEN_OVER_ELEVATION, _column_order, _seen_over

    def flags(points: np.ndarray, cfg: CloudConfig) -> np.ndarray:  # every return taking part
        dx, dy = points[:, 0] - cfg.mount_x, points[:, 1] - cfg.mount_y
        rho = np.hypot(dx, dy)
        col, order = _column_order(rho, np.arctan2(dy, dx), cfg.column_width_deg)
        return _seen_over(points, np.ones(len(points), dtype=bool), (col, order, rho), cfg)

    rng = np.random.default_rng(3)
    n = 3000
    rho = rng.uniform(2.0, 60.0, n)
    az = np.radians(rng.choice(np.arange(-30.0, 30.0, 0.2), n) + rng.normal(0.0, 0.01, n))
    z = rng.uniform(0.2, 3.5, n)
    points = np.column_stack([rho * np.cos(az), rho * np.sin(az), z])
    cfg = CloudConfig()
    got = flags(points, cfg)
    col = np.floor(az / np.radians(cfg.column_width_deg) + 0.5)
    slope = (z - cfg.mount_z) / rho
    same = col[:, None] == col[None, :]
    nearer = rho[None, :] < rho[:, None] - cfg.seen_over_gap
    beneath = slope[None, :] < slope[:, None] - math.tan(SEEN_OVER_ELEVATION)
    close = same & (np.abs(rho[None, :] - rho[:, None]) <= cfg.seen_over_gap) & ~np.eye(n, dtype=bool)
    want = (same & nearer & beneath).any(axis=1) & ~close.any(axis=1)
    assert 0 < want.sum() < n
    np.testing.assert_array_equal(got, want)
    above = np.vstack([points, [[cfg.mount_x, cfg.mount_y, 3.0]]])  # a return right above the lidar
    np.testing.assert_array_equal(flags(above, cfg), np.append(want, False))


def test_deterministic():
    points, _, _ = scan(piecewise(), TRAFFIC, az_step_deg=0.4)
    a, b = process_cloud(points), process_cloud(points.copy())
    np.testing.assert_array_equal(a.points_2d, b.points_2d)
    np.testing.assert_array_equal(a.model.normals, b.model.normals)
    np.testing.assert_array_equal(a.model.offsets, b.model.offsets)
    assert a.stats == b.stats
    xy, stats = to_ground_plane(points)
    np.testing.assert_array_equal(xy, a.points_2d)
    assert stats == a.stats
    # another seed: other fit subsamples and hypotheses, the same classification but for a point or two
    # within a few millimetres of the ground threshold
    c = process_cloud(points, CloudConfig(seed=7))
    assert np.count_nonzero(c.kept != a.kept) <= 4
    differ = c.kept != a.kept
    cfg = CloudConfig()
    near = np.minimum(np.abs(np.abs(a.heights[differ]) - cfg.distance_threshold),
                      np.abs(a.heights[differ] - cfg.low_object_height))
    assert np.all(near < 0.01)


def test_empty_cloud():
    xy, stats = to_ground_plane(np.zeros((0, 3)))
    assert xy.shape == (0, 2)
    assert stats == CloudStats()
    res = process_cloud(np.zeros((0, 3)))
    cfg = CloudConfig()
    level = GroundModel.level(cfg.ring_edges, (1,) + cfg.ring_sectors)
    assert res.model.fallback.all() and (res.model.source == -1).all() and not res.model.hinged.any()
    np.testing.assert_array_equal(res.model.normals, level.normals)
    np.testing.assert_array_equal(res.model.offsets, level.offsets)
    assert res.points_e.shape == (0, 3) and res.kept.shape == (0,)
    assert fit_ground(np.zeros((0, 3))).n_patches == 129
    assert to_ground_plane([[np.nan, 0.0, 0.0]])[1].non_finite == 1


@pytest.mark.parametrize("bad, problem", [
    (np.zeros((5, 2)), r"shape \(N, 3\)"),
    (np.zeros(6), r"shape \(N, 3\)"),
    (np.zeros((2, 3, 3)), r"shape \(N, 3\)"),
    (np.zeros(0), r"shape \(N, 3\)"),
    ([["a", "b", "c"]], "real numbers"),
    ([[1.0, None, 2.0]], "real numbers"),
    (np.ones((2, 3), dtype=complex), "real numbers"),
    (np.ones((2, 3), dtype=bool), "real numbers"),
    ([[1.0, 2.0, 3.0], [1.0, 2.0]], "points_sensor"),
])
def test_bad_input_is_named(bad, problem):
    with pytest.raises(ValueError, match=problem):
        to_ground_plane(bad)


def test_bad_config_type():
    with pytest.raises(TypeError, match="CloudConfig"):
        to_ground_plane(np.zeros((0, 3)), config={"seed": 1})


def test_integer_and_float32_input():
    points, _, _ = scan(TILTED, TRAFFIC, az_step_deg=0.8)
    a = to_ground_plane(points)[0]
    b = to_ground_plane(points.astype(np.float32))[0]
    assert abs(len(a) - len(b)) <= 2
    assert to_ground_plane(np.array([[10, 0, -2], [10, 1, 0]]))[1].points_in == 2


def test_a_free_plane_barely_better_than_the_hinged_one_is_not_taken():
    # the patch 40-55 m ahead sees the ground along one scan line at x = 52 m (a beam 2.1 deg down
    # from 1.9 m) and the same beam's returns across the foot of a ragged hedge at the road's edge,
    # nearer and so higher up: 0.2 m at 46 m, 0.02 m at 51 m. A free plane through both tilts 2 deg
    # down and out about the line; the sparse far ring at 66 m (fewer than min_points returns)
    # borrows it and stands 0.4 m above it
    rng = np.random.default_rng(9)
    ground = np.column_stack([rng.uniform(-40, 40, 4000), rng.uniform(-15, 15, 4000), np.zeros(4000)])
    line = np.column_stack([52.0 + rng.normal(0, 0.05, 60), np.linspace(-6, 6, 60), rng.normal(0, 0.01, 60)])
    x = np.linspace(46, 51, 30)
    foot = np.column_stack([x, np.full(30, -7.0), 1.9 - np.hypot(x, 7.0) * 1.9 / 52.0 + 0.03])
    far = np.column_stack([66.0 + rng.normal(0, 0.05, 20), np.linspace(-5, 5, 20), rng.normal(0, 0.01, 20)])
    cloud = np.vstack([ground, line, foot, far])
    model = fit_ground(cloud)
    k, k_far = model.ring_starts[5], model.ring_starts[6]
    assert (model.patch_of(line) == k).all() and (model.patch_of(foot) == k).all() and (model.patch_of(far) == k_far).all()
    # the hinged plane through the ground inside explains the line and most of the foot: it is taken,
    # and the far ring, on the plane it borrows, is ground
    assert model.hinged[k] and model.slopes_deg[k] < 1.0 and model.fallback[k_far] and model.source[k_far] == k
    assert np.abs(model.height(far)).max() < CloudConfig().distance_threshold
    # taking every free plane that passes its tests: tilted about the line, the far ring left as objects
    free = fit_ground(cloud, CloudConfig(hinged_share=None))
    assert not free.hinged[k] and not free.fallback[k] and free.slopes_deg[k] > 1.5
    assert free.fallback[k_far] and (free.height(far) > 0.3).all()


def test_a_near_face_climbed_by_dense_beams_takes_no_part_in_the_fits():
    # a wall 9 m beside the sensor: a dense lidar's neighbouring beams climb its face 4 cm apart, so no
    # two returns next to each other in a column rise by more than distance_threshold. All but its top
    # returns still stand at its foot (another return more than that higher within distance_threshold
    # in rho in the column); the ground's returns in the same columns lie rings apart and do not
    from tracker.cloud import _column_order, _wall_feet

    cfg = CloudConfig()
    phi = np.radians(np.arange(60.0, 120.0, 0.2))
    z_face = np.arange(0.0, 3.0, 0.04)
    rho_face = 9.0 / np.sin(phi)
    face_rho = np.repeat(rho_face, len(z_face)) + np.random.default_rng(2).normal(0, 0.005, len(phi) * len(z_face))
    face_phi, face_z = np.repeat(phi, len(z_face)), np.tile(z_face, len(phi))
    ring_rho = np.tile([3.0, 3.6, 4.3, 5.1], len(phi))  # the ground inside, four rings
    ring_phi, ring_z = np.repeat(phi, 4), np.zeros(4 * len(phi))
    rho, ph, z = (np.concatenate(a) for a in ((face_rho, ring_rho), (face_phi, ring_phi), (face_z, ring_z)))
    feet = _wall_feet(rho, z, _column_order(rho, ph, cfg.column_width_deg), cfg)
    face = np.arange(len(rho)) < len(face_rho)
    assert not feet[~face].any()
    low = face & (z < 3.0 - 0.04 - 2 * cfg.distance_threshold)
    assert feet[low].all()


def test_the_wall_feet_kernel_against_the_oracle():
    # columns of ground rings, vehicle sides and faces, with equal heights, equal rho and single returns
    from oracles.cloud import wall_feet_sorted

    from tracker.cloud import wall_feet_kernel

    rng = np.random.default_rng(11)
    counts = []
    for _ in range(20):
        n = int(rng.integers(2, 400))
        c = np.sort(rng.integers(0, 40, n)).astype(float)
        r = np.where(rng.random(n) < 0.5, np.round(rng.uniform(2, 40, n), 1), 5.0 + rng.normal(0, 0.1, n))
        h = np.where(rng.random(n) < 0.7, np.round(rng.normal(0, 0.05, n), 2), np.round(rng.uniform(0.2, 2.0, n), 2))
        order = np.lexsort((r, c))
        c, r, h = c[order], r[order], h[order]
        feet = wall_feet_kernel(c, r, h, 0.15)
        np.testing.assert_array_equal(feet, wall_feet_sorted(c, r, h, 0.15))
        counts += [feet.sum(), (~feet).sum()]
    assert counts[0::2].count(0) < 5 and sum(counts[0::2]) > 0.2 * sum(counts)  # feet and not, in most draws


@pytest.mark.parametrize("low_height", [0.3, None])
def test_the_classification_kernel_against_the_oracle(low_height):
    # ground, below-ground, above-ceiling and kept points over tilted patches, with kerb-like low
    # points alone and beside taller ones
    from oracles.cloud import classify

    from tracker.cloud import ABOVE_CEILING, BELOW_GROUND, GROUND, KEPT, LOW_OBJECT, classify_kernel

    rng = np.random.default_rng(12)
    n = 5000
    pts = np.column_stack([rng.uniform(-60, 60, n), rng.uniform(-20, 20, n),
                           rng.choice([0.0, 0.22, 1.2, 5.0, -0.5], n) + rng.normal(0, 0.02, n)])
    patch = rng.integers(0, 6, n)
    tilt = rng.normal(0, 0.02, (6, 2))
    normals = np.column_stack([tilt, np.ones(6)]) / np.sqrt(1 + (tilt**2).sum(axis=1))[:, None]
    offsets = rng.normal(0, 0.03, 6)
    h, cls, xy = classify_kernel(pts, patch, normals, offsets, 0.15, 4.0, -1.0 if low_height is None else low_height, 0.5)
    h_ref, masks, xy_ref = classify(pts, patch, normals, offsets, 0.15, 4.0, low_height, 0.5)
    np.testing.assert_array_equal(h, h_ref)
    for code, mask in zip((GROUND, BELOW_GROUND, ABOVE_CEILING, LOW_OBJECT, KEPT), masks):
        np.testing.assert_array_equal(cls == code, mask)
        assert mask.any() or (code == LOW_OBJECT and low_height is None)
    np.testing.assert_array_equal(xy, xy_ref)
