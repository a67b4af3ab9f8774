"""The projection of points on a road's centerline (``tracker.road.Road.to_frenet``), in numpy:
Newton's iterations on ``g(s) = (p - c(s)) . t(s) = 0`` from a start next to the nearest curve
sample, on the road's frame (wrapped on a closed road, continued along the end tangents of an open
one) evaluated by ``oracles.centerline``."""

from __future__ import annotations

import numpy as np

from oracles.centerline import frame as curve_frame
from tracker.road import (
    PROJECTION_MAX_ITERATIONS,
    PROJECTION_MAX_STEP,
    PROJECTION_MIN_DENOMINATOR,
    PROJECTION_TOLERANCE,
    SEED_GRID_RESOLUTION,
    Road,
)


def road_frame(road: Road, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position ``(N, 2)``, unit tangent ``(N, 2)`` and curvature ``(N,)`` at any ``s``: wrapped on a
    closed road; beyond an open road's ends the end's tangent line (curvature 0)."""
    s = np.asarray(s, dtype=float)
    if road.closed:
        return curve_frame(road._curve, np.mod(s, road.length))
    xy, tangent, kappa = curve_frame(road._curve, np.clip(s, 0.0, road.length))
    for beyond, ref in ((s < 0.0, 0.0), (s > road.length, road.length)):
        end_xy, end_t, _ = curve_frame(road._curve, np.array([ref]))
        xy[beyond] = end_xy + (s[beyond] - ref)[:, None] * end_t
        kappa[beyond] = 0.0
    return xy, tangent, kappa


def nearest_node(road: Road, pts: np.ndarray) -> np.ndarray:
    """Index of a curve sample near each point: the one its seed-grid cell stores (the sample nearest
    to the cell's centre), else (off the grid, or a cell far from the road) the nearest sample of all,
    by brute force."""
    node = np.full(len(pts), -1)
    grid = road._grid
    if grid is not None:
        cell = np.floor((pts - road._grid_origin) * (1.0 / SEED_GRID_RESOLUTION)).astype(int)
        inside = (cell >= 0).all(axis=1) & (cell[:, 0] < grid.shape[0]) & (cell[:, 1] < grid.shape[1])
        node[inside] = grid[cell[inside, 0], cell[inside, 1]]
    off = node < 0
    if off.any():
        dist = np.linalg.norm(pts[off, None, :] - road._node_xy[None, :, :], axis=2)
        node[off] = np.argmin(dist, axis=1)
    return node


def node_start(road: Road, pts: np.ndarray, node: np.ndarray) -> np.ndarray:
    """One Newton step from the curve samples ``node`` (their stored frames): ``s_node + (d . t) /
    max(1 - kappa (d x t), PROJECTION_MIN_DENOMINATOR)``, ``d`` the point less the sample."""
    x, y, tx, ty, kappa = road._node_frame[node].T
    dx, dy = pts[:, 0] - x, pts[:, 1] - y
    denom = np.maximum(1.0 - kappa * (dy * tx - dx * ty), PROJECTION_MIN_DENOMINATOR)
    return road._nodes[node] + (dx * tx + dy * ty) / denom


def newton(road: Road, pts: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Newton's iterations from the starts ``s``, every point stepping while any is pending (at most
    ``PROJECTION_MAX_ITERATIONS``): ``(s, lateral, pending)``, ``pending`` where the last step was not
    below ``PROJECTION_TOLERANCE``."""
    s = np.array(s, dtype=float)
    lateral = np.zeros(len(s))
    pending = np.ones(len(s), dtype=bool)
    for _ in range(PROJECTION_MAX_ITERATIONS):
        xy, tangent, kappa = road_frame(road, s)
        d = pts - xy
        along = d[:, 0] * tangent[:, 0] + d[:, 1] * tangent[:, 1]
        lateral = d[:, 1] * tangent[:, 0] - d[:, 0] * tangent[:, 1]
        ds = np.clip(along / np.maximum(1.0 - kappa * lateral, PROJECTION_MIN_DENOMINATOR),
                     -PROJECTION_MAX_STEP, PROJECTION_MAX_STEP)
        s = s + ds
        if road.closed:
            s = np.mod(s, road.length)
        pending = np.abs(ds) >= PROJECTION_TOLERANCE
        if not pending.any():
            break
    return s, lateral, pending


def project(road: Road, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``newton`` from ``node_start`` at ``nearest_node``: the projection without a hint."""
    pts = np.asarray(pts, dtype=float)
    return newton(road, pts, node_start(road, pts, nearest_node(road, pts)))


def to_frenet(road: Road, pts: np.ndarray, s_hint: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``newton`` from the hints ``s_hint``, the points it leaves pending then ``project``ed; without
    hints ``project``. Returns ``(s, n, pending)``: ``pending`` where no Newton search converged."""
    pts = np.asarray(pts, dtype=float)
    if s_hint is None:
        return project(road, pts)
    s, n, pending = newton(road, pts, s_hint)
    if pending.any():
        s[pending], n[pending], pending[pending] = project(road, pts[pending])
    return s, n, pending
