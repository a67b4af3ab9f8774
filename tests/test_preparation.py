"""Tests of tracker/preparation.py: the batched ``prepare_clusters`` (and ``tracker.measurement.prepare_cluster``,
both by ``tracker.measurement.prepare_kernel``) against the one-cluster numpy oracle
``oracles.preparation.prepare_cluster`` on many kinds of clusters at once."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from oracles.preparation import prepare_cluster as oracle_cluster

from tracker.config import MeasurementConfig
from tracker.measurement import ClusterBatch, prepare_cluster, rectangle_corners
from tracker.preparation import prepare_batch, prepare_clusters

FIELDS = ("points", "part", "proj", "chord_start", "chord_end", "chord_dir", "chord_len", "end_margin", "end_gap", "order")


def l_shape(rng: np.random.Generator, count: int) -> np.ndarray:
    """Points on the two sides of a car seen from a corner (a two-sided cluster), with noise."""
    centre = rng.uniform([10.0, -20.0], [40.0, 20.0])
    psi = rng.uniform(-np.pi, np.pi)
    c = rectangle_corners(centre, np.array(psi), np.array(rng.uniform(4.0, 14.0)), np.array(rng.uniform(1.6, 2.6)))
    near = int(np.argmin(np.linalg.norm(c, axis=1)))
    a, b, d = c[(near - 1) % 4], c[near], c[(near + 1) % 4]
    t = rng.random(count)
    side = rng.random(count) < 0.5
    pts = np.where(side[:, None], a + t[:, None] * (b - a), b + t[:, None] * (d - b))
    return pts + rng.normal(0.0, 0.03, pts.shape)


def line(rng: np.random.Generator, count: int) -> np.ndarray:
    start = rng.uniform([5.0, -30.0], [60.0, 30.0])
    u = rng.normal(size=2)
    return start + np.outer(np.linspace(0.0, rng.uniform(0.5, 12.0), count), u / np.linalg.norm(u)) + rng.normal(0, 0.02, (count, 2))


def random_clusters(seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    out = [l_shape(rng, int(rng.integers(4, 200))) for _ in range(12)]
    out += [line(rng, int(rng.integers(2, 150))) for _ in range(8)]
    out += [rng.uniform(-40, 40, (1, 2)), rng.uniform(-40, 40, (2, 2)), np.tile(rng.uniform(5, 9, (1, 2)), (5, 1))]
    out += [l_shape(rng, 3), rng.normal(20.0, 2.0, (40, 2))]  # too few for two sides; a blob
    # a short face in range noise: elongated less than the eigenvalue ratio asks, but within the noise of one line
    out += [np.column_stack([36.0 + rng.normal(0.0, 0.03, 5), np.linspace(-0.25, 0.25, 5)])]
    return [out[i] for i in rng.permutation(len(out))]


def assert_same(batch, reference) -> None:
    assert len(batch) == len(reference)
    for b, r in zip(batch, reference):
        assert (b.two_sided, b.corner, b.raw_count, b.dropped) == (r.two_sided, r.corner, r.raw_count, r.dropped)
        assert b.eigen_ratio == pytest.approx(r.eigen_ratio, rel=1e-9) or (np.isinf(b.eigen_ratio) and np.isinf(r.eigen_ratio))
        for name in FIELDS:
            np.testing.assert_allclose(getattr(b, name), getattr(r, name), rtol=1e-9, atol=1e-9, err_msg=name)
        assert (b.velocity is None) == (r.velocity is None)
        if b.velocity is not None:
            np.testing.assert_array_equal(b.velocity, r.velocity)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("config", [MeasurementConfig(), MeasurementConfig(max_cluster_points=12)],
                         ids=["default", "12-points"])
def test_batch_equals_the_one_cluster_oracle(seed: int, config: MeasurementConfig) -> None:
    clusters = random_clusters(seed)
    rng = np.random.default_rng(100 + seed)
    velocities = [rng.normal(0, 10, 2) if rng.random() < 0.5 else None for _ in clusters]
    batch = prepare_clusters(clusters, config, velocities)
    assert_same(batch, [oracle_cluster(c, config, v) for c, v in zip(clusters, velocities)])
    assert sum(c.raw_count > c.size for c in batch) >= 3  # downsampling exercised
    assert sum(c.two_sided for c in batch) >= 5  # corners exercised
    assert sum(not c.two_sided for c in batch) >= 5


@pytest.mark.parametrize("seed", range(3))
def test_prepare_batch_equals_the_batch_of_the_prepared_clusters(seed: int) -> None:
    # the tracker's path (padded arrays straight into a ClusterBatch) against ClusterBatch.of
    clusters = random_clusters(seed)
    rng = np.random.default_rng(200 + seed)
    velocities = [rng.normal(0, 10, 2) if rng.random() < 0.5 else None for _ in clusters]
    got = prepare_batch(clusters, MeasurementConfig(), velocities)
    want = ClusterBatch.of([oracle_cluster(c, MeasurementConfig(), v) for c, v in zip(clusters, velocities)])
    for name in want.__dataclass_fields__:
        if name in ("occluded_end", "continued_end"):  # set by the tracker from the whole scan, not by preparation
            assert getattr(got, name) is None and getattr(want, name) is None
            continue
        np.testing.assert_allclose(getattr(got, name), getattr(want, name), rtol=1e-9, atol=1e-9, err_msg=name)
    # a cluster with a non-finite point: the batch of the clusters prepared one by one
    clusters[3] = np.vstack([clusters[3], [[np.nan, 1.0]]])
    mixed = prepare_batch(clusters, MeasurementConfig(), velocities)
    assert mixed.valid.sum() == want.valid.sum()


def test_small_point_budget_downsamples_both_parts_like_the_oracle() -> None:
    config = dataclasses.replace(MeasurementConfig(), max_cluster_points=7)
    clusters = random_clusters(11)
    assert_same(prepare_clusters(clusters, config), [oracle_cluster(c, config) for c in clusters])


def test_non_finite_points_are_dropped_and_counted_and_bad_input_is_refused() -> None:
    rng = np.random.default_rng(0)
    pts = l_shape(rng, 30)
    pts[3] = np.nan
    pts[17, 1] = np.inf
    second = l_shape(rng, 20)
    batch = prepare_clusters([pts, second], velocities=[None, np.array([3.0, -1.0])])
    assert batch[0].dropped == 2 and batch[0].raw_count == 28
    assert 3 not in batch[0].order and 17 not in batch[0].order  # the kept points' input indices
    assert_same(batch, [oracle_cluster(pts), oracle_cluster(second, velocity=np.array([3.0, -1.0]))])
    assert_same([prepare_cluster(pts, MeasurementConfig(max_cluster_points=9))],
                [oracle_cluster(pts, MeasurementConfig(max_cluster_points=9))])
    with pytest.raises(ValueError, match="at least one finite point"):
        prepare_clusters([np.full((2, 2), np.inf)])
    with pytest.raises(ValueError, match="velocity"):
        prepare_clusters([pts[:3] * 0 + 1.0 + np.arange(3)[:, None]], velocities=[[np.nan, 1.0]])
    with pytest.raises(ValueError, match="2 clusters but 1 velocities"):
        prepare_clusters([pts, pts], velocities=[None])
    assert prepare_clusters([]) == []


@pytest.mark.parametrize("batch", ["one-cluster", "single-points", "pairs", "point-at-sensor"])
def test_degenerate_batches_equal_the_oracle(batch) -> None:
    rng = np.random.default_rng(7)
    clusters = {
        "one-cluster": [l_shape(rng, 60)],
        "single-points": [rng.uniform(-30, 30, (1, 2)) for _ in range(5)],  # width 1
        "pairs": [rng.uniform(-30, 30, (2, 2)) for _ in range(4)],
        "point-at-sensor": [np.zeros((1, 2)), l_shape(rng, 12)],
    }[batch]
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        got = prepare_clusters(clusters)
    assert_same(got, [oracle_cluster(c) for c in clusters])
    assert_same([prepare_cluster(c) for c in clusters], [oracle_cluster(c) for c in clusters])


BATCH_FIELDS = ("points", "valid", "part", "proj", "chord_start", "chord_end", "chord_dir", "chord_len", "end_margin",
                "end_gap", "two_sided", "single", "fused", "velocity", "centroid")


@pytest.mark.parametrize("seed", range(3))
def test_scanned_batch_is_the_batch_with_its_shadow_flags(seed: int) -> None:
    """``prepare_scanned_batch`` (one call of ``scanned_batch_kernel``) gives bit for bit what
    ``prepare_batch`` then ``occluded_ends`` and ``continued_ends`` of its ends give, with the flags
    switched off as the settings say; some ends of the random clusters are in shadows, some continue."""
    from tracker.clustering import continued_ends, occluded_ends
    from tracker.preparation import prepare_scanned_batch

    rng = np.random.default_rng(seed)
    clusters = [c + np.array([30.0, 0.0]) for c in random_clusters(seed)]
    velocities = [rng.normal(0.0, 10.0, 2) if rng.random() < 0.5 else None for _ in clusters]
    scan = np.concatenate(clusters + [rng.uniform(-60.0, 60.0, (300, 2))])
    resolution, max_range = np.radians(0.2), 60.0
    flags = [0, 0]
    settings = [MeasurementConfig(), MeasurementConfig(shadow_window=None),
                MeasurementConfig(continuation_rays=None),
                MeasurementConfig(shadow_window=3.0, continuation_rays=2.0)]
    for config in settings:
        got = prepare_scanned_batch(clusters, config, velocities, scan, resolution, max_range)
        ref = prepare_batch(clusters, config, velocities)
        for name in BATCH_FIELDS:
            np.testing.assert_array_equal(getattr(got, name), getattr(ref, name), err_msg=name)
        if config.shadow_window is None:
            assert got.occluded_end is None and got.continued_end is None
            continue
        occluded = occluded_ends(ref.bearing_ends(), scan, config.shadow_window * resolution, config.shadow_margin,
                                 max_range, config.shadow_range_margin)
        np.testing.assert_array_equal(got.occluded_end, occluded)
        flags[0] += int(occluded.sum())
        if config.continuation_rays is None:
            assert got.continued_end is None
            continue
        continued = continued_ends(*ref.side_ends(), scan, config.continuation_rays, config.continuation_offset)
        np.testing.assert_array_equal(got.continued_end, continued)
        flags[1] += int(continued.sum())
    assert flags[0] > 0 and flags[1] > 0
    # a cluster with a non-finite point: its point dropped, the flags of the batch's ends the same way
    clusters[2] = np.vstack([clusters[2], [[np.nan, 0.0]]])
    config = settings[-1]
    got = prepare_scanned_batch(clusters, config, velocities, scan, resolution, max_range)
    ref = prepare_batch(clusters, config, velocities)
    for name in BATCH_FIELDS:
        np.testing.assert_array_equal(getattr(got, name), getattr(ref, name), err_msg=name)
    np.testing.assert_array_equal(got.occluded_end, occluded_ends(
        ref.bearing_ends(), scan, config.shadow_window * resolution, config.shadow_margin, max_range,
        config.shadow_range_margin))
    np.testing.assert_array_equal(got.continued_end, continued_ends(*ref.side_ends(), scan, config.continuation_rays,
                                                                    config.continuation_offset))


def test_scanned_batch_needs_a_two_dimensional_scan() -> None:
    from tracker.preparation import prepare_scanned_batch

    with pytest.raises(ValueError, match=r"\(N, 2\)"):
        prepare_scanned_batch(random_clusters(0), MeasurementConfig(), None, np.zeros((10, 3)), 0.0035, 100.0)
