"""Read an OpenDRIVE (.xodr) map into a ``LaneGraph``, with the standard library's XML parser.

Every lane (other than ``type="none"``) of every lane section of every road becomes one lanelet:
its boundaries are the lane's inner and outer borders sampled every ``SAMPLE_SPACING`` m along the
road's reference line and at both sides of every geometry start (where the reference line's heading
jumps, the borders jump too), ordered in its driving direction (right lanes,
negative ids, drive along the reference line; left lanes against it: right-hand traffic).

Read: the plan view (``line``, ``arc``, ``spiral``, ``poly3``, ``paramPoly3`` with either
``pRange``), ``laneOffset``, lane ``width`` and ``border`` records, lane types, lane links between
sections, road links (to roads with ``contactPoint``, and to junctions through their connections'
``laneLink``). Neighbours are the lanes next to each other in a section; the two lanes either side
of the centre lane are oncoming neighbours.

Not read: elevation and superelevation (the map is flat), ``rightHandTraffic``/``rule="LHT"`` (always
right-hand traffic), lane ``height``, road marks, objects, signals, ``geoReference`` (the map stays
in the file's x/y frame), junction groups and controllers.

Lane types map to kinds: driving, entry, exit, onRamp, offRamp, connectingRamp, bidirectional,
slipLane, bus, taxi, HOV, mwyEntry, mwyExit -> driving; parking; shoulder; sidewalk, walking ->
sidewalk; biking -> bicycle; everything else (border, curb, median, restricted, stop, rail, tram,
roadWorks, special1-3) -> other.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tracker.maps.graph import Lanelet, LaneGraph, xml_root

#: Spacing (m) of the boundary samples along the reference line.
SAMPLE_SPACING = 0.5
#: Step (m) of the numerical integration of spirals and cubic polynomials.
INTEGRATION_STEP = 0.05

DRIVING_TYPES = {
    "driving", "entry", "exit", "onramp", "offramp", "connectingramp", "bidirectional", "sliplane",
    "bus", "taxi", "hov", "mwyentry", "mwyexit",
}
KIND_OF_TYPE = {"parking": "parking", "shoulder": "shoulder", "sidewalk": "sidewalk", "walking": "sidewalk", "biking": "bicycle"}


def _kind(lane_type: str) -> str:
    t = lane_type.lower()
    return "driving" if t in DRIVING_TYPES else KIND_OF_TYPE.get(t, "other")


def _f(el: ET.Element, name: str, where: str, default: float | None = None) -> float:
    value = el.get(name)
    if value is None:
        if default is not None:
            return default
        raise ValueError(f"{where} has no attribute {name!r}")
    try:
        return float(value)
    except ValueError:
        raise ValueError(f"{where} has {name}={value!r}, not a number") from None


def _cubic(records: np.ndarray, ds: np.ndarray) -> np.ndarray:
    """Evaluate rows (a, b, c, d) of ``records`` at local distances ``ds``."""
    a, b, c, d = records.T
    return a + ds * (b + ds * (c + ds * d))


# -- plan view ---------------------------------------------------------------------------------------
def _integrate(heading: np.ndarray, step: float) -> tuple[np.ndarray, np.ndarray]:
    """Positions along a curve of the given headings sampled every ``step`` m (trapezoid rule)."""
    c, s = np.cos(heading), np.sin(heading)
    x = np.concatenate([[0.0], np.cumsum(0.5 * step * (c[1:] + c[:-1]))])
    y = np.concatenate([[0.0], np.cumsum(0.5 * step * (s[1:] + s[:-1]))])
    return x, y


def _local_curve(u: np.ndarray, v: np.ndarray, du: np.ndarray, dv: np.ndarray, ds: np.ndarray):
    """Positions and headings in the geometry's local frame at arc lengths ``ds`` of a curve sampled
    densely as (u, v) with derivatives (du, dv)."""
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(u), np.diff(v)))])
    lu, lv = np.interp(ds, arc, u), np.interp(ds, arc, v)
    lh = np.interp(ds, arc, np.unwrap(np.arctan2(dv, du)))
    return lu, lv, lh


def _geometry_points(geo: ET.Element, ds: np.ndarray, where: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """x, y, heading at arc lengths ``ds`` (m, from the geometry's start) of one planView geometry."""
    x0, y0, h0 = _f(geo, "x", where), _f(geo, "y", where), _f(geo, "hdg", where)
    length = _f(geo, "length", where)
    kind = next(iter(geo), None)
    if kind is None:
        raise ValueError(f"{where} has no shape element")
    tag = kind.tag
    if tag == "line":
        lu, lv, lh = ds, np.zeros_like(ds), np.zeros_like(ds)
    elif tag == "arc":
        k = _f(kind, "curvature", where)
        lh = k * ds
        if abs(k) < 1e-12:
            lu, lv = ds, np.zeros_like(ds)
        else:
            lu, lv = np.sin(lh) / k, (1.0 - np.cos(lh)) / k
    elif tag == "spiral":
        k0, k1 = _f(kind, "curvStart", where), _f(kind, "curvEnd", where)
        n = max(int(np.ceil(length / INTEGRATION_STEP)), 2)
        t = np.linspace(0.0, length, n + 1)
        heading = k0 * t + 0.5 * (k1 - k0) / max(length, 1e-12) * t * t
        u, v = _integrate(heading, t[1] - t[0])
        lu, lv, lh = np.interp(ds, t, u), np.interp(ds, t, v), np.interp(ds, t, heading)
    elif tag == "poly3":
        a, b, c, d = (_f(kind, k, where) for k in "abcd")
        n = max(int(np.ceil(length / INTEGRATION_STEP)), 2)
        u = np.linspace(0.0, length, n + 1)  # u <= arc length, so u in [0, length] covers the curve
        v = a + u * (b + u * (c + u * d))
        lu, lv, lh = _local_curve(u, v, np.ones_like(u), b + u * (2 * c + 3 * d * u), ds)
    elif tag == "paramPoly3":
        cu = [_f(kind, k, where) for k in ("aU", "bU", "cU", "dU")]
        cv = [_f(kind, k, where) for k in ("aV", "bV", "cV", "dV")]
        top = 1.0 if kind.get("pRange", "arcLength") == "normalized" else length
        n = max(int(np.ceil(length / INTEGRATION_STEP)), 2)
        p = np.linspace(0.0, top, n + 1)
        u = cu[0] + p * (cu[1] + p * (cu[2] + p * cu[3]))
        v = cv[0] + p * (cv[1] + p * (cv[2] + p * cv[3]))
        du = cu[1] + p * (2 * cu[2] + 3 * cu[3] * p)
        dv = cv[1] + p * (2 * cv[2] + 3 * cv[3] * p)
        lu, lv, lh = _local_curve(u, v, du, dv, ds)
    else:
        raise ValueError(f"{where} is a <{tag}>, which is not supported")
    c, s = np.cos(h0), np.sin(h0)
    return x0 + c * lu - s * lv, y0 + s * lu + c * lv, h0 + lh


@dataclass
class _Road:
    id: str
    length: float
    junction: str
    geometries: list[ET.Element]
    geo_s: np.ndarray
    offsets: np.ndarray  # (R, 5): s, a, b, c, d
    sections: list[ET.Element]
    section_s: np.ndarray
    links: dict[str, ET.Element] = field(default_factory=dict)

    def reference(self, s: np.ndarray, name: str, which: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """x, y, heading of the reference line at ``s`` (m), each sample evaluated on its geometry (or on
        geometry ``which``, one index per sample)."""
        if which is None:
            which = np.clip(np.searchsorted(self.geo_s, s, side="right") - 1, 0, len(self.geometries) - 1)
        x, y, h = np.empty_like(s), np.empty_like(s), np.empty_like(s)
        for g in np.unique(which):  # one vectorised evaluation per geometry
            sel = which == g
            where = f"{name}: road {self.id} geometry {g}"
            x[sel], y[sel], h[sel] = _geometry_points(self.geometries[g], s[sel] - self.geo_s[g], where)
        return x, y, h

    def lane_offset(self, s: np.ndarray) -> np.ndarray:
        if not len(self.offsets):
            return np.zeros_like(s)
        k = np.clip(np.searchsorted(self.offsets[:, 0], s, side="right") - 1, 0, len(self.offsets) - 1)
        return _cubic(self.offsets[k, 1:], s - self.offsets[k, 0])


def _parse_road(el: ET.Element, name: str) -> _Road:
    rid = el.get("id")
    where = f"{name}: road {rid}"
    if rid is None:
        raise ValueError(f"{name}: a <road> has no id")
    geos = el.findall("planView/geometry")
    if not geos:
        raise ValueError(f"{where} has no planView geometry")
    geo_s = np.array([_f(g, "s", f"{where} geometry {i}") for i, g in enumerate(geos)])
    geo_len = np.array([_f(g, "length", f"{where} geometry {i}") for i, g in enumerate(geos)])
    order = np.argsort(geo_s, kind="stable")
    geos, geo_s = [geos[i] for i in order], geo_s[order]
    offsets = np.array(
        [[_f(o, k, f"{where} laneOffset") for k in ("s", "a", "b", "c", "d")] for o in el.findall("lanes/laneOffset")]
    ).reshape(-1, 5)
    sections = el.findall("lanes/laneSection")
    if not sections:
        raise ValueError(f"{where} has no laneSection")
    section_s = np.array([_f(sec, "s", f"{where} laneSection") for sec in sections])
    links = {}
    for kind in ("predecessor", "successor"):
        link = el.find(f"link/{kind}")
        if link is not None:
            links[kind] = link
    length = _f(el, "length", where, default=float(geo_s[-1] + geo_len[order][-1]))
    return _Road(rid, length, el.get("junction", "-1"), geos, geo_s, offsets[np.argsort(offsets[:, 0], kind="stable")],
                 sections, section_s, links)


def _lane_widths(lane: ET.Element, where: str) -> tuple[str, np.ndarray]:
    """("width" | "border", rows (sOffset, a, b, c, d) sorted by sOffset)."""
    for tag in ("width", "border"):
        recs = lane.findall(tag)
        if recs:
            rows = np.array([[_f(r, "sOffset", f"{where} {tag}")] + [_f(r, k, f"{where} {tag}") for k in "abcd"] for r in recs])
            return tag, rows[np.argsort(rows[:, 0], kind="stable")]
    return "width", np.zeros((1, 5))


def _eval_records(rows: np.ndarray, ds: np.ndarray) -> np.ndarray:
    k = np.clip(np.searchsorted(rows[:, 0], ds, side="right") - 1, 0, len(rows) - 1)
    return _cubic(rows[k, 1:], ds - rows[k, 0])


def read_opendrive(path: str | Path) -> LaneGraph:
    """The lane graph of the OpenDRIVE file ``path``. ``FileNotFoundError`` for a missing file,
    ``ValueError`` (one line naming the file and the element) for a broken one."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such map file")
    name = path.name
    root = xml_root(path, "OpenDRIVE")
    roads = {}
    for el in root.findall("road"):
        road = _parse_road(el, name)
        if road.id in roads:
            raise ValueError(f"{name}: two roads have the id {road.id}")
        roads[road.id] = road
    junctions = {j.get("id"): j for j in root.findall("junction")}

    # lanes: key (road id, section index, lane id) -> geometry and kind
    keys, left_pts, right_pts, kinds, sources = [], [], [], [], []
    section_lanes: dict[tuple[str, int], dict[int, ET.Element]] = {}
    for road in roads.values():
        for k, sec in enumerate(road.sections):
            s0 = road.section_s[k]
            s1 = road.section_s[k + 1] if k + 1 < len(road.sections) else road.length
            where = f"{name}: road {road.id} laneSection {k}"
            if s1 <= s0:
                raise ValueError(f"{where} starts at s={s0} m, not before its end {s1} m")
            n = max(int(np.ceil((s1 - s0) / SAMPLE_SPACING)), 1)
            # every geometry start inside the section is sampled twice, at the end of the geometry before it
            # and at the start of its own: where the reference line's heading jumps, so do the borders
            inner_geo = road.geo_s[(road.geo_s > s0) & (road.geo_s < s1)]
            grid = np.linspace(s0, s1, n + 1)
            grid = grid[np.min(np.abs(grid[:, None] - np.append(inner_geo, np.inf)[None]), axis=1) > 1e-6]
            s = np.concatenate([grid, inner_geo, inner_geo])
            which = np.clip(np.searchsorted(road.geo_s, s, side="right") - 1, 0, len(road.geometries) - 1)
            which[len(grid):len(grid) + len(inner_geo)] -= 1
            order = np.lexsort((which, s))
            s, which = s[order], which[order]
            x, y, h = road.reference(s, name, which)
            normal = np.column_stack([-np.sin(h), np.cos(h)])
            base = road.lane_offset(s)
            lanes = {}
            for side, sign in (("right", -1), ("left", 1)):
                found = []
                for lane in sec.findall(f"{side}/lane"):
                    lid = int(_f(lane, "id", f"{where} {side} lane"))
                    if sign * lid <= 0:
                        raise ValueError(f"{where}: lane {lid} is in <{side}>; {side} lanes have {'negative' if sign < 0 else 'positive'} ids")
                    found.append((abs(lid), lid, lane))
                found.sort()
                t_inner = base.copy()
                for _, lid, lane in found:
                    tag, rows = _lane_widths(lane, f"{where} lane {lid}")
                    ds = s - s0
                    if tag == "width":
                        t_outer = t_inner + sign * np.maximum(_eval_records(rows, ds), 0.0)
                    else:
                        t_outer = base + _eval_records(rows, ds)
                    lanes[lid] = lane
                    lane_type = lane.get("type", "driving")
                    if lane_type.lower() != "none":
                        inner = np.column_stack([x, y]) + t_inner[:, None] * normal
                        outer = np.column_stack([x, y]) + t_outer[:, None] * normal
                        # a repeated sample with no jump adds nothing
                        step = np.maximum(np.hypot(*np.diff(inner, axis=0).T), np.hypot(*np.diff(outer, axis=0).T))
                        keep = np.concatenate([[True], step > 1e-9])
                        inner, outer = inner[keep], outer[keep]
                        if sign < 0:  # right lane: drives along s, inner border on its left
                            left_pts.append(inner)
                            right_pts.append(outer)
                        else:  # left lane: drives against s, inner border on its left
                            left_pts.append(inner[::-1])
                            right_pts.append(outer[::-1])
                        keys.append((road.id, k, lid))
                        kinds.append(_kind(lane_type))
                        sources.append(f"road {road.id} laneSection {k} lane {lid}")
                    t_inner = t_outer
            section_lanes[(road.id, k)] = lanes

    index = {key: i for i, key in enumerate(keys)}
    joins: set[tuple[tuple, str, tuple, str]] = set()

    def join(a: tuple, end_a: str, b: tuple, end_b: str) -> None:
        if a in index and b in index:
            joins.add((a, end_a, b, end_b))
            joins.add((b, end_b, a, end_a))

    def linked(lane: ET.Element, kind: str) -> list[int]:
        return [int(_f(el, "id", f"{name}: lane link")) for el in lane.findall(f"link/{kind}")]

    for road in roads.values():
        last = len(road.sections) - 1
        for k in range(last + 1):
            for lid, lane in section_lanes[(road.id, k)].items():
                if k < last:  # the next section of the same road
                    nxt = linked(lane, "successor") or ([lid] if lid in section_lanes[(road.id, k + 1)] else [])
                    for other in nxt:
                        join((road.id, k, lid), "end", (road.id, k + 1, other), "start")
        for kind, end, k in (("successor", "end", last), ("predecessor", "start", 0)):
            link = road.links.get(kind)
            if link is None:
                continue
            etype, eid = link.get("elementType", "road"), link.get("elementId")
            if etype == "road":
                if eid not in roads:
                    raise ValueError(f"{name}: road {road.id} names {kind} road {eid}, which is not in the file")
                other = roads[eid]
                cp = link.get("contactPoint", "start")
                ok = 0 if cp == "start" else len(other.sections) - 1
                for lid, lane in section_lanes[(road.id, k)].items():
                    for target in linked(lane, kind):
                        join((road.id, k, lid), end, (eid, ok, target), cp)
            elif etype == "junction":
                if eid not in junctions:
                    raise ValueError(f"{name}: road {road.id} names {kind} junction {eid}, which is not in the file")
                for conn in junctions[eid].findall("connection"):
                    if conn.get("incomingRoad") != road.id:
                        continue
                    cid, cp = conn.get("connectingRoad"), conn.get("contactPoint", "start")
                    if cid not in roads:
                        raise ValueError(f"{name}: junction {eid} connection {conn.get('id')} names connecting road {cid}, which is not in the file")
                    ok = 0 if cp == "start" else len(roads[cid].sections) - 1
                    for ll in conn.findall("laneLink"):
                        a = int(_f(ll, "from", f"{name}: junction {eid} laneLink"))
                        b = int(_f(ll, "to", f"{name}: junction {eid} laneLink"))
                        join((road.id, k, a), end, (cid, ok, b), cp)

    successors: list[list[int]] = [[] for _ in keys]
    predecessors: list[list[int]] = [[] for _ in keys]
    for a, end_a, b, end_b in joins:
        exit_a = "end" if a[2] < 0 else "start"
        entry_b = "start" if b[2] < 0 else "end"
        if end_a == exit_a and end_b == entry_b:
            successors[index[a]].append(index[b])
            predecessors[index[b]].append(index[a])

    lanelets = []
    for i, (rid, k, lid) in enumerate(keys):
        sign = -1 if lid < 0 else 1
        inner_id = lid - sign if abs(lid) > 1 else -lid  # across the centre: the first lane on the other side
        outer_id = lid + sign
        inner = index.get((rid, k, inner_id))
        outer = index.get((rid, k, outer_id))
        lanelets.append(Lanelet(
            id=i + 1,
            left=left_pts[i],
            right=right_pts[i],
            predecessors=tuple(sorted(p + 1 for p in set(predecessors[i]))),
            successors=tuple(sorted(q + 1 for q in set(successors[i]))),
            left_neighbor=None if inner is None else inner + 1,
            left_same_direction=abs(lid) > 1,
            right_neighbor=None if outer is None else outer + 1,
            right_same_direction=True,
            kind=kinds[i],
            source=sources[i],
        ))
    return LaneGraph(lanelets, source=name)
