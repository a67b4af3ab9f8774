"""``render_mode = "rgb_array"`` of ``eot/TrackedRoad-v0``, drawn with matplotlib's Agg canvas.

highway-env's pygame viewer draws black frames under ``SDL_VIDEODRIVER=dummy``; this renderer needs no
display at all (``matplotlib.figure.Figure`` + ``FigureCanvasAgg``, never pyplot). The view follows the
ego, north up, ``view_half_width`` m each way: road edges and lane lines, the other vehicles' true
outlines (each in its colour, ``sim.evaluation.plots.vehicle_color``, as in the run's figures), the ego (black),
the latest lidar scan (green points), the radar detections of the latest frame (red crosses, 0.5 s
velocity arrows), and the tracks as filled rectangles labelled by track label, in the colour of the
vehicle GOSPA assigns them to (the runner's assignment: scored truth set, c = 5 m), grey when
unassigned (none with ``perception = "truth"``). The frame is ``(screen_height, screen_width, 3)`` uint8.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection, PolyCollection
from matplotlib.figure import Figure

from sim.evaluation.metrics import GOSPA_C, GOSPA_P, gospa
from sim.evaluation.plots import LIDAR_COLOR, RADAR_COLOR, UNMATCHED_COLOR, vehicle_color
from sim.evaluation.runner import truth_set
from sim.world.truth import rectangle_corners
from tracker.track import curvilinear_to_cartesian
from tracker.transforms import rotate, to_global

if TYPE_CHECKING:
    from sim.env.view import EnvView

_DPI = 100


class Renderer:
    """Draws frames of one environment (the figure is made once and reused)."""

    def __init__(self, env: EnvView) -> None:
        s = env.settings
        self.env = env
        self.size = (int(s.screen_width), int(s.screen_height))
        self.fig = Figure(figsize=(self.size[0] / _DPI, self.size[1] / _DPI), dpi=_DPI)
        self.canvas = FigureCanvasAgg(self.fig)
        self.ax = self.fig.add_axes((0.0, 0.0, 1.0, 1.0))

    def draw(self) -> np.ndarray:
        """The current frame as an RGB array."""
        env = self.env
        ax = self.ax
        ax.clear()
        ax.set_facecolor("#f4f4f0")
        ax.set_axis_off()
        road = env.world.road
        ego = env.world.ego_state()
        half = float(env.settings.view_half_width)
        # road: edges and lane lines over the window around the ego
        s = ego.s + np.linspace(-1.6 * half, 1.6 * half, 161)
        if road.closed:
            s = np.mod(s, road.length)
        else:
            s = s[(s >= 0.0) & (s <= road.length)]
        if len(s) >= 2:
            if getattr(road.layout, "_uniform", None) is not None:
                offsets = [road.right_edge + k * road.lane_width for k in range(road.lanes + 1)]
                lines = [road.to_cartesian(s, np.full_like(s, n)) for n in offsets]
            else:  # lanes of different widths (parking lanes): the layout's boundaries
                bounds = road.layout.boundaries_at(road.wrap_s(s))
                lines = [road.to_cartesian(s, bounds[:, k]) for k in range(road.lanes + 1)]
            breaks = np.flatnonzero(np.abs(np.diff(s)) > 0.5 * road.length) + 1 if road.closed else []
            for k, xy in enumerate(lines):
                edge = k in (0, road.lanes)
                for part in np.split(xy, breaks):
                    ax.plot(part[:, 0], part[:, 1], color="0.3" if edge else "0.6", lw=1.4 if edge else 0.8,
                            ls="-" if edge else (0, (6, 6)))
        frame = env.last_frame
        if frame is not None:
            snap = frame.truth
            pose = ((snap.ego.x, snap.ego.y), snap.ego.yaw)
            if len(snap):
                ax.add_collection(PolyCollection(snap.corners(), facecolors="none", linewidths=1.2,
                                                 edgecolors=[vehicle_color(v) for v in snap.ids]))
            if np.asarray(frame.frame.lidar).shape[1] == 3:  # the 3-D lidar: its returns off the ground, from above
                scan = frame.lidar
                pts = scan.points_global()[~scan.ground, :2]
            else:
                pts = to_global(np.asarray(frame.frame.lidar).reshape(-1, 2), *pose).reshape(-1, 2)
            ax.scatter(pts[:, 0], pts[:, 1], s=2.0, c=LIDAR_COLOR, zorder=6)
            radar = frame.frame.radar
            if len(radar):
                rxy = to_global(radar.xy, *pose).reshape(-1, 2)
                rv = rotate(radar.velocity, snap.ego.yaw).reshape(-1, 2)
                ax.scatter(rxy[:, 0], rxy[:, 1], s=22.0, marker="x", c=RADAR_COLOR, zorder=6)
                ax.add_collection(LineCollection(np.stack([rxy, rxy + 0.5 * rv], axis=1), colors=RADAR_COLOR, zorder=6))
        e = env.world.ego
        ax.add_collection(PolyCollection(
            rectangle_corners(np.array([e.position]), np.array([e.heading]), np.array([e.LENGTH]), np.array([e.WIDTH])),
            facecolors="k", edgecolors="k", alpha=0.8, zorder=5))
        tracks = env.tracks
        if tracks:
            state = curvilinear_to_cartesian(road, np.stack([tr.mean for tr in tracks])).reshape(-1, 7)
            corners = rectangle_corners(state[:, :2], state[:, 3], state[:, 5], state[:, 6])
            colors = self._track_colors(state[:, :2])
            ax.add_collection(PolyCollection(corners, facecolors=colors, edgecolors=colors, alpha=0.45, zorder=7))
            for k, tr in enumerate(tracks):
                ax.text(state[k, 0], state[k, 1] + 2.0, str(tr.label), color=colors[k], fontsize=9, ha="center",
                        va="bottom", zorder=8, clip_on=True)
        ax.set_xlim(e.position[0] - half, e.position[0] + half)
        ax.set_ylim(e.position[1] - half * self.size[1] / self.size[0], e.position[1] + half * self.size[1] / self.size[0])
        ax.set_aspect("equal", adjustable="box")
        ax.text(0.01, 0.99, f"t = {env.sim_time:5.1f} s  v = {ego.v:4.1f} m/s  {env.settings.perception}"
                + (f" ({env.settings.variant}): {len(tracks)} tracks" if env.settings.perception == "tracks" else ""),
                transform=ax.transAxes, fontsize=9, va="top", ha="left")
        self.canvas.draw()
        rgba = np.asarray(self.canvas.buffer_rgba())
        return np.ascontiguousarray(rgba[: self.size[1], : self.size[0], :3])

    def _track_colors(self, track_xy: np.ndarray) -> list[str]:
        """Each track's colour: its GOSPA-assigned vehicle's (scored truth set of the last frame), else grey."""
        env = self.env
        colors = [UNMATCHED_COLOR] * len(track_xy)
        frame = env.last_frame
        if frame is None or len(frame.truth) == 0:
            return colors
        snap = frame.truth
        keep = truth_set(snap, env.world.road, env.rig.config.lidar.max_range)
        g = gospa(snap.xy[keep], track_xy, GOSPA_C, GOSPA_P)
        ids = snap.ids[keep]
        for t, k in zip(g.truth_index, g.estimate_index):
            colors[int(k)] = vehicle_color(int(ids[t]))
        return colors

    def close(self) -> None:
        self.fig.clear()


__all__ = ["Renderer"]
