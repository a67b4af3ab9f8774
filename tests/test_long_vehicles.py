"""``sim.evaluation.long_vehicles``: when a long vehicle's side counts as seen, and the length error 3 s later."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from sim.evaluation.long_vehicles import LENGTH_DELAY, length_errors, metrics, side_seen
from tracker.measurement import rectangle_corners, rectangle_scan

RES = np.radians(0.2)
RAYS = np.arange(-np.pi, np.pi, RES)


def returns_of(xy: tuple[float, float], length: float, width: float) -> int:
    """Exact returns of an unoccluded rectangle (heading +x) for a lidar at the origin (the oracle)."""
    corners = rectangle_corners(np.array(xy), np.array(0.0), np.array(length), np.array(width))
    _, hit = rectangle_scan(corners, RAYS)
    return int(hit.sum())


def bearings_of(xy: tuple[float, float], length: float, width: float) -> np.ndarray:
    """The lowest and highest bearing of the exact returns (as ``FrameRecord.lidar_bearings``)."""
    corners = rectangle_corners(np.array(xy), np.array(0.0), np.array(length), np.array(width))
    _, hit = rectangle_scan(corners, RAYS)
    b = RAYS[hit]
    return np.array([b.min(), b.max()])


def seen(xy: tuple[float, float], length: float = 12.0, width: float = 2.5, returns: float | None = None,
         bearings: np.ndarray | None = None) -> bool:
    shown = returns_of(xy, length, width) if returns is None else returns
    return bool(side_seen((0.0, 0.0), np.array([xy]), np.zeros(1), np.array([length]), np.array([width]),
                          np.array([shown]), RES, None if bearings is None else bearings[None])[0])


def test_a_trucks_side_counts_as_seen_only_when_it_faces_the_lidar_densely_and_unhidden() -> None:
    """A 12 m truck in the next lane 15 m ahead shows its side (and rear) densely: seen. Straight ahead
    in the ego's lane it shows only its rear; 80 m ahead in the next lane its side is seen edge-on, rays
    ~10 m apart along it; with 84 % of its returns it is partly hidden; a 4.5 m car is no long vehicle:
    not seen. With 2 % of its returns dropped, beside the ego (its whole side, no end) and behind in the
    next lane: seen."""
    assert seen((15.0, 3.5))
    assert not seen((15.0, 0.0))
    assert not seen((80.0, 3.5))
    assert not seen((15.0, 3.5), returns=0.84 * returns_of((15.0, 3.5), 12.0, 2.5))
    assert seen((15.0, 3.5), returns=0.98 * returns_of((15.0, 3.5), 12.0, 2.5))
    assert not seen((15.0, 3.5), length=4.5, width=1.8)
    assert seen((0.0, -3.5))
    assert seen((-15.0, 3.5))
    # with the bearings of its returns: reaching both ends of its outline, seen; stopping 3 rays short
    # of either end (a part hidden there): not seen, whatever their count
    full = bearings_of((15.0, 3.5), 12.0, 2.5)
    assert seen((15.0, 3.5), bearings=full)
    assert not seen((15.0, 3.5), bearings=full - np.array([0.0, 3 * RES]))
    assert not seen((15.0, 3.5), bearings=full + np.array([3 * RES, 0.0]))


def _frame(t: float, ids, xy, length, points, track_truth_id, track_length) -> SimpleNamespace:
    n = len(ids)
    truth = SimpleNamespace(ids=np.array(ids), ego=SimpleNamespace(x=0.0, y=0.0), xy=np.array(xy, dtype=float).reshape(n, 2),
                            yaw=np.zeros(n), length=np.array(length, dtype=float), width=np.full(n, 2.5))
    state = np.zeros((len(track_truth_id), 7))
    state[:, 5] = track_length
    return SimpleNamespace(t=t, truth=truth, lidar_points=np.array(points), track_truth_id=np.array(track_truth_id),
                           track_state=state, scored=np.ones(n, dtype=bool))


def test_the_length_is_scored_three_seconds_after_the_side_is_first_seen() -> None:
    """Truck 1 (12 m) is seen from t = 0; 3 s later its track is 11.4 m long: within 1 m. Truck 2 (16 m)
    is seen from t = 1 s but has no track at 4 s: counted, a miss. Truck 3 is seen only from t = 3.5 s,
    less than 3 s before the run ends: not counted. A bus straight ahead (side never seen): not counted."""
    full = [returns_of((15.0, 3.5), 12.0, 2.5), returns_of((-15.0, -3.5), 16.0, 2.5), returns_of((15.0, -3.5), 12.0, 2.5)]
    frames = []
    for k in range(46):  # 0 .. 4.5 s
        t = 0.1 * k
        points = [full[0], full[1] if t >= 1.0 - 1e-9 else 0, full[2] if t >= 3.5 - 1e-9 else 0, 40]
        frames.append(_frame(t, [1, 2, 3, 4], [(15.0, 3.5), (-15.0, -3.5), (15.0, -3.5), (30.0, 0.0)],
                             [12.0, 16.0, 12.0, 14.0], points,
                             [1, 4], [11.4 if t >= 2.0 else 4.5, 14.0]))
    rows = length_errors(frames, RES)
    assert [(tid, round(t0, 1), length) for tid, t0, length, _ in rows] == [(1, 0.0, 12.0), (2, 1.0, 16.0)]
    assert rows[0][3] == pytest.approx(-0.6) and rows[1][3] is None
    m = metrics(frames, RES)
    assert m == {"long_sides_seen": 2, "long_length_within_1m": 1, "long_length_err_max_m": abs(11.4 - 12.0)}
    for f in frames[40:]:  # truck 2 beyond the lidar range by 4 s: no longer scored, not counted
        f.scored[1] = False
    assert [tid for tid, *_ in length_errors(frames, RES)] == [1]
    assert LENGTH_DELAY == 3.0
