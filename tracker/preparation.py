"""Batched cluster preparation: ``prepare_clusters`` does for a list of clusters at once what
``tracker.measurement.prepare_cluster`` (the readable one-cluster reference) does for one, with numpy
over padded ``(K, N)`` arrays instead of a Python call per cluster. The tracker uses it every frame;
``tests/test_preparation.py`` checks it against the reference on random and real clusters.

Per cluster (all vectorised across clusters): centroid and scatter, points sorted by bearing about the
centroid's bearing, one/two-sided from the eigenvalue ratio, the corner split minimising the two line
fits' total-least-squares residuals (prefix sums over every split), even downsampling to
``max_cluster_points`` (the corner kept in both parts), the chords of slot 0 (all points) and slots 1, 2
(before / after the corner, the corner point in both), the corner as the intersection of the two
fitted lines when they meet at a useful angle near the corner point, the end-gap margins, and every
kept point's chord coordinates. Clusters with a non-finite point take the reference path (it drops and
counts them).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from tracker import jit as compiled_kernels
from tracker.clustering import continued_ends, occluded_ends
from tracker.config import MeasurementConfig
from tracker.measurement import (
    CORNER_MAX_SHIFT, CORNER_MIN_ANGLE, MAX_END_GAP, MIN_CHORD, Cluster, ClusterBatch, _lambda_min, prepare_cluster,
)
from tracker.jit import njit
from tracker.clustering import bearing_sorted_scan, continued_ends_sorted, occluded_ends_sorted


def _masked_scatter(pts: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Count, centroid ``(..., 2)`` and biased scatter ``sxx, syy, sxy`` of ``pts (..., N, 2)`` over the
    points where the mask ``w (..., N)`` is true."""
    wf = w.astype(float)
    count = wf.sum(axis=-1)
    safe = np.maximum(count, 1.0)
    c = np.einsum("...n,...nd->...d", wf, pts) / safe[..., None]
    d = (pts - c[..., None, :]) * wf[..., None]
    sxx = np.einsum("...n,...n->...", d[..., 0], d[..., 0]) / safe
    syy = np.einsum("...n,...n->...", d[..., 1], d[..., 1]) / safe
    sxy = np.einsum("...n,...n->...", d[..., 0], d[..., 1]) / safe
    return count, c, sxx, syy, sxy


def _corner_indices(pts: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Corner split ``k`` in ``1..n-2`` per row of bearing-sorted ``pts (K, N, 2)`` with ``n (K,)`` valid
    points each (``n >= 3``): ``tracker.measurement.corner_index`` for all rows at once."""
    count, width = pts.shape[0], pts.shape[1]
    valid = np.arange(width)[None, :] < n[:, None]
    _, centre, *_ = _masked_scatter(pts, valid)
    p = (pts - centre[:, None, :]) * valid[..., None]
    x, y = p[..., 0], p[..., 1]
    # prefix sums of (count, x, y, xx, yy, xy), stacked: c[:, :, i] sums points 0..i-1
    c = np.concatenate([np.zeros((6, count, 1)), np.cumsum(np.stack([valid.astype(float), x, y, x * x, y * y, x * y]), axis=2)], axis=2)
    k = np.arange(1, max(width - 1, 2))  # candidate splits (N-2,)
    kk = k[None, :]

    def residual(sums: np.ndarray) -> np.ndarray:  # sums (6, K, N-2) of the points of a part
        cnt, sx, sy, sxx, syy, sxy = sums
        cnt = np.maximum(cnt, 1.0)
        return np.maximum(_lambda_min(sxx - sx * sx / cnt, syy - sy * sy / cnt, sxy - sx * sy / cnt), 0.0)

    # part one: points 0..k (sums c[k + 1] - c[0], c[0] = 0); part two: k..n-1 (c[n] - c[k]); a
    # split k beyond n - 2 is invalid, and its sums (clamped to the row's last point) are never used
    head = c[:, :, 2 : len(k) + 2]
    end = np.take_along_axis(c, np.broadcast_to(n[None, :, None], (6, count, 1)), axis=2)
    tail = end - c[:, :, 1 : len(k) + 1]
    cost = np.where(kk <= (n - 2)[:, None], residual(head) + residual(tail), np.inf)
    return k[np.argmin(cost, axis=1)]


def _even_mask(mask: np.ndarray, rows: np.ndarray, lo: np.ndarray, hi: np.ndarray, count: np.ndarray) -> None:
    """Set ``mask[row, i]`` for ``count`` indices evenly spread over ``lo..hi`` (both ends kept) per row,
    as ``tracker.measurement._even`` (duplicates collapse)."""
    if not len(rows):
        return
    count = np.maximum(count, 2)
    j = np.arange(int(count.max()))[None, :]
    step = (hi - lo) / (count - 1)  # as numpy.linspace: j * step + start, the last one exactly the stop
    pos = np.where(j == (count - 1)[:, None], hi[:, None], j * step[:, None] + lo[:, None])
    idx = np.round(pos).astype(int)
    take = j < count[:, None]
    r = np.broadcast_to(rows[:, None], idx.shape)
    mask[r[take], idx[take]] = True


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
    None unless a sharp-end rule, ``sharp_side_whole`` or ``sharp_parts_whole``, asks for it): the batch
    the tracker's update takes. One compiled call (``tracker.preparation.scanned_batch_kernel``:
    the same kernels, the same numbers) when the kernels are on and every cluster is regular."""
    scan = np.asarray(scan, dtype=float)
    if scan.ndim != 2 or scan.shape[1] != 2:
        raise ValueError(f"prepare_scanned_batch: scan must be lidar returns of shape (N, 2) in E; got {scan.shape}")
    shadows = config.shadow_window is not None
    continuation = shadows and config.continuation_rays is not None and bool(config.sharp_side_whole
                                                                              or config.sharp_parts_whole)
    window = config.shadow_window * lidar_resolution if shadows else 0.0
    arrays, velocities = _checked(clusters, velocities)
    flat = _all_regular(arrays) if arrays else None
    if flat is None or not compiled_kernels.enabled():
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
        flat, _offsets(arrays), *_kernel_settings(config), np.ascontiguousarray(scan), shadows, float(window),
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


def _prepare_finite(arrays: list[np.ndarray], velocities: list[np.ndarray | None], config: MeasurementConfig,
                    *, compiled: bool | None = None, flat: np.ndarray | None = None) -> _Prepared:
    """The padded arrays of finite, non-empty clusters: by the compiled kernel
    (``tracker.preparation``) when ``compiled`` (default: ``tracker.compiled.enabled()``), else
    by numpy (the reference). ``flat``: the clusters' points concatenated, when the caller has them."""
    vel_out = _checked_velocities(velocities)
    if compiled is None:
        compiled = compiled_kernels.enabled()
    if compiled:
        compiled_kernels.require()
        return _prepare_compiled(arrays, vel_out, config, flat)
    return _prepare_numpy(arrays, vel_out, config)


def _offsets(arrays: list[np.ndarray]) -> np.ndarray:
    """Where each cluster starts in the concatenated points, and the end: ``(K + 1,)``."""
    offsets = np.zeros(len(arrays) + 1, dtype=np.intp)
    np.cumsum([len(a) for a in arrays], out=offsets[1:])
    return offsets


def _kernel_settings(config: MeasurementConfig) -> tuple:
    """``prepare_kernel``'s settings after its points and offsets."""
    return (int(config.max_cluster_points), int(config.min_points_two_sided), float(config.two_side_eigen_ratio),
            bool(config.end_gap_correction), MIN_CHORD, math.sin(CORNER_MIN_ANGLE), CORNER_MAX_SHIFT, MAX_END_GAP)


def _prepare_compiled(arrays: list[np.ndarray], vel_out: list[np.ndarray | None], config: MeasurementConfig,
                      flat: np.ndarray | None = None) -> _Prepared:
    offsets = _offsets(arrays)
    n = np.diff(offsets)
    (points, valid, part, proj, starts, ends, direction, length, margin, half_gap, two, corner, ratio, order,
     kept_count) = prepare_kernel(np.concatenate(arrays) if flat is None else flat, offsets, *_kernel_settings(config))
    m = int(kept_count.max())
    c = np.ascontiguousarray  # the kernels downstream take C-contiguous arrays (one compiled signature)
    return _Prepared(
        points=c(points[:, :m]), valid=c(valid[:, :m]), part=c(part[:, :m]), proj=c(proj[:, :, :m]),
        chord_start=starts, chord_end=ends, chord_dir=direction, chord_len=length, end_margin=margin,
        end_gap=half_gap, two_sided=two, corner=corner, eigen_ratio=ratio, raw_count=n, order=order[:, :m],
        kept_count=kept_count,
        velocity=vel_out,
    )


def _prepare_numpy(arrays: list[np.ndarray], vel_out: list[np.ndarray | None], config: MeasurementConfig) -> _Prepared:
    n = np.array([len(a) for a in arrays])
    count, width = len(arrays), int(n.max())
    rows = np.arange(count)
    valid = np.arange(width)[None, :] < n[:, None]
    raw = np.zeros((count, width, 2))
    raw[valid] = np.concatenate(arrays)
    # centroid, scatter, bearing order
    _, centroid, sxx, syy, sxy = _masked_scatter(raw, valid)
    cx, cy = centroid[:, 0], centroid[:, 1]
    ref = np.where(np.hypot(cx, cy) > 1e-9, np.arctan2(cy, cx), 0.0)
    rel = np.arctan2(raw[..., 1], raw[..., 0]) - ref[:, None]
    rel -= 2.0 * np.pi * np.round(rel / (2.0 * np.pi))
    rel = np.where(valid, rel, np.inf)
    order = np.argsort(rel, axis=1, kind="stable")
    pts = np.take_along_axis(raw, order[..., None], axis=1)
    rel = np.take_along_axis(rel, order, axis=1)
    # one or two sides
    root = np.sqrt(0.25 * (sxx - syy) ** 2 + sxy**2)
    lam_min, lam_max = 0.5 * (sxx + syy) - root, 0.5 * (sxx + syy) + root
    ratio = np.where(lam_min > 1e-15 * np.maximum(lam_max, 1e-300), lam_max / np.where(lam_min > 0, lam_min, 1.0), np.inf)
    ratio = np.where(n >= 2, ratio, np.inf)
    two = (n >= config.min_points_two_sided) & (ratio < config.two_side_eigen_ratio)
    k = np.full(count, -1)
    if two.any():
        k[two] = _corner_indices(pts[two], n[two])
    # downsampling: the kept points of the sorted cluster (the corner in both parts)
    bound = config.max_cluster_points
    keep = valid.copy()
    big = n > bound
    big_two, big_one = np.flatnonzero(big & two), np.flatnonzero(big & ~two)
    if len(big_two) or len(big_one):
        keep[big] = False
        kt, nt = k[big_two], n[big_two]
        m0 = np.minimum(np.maximum(2, np.round(bound * (kt + 1) / (nt + 1)).astype(int)), bound - 1)
        _even_mask(keep, big_two, np.zeros_like(kt), kt, m0)
        _even_mask(keep, big_two, kt, nt - 1, bound + 1 - m0)
        _even_mask(keep, big_one, np.zeros_like(big_one), n[big_one] - 1, np.full(len(big_one), bound))
    # chords from all the points: slot 0 whole, slot 1 = 0..k, slot 2 = k..n-1 (two-sided)
    j = np.arange(width)[None, :]
    members = np.stack([valid, valid & ((j <= k[:, None]) | ~two[:, None]), valid & ((j >= k[:, None]) | ~two[:, None])], axis=1)
    cnt, origin, mxx, myy, mxy = _masked_scatter(pts[:, None], members)  # (K, 3)
    first = np.stack([np.zeros(count, int), np.zeros(count, int), np.where(two, k, 0)], axis=1)
    last = np.stack([n - 1, np.where(two, k, n - 1), n - 1], axis=1)
    p_first = pts[rows[:, None], first]  # (K, 3, 2)
    p_last = pts[rows[:, None], last]
    norm = np.maximum(np.hypot(cx, cy), 1e-12)
    fallback = np.stack([-cy / norm, cx / norm], axis=1)  # the line-of-sight normal
    phi = 0.5 * np.arctan2(2.0 * mxy, mxx - myy)
    u = np.stack([np.cos(phi), np.sin(phi)], axis=-1)
    u = np.where((np.einsum("ksd,ksd->ks", u, p_last - p_first) >= 0.0)[..., None], u, -u)
    flat = (cnt < 2) | (mxx + myy <= MIN_CHORD**2)
    direction = np.where(flat[..., None], fallback[:, None, :], u)
    along = np.einsum("ksnd,ksd->ksn", pts[:, None] - origin[:, :, None, :], direction)
    lo = np.where(members, along, np.inf).min(axis=2)
    hi = np.where(members, along, -np.inf).max(axis=2)
    if two.any():  # the corner: where the two fitted lines meet, if they meet near the corner point
        t = np.flatnonzero(two)
        o1, u1, o2, u2 = origin[t, 1], direction[t, 1], origin[t, 2], direction[t, 2]
        den = u1[:, 0] * u2[:, 1] - u1[:, 1] * u2[:, 0]
        ok = np.abs(den) >= np.sin(CORNER_MIN_ANGLE)
        w = o2 - o1
        a = (w[:, 0] * u2[:, 1] - w[:, 1] * u2[:, 0]) / np.where(ok, den, 1.0)
        x = o1 + a[:, None] * u1
        corner_pt = pts[t, k[t]]
        ok &= np.hypot(*(x - corner_pt).T) <= CORNER_MAX_SHIFT
        x = np.where(ok[:, None], x, corner_pt)
        h1 = np.einsum("kd,kd->k", x - o1, u1)
        l2 = np.einsum("kd,kd->k", x - o2, u2)
        hi[t, 1] = np.maximum(h1, lo[t, 1])
        lo[t, 2] = np.minimum(l2, hi[t, 2])
    starts = origin + lo[..., None] * direction
    ends = origin + hi[..., None] * direction
    length = hi - lo
    margin, half_gap = np.zeros((count, 3, 2)), np.zeros((count, 3, 2))
    if config.end_gap_correction:
        db = np.zeros(count)  # the median bearing step (the upper one of an even count, as np.partition)
        if width > 1:
            gaps = np.sort(np.where(j[:, 1:] < n[:, None], np.diff(np.where(valid, rel, 0.0), axis=1), np.inf), axis=1)
            db = np.where(n >= 2, gaps[rows, np.maximum(n - 1, 1) // 2], 0.0)  # a lone point has no gap
        dist = np.abs(origin[..., 0] * direction[..., 1] - origin[..., 1] * direction[..., 0])
        r2 = np.stack([(starts * starts).sum(axis=-1), (ends * ends).sum(axis=-1)], axis=-1)
        gap = r2 * db[:, None, None] / np.maximum(dist, 1e-3)[..., None]
        half_gap = np.where((n >= 2)[:, None, None], 0.5 * np.minimum(gap, MAX_END_GAP), 0.0)
        half_gap[two, 1, 1] = 0.0  # the corner of a split is observed
        half_gap[two, 2, 0] = 0.0
        margin = np.minimum(half_gap, 0.5 * length[..., None])
    # the kept points, compacted, with their part and chord coordinates
    kept_count = keep.sum(axis=1)
    pick = np.argsort(~keep, axis=1, kind="stable")[:, : int(kept_count.max())]  # kept indices first, in order
    corner = np.where(two, (keep & (j < k[:, None])).sum(axis=1), -1)  # index of the corner among the kept
    kpts = pts[rows[:, None], pick]
    part = (two[:, None] & (np.arange(pick.shape[1])[None, :] > corner[:, None])).astype(np.intp)
    slot = 1 + part
    proj0 = np.einsum("kmd,kd->km", kpts - starts[:, None, 0], direction[:, 0])
    proj1 = np.einsum("kmd,kmd->km", kpts - starts[rows[:, None], slot], direction[rows[:, None], slot])
    src = np.take_along_axis(order, pick, axis=1)
    kept = np.arange(pick.shape[1])[None, :] < kept_count[:, None]
    one = ~two  # one part: slots 1 and 2 repeat slot 0
    for a in (starts, ends, direction, length, margin, half_gap):
        a[one, 1:] = a[one, :1]
    return _Prepared(
        points=np.where(kept[..., None], kpts, 0.0), valid=kept, part=np.where(kept, part, 0),
        proj=np.where(kept[:, None, :], np.stack([proj0, proj1], axis=1), 0.0),
        chord_start=starts, chord_end=ends, chord_dir=direction, chord_len=length, end_margin=margin,
        end_gap=half_gap, two_sided=two, corner=corner, eigen_ratio=ratio, raw_count=n, order=src, kept_count=kept_count,
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
# Compiled cluster preparation: ``tracker.preparation._prepare_finite`` as one numba call.
#
# The numpy reference pads all clusters to the largest and runs ~150 array operations whatever their
# number; this kernel walks each cluster once (the same steps, in the same order, see the reference's
# module docstring): centroid and scatter, bearing sort (stable), one/two-sided from the eigenvalue
# ratio, the corner split from prefix sums, even downsampling (numpy's round half to even), the chords of
# slots 0, 1, 2, the fitted corner, the end-gap margins and the kept points' chord coordinates.
# --------------------------------------------------------------------------------------------------


@njit(inline="always")
def _lambda_min_scalar(sxx: float, syy: float, sxy: float) -> float:
    return 0.5 * (sxx + syy) - math.sqrt(0.25 * (sxx - syy) ** 2 + sxy * sxy)


@njit(inline="always")
def _residual(cnt: float, sx: float, sy: float, sxx: float, syy: float, sxy: float) -> float:
    cnt = max(cnt, 1.0)
    return max(_lambda_min_scalar(sxx - sx * sx / cnt, syy - sy * sy / cnt, sxy - sx * sy / cnt), 0.0)


@njit(inline="always")
def _even(keep: np.ndarray, lo: int, hi: int, count: int) -> None:
    count = max(count, 2)
    step = (hi - lo) / (count - 1)
    for j in range(count):
        pos = float(hi) if j == count - 1 else j * step + lo
        keep[int(np.rint(pos))] = True


@njit(inline="always")
def _mean_scatter(pts, j0, j1):
    """Centroid and biased scatter ``(cx, cy, sxx, syy, sxy)`` of ``pts[j0:j1 + 1]``."""
    cnt = j1 - j0 + 1
    cx = 0.0
    cy = 0.0
    for j in range(j0, j1 + 1):
        cx += pts[j, 0]
        cy += pts[j, 1]
    cx /= cnt
    cy /= cnt
    sxx = 0.0
    syy = 0.0
    sxy = 0.0
    for j in range(j0, j1 + 1):
        dx = pts[j, 0] - cx
        dy = pts[j, 1] - cy
        sxx += dx * dx
        syy += dy * dy
        sxy += dx * dy
    return cx, cy, sxx / cnt, syy / cnt, sxy / cnt


@njit(inline="always")
def _corner_split(pts: np.ndarray, n: int) -> int:
    cx, cy, _, _, _ = _mean_scatter(pts, 0, n - 1)
    c = np.zeros((n + 1, 6))
    for j in range(n):
        x = pts[j, 0] - cx
        y = pts[j, 1] - cy
        c[j + 1, 0] = c[j, 0] + 1.0
        c[j + 1, 1] = c[j, 1] + x
        c[j + 1, 2] = c[j, 2] + y
        c[j + 1, 3] = c[j, 3] + x * x
        c[j + 1, 4] = c[j, 4] + y * y
        c[j + 1, 5] = c[j, 5] + x * y
    best = np.inf
    k_best = 1
    for k in range(1, n - 1):
        head = _residual(c[k + 1, 0], c[k + 1, 1], c[k + 1, 2], c[k + 1, 3], c[k + 1, 4], c[k + 1, 5])
        tail = _residual(c[n, 0] - c[k, 0], c[n, 1] - c[k, 1], c[n, 2] - c[k, 2],
                         c[n, 3] - c[k, 3], c[n, 4] - c[k, 4], c[n, 5] - c[k, 5])
        if head + tail < best:
            best = head + tail
            k_best = k
    return k_best


@njit
def prepare_kernel(flat, offsets, bound, min_two, ratio_max, gap_correction, min_chord, sin_min_angle, max_shift,
                   max_end_gap):
    """Padded per-cluster arrays (``tracker.preparation._Prepared``'s fields, kept points padded to the
    largest possible count) of the clusters ``flat[offsets[i]:offsets[i + 1]]`` (finite, non-empty)."""
    count = len(offsets) - 1
    width = 0
    for i in range(count):
        width = max(width, min(offsets[i + 1] - offsets[i], bound + 2))
    points = np.zeros((count, width, 2))
    valid = np.zeros((count, width), dtype=np.bool_)
    part = np.zeros((count, width), dtype=np.intp)
    proj = np.zeros((count, 2, width))
    order_out = np.zeros((count, width), dtype=np.intp)
    chord_start = np.zeros((count, 3, 2))
    chord_end = np.zeros((count, 3, 2))
    chord_dir = np.zeros((count, 3, 2))
    chord_len = np.zeros((count, 3))
    end_margin = np.zeros((count, 3, 2))
    end_gap = np.zeros((count, 3, 2))
    two_sided = np.zeros(count, dtype=np.bool_)
    corner_out = np.full(count, -1, dtype=np.intp)
    eigen_ratio = np.zeros(count)
    kept_count = np.zeros(count, dtype=np.intp)
    for i in range(count):
        o = offsets[i]
        n = offsets[i + 1] - o
        raw = flat[o : o + n]
        cx, cy, sxx, syy, sxy = _mean_scatter(raw, 0, n - 1)  # centroid, biased scatter
        # bearing order about the centroid's bearing
        ref = math.atan2(cy, cx) if math.hypot(cx, cy) > 1e-9 else 0.0
        rel0 = np.empty(n)
        for j in range(n):
            a = math.atan2(raw[j, 1], raw[j, 0]) - ref
            rel0[j] = a - 2.0 * np.pi * np.rint(a / (2.0 * np.pi))
        order = np.argsort(rel0, kind="mergesort")
        pts = np.empty((n, 2))
        rel = np.empty(n)
        for j in range(n):
            pts[j, 0] = raw[order[j], 0]
            pts[j, 1] = raw[order[j], 1]
            rel[j] = rel0[order[j]]
        # one or two sides
        root = math.sqrt(0.25 * (sxx - syy) ** 2 + sxy * sxy)
        lam_min = 0.5 * (sxx + syy) - root
        lam_max = 0.5 * (sxx + syy) + root
        ratio = np.inf
        if n >= 2 and lam_min > 1e-15 * max(lam_max, 1e-300):
            ratio = lam_max / lam_min
        two = n >= min_two and ratio < ratio_max
        k = _corner_split(pts, n) if two else -1
        # downsampling
        keep = np.zeros(n, dtype=np.bool_)
        if n > bound:
            if two:
                m0 = min(max(2, int(np.rint(bound * (k + 1) / (n + 1)))), bound - 1)
                _even(keep, 0, k, m0)
                _even(keep, k, n - 1, bound + 1 - m0)
            else:
                _even(keep, 0, n - 1, bound)
        else:
            keep[:] = True
        # chords: slot 0 all points, slot 1 = 0..k, slot 2 = k..n-1 (two-sided)
        norm = max(math.hypot(cx, cy), 1e-12)
        origin = np.zeros((3, 2))
        direction = np.zeros((3, 2))
        lo = np.zeros(3)
        hi = np.zeros(3)
        for s in range(3):
            j0 = 0
            j1 = n - 1
            if two and s == 1:
                j1 = k
            if two and s == 2:
                j0 = k
            cnt = j1 - j0 + 1
            ox, oy, mxx, myy, mxy = _mean_scatter(pts, j0, j1)
            if cnt < 2 or mxx + myy <= min_chord * min_chord:
                ux = -cy / norm
                uy = cx / norm
            else:
                phi = 0.5 * math.atan2(2.0 * mxy, mxx - myy)
                ux = math.cos(phi)
                uy = math.sin(phi)
                if ux * (pts[j1, 0] - pts[j0, 0]) + uy * (pts[j1, 1] - pts[j0, 1]) < 0.0:
                    ux = -ux
                    uy = -uy
            low = np.inf
            high = -np.inf
            for j in range(j0, j1 + 1):
                t = (pts[j, 0] - ox) * ux + (pts[j, 1] - oy) * uy
                low = min(low, t)
                high = max(high, t)
            origin[s, 0] = ox
            origin[s, 1] = oy
            direction[s, 0] = ux
            direction[s, 1] = uy
            lo[s] = low
            hi[s] = high
        if two:  # the corner: where the two fitted lines meet, if they meet near the corner point
            u1x, u1y, u2x, u2y = direction[1, 0], direction[1, 1], direction[2, 0], direction[2, 1]
            den = u1x * u2y - u1y * u2x
            ok = abs(den) >= sin_min_angle
            wx = origin[2, 0] - origin[1, 0]
            wy = origin[2, 1] - origin[1, 1]
            a = (wx * u2y - wy * u2x) / (den if ok else 1.0)
            xx = origin[1, 0] + a * u1x
            xy = origin[1, 1] + a * u1y
            ok = ok and math.hypot(xx - pts[k, 0], xy - pts[k, 1]) <= max_shift
            if not ok:
                xx = pts[k, 0]
                xy = pts[k, 1]
            h1 = (xx - origin[1, 0]) * u1x + (xy - origin[1, 1]) * u1y
            l2 = (xx - origin[2, 0]) * u2x + (xy - origin[2, 1]) * u2y
            hi[1] = max(h1, lo[1])
            lo[2] = min(l2, hi[2])
        starts = np.empty((3, 2))
        ends = np.empty((3, 2))
        length = np.empty(3)
        for s in range(3):
            for d in range(2):
                starts[s, d] = origin[s, d] + lo[s] * direction[s, d]
                ends[s, d] = origin[s, d] + hi[s] * direction[s, d]
            length[s] = hi[s] - lo[s]
        margin = np.zeros((3, 2))
        half_gap = np.zeros((3, 2))
        if gap_correction and n >= 2:
            gaps = rel[1:] - rel[:-1]
            gaps = gaps[np.argsort(gaps, kind="mergesort")]  # numpy.sort's values
            db = gaps[(n - 1) // 2]
            for s in range(3):
                dist = abs(origin[s, 0] * direction[s, 1] - origin[s, 1] * direction[s, 0])
                r2s = starts[s, 0] * starts[s, 0] + starts[s, 1] * starts[s, 1]
                r2e = ends[s, 0] * ends[s, 0] + ends[s, 1] * ends[s, 1]
                half_gap[s, 0] = 0.5 * min(r2s * db / max(dist, 1e-3), max_end_gap)
                half_gap[s, 1] = 0.5 * min(r2e * db / max(dist, 1e-3), max_end_gap)
                margin[s, 0] = min(half_gap[s, 0], 0.5 * length[s])
                margin[s, 1] = min(half_gap[s, 1], 0.5 * length[s])
            if two:
                margin[1, 1] = 0.0  # the corner of a split is observed
                margin[2, 0] = 0.0
                half_gap[1, 1] = 0.0
                half_gap[2, 0] = 0.0
        # the kept points, compacted, with their part and chord coordinates
        corner = -1
        if two:
            corner = 0
            for j in range(k):
                if keep[j]:
                    corner += 1
        m = 0
        for j in range(n):
            if not keep[j]:
                continue
            points[i, m, 0] = pts[j, 0]
            points[i, m, 1] = pts[j, 1]
            valid[i, m] = True
            p = 1 if (two and m > corner) else 0
            part[i, m] = p
            proj[i, 0, m] = (pts[j, 0] - starts[0, 0]) * direction[0, 0] + (pts[j, 1] - starts[0, 1]) * direction[0, 1]
            proj[i, 1, m] = ((pts[j, 0] - starts[1 + p, 0]) * direction[1 + p, 0]
                             + (pts[j, 1] - starts[1 + p, 1]) * direction[1 + p, 1])
            order_out[i, m] = order[j]
            m += 1
        for s in range(3):
            src = s if two else 0  # one part: slots 1 and 2 repeat slot 0
            for d in range(2):
                chord_start[i, s, d] = starts[src, d]
                chord_end[i, s, d] = ends[src, d]
                chord_dir[i, s, d] = direction[src, d]
                end_margin[i, s, d] = margin[src, d]
                end_gap[i, s, d] = half_gap[src, d]
            chord_len[i, s] = length[src]
        two_sided[i] = two
        corner_out[i] = corner
        eigen_ratio[i] = ratio
        kept_count[i] = m
    return (points, valid, part, proj, chord_start, chord_end, chord_dir, chord_len, end_margin, end_gap, two_sided,
            corner_out, eigen_ratio, order_out, kept_count)


@njit
def scanned_batch_kernel(flat, offsets, bound, min_two, ratio_max, gap_correction, min_chord, sin_min_angle, max_shift,
                         max_end_gap, scan, shadows, window, margin, max_range, range_margin, continuation, rays,
                         offset):  # pragma: no cover - compiled
    """``prepare_kernel``'s arrays cut to the most points kept (``tracker.preparation._prepare_compiled``),
    whether each cluster's chord is a single point, and the shadow flags of the clusters' ends in
    ``scan`` (``shadows``: ``occluded_ends`` of the bearing ends with ``window``, ``margin``,
    ``max_range``, ``range_margin``; ``continuation``: ``continued_ends`` of the side ends with
    ``rays`` ray gaps and ``offset``), all False where a flag is off (the caller leaves it out).
    Returns ``(points, valid, part, proj, chord_start, chord_end, chord_dir, chord_len, end_margin,
    end_gap, two_sided, single, kept_count, occluded, continued)``."""
    (points, valid, part, proj, starts, ends, direction, length, margin_out, half_gap, two, _corner, _ratio, _order,
     kept_count) = prepare_kernel(flat, offsets, bound, min_two, ratio_max, gap_correction, min_chord, sin_min_angle,
                                  max_shift, max_end_gap)
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
