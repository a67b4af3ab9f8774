"""Angle helpers: every angle in frenet-eot is wrapped to (-pi, pi]."""

from __future__ import annotations

import numpy as np


def wrap_angle(angle: np.ndarray | float) -> np.ndarray | float:
    """Wrap ``angle`` (rad) to (-pi, pi]; arrays element-wise, floats stay floats."""
    wrapped = np.pi - np.mod(np.pi - np.asarray(angle, dtype=float), 2.0 * np.pi)
    return float(wrapped) if np.ndim(wrapped) == 0 else wrapped
