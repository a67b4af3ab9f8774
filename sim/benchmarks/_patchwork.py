"""Patchwork++ (``pypatchworkpp``, Lee et al. 2022, C++; the ``baselines`` extra) as the benchmarks'
reference ground segmentation: built for a lidar's height and range, run on one cloud in the sensor
frame, its ground returns as a mask."""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Iterator

import numpy as np

#: What a benchmark reports in place of Patchwork++'s numbers without the package.
MISSING = 'pypatchworkpp is not installed: pip install -e ".[baselines]"'


@contextlib.contextmanager
def _stdout_silenced() -> Iterator[None]:
    """File descriptor 1 to /dev/null: the library's constructor prints to the C++ stdout, which would
    land in the middle of ``eot bench``'s JSON."""
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 1)
            yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


class Patchwork:
    """Patchwork++ for a lidar ``sensor_height`` (m) above the ground with ``max_range`` (m), its other
    parameters the library's defaults; ``Patchwork.create`` gives None without the package."""

    def __init__(self, module, sensor_height: float, max_range: float) -> None:
        params = module.Parameters()
        params.sensor_height, params.max_range, params.verbose = float(sensor_height), float(max_range), False
        with _stdout_silenced():
            self._segmenter = module.patchworkpp(params)

    @classmethod
    def create(cls, sensor_height: float, max_range: float) -> Patchwork | None:
        try:
            import pypatchworkpp
        except ImportError:
            return None
        return cls(pypatchworkpp, sensor_height, max_range)

    def ground(self, points: np.ndarray) -> np.ndarray:
        """The ground mask (N,) of the cloud ``points (N, 3)`` in the sensor frame (m)."""
        cloud = np.column_stack([np.asarray(points, dtype=float), np.zeros(len(points))])  # x, y, z, intensity
        with _stdout_silenced():
            self._segmenter.estimateGround(cloud)
        mask = np.zeros(len(points), dtype=bool)
        mask[np.asarray(self._segmenter.getGroundIndices(), dtype=np.int64)] = True
        return mask
