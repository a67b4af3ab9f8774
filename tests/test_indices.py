"""tracker.indices: the count-based unique against numpy.unique."""

from __future__ import annotations

import numpy as np
import pytest

from tracker.indices import unique_indices


@pytest.mark.parametrize("seed", range(4))
def test_unique_indices_equals_numpy_unique(seed):
    rng = np.random.default_rng(seed)
    for _ in range(50):
        count = int(rng.integers(1, 60))
        index = rng.integers(0, count, int(rng.integers(0, 80)))
        used, slot = unique_indices(index, count)
        ref_used, ref_slot = np.unique(index, return_inverse=True)
        np.testing.assert_array_equal(used, ref_used)
        np.testing.assert_array_equal(slot, ref_slot.reshape(-1))
        np.testing.assert_array_equal(used[slot], index)


def test_unique_indices_of_nothing_is_empty():
    used, slot = unique_indices(np.zeros(0, dtype=int), 5)
    assert used.shape == (0,) and slot.shape == (0,)
