"""The tracker benchmark's scene: lane-following cars placed so that all of them are in the lidar's view.

Road: a closed circle of radius ``RADIUS`` (500 m) with ``lanes`` lanes of 3.5 m; the ego drives at
``EGO_SPEED`` in lane ``(lanes - 1) // 2`` (lane 1 of 4). Every car drives in its lane at the speed
that gives it the ego's angular rate (``v_i = EGO_SPEED (R - n_i) / (R - n_ego)``, within 4 % of the
ego's speed), so the whole scene turns rigidly with the ego: what is in view at ``t = 0`` stays in view.

Placement (``place_cars``): candidate slots every ``SLOT_STEP`` m along each lane within
``MAX_CENTRE_RANGE`` of the ego, drawn in a random order (seeded); a candidate is kept when, with the
cars kept so far, every car still shows at least ``MIN_VISIBLE_FRACTION`` of its angular extent and at
least ``MIN_VISIBLE_DEG`` to the ego (a 0.1 deg depth buffer of the cars' rectangles, nearest first),
and it keeps ``MIN_GAP`` m from the cars of its lane. ``layout`` tries ``LANE_CHOICES`` in order and
takes the narrowest road on which ``count`` cars fit. The measured number in view (lidar points on the
car) is reported beside every timing.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from sim.world.truth import EgoPose, Snapshot
from tracker import Road

RADIUS = 500.0
EGO_SPEED = 20.0
CAR_LENGTH = 4.8
CAR_WIDTH = 2.0
#: Lane counts tried, narrowest first, until the asked-for number of cars fits in view.
LANE_CHOICES = (4, 6, 8, 10, 12, 14, 16)
SLOT_STEP = 2.0
MAX_CENTRE_RANGE = 92.0
MIN_GAP = 9.0
MIN_VISIBLE_FRACTION = 0.5
MIN_VISIBLE_DEG = 1.0
BIN_DEG = 0.1
_BINS = int(round(360.0 / BIN_DEG))


@dataclass(frozen=True)
class Layout:
    """Cars of the scene: ``road``, ``ego_lane``, and per car its arc length at ``t = 0`` (``s0``, m),
    ``lane`` and ``speed`` (m/s)."""

    road: Road
    ego_lane: int
    s0: np.ndarray
    lane: np.ndarray
    speed: np.ndarray

    @property
    def lanes(self) -> int:
        """Number of lanes of the road."""
        return int(len(self.road.lane_centers))

    def __len__(self) -> int:
        return int(len(self.s0))


@lru_cache(maxsize=8)
def ring_road(lanes: int) -> Road:
    """The benchmark road: a closed circle of radius ``RADIUS`` with ``lanes`` lanes (built once per
    lane count)."""
    return Road.from_curvature([(2 * np.pi * RADIUS, 1 / RADIUS, 1 / RADIUS)], closed=True, lanes=lanes)


def _bearing_bins(road: Road, s: np.ndarray, n: np.ndarray, ego_lane: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per candidate (at ``t = 0``): first 0.1 deg bin of its rectangle seen from the ego, number of
    bins it covers, and the range of its centre (m)."""
    n_ego = road.lane_centers[ego_lane]
    ego_xy = road.to_cartesian(np.array([0.0]), np.array([n_ego]))[0]
    yaw_ego = float(road.heading(np.array([0.0]))[0])
    xy = road.to_cartesian(s, n)
    yaw = road.heading(s)
    dx, dy = (CAR_LENGTH / 2) * np.array([1, 1, -1, -1]), (CAR_WIDTH / 2) * np.array([1, -1, -1, 1])
    c, sn = np.cos(yaw)[:, None], np.sin(yaw)[:, None]
    corners = np.stack([xy[:, :1] + c * dx - sn * dy, xy[:, 1:] + sn * dx + c * dy], axis=-1) - ego_xy
    centre = xy - ego_xy
    b_centre = np.arctan2(centre[:, 1], centre[:, 0]) - yaw_ego
    rel = np.angle(np.exp(1j * (np.arctan2(corners[..., 1], corners[..., 0]) - yaw_ego - b_centre[:, None])))
    lo = np.degrees(b_centre + rel.min(axis=1))
    hi = np.degrees(b_centre + rel.max(axis=1))
    first = np.floor(lo / BIN_DEG).astype(int) % _BINS
    count = np.maximum(1, np.round((hi - lo) / BIN_DEG).astype(int))
    return first, count, np.hypot(centre[:, 0], centre[:, 1])


def place_cars(road: Road, count: int, ego_lane: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray] | None:
    """Arc lengths ``s0`` and lanes of ``count`` cars all in view of the ego (module docstring), or
    ``None`` when they do not fit on this road."""
    lanes = len(road.lane_centers)
    ds = np.arange(-MAX_CENTRE_RANGE, MAX_CENTRE_RANGE + 1e-9, SLOT_STEP)
    lane_grid, ds_grid = np.meshgrid(np.arange(lanes), ds, indexing="ij")
    lane_c, ds_c = lane_grid.ravel(), ds_grid.ravel()
    keep = ~((lane_c == ego_lane) & (np.abs(ds_c) < MIN_GAP + 1.0))
    lane_c, ds_c = lane_c[keep], ds_c[keep]
    first, span, rng_m = _bearing_bins(road, road.wrap_s(ds_c), road.lane_centers[lane_c], ego_lane)
    ok = rng_m <= MAX_CENTRE_RANGE
    order = np.random.default_rng(seed).permutation(np.flatnonzero(ok))
    need = np.maximum(np.ceil(MIN_VISIBLE_FRACTION * span), MIN_VISIBLE_DEG / BIN_DEG).astype(int)

    depth = np.full(_BINS, np.inf)  # range of the nearest kept car per bin
    owner = np.full(_BINS, -1)  # its index into ``kept``
    kept: list[int] = []
    shown = np.zeros(0, dtype=int)  # bins each kept car owns
    for i in order:
        if any(lane_c[j] == lane_c[i] and abs(ds_c[j] - ds_c[i]) < MIN_GAP for j in kept):
            continue
        bins = (first[i] + np.arange(span[i])) % _BINS
        wins = rng_m[i] < depth[bins]
        if wins.sum() < need[i]:
            continue
        lost = np.bincount(owner[bins][wins & (owner[bins] >= 0)], minlength=len(kept))
        if len(kept) and np.any(shown - lost < need[kept]):
            continue
        depth[bins[wins]] = rng_m[i]
        owner[bins[wins]] = len(kept)
        shown = np.append(shown - lost, int(wins.sum()))
        kept.append(int(i))
        if len(kept) == count:
            k = np.array(kept)
            return road.wrap_s(ds_c[k]), lane_c[k]
    return None


def layout(count: int, seed: int = 0, lanes: int | None = None) -> Layout:
    """``count`` cars in view on the narrowest ring road of ``LANE_CHOICES`` (or on ``lanes`` lanes);
    ``ValueError`` when they do not fit."""
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        raise ValueError(f"target count must be an integer >= 1; got {count!r}")
    choices = LANE_CHOICES if lanes is None else (lanes,)
    for n_lanes in choices:
        if n_lanes < 2:
            raise ValueError(f"lanes must be >= 2; got {n_lanes}")
        road = ring_road(n_lanes)
        ego_lane = (n_lanes - 1) // 2
        placed = place_cars(road, count, ego_lane, seed)
        if placed is not None:
            s0, lane = placed
            n = road.lane_centers
            speed = EGO_SPEED * (RADIUS - n[lane]) / (RADIUS - n[ego_lane])
            return Layout(road, ego_lane, s0, lane, speed)
    raise ValueError(f"{count} cars do not fit in view on a ring road with {choices[-1]} lanes or fewer")


def truth_function(scene: Layout) -> Callable[[float], Snapshot]:
    """``truth_at(t) -> Snapshot`` of the ego and the cars of ``scene`` (all turning rigidly)."""
    road, n_lane = scene.road, scene.road.lane_centers
    n_ego = float(n_lane[scene.ego_lane])
    omega = EGO_SPEED / (RADIUS - n_ego)
    count = len(scene)
    n = n_lane[scene.lane]
    ids = np.arange(1, count + 1)

    def truth_at(t: float) -> Snapshot:
        s_ego = road.wrap_s(np.array([EGO_SPEED * t]))
        ego_xy = road.to_cartesian(s_ego, np.array([n_ego]))[0]
        yaw_ego = float(road.heading(s_ego)[0])
        s = road.wrap_s(scene.s0 + scene.speed * t)
        return Snapshot(
            t, EgoPose(float(ego_xy[0]), float(ego_xy[1]), yaw_ego, EGO_SPEED, omega),
            ids, road.to_cartesian(s, n), road.heading(s), scene.speed, np.full(count, omega),
            np.full(count, CAR_LENGTH), np.full(count, CAR_WIDTH), s, n, np.zeros(count), np.zeros(count),
        )

    return truth_at
