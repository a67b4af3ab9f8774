"""Figures of a run (``Result``): GOSPA and cardinality over time, a bird's-eye view, per-target yaw,
speed and extent over time, and an animated GIF that follows the ego.

Figures are drawn on matplotlib's Agg canvas directly (``matplotlib.figure.Figure`` +
``FigureCanvasAgg``), never through pyplot, so they work on headless machines and do not change the
backend of an interactive session.

**Colours** are the same in every figure (and in ``events.png`` of ``sim.evaluation.inspect``): one colour per
true vehicle, ``vehicle_color(id)`` (``VEHICLE_COLORS``, cycled by id); a track takes the colour of
the vehicle GOSPA assigns it to in that frame (``FrameRecord.track_truth_id``), and a track assigned
to none (a false track) is grey (``UNMATCHED_COLOR``); the ego is black. Track labels are written as
numbers next to the tracks. Lidar points are green and radar detections red (no vehicle has those
colours).

- ``gospa.png``: GOSPA (m) over time, its parts (p-th-power sums, m^2: localisation, missed, false,
  stacked) and the cardinality (true count of the scored truth set vs estimated count) -- the paper's
  simulation figure;
- ``gospa_visible.png``: the same scored against the visible vehicles only;
- ``birdseye.png``: the paths over the run (ego, each vehicle while scored, the track centres), the
  axes fitted to them, and below three snapshots around the ego with the vehicles' and tracks'
  rectangles; each snapshot's title counts what it shows;
- ``targets.png``: yaw (deg), speed (m/s), length and width (m) over time per truth vehicle (lines)
  with the estimates of the tracks assigned to it by GOSPA (dots);
- ``cloud.png`` (runs with the 3-D lidar, ``sensors.lidar.model = "vlp16"``): the paper's Fig. 2 for
  one frame: the raw cloud, the cloud without the ground (and above the height ceiling), and the 2-D
  points projected onto the road plane, with the truth rectangles (``plot_cloud_pipeline``);
- ``run.gif`` (``gif=True``): the run seen from above, following the ego: road, lidar points, radar
  detections with velocity arrows, vehicle outlines, track rectangles with labels (Pillow, which
  comes with matplotlib).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection, PolyCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from sim.evaluation.records import FrameRecord
from sim.evaluation.runner import Result
from sim.world.truth import rectangle_corners
from tracker.transforms import rotate, to_global

#: Colours of the true vehicles, cycled by vehicle id (``vehicle_color``): tab10 without its green,
#: red and grey (the lidar, the radar and unmatched tracks), and three darker ones from tab20b.
VEHICLE_COLORS = ("#1f77b4", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#bcbd22", "#17becf", "#393b79", "#7b4173",
                  "#e7ba52")
#: Colour of a track that GOSPA assigns to no vehicle (a false track).
UNMATCHED_COLOR = "#7f7f7f"
#: Colours of the lidar points and the radar detections.
LIDAR_COLOR = "#2ca02c"
RADAR_COLOR = "#d62728"


def vehicle_color(vehicle_id: int) -> str:
    """The colour of the true vehicle ``vehicle_id`` (``VEHICLE_COLORS``, cycled)."""
    return VEHICLE_COLORS[int(vehicle_id) % len(VEHICLE_COLORS)]


def track_colors(f: FrameRecord) -> list[str]:
    """The colours of the frame's tracks: their GOSPA-assigned vehicle's, grey when unassigned."""
    return [vehicle_color(v) if v >= 0 else UNMATCHED_COLOR for v in np.asarray(f.track_truth_id, dtype=int)]


def _figure(width: float, height: float, dpi: int = 110) -> Figure:
    fig = Figure(figsize=(width, height), dpi=dpi)
    FigureCanvasAgg(fig)
    return fig


def _save(fig: Figure, path: Path) -> Path:
    fig.savefig(path)
    return path


def _title(result: Result) -> str:
    return f"{result.spec.name} / {result.variant} / seed {result.seed}"


# -- GOSPA and cardinality ------------------------------------------------------------------------
def plot_gospa(result: Result, path: str | Path, *, visible: bool = False) -> Path:
    """``gospa_figure(result, visible=visible)`` written to ``path`` (PNG)."""
    return _save(gospa_figure(result, visible=visible), Path(path))


def gospa_figure(result: Result, *, visible: bool = False) -> Figure:
    """GOSPA, its parts and the cardinality over time (scored truth set, or visible-only with
    ``visible=True``)."""
    frames = result.frames
    t = result.times
    g = [f.gospa_visible if visible else f.gospa for f in frames]
    total = np.array([x.gospa for x in g])
    loc = np.array([x.localization for x in g])
    missed = np.array([x.missed for x in g])
    false = np.array([x.false for x in g])
    n_true = np.array([f.n_visible if visible else f.n_truth for f in frames])
    n_est = np.array([f.n_tracks_scored for f in frames])
    c, p = result.settings.get("gospa_c", 5.0), result.settings.get("gospa_p", 2.0)
    fig = _figure(9.5, 7.5)
    ax1, ax2, ax3 = fig.subplots(3, 1, sharex=True)
    which = "the visible vehicles only" if visible else "the vehicles in lidar range on the road (occluded included)"
    fig.suptitle(f"{_title(result)}: scored against {which}", fontsize=10)
    legend = dict(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    ax1.plot(t, total, color="k", lw=1.5, label="GOSPA")
    ax1.set_ylabel("GOSPA (m)")
    ax1.set_ylim(bottom=0.0)
    ax1.grid(alpha=0.3)
    ax1.set_title(f"GOSPA (alpha = 2, p = {p:g}, c = {c:g} m), mean {np.mean(total):.2f} m" if len(t) else "GOSPA",
                  fontsize=9)
    ax2.stackplot(t, loc, missed, false, labels=["localisation", "missed", "false"],
                  colors=["#1f77b4", "#d62728", "#ff7f0e"], alpha=0.8)
    ax2.set_ylabel(f"GOSPA^{p:g} parts (m^{p:g})")
    ax2.set_ylim(bottom=0.0)
    ax2.set_title(f"GOSPA parts as p-th-power sums, stacked (they add up to GOSPA^{p:g})", fontsize=9)
    ax2.legend(**legend)
    ax2.grid(alpha=0.3)
    ax3.step(t, n_true, where="post", color="k", lw=1.5, label="true")
    ax3.step(t, n_est, where="post", color="#1f77b4", lw=1.2, ls="--", label="estimated\n(tracks)")
    ax3.set_ylabel("count (vehicles)")
    ax3.set_xlabel("t (s)")
    ax3.set_title("cardinality: number of true vehicles and of tracks", fontsize=9)
    ax3.set_ylim(-0.2, max(int(np.max(n_true, initial=0)), int(np.max(n_est, initial=0))) + 1.2)
    ax3.yaxis.get_major_locator().set_params(integer=True)
    ax3.legend(**legend)
    ax3.grid(alpha=0.3)
    if len(t):
        ax3.set_xlim(float(t[0]), float(t[-1]) if len(t) > 1 else float(t[0]) + 0.1)
    fig.tight_layout()
    return fig


# -- bird's-eye view ------------------------------------------------------------------------------
def _road_lines(result: Result, s_low: float, s_high: float, step: float = 1.0) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Edges (solid) and lane lines (dashed) as (K, 2) polylines over ``[s_low, s_high]``."""
    road = result.road
    if road.closed:
        s = np.linspace(0.0, road.length, max(2, int(road.length / step) + 1))
    else:
        s_low, s_high = max(0.0, s_low), min(road.length, s_high)
        s = np.linspace(s_low, s_high, max(2, int((s_high - s_low) / step) + 1))
    right, left = road.edges(s)
    edges = [road.to_cartesian(s, right), road.to_cartesian(s, left)]
    return edges, [xy for _, xy in _lane_lines(road, s, right, left)]


def _lane_lines(road, s: np.ndarray, right: np.ndarray, left: np.ndarray) -> list[tuple[int, np.ndarray]]:  # noqa: ANN001
    """The inner lane boundaries ``k`` of ``road`` at arc lengths ``s`` as polylines (K, 2) in G, NaN (a gap
    in the line) where a boundary does not lie inside the edges ``right``, ``left`` (m) at ``s``."""
    bounds = road.layout.boundaries_at(road.wrap_s(s))  # (K, lanes + 1)
    lines = []
    for k in range(1, road.lanes):
        inside = (bounds[:, k] > right + 0.05) & (bounds[:, k] < left - 0.05)
        if inside.any():
            lines.append((k, road.to_cartesian(s, bounds[:, k]) + np.where(inside, 0.0, np.nan)[:, None]))
    return lines


def _draw_road(ax, edges: list[np.ndarray], lanes: list[np.ndarray]) -> None:  # noqa: ANN001
    for e in edges:
        ax.plot(e[:, 0], e[:, 1], color="0.35", lw=1.0)
    for lane in lanes:
        ax.plot(lane[:, 0], lane[:, 1], color="0.6", lw=0.6, ls=(0, (6, 6)))


def _track_rectangles(f: FrameRecord) -> np.ndarray:
    st = f.track_state
    if len(st) == 0:
        return np.zeros((0, 4, 2))
    return rectangle_corners(st[:, :2], st[:, 3], st[:, 5], st[:, 6])


def _ego_xy(result: Result) -> np.ndarray:
    return np.array([[f.truth.ego.x, f.truth.ego.y] for f in result.frames]).reshape(-1, 2)


def _in_view(corners: np.ndarray, center: tuple[float, float], half: float) -> np.ndarray:
    """Which rectangles ``corners (K, 4, 2)`` have a corner inside the square view of half-width
    ``half`` (m) around ``center``: the ones a panel of that view shows."""
    if len(corners) == 0:
        return np.zeros(0, dtype=bool)
    d = np.abs(np.asarray(corners) - np.asarray(center, dtype=float))
    return np.any(np.all(d <= half, axis=-1), axis=-1)


def _view_counts(f: FrameRecord, center: tuple[float, float], half: float) -> str:
    """What a view of ``f`` shows: vehicles (ego excluded; how many not scored) and tracks (how many
    assigned to no vehicle)."""
    seen = _in_view(f.truth.corners(), center, half)
    shown = _in_view(_track_rectangles(f), center, half)
    vehicles = int(seen.sum())
    unscored = int((seen & ~np.asarray(f.scored, dtype=bool)).sum())
    tracks = int(shown.sum())
    unmatched = int((shown & (np.asarray(f.track_truth_id) < 0)).sum())
    text = _count(vehicles, "vehicle") + (f" ({unscored} not scored)" if unscored else "")
    text += ", " + _count(tracks, "track") + (f" ({unmatched} unmatched)" if unmatched else "")
    return text + " in view"


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}{'' if n == 1 else 's'}"


def _data_limits(points: np.ndarray, *, margin_fraction: float = 0.04, min_margin: float = 5.0,
                 min_extent: float = 20.0) -> tuple[tuple[float, float], tuple[float, float]]:
    """Axis limits ``(x_lo, x_hi), (y_lo, y_hi)`` (m) around the finite ``points (K, 2)``: their
    bounding box plus ``max(min_margin, margin_fraction * largest side)`` on each side, each side
    at least ``min_extent`` (centred)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if len(pts) == 0:
        return (-min_extent / 2, min_extent / 2), (-min_extent / 2, min_extent / 2)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    margin = max(min_margin, margin_fraction * float(np.max(hi - lo)))
    lo, hi = lo - margin, hi + margin
    grow = np.maximum(min_extent - (hi - lo), 0.0) / 2
    lo, hi = lo - grow, hi + grow
    return (float(lo[0]), float(hi[0])), (float(lo[1]), float(hi[1]))


def _snapshot_legend_handles() -> list:
    return [
        Patch(facecolor="k", alpha=0.7, label="ego"),
        Patch(facecolor="none", edgecolor=VEHICLE_COLORS[0], lw=1.4, label="vehicle (outline in its colour)"),
        Patch(facecolor="none", edgecolor=VEHICLE_COLORS[0], lw=1.0, ls="--", label="vehicle not scored"),
        Patch(facecolor=VEHICLE_COLORS[0], edgecolor=VEHICLE_COLORS[0], alpha=0.4,
              label="track (its vehicle's colour; number = track label)"),
        Patch(facecolor=UNMATCHED_COLOR, edgecolor=UNMATCHED_COLOR, alpha=0.4, label="unmatched track"),
    ]


def plot_birdseye(result: Result, path: str | Path, *, snapshots: int = 3, half_window: float = 45.0) -> Path:
    """``birdseye_figure`` written to ``path`` (PNG)."""
    return _save(birdseye_figure(result, snapshots=snapshots, half_window=half_window), Path(path))


def birdseye_figure(result: Result, *, snapshots: int = 3, half_window: float = 45.0) -> Figure:
    """Bird's-eye view: the paths over the run (ego, each vehicle while scored, the track centres in
    their vehicle's colour, grey when unmatched) on the road, the axes fitted to them (equal scale),
    and below ``snapshots`` views (``half_window`` m around the ego) with the vehicles' and tracks'
    rectangles, each titled with the counts of what it shows."""
    frames = result.frames
    ego = _ego_xy(result)
    ego_s = np.array([f.ego_s for f in frames])
    road = result.road
    # the data: the ego's path, each vehicle's centre while scored, the track centres
    ids = sorted({int(i) for f in frames for i, sc in zip(f.truth.ids, f.scored) if sc})
    paths = {vid: np.full((len(frames), 2), np.nan) for vid in ids}
    for k, f in enumerate(frames):
        for row, (vid, sc) in enumerate(zip(f.truth.ids, f.scored)):
            if sc:
                paths[int(vid)][k] = f.truth.xy[row]
    track_xy = np.concatenate([f.track_state[:, :2] for f in frames], axis=0) if frames else np.zeros((0, 2))
    track_vid = np.concatenate([np.asarray(f.track_truth_id, dtype=int) for f in frames]) if frames else np.zeros(0, int)
    labels = {int(tr.label) for f in frames for tr in f.tracks}
    (x_lo, x_hi), (y_lo, y_hi) = _data_limits(np.concatenate([ego, *paths.values(), track_xy], axis=0))
    # the overview's height follows the data's aspect (equal scale), within 1.2-6 in; its legend gets
    # the top row's right sixth
    top_h = float(np.clip(8.0 * (y_hi - y_lo) / (x_hi - x_lo), 1.2, 6.0))
    fig = _figure(11.0, top_h + 5.0)
    gs = fig.add_gridspec(2, max(1, snapshots), height_ratios=[top_h, 3.6])
    ax = fig.add_subplot(gs[0, :].subgridspec(1, 2, width_ratios=[5.0, 1.0], wspace=0.0)[0])
    margin = 110.0
    s_low = float(ego_s.min()) - margin if len(ego_s) else 0.0
    s_high = float(ego_s.max()) + margin if len(ego_s) else road.length
    if road.closed and len(ego_s) and float(np.ptp(ego_s)) > 0.5 * road.length:
        s_low, s_high = 0.0, road.length
    edges, lanes = _road_lines(result, s_low, s_high)
    _draw_road(ax, edges, lanes)
    handles: list = [Line2D([], [], color="k", lw=2.0, ls="--", label="ego")]
    for vid in ids:
        color = vehicle_color(vid)
        ax.plot(paths[vid][:, 0], paths[vid][:, 1], color=color, lw=3.0, alpha=0.35, solid_capstyle="round")
        mine = track_vid == vid
        ax.plot(track_xy[mine, 0], track_xy[mine, 1], ".", ms=2.5, color=color)
        handles.append(Line2D([], [], color=color, lw=3.0, alpha=0.6, marker=".", ms=7, mfc=color, mec=color,
                              label=f"vehicle {vid}"))
    unmatched = track_vid < 0
    if unmatched.any():
        ax.plot(track_xy[unmatched, 0], track_xy[unmatched, 1], "x", ms=3.0, mew=0.8, color=UNMATCHED_COLOR)
        handles.append(Line2D([], [], ls="none", marker="x", color=UNMATCHED_COLOR, label="unmatched track"))
    ax.plot(ego[:, 0], ego[:, 1], color="k", lw=2.0, ls="--")
    ax.set_xlim(x_lo, x_hi)
    ax.set_ylim(y_lo, y_hi)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False,
              ncol=1 + (len(handles) - 1) // 18, title="line: vehicle while scored\ndots: its tracks' centres",
              title_fontsize=7.5)
    duration = float(frames[-1].t - frames[0].t) if frames else 0.0
    ax.set_title(f"{_title(result)}: paths over {duration:.1f} s ({len(frames)} frames), "
                 f"{_count(len(ids), 'scored vehicle')}, {_count(len(labels), 'track label')}", fontsize=10)
    ax.grid(alpha=0.2)
    if frames:
        picks = np.unique(np.linspace(0, len(frames) - 1, snapshots + 2)[1:-1].round().astype(int))
        for j, k in enumerate(picks):
            f = frames[int(k)]
            sax = fig.add_subplot(gs[1, j])
            e = f.truth.ego
            es = f.ego_s
            sub_edges, sub_lanes = _road_lines(result, es - 1.5 * half_window, es + 1.5 * half_window)
            _draw_road(sax, sub_edges, sub_lanes)
            _draw_rectangles(sax, f)
            sax.set_xlim(e.x - half_window, e.x + half_window)
            sax.set_ylim(e.y - half_window, e.y + half_window)
            sax.set_aspect("equal")
            sax.set_title(f"t = {f.t:.1f} s: {_view_counts(f, (e.x, e.y), half_window)}", fontsize=8.5)
            sax.set_xlabel("x (m)", fontsize=8)
            sax.set_ylabel("y (m)", fontsize=8)
            sax.tick_params(labelsize=7)
        fig.legend(handles=_snapshot_legend_handles(), loc="lower center", ncol=5, fontsize=7.5, frameon=False)
    fig.tight_layout(rect=(0.0, 0.035 if frames else 0.0, 1.0, 1.0))
    return fig


def _draw_rectangles(ax, f: FrameRecord, *, labels: bool = True) -> None:  # noqa: ANN001
    """The ego (black), the vehicles' outlines in their colours (dashed: not scored) and the tracks
    filled in their vehicle's colour (grey: unmatched), with their labels."""
    e = f.truth.ego
    ego_c = rectangle_corners(np.array([[e.x, e.y]]), np.array([e.yaw]), np.array([e.length]), np.array([e.width]))
    ax.add_collection(PolyCollection(ego_c, facecolors="k", edgecolors="k", alpha=0.7))
    truth_c = f.truth.corners()
    if len(truth_c):
        ax.add_collection(PolyCollection(truth_c, facecolors="none", edgecolors=[vehicle_color(i) for i in f.truth.ids],
                                         linestyles=["-" if sc else "--" for sc in f.scored],
                                         linewidths=[1.4 if sc else 1.0 for sc in f.scored]))
    tr_c = _track_rectangles(f)
    if len(tr_c):
        colors = track_colors(f)
        ax.add_collection(PolyCollection(tr_c, facecolors=colors, edgecolors=colors, alpha=0.4, linewidths=1.0))
        if labels:
            for k, tr in enumerate(f.tracks):
                ax.text(f.track_state[k, 0], f.track_state[k, 1] + 2.2, str(tr.label), color=colors[k], fontsize=7,
                        ha="center", va="bottom", clip_on=True)


# -- per-target yaw, speed and extent -------------------------------------------------------------
def plot_targets(result: Result, path: str | Path) -> Path:
    """``targets_figure(result)`` written to ``path`` (PNG)."""
    return _save(targets_figure(result), Path(path))


def targets_figure(result: Result) -> Figure:
    """Yaw, speed, length and width over time per truth vehicle (lines, while scored) and the
    estimates of the tracks GOSPA assigns to it (dots, same colour)."""
    frames = result.frames
    ids = sorted({int(i) for f in frames for i, s in zip(f.truth.ids, f.scored) if s})
    quantities = [("yaw (deg)", 3, 180.0 / math.pi), ("speed (m/s)", 2, 1.0), ("length (m)", 5, 1.0), ("width (m)", 6, 1.0)]
    fig = _figure(10.0, 9.0)
    axes = fig.subplots(len(quantities), 1, sharex=True)
    handles = []
    for vid in ids:
        color = vehicle_color(vid)
        t_true, v_true, t_est, v_est = [], [], [], []
        for f in frames:
            rows = np.flatnonzero(f.truth.ids == vid)
            if rows.size == 0 or not f.scored[rows[0]]:
                t_true.append(f.t)
                v_true.append(np.full(7, np.nan))
                continue
            t_true.append(f.t)
            v_true.append(f.truth_state[rows[0]])
            for k in np.flatnonzero(f.track_truth_id == vid):
                t_est.append(f.t)
                v_est.append(f.track_state[k])
        vt = np.array(v_true).reshape(-1, 7)
        ve = np.array(v_est).reshape(-1, 7)
        for ax, (_, col, scale) in zip(axes, quantities):
            y = vt[:, col] * scale
            if col == 3:
                y = np.degrees(np.unwrap(np.nan_to_num(vt[:, col]))) * np.where(np.isnan(vt[:, col]), np.nan, 1.0)
            ax.plot(t_true, y, color=color, lw=1.4)
            if len(ve):
                ye = ve[:, col] * scale
                if col == 3:  # put estimates on the truth's unwrapped branch
                    ref = np.interp(t_est, np.asarray(t_true)[~np.isnan(y)], y[~np.isnan(y)])
                    ye = ref + np.degrees(np.angle(np.exp(1j * (np.radians(ye) - np.radians(ref)))))
                ax.plot(t_est, ye, ".", ms=2.5, color=color)
        handles.append(Line2D([], [], color=color, lw=1.4, marker=".", ms=6, label=f"vehicle {vid}"))
    for ax, (name, _, _) in zip(axes, quantities):
        ax.set_ylabel(name)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("t (s)")
    if frames:
        axes[-1].set_xlim(frames[0].t, max(frames[-1].t, frames[0].t + 0.1))
    if ids:
        axes[0].legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False,
                       ncol=1 + (len(handles) - 1) // 20)
    else:
        axes[0].text(0.5, 0.5, "no vehicle was scored", transform=axes[0].transAxes, ha="center", va="center")
    axes[0].set_title(f"{_title(result)}: each vehicle's truth while scored (line) and the estimates of the tracks "
                      "GOSPA assigns to it (dots)", fontsize=9)
    fig.tight_layout()
    return fig


# -- animated GIF ---------------------------------------------------------------------------------
def write_gif(
    result: Result,
    path: str | Path,
    *,
    half_window: float = 55.0,
    stride: int = 2,
    dpi: int = 80,
    progress: Callable[[int, int], None] | None = None,
) -> Path:
    """An animated GIF of the run (every ``stride``-th frame, real-time playback speed), the view
    following the ego (``half_window`` m each way, north up): road, lidar points, radar detections
    with 0.5 s velocity arrows, the vehicles' outlines (their colours; dashed: not scored), the ego
    (black) and track rectangles (their vehicle's colour, grey when unmatched) with labels; the title
    counts what the view shows. ``progress(done, total)`` after each frame. Needs
    ``run_scenario(..., keep_sensor_data=True)``."""
    from PIL import Image

    frames = result.frames[:: max(1, int(stride))]
    if not frames:
        raise ValueError("write_gif: the result has no frames")
    if frames[0].frame is None:
        raise ValueError("write_gif needs the sensor data: run with run_scenario(..., keep_sensor_data=True)")
    fig = _figure(7.0, 7.6, dpi=dpi)
    ax = fig.add_axes((0.11, 0.14, 0.86, 0.8))
    edges, lanes = _road_lines(result, -1e9, 1e9, step=2.0)
    _draw_road(ax, edges, lanes)
    ax.set_aspect("equal")
    ax.tick_params(labelsize=7)
    ax.set_xlabel("x (m)", fontsize=8)
    ax.set_ylabel("y (m)", fontsize=8)
    lidar = ax.scatter([], [], s=1.5, c=LIDAR_COLOR, label="lidar", zorder=7)
    radar = ax.scatter([], [], s=18.0, marker="x", c=RADAR_COLOR, label="radar", zorder=4)
    arrows = LineCollection([], colors=RADAR_COLOR, linewidths=1.0, zorder=4)
    ax.add_collection(arrows)
    ego_poly = PolyCollection([], facecolors="k", edgecolors="k", alpha=0.75, zorder=5)
    truth_poly = PolyCollection([], facecolors="none", linewidths=1.3, zorder=5)
    track_poly = PolyCollection([], alpha=0.45, linewidths=1.0, zorder=6)
    for coll in (ego_poly, truth_poly, track_poly):
        ax.add_collection(coll)
    proxies = [
        Line2D([], [], ls="none", marker=".", color=LIDAR_COLOR, label="lidar"),
        Line2D([], [], ls="none", marker="x", color=RADAR_COLOR, label="radar (0.5 s arrow)"),
        Patch(facecolor="k", alpha=0.75, label="ego"),
        Patch(facecolor="none", edgecolor=VEHICLE_COLORS[0], label="vehicle (its colour)"),
        Patch(facecolor=VEHICLE_COLORS[0], alpha=0.45, label="track (its vehicle's colour, label)"),
        Patch(facecolor=UNMATCHED_COLOR, alpha=0.45, label="unmatched track"),
    ]  # fmt: skip
    fig.legend(handles=proxies, loc="lower center", ncol=3, fontsize=8, frameon=False)
    title = ax.set_title("", fontsize=8.5)
    texts: list = []
    frame_dt = (frames[1].t - frames[0].t) if len(frames) > 1 else 0.1

    def update(i: int) -> list:
        f = frames[i]
        e = f.truth.ego
        pose = ((e.x, e.y), e.yaw)
        pts = to_global(_lidar_xy(f.frame, result.config), *pose).reshape(-1, 2) if f.frame is not None else np.zeros((0, 2))
        lidar.set_offsets(pts)
        if f.frame is not None and len(f.frame.radar):
            rxy = to_global(f.frame.radar.xy, *pose).reshape(-1, 2)
            rv = rotate(f.frame.radar.velocity, e.yaw).reshape(-1, 2)
            radar.set_offsets(rxy)
            arrows.set_segments(np.stack([rxy, rxy + 0.5 * rv], axis=1))
        else:
            radar.set_offsets(np.zeros((0, 2)))
            arrows.set_segments([])
        ego_poly.set_verts(rectangle_corners(np.array([[e.x, e.y]]), np.array([e.yaw]), np.array([e.length]),
                                             np.array([e.width])))
        truth_poly.set_verts(f.truth.corners())
        truth_poly.set_edgecolors([vehicle_color(v) for v in f.truth.ids])
        truth_poly.set_linestyles(["-" if sc else "--" for sc in f.scored])
        tr_c = _track_rectangles(f)
        colors = track_colors(f)
        track_poly.set_verts(tr_c)
        track_poly.set_facecolors(colors)
        track_poly.set_edgecolors(colors)
        for txt in texts:
            txt.remove()
        texts.clear()
        for k, tr in enumerate(f.tracks):
            texts.append(ax.text(f.track_state[k, 0], f.track_state[k, 1] + 2.2, str(tr.label), color=colors[k],
                                 fontsize=8, ha="center", va="bottom", clip_on=True, zorder=7))
        ax.set_xlim(e.x - half_window, e.x + half_window)
        ax.set_ylim(e.y - half_window, e.y + half_window)
        title.set_text(f"{_title(result)}\nt = {f.t:5.1f} s   GOSPA {f.gospa.gospa:4.2f} m   "
                       f"{_view_counts(f, (e.x, e.y), half_window)}")
        return []

    # Each frame is drawn once on the Agg canvas and kept as a palette image (a quarter of the
    # memory of RGBA); Pillow writes the GIF. (matplotlib's FuncAnimation + PillowWriter draws
    # every frame twice and keeps RGBA copies.)
    images = []
    if progress is not None:
        progress(0, len(frames))
    for i in range(len(frames)):
        update(i)
        fig.canvas.draw()
        rgba = np.asarray(fig.canvas.buffer_rgba())
        images.append(Image.fromarray(rgba[..., :3]).quantize(colors=255, method=Image.Quantize.FASTOCTREE))
        if progress is not None:
            progress(i + 1, len(frames))
    duration_ms = int(round(1000.0 * frame_dt)) if frame_dt > 0 else 200
    images[0].save(str(path), format="GIF", save_all=True, append_images=images[1:], duration=duration_ms, loop=0)
    return Path(path)


def gif_frame_count(result: Result, stride: int = 2) -> int:
    """The number of frames ``write_gif(result, ..., stride=stride)`` draws."""
    return len(result.frames[:: max(1, int(stride))])


def _lidar_xy(frame, config) -> np.ndarray:  # noqa: ANN001
    """The frame's lidar as 2-D points in E: as given, or a 3-D cloud through the tracker's pipeline."""
    pts = np.asarray(frame.lidar)
    if pts.ndim == 2 and pts.shape[1] == 3:
        from tracker.cloud import process_cloud

        return process_cloud(pts, config.cloud).outline_2d
    return pts.reshape(-1, 2)


def cloud_frame(result: Result) -> FrameRecord | None:
    """The kept frame with a 3-D cloud and the most scored vehicles (the earliest of those), or None."""
    best, most = None, -1
    for f in result.frames:
        if f.frame is None or np.asarray(f.frame.lidar).shape[1] != 3:
            continue
        if f.n_truth > most:
            best, most = f, f.n_truth
    return best


def plot_cloud_pipeline(result: Result, path: str | Path, frame: FrameRecord | None = None, *, half_window: float = 40.0) -> Path:
    """The 3-D pipeline on one frame (the paper's Fig. 2): (a) the raw cloud in E, coloured by height;
    (b) what is left after RANSAC ground removal and the height ceiling; (c) those points projected
    onto the fitted road plane (2-D, E) with the truth rectangles; within ``half_window`` m of the
    ego. ``frame`` defaults to ``cloud_frame(result)``; raises ``ValueError`` when the run kept no 3-D
    frame (``run_scenario(..., keep_sensor_data=True)`` with the vlp16 lidar)."""
    from mpl_toolkits.mplot3d import Axes3D  # noqa: F401  (registers the 3-D projection)

    from tracker.cloud import process_cloud
    from tracker.transforms import to_local

    f = cloud_frame(result) if frame is None else frame
    if f is None or f.frame is None or np.asarray(f.frame.lidar).shape[1] != 3:
        raise ValueError("plot_cloud_pipeline needs a run that kept its 3-D lidar frames (the vlp16 model, keep_sensor_data=True)")
    cloud = process_cloud(np.asarray(f.frame.lidar), result.config.cloud)
    pe = cloud.points_e
    near = cloud.finite & (np.abs(pe[:, 0]) <= half_window) & (np.abs(pe[:, 1]) <= half_window)
    fig = _figure(15.0, 5.2)
    z_lo, z_hi = -1.0, 4.0
    panels = [
        ("a. raw cloud", near),
        ("b. ground and points above the ceiling removed", near & cloud.kept),
    ]
    for i, (title, mask) in enumerate(panels):
        ax = fig.add_subplot(1, 3, i + 1, projection="3d")
        p = pe[mask]
        ax.scatter(p[:, 0], p[:, 1], p[:, 2], c=np.clip(p[:, 2], z_lo, z_hi), cmap="viridis", vmin=z_lo, vmax=z_hi,
                   s=0.6, depthshade=False)
        ax.set_xlim(-half_window, half_window)
        ax.set_ylim(-half_window, half_window)
        ax.set_zlim(z_lo, 6.0)
        ax.set_box_aspect((1.0, 1.0, 0.25))
        ax.view_init(elev=28.0, azim=-120.0)
        ax.set_xlabel("x (m)", fontsize=7)
        ax.set_ylabel("y (m)", fontsize=7)
        ax.set_zlabel("z (m)", fontsize=7)
        ax.tick_params(labelsize=6)
        ax.set_title(f"{title}\n{int(mask.sum())} points", fontsize=9)
    ax = fig.add_subplot(1, 3, 3)
    e = f.truth.ego
    corners = rectangle_corners(f.truth.xy, f.truth.yaw, f.truth.length, f.truth.width)
    local = to_local(corners.reshape(-1, 2), (e.x, e.y), e.yaw).reshape(-1, 4, 2)
    ax.add_collection(PolyCollection(local, facecolors="none", edgecolors=[vehicle_color(v) for v in f.truth.ids],
                                     linewidths=1.0, label="vehicles (their colours)"))
    ego_c = rectangle_corners(np.zeros((1, 2)), np.zeros(1), np.array([e.length]), np.array([e.width]))
    ax.add_collection(PolyCollection(ego_c, facecolors="k", alpha=0.75))
    q = cloud.outline_2d
    ax.scatter(q[:, 0], q[:, 1], s=1.5, c="#d62728", label="projected points")
    over = cloud.points_2d[cloud.seen_over[cloud.kept]]
    if len(over):
        ax.scatter(over[:, 0], over[:, 1], s=6, marker="x", linewidths=0.6, c="#7f7f7f",
                   label="seen over a nearer object (left out)")
    ax.set_xlim(-half_window, half_window)
    ax.set_ylim(-half_window, half_window)
    ax.set_aspect("equal")
    ax.set_xlabel("x in E (m)")
    ax.set_ylabel("y in E (m)")
    st = cloud.stats
    ax.set_title(f"c. projected onto the road plane (2-D)\n{st.kept - st.seen_over} of {st.points_in} points; "
                 f"ground {st.ground}, below {st.below_ground}, above ceiling {st.above_ceiling}, "
                 f"seen over {st.seen_over}", fontsize=9)
    ax.legend(loc="upper right", fontsize=7)
    fig.suptitle(f"{_title(result)}, t = {f.t:.1f} s: the 3-D lidar pipeline "
                 f"(mount transform, RANSAC ground removal, projection)", fontsize=10)
    return _save(fig, Path(path))


def write_figures(
    result: Result,
    out: str | Path,
    *,
    gif: bool = False,
    progress: Callable[[int, int], None] | None = None,
) -> dict[str, Path]:
    """Write every figure of ``result`` into the folder ``out`` (PNG; plus ``run.gif`` with
    ``gif=True``); returns the paths by name. ``progress(done, total)`` counts the figures and the
    GIF's frames: ``(0, total)`` first, then after each figure and each GIF frame."""
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    figures: list[tuple[str, Callable[[], Path]]] = [
        ("gospa", lambda: plot_gospa(result, folder / "gospa.png")),
        ("gospa_visible", lambda: plot_gospa(result, folder / "gospa_visible.png", visible=True)),
        ("birdseye", lambda: plot_birdseye(result, folder / "birdseye.png")),
        ("targets", lambda: plot_targets(result, folder / "targets.png")),
    ]
    if cloud_frame(result) is not None:
        figures.append(("cloud", lambda: plot_cloud_pipeline(result, folder / "cloud.png")))
    total = len(figures) + (gif_frame_count(result) if gif else 0)
    tick = progress if progress is not None else (lambda done, total: None)
    tick(0, total)
    paths: dict[str, Path] = {}
    for done, (name, draw) in enumerate(figures, start=1):
        paths[name] = draw()
        tick(done, total)
    if gif:
        def frame_done(i: int, n: int) -> None:
            if i:  # write_gif's (0, n) is already counted
                tick(len(figures) + i, total)

        paths["gif"] = write_gif(result, folder / "run.gif", progress=frame_done)
    return paths


__all__ = [
    "LIDAR_COLOR", "RADAR_COLOR", "UNMATCHED_COLOR", "VEHICLE_COLORS", "cloud_frame", "gif_frame_count",
    "birdseye_figure", "gospa_figure", "plot_birdseye", "plot_cloud_pipeline", "plot_gospa", "plot_targets", "targets_figure",
    "track_colors", "vehicle_color", "write_figures", "write_gif",
]  # fmt: skip


# -- a route's road on its lane map -------------------------------------------------------------------
def route_figure(graph, corridor, start: tuple[float, float, float], goal: tuple[float, float] | None = None) -> Figure:  # noqa: ANN001
    """The road of a route (``tracker.maps.Corridor``) over its lane map (``tracker.maps.LaneGraph``): every
    lanelet's outline (grey; the corridor's lanelets filled), the road's edges (black) and lane lines
    (dashed, blue where the lane runs against the route), the start pose and the goal. Axes in metres
    of the map's frame, equal scale, fitted to the road with a margin."""
    road = corridor.road
    fig = _figure(9.0, 7.5)
    ax = fig.add_subplot(1, 1, 1)
    outlines = [ll.polygon() for ll in graph.lanelets]
    members = [ll.id in corridor.members for ll in graph.lanelets]
    ax.add_collection(PolyCollection([p for p, m in zip(outlines, members) if not m], facecolors="none",
                                     edgecolors="0.75", linewidths=0.5))
    ax.add_collection(PolyCollection([p for p, m in zip(outlines, members) if m], facecolors="#cfe3f3",
                                     edgecolors="0.55", linewidths=0.5))
    s = np.linspace(0.0, road.length, max(2, int(road.length) + 1))
    right, left = road.edges(s)
    for n in (right, left):
        xy = road.to_cartesian(s, n)
        ax.plot(xy[:, 0], xy[:, 1], color="black", lw=1.2)
    for k, xy in _lane_lines(road, s, right, left):
        against = road.lane_directions[k] < 0 or road.lane_directions[k - 1] < 0
        ax.plot(xy[:, 0], xy[:, 1], color="#1f77b4" if against else "0.35", lw=0.8, ls=(0, (5, 4)))
    ax.annotate("", xy=(start[0] + 6.0 * math.cos(start[2]), start[1] + 6.0 * math.sin(start[2])),
                xytext=(start[0], start[1]), arrowprops={"arrowstyle": "->", "color": "#2ca02c", "lw": 2.0})
    if goal is not None:
        ax.plot([goal[0]], [goal[1]], marker="*", ms=12, color="#d62728", ls="none")
    pts = np.vstack([road.to_cartesian(s, right), road.to_cartesian(s, left)])
    (x0, x1), (y0, y1) = _data_limits(pts)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m, map frame)")
    ax.set_ylabel("y (m, map frame)")
    ax.set_title(f"{graph.source}: route of {len(corridor.route)} lanelets, {road.length:.0f} m, up to {road.lanes} lanes")
    ax.legend(handles=[Line2D([], [], color="black", lw=1.2, label="road edges"),
                       Line2D([], [], color="0.35", lw=0.8, ls=(0, (5, 4)), label="lane lines"),
                       Line2D([], [], color="#1f77b4", lw=0.8, ls=(0, (5, 4)), label="beside an oncoming lane"),
                       Patch(facecolor="#cfe3f3", edgecolor="0.55", label="lanelets of the road"),
                       Patch(facecolor="none", edgecolor="0.75", label="other lanelets"),
                       Line2D([], [], color="#2ca02c", lw=2.0, label="start")], loc="best", fontsize=8)
    return fig
