"""Pre-gating of the tracker's update (``tracker.tracker.Tracker._update``): the (component, cluster)
pairs worth a UKF update, in one numba call (``candidate_pairs_kernel``): a component's rectangle centre
within its reach of the cluster's centroid (the distance ``sqrt(dx^2 + dy^2)``), a positive detection
probability, and a cluster free or owned by the component's track group."""

from __future__ import annotations

import math

import numpy as np

from tracker.jit import njit


@njit
def candidate_pairs_kernel(center, reach, centroid, p_d, owned, group):  # pragma: no cover - compiled
    """The pairs ``(comp, clu)``, in row-major order (``numpy.nonzero``'s), of the components whose
    rectangle centre ``center (C, 2)`` lies within ``reach (C,)`` m of the centroid ``centroid[clu]`` of
    the cluster, whose detection probability ``p_d`` is positive, and which may take the cluster: a
    cluster no track owns (``owned[k] < 0``) or one their track group owns (``owned[k] == group[comp]``)."""
    clusters = centroid.shape[0]
    count = center.shape[0]
    comp = np.empty(count * clusters, dtype=np.int64)
    clu = np.empty(count * clusters, dtype=np.int64)
    pairs = 0
    for c in range(count):
        if not p_d[c] > 0.0:
            continue
        for k in range(clusters):
            if owned[k] >= 0 and owned[k] != group[c]:
                continue
            dx = center[c, 0] - centroid[k, 0]
            dy = center[c, 1] - centroid[k, 1]
            if math.sqrt(dx * dx + dy * dy) <= reach[c]:
                comp[pairs] = c
                clu[pairs] = k
                pairs += 1
    return comp[:pairs], clu[:pairs]
