"""Compiled steps of the tracker's extraction of the tracks (``Tracker._extract``).

``report_centres_kernel``: the report-range test's rectangle centres in E of the components at
``index``, the rows gathered and converted in one call (the centres of ``tracker.measurement.to_vehicle``,
computed by its kernel ``to_vehicle_kernel``), without ``to_vehicle``'s per-call Python work and the
fancy-indexed copy of the rows. The distance of the centres stays in numpy (``numpy.hypot``: numba's
``hypot`` may differ from numpy's in the last bit).
"""

from __future__ import annotations

import numpy as np

from tracker.jit import njit
from tracker.centerline import to_vehicle_kernel


@njit
def report_centres_kernel(kind, means, index, ego_x, ego_y, ego_yaw, closed, length, ends, table, bucket_cell,
                          starts_next, inv_bucket, hops, nodes, weights, min_extent):  # pragma: no cover - compiled
    """The rectangle centres ``(K, 2)`` in E of the curvilinear states ``means[index]`` (``index (K,)``
    into ``means (N, 7 or 8)``), as ``to_vehicle(means[index], ...).center`` computes them, and whether
    every one of their ``s`` is finite (checked first; no centre computed when one is not: the caller
    raises ``to_vehicle``'s error). Returns ``(center, finite)``."""
    count = index.shape[0]
    states = np.empty((count, means.shape[1]))
    for k in range(count):
        states[k] = means[index[k]]
        if not np.isfinite(states[k, 0]):
            return np.empty((0, 2)), False
    center, _, _ = to_vehicle_kernel(kind, states, ego_x, ego_y, ego_yaw, closed, length, ends, table, bucket_cell,
                                     starts_next, inv_bucket, hops, nodes, weights, min_extent)
    return center, True
