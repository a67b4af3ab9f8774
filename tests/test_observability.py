"""``sim.evaluation.observability``: the seen pairs split by whether the vehicle has shown its length, its width."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from sim.evaluation.long_vehicles import face_shown, side_seen, side_shown
from sim.evaluation.metrics import gospa
from sim.evaluation.observability import metrics, shown_pairs
from tracker.measurement import rectangle_corners, rectangle_scan

RES = np.radians(0.2)
RAYS = np.arange(-np.pi, np.pi, RES)


def returns_of(xy: tuple[float, float], length: float, width: float) -> int:
    """Exact returns of an unoccluded rectangle (heading +x) for a lidar at the origin (the oracle)."""
    corners = rectangle_corners(np.array(xy), np.array(0.0), np.array(length), np.array(width))
    return int(rectangle_scan(corners, RAYS)[1].sum())


def shown(xy: tuple[float, float], length: float = 4.7, width: float = 1.8) -> bool:
    return bool(side_shown((0.0, 0.0), np.array([xy]), np.zeros(1), np.array([length]), np.array([width]),
                           np.array([returns_of(xy, length, width)]), RES)[0])


def test_a_cars_side_is_shown_where_it_faces_the_lidar_densely() -> None:
    """A car in the next lane 8 m ahead shows its side whole; straight ahead only its rear; 60 m ahead in
    the next lane its side is seen edge-on (rays ~5 m apart along it). A long vehicle's side seen is the
    same test (``side_seen``), the car is no long vehicle."""
    assert shown((8.0, 3.5))
    assert not shown((15.0, 0.0))
    assert not shown((60.0, 3.5))
    car = (np.array([[8.0, 3.5]]), np.zeros(1), np.array([4.7]), np.array([1.8]), np.array([returns_of((8.0, 3.5), 4.7, 1.8)]))
    assert not side_seen((0.0, 0.0), *car, RES)[0]
    truck = (np.array([[15.0, 3.5]]), np.zeros(1), np.array([12.0]), np.array([2.5]),
             np.array([returns_of((15.0, 3.5), 12.0, 2.5)]))
    assert side_seen((0.0, 0.0), *truck, RES)[0] and side_shown((0.0, 0.0), *truck, RES)[0]


def test_a_cars_end_is_shown_where_the_lidar_lies_beyond_it() -> None:
    """The width's test (``face_shown``): a car 15 m straight ahead or behind shows its end whole, and so does
    one 60 m ahead in the next lane (its rear 1.7 deg wide, 8 rays); one beside the lidar (1 m ahead, or
    10 m to the side) shows only its side."""
    def face(xy):
        return bool(face_shown((0.0, 0.0), np.array([xy]), np.zeros(1), np.array([4.7]), np.array([1.8]),
                               np.array([returns_of(xy, 4.7, 1.8)]), RES)[0])

    assert face((15.0, 0.0)) and face((-15.0, 0.0)) and face((60.0, 3.5)) and face((12.0, 3.5))
    assert not face((1.0, 3.5)) and not face((0.0, 10.0))
    assert shown((1.0, 3.5)) and not shown((15.0, 0.0))  # the length's test the other way round


def _frame(xy: list[tuple[float, float]], track_xy: list[tuple[float, float]], track_length: list[float],
           visible: list[bool], track_width: tuple[float, float] = (1.8, 1.8)) -> SimpleNamespace:
    """A frame of two 4.7 x 1.8 m cars (ids 1, 2, heading +x) with tracks at ``track_xy``, all scored."""
    n = len(xy)
    xy_a = np.array(xy, dtype=float)
    truth = SimpleNamespace(ids=np.array([1, 2]), ego=SimpleNamespace(x=0.0, y=0.0), xy=xy_a, yaw=np.zeros(n),
                            length=np.full(n, 4.7), width=np.full(n, 1.8))
    state = np.zeros((n, 7))
    state[:, :2], state[:, 5], state[:, 6] = xy_a, 4.7, 1.8
    tracks = np.zeros((len(track_xy), 7))
    tracks[:, :2], tracks[:, 5], tracks[:, 6] = np.array(track_xy, dtype=float), track_length, track_width
    points = np.array([returns_of(p, 4.7, 1.8) for p in xy])
    return SimpleNamespace(truth=truth, truth_state=state, track_state=tracks, lidar_points=points, lidar_bearings=None,
                           scored=np.ones(n, dtype=bool), visible=np.array(visible),
                           gospa=gospa(xy_a, tracks[:, :2], 5.0, 2.0))


def test_pairs_split_by_whether_the_length_was_shown_so_far() -> None:
    """Car 1 is followed straight ahead (never shown), its track 0.5 m ahead and 0.4 m long; car 2 is far
    in the next lane for two frames (edge-on), beside the lidar in the third (shown) and far again in the
    fourth (still shown: the length, once seen, can be held), its track 0.1 m off and 0.2 m short. In the
    fifth frame car 2 is hidden: its pair is not a seen one."""
    frames = []
    for k, b in enumerate([(60.0, 3.5), (55.0, 3.5), (8.0, 3.5), (55.0, 3.5), (55.0, 3.5)]):
        frames.append(_frame([(15.0, 0.0), b], [(15.5, 0.0), (b[0] + 0.1, b[1])], [5.1, 4.5], [True, k < 4]))
    flags, _, position, length, _ = shown_pairs(frames, RES)
    assert flags.tolist() == [False, False, False, False, False, True, False, True, False]
    m = metrics(frames, RES)
    assert m["matched_pairs_seen"] == 9 and m["matched_pairs_seen_length_shown"] == 2
    assert m["length_shown_share"] == pytest.approx(2 / 9)
    assert m["pos_rmse_seen_length_shown_m"] == pytest.approx(0.1)
    assert m["pos_rmse_seen_length_unshown_m"] == pytest.approx(((5 * 0.5**2 + 2 * 0.1**2) / 7) ** 0.5)
    assert m["length_rmse_seen_shown_m"] == pytest.approx(0.2)
    assert m["length_rmse_seen_unshown_m"] == pytest.approx(((5 * 0.4**2 + 2 * 0.2**2) / 7) ** 0.5)
    assert metrics([], RES)["length_shown_share"] is None


def test_pairs_split_by_whether_the_width_was_shown_so_far() -> None:
    """Car 1 is followed straight ahead (its rear shown from the first frame), its track 0.05 m too wide; car 2
    is beside the lidar for two frames (its side only), 12 m ahead in the next lane in the third (its rear
    shown) and beside again in the fourth (still shown), its track 0.2 m too narrow."""
    frames = []
    for b in [(1.0, 3.5), (1.0, 3.5), (12.0, 3.5), (1.0, 3.5)]:
        frames.append(_frame([(15.0, 0.0), b], [(15.0, 0.0), b], [4.7, 4.7], [True, True], track_width=(1.85, 1.6)))
    _, faces, _, _, width = shown_pairs(frames, RES)
    assert faces.tolist() == [True, False, True, False, True, True, True, True]
    np.testing.assert_allclose(width, [0.05, -0.2] * 4)
    m = metrics(frames, RES)
    assert m["matched_pairs_seen_width_shown"] == 6 and m["width_shown_share"] == pytest.approx(6 / 8)
    assert m["width_rmse_seen_shown_m"] == pytest.approx(((4 * 0.05**2 + 2 * 0.2**2) / 6) ** 0.5)
    assert m["width_rmse_seen_unshown_m"] == pytest.approx(0.2)
    assert metrics([], RES)["width_shown_share"] is None


def test_a_runs_split_partitions_its_seen_pairs() -> None:
    """On a run, the two parts hold exactly the seen pairs: their counts add up to the seen pairs and their
    squared RMSEs, weighted by the counts, to ``pos_rmse_seen_m``'s."""
    from sim.evaluation.runner import run_scenario
    from sim.world.scenario import load_scenario

    m = run_scenario(load_scenario("scenarios/curvy-multi.toml"), 0, duration=4.0).metrics
    seen = m["matched_pairs_seen"]
    shown_n = m["matched_pairs_seen_length_shown"]
    assert seen == m["matched_pairs"] - m["matched_pairs_hidden"] and 0 < shown_n < seen
    parts = shown_n * m["pos_rmse_seen_length_shown_m"] ** 2 + (seen - shown_n) * m["pos_rmse_seen_length_unshown_m"] ** 2
    assert parts == pytest.approx(seen * m["pos_rmse_seen_m"] ** 2, rel=1e-9)
    faces = m["matched_pairs_seen_width_shown"]
    assert 0 < faces <= seen and m["width_shown_share"] == pytest.approx(faces / seen)
