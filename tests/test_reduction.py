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


def test_merge_across_the_start_of_a_closed_road():
    # s wraps at 500 m: components at 499.95 m and 0.05 m are 0.1 m apart
    mix = mixture([0.6, 0.6], [[499.95, 0.0], [0.05, 0.0]], [0.01, 0.01], [1, 2])
    wrap = Wrapping(periods=((0, 500.0),))
    out = merge(mix, gate=4.0, wrapping=wrap)
    assert len(out) == 1 and out.weights[0] == pytest.approx(1.2)
    assert min(out.means[0, 0], 500.0 - out.means[0, 0]) == pytest.approx(0.0, abs=1e-9)
    assert len(merge(mix, gate=4.0)) == 2  # without the period they are 499.9 m apart
