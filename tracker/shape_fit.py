"""L-shape / rectangle fit of a lidar cluster, for initialising a target (birth from a cluster).

Search-based L-shape fitting (Zhang et al., "Efficient L-shape fitting for vehicle detection using laser
scanners", IV 2017) with their *variance* criterion: for a candidate orientation ``theta`` in
``[0, pi/2)`` project the points on ``e1 = (cos theta, sin theta)`` and ``e2 = (-sin theta, cos theta)``;
each point's distance to the nearer edge of the bounding interval is
``d_k = min(c_k - min c, max c - c_k)`` on each axis, and the point belongs to the edge set of the axis
where it is smaller (``E1`` where ``d_1 <= d_2``, else ``E2``); the score ``-(var_E1(d_1) + var_E2(d_2))``
is largest when each edge set lies along its edge. A coarse grid (``angle_step``) is refined around its
best cell, all candidates vectorised. The rectangle is the bounding box in the best frame.
Not the same paper's *closeness* criterion (``sum 1 / max(min(d_1, d_2), d0)``,
``d0 = 0.01 m``): with a dense face and a sparse side (a far side seen at a grazing angle, returns metres
apart) the extreme points' ``1 / d0`` terms dominate it, and a box turned a few degrees, one point more at
an edge, outscores the true one (measured on 1,000 ray-cast cars and trucks 10-70 m away, 0.2 deg rays,
3 cm range noise: closeness 3.8 % of headings more than 3 deg off, variance 0.4 %; 90th percentile 1.9
deg against 0.9 deg); the box's width then takes the turn's lateral spread, which the class prior
reads as a truck's.

Which axis is the length, and which way the heading points, is ambiguous from points alone:
with ``heading_hint`` (e.g. the road's heading, rad) the axis direction closest to it is chosen;
without, the longer side is the length and the heading points away from the sensor along it.
A side seen only in part (a car seen from behind shows its width only) is extended to ``min_length``
/ ``min_width`` on the far side from the sensor, which is where the unseen part must be.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tracker.angles import wrap_angle


@dataclass(frozen=True)
class RectangleFit:
    """A fitted rectangle in the points' frame: ``center (2,)`` m, ``heading`` rad in (-pi, pi],
    ``length``, ``width`` m, and the variance criterion's ``score`` of the chosen orientation."""

    center: np.ndarray
    heading: float
    length: float
    width: float
    score: float


def _edge_variance(c1: np.ndarray, c2: np.ndarray) -> np.ndarray:
    """Variance criterion scores ``(A,)`` of projections ``c1, c2 (A, N)`` (module docstring)."""
    d1 = np.minimum(c1 - c1.min(axis=1, keepdims=True), c1.max(axis=1, keepdims=True) - c1)
    d2 = np.minimum(c2 - c2.min(axis=1, keepdims=True), c2.max(axis=1, keepdims=True) - c2)
    score = np.zeros(len(c1))
    for d, edge in ((d1, d1 <= d2), (d2, d2 < d1)):
        count = edge.sum(axis=1)
        mean = np.where(edge, d, 0.0).sum(axis=1) / np.maximum(count, 1)
        score -= np.where(edge, (d - mean[:, None]) ** 2, 0.0).sum(axis=1) / np.maximum(count, 1)
    return score


def _best_angle(p: np.ndarray, angles: np.ndarray) -> tuple[float, float]:
    c, s = np.cos(angles)[:, None], np.sin(angles)[:, None]
    c1 = c * p[None, :, 0] + s * p[None, :, 1]
    c2 = -s * p[None, :, 0] + c * p[None, :, 1]
    score = _edge_variance(c1, c2)
    i = int(np.argmax(score))
    return float(angles[i]), float(score[i])


def fit_rectangle(
    points: np.ndarray,
    heading_hint: float | None = None,
    sensor: np.ndarray | tuple[float, float] = (0.0, 0.0),
    min_length: float = 0.0,
    min_width: float = 0.0,
    angle_step: float = np.radians(1.0),
) -> RectangleFit:
    """Fit a rectangle to ``points (N, 2)`` (m, any frame; ``sensor`` is the lidar's position in it).
    See the module docstring for the criterion and the length/heading choice. Raises ``ValueError``
    for fewer than one finite point."""
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ValueError(f"points must have shape (N, 2); got {pts.shape}")
    pts = pts[np.isfinite(pts).all(axis=1)]
    if len(pts) == 0:
        raise ValueError("fit_rectangle needs at least one finite point")
    if not angle_step > 0:
        raise ValueError(f"angle_step must be > 0 rad; got {angle_step!r}")
    origin = pts.mean(axis=0)
    p = pts - origin
    sensor = np.asarray(sensor, dtype=float) - origin
    score = 0.0
    theta = 0.0
    if len(pts) >= 2:
        coarse = np.arange(0.0, np.pi / 2, angle_step)
        theta, score = _best_angle(p, coarse)
        fine = theta + np.linspace(-angle_step, angle_step, 41)
        theta, score = _best_angle(p, fine)
    axes = np.array([[np.cos(theta), np.sin(theta)], [-np.sin(theta), np.cos(theta)]])  # rows e1, e2
    proj = p @ axes.T  # (N, 2)
    lo, hi = proj.min(axis=0), proj.max(axis=0)
    # which axis is the length
    if heading_hint is not None:
        hint = np.array([np.cos(heading_hint), np.sin(heading_hint)])
        along = int(np.argmax(np.abs(axes @ hint)))
    else:
        along = int(np.argmax(hi - lo))
    across = 1 - along
    s_proj = axes @ sensor
    for axis, minimum in ((along, float(min_length)), (across, float(min_width))):
        if hi[axis] - lo[axis] < minimum:  # extend away from the sensor
            if abs(s_proj[axis] - lo[axis]) <= abs(s_proj[axis] - hi[axis]):
                hi[axis] = lo[axis] + minimum
            else:
                lo[axis] = hi[axis] - minimum
    center = origin + 0.5 * (lo + hi) @ axes
    direction = axes[along]
    if heading_hint is not None:
        if direction @ np.array([np.cos(heading_hint), np.sin(heading_hint)]) < 0:
            direction = -direction
    elif direction @ (center - (sensor + origin)) < 0:
        direction = -direction
    heading = float(wrap_angle(np.arctan2(direction[1], direction[0])))
    return RectangleFit(center, heading, float(hi[along] - lo[along]), float(hi[across] - lo[across]), score)
