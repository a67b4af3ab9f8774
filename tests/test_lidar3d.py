"""The 3-D lidar (sim.sensors.lidar3d) and the ground (sim.world.ground) against brute-force oracles.

The oracles are independent of ``cast_3d``: per box (an oriented 3-D box) all rays move into the
box frame and meet the three slabs; a general convex prism is cut face by face (side walls, roof,
floor); the ground is the flat plane or, on a straight road, the exact piecewise-planar surface
(three planes: the ray's below-ground set as unions and intersections of half-lines in the slant
range). Ranges must agree to 1e-9 (relative), owners and ground flags exactly. On a curved road the
ground search is checked against dense sampling of the same casting surface.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from sim.sensors.clutter import ClutterConfig, generate_roadside
from sim.sensors.lidar3d import LIDAR3D_MODELS, Lidar3D, Lidar3DConfig, Prisms, cast_3d
from sim.world.ground import FlatGround, GroundSurface, RoadGround
from tracker.road import Road

MAX_RANGE = 100.0
COARSE = Lidar3DConfig(resolution_deg=1.0)  # 16 beams x 360 azimuths


def rot_z(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def coarse_directions(yaw: float = 0.0) -> np.ndarray:
    """The coarse VLP-16 rays (5760, 3) in G for an upright sensor with heading ``yaw``."""
    return COARSE.directions @ rot_z(yaw).T


# -- the oracle -------------------------------------------------------------------------------------
def oracle_boxes(origin: np.ndarray, d: np.ndarray, boxes: list[tuple]) -> tuple[np.ndarray, np.ndarray]:
    """Slant range (inf) and owner (-1) of the first box hit per ray; a box is
    ``(cx, cy, yaw, length, width, base, top, owner)``."""
    best = np.full(len(d), np.inf)
    who = np.full(len(d), -1)
    for cx, cy, yaw, length, width, base, top, owner in boxes:
        r = rot_z(-yaw)
        p = r @ (np.asarray(origin, float) - np.array([cx, cy, 0.0]))
        q = d @ r.T
        near = np.zeros(len(d))
        far = np.full(len(d), np.inf)
        for axis, (lo, hi) in enumerate(((-length / 2, length / 2), (-width / 2, width / 2), (base, top))):
            with np.errstate(divide="ignore", invalid="ignore"):
                t1 = (lo - p[axis]) / q[:, axis]
                t2 = (hi - p[axis]) / q[:, axis]
            parallel = q[:, axis] == 0.0
            inside = lo <= p[axis] <= hi
            t1 = np.where(parallel, -np.inf if inside else np.inf, t1)
            t2 = np.where(parallel, np.inf if inside else -np.inf, t2)
            near = np.maximum(near, np.minimum(t1, t2))
            far = np.minimum(far, np.maximum(t1, t2))
        hit = (near <= far) & (near <= MAX_RANGE) & (near < best)
        best[hit] = near[hit]
        who[hit] = owner
    return best, who


def oracle_flat(origin: np.ndarray, d: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore"):
        r = -origin[2] / d[:, 2]
    return np.where((d[:, 2] < 0.0) & (r <= MAX_RANGE), r, np.inf)


def halfline(alpha: np.ndarray, beta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The set ``{r : alpha r <= beta}`` as an interval ``[lo, hi]`` (empty when lo > hi)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        x = beta / alpha
    lo = np.where(alpha < 0.0, x, np.where((alpha == 0.0) & (beta < 0.0), np.inf, -np.inf))
    hi = np.where(alpha > 0.0, x, np.where((alpha == 0.0) & (beta < 0.0), -np.inf, np.inf))
    return lo, hi


def oracle_straight_road(origin: np.ndarray, d: np.ndarray, p0, heading, grade, bank, right, left) -> np.ndarray:
    """First slant range where the ray is on or below ``grade s + bank clip(n, right, left)`` (bank
    >= 0) of the straight road through ``p0`` with ``heading``: ``min(max(P_mid, P_right), P_left)``
    with the planes ``P_x = grade s + bank x`` (``x = n`` or an edge)."""
    t = np.array([math.cos(heading), math.sin(heading)])
    nu = np.array([-t[1], t[0]])
    o = np.asarray(origin, float)
    s0, n0 = (o[:2] - p0) @ t, (o[:2] - p0) @ nu
    ds, dn = d[:, :2] @ t, d[:, :2] @ nu
    # z0 + dz r <= grade (s0 + ds r) + bank * x(r):  (dz - grade ds - bank dx) r <= grade s0 + bank x0 - z0
    mid = halfline(d[:, 2] - grade * ds - bank * dn, np.full(len(d), grade * s0 + bank * n0 - o[2]))
    at_right = halfline(d[:, 2] - grade * ds, np.full(len(d), grade * s0 + bank * right - o[2]))
    at_left = halfline(d[:, 2] - grade * ds, np.full(len(d), grade * s0 + bank * left - o[2]))

    def member(c, iv):
        tol = 1e-12 * (1.0 + np.abs(c))
        return (c >= iv[0] - tol) & (c <= iv[1] + tol)

    best = np.full(len(d), np.inf)
    for iv in (at_left, mid, at_right):
        c = np.maximum(iv[0], 0.0)
        ok = np.isfinite(c) & member(c, at_left) & (member(c, mid) | member(c, at_right)) & (c <= MAX_RANGE)
        best = np.where(ok & (c < best), c, best)
    return best


def combine(box_range, box_owner, ground_range):
    ground = ground_range < box_range
    return np.where(ground, ground_range, box_range), np.where(ground, -1, box_owner), ground


def assert_same(result, expected_range, expected_owner, expected_ground):
    assert np.array_equal(np.isfinite(result.range), np.isfinite(expected_range))
    hit = np.isfinite(expected_range)
    assert np.allclose(result.range[hit], expected_range[hit], rtol=1e-9, atol=0.0)
    assert np.array_equal(result.owner, expected_owner)
    assert np.array_equal(result.ground, expected_ground)


def box_prisms(boxes: list[tuple]) -> Prisms:
    b = np.array([box[:7] for box in boxes], dtype=float)
    return Prisms.from_rectangles(b[:, :2], b[:, 2], b[:, 3], b[:, 4], b[:, 5], b[:, 6], [box[7] for box in boxes])


def check_flat(origin, boxes, yaw=0.0):
    d = coarse_directions(yaw)
    result = cast_3d(origin, d, box_prisms(boxes) if boxes else Prisms.empty(), FlatGround(), MAX_RANGE)
    br, bo = oracle_boxes(np.asarray(origin, float), d, boxes)
    expected = combine(br, bo, oracle_flat(np.asarray(origin, float), d))
    assert_same(result, *expected)
    return result, d


# -- cast_3d against the oracle ---------------------------------------------------------------------
def test_flat_ground_only():
    result, d = check_flat([3.0, -2.0, 1.9], [])
    assert result.ground.sum() == 7 * 360  # beams -15 .. -3 deg reach z = 0 within 100 m; -1 deg does not
    assert not np.any(result.ground & (d[:, 2] > 0))


def test_box_seen_from_the_side():
    result, _ = check_flat([0.0, 0.0, 1.9], [(12.0, 1.0, 0.3, 4.6, 1.9, 0.25, 1.6, 5)])
    assert (result.owner == 5).sum() > 20


def test_roof_hit_by_down_beams_at_short_range():
    boxes = [(3.0, 0.0, 0.0, 4.0, 2.0, 0.2, 1.5, 0)]  # footprint x in [1, 5]: the -15 deg beam meets the roof
    origin = np.array([0.0, 0.0, 1.9])
    result, d = check_flat(origin, boxes)
    z = origin[2] + d[:, 2] * result.range
    roof = (result.owner == 0) & np.isclose(z, 1.5, atol=1e-9)
    assert roof.sum() >= 20


def test_low_box_in_front_of_a_tall_one():
    low = (8.0, 0.0, 0.0, 1.0, 4.0, 0.0, 0.8, 0)
    tall = (15.0, 0.0, 0.0, 2.0, 6.0, 0.0, 4.0, 1)
    result, d = check_flat([0.0, 0.0, 1.9], [low, tall])
    az = np.arctan2(d[:, 1], d[:, 0])
    behind_low = np.abs(az) < math.atan2(1.5, 8.5)  # bearings where the low box blocks the view in 2-D
    assert np.any(behind_low & (result.owner == 1))  # the tall box's upper part shows over the low one
    assert np.any(behind_low & (result.owner == 0))


def test_rays_pass_under_a_raised_box_and_hit_its_bottom():
    trailer = (10.0, 0.0, 0.0, 4.0, 2.5, 1.0, 3.0, 0)  # 1 m clearance: low beams pass under
    gantry = (0.0, 12.0, 0.0, 3.0, 3.0, 2.5, 3.5, 1)  # above the sensor: upward beams hit its bottom
    bridge = (-2.0, 0.0, 0.5, 30.0, 6.0, 5.0, 6.0, 2)  # overhead: the sensor stands in its footprint
    origin = np.array([0.0, 0.0, 1.9])
    result, d = check_flat(origin, [trailer, gantry, bridge])
    hit_xyz = origin + d * np.where(result.hit, result.range, 0.0)[:, None]
    under = result.ground & (np.abs(hit_xyz[:, 0] - 10.0) < 2.0) & (np.abs(hit_xyz[:, 1]) < 1.25)
    assert under.sum() > 5
    assert np.any((result.owner == 1) & np.isclose(hit_xyz[:, 2], 2.5))
    assert np.any((result.owner == 2) & np.isclose(hit_xyz[:, 2], 5.0))


def test_wrap_around_at_pi():
    boxes = [(-10.0, 0.0, 0.2, 4.5, 1.8, 0.2, 1.6, 3), (-30.0, -0.5, -0.1, 1.0, 8.0, 0.0, 3.0, 4)]
    result, d = check_flat([0.0, 0.0, 1.9], boxes)
    az = np.arctan2(d[:, 1], d[:, 0])
    assert np.any((result.owner == 3) & (az > 3.0)) and np.any((result.owner == 3) & (az < -3.0))


def test_random_scenes_and_headings():
    rng = np.random.default_rng(11)
    for trial in range(4):
        boxes = []
        for i in range(8):
            r, b = rng.uniform(4.0, 60.0), rng.uniform(-math.pi, math.pi)
            base = rng.choice([0.0, 0.3, 1.2])
            boxes.append((r * math.cos(b), r * math.sin(b), rng.uniform(-3, 3), rng.uniform(1, 6), rng.uniform(0.5, 3),
                          base, base + rng.uniform(0.5, 4.0), i))
        check_flat([0.0, 0.0, 1.9], boxes, yaw=rng.uniform(-math.pi, math.pi))


def straight_road(heading: float = math.radians(20.0)) -> tuple[Road, np.ndarray]:
    p0 = np.array([-250.0 * math.cos(heading), -250.0 * math.sin(heading)])
    road = Road.from_waypoints([p0, -p0], lanes=3)
    return road, p0


@pytest.fixture(scope="module")
def sloped():
    road, p0 = straight_road()
    return road, p0, RoadGround(road, grade=0.04, bank=0.03)


def test_sloped_ground_matches_the_exact_planes(sloped):
    road, p0, ground = sloped
    heading = math.radians(20.0)
    for s, n, yaw in ((260.0, -1.75, heading), (200.0, 3.5, heading + math.pi), (300.0, 0.0, heading + 1.0)):
        xy = np.asarray(road.to_cartesian(s, n))
        z = float(ground.height(xy[None])[0])
        origin = np.array([xy[0], xy[1], z + 1.9])
        d = coarse_directions(yaw)
        t = np.array([math.cos(heading), math.sin(heading)])
        nu = np.array([-t[1], t[0]])
        boxes = []
        for i, (ds, dn) in enumerate(((15.0, 3.5), (-25.0, -3.5), (40.0, 0.0), (8.0, 9.0))):
            c = xy + ds * t + (dn - n) * nu
            gz = float(ground.height(c[None])[0])
            boxes.append((c[0], c[1], heading, 4.5, 1.9, gz + 0.3, gz + 1.7, i))
        result = cast_3d(origin, d, box_prisms(boxes), ground, MAX_RANGE)
        br, bo = oracle_boxes(origin, d, boxes)
        gr = oracle_straight_road(origin, d, p0, heading, 0.04, 0.03, road.right_edge, road.left_edge)
        expected = combine(br, bo, gr)
        assert_same(result, *expected)
        assert result.ground.sum() > 2000
        assert np.any(result.ground & (d[:, 2] > 0.0))  # upward beams meet the climbing road ahead


def test_road_ground_validation():
    road, _ = straight_road()
    loop = Road.from_waypoints([[0, 0], [100, 0], [100, 100], [0, 100]], closed=True)
    with pytest.raises(ValueError, match="grade"):
        RoadGround(loop, grade=0.01)
    RoadGround(loop, bank=0.02)
    with pytest.raises(ValueError, match="grade"):
        RoadGround(road, grade=0.2)
    with pytest.raises(ValueError, match="bank"):
        RoadGround(road, bank=float("nan"))
    with pytest.raises(ValueError, match="cell"):
        RoadGround(road, cell=0.0)


def test_road_ground_grid_on_a_curved_road():
    road = Road.from_curvature([(60.0, 0.0, 0.0), (60.0, 0.0, 1 / 150), (100.0, 1 / 150, 1 / 150)], lanes=3)
    ground = RoadGround(road, grade=0.04, bank=0.03, margin=40.0)
    grid = ground.grid
    rng = np.random.default_rng(3)
    lo, hi = grid.origin + 1.0, grid.origin + grid.cell * (np.array(grid.shape) - 2)
    xy = rng.uniform(lo, hi, (20000, 2))
    exact = ground.height(xy)
    error = np.abs(grid.height(xy[:, 0], xy[:, 1]) - exact)
    assert error.max() <= 0.01  # well below the 3 cm range noise, even at the kink of s at the road's end
    s, _ = road.to_frenet(xy)
    assert error[(s > 2.0) & (s < road.length - 2.0)].max() <= 1e-3
    # the kinks at the road edges are exact: no smoothing across a cell
    s = rng.uniform(10.0, 200.0, 500)
    for edge in (road.right_edge, road.left_edge):
        pts = road.to_cartesian(s, np.full_like(s, edge))
        assert np.abs(grid.height(pts[:, 0], pts[:, 1]) - ground.height(pts)).max() <= 1e-3
    # the rise bounds hold along rays from a sensor (also off the road, where the terrain is level
    # across), and are not loose: about the road's steepest slope
    cases = ((150.0, 0.0, 30.0), (60.0, -12.0, 25.0), (60.0, -20.0, 60.0))  # the last leaves the grid
    for s_c, n_c, radius in cases:
        centre = road.to_cartesian(s_c, n_c)
        surface = ground.surface(centre, radius)
        assert isinstance(surface, GroundSurface) and surface.flat is None
        phi = rng.uniform(-math.pi, math.pi, 5000)
        ux, uy = np.cos(phi), np.sin(phi)
        t1 = rng.uniform(0.0, radius, 5000)
        t2 = np.minimum(t1 + rng.exponential(3.0, 5000), radius)
        rise = surface.rise(ux, uy)
        h1 = grid.height(centre[0] + ux * t1, centre[1] + uy * t1)
        h2 = grid.height(centre[0] + ux * t2, centre[1] + uy * t2)
        assert np.all(h2 - h1 <= rise * (t2 - t1) + 1e-12)
        assert rise.max() <= 0.1
        if radius < 60.0:
            assert rise.min() < 0.0  # downhill sectors: the ground only falls there
    g = ground.gradient(xy[:200])
    h = 1e-4
    fd = np.column_stack(
        [(ground.height(xy[:200] + [h, 0]) - ground.height(xy[:200] - [h, 0])) / (2 * h),
         (ground.height(xy[:200] + [0, h]) - ground.height(xy[:200] - [0, h])) / (2 * h)]
    )
    sn = road.to_frenet(xy[:200])[1]
    away = np.minimum(np.abs(sn - road.right_edge), np.abs(sn - road.left_edge)) > 1e-3
    assert np.allclose(g[away], fd[away], atol=1e-6)


def test_flat_surface_and_road_without_slope_are_exact():
    road, _ = straight_road()
    assert FlatGround().surface((0.0, 0.0), 100.0).flat == 0.0
    assert RoadGround(road).surface((0.0, 0.0), 100.0).flat == 0.0
    assert np.all(FlatGround().height(np.ones((3, 2))) == 0.0)


# -- the scan ---------------------------------------------------------------------------------------
def test_mount_with_roll_pitch_yaw_matches_the_oracle():
    cfg = Lidar3DConfig(resolution_deg=1.0, mount_x=1.2, mount_y=-0.3, mount_z=1.7, mount_roll_deg=4.0,
                      mount_pitch_deg=-8.0, mount_yaw_deg=30.0, range_noise_std=0.0, dropout_probability=0.0,
                      min_range=0.0)
    lidar = Lidar3D(cfg)
    boxes = [(14.0, 3.0, 0.2, 4.5, 1.9, 0.3, 1.6, 0), (-9.0, -4.0, 1.0, 4.0, 1.8, 0.2, 1.5, 1),
             (25.0, -8.0, 0.0, 0.4, 0.4, 0.0, 6.0, 2)]
    origin, yaw = np.array([2.0, 1.0, 0.0]), 0.7
    scan = lidar.scan(origin, yaw, box_prisms(boxes), FlatGround(), vehicle_ids=[11, 12], rng=np.random.default_rng(0))
    position, rotation = lidar.pose(origin, yaw)
    d = cfg.directions @ rotation.T
    br, bo = oracle_boxes(position, d, boxes)
    rng_, owner, ground = combine(br, bo, oracle_flat(position, d))
    hit = np.flatnonzero(np.isfinite(rng_))
    assert len(scan) == hit.size
    assert np.allclose(scan.range, rng_[hit], rtol=1e-9, atol=0.0)
    assert np.array_equal(scan.ground, ground[hit])
    labels = np.where(owner[hit] == 0, 11, np.where(owner[hit] == 1, 12, -1))
    assert np.array_equal(scan.vehicle_id, labels)
    assert np.array_equal(scan.roadside_index, np.where(owner[hit] == 2, 0, -1))
    # the points, back in G, are where the rays hit
    assert np.allclose(scan.points_global(), position + d[hit] * rng_[hit, None], atol=1e-9)
    assert np.allclose(np.linalg.norm(scan.points, axis=1), scan.range)
    assert np.allclose(scan.elevation, np.arcsin(scan.points[:, 2] / scan.range))
    assert np.allclose(position, origin + rot_z(yaw) @ [1.2, -0.3, 1.7])


def box_distance(p: np.ndarray, box: tuple) -> np.ndarray:
    """Distance (K,) of the points ``p`` (K, 3) from the surface of ``box``."""
    cx, cy, yaw, length, width, base, top, _ = box
    q = (p - [cx, cy, 0.5 * (base + top)]) @ rot_z(-yaw).T
    excess = np.abs(q) - [length / 2, width / 2, (top - base) / 2]
    return np.linalg.norm(np.maximum(excess, 0.0), axis=1) + np.maximum(-excess.max(axis=1), 0.0)


def test_scan_points_lie_on_the_hit_surfaces(sloped):
    road, _, ground = sloped
    lidar = Lidar3D(Lidar3DConfig(resolution_deg=1.0))
    xy = np.asarray(road.to_cartesian(240.0, 1.75))
    origin = np.array([xy[0], xy[1], float(ground.height(xy[None])[0])])
    heading = math.radians(20.0)
    t = np.array([math.cos(heading), math.sin(heading)])
    nu = np.array([-t[1], t[0]])
    boxes = []
    for i, (ds, dn) in enumerate(((12.0, 0.0), (-20.0, 0.0), (35.0, -3.5))):
        c = xy + ds * t + dn * nu
        gz = float(ground.height(c[None])[0])
        boxes.append((c[0], c[1], heading, 4.5, 1.9, gz + 0.3, gz + 1.6, i))
    scan = lidar.scan(origin, heading, box_prisms(boxes), ground, vehicle_ids=[4, 5, 6], rng=np.random.default_rng(2))
    p = scan.points_global()
    tol = 6.0 * lidar.config.range_noise_std
    assert scan.ground.sum() > 1000 and (scan.vehicle_id >= 0).sum() > 50
    assert np.abs(p[scan.ground, 2] - ground.height(p[scan.ground, :2])).max() <= tol
    for vid, box in zip((4, 5, 6), boxes):
        on = scan.vehicle_id == vid
        assert on.any() and box_distance(p[on], box).max() <= tol
    assert np.all(scan.range >= lidar.config.min_range - tol)


def test_same_seed_same_scan_and_scene_independent_stream():
    lidar = Lidar3D(Lidar3DConfig(resolution_deg=1.0))
    prisms = box_prisms([(10.0, 0.0, 0.0, 4.5, 1.9, 0.2, 1.6, 0)])
    a = lidar.scan([0, 0, 0], 0.1, prisms, FlatGround(), vehicle_ids=[1], rng=np.random.default_rng(5), t=0.3)
    b = lidar.scan([0, 0, 0], 0.1, prisms, FlatGround(), vehicle_ids=[1], rng=np.random.default_rng(5), t=0.3)
    for name in ("points", "azimuth", "elevation", "beam", "range", "vehicle_id", "roadside_index", "ground"):
        assert np.array_equal(getattr(a, name), getattr(b, name))
    assert a.t == 0.3 and a.rays == 5760 and len(a) == len(b)
    r1, r2 = np.random.default_rng(9), np.random.default_rng(9)
    lidar.scan([0, 0, 0], 0.1, prisms, FlatGround(), vehicle_ids=[1], rng=r1)
    lidar.scan([50, 0, 0], 2.0, Prisms.empty(), FlatGround(), vehicle_ids=[], rng=r2)
    assert r1.random() == r2.random()


def test_roadside_prisms_and_owner_convention():
    road, _ = straight_road(0.0)
    objects = generate_roadside(road, ClutterConfig(post_spacing=5.0, tree_density=20.0), rng=np.random.default_rng(1))
    roadside = Prisms.from_polygons(objects.vertices, objects.offsets, 0.0, 1.0, np.arange(len(objects)) + 2)
    assert len(roadside) == len(objects) and roadside.vertices.shape[1] == 8
    cars = Prisms.from_rectangles([[10.0, 1.75], [-15.0, -1.75]], 0.0, 4.5, 1.8, 0.2, 1.6)
    scene = Prisms.concatenate([cars, roadside.relabel(0).relabel(roadside.owner)])
    rebuilt = Prisms(scene.vertices, scene.sizes, scene.base, scene.top, scene.owner)  # validated and derived anew
    for name in ("vertices", "sizes", "base", "top", "owner", "centre", "radius", "normals", "offsets"):
        assert np.array_equal(getattr(scene, name), getattr(rebuilt, name))
    lidar = Lidar3D(Lidar3DConfig(resolution_deg=1.0, dropout_probability=0.0))
    scan = lidar.scan([0.0, 0.0, 0.0], 0.0, scene, FlatGround(), vehicle_ids=[21, 22], rng=np.random.default_rng(0))
    assert set(np.unique(scan.vehicle_id)) == {-1, 21, 22}
    side = scan.roadside_index >= 0
    assert side.any() and np.all(scan.vehicle_id[side] == -1) and np.all(~scan.ground[side])
    assert scan.roadside_index.max() < len(objects)
    # the roadside owners, as cast, match the footprints they hit
    p = scan.points_global()[side]
    for j in np.unique(scan.roadside_index[side])[:20]:
        poly = objects.polygon(int(j))
        pts = p[scan.roadside_index[side] == j]
        assert np.all(np.linalg.norm(pts[:, None, :2] - poly[None], axis=2).min(axis=1) < 1.0)


def test_config_validation():
    assert Lidar3DConfig().rays == 28_800
    assert np.allclose(np.degrees(Lidar3DConfig().elevations), np.arange(-15, 16, 2))
    assert np.allclose(np.linalg.norm(Lidar3DConfig().directions, axis=1), 1.0)
    for kwargs, field in (
        ({"beams": 0}, "beams"),
        ({"beams": 1}, "elevation_min_deg"),
        ({"elevation_min_deg": 20.0}, "elevation_min_deg"),
        ({"elevation_max_deg": 95.0}, "elevation_max_deg"),
        ({"resolution_deg": 0.7}, "resolution_deg"),
        ({"resolution_deg": -0.2}, "resolution_deg"),
        ({"max_range": float("inf")}, "max_range"),
        ({"min_range": 200.0}, "min_range"),
        ({"range_noise_std": -1.0}, "range_noise_std"),
        ({"dropout_probability": 1.5}, "dropout_probability"),
        ({"rate_hz": 0.0}, "rate_hz"),
        ({"mount_z": float("nan")}, "mount_z"),
        ({"mount_pitch_deg": "5"}, "mount_pitch_deg"),
    ):
        with pytest.raises(ValueError, match=field):
            Lidar3DConfig(**kwargs)
    with pytest.raises(ValueError, match="Lidar3DConfig"):
        Lidar3D(object())


def test_cast_and_prism_validation():
    d = coarse_directions()
    with pytest.raises(ValueError, match="above the ground"):
        cast_3d([0, 0, -0.5], d, Prisms.empty(), FlatGround(), MAX_RANGE)
    with pytest.raises(ValueError, match="vertical"):
        cast_3d([0, 0, 1], [[0.0, 0.0, 1.0]], Prisms.empty(), FlatGround(), MAX_RANGE)
    with pytest.raises(ValueError, match="unit"):
        cast_3d([0, 0, 1], [[2.0, 0.0, 0.0]], Prisms.empty(), FlatGround(), MAX_RANGE)
    with pytest.raises(ValueError, match="max_range"):
        cast_3d([0, 0, 1], d, Prisms.empty(), FlatGround(), 0.0)
    with pytest.raises(ValueError, match="top must be above base"):
        Prisms.from_rectangles([[5.0, 0.0]], 0.0, 4.0, 2.0, 1.0, 1.0)
    clockwise = np.array([[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]])
    with pytest.raises(ValueError, match="counter-clockwise"):
        Prisms.from_polygons(clockwise, [0, 4], 0.0, 1.0)
    concave = np.array([[0.0, 0.0], [2.0, 0.0], [1.0, 0.2], [2.0, 2.0], [0.0, 2.0]])
    with pytest.raises(ValueError, match="convex"):
        Prisms.from_polygons(concave, [0, 5], 0.0, 1.0)


def test_ground_hits_on_a_curved_road_match_a_dense_march():
    """The march finds the first crossing of the casting surface: compared with dense 2 cm sampling
    of the same surface along every ray plus bisection (and, for the heights, with the exact road)."""
    k = 1.0 / 120.0
    road = Road.from_curvature([(40.0, 0.0, 0.0), (40.0, 0.0, k), (120.0, k, k)], lanes=3)
    ground = RoadGround(road, grade=-0.05, bank=0.04)
    grid = ground.grid
    rng = np.random.default_rng(8)
    for s_c, n_c in ((90.0, -1.75), (120.0, 7.0)):
        xy = road.to_cartesian(s_c, n_c)
        origin = np.array([xy[0], xy[1], float(ground.height(xy[None])[0]) + 1.9])
        d = coarse_directions(rng.uniform(-math.pi, math.pi))
        result = cast_3d(origin, d, Prisms.empty(), ground, 60.0)
        rho = np.hypot(d[:, 0], d[:, 1])
        t = np.arange(0.0, 60.0, 0.02)
        cand = np.flatnonzero(d[:, 2] < 0.12)
        hit = np.zeros(cand.size, dtype=bool)
        j = np.zeros(cand.size, dtype=np.int64)
        for c0 in range(0, cand.size, 300):  # in chunks: 300 rays x 3000 samples at a time
            c = cand[c0 : c0 + 300]
            f = origin[2] + (d[c, 2] / rho[c])[:, None] * t - grid.height(
                (origin[0] + (d[c, 0] / rho[c])[:, None] * t).ravel(),
                (origin[1] + (d[c, 1] / rho[c])[:, None] * t).ravel(),
            ).reshape(c.size, t.size)
            below = (f <= 0.0) & (t[None, :] <= 60.0 * rho[c, None])  # within the slant range
            hit[c0 : c0 + 300] = below.any(axis=1)
            j[c0 : c0 + 300] = np.argmax(below, axis=1)
        lo, hi = t[np.maximum(j - 1, 0)], t[j]
        ray = cand[hit]
        lo, hi = lo[hit], hi[hit]
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            fm = origin[2] + d[ray, 2] / rho[ray] * mid - grid.height(
                origin[0] + d[ray, 0] / rho[ray] * mid, origin[1] + d[ray, 1] / rho[ray] * mid
            )
            lo, hi = np.where(fm > 0.0, mid, lo), np.where(fm > 0.0, hi, mid)
        expected = np.full(len(d), np.inf)
        expected[ray] = hi / rho[ray]
        assert np.array_equal(result.ground, np.isfinite(expected))
        assert np.allclose(result.range[ray], expected[ray], rtol=1e-8, atol=1e-9)
        assert result.ground.sum() > 1000
        # the points are on the true (exact) surface within the grid's interpolation error
        p = origin + d[ray] * result.range[ray, None]
        assert np.abs(p[:, 2] - ground.height(p[:, :2])).max() <= 1e-3


def oracle_polygon_prisms(origin: np.ndarray, d: np.ndarray, polygons: list[np.ndarray], base, top, owners):
    """Slant range and owner of the first hit per ray on upright prisms over convex CCW polygons, face
    by face: every side wall (a vertical rectangle) and the roof and floor (the polygon at ``top``
    and ``base``), each intersected with the ray's line and checked for containment."""
    best = np.full(len(d), np.inf)
    who = np.full(len(d), -1)
    for poly, lo, hi, owner in zip(polygons, base, top, owners):
        cands = []
        for a, b in zip(poly, np.roll(poly, -1, axis=0)):
            e = b - a
            nu = np.array([e[1], -e[0]])
            with np.errstate(divide="ignore", invalid="ignore"):
                r = ((a - origin[:2]) @ nu) / (d[:, :2] @ nu)
            p = origin + d * np.where(np.isfinite(r), r, 0.0)[:, None]
            along = ((p[:, :2] - a) @ e) / (e @ e)
            ok = np.isfinite(r) & (along >= 0.0) & (along <= 1.0) & (p[:, 2] >= lo) & (p[:, 2] <= hi)
            cands.append(np.where(ok, r, np.inf))
        for z in (lo, hi):
            with np.errstate(divide="ignore", invalid="ignore"):
                r = (z - origin[2]) / d[:, 2]
            p = origin + d * np.where(np.isfinite(r), r, 0.0)[:, None]
            edge = np.roll(poly, -1, axis=0) - poly
            rel = p[:, None, :2] - poly[None]
            inside = np.all(edge[None, :, 0] * rel[..., 1] - edge[None, :, 1] * rel[..., 0] >= 0.0, axis=1)
            cands.append(np.where(np.isfinite(r) & inside, r, np.inf))
        r = np.min(np.where(np.stack(cands) > 0.0, np.stack(cands), np.inf), axis=0)
        r = np.where(r <= MAX_RANGE, r, np.inf)
        better = r < best
        best[better] = r[better]
        who[better] = owner
    return best, who


def test_convex_prisms_against_a_face_by_face_oracle():
    rng = np.random.default_rng(21)
    road, _ = straight_road(0.3)
    config = ClutterConfig(post_spacing=6.0, tree_density=30.0, parked_car_density=10.0)
    objects = generate_roadside(road, config, rng=rng)
    near = np.flatnonzero(np.hypot(*objects.centre.T) < 45.0)
    polygons = [objects.polygon(int(j)) for j in near]
    for _ in range(12):  # random convex polygons, 3 to ~10 vertices
        c = rng.uniform(-40.0, 40.0, 2)
        pts = c + rng.normal(0.0, 1.5, (rng.integers(3, 12), 2))
        hull = ConvexHull(pts)
        polygons.append(pts[hull.vertices])  # counter-clockwise
    polygons.append(np.array([[-6.0, -6.0], [6.0, -6.0], [6.0, 6.0], [-6.0, 6.0]]))  # a canopy overhead
    count = len(polygons)
    base = rng.choice([0.0, 0.4, 2.3], count)
    top = base + rng.uniform(0.5, 6.0, count)
    base[-1], top[-1] = 4.0, 4.5
    owners = np.arange(count) + 3
    sizes = [len(p) for p in polygons]
    prisms = Prisms.from_polygons(np.concatenate(polygons), np.concatenate([[0], np.cumsum(sizes)]), base, top, owners)
    origin = np.array([0.5, -0.3, 1.9])
    d = coarse_directions(0.2)
    result = cast_3d(origin, d, prisms, FlatGround(), MAX_RANGE)
    br, bo = oracle_polygon_prisms(origin, d, polygons, base, top, owners)
    assert_same(result, *combine(br, bo, oracle_flat(origin, d)))
    assert len(np.unique(result.owner)) > 20 and np.any(result.owner == owners[-1])


# -- the models of real sizes ------------------------------------------------------------------------
#: Per model: beams, lowest and highest elevation (deg), azimuths per revolution (the data sheets).
SHEETS = {"vlp16": (16, -15.0, 15.0, 1800), "vlp32c": (32, -25.0, 15.0, 1800), "hdl64e": (64, -24.9, 2.0, 2000),
          "os1-128": (128, -22.5, 22.5, 1024)}


@pytest.mark.parametrize("name", list(SHEETS))
def test_model_tables_follow_the_data_sheets(name):
    beams, low, high, azimuths = SHEETS[name]
    model = LIDAR3D_MODELS[name]
    config = Lidar3DConfig.of_model(name, max_range=80.0)
    table = np.asarray(model.elevations_deg)
    assert len(table) == beams and table[0] == low and table[-1] == high and np.all(np.diff(table) > 0)
    assert config.azimuth_count == azimuths and config.rays == beams * azimuths == model.rays
    assert config.max_range == 80.0 and np.allclose(np.degrees(config.elevations), table)
    if name == "vlp32c":  # densest around the horizon: 1/3 deg from -4 to +1.667 deg
        near = table[(table >= -4.0) & (table <= 1.67)]
        assert np.allclose(np.diff(near), 1.0 / 3.0, atol=0.002)
    if name == "hdl64e":  # two blocks: ~1/3 deg above -8.33 deg, ~1/2 deg below
        assert np.allclose(np.diff(table[32:]), 10.33 / 31, atol=1e-3) and np.allclose(np.diff(table[:32]), 16.03 / 31, atol=1e-3)


@pytest.mark.parametrize("name", list(SHEETS))
def test_each_models_beams_meet_flat_ground_at_their_rings(name):
    """Over flat ground from 1.9 m, a beam at elevation ``e < 0`` returns a ring at horizontal range
    ``1.9 / tan(-e)`` (geometry), within the range noise; beams that reach no ground within range and
    upward beams return nothing."""
    config = Lidar3DConfig.of_model(name, resolution_deg=2.0, range_noise_std=0.0, dropout_probability=0.0)
    scan = Lidar3D(config).scan(np.zeros(3), 0.3, Prisms.empty(), FlatGround(), vehicle_ids=[], rng=np.random.default_rng(0))
    assert scan.ground.all()
    elevation = np.radians(np.asarray(LIDAR3D_MODELS[name].elevations_deg))
    ring = 1.9 / np.tan(-np.minimum(elevation, -1e-9))
    slant = 1.9 / np.sin(-np.minimum(elevation, -1e-9))
    reaches = (elevation < 0) & (slant <= config.max_range) & (slant >= config.min_range)
    assert sorted(set(scan.beam.tolist())) == np.flatnonzero(reaches).tolist()
    assert np.all(np.bincount(scan.beam, minlength=len(elevation))[reaches] == config.azimuth_count)
    np.testing.assert_allclose(np.hypot(scan.points[:, 0], scan.points[:, 1]), ring[scan.beam], rtol=1e-9)
    np.testing.assert_allclose(scan.elevation, elevation[scan.beam], atol=1e-12)


def test_of_model_errors():
    with pytest.raises(ValueError, match="one of"):
        Lidar3DConfig.of_model("vlp64")
    with pytest.raises(ValueError, match="beams is the model's"):
        Lidar3DConfig.of_model("vlp32c", beams=16)
    with pytest.raises(ValueError, match="elevations_deg must hold beams"):
        Lidar3DConfig(beams=3, elevation_min_deg=-10.0, elevation_max_deg=10.0, elevations_deg=(-10.0, 5.0, 0.0))
