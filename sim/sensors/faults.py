"""Sensor faults on the frames of a run: the scenario's ``[faults]`` table (``sim.world.scenario.FaultsSpec``).

``FaultInjector(spec, lidar_config, rng).apply(frames)`` wraps the ``SensorRig``'s frame stream:

- a frame in a ``lidar_dropout`` interval ``[start, end)`` (by its stamp) loses its lidar points
  (``SensorFrame.lidar`` becomes an empty scan, so the visible-truth scoring sees nothing either);
- a frame in a ``radar_dropout`` interval, or any frame with ``radar_missing``, loses its radar
  detections;
- with ``lidar_spikes`` = p, each remaining point is, with probability p, moved along its own ray to
  a range uniform in the lidar's ``[min_range, max_range]`` (it then hits nothing: vehicle id -1);
- the first frame at or after each ``duplicate_frames`` time is yielded twice (the same frame object:
  the tracker sees the same timestamp twice).

The ``lidar_time_offset`` fault is the rig's (``SensorRig.frames(..., lidar_delay=...)``), which
scans the world that long before the frame's stamp; ``run_scenario`` passes it. Everything else in a
frame is unchanged, and the spikes draw from their own generator, so a faulty run has the same
traffic and the same sensor noise as the clean run of the same seed. ``counts`` tallies what was
done (``fault_*`` keys of the run's metrics).

How the tracker lives through a lidar dropout is measured after the run, from its scored frames, by
``sim.evaluation.dropouts``.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from sim.sensors.lidar import LidarConfig, LidarScan
from sim.sensors.radar import RadarScan
from sim.sensors.rig import SensorFrame
from sim.world.scenario import FaultsSpec
from tracker.frame import Frame, RadarDetections

#: Stream tag mixed into the seed for the faults' random generator (lidar spikes).
FAULT_STREAM = 0x46415554  # "FAUT"


def in_intervals(t: float, intervals: Sequence[tuple[float, float]]) -> bool:
    """Whether ``t`` (s) lies in one of the intervals ``[start, end)``."""
    return any(start <= t < end for start, end in intervals)


def _empty_scan(scan: LidarScan) -> LidarScan:
    return LidarScan(
        t=scan.t,
        azimuth=np.zeros(0),
        range=np.zeros(0),
        points=np.zeros((0, 2)),
        vehicle_id=np.zeros(0, dtype=scan.vehicle_id.dtype),
        roadside_index=np.zeros(0, dtype=scan.roadside_index.dtype),
        rays=scan.rays,
    )


def _empty_radar(scan: RadarScan) -> RadarScan:
    keep = np.zeros(len(scan.t), dtype=bool)
    return RadarScan(t=scan.t[keep], xy=scan.xy[keep], velocity=scan.velocity[keep], target_id=scan.target_id[keep],
                     unit=scan.unit[keep])


@dataclass
class FaultInjector:
    """Applies ``spec`` to a stream of ``SensorFrame``s (module docstring); ``lidar`` gives the spike
    ranges, ``rng`` draws the spikes. ``counts``: ``lidar_frames_dropped``, ``radar_frames_dropped``,
    ``radar_detections_dropped``, ``lidar_points_spiked``, ``frames_duplicated``."""

    spec: FaultsSpec
    lidar: LidarConfig
    rng: np.random.Generator
    counts: Counter[str] = field(default_factory=Counter)

    def apply(self, frames: Iterable[SensorFrame]) -> Iterator[SensorFrame]:
        """The faulty stream (lazy)."""
        duplicates = sorted(self.spec.duplicate_frames)
        for sf in frames:
            out = self.frame(sf)
            yield out
            t = float(sf.frame.t)
            while duplicates and duplicates[0] <= t + 1e-9:
                duplicates.pop(0)
                self.counts["frames_duplicated"] += 1
                yield out

    def frame(self, sf: SensorFrame) -> SensorFrame:
        """One frame with the lidar dropout, radar dropout and spike faults applied."""
        spec = self.spec
        t = float(sf.frame.t)
        lidar, radar = sf.lidar, sf.radar
        changed = False
        if in_intervals(t, spec.lidar_dropout):
            lidar = _empty_scan(lidar)
            self.counts["lidar_frames_dropped"] += 1
            changed = True
        elif spec.lidar_spikes > 0.0 and len(lidar):
            hit = self.rng.random(len(lidar)) < spec.lidar_spikes
            hit &= np.isfinite(lidar.range)  # an organized cloud's rays without a return stay so
            ranges = self.rng.uniform(self.lidar.min_range, self.lidar.max_range, len(lidar))
            if hit.any():
                new_range = np.where(hit, ranges, lidar.range)
                # along each point's own ray: from its lidar (a rig's merged cloud has several)
                start = lidar.point_origins() if hasattr(lidar, "point_origins") else np.zeros_like(lidar.points)
                rel = lidar.points - start
                direction = rel / np.maximum(np.linalg.norm(rel, axis=1), 1e-12)[:, None]
                points = np.where(hit[:, None], start + direction * new_range[:, None], lidar.points)
                lidar = replace(
                    lidar,
                    range=new_range,
                    points=points,
                    vehicle_id=np.where(hit, -1, lidar.vehicle_id),
                    roadside_index=np.where(hit, -1, lidar.roadside_index),
                )
                self.counts["lidar_points_spiked"] += int(hit.sum())
                changed = True
        if len(radar) and (spec.radar_missing or in_intervals(t, spec.radar_dropout)):
            self.counts["radar_frames_dropped"] += 1
            self.counts["radar_detections_dropped"] += len(radar)
            radar = _empty_radar(radar)
            changed = True
        if not changed:
            return sf
        frame = Frame(
            t=sf.frame.t,
            ego=sf.frame.ego,
            lidar=lidar.points,
            radar=RadarDetections(radar.t, radar.xy[:, 0], radar.xy[:, 1], radar.velocity[:, 0], radar.velocity[:, 1]),
        )
        return SensorFrame(frame=frame, truth=sf.truth, lidar=lidar, radar=radar)


def fault_metrics(counts: Counter[str]) -> dict[str, int]:
    """The injector's counts as ``fault_*`` metrics (every key, 0 when nothing was done)."""
    keys = ("lidar_frames_dropped", "radar_frames_dropped", "radar_detections_dropped", "lidar_points_spiked",
            "frames_duplicated")
    return {f"fault_{k}": int(counts.get(k, 0)) for k in keys}


__all__ = [
    "FAULT_STREAM",
    "FaultInjector",
    "fault_metrics",
    "in_intervals",
]
