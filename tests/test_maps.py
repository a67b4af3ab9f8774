"""tracker.maps: lane maps read from CommonRoad, Lanelet2 and OpenDRIVE files, and the road of a route.

The CommonRoad copies in tests/data always run; every file of /work/shared/data/commonroad runs when
that directory is there. Numbers are checked against the map's own geometry (tests/maps_checks.py),
against lanelet2's and pyxodr's readings, and between equivalent maps in different formats.
"""

from __future__ import annotations

import os
import re
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
from maps_checks import (
    edge_deviation,
    longest_route_start,
    on_road_fraction,
    open_scenario,
    planning_start,
    vehicle_centres,
)

from tracker.lanes import EDGE_TABLE_STEP
from tracker.maps import (
    LaneGraph,
    Lanelet,
    read_map,
    route_corridor,
    route_lanelets,
    route_road,
)
from tracker.maps.commonroad import graph_from_lanelet_network
from tracker.maps.graph import point_polyline_distance

pytest.importorskip("commonroad")
pytest.importorskip("lanelet2")

DATA = Path(__file__).resolve().parent / "data"
#: More CommonRoad scenario files to check every route on (skipped where absent): $EOT_COMMONROAD_DIR, by
#: default the workplace's shared data beside the repository (held-out recordings are checked the same way)
SHARED = Path(os.environ.get("EOT_COMMONROAD_DIR", Path(__file__).resolve().parents[2] / "shared" / "data" / "commonroad"))
#: the map the shipped scenario scenarios/maps/freeway-us101.toml runs on (one copy in the repository)
US101_4 = Path(__file__).resolve().parents[1] / "scenarios" / "maps" / "USA_US101-4_1_T-1.xml"
COPIES = sorted([*DATA.glob("*.xml"), US101_4])
SHARED_FILES = sorted(SHARED.glob("*.xml")) if SHARED.is_dir() else []
US101_1, LANKER = DATA / "USA_US101-1_1_T-1.xml", DATA / "USA_Lanker-1_1_T-1.xml"
#: The Lanelet2 copy's origin (tests/data/make_maps.py).
OSM_ORIGIN = (34.1398, -118.3703)

_graphs: dict[Path, LaneGraph] = {}


def graph_of(path: Path) -> LaneGraph:
    """The lane graph of a map file; of a shared CommonRoad file, from the scenario read once for its
    vehicles too (tests/data's copies go through read_map)."""
    if path not in _graphs:
        if path.parent == SHARED:
            _graphs[path] = graph_from_lanelet_network(open_scenario(path)[0].lanelet_network, source=path.name)
        else:
            _graphs[path] = read_map(path, origin=OSM_ORIGIN) if path.suffix == ".osm" else read_map(path)
    return _graphs[path]


# -- the lane graph ------------------------------------------------------------------------------------
def test_commonroad_topology_and_geometry():
    g = graph_of(US101_4)
    assert len(g) == 12
    two = g.lanelet(2)
    assert two.successors == (4,) and g.lanelet(4).predecessors == (2,)
    assert two.right_neighbor == 42 and two.right_same_direction and two.left_neighbor is None
    # the centerline is the boundaries' midpoint, vertex by vertex (same vertex counts here)
    np.testing.assert_allclose(two.center, 0.5 * (two.left + two.right), atol=1e-12)
    # a point on each lanelet's centerline lies inside it and is located there
    mids = np.array([ll.center[len(ll.center) // 2] for ll in g.lanelets])
    assert (g.locate(mids) == g.ids).all() or (np.diag(g.contains(mids))).all()
    assert np.diag(g.contains(mids)).all()
    far = np.array([[1e4, 1e4]])
    assert g.locate(far)[0] == -1


def test_oncoming_neighbours_in_the_urban_map():
    g = graph_of(LANKER)
    ll = g.lanelet(3419)
    assert ll.left_neighbor == 3464 and not ll.left_same_direction
    # oncoming lanelets run the other way: their headings differ by about pi
    mid = ll.center[len(ll.center) // 2][None]
    turn = np.angle(np.exp(1j * (g.heading_at(3464, mid) - g.heading_at(3419, mid))))
    assert abs(abs(turn[0]) - np.pi) < 0.3


def test_locate_with_yaw_picks_the_lanelet_driven_that_way():
    g = graph_of(LANKER)
    ll = g.lanelet(3419)
    p = ll.center[1][None]
    yaw = g.heading_at(3419, p)
    assert g.locate(p, yaw)[0] == 3419
    assert g.locate(p, yaw + np.pi)[0] == -1  # nothing on 3419's polygon drives the other way


# -- routes on every CommonRoad map --------------------------------------------------------------------
ROUTE_FILES = [pytest.param(p, id=f"data/{p.name}") for p in COPIES] + [pytest.param(p, id=f"shared/{p.name}") for p in SHARED_FILES]


@pytest.mark.parametrize("path", ROUTE_FILES)
def test_route_road_follows_the_lanelets_and_holds_the_vehicles(path):
    graph = graph_of(path)
    centres = vehicle_centres(path)
    starts = [planning_start(path)]
    if path.name.startswith("USA_Lanker"):
        starts.append(longest_route_start(graph))  # across the intersection
    for start in starts:
        corridor = route_corridor(graph, start)
        road = corridor.road
        assert road.length > 50.0
        # edges within 0.2 m of the outermost chained lanelet boundaries (away from the joins where a
        # lane begins or ends at once: there the edges step over tracker.lanes.EDGE_TABLE_STEP)
        assert edge_deviation(graph, corridor, join_margin=EDGE_TABLE_STEP) <= 0.2
        assert edge_deviation(graph, corridor) <= 0.3  # within 0.1 m of such a join the edge is mid-step
        fraction, count = on_road_fraction(graph, corridor, centres)
        assert count > 50 and fraction >= 0.99, (fraction, count)
        # the start pose is on the road, in a lane driven its way
        s, n = road.to_frenet(np.array([start[:2]]))
        assert road.on_road(np.array([start[:2]]))[0]
        assert road.lane_direction(s, n)[0] == 1


def test_auxiliary_lane_begins_with_zero_width():
    corridor = route_corridor(graph_of(US101_4), planning_start(US101_4))
    road = corridor.road
    assert corridor.route == (2, 4)
    aux = [j for j in range(road.lanes) if 16 in corridor.lanes[:, j]]
    assert len(aux) == 1
    j = aux[0]
    join = corridor.route_starts[1]
    centres = road.lane_centers_at(np.array([join - 5.0, join + 5.0]))
    assert np.isnan(centres[0, j]) and np.isfinite(centres[1, j])
    # its width where present is lanelet 16's width: distance between its boundaries
    s = join + 10.0
    width = np.diff(road.layout.boundaries_at(s))[j]
    ll = graph_of(US101_4).lanelet(16)
    mid_right = road.to_cartesian(s, road.layout.boundaries_at(s)[j])
    assert point_polyline_distance(np.atleast_2d(mid_right), ll.right)[0] < 0.05
    assert 3.0 < width < 4.5


def test_two_way_urban_road_has_oncoming_lanes_and_leaves_crossing_roads_off():
    graph = graph_of(LANKER)
    corridor = route_corridor(graph, planning_start(LANKER))
    road = corridor.road
    assert road.two_way and (road.lane_directions == -1).sum() >= 3
    oncoming = {int(i) for j in np.flatnonzero(road.lane_directions == -1) for i in corridor.lanes[:, j] if i >= 0}
    assert 3440 in oncoming and 3419 in oncoming
    # lanelets that cross the route in the intersection are not neighbours: their points away from
    # the corridor's lanelets are off the road
    others = [ll for ll in graph.lanelets if ll.id not in corridor.members]
    pts = np.vstack([ll.center for ll in others])
    outside = ~graph.contains(pts, sorted(corridor.members)).any(axis=1)
    assert outside.sum() > 100
    assert road.on_road(pts[outside]).mean() < 0.05


def test_route_to_a_goal_and_through_via_points():
    graph = graph_of(LANKER)
    # from the middle lane of the southern approach to the outgoing lanelet of a right turn: the route
    # starts in the rightmost lane beside the start (the only one that turns right) and turns
    mid = graph.lanelet(3567).center[1]
    start = (float(mid[0]), float(mid[1]), float(graph.heading_at(3567, mid[None])[0]))
    goal = graph.lanelet(3495).center[2]
    route = route_lanelets(graph, start, goal)
    assert route == [3573, 3680, 3495]
    road = route_road(graph, start, goal)
    assert road.on_road(np.vstack([goal, mid]))[:2].all()
    # through a via point on the left turn, then on
    via = graph.lanelet(3670).center[4]
    route = route_lanelets(graph, start, via=[via])
    assert route[:3] == [3561, 3671, 3670]
    with pytest.raises(ValueError, match=r"^USA_Lanker-1_1_T-1.xml: no route along successors from lanelet"):
        route_lanelets(graph, start, graph.lanelet(3473).center[1])  # an approach from the west: not reachable
    with pytest.raises(ValueError, match=r"lies on no lanelet"):
        route_lanelets(graph, (1e4, 1e4, 0.0))


def test_route_with_a_lane_change_after_a_join():
    graph = graph_of(US101_4)
    goal = graph.lanelet(16).center[-3]  # the auxiliary lane, beside lanelet 13 after the join
    corridor = route_corridor(graph, planning_start(US101_4), goal)
    assert corridor.route == (12, 13, 16)  # begins in the rightmost lane, changes into the auxiliary lane
    road = corridor.road
    # the centerline ends on lanelet 16's centerline and starts on lanelet 12's
    ends = road.to_cartesian(np.array([0.0, road.length]), np.zeros(2))
    from tracker.maps.graph import point_polyline_distance as dist
    assert dist(ends[:1], graph.lanelet(12).center)[0] < 0.05
    assert dist(ends[1:], graph.lanelet(16).center)[0] < 0.05
    assert road.on_road(goal[None])[0]
    assert edge_deviation(graph, corridor, join_margin=EDGE_TABLE_STEP) <= 0.2
    with pytest.raises(ValueError, match=r"lanelet 40 neither succeeds lanelet 12 nor lies beside it"):
        route_corridor(graph, planning_start(US101_4), route=[12, 40])


# -- the same map in other formats ---------------------------------------------------------------------
def _road_gap(a, b, margin: float = 5.0) -> float:
    """Largest distance (m) between two roads' centerlines and edges over ``a``'s interior: points of
    ``a`` projected on ``b`` and compared there."""
    ra, rb = a.road, b.road
    s = np.linspace(margin, ra.length - margin, 400)
    sb, nb = rb.to_frenet(ra.to_cartesian(s, np.zeros_like(s)))
    worst = float(np.abs(nb).max())
    for side in (0, 1):
        xy = ra.to_cartesian(s, ra.edges(s)[side])
        sb, nb = rb.to_frenet(xy)
        worst = max(worst, float(np.abs(nb - rb.edges(sb)[side]).max()))
    return worst


@pytest.mark.parametrize(("other", "source"), [
    (DATA / "USA_US101-1_1_T-1.xodr", US101_1),
    (DATA / "USA_US101-4_1_T-1.osm", US101_4),
])
def test_other_formats_give_the_same_road(other, source):
    start = planning_start(source)
    a = route_corridor(graph_of(source), start)
    b = route_corridor(graph_of(other), start)
    assert len(graph_of(other)) == (len(graph_of(source)))
    assert abs(a.road.length - b.road.length) < 0.1
    assert a.road.lanes == b.road.lanes
    assert _road_gap(a, b) <= 0.05
    assert _road_gap(b, a) <= 0.05


def test_opendrive_lanes_match_pyxodr():
    pyxodr = pytest.importorskip("pyxodr.road_objects.network")
    path = DATA / "USA_US101-1_1_T-1.xodr"
    net = pyxodr.RoadNetwork(str(path), resolution=0.1)
    ours = {ll.source: ll for ll in graph_of(path).lanelets}
    checked = 0
    # pyxodr's points lie within 2 cm of our borders, ours within 5 cm of pyxodr's: the generated
    # road's reference line is a polyline turning by up to 0.05 rad at its corners, where borders 10-20 m
    # off it jump along themselves by the offset times the turn; pyxodr takes its normals from
    # differences of its 0.1 m samples and so rounds those corners (a lane width or sign error would
    # show as metres)
    for road in net.get_roads():
        for k, section in enumerate(road.lane_sections):
            for lane in section.right_lanes:
                ll = ours[f"road {road.id} laneSection {k} lane {lane.id}"]
                outer = np.asarray(lane.boundary_line)[:, :2]
                assert point_polyline_distance(outer, ll.right).max() < 0.02
                # pyxodr's samples (every 0.1 m) stop short of the lane's end: compare ours up to its last one
                ahead = (ll.right - outer[-1]) @ (outer[-1] - outer[-2]) > 0.0
                assert point_polyline_distance(ll.right[~ahead], outer).max() < 0.05
                checked += 1
    assert checked == 6


def test_lanelet2_copy_matches_lanelet2_positions():
    import lanelet2
    from lanelet2.projection import UtmProjector

    path = DATA / "USA_US101-4_1_T-1.osm"
    lmap = lanelet2.io.load(str(path), UtmProjector(lanelet2.io.Origin(*OSM_ORIGIN)))
    g = graph_of(path)
    for ll in lmap.laneletLayer:
        left = np.array([[p.x, p.y] for p in ll.leftBound])
        np.testing.assert_allclose(g.lanelet(ll.id).left, left, atol=1e-9)
    # and the CommonRoad original: the same outer boundaries within a millimetre
    cr = graph_of(US101_4)
    for ll in cr.lanelets:
        assert point_polyline_distance(ll.right, g.lanelet(ll.id).right).max() < 0.05


def test_lanelet2_local_projection_and_default_origin():
    path = DATA / "USA_US101-4_1_T-1.osm"
    utm = graph_of(path)
    local = read_map(path, origin=OSM_ORIGIN, projection="local")
    # ground metres vs UTM grid metres: the same shapes within UTM's scale (k = 0.9996-1.001) and
    # its grid convergence (~1.5 deg at this longitude: a rotation about the origin)
    a, b = utm.lanelet(2).left, local.lanelet(2).left
    ratio = np.hypot(*np.diff(b, axis=0).T).sum() / np.hypot(*np.diff(a, axis=0).T).sum()
    assert 0.999 < ratio < 1.0011
    assert np.abs(np.hypot(*a.T) - np.hypot(*b.T)).max() < 0.002 * np.hypot(*a.T).max() + 0.01
    # without an origin the first node is the origin: the same map shifted
    first = read_map(path)
    shift = first.lanelet(2).left - utm.lanelet(2).left
    np.testing.assert_allclose(shift, shift[:1].repeat(len(shift), axis=0), atol=1e-6)
    with pytest.raises(ValueError, match="projection must be 'utm' or 'local'"):
        read_map(path, projection="mercator")


# -- broken files ----------------------------------------------------------------------------------------
def _broken(tmp_path, source: Path, edit, name: str | None = None) -> Path:
    text = source.read_text()
    out = tmp_path / (name or source.name)
    out.write_text(edit(text))
    return out


def _one_line(err: pytest.ExceptionInfo) -> str:
    msg = str(err.value)
    assert "\n" not in msg
    return msg


def test_broken_commonroad_files(tmp_path):
    with pytest.raises(ValueError) as err:
        read_map(_broken(tmp_path, US101_1, lambda t: t[: len(t) // 2]))
    assert _one_line(err).startswith("USA_US101-1_1_T-1.xml: not well-formed XML")
    with pytest.raises(ValueError) as err:
        no_left = lambda t: re.sub(r'(<lanelet id="538">\s*)<leftBound>.*?</leftBound>', r"\1", t, count=1, flags=re.DOTALL)
        read_map(_broken(tmp_path, US101_1, no_left))
    assert "lanelet 538 has a left boundary of 0 points; need at least 2" in _one_line(err)
    with pytest.raises(ValueError) as err:
        read_map(_broken(tmp_path, US101_4, lambda t: t.replace('<successor ref="4"/>', '<successor ref="99999"/>', 1)))
    assert _one_line(err) == "USA_US101-4_1_T-1.xml: lanelet 2 names successor 99999, which is not in the map"
    with pytest.raises(FileNotFoundError) as err:
        read_map(tmp_path / "absent.xml")
    assert "absent.xml: no such map file" in _one_line(err)
    with pytest.raises(ValueError, match=r"^map.geojson: unknown map format '.geojson'"):
        read_map(tmp_path / "map.geojson")


def test_broken_opendrive_and_lanelet2_files(tmp_path):
    xodr = DATA / "USA_US101-1_1_T-1.xodr"
    with pytest.raises(ValueError) as err:
        read_map(_broken(tmp_path, xodr, lambda t: t[: len(t) // 3]))
    assert _one_line(err).startswith("USA_US101-1_1_T-1.xodr: not well-formed XML")
    with pytest.raises(ValueError) as err:
        read_map(_broken(tmp_path, xodr, lambda t: t.replace("<line />", "<clothoid />", 1)))
    assert _one_line(err) == "USA_US101-1_1_T-1.xodr: road 1 geometry 0 is a <clothoid>, which is not supported"
    osm = DATA / "USA_US101-4_1_T-1.osm"
    with pytest.raises(ValueError) as err:
        read_map(_broken(tmp_path, osm, lambda t: t[: len(t) // 2]), origin=OSM_ORIGIN)
    assert _one_line(err).startswith("USA_US101-4_1_T-1.osm: ")
    # a lanelet whose left boundary way is gone
    text = osm.read_text()
    rel = text.index('<relation id="2"')
    ref = re.search(r'<member type="way" ref="(\d+)" role="left"', text[rel:]).group(1)
    with pytest.raises(ValueError) as err:
        read_map(_broken(tmp_path, osm, lambda t: re.sub(rf'<way id="{ref}".*?</way>', "", t, count=1, flags=re.DOTALL)), origin=OSM_ORIGIN)
    assert _one_line(err).startswith("USA_US101-4_1_T-1.osm: ")
    assert "lanelet 2" in str(err.value)
    with pytest.raises(FileNotFoundError):
        read_map(tmp_path / "absent.osm")


def test_opendrive_link_to_a_missing_road(tmp_path):
    xodr = DATA / "USA_US101-1_1_T-1.xodr"

    def link(text: str) -> str:
        return text.replace("<planView>", '<link><successor elementType="road" elementId="7" contactPoint="start" /></link><planView>', 1)

    with pytest.raises(ValueError) as err:
        read_map(_broken(tmp_path, xodr, link))
    assert _one_line(err) == "USA_US101-1_1_T-1.xodr: road 1 names successor road 7, which is not in the file"


def test_lane_graph_validation_names_the_element():
    sq = np.array([[0.0, 1.0], [10.0, 1.0]])
    with pytest.raises(ValueError, match=r"^m.xml: lanelet 3 has a left boundary of 1 point; need at least 2$"):
        LaneGraph([Lanelet(3, sq[:1], sq - [0, 2])], source="m.xml")
    with pytest.raises(ValueError, match=r"^m.xml: lanelet 3 names successor 4, which is not in the map$"):
        LaneGraph([Lanelet(3, sq, sq - [0, 2], successors=(4,))], source="m.xml")
    with pytest.raises(ValueError, match=r"^m.xml: two lanelets have the id 3$"):
        LaneGraph([Lanelet(3, sq, sq - [0, 2]), Lanelet(3, sq, sq - [0, 2])], source="m.xml")


def test_missing_map_library_is_one_line(monkeypatch, tmp_path):
    for name in [m for m in sys.modules if m == "commonroad" or m.startswith("commonroad.")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "commonroad", None)
    target = tmp_path / "m.xml"
    shutil.copy(US101_1, target)
    with pytest.raises(ImportError) as err:
        read_map(target)
    assert _one_line(err) == "reading CommonRoad maps needs commonroad-io: pip install 'frenet-eot[maps]'"



def test_route_onward_and_behind():
    """``onward`` goes on past the goal's lanelet, ``behind`` begins before the start's (the road a sensor
    at either end still sees): US-101-4's right lane is lanelet 2 (91 m) then lanelet 4 (31 m)."""
    graph = graph_of(US101_4)
    start_in_4, goal_in_4 = (28.87, -26.28, -0.72), (36.5, -32.94)
    assert route_lanelets(graph, start_in_4, goal_in_4) == [4]
    assert route_lanelets(graph, start_in_4, goal_in_4, behind=50.0) == [2, 4]
    centre = graph.lanelet(2).center
    start_in_2, goal_in_2 = (*centre[1], -0.75), tuple(centre[len(centre) // 2])
    assert route_lanelets(graph, start_in_2, goal_in_2) == [2]
    assert route_lanelets(graph, start_in_2, goal_in_2, onward=10.0) == [2, 4]
    road = route_road(graph, start_in_4, goal_in_4, onward=100.0, behind=100.0)  # the whole map: 91 + 31 m
    assert 118.0 < road.length < 126.0
