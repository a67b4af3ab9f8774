"""Real lane maps: read CommonRoad, Lanelet2 and OpenDRIVE maps into one ``LaneGraph`` and build the
``tracker.Road`` of a route through it (docs/maps.md).

The map libraries (``commonroad-io``, ``lanelet2``) are imported only inside the readers that need
them (install them with ``pip install 'frenet-eot[maps]'``); OpenDRIVE is parsed with the standard
library. Importing this package needs numpy and scipy only.
"""

from __future__ import annotations

from pathlib import Path

from tracker.maps.graph import KINDS, ROAD_KINDS, Lanelet, LaneGraph
from tracker.maps.route import Corridor, route_corridor, route_lanelets, route_road


def read_commonroad(path: str | Path) -> LaneGraph:
    """The lane map of a CommonRoad XML file (needs commonroad-io; ``tracker.maps.commonroad``)."""
    from tracker.maps.commonroad import read_commonroad as read

    return read(path)


def read_lanelet2(path: str | Path, origin: tuple[float, float] | None = None, projection: str = "utm") -> LaneGraph:
    """The lane map of a Lanelet2 OSM file, projected to metres about ``origin`` = (lat, lon) deg
    (default: the file's first node) with ``projection`` ``"utm"`` (default) or ``"local"`` (needs
    lanelet2; ``tracker.maps.lanelet2_osm``)."""
    from tracker.maps.lanelet2_osm import read_lanelet2 as read

    return read(path, origin=origin, projection=projection)


def read_opendrive(path: str | Path) -> LaneGraph:
    """The lane map of an OpenDRIVE (.xodr) file (standard library only; ``tracker.maps.opendrive``)."""
    from tracker.maps.opendrive import read_opendrive as read

    return read(path)


#: Reader of each file suffix.
READERS = {".xml": read_commonroad, ".osm": read_lanelet2, ".xodr": read_opendrive}


def read_map(path: str | Path, **kwargs) -> LaneGraph:
    """The lane map of ``path``, read by its suffix: ``.xml`` CommonRoad (``.xml.gz`` gzip-compressed),
    ``.osm`` Lanelet2, ``.xodr`` OpenDRIVE (keywords go to the reader)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".gz" and path.with_suffix("").suffix.lower() == ".xml":
        suffix = ".xml"
    reader = READERS.get(suffix)
    if reader is None:
        raise ValueError(f"{path.name}: unknown map format {path.suffix!r}; expected one of {', '.join(READERS)} "
                         "(.xml.gz: a compressed CommonRoad file)")
    return reader(path, **kwargs)


__all__ = [
    "KINDS",
    "ROAD_KINDS",
    "Corridor",
    "LaneGraph",
    "Lanelet",
    "read_commonroad",
    "read_lanelet2",
    "read_map",
    "read_opendrive",
    "route_corridor",
    "route_lanelets",
    "route_road",
]
