"""Today's tracker reproduces the reference run (tests/reference/tracks.npz, made by
``python tests/make_reference.py``): the guard that a speed-up of ``tracker`` changed no result.

Tolerance 1e-9 (absolute and relative): a reordering of floating-point sums (batched BLAS, a different
vectorisation) moves numbers by ~1e-15 per operation; anything that changes a decision (a gate, a
prune, a label) or a formula moves them by far more."""

from __future__ import annotations

import numpy as np
from make_reference import REFERENCE, run_reference

TOLERANCE = 1e-9


def test_tracker_reproduces_the_reference_run():
    ref = np.load(REFERENCE)
    now = run_reference()
    np.testing.assert_array_equal(now["frame"], ref["frame"], err_msg="tracks reported in other frames")
    np.testing.assert_array_equal(now["label"], ref["label"], err_msg="other labels")
    for key in ("weight", "mean", "cov"):
        np.testing.assert_allclose(now[key], ref[key], rtol=TOLERANCE, atol=TOLERANCE, err_msg=key)
