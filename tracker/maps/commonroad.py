"""Read the lane map of a CommonRoad scenario file (XML) into a ``LaneGraph``.

Uses ``commonroad-io`` (the optional ``maps`` extra). Every lanelet becomes one ``Lanelet`` with its
id, boundaries, successors, predecessors and left/right neighbours (``adjacentLeft``/``adjacentRight``
with their ``drivingDir``). Lanelet types map to kinds: ``shoulder`` -> shoulder, ``parking`` -> parking,
``sidewalk`` -> sidewalk, ``crosswalk`` -> crosswalk, ``bicycleLane`` -> bicycle, ``border``,
``restricted``, ``restricted_area`` -> other, every other type (urban, highway, ramps, bus lanes,
intersection...) -> driving. Traffic signs, lights, stop lines and the scenario's obstacles are not read.
"""

from __future__ import annotations

import contextlib
import gzip
import io
import logging
import shutil
import tempfile
import zlib
from collections.abc import Iterator
from pathlib import Path

from tracker.maps.graph import Lanelet, LaneGraph, xml_root

#: CommonRoad lanelet types that are not "driving" (``LaneletType.value`` -> kind).
KIND_OF_TYPE = {
    "shoulder": "shoulder",
    "parking": "parking",
    "sidewalk": "sidewalk",
    "crosswalk": "crosswalk",
    "bicycleLane": "bicycle",
    "border": "other",
    "restricted": "other",
    "restricted_area": "other",
}


def import_reader():
    """commonroad-io's ``CommonRoadFileReader`` (``ImportError`` naming the extra without it)."""
    try:
        from commonroad.common.file_reader import CommonRoadFileReader
    except ImportError:
        raise ImportError("reading CommonRoad maps needs commonroad-io: pip install 'frenet-eot[maps]'") from None
    return CommonRoadFileReader


@contextlib.contextmanager
def _quiet(name: str):
    """Raise the level of logger ``name`` to ERROR while inside (commonroad-io logs a warning for every
    2020a-format intersection element it maps to the newer names)."""
    log = logging.getLogger(name)
    level = log.level
    log.setLevel(logging.ERROR)
    try:
        yield
    finally:
        log.setLevel(level)


@contextlib.contextmanager
def uncompressed(path: Path) -> Iterator[Path]:
    """``path`` itself, or for a gzip-compressed ``.gz`` file a temporary uncompressed copy (commonroad-io
    opens files by name); ``ValueError`` naming the file when it is not gzip."""
    if path.suffix.lower() != ".gz":
        yield path
        return
    with tempfile.TemporaryDirectory(prefix="eot-") as folder:
        plain = Path(folder) / path.name[: -len(".gz")]
        try:
            with gzip.open(path, "rb") as src, open(plain, "wb") as dst:
                shutil.copyfileobj(src, dst)
        except (OSError, EOFError, zlib.error) as exc:
            raise ValueError(f"{path.name}: not a readable gzip file ({exc})") from None
        yield plain


@contextlib.contextmanager
def quiet():
    """Silence commonroad-io's notices on older formats while inside (stdout and its logger)."""
    with contextlib.redirect_stdout(io.StringIO()), _quiet("commonroad"):
        yield


def _precheck(path: Path, name: str) -> None:
    """Parse the XML with the standard library to report a broken file ``name`` in one line naming the
    element."""
    root = xml_root(path, "commonRoad")
    ids = set()
    for el in root.findall("lanelet"):
        lid = el.get("id")
        if lid is None:
            raise ValueError(f"{name}: a <lanelet> has no id")
        ids.add(lid)
        for bound in ("leftBound", "rightBound"):
            b = el.find(bound)
            count = 0 if b is None else len(b.findall("point"))
            if count < 2:
                side = bound[: -len("Bound")]
                raise ValueError(f"{name}: lanelet {lid} has a {side} boundary of {count} point{'s' if count != 1 else ''}; need at least 2")
    for el in root.findall("lanelet"):
        for tag in ("predecessor", "successor", "adjacentLeft", "adjacentRight"):
            for ref in el.findall(tag):
                if ref.get("ref") not in ids:
                    raise ValueError(f"{name}: lanelet {el.get('id')} names {tag} {ref.get('ref')}, which is not in the map")


def lanelet_from_commonroad(ll, source: str = "") -> Lanelet:
    """A ``Lanelet`` from a ``commonroad.scenario.lanelet.Lanelet``."""
    types = {t.value for t in (ll.lanelet_type or ())}
    kinds = [KIND_OF_TYPE[t] for t in types if t in KIND_OF_TYPE]
    return Lanelet(
        id=int(ll.lanelet_id),
        left=ll.left_vertices,
        right=ll.right_vertices,
        predecessors=tuple(int(i) for i in ll.predecessor),
        successors=tuple(int(i) for i in ll.successor),
        left_neighbor=None if ll.adj_left is None else int(ll.adj_left),
        left_same_direction=bool(ll.adj_left_same_direction) if ll.adj_left is not None else True,
        right_neighbor=None if ll.adj_right is None else int(ll.adj_right),
        right_same_direction=bool(ll.adj_right_same_direction) if ll.adj_right is not None else True,
        kind=sorted(kinds)[0] if kinds else "driving",
        source=source or f"lanelet {ll.lanelet_id}",
    )


def graph_from_lanelet_network(network, source: str = "map") -> LaneGraph:
    """A ``LaneGraph`` from a ``commonroad.scenario.lanelet.LaneletNetwork``."""
    return LaneGraph([lanelet_from_commonroad(ll) for ll in network.lanelets], source=source)


def open_commonroad(path: str | Path, *, what: str = "map file", lanelets_only: bool = True, planning: bool = False):
    """commonroad-io's reading of the CommonRoad file ``path`` (``.xml`` or gzip-compressed ``.xml.gz``): its
    ``LaneletNetwork`` (``lanelets_only``) or its whole ``Scenario`` (with ``planning``: the pair
    ``(Scenario, PlanningProblemSet)``). Raises ``FileNotFoundError`` naming
    ``what`` for a missing file, ``ValueError`` (one line naming the file, and for a map the broken
    element where the standard library finds it) when commonroad-io cannot read it, ``ImportError``
    without commonroad-io."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such {what}")
    reader = import_reader()
    with uncompressed(path) as plain:
        try:
            with quiet():  # notices on older formats
                opened = reader(str(plain))
                if lanelets_only:
                    return opened.open_lanelet_network()
                scenario, problems = opened.open()
                return (scenario, problems) if planning else scenario
        except Exception as err:  # noqa: BLE001 - any failure of the library becomes one line naming the file
            if lanelets_only:
                _precheck(plain, path.name)  # names the broken element when it finds one
            first = str(err).splitlines()[0] if str(err) else ""
            raise ValueError(f"{path.name}: commonroad-io cannot read it ({type(err).__name__}: {first})") from None


def read_commonroad(path: str | Path) -> LaneGraph:
    """The lane map of the CommonRoad file ``path`` (XML, formats 2018b-2020a and later; ``.xml.gz``:
    gzip-compressed).

    Raises ``FileNotFoundError`` for a missing file and ``ValueError`` (one line naming the file and
    the element) for a broken one; ``ImportError`` without commonroad-io.
    """
    return graph_from_lanelet_network(open_commonroad(path), source=Path(path).name)
