"""Figures of a run (``Result``): GOSPA and cardinality over time, a bird's-eye view, per-target yaw,
speed and extent over time, and an animated GIF that follows the ego.

Figures are drawn on matplotlib's Agg canvas directly (``matplotlib.figure.Figure`` +
``FigureCanvasAgg``), never through pyplot, so they work on headless machines and do not change the
backend of an interactive session. Colours: one per track label (tab10 cycle); truth in grey/black.

- ``gospa.png``: GOSPA (m) over time, its parts (p-th-power sums, m^2: localisation, missed, false,
  stacked) and the cardinality (true count of the scored truth set vs estimated count) -- the paper's
  simulation figure;
- ``gospa_visible.png``: the same scored against the visible vehicles only;
- ``birdseye.png``: the road around the ego's path with truth trajectories, track trajectories and,
  below, three snapshots with truth and track rectangles and labels;
- ``targets.png``: yaw (deg), speed (m/s), length and width (m) over time per truth vehicle (lines)
  with the estimates of the tracks assigned to it by GOSPA (dots);
- ``cloud.png`` (runs with the 3-D lidar, ``sensors.lidar.model = "vlp16"``): the paper's Fig. 2 for
  one frame: the raw cloud, the cloud without the ground (and above the height ceiling), and the 2-D
  points projected onto the road plane, with the truth rectangles (``plot_cloud_pipeline``);
- ``run.gif`` (``gif=True``): the run seen from above, following the ego: road, lidar points, radar
  detections with velocity arrows, truth outlines, track rectangles with labels (Pillow, which
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

from sim.runner import FrameRecord, Result
from sim.truth import rectangle_corners
from tracker.transforms import rotate, to_global

_TAB10 = [
    "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd",
    "#8c564b", "#e377c2", "#bcbd22", "#17becf", "#7f7f7f",
]  # fmt: skip


def label_color(label: int) -> str:
    """The colour of a track label (tab10 cycle)."""
    return _TAB10[int(label) % len(_TAB10)]


def _figure(width: float, height: float, dpi: int = 110) -> Figure:
    fig = Figure(figsize=(width, height), dpi=dpi)
    FigureCanvasAgg(fig)
    return fig


def _save(fig: Figure, path: Path) -> Path:
    fig.savefig(path)
    return path


# -- GOSPA and cardinality ------------------------------------------------------------------------
def plot_gospa(result: Result, path: str | Path, *, visible: bool = False) -> Path:
    """GOSPA, its parts and the cardinality over time (scored truth set, or visible-only with
    ``visible=True``) written to ``path`` (PNG)."""
    frames = result.frames
    t = result.times
    g = [f.gospa_visible if visible else f.gospa for f in frames]
    total = np.array([x.gospa for x in g])
    loc = np.array([x.localization for x in g])
    missed = np.array([x.missed for x in g])
    false = np.array([x.false for x in g])
    n_true = np.array([f.n_visible if visible else f.n_truth for f in frames])
    n_est = np.array([f.n_tracks for f in frames])
    c, p = result.settings.get("gospa_c", 5.0), result.settings.get("gospa_p", 2.0)
    fig = _figure(8.0, 7.5)
    ax1, ax2, ax3 = fig.subplots(3, 1, sharex=True)
    which = "visible vehicles only" if visible else "vehicles in lidar range on the road (occluded included)"
    fig.suptitle(f"{result.spec.name} / {result.variant} / seed {result.seed}: truth = {which}", fontsize=10)
    ax1.plot(t, total, color="k", lw=1.5, label="GOSPA")
    ax1.set_ylabel("GOSPA (m)")
    ax1.set_ylim(bottom=0.0)
    ax1.grid(alpha=0.3)
    ax1.set_title(f"GOSPA (alpha = 2, p = {p:g}, c = {c:g} m), mean {np.mean(total):.2f} m" if len(t) else "GOSPA",
                  fontsize=9)
    ax2.stackplot(t, loc, missed, false, labels=["localisation", "missed", "false"],
                  colors=["#1f77b4", "#d62728", "#ff7f0e"], alpha=0.8)
    ax2.set_ylabel(f"parts (m^{p:g})")
    ax2.set_title("GOSPA parts as p-th-power sums (they add up to GOSPA^p)", fontsize=9)
    ax2.legend(loc="upper right", fontsize=8)
    ax2.grid(alpha=0.3)
    ax3.step(t, n_true, where="post", color="k", lw=1.5, label="true")
    ax3.step(t, n_est, where="post", color="#1f77b4", lw=1.2, ls="--", label="estimated")
    ax3.set_ylabel("cardinality")
    ax3.set_xlabel("t (s)")
    ax3.set_ylim(-0.2, max(int(np.max(n_true, initial=0)), int(np.max(n_est, initial=0))) + 1.2)
    ax3.yaxis.get_major_locator().set_params(integer=True)
    ax3.legend(loc="upper right", fontsize=8)
    ax3.grid(alpha=0.3)
    fig.tight_layout()
    return _save(fig, Path(path))


# -- bird's-eye view ------------------------------------------------------------------------------
def _road_lines(result: Result, s_low: float, s_high: float, step: float = 1.0) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Edges (solid) and lane lines (dashed) as (K, 2) polylines over ``[s_low, s_high]``."""
    road = result.road
    if road.closed:
        s = np.linspace(0.0, road.length, max(2, int(road.length / step) + 1))
    else:
        s_low, s_high = max(0.0, s_low), min(road.length, s_high)
        s = np.linspace(s_low, s_high, max(2, int((s_high - s_low) / step) + 1))
    edges = [road.to_cartesian(s, np.full_like(s, n)) for n in (road.right_edge, road.left_edge)]
    lanes = [road.to_cartesian(s, np.full_like(s, road.right_edge + k * road.lane_width)) for k in range(1, road.lanes)]
    return edges, lanes


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


def plot_birdseye(result: Result, path: str | Path, *, snapshots: int = 3, half_window: float = 45.0) -> Path:
    """Bird's-eye view: the road around the ego's path with truth and track trajectories, and
    ``snapshots`` views (``half_window`` m around the ego) with truth and track rectangles."""
    frames = result.frames
    fig = _figure(11.0, 9.0)
    gs = fig.add_gridspec(2, max(1, snapshots), height_ratios=[1.35, 1.0])
    ax = fig.add_subplot(gs[0, :])
    ego = _ego_xy(result)
    ego_s = np.array([f.ego_s for f in frames])
    road = result.road
    margin = 110.0
    s_low = float(ego_s.min()) - margin if len(ego_s) else 0.0
    s_high = float(ego_s.max()) + margin if len(ego_s) else road.length
    if road.closed and len(ego_s) and float(np.ptp(ego_s)) > 0.5 * road.length:
        s_low, s_high = 0.0, road.length
    edges, lanes = _road_lines(result, s_low, s_high)
    _draw_road(ax, edges, lanes)
    # truth trajectories (only where scored)
    ids = sorted({int(i) for f in frames for i in f.truth.ids})
    for vid in ids:
        pts = np.array([f.truth.xy[list(f.truth.ids).index(vid)] if vid in f.truth.ids and f.scored[list(f.truth.ids).index(vid)]
                        else (np.nan, np.nan) for f in frames])
        ax.plot(pts[:, 0], pts[:, 1], color="0.2", lw=2.5, alpha=0.35, solid_capstyle="round")
    ax.plot(ego[:, 0], ego[:, 1], color="k", lw=2.0, ls="--", label="ego")
    # track trajectories per label
    by_label: dict[int, list[tuple[float, float, float]]] = {}
    for f in frames:
        for k, tr in enumerate(f.tracks):
            by_label.setdefault(tr.label, []).append((f.t, f.track_state[k, 0], f.track_state[k, 1]))
    for label, rows in by_label.items():
        arr = np.array(rows)
        ax.plot(arr[:, 1], arr[:, 2], ".", ms=2.0, color=label_color(label))
    ax.plot([], [], color="0.2", lw=2.5, alpha=0.35, label="truth (while scored)")
    ax.plot([], [], ".", color=label_color(0), label="tracks (colour = label)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(loc="best", fontsize=8)
    ax.set_title(f"{result.spec.name} / {result.variant} / seed {result.seed}: {len(frames)} frames, "
                 f"{len(by_label)} track labels", fontsize=10)
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
            _draw_rectangles(sax, f, result)
            sax.set_xlim(e.x - half_window, e.x + half_window)
            sax.set_ylim(e.y - half_window, e.y + half_window)
            sax.set_aspect("equal")
            sax.set_title(f"t = {f.t:.1f} s: {f.n_truth} true, {f.n_tracks} tracks", fontsize=9)
            sax.tick_params(labelsize=7)
    fig.tight_layout()
    return _save(fig, Path(path))


def _draw_rectangles(ax, f: FrameRecord, result: Result, *, labels: bool = True) -> None:  # noqa: ANN001
    e = f.truth.ego
    ego_c = rectangle_corners(np.array([[e.x, e.y]]), np.array([e.yaw]), np.array([e.length]), np.array([e.width]))
    ax.add_collection(PolyCollection(ego_c, facecolors="k", edgecolors="k", alpha=0.7))
    truth_c = f.truth.corners()
    if len(truth_c):
        ax.add_collection(PolyCollection(truth_c, facecolors="none", edgecolors=["0.2" if s else "0.65" for s in f.scored],
                                         linewidths=1.2))
    tr_c = _track_rectangles(f)
    if len(tr_c):
        colors = [label_color(tr.label) for tr in f.tracks]
        ax.add_collection(PolyCollection(tr_c, facecolors=colors, edgecolors=colors, alpha=0.45, linewidths=1.0))
        if labels:
            for k, tr in enumerate(f.tracks):
                ax.text(f.track_state[k, 0], f.track_state[k, 1] + 2.2, str(tr.label), color=colors[k], fontsize=7,
                        ha="center", va="bottom", clip_on=True)


# -- per-target yaw, speed and extent -------------------------------------------------------------
def plot_targets(result: Result, path: str | Path) -> Path:
    """Yaw, speed, length and width over time per truth vehicle (lines, while scored) and the
    estimates of the tracks GOSPA assigns to it (dots, same colour)."""
    frames = result.frames
    ids = sorted({int(i) for f in frames for i, s in zip(f.truth.ids, f.scored) if s})
    quantities = [("yaw (deg)", 3, 180.0 / math.pi), ("speed (m/s)", 2, 1.0), ("length (m)", 5, 1.0), ("width (m)", 6, 1.0)]
    fig = _figure(9.0, 9.0)
    axes = fig.subplots(len(quantities), 1, sharex=True)
    for vid in ids:
        color = _TAB10[vid % len(_TAB10)]
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
        axes[0].plot([], [], color=color, label=f"vehicle {vid}")
    for ax, (name, _, _) in zip(axes, quantities):
        ax.set_ylabel(name)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("t (s)")
    if ids:
        axes[0].legend(loc="best", fontsize=7, ncol=min(len(ids), 4))
    axes[0].set_title(f"{result.spec.name} / {result.variant}: truth (lines) and assigned tracks (dots)", fontsize=10)
    fig.tight_layout()
    return _save(fig, Path(path))


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
    with 0.5 s velocity arrows, truth outlines (grey), the ego (black) and track rectangles with
    labels. Needs ``run_scenario(..., keep_sensor_data=True)``."""
    from PIL import Image

    frames = result.frames[:: max(1, int(stride))]
    if not frames:
        raise ValueError("write_gif: the result has no frames")
    if frames[0].frame is None:
        raise ValueError("write_gif needs the sensor data: run with run_scenario(..., keep_sensor_data=True)")
    fig = _figure(7.0, 7.4, dpi=dpi)
    ax = fig.add_axes((0.08, 0.1, 0.9, 0.84))
    edges, lanes = _road_lines(result, -1e9, 1e9, step=2.0)
    _draw_road(ax, edges, lanes)
    ax.set_aspect("equal")
    ax.tick_params(labelsize=7)
    lidar = ax.scatter([], [], s=1.5, c="#2ca02c", label="lidar", zorder=7)
    radar = ax.scatter([], [], s=18.0, marker="x", c="#d62728", label="radar", zorder=4)
    arrows = LineCollection([], colors="#d62728", linewidths=1.0, zorder=4)
    ax.add_collection(arrows)
    ego_poly = PolyCollection([], facecolors="k", edgecolors="k", alpha=0.75, zorder=5)
    truth_poly = PolyCollection([], facecolors="none", edgecolors="0.3", linewidths=1.2, zorder=5)
    track_poly = PolyCollection([], alpha=0.45, linewidths=1.0, zorder=6)
    for coll in (ego_poly, truth_poly, track_poly):
        ax.add_collection(coll)
    from matplotlib.patches import Patch

    proxies = [
        lidar, radar,
        Patch(facecolor="k", alpha=0.75, label="ego"),
        Patch(facecolor="none", edgecolor="0.3", label="truth"),
        Patch(facecolor=label_color(0), alpha=0.45, label="tracks (label)"),
    ]  # fmt: skip
    fig.legend(handles=proxies, loc="lower center", ncol=5, fontsize=8, frameon=False)
    title = ax.set_title("", fontsize=9)
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
        tr_c = _track_rectangles(f)
        colors = [label_color(tr.label) for tr in f.tracks]
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
        title.set_text(f"{result.spec.name} / {result.variant}   t = {f.t:5.1f} s   GOSPA {f.gospa.gospa:4.2f} m   "
                       f"{f.n_truth} true / {f.n_tracks} tracks")
        return []

    # Each frame is drawn once on the Agg canvas and kept as a palette image (a quarter of the
    # memory of RGBA); Pillow writes the GIF. (matplotlib's FuncAnimation + PillowWriter draws
    # every frame twice and keeps RGBA copies.)
    images = []
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


def _lidar_xy(frame, config) -> np.ndarray:  # noqa: ANN001
    """The frame's lidar as 2-D points in E: as given, or a 3-D cloud through the tracker's pipeline."""
    pts = np.asarray(frame.lidar)
    if pts.ndim == 2 and pts.shape[1] == 3:
        from tracker.cloud import process_cloud

        return process_cloud(pts, config.cloud).points_2d
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
    ax.add_collection(PolyCollection(local, facecolors="none", edgecolors="0.3", linewidths=0.8, label="truth"))
    ego_c = rectangle_corners(np.zeros((1, 2)), np.zeros(1), np.array([e.length]), np.array([e.width]))
    ax.add_collection(PolyCollection(ego_c, facecolors="k", alpha=0.75))
    q = cloud.points_2d
    ax.scatter(q[:, 0], q[:, 1], s=1.5, c="#d62728", label="projected points")
    ax.set_xlim(-half_window, half_window)
    ax.set_ylim(-half_window, half_window)
    ax.set_aspect("equal")
    ax.set_xlabel("x in E (m)")
    ax.set_ylabel("y in E (m)")
    st = cloud.stats
    ax.set_title(f"c. projected onto the road plane (2-D)\n{st.kept} of {st.points_in} points; "
                 f"ground {st.ground}, below {st.below_ground}, above ceiling {st.above_ceiling}", fontsize=9)
    ax.legend(loc="upper right", fontsize=7)
    fig.suptitle(f"{result.spec.name} / seed {result.seed}, t = {f.t:.1f} s: the 3-D lidar pipeline "
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
    ``gif=True``); returns the paths by name."""
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    paths = {
        "gospa": plot_gospa(result, folder / "gospa.png"),
        "gospa_visible": plot_gospa(result, folder / "gospa_visible.png", visible=True),
        "birdseye": plot_birdseye(result, folder / "birdseye.png"),
        "targets": plot_targets(result, folder / "targets.png"),
    }
    if cloud_frame(result) is not None:
        paths["cloud"] = plot_cloud_pipeline(result, folder / "cloud.png")
    if gif:
        paths["gif"] = write_gif(result, folder / "run.gif", progress=progress)
    return paths


__all__ = ["cloud_frame", "label_color", "plot_birdseye", "plot_cloud_pipeline", "plot_gospa", "plot_targets", "write_figures", "write_gif"]
