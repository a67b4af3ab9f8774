"""Write the OpenDRIVE and Lanelet2 copies of a CommonRoad lane map (run once; the outputs are committed).

    PYTHONPATH=. python tests/data/make_maps.py

- ``USA_US101-1_1_T-1.xodr``: the six side-by-side lanelets of ``USA_US101-1_1_T-1.xml`` as one
  OpenDRIVE road of six right lanes. Its reference line is the leftmost lanelet's left boundary, one
  ``line`` geometry per segment; each lane's width is piecewise linear in ``s``, one ``width`` record
  per breakpoint (every reference vertex and every boundary vertex projected on the reference line).
- ``USA_US101-4_1_T-1.osm``: every lanelet of ``USA_US101-4_1_T-1.xml`` (auxiliary lane and two
  sections of lanelets) written by lanelet2's own writer with a UTM projector about ``ORIGIN``.
  A boundary two side-by-side lanelets share is one linestring (the left lanelet's right boundary;
  CommonRoad stores it twice, with vertices up to 2 cm apart), and vertices closer than ``SNAP`` m are
  one point, so successors and neighbours are lanelet2's shared-element topology.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from tracker.maps import read_commonroad

HERE = Path(__file__).resolve().parent
#: Latitude and longitude (deg) of the Lanelet2 map's origin (about where US-101 was recorded).
ORIGIN = (34.1398, -118.3703)
#: Boundary vertices of the CommonRoad map closer than this (m) become one Lanelet2 point.
SNAP = 0.05


def _project(points: np.ndarray, line: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(s, t) of ``points`` on the polyline ``line``: arc length of the nearest point and signed
    lateral offset (positive left)."""
    a, d = line[:-1], np.diff(line, axis=0)
    seg_len = np.hypot(d[:, 0], d[:, 1])
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    rel = points[:, None, :] - a[None]
    u = np.clip(np.einsum("nsj,sj->ns", rel, d) / seg_len**2, 0.0, 1.0)
    gap = rel - u[..., None] * d[None]
    k = np.argmin(np.einsum("nsj,nsj->ns", gap, gap), axis=1)
    rows = np.arange(len(points))
    s = cum[k] + u[rows, k] * seg_len[k]
    t = (d[k, 0] * rel[rows, k, 1] - d[k, 1] * rel[rows, k, 0]) / seg_len[k]
    return s, t


def write_opendrive(source: Path, target: Path) -> None:
    graph = read_commonroad(source)
    leftmost = [ll for ll in graph.lanelets if ll.left_neighbor is None]
    assert len(leftmost) == 1, "one row of side-by-side lanelets expected"
    row = [leftmost[0]]
    while row[-1].right_neighbor is not None:
        row.append(graph.lanelet(row[-1].right_neighbor))
    ref = row[0].left
    d = np.diff(ref, axis=0)
    seg = np.hypot(d[:, 0], d[:, 1])
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    length = cum[-1]
    projected = [_project(ll.right, ref) for ll in row]
    breaks = np.unique(np.concatenate([cum] + [s for s, _ in projected]))
    breaks = breaks[(breaks >= 0.0) & (breaks < length)]
    t = [np.zeros_like(breaks)]
    for s, off in projected:
        order = np.argsort(s)
        t.append(np.interp(breaks, s[order], off[order]))

    root = ET.Element("OpenDRIVE")
    ET.SubElement(root, "header", revMajor="1", revMinor="6", name=source.stem, north="0", south="0", east="0", west="0")
    road = ET.SubElement(root, "road", id="1", junction="-1", length=f"{length:.6f}")
    plan = ET.SubElement(road, "planView")
    for i in range(len(seg)):
        g = ET.SubElement(plan, "geometry", s=f"{cum[i]:.6f}", x=f"{ref[i, 0]:.6f}", y=f"{ref[i, 1]:.6f}",
                          hdg=f"{np.arctan2(d[i, 1], d[i, 0]):.9f}", length=f"{seg[i]:.6f}")
        ET.SubElement(g, "line")
    lanes = ET.SubElement(road, "lanes")
    section = ET.SubElement(lanes, "laneSection", s="0")
    center = ET.SubElement(section, "center")
    ET.SubElement(center, "lane", id="0", type="none", level="false")
    right = ET.SubElement(section, "right")
    for j in range(len(row)):
        lane = ET.SubElement(right, "lane", id=str(-(j + 1)), type="driving", level="false")
        width = t[j] - t[j + 1]
        slope = np.diff(np.append(width, width[-1])) / np.diff(np.append(breaks, length))
        for s0, a, b in zip(breaks, width, slope):
            ET.SubElement(lane, "width", sOffset=f"{s0:.6f}", a=f"{a:.6f}", b=f"{b:.9f}", c="0", d="0")
    ET.indent(root)
    ET.ElementTree(root).write(target, encoding="utf-8", xml_declaration=True)


def write_lanelet2(source: Path, target: Path) -> None:
    import lanelet2
    from lanelet2.core import Lanelet, LaneletMap, LineString3d, Point3d, getId
    from lanelet2.io import Origin
    from lanelet2.projection import UtmProjector

    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    graph = read_commonroad(source)
    # a boundary shared by two side-by-side lanelets is one linestring: the left lanelet's right boundary
    bounds = {}
    for ll in graph.lanelets:
        left = ll.left
        if ll.left_neighbor is not None and ll.left_same_direction:
            left = graph.lanelet(ll.left_neighbor).right
        bounds[ll.id] = (left, ll.right)
    # vertices closer than SNAP m are one point (ends of successive lanelets, ends of shared boundaries)
    allpts = np.vstack([np.vstack(b) for b in bounds.values()])
    pairs = cKDTree(allpts).query_pairs(SNAP, output_type="ndarray")
    adj = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(allpts), len(allpts)))
    _, label = connected_components(adj, directed=False)
    points = {}
    for k in np.unique(label):
        xy = allpts[label == k][0]
        points[k] = Point3d(getId(), float(xy[0]), float(xy[1]), 0.0)
    strings: dict[tuple[int, ...], LineString3d] = {}
    offset = [0]

    def linestring(line: np.ndarray) -> LineString3d:
        pts = [points[label[offset[0] + i]] for i in range(len(line))]
        offset[0] += len(line)
        key = tuple(p.id for p in pts)
        if key in strings:
            return strings[key]
        if key[::-1] in strings:
            return strings[key[::-1]].invert()
        ls = LineString3d(getId(), pts, {"type": "line_thin", "subtype": "dashed"})
        strings[key] = ls
        return ls

    lmap = LaneletMap()
    for ll in graph.lanelets:  # the same order as ``bounds`` (and ``allpts``)
        left, right = bounds[ll.id]
        left_ls = linestring(left)
        lanelet = Lanelet(ll.id, left_ls, linestring(right),
                          {"type": "lanelet", "subtype": "highway", "location": "urban", "one_way": "yes"})
        lmap.add(lanelet)
    lanelet2.io.write(str(target), lmap, UtmProjector(Origin(*ORIGIN)))


if __name__ == "__main__":
    write_opendrive(HERE / "USA_US101-1_1_T-1.xml", HERE / "USA_US101-1_1_T-1.xodr")
    write_lanelet2(HERE.parents[1] / "scenarios" / "maps" / "USA_US101-4_1_T-1.xml", HERE / "USA_US101-4_1_T-1.osm")
