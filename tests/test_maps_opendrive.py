"""tracker.maps.opendrive on small hand-written OpenDRIVE files: each plan-view geometry against its
closed form, lane offsets and widths, left (oncoming) lanes, and links through a junction."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import fresnel

from tracker.maps import read_map, route_lanelets, route_road


def _write(tmp_path, body: str, name: str = "m.xodr"):
    path = tmp_path / name
    path.write_text(f'<?xml version="1.0"?>\n<OpenDRIVE><header revMajor="1" revMinor="6"/>{body}</OpenDRIVE>\n')
    return path


def _road(rid, length, geometry, lanes, *, junction="-1", link="", offset=""):
    return (f'<road id="{rid}" length="{length}" junction="{junction}">{link}<planView>{geometry}</planView>'
            f'<lanes>{offset}<laneSection s="0"><center><lane id="0" type="none"/></center>{lanes}</laneSection></lanes></road>')


def _lane(lid, width, link=""):
    return f'<lane id="{lid}" type="driving"><link>{link}</link><width sOffset="0" a="{width}" b="0" c="0" d="0"/></lane>'


TWO_WAY = '<left>' + _lane(1, 3.0) + '</left><right>' + _lane(-1, 3.5) + '</right>'


def _by_source(graph):
    return {ll.source: ll for ll in graph.lanelets}


def test_arc_with_lane_offset_and_an_oncoming_lane(tmp_path):
    radius, length = 50.0, 60.0
    geo = f'<geometry s="0" x="0" y="0" hdg="0" length="{length}"><arc curvature="{1 / radius}"/></geometry>'
    offset = '<laneOffset s="0" a="0.5" b="0" c="0" d="0"/>'
    g = read_map(_write(tmp_path, _road("1", length, geo, TWO_WAY, offset=offset)))
    lanes = _by_source(g)
    right, left = lanes["road 1 laneSection 0 lane -1"], lanes["road 1 laneSection 0 lane 1"]
    centre = np.array([0.0, radius])
    # offsets are toward the centre of the turn (left): distance R - t
    np.testing.assert_allclose(np.hypot(*(right.right - centre).T), radius + 3.0, atol=1e-9)  # t = 0.5 - 3.5
    np.testing.assert_allclose(np.hypot(*(right.left - centre).T), radius - 0.5, atol=1e-9)
    np.testing.assert_allclose(np.hypot(*(left.right - centre).T), radius - 3.5, atol=1e-9)  # t = 0.5 + 3.0
    # the right lane drives along s, the left one against it; each is the other's oncoming neighbour
    assert np.allclose(right.left[0], [0.0, 0.5]) and np.allclose(left.left[-1], [0.0, 0.5])
    assert right.left_neighbor == left.id and not right.left_same_direction
    assert left.left_neighbor == right.id and not left.left_same_direction
    # a road driven along the arc: two lanes, the left one oncoming, 6.5 m wide in all
    road = route_road(g, (0.5, -1.0, 0.0))
    assert list(road.lane_directions) == [1, -1]
    right_edge, left_edge = road.edges(np.array([20.0]))
    assert abs(left_edge[0] - right_edge[0] - 6.5) < 0.01


def test_spiral_poly3_and_parampoly3_follow_their_closed_forms(tmp_path):
    length, k1 = 50.0, 0.04
    spiral = f'<geometry s="0" x="0" y="0" hdg="0" length="{length}"><spiral curvStart="0" curvEnd="{k1}"/></geometry>'
    c = 0.01  # v = c u^2
    u_end = 30.0
    arc_len = float(np.trapezoid(np.sqrt(1 + (2 * c * np.linspace(0, u_end, 200001)) ** 2), np.linspace(0, u_end, 200001)))
    poly3 = f'<geometry s="0" x="0" y="0" hdg="0.3" length="{arc_len}"><poly3 a="0" b="0" c="{c}" d="0"/></geometry>'
    param = (f'<geometry s="0" x="0" y="0" hdg="0.3" length="{arc_len}"><paramPoly3 aU="0" bU="{u_end}" cU="0" dU="0" '
             f'aV="0" bV="0" cV="{c * u_end**2}" dV="0" pRange="normalized"/></geometry>')
    right = '<right>' + _lane(-1, 3.5) + '</right>'
    body = _road("1", length, spiral, right) + _road("2", arc_len, poly3, right) + _road("3", arc_len, param, right)
    lanes = _by_source(read_map(_write(tmp_path, body)))
    # spiral: the reference line (the lane's left border) ends where the Fresnel integrals say
    a = k1 / length / 2.0  # heading = a s^2
    scale = np.sqrt(np.pi / (2 * a))
    fs, fc = fresnel(length / scale)
    end = lanes["road 1 laneSection 0 lane -1"].left[-1]
    np.testing.assert_allclose(end, [scale * fc, scale * fs], atol=2e-3)
    # poly3 and paramPoly3: the reference points satisfy v = c u^2 in the frame turned by hdg
    for rid in ("2", "3"):
        ref = lanes[f"road {rid} laneSection 0 lane -1"].left
        rot = np.array([[np.cos(0.3), np.sin(0.3)], [-np.sin(0.3), np.cos(0.3)]])
        u, v = (ref @ rot.T).T
        np.testing.assert_allclose(v, c * u**2, atol=2e-3)
        assert abs(u[-1] - u_end) < 0.01


def test_links_through_a_junction(tmp_path):
    line = '<geometry s="0" x="{x}" y="0" hdg="0" length="{n}"><line/></geometry>'

    def lanes(pred, succ):  # the connecting road's lanes, linked to lanes pred / succ of the roads at its ends
        return ('<left>' + _lane(1, 3.5, f'<predecessor id="{pred}"/><successor id="{succ}"/>') + '</left>'
                '<right>' + _lane(-1, 3.5, f'<predecessor id="-{pred}"/><successor id="-{succ}"/>') + '</right>')

    one = _road("1", 50, line.format(x=0, n=50), '<left>' + _lane(1, 3.5) + '</left><right>' + _lane(-1, 3.5) + '</right>',
                link='<link><successor elementType="junction" elementId="100"/></link>')
    two = _road("2", 50, line.format(x=60, n=50), '<left>' + _lane(1, 3.5) + '</left><right>' + _lane(-1, 3.5) + '</right>',
                link='<link><predecessor elementType="junction" elementId="100"/></link>')
    conn = _road("10", 10, line.format(x=50, n=10), lanes(1, 1), junction="100",
                 link='<link><predecessor elementType="road" elementId="1" contactPoint="end"/>'
                      '<successor elementType="road" elementId="2" contactPoint="start"/></link>')
    junction = ('<junction id="100">'
                '<connection id="0" incomingRoad="1" connectingRoad="10" contactPoint="start"><laneLink from="-1" to="-1"/></connection>'
                '<connection id="1" incomingRoad="2" connectingRoad="10" contactPoint="end"><laneLink from="1" to="1"/></connection>'
                '</junction>')
    g = read_map(_write(tmp_path, one + two + conn + junction))
    by = _by_source(g)
    lane = {key: by[f"road {key[0]} laneSection 0 lane {key[1]}"].id for key in
            [("1", -1), ("1", 1), ("2", -1), ("2", 1), ("10", -1), ("10", 1)]}
    assert g.lanelet(lane["1", -1]).successors == (lane["10", -1],)
    assert g.lanelet(lane["10", -1]).successors == (lane["2", -1],)
    assert g.lanelet(lane["2", 1]).successors == (lane["10", 1],)  # left lanes drive against s
    assert g.lanelet(lane["10", 1]).successors == (lane["1", 1],)
    assert g.lanelet(lane["1", 1]).successors == ()
    assert route_lanelets(g, (5.0, -1.5, 0.0), (100.0, -1.5)) == [lane["1", -1], lane["10", -1], lane["2", -1]]
    road = route_road(g, (5.0, -1.5, 0.0), (100.0, -1.5))
    assert abs(road.length - 110.0) < 0.5
    assert list(road.lane_directions) == [1, -1]


def test_broken_links_and_missing_elements(tmp_path):
    line = '<geometry s="0" x="0" y="0" hdg="0" length="50"><line/></geometry>'
    right = '<right>' + _lane(-1, 3.5) + '</right>'
    bad = _road("1", 50, line, right, link='<link><successor elementType="junction" elementId="9"/></link>')
    with pytest.raises(ValueError, match=r"^m.xodr: road 1 names successor junction 9, which is not in the file$"):
        read_map(_write(tmp_path, bad))
    with pytest.raises(ValueError, match=r"^m.xodr: road 1 has no planView geometry$"):
        read_map(_write(tmp_path, _road("1", 50, "", right)))
    wrong_side = '<right>' + _lane(2, 3.5) + '</right>'
    with pytest.raises(ValueError, match=r"^m.xodr: road 1 laneSection 0: lane 2 is in <right>; right lanes have negative ids$"):
        read_map(_write(tmp_path, _road("1", 50, line, wrong_side)))
    no_length = line.replace(' length="50"', "")
    with pytest.raises(ValueError, match=r"^m.xodr: road 1 geometry 0 has no attribute 'length'$"):
        read_map(_write(tmp_path, _road("1", 50, no_length, right)))
