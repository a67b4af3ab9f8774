"""Tests of tracker/reduction.py: moment matching, angle-aware merging, labels, prune and cap."""

from __future__ import annotations

import numpy as np
import pytest

from tracker.reduction import Mixture, cap, merge, prune, reduce
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
