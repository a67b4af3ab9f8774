"""Tests of tracker/reduction.py: moment matching, angle-aware merging, labels, prune and cap."""

from __future__ import annotations

import numpy as np
import pytest

from oracles import reduction as oracle
from tracker.reduction import UNION_LENGTH_STD, Mixture, absorb_overlapping, cap, merge, prune, reduce
from tracker.ukf import Wrapping


def mixture(weights, means, variances, labels):
    means = np.asarray(means, dtype=float).reshape(len(weights), -1)
    d = means.shape[1]
    covs = np.array([np.eye(d) * v for v in variances])
    return Mixture(np.asarray(weights, float), means, covs, np.asarray(labels))


def test_merge_moment_matches_and_keeps_heaviest_label():
    mix = mixture([0.6, 0.2, 0.5], [[0.0], [1.0], [50.0]], [1.0, 1.0, 1.0], [7, 3, 9])
    out = merge(mix, gate=4.0)
    assert len(out) == 2
    k = int(np.argmax(out.labels == 7))
    assert out.weights[k] == pytest.approx(0.8)
    assert out.means[k, 0] == pytest.approx(0.25)  # (0.6 * 0 + 0.2 * 1) / 0.8
    # moment matching: sum w (P + (m - mean)^2) / sum w
    assert out.covs[k, 0, 0] == pytest.approx((0.6 * (1 + 0.25**2) + 0.2 * (1 + 0.75**2)) / 0.8)
    assert sorted(out.labels.tolist()) == [7, 9]


def test_merge_wraps_angles():
    mix = mixture([0.5, 0.5], [[0.0, np.pi - 0.1], [0.0, -np.pi + 0.1]], [0.1, 0.1], [1, 2])
    out = merge(mix, gate=4.0, wrapping=Wrapping(angles=(1,)))
    assert len(out) == 1
    assert abs(abs(out.means[0, 1]) - np.pi) < 1e-12  # mean at pi, not at 0
    assert out.covs[0, 1, 1] == pytest.approx(0.1 + 0.01)
    # without angle awareness the two would not merge (2 pi - 0.2 apart)
    assert len(merge(mix, gate=4.0)) == 2


def test_prune_and_cap():
    mix = mixture([0.001, 0.5, 0.3, 0.9], [[0.0], [10.0], [20.0], [30.0]], [1, 1, 1, 1], [1, 2, 3, 4])
    assert prune(mix, 0.01).labels.tolist() == [2, 3, 4]
    assert cap(mix, 2).labels.tolist() == [4, 2]
    out = reduce(mix, prune_threshold=0.01, merge_gate=4.0, max_components=2)
    assert out.labels.tolist() == [4, 2]
    assert out.weights.sum() == pytest.approx(1.4)


def test_merge_same_label_joins_close_heavy_fragments_only():
    from tracker.reduction import merge_same_label

    # label 3: two heavy posteriors 0.8 m apart (fragments) and a light missed-detection copy;
    # label 4: a heavy component far away with the same label is kept apart
    mix = mixture(
        [1.0, 0.9, 0.1, 1.0, 1.0],
        [[10.0, 0.0], [10.8, 0.0], [10.4, 0.0], [50.0, 0.0], [10.0, 3.5]],
        [0.01, 0.01, 0.01, 0.01, 0.01],
        [3, 3, 3, 4, 4],
    )
    out = merge_same_label(mix, distance=2.0, min_weight=0.5)
    assert sorted(out.labels.tolist()) == [3, 3, 4, 4]
    heavy3 = (out.labels == 3) & (out.weights > 0.5)
    assert out.weights[heavy3][0] == pytest.approx(1.9)
    assert out.means[heavy3][0, 0] == pytest.approx((10.0 * 1.0 + 10.8 * 0.9) / 1.9)
    assert np.any((out.labels == 3) & np.isclose(out.weights, 0.1))  # the light copy is untouched
    assert np.count_nonzero(out.labels == 4) == 2  # 40 m apart: not merged


@pytest.mark.parametrize("heading", [0.0, 0.3])
def test_merge_same_label_reaches_half_a_long_vehicle_along_it(heading):
    """A 13.5 m truck's points in three clusters updated its track 4.5 m apart along it: with
    ``along_length`` two heavy posteriors of one label within half the heaviest's length along its
    heading (and ``distance`` across) are one track; a car's (4.5 m) are not, nor is a truck's
    posterior 4 m to its side; without ``along_length`` only ``distance`` counts."""
    from tracker.reduction import merge_same_label

    u, v = np.array([np.cos(heading), np.sin(heading)]), np.array([-np.sin(heading), np.cos(heading)])

    def state(pos, length):  # [s, n, v, xi, xi_dot, L, W]
        return [pos[0], pos[1], 15.0, heading, 0.0, length, 2.5]

    for length, merged in ((13.5, True), (4.5, False)):
        far = 4.5 * u + 0.5 * v
        mix = mixture([1.0, 0.9], [state((0.0, 0.0), length), state(far, length)], [0.01, 0.01], [5, 5])
        assert (len(merge_same_label(mix, distance=3.0, along_length=True)) == 1) == merged
        assert len(merge_same_label(mix, distance=3.0, along_length=False)) == 2
    beside = mixture([1.0, 0.9], [state((0.0, 0.0), 13.5), state(4.0 * v, 13.5)], [0.01, 0.01], [5, 5])
    assert len(merge_same_label(beside, distance=3.0, along_length=True)) == 2


def test_merge_across_the_start_of_a_closed_road():
    # s wraps at 500 m: components at 499.95 m and 0.05 m are 0.1 m apart
    mix = mixture([0.6, 0.6], [[499.95, 0.0], [0.05, 0.0]], [0.01, 0.01], [1, 2])
    wrap = Wrapping(periods=((0, 500.0),))
    out = merge(mix, gate=4.0, wrapping=wrap)
    assert len(out) == 1 and out.weights[0] == pytest.approx(1.2)
    assert min(out.means[0, 0], 500.0 - out.means[0, 0]) == pytest.approx(0.0, abs=1e-9)
    assert len(merge(mix, gate=4.0)) == 2  # without the period they are 499.9 m apart


@pytest.mark.parametrize("seed", range(5))
def test_merge_equals_the_one_at_a_time_greedy_merge(seed):
    rng = np.random.default_rng(seed)
    n = 40
    centres = rng.uniform([0, -5, 10, -0.2, -0.1, 4, 1.8], [50, 5, 20, 0.2, 0.1, 5, 2.0], (6, 7))
    means = centres[rng.integers(0, 6, n)] + rng.normal(0, 0.3, (n, 7)) * [1, 0.3, 0.5, 0.02, 0.02, 0.1, 0.05]
    means[:5, 3] = np.pi - 0.01 * rng.random(5)  # headings across the +-pi cut
    means[5:10, 3] = -np.pi + 0.01 * rng.random(5)
    a = rng.normal(size=(n, 7, 7)) * 0.3
    covs = a @ np.swapaxes(a, 1, 2) + np.diag([0.5, 0.1, 0.3, 0.01, 0.01, 0.2, 0.05])
    mix = Mixture(rng.uniform(0.01, 1.0, n), means, covs, np.arange(n))
    wrap = Wrapping(angles=(3,), periods=((0, 60.0),))
    got, want = merge(mix, 4.0, wrap), oracle.merge(mix, 4.0, wrap)
    assert len(want) < n  # something merged
    np.testing.assert_array_equal(got.labels, want.labels)
    for name in ("weights", "means", "covs"):
        np.testing.assert_allclose(getattr(got, name), getattr(want, name), rtol=1e-12, atol=1e-12, err_msg=name)


def vehicles(rows, length_std=0.3, weights=None):
    """A mixture of states ``[s, n, v, xi, xi_dot, L, W]`` from rows ``(label, s, n, L, W)``."""
    means = np.array([[s, n, 10.0, 0.0, 0.0, length, width] for _, s, n, length, width in rows])
    covs = np.array([np.diag([0.2, 0.1, 0.5, 0.01, 0.01, length_std**2, 0.05]) for _ in rows])
    w = np.ones(len(rows)) if weights is None else np.asarray(weights, float)
    return Mixture(w, means, covs, np.array([r[0] for r in rows]))


def test_two_labels_whose_rectangles_overlap_along_the_road_are_one_vehicle():
    # a truck's side seen as two fragments, both lengths seen: label 9 (a newcomer, 101.5 .. 106.5 m)
    # overlaps label 5 (last frame's track, 97 .. 103 m) by 1.5 m; 5 keeps its label and takes the union of
    # the two, 97 .. 106.5 m; 9 goes with every component it has (a light one too)
    mix = vehicles([(5, 100.0, 0.1, 6.0, 2.3), (9, 104.0, -0.2, 5.0, 2.5), (9, 103.0, 0.0, 5.0, 2.5), (4, 130.0, 0.0, 4.5, 1.8)],
                   weights=[0.9, 1.0, 0.2, 1.0])
    out, absorbed = absorb_overlapping(mix, 0.5, 0.5, keep_labels={5})
    assert absorbed == 1 and sorted(out.labels.tolist()) == [4, 5]
    k = int(np.flatnonzero(out.labels == 5)[0])
    assert out.means[k, 0] == pytest.approx(101.75) and out.means[k, 5] == pytest.approx(9.5)
    assert out.means[k, 6] == pytest.approx(2.5) and out.weights[k] == pytest.approx(1.0)  # the wider, the heavier
    assert out.covs[k, 0, 0] == pytest.approx(0.2 + 1.75**2) and out.covs[k, 5, 5] == pytest.approx(0.3**2 + 3.5**2)
    assert out.means[k, 1] == pytest.approx(0.1)  # the keeper's own lateral offset, speed, heading
    # without last frame's tracks the smaller (older) label keeps (same lengths known: the same union)
    out, _ = absorb_overlapping(mix, 0.5, 0.5)
    assert sorted(out.labels.tolist()) == [4, 5]
    out, _ = absorb_overlapping(mix, 0.5, 0.5, keep_labels={9})
    assert sorted(out.labels.tolist()) == [4, 9, 9]  # the keeper keeps its light component
    assert out.means[int(np.flatnonzero(out.labels == 9)[0]), 0] == pytest.approx(101.75)


def test_a_prior_length_is_no_evidence_of_where_a_vehicle_ends():
    # two newcomers for one car from the first scan, each with the prior's 4.5 m (sd 1 m), 3 m apart: the
    # older keeps its own rectangle (their union, 7.5 m, would be a car's length wrong by 3 m)
    mix = vehicles([(2, 17.0, 1.6, 4.5, 1.8), (1, 20.0, 1.7, 4.5, 1.8)], length_std=1.0)
    out, absorbed = absorb_overlapping(mix, 0.5, 0.5)
    assert absorbed == 1 and out.labels.tolist() == [1]
    assert out.means[0].tolist() == mix.means[1].tolist()
    assert UNION_LENGTH_STD < 1.0
    # of two newcomers the longer hypothesis keeps: a truck's prior (12 m) over a car's
    mix = vehicles([(3, 89.4, 4.2, 7.6, 1.8), (7, 82.8, 4.0, 12.0, 2.5)], length_std=1.0)
    out, _ = absorb_overlapping(mix, 0.5, 0.5)
    assert out.labels.tolist() == [7] and out.means[0, 5] == 12.0


@pytest.mark.parametrize("rows, why", [
    ([(1, 100.0, 0.0, 4.5, 1.8), (2, 100.0, 3.5, 4.5, 1.8)], "side by side in adjacent lanes"),
    ([(1, 100.0, 0.0, 4.5, 1.8), (2, 105.5, 0.0, 4.5, 1.8)], "bumper to bumper, 1 m apart"),
    ([(1, 100.0, 0.0, 4.5, 1.8), (2, 104.2, 0.0, 4.5, 1.8)], "overlapping by 0.3 m, less than the 0.5 allowed"),
    ([(1, 100.0, 0.0, 4.5, 1.8), (1, 102.0, 0.0, 4.5, 1.8)], "one label (merge_same_label's case)"),
])
def test_vehicles_that_do_not_overlap_keep_their_labels(rows, why):
    mix = vehicles(rows)
    out, absorbed = absorb_overlapping(mix, 0.5, 0.5)
    assert absorbed == 0 and out is mix, why
    # light components (below the extraction threshold) are not tracks: never absorbed
    heavy = vehicles([(1, 100.0, 0.0, 4.5, 1.8), (2, 101.0, 0.0, 4.5, 1.8)], weights=[1.0, 0.3])
    assert absorb_overlapping(heavy, 0.5, 0.5)[1] == 0


def test_overlap_is_taken_along_the_heading_in_cartesian_states_and_across_a_closed_roads_start():
    north = lambda label, y, length: [label, 0.0, y, 10.0, np.pi / 2, 0.0, length, 2.5]  # noqa: E731
    means = np.array([north(1, 100.0, 6.0)[1:], north(2, 104.0, 5.0)[1:]])
    covs = np.array([np.diag([0.2, 0.2, 0.5, 0.01, 0.01, 0.09, 0.05])] * 2)
    mix = Mixture(np.ones(2), means, covs, np.array([1, 2]))
    out, absorbed = absorb_overlapping(mix, 0.5, 0.5, cartesian=True)
    assert absorbed == 1 and out.means[0, 1] == pytest.approx(101.75) and out.means[0, 0] == pytest.approx(0.0)
    assert out.means[0, 5] == pytest.approx(9.5)
    # beside each other (3.5 m apart in x, across the heading): two vehicles
    means[1, :2] = [3.5, 100.0]
    assert absorb_overlapping(Mixture(np.ones(2), means, covs, np.array([1, 2])), 0.5, 0.5, cartesian=True)[1] == 0
    # a 1000 m ring: 998 m and 3 m are 5 m apart the short way round; the union's centre wraps
    ring = vehicles([(1, 998.0, 0.0, 6.0, 2.5), (2, 3.0, 0.0, 6.0, 2.5)])
    out, absorbed = absorb_overlapping(ring, 0.5, 0.5, Wrapping(periods=((0, 1000.0),)))
    assert absorbed == 1 and out.means[0, 0] == pytest.approx(0.5) and out.means[0, 5] == pytest.approx(11.0)


def test_a_coasting_tracks_label_goes_to_the_updated_newcomer_beside_it():
    # last frame's track 3 coasts (no cluster updated it: its prediction missed its car, whose points
    # seeded newcomer 8 beside it, overlapping it by 2 m): the label stays 3, the state is 8's
    mix = vehicles([(3, 100.0, 0.0, 4.5, 1.8), (8, 102.5, 0.1, 4.5, 1.8)], length_std=1.0, weights=[0.8, 1.0])
    out, absorbed = absorb_overlapping(mix, 0.5, 0.5, keep_labels={3}, updated={8})
    assert absorbed == 1 and out.labels.tolist() == [3]
    assert out.means[0].tolist() == mix.means[1].tolist() and out.weights[0] == 1.0
    # both updated (fragments of one vehicle): the keeper's own state
    out, _ = absorb_overlapping(mix, 0.5, 0.5, keep_labels={3}, updated={3, 8})
    assert out.labels.tolist() == [3] and out.means[0].tolist() == mix.means[0].tolist()


def test_a_coasting_tracks_prediction_is_no_fragment_of_the_newcomers_vehicle():
    # both lengths known (a car's 4.8 m, seen before): coasting track 3's prediction missed its car by
    # 2.5 m and newcomer 8 sits on it; the label is 3's and the state 8's, with 8's own length, not the
    # 7.3 m union of a prediction and a measurement (Cartesian occlusion, seeds 3, 9 and 11: 9.5-9.9 m)
    mix = vehicles([(3, 100.0, 0.0, 4.8, 1.9), (8, 102.5, 0.1, 4.8, 1.9)], length_std=0.2, weights=[0.8, 1.0])
    out, absorbed = absorb_overlapping(mix, 0.5, 0.5, keep_labels={3}, updated={8})
    assert absorbed == 1 and out.labels.tolist() == [3]
    assert out.means[0].tolist() == mix.means[1].tolist() and out.means[0, 5] == pytest.approx(4.8)
    # both seen (two fragments of one long vehicle): their union
    out, _ = absorb_overlapping(mix, 0.5, 0.5, keep_labels={3}, updated={3, 8})
    assert out.means[0, 5] == pytest.approx(7.3)


@pytest.mark.parametrize("seed", range(3))
def test_merge_equals_the_oracle(seed):
    """Mixtures of clumps of components (so that groups form), headings across +-pi and arc lengths
    across a closed road's seam, with and without wrapping, gates of 4 and 30: the same groups (labels)
    and the same moments to 1e-9."""
    rng = np.random.default_rng(seed)
    wrappings = [Wrapping(), Wrapping(angles=(3,), periods=((0, 500.0),))]
    merged = 0
    for _ in range(60):
        n = int(rng.integers(2, 40))
        centre = rng.choice([0.5, 250.0, 499.6], size=n)
        means = np.column_stack([centre + rng.normal(0, 1.0, n), rng.normal(0, 1.0, n), rng.uniform(5, 30, n),
                                 rng.choice([-3.1, 0.0, 3.1], size=n) + rng.normal(0, 0.05, n), rng.normal(0, 0.1, n),
                                 rng.uniform(3, 12, n), rng.uniform(1.5, 2.6, n)])
        a = rng.normal(size=(n, 7, 7)) * rng.uniform(0.1, 1.0, (n, 1, 1))
        covs = a @ np.swapaxes(a, 1, 2) + 0.05 * np.eye(7)
        mix = Mixture(rng.uniform(0.01, 1.0, n), np.mod(means, [500.0, 1e9, 1e9, 1e9, 1e9, 1e9, 1e9]), covs,
                      rng.integers(0, 50, n))
        for wrapping in wrappings:
            for gate in (4.0, 30.0):
                got, want = merge(mix, gate, wrapping), oracle.merge(mix, gate, wrapping)
                np.testing.assert_array_equal(got.labels, want.labels)
                for name in ("weights", "means", "covs"):
                    np.testing.assert_allclose(getattr(got, name), getattr(want, name), rtol=1e-9, atol=1e-9)
                merged += len(got) < n
    assert merged > 0


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_merge_of_low_dimensional_mixtures_equals_the_oracle(dim):
    """Merging states of one to three coordinates (the position bound reads the first two only where
    they exist): the same groups and moments as the oracle."""
    rng = np.random.default_rng(dim)
    for _ in range(50):
        n = int(rng.integers(2, 12))
        root = rng.normal(0.0, 1.0, (n, dim, dim)) * rng.uniform(0.2, 1.5, (n, 1, 1))
        mix = Mixture(rng.uniform(0.05, 1.0, n), rng.choice([0.0, 3.0, 40.0], (n, 1)) + rng.normal(0.0, 1.0, (n, dim)),
                      root @ np.swapaxes(root, 1, 2) + 0.05 * np.eye(dim), rng.integers(0, 9, n))
        got, want = merge(mix, 4.0), oracle.merge(mix, 4.0)
        np.testing.assert_array_equal(got.labels, want.labels)
        for name in ("weights", "means", "covs"):
            np.testing.assert_allclose(getattr(got, name), getattr(want, name), rtol=1e-9, atol=1e-9)


def test_merge_at_the_gate():
    """Pairs whose distance lies just inside and just outside the gate along one axis of a diagonal
    covariance (where the position bound that lets the merge skip a pair equals the distance itself):
    merged only inside, as the oracle."""
    gate = 4.0
    for axis in (0, 1):
        for factor in (1.0 - 1e-7, 1.0 + 1e-7, 1.0 + 1e-5, 1.0 - 1e-5):
            covs = np.broadcast_to(np.diag([2.0, 0.5, 1.0, 0.01, 0.01, 0.3, 0.05]), (2, 7, 7)).copy()
            means = np.zeros((2, 7))
            means[1, axis] = np.sqrt(gate * covs[0, axis, axis] * factor)
            mix = Mixture(np.array([0.9, 0.6]), means, covs, np.array([1, 2]))
            got, want = merge(mix, gate), oracle.merge(mix, gate)
            assert len(got) == len(want) == (1 if factor < 1.0 else 2), (axis, factor)
            np.testing.assert_array_equal(got.labels, want.labels)


@pytest.mark.parametrize("seed", range(3))
def test_the_screen_of_absorb_overlapping_equals_the_oracle(seed):
    """``absorb_overlapping``'s compiled screen (``_screened_candidates``: the candidates and whether two
    of them may overlap) against the oracle's candidates and pair test: random heavy components of a few
    labels, apart and overlapping, curvilinear (across a closed road's seam too) and Cartesian; a periodic
    lateral position (which the screen leaves to the pair test). A label is absorbed exactly where the
    oracle finds a pair ``i < j`` that overlaps (along ``i``'s heading), and both outcomes are reached."""
    from tracker.reduction import _position_periods, _screened_candidates

    rng = np.random.default_rng(seed)
    outcomes = set()
    for _ in range(80):
        n = int(rng.integers(2, 14))
        means = np.column_stack([rng.choice([1.0, 150.0, 499.0], n) + rng.normal(0.0, 6.0, n), rng.normal(0.0, 2.0, n),
                                 rng.uniform(5, 30, n), rng.normal(0.0, 0.3, n), np.zeros(n),
                                 rng.uniform(3.0, 14.0, n), rng.uniform(1.6, 2.6, n)])
        covs = np.broadcast_to(np.diag([1.0, 0.1, 1.0, 0.01, 0.01, rng.uniform(0.1, 2.0), 0.05]), (n, 7, 7)).copy()
        mix = Mixture(rng.uniform(0.3, 1.0, n), np.mod(means, [500.0, *[1e9] * 6]), covs, rng.integers(1, 6, n))
        for wrapping, cartesian in ((Wrapping(angles=(3,)), False), (Wrapping(angles=(3,), periods=((0, 500.0),)), False),
                                    (Wrapping(angles=(3,)), True), (Wrapping(angles=(3,), periods=((1, 7.0),)), False)):
            periods, s_period = _position_periods(wrapping)
            cand, may_overlap = _screened_candidates(mix, 0.5, 0.3, cartesian, bool(periods), s_period)
            want = oracle.absorb_candidates(mix, 0.5)
            np.testing.assert_array_equal(cand, want)
            over = oracle.overlapping(mix.means[want], 0.3, cartesian, periods) if len(want) >= 2 else np.zeros((0, 0))
            assert may_overlap == (len(want) >= 2 if periods and s_period is None else bool(over.any()))
            _, count = absorb_overlapping(mix, 0.5, 0.3, wrapping, cartesian, {1, 2}, {2, 3})
            assert (count > 0) == bool(np.triu(over).any())  # the pairs taken in order (i < j)
            outcomes.add(count > 0)
    assert outcomes == {True, False}


def test_overlapping_pairs_kernel_against_the_rule():
    """``overlapping_pairs_kernel`` against the rule written out here: ``i`` and ``j`` overlap when the
    centres are closer along the road (along ``i``'s heading, Cartesian) than half the lengths' sum
    less ``overlap``, and across it than half the narrower width; ``s`` wraps on a closed road."""
    from tracker.reduction import overlapping_pairs_kernel

    rng = np.random.default_rng(7)
    hits = 0
    for cartesian, period in ((False, 0.0), (False, 300.0), (True, 0.0)):
        for _ in range(30):
            n = int(rng.integers(2, 12))
            m = np.column_stack([rng.choice([2.0, 150.0, 298.0], n) + rng.normal(0.0, 5.0, n), rng.normal(0.0, 2.0, n),
                                 np.zeros(n), rng.normal(0.0, 0.4, n), np.zeros(n), rng.uniform(3.0, 14.0, n),
                                 rng.uniform(1.6, 2.6, n)])
            heading = m[:, 3] if cartesian else np.zeros(n)
            got = overlapping_pairs_kernel(m, np.cos(heading), np.sin(heading), cartesian, 0.3, period)
            for i in range(n):
                for j in range(n):
                    d = m[j, :2] - m[i, :2]
                    if period:
                        d[0] -= period * np.floor(d[0] / period + 0.5)
                    c, s = np.cos(heading[i]), np.sin(heading[i])
                    along, across = (d[0] * c + d[1] * s, -d[0] * s + d[1] * c) if cartesian else (d[0], d[1])
                    rule = (i != j and abs(along) < 0.5 * (m[i, 5] + m[j, 5]) - 0.3
                            and abs(across) < 0.5 * min(m[i, 6], m[j, 6]))
                    assert got[i, j] == rule, (cartesian, period, i, j)
                    hits += rule
    assert hits > 0


def test_absorb_candidates_kernel_equals_the_oracle():
    """``absorb_candidates_kernel`` against the oracle's candidates of ``absorb_overlapping``: the
    heaviest component of each label among those of weight >= the threshold (weights at it, and ties of
    weight, which go in index order), heaviest first; none and one too."""
    from tracker.reduction import absorb_candidates_kernel

    rng = np.random.default_rng(3)
    for _ in range(200):
        n = int(rng.integers(0, 16))
        weights = rng.choice([0.2, 0.5, np.nextafter(0.5, 0.0), 0.7, 0.9], n)
        labels = rng.integers(1, 6, n)
        mix = Mixture(weights, np.zeros((n, 7)), np.zeros((n, 7, 7)), labels)
        np.testing.assert_array_equal(absorb_candidates_kernel(weights, labels.astype(np.int64), 0.5),
                                      oracle.absorb_candidates(mix, 0.5))


def _random_mixture(rng, n: int, dim: int, road_length: float):
    """``n`` random components of ``dim`` (7 or 8) state entries in a few groups of near-duplicates
    (merged by a gate of 4), some across a closed road's start (``s`` below 0 and at or beyond
    ``road_length``), weights partly at 1e-4 (the prune threshold) and 0.5, labels of a few values."""
    centre = rng.choice([-0.4, 0.0, 30.0, road_length - 0.3, road_length, 0.5 * road_length], n)
    means = np.column_stack([centre + rng.choice([0.0, 1.0], n) * rng.normal(0.0, 0.8, n), rng.normal(0.0, 1.5, n),
                             rng.uniform(5, 30, n), rng.normal(0.0, 0.2, n) + rng.choice([0.0, np.pi], n),
                             rng.normal(0.0, 0.05, n), rng.uniform(3.0, 14.0, n), rng.uniform(1.6, 2.6, n),
                             rng.normal(0.0, 0.5, n)])[:, :dim]
    root = rng.normal(0.0, 0.3, (n, dim, dim))
    covs = root @ np.swapaxes(root, 1, 2) + np.diag(rng.uniform(0.05, 2.0, dim))
    weights = np.where(rng.random(n) < 0.2, rng.choice([1e-4, np.nextafter(1e-4, 0.0), 0.5], n), rng.uniform(0.0, 1.0, n))
    return weights, means, covs, rng.integers(1, 5, n)


def _staged_reduce_in_view(mix, near, limit, lateral, bounds, period, **settings):
    """The reduce stage step by step with the product's ``reduce`` (its merge compiled): the mask of the
    components in view and on the road, ``Mixture.take``, ``reduce`` and ``numpy.mod`` of ``s``."""
    inside = near <= limit
    on_road = (lateral >= bounds[0]) & (lateral <= bounds[1])
    counts = int((~inside).sum()), int((inside & ~on_road).sum())
    mix = reduce(mix.take(inside & on_road), **settings)
    if period is not None and len(mix):
        mix.means[:, 0] = np.mod(mix.means[:, 0], period)
    return mix, counts


@pytest.mark.parametrize("dim", [7, 8])
@pytest.mark.parametrize("seed", range(2))
def test_reduce_in_view_equals_the_staged_reduction_and_the_oracle(seed, dim):
    """``tracker.reduction.reduce_in_view`` by one compiled call (``reduce_kernel``) against the staged
    product steps, bit for bit (weights, means, covariances, labels, both counts): random mixtures of 0
    to 25 components, 7 and 8 state entries, closed (``s`` wraps, before and after the merge) and open
    roads, ranges and lateral offsets at their limits, weights at the prune threshold, heavy components
    of one label left apart (``merge_same_label``'s frames), caps of 3 and 100; and the oracle's reduce
    stage (the same labels and counts, numbers to 1e-9)."""
    from tracker.reduction import reduce_in_view

    rng = np.random.default_rng(seed)
    length, limit, bounds = 400.0, 60.0, (-3.0, 2.5)
    seen = {"pending": 0, "capped": 0, "merged": 0, "empty": 0}
    for trial in range(120):
        n = int(rng.integers(0, 26)) if trial % 10 else int(trial % 3)  # some empty and single mixtures
        mix = Mixture(*_random_mixture(rng, n, dim, length))
        near = np.where(rng.random(n) < 0.15, limit, rng.uniform(0.0, 1.3 * limit, n))
        lateral = np.where(rng.random(n) < 0.15, rng.choice(bounds, n), mix.means[:, 1] if n else np.zeros(0))
        closed = bool(trial % 2)
        wrapping = Wrapping(angles=(3,), periods=((0, length),) if closed else ())
        settings = dict(prune_threshold=1e-4, merge_gate=4.0, max_components=3 if trial % 4 == 0 else 100,
                        wrapping=wrapping, same_label_distance=None if trial % 5 == 0 else 3.0,
                        same_label_min_weight=0.5, same_label_along_length=bool(trial % 3))
        period = length if closed else None
        ref, ref_counts = _staged_reduce_in_view(mix, near, limit, lateral, bounds, period, **settings)
        got, *counts = reduce_in_view(mix, near, limit, lateral, bounds, s_period=period, **settings)
        assert tuple(counts) == ref_counts
        for name in ("weights", "means", "covs", "labels"):
            a, b = getattr(got, name), getattr(ref, name)
            assert a.shape == b.shape and a.dtype == b.dtype, name
            np.testing.assert_array_equal(a, b, err_msg=name)
        want, *want_counts = oracle.reduce_in_view(mix, near, limit, lateral, bounds, s_period=period, **settings)
        assert tuple(want_counts) == ref_counts
        np.testing.assert_array_equal(want.labels, got.labels)
        for name in ("weights", "means", "covs"):
            np.testing.assert_allclose(getattr(got, name), getattr(want, name), rtol=1e-9, atol=1e-9)
        kept = int(((near <= limit) & (lateral >= bounds[0]) & (lateral <= bounds[1]) & (mix.weights >= 1e-4)).sum())
        heavy = ref.labels[ref.weights >= 0.5]
        seen["pending"] += settings["same_label_distance"] is not None and len(set(heavy.tolist())) < len(heavy)
        seen["capped"] += len(ref) == 3 and settings["max_components"] == 3 and kept > 3
        seen["merged"] += len(ref) < kept
        seen["empty"] += n == 0
    assert all(seen.values()), seen


def test_reduce_in_view_at_the_limits():
    """Exact limits: a range equal to the limit is in view, a lateral offset equal to a bound on the
    road, a weight equal to the prune threshold kept (one below it dropped), a pair at the merge gate's
    boundary (distance^2 = gate along one axis, times 1 -+ 1e-7) merged only inside it, and ``s`` of
    a lone component beyond the road's length (or below 0) taken modulo it."""
    from tracker.reduction import reduce_in_view

    wrapping = Wrapping(angles=(3,), periods=((0, 300.0),))
    settings = dict(prune_threshold=1e-4, merge_gate=4.0, max_components=100, wrapping=wrapping,
                    same_label_distance=3.0, s_period=300.0)
    for factor in (1.0 - 1e-7, 1.0 + 1e-7):
        covs = np.broadcast_to(np.diag([2.0, 0.5, 1.0, 0.01, 0.01, 0.3, 0.05]), (6, 7, 7)).copy()
        means = np.zeros((6, 7))
        means[:, 5:] = 4.5, 1.9
        means[1, 0] = np.sqrt(4.0 * 2.0 * factor)  # at the gate from component 0
        means[2, 0], means[3, 0], means[4, 0], means[5, 0] = 450.0, -150.0, -200.0, 200.0
        weights = np.array([0.9, 0.6, 1e-4, np.nextafter(1e-4, 0.0), 0.3, 0.3])
        mix = Mixture(weights, means, covs, np.arange(6))
        near = np.array([50.0, 50.0, 50.0, 50.0, 60.0, np.nextafter(60.0, 61.0)])
        lateral = np.array([2.5, -3.0, 0.0, 0.0, 0.0, 0.0])
        got, left_view, off_road = reduce_in_view(mix, near, 60.0, lateral, (-3.0, 2.5), **settings)
        assert (left_view, off_road) == (1, 0)
        assert sorted(got.labels.tolist()) == ([0, 2, 4] if factor < 1.0 else [0, 1, 2, 4])
        assert got.means[got.labels == 2, 0] == 150.0 and got.means[got.labels == 4, 0] == 100.0
