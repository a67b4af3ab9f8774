"""Scalar geometry shared by the compiled kernels (the tracker's and the simulator's): the wrap of an
angle (``tracker.angles.wrap_angle``) and a rectangle's corner offsets (``tracker.measurement.SX``,
``SY``)."""

from __future__ import annotations

import math

from tracker.jit import njit

TWO_PI = 2.0 * math.pi


@njit
def wrap_angle(a):  # pragma: no cover - compiled
    """``a`` (rad) wrapped to (-pi, pi], as ``tracker.angles.wrap_angle`` (Python's float modulo is
    numpy's ``np.mod``)."""
    return math.pi - ((math.pi - a) % TWO_PI)


@njit
def corner_offset(k, half_length, half_width):  # pragma: no cover - compiled
    """Body-frame offset ``(along, across)`` of corner ``k`` of a rectangle: front-right, front-left,
    rear-left, rear-right for ``k = 0 .. 3`` (counter-clockwise; ``SX[k] L/2``, ``SY[k] W/2``)."""
    return (half_length if k < 2 else -half_length), (-half_width if k == 0 or k == 3 else half_width)
