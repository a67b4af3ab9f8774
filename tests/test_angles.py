"""Tests of tracker/angles.py: ``wrap_angle`` maps to (-pi, pi], and its float, numpy-scalar, 0-d and
array paths give the same numbers bit for bit, as does the kernels' scalar wrap (tracker/geometry.py)."""

from __future__ import annotations

import math

import numpy as np

from tracker.angles import wrap_angle


def test_wrap_angle_range_and_paths_agree():
    rng = np.random.default_rng(0)
    x = np.concatenate([rng.uniform(-60.0, 60.0, 20000),
                        [math.pi, -math.pi, 0.0, -0.0, 3 * math.pi, -3 * math.pi, 2 * math.pi, 1e-17, -1e-17, 1e12]])
    ref = np.pi - np.mod(np.pi - x, 2.0 * np.pi)  # the definition
    arr = wrap_angle(x)
    floats = np.array([wrap_angle(float(v)) for v in x])
    scalars = np.array([wrap_angle(np.float64(v)) for v in x])
    zero_d = np.array([wrap_angle(np.array(v)) for v in x])
    for got in (arr, floats, scalars, zero_d):
        np.testing.assert_array_equal(got, ref)
    assert np.all((arr > -np.pi) & (arr <= np.pi))
    assert wrap_angle(-math.pi) == math.pi and wrap_angle(math.pi) == math.pi
    assert type(wrap_angle(1.0)) is float and type(wrap_angle(np.float64(1.0))) is float
    assert isinstance(wrap_angle([0.0, 7.0]), np.ndarray) and wrap_angle(np.array([1, 8])).dtype == float
    small = np.abs(x) < 100.0  # the same direction (far from 0, cos(x) itself has lost its digits)
    np.testing.assert_allclose(np.cos(arr[small]), np.cos(x[small]), atol=1e-9)


def test_the_kernels_scalar_wrap_is_wrap_angle_bit_for_bit():
    """``tracker.geometry.wrap_angle`` (the kernels' scalar wrap) gives ``wrap_angle``'s numbers."""
    from tracker.geometry import wrap_angle as kernel_wrap

    rng = np.random.default_rng(1)
    x = np.concatenate([rng.uniform(-60.0, 60.0, 2000), [math.pi, -math.pi, 0.0, -0.0, 3 * math.pi, 1e-17, 1e12]])
    np.testing.assert_array_equal(np.array([kernel_wrap(v) for v in x]), wrap_angle(x))
