"""Road model speed: one-point and 10^5-point to_frenet / to_cartesian (median over repeats)."""

from __future__ import annotations

import argparse

import numpy as np

from sim.benchmarks._timing import median_seconds
from tracker import Road


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--repeat", type=int, default=3000, help="single-point calls per measurement")
    parser.add_argument("--batch-repeat", type=int, default=15, help="10^5-point calls per measurement")


def bench_roads() -> dict[str, Road]:
    """The benchmark roads: a 1.7 km winding curvature profile and a spline through its samples."""
    segments = [(200.0, 0.0, 0.0), (60.0, 0.0, 1 / 60), (150.0, 1 / 60, 1 / 60), (80.0, 1 / 60, -1 / 90)]
    segments += [(300.0, -1 / 90, -1 / 90), (60.0, -1 / 90, 0.0), (400.0, 0.0, 1 / 400), (450.0, 1 / 400, 1 / 400)]
    clothoid = Road.from_curvature(segments, lanes=3)
    s = np.linspace(0.0, clothoid.length, 60)
    hermite = Road.from_waypoints(clothoid.position(s), lanes=3)
    return {"curvature-profile": clothoid, "waypoint-spline": hermite}


def run(args: argparse.Namespace) -> dict:
    rng = np.random.default_rng(0)
    out: dict[str, dict[str, float]] = {}
    for name, road in bench_roads().items():
        s = rng.uniform(0.0, road.length, 100_000)
        n = rng.uniform(road.right_edge, road.left_edge, 100_000)
        xy = road.to_cartesian(s, n)
        p, s1, n1 = xy[12345], float(s[12345]), float(n[12345])
        p_list = tuple(float(v) for v in p)
        p_row = np.ascontiguousarray(p[None, :])  # the same point as a (1, 2) array
        out[name] = {
            "length_m": round(road.length, 1),
            "to_frenet_1pt_hint_us": 1e6 * median_seconds(lambda: road.to_frenet(p_list, s_hint=s1 - 0.5), 15, args.repeat // 15),
            "to_frenet_1pt_no_hint_us": 1e6 * median_seconds(lambda: road.to_frenet(p_list), 15, args.repeat // 15),
            "to_frenet_1pt_array_us": 1e6 * median_seconds(lambda: road.to_frenet(p_row), 15, args.repeat // 15),
            "to_cartesian_1pt_us": 1e6 * median_seconds(lambda: road.to_cartesian(s1, n1), 15, args.repeat // 15),
            "to_frenet_1e5_ms": 1e3 * median_seconds(lambda: road.to_frenet(xy), args.batch_repeat),
            "to_cartesian_1e5_ms": 1e3 * median_seconds(lambda: road.to_cartesian(s, n), args.batch_repeat),
        }
        out[name] = {k: round(v, 2) for k, v in out[name].items()}
    return out
