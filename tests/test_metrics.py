"""Tests of sim/evaluation/metrics.py: hand-computed GOSPA cases and Stone Soup's GOSPAMetric as the oracle."""

from __future__ import annotations

import datetime

import numpy as np
import pytest

from sim.evaluation.metrics import (
    IdSwitchCounter,
    cardinality_error,
    euclidean_distances,
    gaussian_wasserstein,
    gospa,
    matched_errors,
)


def test_hand_computed_assignment_and_parts():
    truth = np.array([[0.0, 0.0], [10.0, 0.0], [50.0, 50.0]])
    est = np.array([[10.0, 1.0], [0.0, 2.0], [100.0, 100.0], [20.0, 20.0]])
    r = gospa(truth, est, c=5.0, p=2.0)
    # truth 0 <-> est 1 (2 m), truth 1 <-> est 0 (1 m); truth 2 missed; est 2, 3 false
    assert sorted(zip(r.truth_index.tolist(), r.estimate_index.tolist())) == [(0, 1), (1, 0)]
    assert r.localization == pytest.approx(4.0 + 1.0)
    assert r.missed == pytest.approx(12.5)
    assert r.false == pytest.approx(25.0)
    assert r.gospa == pytest.approx(np.sqrt(5.0 + 12.5 + 25.0))


def test_pair_beyond_cutoff_counts_as_missed_plus_false():
    r = gospa(np.array([[0.0, 0.0]]), np.array([[6.0, 0.0]]), c=5.0, p=1.0)
    assert r.assigned == 0 and r.localization == 0.0
    assert (r.missed, r.false, r.gospa) == pytest.approx((2.5, 2.5, 5.0))
    # exactly at the cut-off: unassigned as well
    r = gospa(np.array([[0.0, 0.0]]), np.array([[5.0, 0.0]]), c=5.0, p=2.0)
    assert r.assigned == 0 and r.gospa == pytest.approx(5.0)


def test_empty_sets():
    assert gospa(np.zeros((0, 2)), np.zeros((0, 2))).gospa == 0.0
    r = gospa(np.zeros((0, 2)), np.array([[1.0, 1.0], [2.0, 2.0]]), c=4.0, p=2.0)
    assert (r.missed, r.false, r.gospa) == pytest.approx((0.0, 16.0, 4.0))
    r = gospa(np.array([[1.0, 1.0]]), [], c=4.0, p=2.0)
    assert (r.missed, r.false, r.gospa) == pytest.approx((8.0, 0.0, np.sqrt(8.0)))


def test_bad_input():
    with pytest.raises(ValueError, match="cut-off"):
        gospa(np.zeros((1, 2)), np.zeros((1, 2)), c=0.0)
    with pytest.raises(ValueError, match="order p"):
        gospa(np.zeros((1, 2)), np.zeros((1, 2)), p=0.5)
    with pytest.raises(ValueError, match=r"truth_xy must have shape \(N, 2\)"):
        gospa(np.zeros((2, 3)), np.zeros((1, 2)))
    with pytest.raises(ValueError, match="non-finite"):
        gospa(np.array([[np.nan, 0.0]]), np.zeros((1, 2)))


def test_agrees_with_stone_soup_on_random_sets():
    pytest.importorskip("stonesoup")
    from stonesoup.measures import Euclidean
    from stonesoup.metricgenerator.ospametric import GOSPAMetric
    from stonesoup.types.state import State

    rng = np.random.default_rng(42)
    now = datetime.datetime(2026, 1, 1)
    for trial in range(200):
        c = float(rng.choice([2.0, 5.0, 10.0]))
        p = float(rng.choice([1.0, 2.0, 3.0]))
        truth = rng.uniform(0.0, 20.0, size=(rng.integers(0, 7), 2))
        est = rng.uniform(0.0, 20.0, size=(rng.integers(0, 7), 2))
        ours = gospa(truth, est, c=c, p=p)
        metric = GOSPAMetric(c=c, p=p, measure=Euclidean(mapping=[0, 1]))
        states_t = [State(row.reshape(2, 1), timestamp=now) for row in truth]
        states_e = [State(row.reshape(2, 1), timestamp=now) for row in est]
        if not states_t and not states_e:
            continue
        ref, _ = metric.compute_gospa_metric(states_e, states_t)
        ref = ref.value
        assert ours.gospa == pytest.approx(ref["distance"], abs=1e-9), trial
        assert ours.localization == pytest.approx(ref["localisation"], abs=1e-9), trial
        assert ours.missed == pytest.approx(ref["missed"], abs=1e-9), trial
        assert ours.false == pytest.approx(ref["false"], abs=1e-9), trial


def test_gaussian_wasserstein_geometry():
    a = np.array([[0.0, 0.0, 0.0, 4.0, 2.0]])
    # same rectangle: 0; translation only: the centre distance
    assert gaussian_wasserstein(a, a)[0, 0] == pytest.approx(0.0, abs=1e-9)
    b = a + np.array([[3.0, 4.0, 0.0, 0.0, 0.0]])
    assert gaussian_wasserstein(a, b)[0, 0] == pytest.approx(5.0)
    # a rectangle turned by pi is the same rectangle
    assert gaussian_wasserstein(a, a + [[0, 0, np.pi, 0, 0]])[0, 0] == pytest.approx(0.0, abs=1e-6)
    # axis-aligned extents: GW^2 = |dm|^2 + sum (sqrt(a_i) - sqrt(b_i))^2 = half-axis differences
    c = np.array([[0.0, 0.0, 0.0, 6.0, 2.0]])
    assert gaussian_wasserstein(a, c)[0, 0] == pytest.approx(1.0)
    d = np.array([[0.0, 0.0, np.pi / 2, 4.0, 2.0]])  # turned 90 deg: half-axes (2,1) vs (1,2)
    assert gaussian_wasserstein(a, d)[0, 0] == pytest.approx(np.sqrt(2.0))
    r = gospa(a, np.vstack([b, d]), c=5.0, distance=gaussian_wasserstein)
    assert r.estimate_index.tolist() == [1]


def test_matched_errors_and_cardinality():
    truth = np.array([[0.0, 0.0, 10.0, 3.1, 0.0, 4.8, 2.0]])
    est = np.array([[0.3, 0.4, 11.0, -3.1, 0.0, 4.5, 2.2]])
    r = gospa(truth[:, :2], est[:, :2])
    e = matched_errors(truth, est, r)
    assert e.position[0] == pytest.approx(0.5)
    assert e.yaw[0] == pytest.approx(2 * np.pi - 6.2)
    assert (e.speed[0], e.length[0], e.width[0]) == pytest.approx((1.0, -0.3, 0.2))
    # the offset (0.3, 0.4) in the frame of a vehicle heading 3.1 rad: along its heading and to its left
    assert e.along[0] == pytest.approx(0.3 * np.cos(3.1) + 0.4 * np.sin(3.1))
    assert e.across[0] == pytest.approx(0.4 * np.cos(3.1) - 0.3 * np.sin(3.1))
    assert np.hypot(e.along[0], e.across[0]) == pytest.approx(e.position[0])
    assert cardinality_error(3, 1) == -2
    np.testing.assert_allclose(euclidean_distances(truth[:, :2], est[:, :2]), [[0.5]])
    # a point tracker (no extent): length and width errors are missing, the others unchanged
    p = matched_errors(truth, est, r, extent=False)
    assert p.length.size == 0 and p.width.size == 0 and p.position[0] == pytest.approx(0.5)


def test_id_switches():
    counter = IdSwitchCounter()
    assert counter.update([1, 2], [10, 20]) == 0
    assert counter.update([1, 2], [10, 20]) == 0
    assert counter.update([1], [10]) == 0  # truth 2 unassigned this frame
    assert counter.update([1, 2], [20, 21]) == 2  # truth 1 took 20, truth 2 re-found as 21
    assert counter.update([1, 2], [20, 21]) == 0
    assert counter.switches == 2
