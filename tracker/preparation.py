"""Batched cluster preparation: ``prepare_clusters`` and ``prepare_batch`` prepare a list of clusters
at once, what ``tracker.measurement.prepare_cluster`` does for one (``tracker.measurement``'s module
docstring, "Data"), by one call of ``tracker.measurement.prepare_kernel`` over all of them;
``prepare_scanned_batch`` adds the shadow flags of the clusters' ends in the frame's lidar returns
(``scanned_batch_kernel``, below). The tracker uses it every frame. A cluster that is not a non-empty
``(n, 2)`` array of finite points goes through ``prepare_cluster`` alone, which drops and counts its
non-finite points (or refuses it).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from tracker.clustering import continued_ends, occluded_ends
from tracker.config import MeasurementConfig
from tracker.measurement import MIN_CHORD, Cluster, ClusterBatch, prepare_cluster, prepare_kernel, prepare_settings
from tracker.jit import njit
from tracker.clustering import bearing_sorted_scan, continued_ends_sorted, occluded_ends_sorted


def _checked(clusters: Sequence[np.ndarray], velocities: Sequence[np.ndarray | None] | None) -> tuple[list[np.ndarray], list]:
    arrays = [np.asarray(c, dtype=float) for c in clusters]
    velocities = list(velocities) if velocities is not None else [None] * len(arrays)
    if len(velocities) != len(arrays):
        raise ValueError(f"prepare_clusters: {len(arrays)} clusters but {len(velocities)} velocities")
    return arrays, velocities


def _regular(a: np.ndarray) -> bool:
    """Whether a cluster takes the batched path (a non-empty ``(n, 2)`` array of finite points)."""
    return a.ndim == 2 and a.shape[1] == 2 and len(a) > 0 and bool(np.isfinite(a).all())


def _all_regular(arrays: list[np.ndarray]) -> np.ndarray | None:
    """All the points (concatenated) when ``all(_regular(a) for a in arrays)``, with one finiteness test
    over all of them; else None."""
    if not all(a.ndim == 2 and a.shape[1] == 2 and len(a) > 0 for a in arrays):
        return None
    flat = np.concatenate(arrays)
    return flat if np.isfinite(flat).all() else None


def prepare_clusters(
    clusters: Sequence[np.ndarray], config: MeasurementConfig | None = None,
    velocities: Sequence[np.ndarray | None] | None = None,
) -> list[Cluster]:
    """``[prepare_cluster(points, config, velocity) for ...]`` for clusters ``(n_k, 2)`` in E (m),
    vectorised across clusters (module docstring). ``velocities`` per cluster or ``None``."""
    config = config if config is not None else MeasurementConfig()
    arrays, velocities = _checked(clusters, velocities)
    out: list[Cluster | None] = [None] * len(arrays)
    fast = []
    for i, a in enumerate(arrays):
        if _regular(a):
            fast.append(i)
        else:
            out[i] = prepare_cluster(a, config, velocities[i])  # raises, or drops and counts non-finite points
    if fast:
        for i, c in zip(fast, _prepare_finite([arrays[i] for i in fast], [velocities[i] for i in fast], config).records()):
            out[i] = c
    return out  # type: ignore[return-value]


def prepare_batch(
    clusters: Sequence[np.ndarray], config: MeasurementConfig | None = None,
    velocities: Sequence[np.ndarray | None] | None = None,
) -> ClusterBatch:
    """``ClusterBatch.of(prepare_clusters(clusters, config, velocities))`` (at least one cluster), built
    from the padded arrays directly when every cluster is regular (the tracker's case)."""
    config = config if config is not None else MeasurementConfig()
    arrays, velocities = _checked(clusters, velocities)
    flat = _all_regular(arrays) if arrays else None
    if flat is not None:
        return _prepare_finite(arrays, velocities, config, flat=flat).batch()
    return ClusterBatch.of(prepare_clusters(arrays, config, velocities))


def prepare_scanned_batch(
    clusters: Sequence[np.ndarray], config: MeasurementConfig, velocities: Sequence[np.ndarray | None] | None,
    scan: np.ndarray, lidar_resolution: float, lidar_range: float,
) -> ClusterBatch:
    """``prepare_batch`` with the clusters' shadow flags in the frame's lidar returns ``scan (N, 2)`` (E):
    ``occluded_end``, ``tracker.clustering.occluded_ends`` of the bearing ends (``shadow_window`` rays of
    ``lidar_resolution`` rad, ``shadow_margin``, the lidar's range ``lidar_range`` m less
    ``shadow_range_margin``; None without ``MeasurementConfig.shadow_window``), and ``continued_end``,
    ``tracker.clustering.continued_ends`` of the side ends (``continuation_rays``, ``continuation_offset``;
    None without the shadow flags or ``continuation_rays``): the batch
    the tracker's update takes. One call of ``scanned_batch_kernel`` when every cluster is a non-empty
    ``(n, 2)`` array of finite points."""
    scan = np.asarray(scan, dtype=float)
    if scan.ndim != 2 or scan.shape[1] != 2:
        raise ValueError(f"prepare_scanned_batch: scan must be lidar returns of shape (N, 2) in E; got {scan.shape}")
    shadows = config.shadow_window is not None
    continuation = shadows and config.continuation_rays is not None
    window = config.shadow_window * lidar_resolution if shadows else 0.0
    arrays, velocities = _checked(clusters, velocities)
    flat = _all_regular(arrays) if arrays else None
    if flat is None:  # a cluster with a non-finite point or none: prepared one by one
        batch = prepare_batch(arrays, config, velocities)
        if not shadows:
            return batch
        occluded = occluded_ends(batch.bearing_ends(), scan, window, config.shadow_margin, lidar_range,
                                 config.shadow_range_margin)
        continued = (continued_ends(*batch.side_ends(), scan, config.continuation_rays, config.continuation_offset)
                     if continuation else None)
        return dataclasses.replace(batch, occluded_end=occluded, continued_end=continued)
    vel_out = _checked_velocities(velocities)
    (points, valid, part, proj, starts, ends, direction, length, margin, half_gap, two, single, kept_count, occluded,
     continued) = scanned_batch_kernel(
        flat, _offsets(arrays), *prepare_settings(config), np.ascontiguousarray(scan), shadows, float(window),
        float(config.shadow_margin), float(lidar_range), float(config.shadow_range_margin), continuation,
        float(config.continuation_rays or 0.0), float(config.continuation_offset))
    fused, velocity = _stacked_velocities(vel_out)
    return ClusterBatch(
        points=points, valid=valid, part=part, proj=proj, chord_start=starts, chord_end=ends, chord_dir=direction,
        chord_len=length, end_margin=margin, end_gap=half_gap, two_sided=two, single=single, fused=fused,
        velocity=velocity, centroid=points.sum(axis=1) / np.maximum(kept_count, 1)[:, None],
        occluded_end=occluded if shadows else None, continued_end=continued if continuation else None,
    )


def _stacked_velocities(velocity: list[np.ndarray | None]) -> tuple[np.ndarray, np.ndarray]:
    """Which clusters have a radar velocity ``(K,)`` and the velocities ``(K, 2)`` (0 where none)."""
    fused = np.array([v is not None for v in velocity], dtype=bool)
    stacked = np.zeros((len(fused), 2))
    if fused.any():
        stacked[fused] = [v for v in velocity if v is not None]
    return fused, stacked


def _checked_velocities(velocities: list[np.ndarray | None]) -> list[np.ndarray | None]:
    given = [v for v in velocities if v is not None]
    if all(type(v) is np.ndarray and v.shape == (2,) and v.dtype == np.float64 for v in given) and (
            not given or math.isfinite(sum(float(v[0]) + float(v[1]) for v in given))):
        return list(velocities)  # the tracker's own: finite float (vx, vy) arrays (a sum that overflows: checked below)
    out: list[np.ndarray | None] = []
    for v in velocities:
        if v is None:
            out.append(None)
            continue
        v = np.asarray(v, dtype=float).reshape(-1)
        if v.shape != (2,) or not np.isfinite(v).all():
            raise ValueError(f"cluster velocity must be a finite (vx, vy) in m/s; got {v!r}")
        out.append(v)
    return out


def _offsets(arrays: list[np.ndarray]) -> np.ndarray:
    """Where each cluster starts in the concatenated points, and the end: ``(K + 1,)``."""
    offsets = np.zeros(len(arrays) + 1, dtype=np.intp)
    np.cumsum([len(a) for a in arrays], out=offsets[1:])
    return offsets


def _prepare_finite(arrays: list[np.ndarray], velocities: list[np.ndarray | None], config: MeasurementConfig,
                    *, flat: np.ndarray | None = None) -> _Prepared:
    """The padded arrays of finite, non-empty clusters, by ``prepare_kernel``, cut to the most points a
    cluster kept. ``flat``: the clusters' points concatenated, when the caller has them."""
    vel_out = _checked_velocities(velocities)
    offsets = _offsets(arrays)
    n = np.diff(offsets)
    (points, valid, part, proj, starts, ends, direction, length, margin, half_gap, two, corner, ratio, order,
     kept_count) = prepare_kernel(np.concatenate(arrays) if flat is None else flat, offsets, *prepare_settings(config))
    m = int(kept_count.max())
    c = np.ascontiguousarray  # the kernels downstream take C-contiguous arrays (one compiled signature)
    return _Prepared(
        points=c(points[:, :m]), valid=c(valid[:, :m]), part=c(part[:, :m]), proj=c(proj[:, :, :m]),
        chord_start=starts, chord_end=ends, chord_dir=direction, chord_len=length, end_margin=margin,
        end_gap=half_gap, two_sided=two, corner=corner, eigen_ratio=ratio, raw_count=n, order=order[:, :m],
        kept_count=kept_count,
        velocity=vel_out,
    )


@dataclass(frozen=True)
class _Prepared:
    """The padded per-cluster arrays of ``_prepare_finite`` (K clusters, M kept points at most)."""

    points: np.ndarray
    valid: np.ndarray
    part: np.ndarray
    proj: np.ndarray
    chord_start: np.ndarray
    chord_end: np.ndarray
    chord_dir: np.ndarray
    chord_len: np.ndarray
    end_margin: np.ndarray
    end_gap: np.ndarray
    two_sided: np.ndarray
    corner: np.ndarray
    eigen_ratio: np.ndarray
    raw_count: np.ndarray
    order: np.ndarray
    kept_count: np.ndarray
    velocity: list[np.ndarray | None]

    def records(self) -> list[Cluster]:
        """One ``Cluster`` per row."""
        out = []
        for i in range(len(self.points)):  # no arithmetic here
            m = int(self.kept_count[i])
            out.append(Cluster(
                points=self.points[i, :m], part=self.part[i, :m], proj=self.proj[i, :, :m],
                chord_start=self.chord_start[i], chord_end=self.chord_end[i], chord_dir=self.chord_dir[i],
                chord_len=self.chord_len[i], two_sided=bool(self.two_sided[i]), corner=int(self.corner[i]),
                eigen_ratio=float(self.eigen_ratio[i]), end_margin=self.end_margin[i], velocity=self.velocity[i],
                end_gap=self.end_gap[i],
                raw_count=int(self.raw_count[i]), dropped=0, order=self.order[i, :m],
            ))
        return out

    def batch(self) -> ClusterBatch:
        """The rows as a ``ClusterBatch`` (what ``ClusterBatch.of(self.records())`` gives)."""
        fused, velocity = _stacked_velocities(self.velocity)
        count = np.maximum(self.kept_count, 1)[:, None]
        return ClusterBatch(
            points=self.points, valid=self.valid, part=self.part, proj=self.proj,
            chord_start=self.chord_start, chord_end=self.chord_end, chord_dir=self.chord_dir,
            chord_len=self.chord_len, end_margin=self.end_margin, end_gap=self.end_gap, two_sided=self.two_sided.copy(),
            single=self.chord_len[:, 0] <= MIN_CHORD, fused=fused,
            velocity=velocity,
            centroid=self.points.sum(axis=1) / count,
        )


# --------------------------------------------------------------------------------------------------
# The compiled kernels of this stage.
#
# The prepared batch with the shadow flags of its clusters' ends: ``prepare_kernel``, then the ends
# bordering another object's shadow and the sides that go on in other returns, both found in the
# frame's lidar returns sorted once by bearing.
# --------------------------------------------------------------------------------------------------


@njit
def scanned_batch_kernel(flat, offsets, bound, min_two, ratio_max, min_residual, line_residual, min_chord,
                         sin_min_angle, max_shift, max_end_gap, scan, shadows, window, margin, max_range, range_margin,
                         continuation, rays, offset):  # pragma: no cover - compiled
    """``prepare_kernel``'s arrays cut to the most points kept (as ``_prepare_finite`` cuts them),
    whether each cluster's chord is a single point, and the shadow flags of the clusters' ends in
    ``scan`` (``shadows``: ``occluded_ends`` of the bearing ends with ``window``, ``margin``,
    ``max_range``, ``range_margin``; ``continuation``: ``continued_ends`` of the side ends with
    ``rays`` ray gaps and ``offset``), all False where a flag is off (the caller leaves it out).
    Returns ``(points, valid, part, proj, chord_start, chord_end, chord_dir, chord_len, end_margin,
    end_gap, two_sided, single, kept_count, occluded, continued)``."""
    (points, valid, part, proj, starts, ends, direction, length, margin_out, half_gap, two, _corner, _ratio, _order,
     kept_count) = prepare_kernel(flat, offsets, bound, min_two, ratio_max, min_residual, line_residual,
                                  min_chord, sin_min_angle, max_shift, max_end_gap)
    count = len(kept_count)
    m = kept_count.max()
    points = points[:, :m].copy()
    valid = valid[:, :m].copy()
    part = part[:, :m].copy()
    proj = proj[:, :, :m].copy()
    single = np.empty(count, dtype=np.bool_)
    for k in range(count):
        single[k] = length[k, 0] <= min_chord
    occluded = np.zeros((count, 2), dtype=np.bool_)
    continued = np.zeros((count, 2), dtype=np.bool_)
    if shadows and len(scan) and count:
        bearing_ends = np.empty((count, 2, 2))  # ClusterBatch.bearing_ends: first and last kept point
        for k in range(count):
            last = max(int(valid[k].sum()) - 1, 0)
            bearing_ends[k, 0] = points[k, 0]
            bearing_ends[k, 1] = points[k, last]
        scan_b, scan_r, scan_xy = bearing_sorted_scan(scan)  # one sort for both searches
        occluded = occluded_ends_sorted(bearing_ends, scan_b, scan_r, window, margin, max_range, range_margin)
        if continuation:
            side = np.empty((count, 2, 2))  # ClusterBatch.side_ends
            outward = np.empty((count, 2, 2))
            start = np.empty((count, 2))
            reach = np.empty((count, 2))
            for k in range(count):
                side[k, 0] = starts[k, 1]
                side[k, 1] = ends[k, 2]
                outward[k, 0, 0] = -direction[k, 1, 0]
                outward[k, 0, 1] = -direction[k, 1, 1]
                outward[k, 1] = direction[k, 2]
                start[k, 0] = half_gap[k, 1, 0]
                start[k, 1] = half_gap[k, 2, 1]
                reach[k, 0] = 2.0 * rays * start[k, 0]
                reach[k, 1] = 2.0 * rays * start[k, 1]
            continued = continued_ends_sorted(side, outward, start, reach, scan_b, scan_xy, offset)
    return (points, valid, part, proj, starts, ends, direction, length, margin_out, half_gap, two, single, kept_count,
            occluded, continued)
