"""Route roads of the CommonRoad maps: read time, route build time, edge deviation, on-road fraction.

Run: ``PYTHONPATH=. python tests/maps_bench.py [files...]`` (default: every file of
/work/shared/data/commonroad and tests/data). Prints one row per route; times are the best of 3.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from maps_checks import edge_deviation, longest_route_start, on_road_fraction, planning_start, vehicle_centres

from tracker.lanes import EDGE_TABLE_STEP
from tracker.maps import read_map, route_corridor

SHARED = Path("/work/shared/data/commonroad")
HERE = Path(__file__).resolve().parent / "data"


def routes(path: Path) -> list[tuple[str, dict]]:
    start = planning_start(path)
    out = [("planning start", {"start": start})]
    if path.name.startswith("USA_Lanker"):
        out.append(("across the intersection", {"start": longest_route_start(read_map(path))}))
    return out


def main(files: list[str]) -> None:
    paths = [Path(f) for f in files] or sorted(SHARED.glob("*.xml")) + sorted(HERE.glob("*.xml"))
    print(f"{'file':28s} {'route':26s} {'read s':>7s} {'route s':>8s} {'length m':>8s} {'edge dev m':>10s} {'away joins':>10s} {'on-road':>8s} {'n':>6s}")
    for path in paths:
        t0 = time.perf_counter()
        graph = read_map(path)
        t_read = time.perf_counter() - t0
        centres = vehicle_centres(path)
        for name, kw in routes(path):
            best = float("inf")
            for _ in range(3):
                t0 = time.perf_counter()
                corridor = route_corridor(graph, **kw)
                best = min(best, time.perf_counter() - t0)
            dev = edge_deviation(graph, corridor)
            dev_away = edge_deviation(graph, corridor, join_margin=EDGE_TABLE_STEP)
            frac, n = on_road_fraction(graph, corridor, centres)
            print(f"{path.name:28s} {name:26s} {t_read:7.3f} {best:8.3f} {corridor.road.length:8.1f} {dev:10.3f} {dev_away:10.3f} {frac:8.4f} {n:6d}")


if __name__ == "__main__":
    main(sys.argv[1:])
