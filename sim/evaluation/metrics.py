"""Evaluation metrics: GOSPA (alpha = 2) with its decomposition, matched-target errors, ID switches.

GOSPA (Rahmathullah, Garcia-Fernandez, Svensson, FUSION 2017) between the truth set X and the
estimate set Y, with cut-off ``c`` (m), order ``p`` and alpha = 2:

    d(X, Y) = [ min_gamma  sum_{(i,j) in gamma} d(x_i, y_j)^p + c^p/2 (|X| - |gamma|) + c^p/2 (|Y| - |gamma|) ]^(1/p)

over partial assignments ``gamma`` whose pairs have ``d < c``. Solved as a rectangular assignment on
``min(d, c)^p`` (``scipy.optimize.linear_sum_assignment``); assigned pairs at the cut-off count as one
missed plus one false target. **Components are reported as p-th-power sums** (the convention of the
GOSPA authors' Python code and of Stone Soup): ``localization + missed + false = gospa^p``.

The base distance is Euclidean between rectangle centres (x, y) in G by default; the extent-aware
option is the Gaussian Wasserstein distance between rectangles (``gaussian_wasserstein``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from tracker.angles import wrap_angle

#: Default GOSPA cut-off (m) and order.
GOSPA_C = 5.0
GOSPA_P = 2.0


@dataclass(frozen=True)
class GospaResult:
    """GOSPA at one time. ``gospa`` (m) and its parts as p-th-power sums (m^p);
    ``truth_index[k]`` is assigned to ``estimate_index[k]`` (only pairs closer than ``c``)."""

    gospa: float
    localization: float
    missed: float
    false: float
    truth_index: np.ndarray
    estimate_index: np.ndarray
    distances: np.ndarray

    @property
    def assigned(self) -> int:
        """Number of truth-estimate pairs in the optimal assignment."""
        return len(self.truth_index)


def _as_points(xy: np.ndarray, name: str, dim: int | None = 2) -> np.ndarray:
    arr = np.asarray(xy, dtype=float)
    if arr.size == 0:
        return arr.reshape(0, dim or (arr.shape[-1] if arr.ndim > 1 else 0))
    if arr.ndim != 2 or (dim is not None and arr.shape[1] != dim):
        raise ValueError(f"{name} must have shape (N, {dim}); got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} contains non-finite values")
    return arr


def euclidean_distances(truth: np.ndarray, estimate: np.ndarray) -> np.ndarray:
    """Pairwise Euclidean distances (|X|, |Y|) between rows of ``truth`` and ``estimate``."""
    return np.linalg.norm(truth[:, None, :] - estimate[None, :, :], axis=2)


def gospa(
    truth_xy: np.ndarray,
    estimate_xy: np.ndarray,
    c: float = GOSPA_C,
    p: float = GOSPA_P,
    *,
    distance: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
) -> GospaResult:
    """GOSPA (alpha = 2) between truth points (|X|, D) and estimates (|Y|, D), in metres.

    ``distance`` maps the two arrays to a (|X|, |Y|) matrix of base distances (default: Euclidean on
    the rows, i.e. rectangle centres (x, y) in G). Parts are p-th-power sums; see the module doc.
    """
    if not c > 0:
        raise ValueError(f"GOSPA cut-off c must be > 0 m; got {c!r}")
    if not p >= 1:
        raise ValueError(f"GOSPA order p must be >= 1; got {p!r}")
    x = _as_points(truth_xy, "truth_xy", None if distance else 2)
    y = _as_points(estimate_xy, "estimate_xy", None if distance else 2)
    nx, ny = len(x), len(y)
    empty = np.zeros(0, dtype=int)
    if nx == 0 or ny == 0:
        missed, false = 0.5 * c**p * nx, 0.5 * c**p * ny
        return GospaResult(float((missed + false) ** (1 / p)), 0.0, missed, false, empty, empty, np.zeros(0))
    d = (distance or euclidean_distances)(x, y)
    if d.shape != (nx, ny):
        raise ValueError(f"distance returned shape {d.shape}; expected ({nx}, {ny})")
    cost = np.minimum(d, c) ** p
    rows, cols = linear_sum_assignment(cost)
    keep = d[rows, cols] < c
    rows, cols = rows[keep], cols[keep]
    loc = float(np.sum(d[rows, cols] ** p))
    missed = 0.5 * c**p * (nx - len(rows))
    false = 0.5 * c**p * (ny - len(rows))
    total = (loc + missed + false) ** (1 / p)
    return GospaResult(float(total), loc, float(missed), float(false), rows, cols, d[rows, cols])


def extent_matrices(yaw: np.ndarray, length: np.ndarray, width: np.ndarray) -> np.ndarray:
    """Extent matrices (N, 2, 2) of rectangles: ``R(yaw) diag((L/2)^2, (W/2)^2) R(yaw)^T`` (m^2),
    the ellipse through the rectangle's side mid-points, as in Granstrom's extended-target GOSPA."""
    c, s = np.cos(yaw), np.sin(yaw)
    a, b = (0.5 * np.asarray(length)) ** 2, (0.5 * np.asarray(width)) ** 2
    return np.stack([np.stack([a * c * c + b * s * s, (a - b) * c * s], -1),
                     np.stack([(a - b) * c * s, a * s * s + b * c * c], -1)], -2)


def gaussian_wasserstein(truth: np.ndarray, estimate: np.ndarray) -> np.ndarray:
    """Pairwise Gaussian Wasserstein distance (m) between rectangles given as rows
    ``[x, y, yaw, length, width]``:

        GW^2 = |m1 - m2|^2 + tr X1 + tr X2 - 2 tr (X1^(1/2) X2 X1^(1/2))^(1/2)

    with extent matrices ``X`` from ``extent_matrices``; for 2x2 matrices
    ``tr sqrt(A) = sqrt(tr A + 2 sqrt(det A))`` with ``tr A = tr(X1 X2)``, ``det A = det X1 det X2``.
    Use as ``gospa(..., distance=gaussian_wasserstein)``.
    """
    x1 = extent_matrices(truth[:, 2], truth[:, 3], truth[:, 4])[:, None]
    x2 = extent_matrices(estimate[:, 2], estimate[:, 3], estimate[:, 4])[None, :]
    dm2 = np.sum((truth[:, None, :2] - estimate[None, :, :2]) ** 2, axis=2)
    tr_prod = np.einsum("...ij,...ji->...", x1, x2)
    det = np.linalg.det(x1) * np.linalg.det(x2)
    tr_sqrt = np.sqrt(np.maximum(tr_prod + 2.0 * np.sqrt(np.maximum(det, 0.0)), 0.0))
    tr1 = np.trace(x1, axis1=-2, axis2=-1)
    tr2 = np.trace(x2, axis1=-2, axis2=-1)
    return np.sqrt(np.maximum(dm2 + tr1 + tr2 - 2.0 * tr_sqrt, 0.0))


@dataclass(frozen=True)
class MatchedErrors:
    """Errors of assigned (truth, estimate) pairs, one entry per pair: position (m), yaw (rad,
    wrapped, estimate - truth), speed (m/s), length and width (m), all estimate minus truth; the
    position error's parts along and across the vehicle's heading (m, signed: ahead of the vehicle's
    centre, to its left), ``along^2 + across^2 = position^2``."""

    position: np.ndarray
    yaw: np.ndarray
    speed: np.ndarray
    length: np.ndarray
    width: np.ndarray
    along: np.ndarray
    across: np.ndarray


def rmse(values: list[np.ndarray], scale: float = 1.0) -> float | None:
    """Root mean square of the arrays ``values`` taken together, times ``scale``; None without a value."""
    arr = np.concatenate(values) if values else np.zeros(0)
    return float(scale * np.sqrt(np.mean(arr**2))) if arr.size else None


def matched_errors(truth: np.ndarray, estimate: np.ndarray, result: GospaResult, *, extent: bool = True) -> MatchedErrors:
    """Errors of the GOSPA-assigned pairs. ``truth`` and ``estimate`` rows are Cartesian views
    ``[x, y, v, psi, psi_dot, L, W]`` (the ``Track.cartesian`` order). ``extent=False`` (a point
    tracker, whose L, W columns are placeholders): ``length`` and ``width`` are empty (missing, so
    an RMSE over them is undefined rather than the placeholder's error)."""
    t = np.asarray(truth, dtype=float).reshape(-1, 7)[result.truth_index]
    e = np.asarray(estimate, dtype=float).reshape(-1, 7)[result.estimate_index]
    none = np.zeros(0)
    d = e[:, :2] - t[:, :2]
    cos, sin = np.cos(t[:, 3]), np.sin(t[:, 3])
    return MatchedErrors(
        position=np.linalg.norm(d, axis=1),
        yaw=np.asarray(wrap_angle(e[:, 3] - t[:, 3])).reshape(-1),
        speed=e[:, 2] - t[:, 2],
        length=e[:, 5] - t[:, 5] if extent else none,
        width=e[:, 6] - t[:, 6] if extent else none,
        along=d[:, 0] * cos + d[:, 1] * sin,
        across=d[:, 1] * cos - d[:, 0] * sin,
    )


class IdSwitchCounter:
    """Counts identity switches: a truth vehicle assigned to a track label different from the label
    it was last assigned to. Frames where it is unassigned do not reset its last label (a track that
    is lost and re-found under a new label counts one switch)."""

    def __init__(self) -> None:
        self.switches = 0
        self._last: dict[int, int] = {}

    def update(self, truth_ids: np.ndarray, labels: np.ndarray) -> int:
        """Record one frame's assignment (assigned pairs only); returns the switches in this frame."""
        new = 0
        for truth_id, label in zip(np.asarray(truth_ids).tolist(), np.asarray(labels).tolist()):
            previous = self._last.get(truth_id)
            if previous is not None and previous != label:
                new += 1
            self._last[truth_id] = label
        self.switches += new
        return new


def cardinality_error(n_truth: int, n_estimate: int) -> int:
    """Estimated minus true number of targets."""
    return int(n_estimate) - int(n_truth)
