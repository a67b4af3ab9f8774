"""Tests of tracker/reduction.py: moment matching, angle-aware merging, labels, prune and cap."""

from __future__ import annotations

import numpy as np
import pytest

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


def greedy_merge_oracle(mix: Mixture, gate: float, wrapping: Wrapping) -> Mixture:
    """Vo & Ma's merge written plainly, one component at a time (the former implementation)."""
    inv = np.linalg.inv(mix.covs)
    remaining = np.ones(len(mix), dtype=bool)
    out_w, out_m, out_p, out_l = [], [], [], []
    for j in np.argsort(-mix.weights, kind="stable"):
        if not remaining[j]:
            continue
        idx = np.flatnonzero(remaining)
        d = wrapping.residual(mix.means[idx] - mix.means[j])
        group = idx[np.einsum("ni,nij,nj->n", d, inv[idx], d) <= gate]
        w = mix.weights[group]
        dev = wrapping.residual(mix.means[group] - mix.means[j])
        mean_dev = (w[:, None] * dev).sum(axis=0) / w.sum()
        spread = dev - mean_dev
        cov = (w[:, None, None] * (mix.covs[group] + spread[:, :, None] * spread[:, None, :])).sum(axis=0) / w.sum()
        out_w.append(w.sum())
        out_m.append(wrapping.wrap(mix.means[j] + mean_dev))
        out_p.append(cov)
        out_l.append(mix.labels[j])
        remaining[group] = False
    return Mixture(np.array(out_w), np.array(out_m), np.array(out_p), np.array(out_l))


@pytest.mark.parametrize("seed", range(5))
def test_batched_merge_equals_the_one_at_a_time_greedy_merge(seed):
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
    got, want = merge(mix, 4.0, wrap), greedy_merge_oracle(mix, 4.0, wrap)
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
