"""Read a Lanelet2 map (OSM XML) into a ``LaneGraph`` with the ``lanelet2`` package (the ``maps`` extra).

Points are projected from latitude/longitude to metres with lanelet2's UTM projector (or its local
Cartesian one) about an origin (lat, lon) deg: x east, y north, relative to the origin. Topology is lanelet2's: lanelets
share points and linestrings.

- successor: lanelet B follows A when B's boundaries start at the points where A's end (both sides);
- neighbours: B is A's left neighbour driving the same way when A's left boundary is B's right one,
  and an oncoming one when A's left boundary is B's left one inverted (likewise on the right).

Lanelet ``subtype`` maps to kinds: road, highway, play_street, emergency_lane, bus_lane -> driving;
parking -> parking; walkway, crosswalk, stairs -> sidewalk / crosswalk; bicycle_lane -> bicycle;
others -> other. Not read: regulatory elements (traffic rules, lights, right of way), areas, height,
``one_way=no`` lanelets (treated as one-way along their boundaries), traffic-rule based lane changes.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from tracker.maps.graph import Lanelet, LaneGraph, xml_root

KIND_OF_SUBTYPE = {
    "road": "driving", "highway": "driving", "play_street": "driving", "emergency_lane": "driving",
    "bus_lane": "driving", "parking": "parking", "walkway": "sidewalk", "stairs": "sidewalk",
    "crosswalk": "crosswalk", "bicycle_lane": "bicycle", "shoulder": "shoulder",
}


def _import_lanelet2():
    try:
        import lanelet2.io
        import lanelet2.projection
    except ImportError:
        raise ImportError("reading Lanelet2 maps needs lanelet2: pip install 'frenet-eot[maps]'") from None
    return lanelet2


def _first_node(path: Path) -> tuple[float, float]:
    """(lat, lon) deg of the first ``<node>`` of an OSM file."""
    try:
        for _, el in ET.iterparse(path, events=("start",)):
            if el.tag == "node":
                return float(el.get("lat")), float(el.get("lon"))
    except (ET.ParseError, TypeError, ValueError) as err:
        raise ValueError(f"{path.name}: not a readable OSM file ({err})") from None
    raise ValueError(f"{path.name}: has no <node>, so no origin; pass origin=(lat, lon)")


def _check_osm(path: Path) -> None:
    """Name the first broken element of an OSM file lanelet2 refused (one line)."""
    name = path.name
    root = xml_root(path)
    nodes = {n.get("id") for n in root.findall("node")}
    ways = {w.get("id"): w for w in root.findall("way")}
    for way in ways.values():
        for nd in way.findall("nd"):
            if nd.get("ref") not in nodes:
                raise ValueError(f"{name}: way {way.get('id')} names node {nd.get('ref')}, which is not in the file")
    for rel in root.findall("relation"):
        tags = {t.get("k"): t.get("v") for t in rel.findall("tag")}
        if tags.get("type") != "lanelet":
            continue
        roles = {m.get("role"): m.get("ref") for m in rel.findall("member")}
        for role in ("left", "right"):
            if roles.get(role) not in ways:
                raise ValueError(f"{name}: lanelet {rel.get('id')} has no {role} boundary way")


def read_lanelet2(path: str | Path, origin: tuple[float, float] | None = None, projection: str = "utm") -> LaneGraph:
    """The lane graph of the Lanelet2 OSM file ``path``, in metres about ``origin`` = (lat, lon) deg
    (default: the file's first node). ``projection``: ``"utm"`` (default; lanelet2's ``UtmProjector``:
    UTM grid metres relative to the origin, lanelet2's usual frame; UTM's scale differs from ground
    distances by up to 0.1 %) or ``"local"`` (``LocalCartesianProjector``: east/north ground metres at
    the origin). ``FileNotFoundError`` for a missing file, ``ValueError`` (one line naming the file and
    the element) for a broken one, ``ImportError`` without lanelet2."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such map file")
    if projection not in ("utm", "local"):
        raise ValueError(f"projection must be 'utm' or 'local'; got {projection!r}")
    lanelet2 = _import_lanelet2()
    lat, lon = origin if origin is not None else _first_node(path)
    make = lanelet2.projection.UtmProjector if projection == "utm" else lanelet2.projection.LocalCartesianProjector
    projector = make(lanelet2.io.Origin(float(lat), float(lon)))
    try:
        lmap, errors = lanelet2.io.loadRobust(str(path), projector)
    except Exception as err:  # noqa: BLE001 - any failure of the library becomes one line naming the file
        _check_osm(path)
        raise ValueError(f"{path.name}: lanelet2 cannot read it ({str(err).splitlines()[0] if str(err) else type(err).__name__})") from None
    if errors:
        _check_osm(path)
        raise ValueError(f"{path.name}: lanelet2 reports: {errors[0].splitlines()[0]}")

    raw = []
    for ll in lmap.laneletLayer:
        left, right = ll.leftBound, ll.rightBound
        raw.append((
            int(ll.id),
            np.array([[p.x, p.y] for p in left], dtype=float).reshape(-1, 2),
            np.array([[p.x, p.y] for p in right], dtype=float).reshape(-1, 2),
            tuple(int(p.id) for p in left),
            tuple(int(p.id) for p in right),
            ll.attributes["subtype"] if "subtype" in ll.attributes else "road",
        ))
    raw.sort(key=lambda r: r[0])
    for lid, left, right, *_ in raw:
        for side, pts in (("left", left), ("right", right)):
            if len(pts) < 2:
                raise ValueError(f"{path.name}: lanelet {lid} has a {side} boundary of {len(pts)} point{'s' if len(pts) != 1 else ''}; need at least 2")

    starts: dict[tuple[int, int], list[int]] = {}
    by_right: dict[tuple[int, ...], list[int]] = {}
    by_left: dict[tuple[int, ...], list[int]] = {}
    for lid, _, _, lp, rp, _ in raw:
        starts.setdefault((lp[0], rp[0]), []).append(lid)
        by_right.setdefault(rp, []).append(lid)
        by_left.setdefault(lp, []).append(lid)
    successors = {lid: tuple(sorted(starts.get((lp[-1], rp[-1]), []))) for lid, _, _, lp, rp, _ in raw}
    predecessors: dict[int, list[int]] = {lid: [] for lid, *_ in raw}
    for lid, succ in successors.items():
        for s in succ:
            predecessors[s].append(lid)

    lanelets = []
    for lid, left, right, lp, rp, subtype in raw:
        left_same = [o for o in by_right.get(lp, []) if o != lid]
        left_opp = [o for o in by_left.get(lp[::-1], []) if o != lid]
        right_same = [o for o in by_left.get(rp, []) if o != lid]
        right_opp = [o for o in by_right.get(rp[::-1], []) if o != lid]
        ln = (left_same[0], True) if left_same else ((left_opp[0], False) if left_opp else (None, True))
        rn = (right_same[0], True) if right_same else ((right_opp[0], False) if right_opp else (None, True))
        lanelets.append(Lanelet(
            id=lid, left=left, right=right,
            predecessors=tuple(sorted(predecessors[lid])), successors=successors[lid],
            left_neighbor=ln[0], left_same_direction=ln[1], right_neighbor=rn[0], right_same_direction=rn[1],
            kind=KIND_OF_SUBTYPE.get(subtype, "other"),
        ))
    return LaneGraph(lanelets, source=path.name)
