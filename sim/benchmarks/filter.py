"""Single-target filter speed: one UKF predict, one update by a 30-point cluster, and a batch of 20 components x 10 clusters (median microseconds)."""

from __future__ import annotations

import argparse

import numpy as np

from sim.benchmarks._timing import median_seconds
from tracker import Road, TrackerConfig
from tracker.measurement import prepare_cluster, rectangle_scan, to_vehicle
from tracker.motion import make_motion, predict
from tracker.ukf import UnscentedTransform
from tracker.update import update_pairs


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--repeat", type=int, default=200, help="timed calls per single-component measurement")
    parser.add_argument("--batch-repeat", type=int, default=30, help="timed calls per batch measurement")
    parser.add_argument("--points", type=int, default=30, help="points per cluster")


def _cluster_points(road: Road, state: np.ndarray, ego: tuple[float, float, float], count: int,
                    rng: np.random.Generator) -> np.ndarray:
    """``count`` lidar points on the visible contour of ``state`` (range noise 3 cm)."""
    corners = to_vehicle(state, ego, road).corners()
    b = np.arctan2(corners[:, 1], corners[:, 0])
    pts, _ = rectangle_scan(corners, np.linspace(b.min() + 1e-6, b.max() - 1e-6, count))
    r = np.hypot(pts[:, 0], pts[:, 1])
    return pts * ((r + 0.03 * rng.standard_normal(len(r))) / r)[:, None]


def run(args: argparse.Namespace) -> dict:
    rng = np.random.default_rng(0)
    road = Road.from_curvature([(2 * np.pi * 80.0, 1 / 80.0, 1 / 80.0)], closed=True, lanes=3)
    config = TrackerConfig()
    ut = UnscentedTransform(config.ukf)
    motion = make_motion(config, road)
    s_ego = 20.0
    ego_xy = road.to_cartesian(s_ego, -3.5)
    ego = (float(ego_xy[0]), float(ego_xy[1]), float(road.heading(s_ego)))
    # 10 targets ahead in the three lanes, 20 components (two per target, one offset)
    targets = np.array([[s_ego + 8.0 + 6.0 * i, (-3.5, 0.0, 3.5)[i % 3], 15.0, 0.0, 0.0, 4.7, 1.9] for i in range(10)])
    clusters = [prepare_cluster(_cluster_points(road, x, ego, args.points, rng), config.measurement,
                                velocity=[15.0, 0.0]) for x in targets]
    means = np.concatenate([targets, targets + np.array([0.5, 0.2, 1.0, 0.02, 0.0, 0.2, 0.1])])
    covs = np.broadcast_to(np.diag([0.5, 0.2, 1.0, 0.05, 0.02, 0.3, 0.1]) ** 2, (20, 7, 7)).copy()
    one_mean, one_cov = means[:1], covs[:1]
    pts = _cluster_points(road, targets[0], ego, args.points, rng)
    comp = np.repeat(np.arange(20), 10)
    clu = np.tile(np.arange(10), 20)
    zero = np.zeros(1, dtype=int)
    single_pair = 1e6 * median_seconds(lambda: update_pairs(one_mean, one_cov, clusters[:1], zero, zero, ego, road, config, ut),
                             args.repeat)
    batch_update = 1e6 * median_seconds(lambda: update_pairs(means, covs, clusters, comp, clu, ego, road, config, ut),
                              args.batch_repeat)
    out = {
        "points_per_cluster": args.points,
        "predict_1_us": 1e6 * median_seconds(lambda: predict(ut, motion, one_mean, one_cov, 0.1), args.repeat),
        "prepare_cluster_us": 1e6 * median_seconds(lambda: prepare_cluster(pts, config.measurement), args.repeat),
        "update_1x1_us": single_pair,
        "predict_20_us": 1e6 * median_seconds(lambda: predict(ut, motion, means, covs, 0.1), args.batch_repeat),
        "prepare_10_clusters_us": 1e6 * median_seconds(
            lambda: [prepare_cluster(_p, config.measurement) for _p in (c.points for c in clusters)], args.batch_repeat
        ),
        "update_20x10_us": batch_update,
        "update_20x10_per_pair_us": batch_update / 200.0,
        "ukf_repairs": ut.repairs,
    }
    return {k: (round(v, 1) if isinstance(v, float) else v) for k, v in out.items()}
