"""Tests of tracker/preprocess.py."""

from __future__ import annotations

import numpy as np
import pytest

from tracker import Road
from tracker.preprocess import bearing_filter, drop_nonfinite, road_bound_mask
from tracker.transforms import to_global, to_local


def test_drop_nonfinite_counts():
    pts = np.array([[1.0, 2.0], [np.nan, 0.0], [3.0, np.inf], [4.0, 5.0]])
    kept, dropped = drop_nonfinite(pts)
    np.testing.assert_array_equal(kept, [[1.0, 2.0], [4.0, 5.0]])
    assert dropped == 2


def test_frame_transforms_round_trip():
    rng = np.random.default_rng(0)
    pts = rng.normal(size=(50, 2)) * 20
    g = to_global(pts, (10.0, -3.0), 0.7)
    np.testing.assert_allclose(to_local(g, (10.0, -3.0), 0.7), pts, atol=1e-12)
    # a point 1 m ahead of an ego heading +y is 1 m north of it
    np.testing.assert_allclose(to_global(np.array([[1.0, 0.0]]), (0.0, 0.0), np.pi / 2), [[0.0, 1.0]], atol=1e-12)


def test_road_bound_mask_keeps_road_points_only():
    road = Road.from_curvature([(200.0, 0.0, 0.0)], lanes=2, lane_width=3.5)  # bounds n in [-3.5, 3.5]
    pts = np.array([[50.0, 0.0], [50.0, 3.9], [50.0, 4.1], [50.0, -8.0], [250.0, 0.0]])
    np.testing.assert_array_equal(road_bound_mask(pts, road, margin=0.5), [True, True, False, False, False])
    assert road_bound_mask(np.zeros((0, 2)), road).shape == (0,)


def test_bearing_filter_keeps_closest_point_per_bin():
    # a wall at x = 10 and points behind it at x = 20 along the same bearings
    y = np.linspace(-2.0, 2.0, 21)
    near = np.column_stack([np.full_like(y, 10.0), y])
    far = 2.0 * near
    pts = np.vstack([far, near])
    kept = bearing_filter(pts, bin_width=np.deg2rad(0.5))
    assert set(kept.tolist()) == set(range(21, 42))
    bearings = np.arctan2(pts[kept, 1], pts[kept, 0])
    assert np.all(np.diff(bearings) > 0)
    with pytest.raises(ValueError, match="bin_width"):
        bearing_filter(pts, 0.0)
