"""Angle helpers: every angle in frenet-eot is wrapped to (-pi, pi]."""

from __future__ import annotations

import math

import numpy as np


_TWO_PI = 2.0 * np.pi


def wrap_angle(angle: np.ndarray | float) -> np.ndarray | float:
    """Wrap ``angle`` (rad) to (-pi, pi]; arrays element-wise, floats stay floats."""
    if type(angle) is np.ndarray and angle.dtype == np.float64 and angle.ndim:  # the common case, no checks
        return np.pi - np.mod(np.pi - angle, _TWO_PI)
    if isinstance(angle, float):  # Python's float modulo is numpy's np.mod: the same number, without numpy
        return float(math.pi - ((math.pi - angle) % _TWO_PI))
    wrapped = np.pi - np.mod(np.pi - np.asarray(angle, dtype=float), _TWO_PI)
    return float(wrapped) if np.ndim(wrapped) == 0 else wrapped
