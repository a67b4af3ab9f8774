"""Validation shared by the tracker's configuration dataclasses (``tracker.config``, ``tracker.cloud``):
errors name the class, the field, the allowed range and the value."""

from __future__ import annotations

import math
from typing import Any

import numpy as np


def check_real(cls_name: str, name: str, value: Any, *, low: float | None = None, high: float | None = None,
               low_open: bool = False, high_open: bool = False, unit: str = "") -> None:
    """Raise ``ValueError`` unless ``value`` is a finite real within the given bounds."""
    where = f"{cls_name}.{name}"
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"{where} must be a real number{(' in ' + unit) if unit else ''}; got {value!r}")
    if not math.isfinite(value):
        raise ValueError(f"{where} must be finite; got {value!r}")
    bad_low = low is not None and (value <= low if low_open else value < low)
    bad_high = high is not None and (value >= high if high_open else value > high)
    if bad_low or bad_high:
        lo = "" if low is None else (f"> {low}" if low_open else f">= {low}")
        hi = "" if high is None else (f"< {high}" if high_open else f"<= {high}")
        rng = " and ".join(part for part in (lo, hi) if part)
        raise ValueError(f"{where} must be {rng}{(' ' + unit) if unit else ''}; got {value!r}")


def finite_array(value: Any, name: str) -> np.ndarray:
    """``value`` as a float array; a ``ValueError`` naming ``name`` and the first non-finite entry if any."""
    arr = np.asarray(value, dtype=float)
    bad = ~np.isfinite(arr)
    if bad.any():
        index = tuple(int(i) for i in np.argwhere(bad)[0])
        raise ValueError(f"{name} must be finite; got {arr[index]!r} at index {index}")
    return arr
