"""Today's tracker reproduces the reference run (tests/reference/tracks.npz, made by
``python tests/make_reference.py``): the guard that a speed-up of ``tracker`` changed no result.

Tolerance: the same frames and labels exactly (any change of a decision -- a gate, a prune, a merge,
a label -- shows there), weights within 1e-9, every mean within 1e-6 of its own standard deviation
(plus 1e-9), covariances within a relative 1e-6. Why not 1e-9 everywhere: the batched cluster
preparation (``tracker.preparation``) sums the same numbers in another order (~1e-16
relative), and over 40 frames the filter amplifies that to 3e-8 m on one track's last two frames (an
ill-conditioned update of a track whose length is still being learnt), i.e. 4e-7 of its standard
deviation. A change of the method moves numbers by far more."""

from __future__ import annotations

import numpy as np
from make_reference import REFERENCE, run_reference


def test_tracker_reproduces_the_reference_run():
    ref = np.load(REFERENCE)
    now = run_reference()
    np.testing.assert_array_equal(now["frame"], ref["frame"], err_msg="tracks reported in other frames")
    np.testing.assert_array_equal(now["label"], ref["label"], err_msg="other labels")
    np.testing.assert_allclose(now["weight"], ref["weight"], rtol=0.0, atol=1e-9, err_msg="weight")
    sd = np.sqrt(np.diagonal(ref["cov"], axis1=1, axis2=2))
    off = np.abs(now["mean"] - ref["mean"])
    assert np.all(off <= 1e-6 * sd + 1e-9), f"means moved by up to {np.max(off / (sd + 1e-300)):.2e} standard deviations"
    scale = np.sqrt(np.einsum("kii,kjj->kij", np.abs(ref["cov"]), np.abs(ref["cov"])))  # sqrt(P_ii P_jj)
    assert np.all(np.abs(now["cov"] - ref["cov"]) <= 1e-6 * scale + 1e-12), "covariances moved"
