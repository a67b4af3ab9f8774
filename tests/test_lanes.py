"""tracker.lanes and the Road's lanes along s: layouts that change, two-way roads, the compiled edge table."""

from __future__ import annotations

import numpy as np
import pytest

from tracker import Road
from tracker.birth import road_births, visible_road_births
from tracker.config import BirthConfig, ClusteringConfig
from tracker.frame import EgoState
from tracker.jit import njit
from tracker.lanes import EDGE_TABLE_STEP, MIN_LANE_WIDTH, LaneLayout, edge_at
from tracker.measurement import Rectangles
from tracker.preprocess import filter_points


def _merge_layout() -> LaneLayout:
    """Three lanes of 3.5 m; from s = 100 to 150 m an auxiliary lane on the right tapers in, it is
    full from 150 to 250 m and tapers out by 300 m; the leftmost lane is oncoming."""
    stations = np.array([0.0, 100.0, 150.0, 250.0, 300.0, 400.0])
    aux = np.array([0.0, 0.0, 3.5, 3.5, 0.0, 0.0])
    right = -5.25 - aux
    bounds = np.column_stack([right, np.full(6, -5.25), np.full(6, -1.75), np.full(6, 1.75), np.full(6, 5.25)])
    return LaneLayout(stations, bounds, directions=[1, 1, 1, -1])


@pytest.fixture(scope="module")
def merge_road() -> Road:
    return Road.from_curvature([(150.0, 0.0, 0.0), (100.0, 0.0, 0.01), (150.0, 0.01, 0.01)], layout=_merge_layout())


def test_uniform_layout_is_the_old_road():
    road = Road.from_curvature([(200.0, 0.0, 0.0)], lanes=3, lane_width=3.2)
    assert road.uniform and not road.two_way
    assert road.right_edge == -0.5 * 3 * 3.2 and road.left_edge == pytest.approx(4.8)
    np.testing.assert_array_equal(road.lane_centers, road.right_edge + (np.arange(3) + 0.5) * 3.2)
    right, left = road.edges(np.array([0.0, 57.3, 200.0]))
    np.testing.assert_array_equal(right, road.right_edge)
    np.testing.assert_array_equal(left, road.left_edge)
    np.testing.assert_array_equal(road.lane_index(np.array([-5.0, -4.7, 0.0, 4.7, 5.0])), [-1, 0, 1, 2, 3])


def test_layout_validation_names_the_problem():
    with pytest.raises(ValueError, match="increase strictly"):
        LaneLayout([0.0, 0.0], [[-1.0, 1.0], [-1.0, 1.0]])
    with pytest.raises(ValueError, match="lies right of boundary 0"):
        LaneLayout([0.0], [[1.0, -1.0]])
    with pytest.raises(ValueError, match=r"shape \(2, M \+ 1\)"):
        LaneLayout([0.0, 1.0], [[-1.0, 1.0]])
    with pytest.raises(ValueError, match="directions"):
        LaneLayout([0.0], [[-1.0, 1.0]], directions=[0])
    with pytest.raises(ValueError, match="kinds"):
        LaneLayout([0.0], [[-1.0, 1.0]], kinds=["bus-lane"])
    with pytest.raises(ValueError, match="finite"):
        LaneLayout([0.0, np.nan], [[-1.0, 1.0], [-1.0, 1.0]])
    with pytest.raises(ValueError, match="not both"):
        Road.from_curvature([(100.0, 0.0, 0.0)], lanes=3, layout=LaneLayout([0.0], [[-1.0, 1.0]]))
    with pytest.raises(ValueError, match="oncoming"):
        Road.from_curvature([(100.0, 0.0, 0.0)], lanes=2, oncoming=3)
    with pytest.raises(ValueError, match="not both"):
        Road.from_curvature([(100.0, 0.0, 0.0)], drive_on="left", layout=LaneLayout([0.0], [[-1.0, 1.0]]))
    with pytest.raises(ValueError, match="directions"):
        LaneLayout([0.0], [[-1.0, 1.0, 3.0]], directions=[True, True])
    with pytest.raises(ValueError, match="no lane at least"):
        LaneLayout([0.0, 10.0], [[0.0, 0.2], [0.0, 0.1]])
    ring = [(2 * np.pi * 100.0, 0.01, 0.01)]
    with pytest.raises(ValueError, match="must meet themselves"):
        Road.from_curvature(ring, closed=True, layout=LaneLayout([0.0, 600.0], [[-3.5, 3.5], [-5.0, 3.5]]))


def test_edges_follow_the_layout(merge_road):
    s = np.array([0.0, 50.0, 100.0, 125.0, 150.0, 200.0, 275.0, 300.0, 399.0])
    right, left = merge_road.edges(s)
    aux = np.interp(s, [100.0, 150.0, 250.0, 300.0], [0.0, 3.5, 3.5, 0.0])
    # the tapering lane counts once it is MIN_LANE_WIDTH wide; its edge is then the boundary's
    expect = np.where(aux >= MIN_LANE_WIDTH, -5.25 - aux, -5.25)
    np.testing.assert_allclose(right, expect, atol=1e-9)
    np.testing.assert_array_equal(left, 5.25)
    assert merge_road.right_edge == pytest.approx(-8.75) and merge_road.left_edge == 5.25
    assert not merge_road.uniform and merge_road.two_way


def test_on_road_follows_the_edges(merge_road):
    s = np.array([50.0, 200.0, 200.0, 350.0, 200.0])
    n = np.array([-7.0, -7.0, -9.0, 5.0, 5.5])
    xy = merge_road.to_cartesian(s, n)
    np.testing.assert_array_equal(merge_road.on_road(xy), [False, True, False, True, False])
    np.testing.assert_array_equal(merge_road.on_road(xy, margin=0.5), [False, True, True, True, True])


def test_lane_centres_and_directions(merge_road):
    centres = merge_road.lane_centers_at(np.array([50.0, 200.0]))
    assert np.isnan(centres[0, 0])
    np.testing.assert_allclose(centres[1], [-7.0, -3.5, 0.0, 3.5])
    np.testing.assert_allclose(centres[0, 1:], [-3.5, 0.0, 3.5])
    with pytest.raises(ValueError, match="vary along s"):
        _ = merge_road.lane_centers
    assert merge_road.lane_center(0, s=200.0) == pytest.approx(-7.0)
    np.testing.assert_array_equal(merge_road.lane_index(np.array([-7.0, -7.0, 3.0]), np.array([50.0, 200.0, 10.0])),
                                  [-1, 0, 3])
    np.testing.assert_array_equal(merge_road.lane_direction(np.array([10.0, 10.0, 10.0]), np.array([-3.0, 3.0, 9.0])),
                                  [1, -1, -1])


def test_two_way_uniform_roads():
    right_hand = Road.from_curvature([(100.0, 0.0, 0.0)], lanes=4, oncoming=2)
    np.testing.assert_array_equal(right_hand.lane_directions, [1, 1, -1, -1])
    left_hand = Road.from_curvature([(100.0, 0.0, 0.0)], lanes=3, oncoming=1, drive_on="left")
    np.testing.assert_array_equal(left_hand.lane_directions, [-1, 1, 1])
    assert right_hand.uniform and right_hand.two_way


def test_edge_at_is_numpy_interp():
    table = np.array([-2.0, -2.5, -4.0, -4.0, -1.0])
    inv_step = 1.0 / 3.0

    @njit
    def many(s, inv, tab):
        out = np.empty(len(s))
        for i in range(len(s)):
            out[i] = edge_at(s[i], inv, tab)
        return out

    s = np.linspace(-5.0, 20.0, 301)
    np.testing.assert_allclose(many(s, inv_step, table), np.interp(s, np.arange(5) * 3.0, table), atol=1e-12)
    flat = np.full(2, -3.7)
    assert (many(s, 0.01, flat) == -3.7).all()


def test_edge_table_resolution(merge_road):
    inv_step, right, _ = merge_road.edge_kernel_args()
    assert inv_step == pytest.approx(1.0 / EDGE_TABLE_STEP, rel=0.01)
    assert len(right) == int(np.ceil(merge_road.length / EDGE_TABLE_STEP)) + 1


def test_road_filter_keeps_what_the_edges_hold(merge_road):
    """The compiled road filter (``filter_points``) against ``Road.within_bounds`` on a varying road."""
    rng = np.random.default_rng(3)
    ego = EgoState(x=float(merge_road.position(200.0)[0]), y=float(merge_road.position(200.0)[1]),
                   yaw=float(merge_road.heading(200.0)), v=10.0)
    s = rng.uniform(120.0, 290.0, 4000)
    n = rng.uniform(-11.0, 8.0, 4000)
    xy = merge_road.to_cartesian(s, n)
    c, si = np.cos(ego.yaw), np.sin(ego.yaw)
    d = xy - [ego.x, ego.y]
    scan = np.column_stack([c * d[:, 0] + si * d[:, 1], -si * d[:, 0] + c * d[:, 1]])
    config = ClusteringConfig(bearing_bin=1e-6)  # a bin per return: the filter keeps every on-road point
    kept, counts, n_kept = filter_points(scan, ego, merge_road, config)
    inside = merge_road.within_bounds(s, n, config.road_margin)
    assert counts["points_off_road"] == int((~inside).sum())
    assert len(kept) + counts["points_bearing_filtered"] == int(inside.sum())
    # every kept return is one of the on-road ones (its lateral offset among theirs)
    gap = np.abs(n_kept[:, None] - n[inside][None, :]).min(axis=1)
    assert len(n_kept) > 1000 and gap.max() < 1e-6


def test_births_in_the_lanes_present_with_their_direction(merge_road):
    config = BirthConfig()
    means, covs = road_births(merge_road, 200.0, 10.0, 80.0, config)
    # at s = 275 (the auxiliary lane half tapered: 1.75 m wide) four lanes; at s = 125 (1.75 m) four too
    ahead = means[means[:, 0] > 200.0]
    np.testing.assert_allclose(ahead[:, 1], [-6.125, -3.5, 0.0, 3.5])
    np.testing.assert_allclose(ahead[:, 3], [0.0, 0.0, 0.0, np.pi])
    assert covs.shape == (len(means), 7, 7)
    ego = EgoState(x=float(merge_road.position(200.0)[0]), y=float(merge_road.position(200.0)[1]),
                   yaw=float(merge_road.heading(200.0)), v=10.0)
    vis, _ = visible_road_births(merge_road, 200.0, ego, 80.0, config, None, Rectangles(np.zeros((0, 2)), np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0)), np.zeros(0, int), 3.0)
    np.testing.assert_allclose(vis, means)


def test_parking_and_shoulder_lanes_are_road_without_births():
    layout = LaneLayout([0.0], [[-6.0, -3.5, 0.0, 3.5]], kinds=["parking", "driving", "driving"])
    road = Road.from_curvature([(300.0, 0.0, 0.0)], layout=layout)
    assert road.on_road(np.array([[100.0, -5.0]]))[0]
    means, _ = road_births(road, 150.0, 10.0, 80.0, BirthConfig())
    np.testing.assert_allclose(np.unique(means[:, 1]), [-1.75, 1.75])
