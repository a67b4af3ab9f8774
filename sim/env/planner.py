"""A rule-based planner that drives ``eot/TrackedRoad-v0`` on its observation alone.

``Planner(config).act(obs, labels) -> action`` for ``action = "ContinuousAction"`` (``[acceleration,
steering]`` in [-1, 1]^2, mapped by the env onto ``accel_range`` / ``steering_range``). It reads only
the observation rows (``sim.env.observation``: row 0 the ego, then one row per track), the rows'
track labels (the env's ``info["labels"]``: to recognise the same lead from step to step) and the
map's lane centres (``PlannerConfig.lane_centers``, or each step's ``act(..., lane_centers=...)``: the
env's ``info["lane_centers"]`` at the ego's ``s``, NaN for a lane absent there on a lane map whose lanes
begin and end); never the world.

- **Lead and ACC.** The lead is the nearest row ahead (``ds > 0``) whose centre lies within
  ``(W_ego + W) / 2 + path_margin`` of the ego's lane centre, or of the ego's own ``n`` (what its body
  overlaps where it is, between lanes too); while changing lanes, of the nearest such row in each of
  the two lanes and across the ego the one asking for the lower acceleration (a slow vehicle further
  on in the lane being left still holds the ego back until the ego has left it).
  The acceleration is the IDM law (``time_headway``, ``min_gap`` bumper to bumper, ``max_accel``,
  ``comfort_decel``, cruise at ``set_speed``: default the ego's speed at the first observation),
  clipped to ``accel_range``. **Flicker:** when the lead's row disappears, the planner keeps it for
  ``lead_hold_s`` seconds, predicted at its last speed, and uses the nearer of it and any other lead.
- **Lane keeping.** A cascade on the ego's own ``n, xi, xi_dot``: lateral speed command
  ``-(n - n_ref) / lateral_time`` (limited to ``min(lateral_speed, 0.1 v)``), course command from it
  (``course_ref = asin(n_dot / v)``; the course is ``xi + beta``, beta the bicycle model's slip angle), yaw
  rate ``(road_turn + (course_ref - xi) / heading_time) / (1 + l_r / (v heading_time))`` (the slip of the
  new command solved for with ``beta ~ yaw_rate l_r / v``, stable down to walking pace), with the
  road's turn rate as feed-forward: ``kappa s_dot = yaw_rate - xi_dot``, where ``yaw_rate`` follows
  from the planner's own last steering command (``v sin(beta) / l_r``, ``l_r = min(L / 2, 3 m)``).
- **Lane change.** When the lead is within ``change_lookahead`` m and slower than ``set_speed -
  slow_margin``, an adjacent lane (left first) is taken if every row reaching into it (its rectangle
  overlapping the lane: a motorcycle on the line between two lanes is in both) leaves a safe gap
  (ahead: ``max(min_change_gap, v_ego * change_headway + 2 s x closing speed)``; behind the same with
  the follower's speed) and its own lead, if any, is farther or faster than the current one; then no
  new change for ``change_cooldown`` s. Only into a lane present where the ego is. With a ``goal_lane``
  (a planning problem's), lane changes go only toward it, one lane at a time, whenever the same gap
  test allows (and not around slow leads).
- **Lanes that end.** When the target lane is absent at the ego's ``s`` (a lane map's auxiliary lane has
  ended), the target becomes the present lane nearest to the ego, without the gap test (the lane is gone).

``decision`` (a ``Decision``) records what the last ``act`` did: the lead's label and where it came
from ("row" or "held"), the gap, the commanded acceleration and the target lane (for the closed-loop
diagnostics of ``sim.studies.closed_loop``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from sim.env.observation import COL
from sim.world.traffic import MAX_REAR_AXLE


@dataclass(frozen=True)
class PlannerConfig:
    """Planner settings (SI units; see the module docstring). ``lane_centers`` (m, lane 0 first) is
    required; ``accel_range`` (m/s^2) and ``steering_range`` (rad) must equal the env's
    ``acceleration_range`` / ``steering_range``; ``period`` (s) its ``1 / policy_frequency``."""

    lane_centers: tuple[float, ...]
    #: Each lane's traffic direction, +1 along ``s`` or -1 against it (default: all +1); lane changes stay within one direction.
    lane_directions: tuple[int, ...] | None = None
    #: Each lane's kind, "driving", "parking" or "shoulder" (default: all driving); lane changes go only into driving lanes.
    lane_kinds: tuple[str, ...] | None = None
    set_speed: float | None = None
    accel_range: tuple[float, float] = (-8.0, 4.0)
    steering_range: tuple[float, float] = (-math.pi / 4, math.pi / 4)
    period: float = 0.2
    time_headway: float = 1.5
    min_gap: float = 4.0
    max_accel: float = 1.5
    comfort_decel: float = 2.5
    path_margin: float = 0.3
    lead_hold_s: float = 1.0
    lateral_time: float = 1.2
    lateral_speed: float = 1.0
    heading_time: float = 0.4
    lane_changes: bool = True
    slow_margin: float = 2.0
    change_lookahead: float = 60.0
    change_headway: float = 0.8
    min_change_gap: float = 8.0
    change_cooldown: float = 4.0
    min_change_speed: float = 8.0
    #: Lane to reach (e.g. a planning problem's goal lane; None: none): lane changes go only toward it, one lane at a time, when the gap allows.
    goal_lane: int | None = None
    max_lead_decel: float = 1.5

    def __post_init__(self) -> None:
        if len(self.lane_centers) < 1:
            raise ValueError("PlannerConfig.lane_centers needs at least one lane centre (m)")
        object.__setattr__(self, "lane_centers", tuple(float(c) for c in self.lane_centers))
        lanes = len(self.lane_centers)
        if self.lane_directions is not None:
            if len(self.lane_directions) != lanes or any(d not in (-1, 1) for d in self.lane_directions):
                raise ValueError(f"PlannerConfig.lane_directions = {self.lane_directions!r}: one +1 or -1 per lane ({lanes})")
            object.__setattr__(self, "lane_directions", tuple(int(d) for d in self.lane_directions))
        if self.goal_lane is not None and not 0 <= self.goal_lane < lanes:
            raise ValueError(f"PlannerConfig.goal_lane = {self.goal_lane!r}: must be a lane, 0..{lanes - 1}")
        if self.lane_kinds is not None and len(self.lane_kinds) != lanes:
            raise ValueError(f"PlannerConfig.lane_kinds = {self.lane_kinds!r}: one kind per lane ({lanes})")
        lo, hi = self.accel_range
        if not lo < 0.0 < hi:
            raise ValueError(f"PlannerConfig.accel_range = {self.accel_range!r}: must contain 0 (m/s^2)")
        for name in ("period", "time_headway", "max_accel", "comfort_decel", "lateral_time", "lateral_speed",
                     "heading_time"):
            if not getattr(self, name) > 0:
                raise ValueError(f"PlannerConfig.{name} = {getattr(self, name)!r}: must be > 0")


@dataclass
class Decision:
    """What the planner did at its last ``act``: ``lead_label`` (the row's label; None: no lead),
    ``lead_source`` ("row", "held" or None), ``lead_ds`` / ``lead_gap`` / ``lead_n`` (m), ``lead_v`` (m/s),
    ``accel`` (commanded, m/s^2), ``target_lane`` and ``changing`` (a lane change in progress)."""

    lead_label: int | None = None
    lead_source: str | None = None
    lead_ds: float = math.inf
    lead_gap: float = math.inf
    lead_v: float = math.nan
    lead_n: float = math.nan
    accel: float = 0.0
    target_lane: int = 0
    changing: bool = False


@dataclass
class _Held:
    label: int
    ds: float
    v: float
    length: float
    n: float
    age: float = 0.0


@dataclass
class Planner:
    """ACC + lane keeping + lane changes on tracks (module docstring). Call ``reset()`` between episodes."""

    config: PlannerConfig
    decision: Decision = field(default_factory=Decision)

    def __post_init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        """Forget the episode: set speed, target lane, held lead, last steering."""
        self._set_speed: float | None = self.config.set_speed
        self._target: int | None = None
        self._held: _Held | None = None
        self._steer = 0.0
        self._since_change = math.inf
        self._last_lead: tuple[int, float] | None = None  # label, speed of the last step's lead
        self._centers = np.asarray(self.config.lane_centers, dtype=float)
        self.decision = Decision()

    # -- helpers --------------------------------------------------------------------------------
    @property
    def centers(self) -> np.ndarray:
        """The lane centres (m) of the last ``act`` (NaN: absent there), else the configuration's."""
        return self._centers

    def lane_of(self, n: float) -> int:
        """The present lane whose centre is nearest to ``n`` (m)."""
        return int(np.nanargmin(np.abs(self._centers - n)))

    def on_path(self, n: np.ndarray | float, width: np.ndarray | float, centre: float, ego_width: float) -> np.ndarray:
        """Whether vehicles at lateral offsets ``n`` (m) of ``width`` (m) lie on a path of the ego's width
        ``ego_width`` (m) centred on ``centre`` (m): centre within ``(W_ego + W) / 2 + path_margin``."""
        return np.abs(np.asarray(n) - centre) < 0.5 * (ego_width + np.asarray(width)) + self.config.path_margin

    def _in_lane(self, rows: np.ndarray, lane: int, ego_width: float) -> np.ndarray:
        return self.on_path(rows[:, COL["n"]], rows[:, COL["width"]], float(self._centers[lane]), ego_width)

    @staticmethod
    def _gap(ds: float, length: float, ego_length: float) -> float:
        return abs(ds) - 0.5 * (length + ego_length)

    def _idm(self, v: float, gap: float | None, v_lead: float) -> float:
        c = self.config
        v0 = max(self._set_speed or 0.0, 0.1)
        acc = c.max_accel * (1.0 - (max(v, 0.0) / v0) ** 4)
        if gap is not None:
            s_star = c.min_gap + max(0.0, v * c.time_headway + v * (v - v_lead) / (2.0 * math.sqrt(c.max_accel * c.comfort_decel)))
            acc -= c.max_accel * (s_star / max(gap, 0.1)) ** 2
        return float(np.clip(acc, *c.accel_range))

    # -- the policy -----------------------------------------------------------------------------
    def act(self, obs: np.ndarray, labels: Sequence[int] | np.ndarray,
            lane_centers: Sequence[float] | np.ndarray | None = None) -> np.ndarray:
        """The action ``[acceleration, steering]`` in [-1, 1]^2 for the (unnormalised) observation
        ``obs`` and its row labels ``labels`` (the env's ``info["labels"]``, one per row); ``lane_centers``
        (m, one per lane of the configuration, NaN where absent; the env's ``info["lane_centers"]``) this
        step's, default the configuration's."""
        c = self.config
        if lane_centers is not None:
            centers = np.asarray(lane_centers, dtype=float).reshape(-1)
            if len(centers) != len(c.lane_centers) or np.isnan(centers).all():
                raise ValueError(f"Planner.act: lane_centers has {len(centers)} entries ({int(np.count_nonzero(~np.isnan(centers)))} "
                                 f"present); the planner was configured with {len(c.lane_centers)} lanes and needs one present")
            self._centers = centers
        obs = np.asarray(obs, dtype=float)
        labels = np.asarray(labels, dtype=np.int64).reshape(-1)
        if len(labels) != len(obs):
            raise ValueError(f"Planner.act: {len(labels)} labels for {len(obs)} observation rows (give info['labels'])")
        ego = obs[0]
        n, v, xi, xi_dot = ego[COL["n"]], ego[COL["v"]], ego[COL["xi"]], ego[COL["xi_dot"]]
        length, width = ego[COL["length"]], ego[COL["width"]]
        if self._set_speed is None:
            self._set_speed = float(v)
        present = obs[1:, COL["present"]] > 0.5
        rows = obs[1:][present]
        row_labels = labels[1:][present]
        lane = self.lane_of(n)
        if self._target is None or np.isnan(self._centers[self._target]):
            self._target = lane  # the first step, or the target lane has ended
        changing = self._target != lane or abs(n - self._centers[self._target]) > 0.5
        self._since_change += c.period

        # lead: per lane of the ego (both while changing lanes), and across the ego's own width where it
        # is, the nearest row ahead; of those the one that asks for the lower IDM acceleration (a slow row
        # further on in the lane being left still counts), or the held one
        is_ahead = rows[:, COL["ds"]] > 0.0
        ahead, ahead_labels = rows[is_ahead], row_labels[is_ahead]
        lead: tuple[int, str, float, float, float, float] | None = None  # label, source, ds, v, length, n
        lowest = math.inf
        paths = [self._in_lane(ahead, k, width) for k in sorted({lane, self._target})]
        paths.append(self.on_path(ahead[:, COL["n"]], ahead[:, COL["width"]], n, width))
        for path in paths:
            in_k = np.flatnonzero(path)
            if not len(in_k):
                continue
            j = int(in_k[np.argmin(ahead[in_k, COL["ds"]])])
            row = ahead[j]
            wanted = self._idm(v, self._gap(float(row[COL["ds"]]), float(row[COL["length"]]), length), float(row[COL["v"]]))
            if wanted < lowest or (wanted == lowest and lead is not None and row[COL["ds"]] < lead[2]):
                lowest = wanted
                lead = (int(ahead_labels[j]), "row", float(row[COL["ds"]]), float(row[COL["v"]]),
                        float(row[COL["length"]]), float(row[COL["n"]]))
        held = self._held
        if held is not None:
            held.age += c.period
            held.ds += (held.v - v) * c.period
            seen = len(rows) and np.any(row_labels == held.label)
            if seen or held.age > c.lead_hold_s or held.ds <= 0.0:
                held = self._held = None
            elif lead is None or held.ds < lead[2]:
                lead = (held.label, "held", held.ds, held.v, held.length, held.n)
        lead_decel = 0.0
        if lead is not None and lead[1] == "row":
            if self._last_lead is not None and self._last_lead[0] == lead[0]:
                lead_decel = (self._last_lead[1] - lead[3]) / c.period
            self._held = _Held(lead[0], lead[2], lead[3], lead[4], lead[5])
        self._last_lead = None if lead is None else (lead[0], lead[3])
        gap = None if lead is None else self._gap(lead[2], lead[4], length)
        accel = self._idm(v, gap, lead[3] if lead else v)

        # lane change: toward the goal lane when one is set (and present), else around a slow lead
        may_change = (c.lane_changes and not changing and self._since_change >= c.change_cooldown
                      and v >= c.min_change_speed and accel > -c.comfort_decel)
        goal = c.goal_lane if c.goal_lane is not None and not np.isnan(self._centers[c.goal_lane]) else None
        options: list[int] = []
        if may_change and goal is not None and goal != lane:
            options = [lane + (1 if goal > lane else -1)]
        elif (may_change and goal is None and lead is not None and lead_decel < c.max_lead_decel
              and lead[2] < c.change_lookahead and lead[3] < (self._set_speed or 0.0) - c.slow_margin):
            options = [lane + 1, lane - 1]
        for k in options:
            if 0 <= k < len(self._centers) and self._may_enter(lane, k) and self._safe(rows, k, v, length, width, lead):
                self._target = k
                self._since_change = 0.0
                changing = True
                break

        steer = self._steering(n, v, xi, xi_dot, length, float(self._centers[self._target]))
        self.decision = Decision(
            lead_label=None if lead is None else lead[0], lead_source=None if lead is None else lead[1],
            lead_ds=math.inf if lead is None else lead[2], lead_gap=math.inf if gap is None else gap,
            lead_v=math.nan if lead is None else lead[3], lead_n=math.nan if lead is None else lead[5], accel=accel, target_lane=int(self._target), changing=changing,
        )
        lo, hi = c.accel_range
        slo, shi = c.steering_range
        return np.array([2.0 * (accel - lo) / (hi - lo) - 1.0, 2.0 * (steer - slo) / (shi - slo) - 1.0], dtype=np.float32)

    def _may_enter(self, lane: int, k: int) -> bool:
        """Whether a lane change from ``lane`` into ``k`` is allowed: a driving lane of the same direction,
        present at the ego's ``s``."""
        c = self.config
        if np.isnan(self._centers[k]):
            return False
        if c.lane_directions is not None and c.lane_directions[k] != c.lane_directions[lane]:
            return False
        return c.lane_kinds is None or c.lane_kinds[k] == "driving"

    def _occupies(self, rows: np.ndarray, k: int) -> np.ndarray:
        """Rows whose rectangle reaches into lane ``k`` (centre within half a lane + half their width of
        its centre): a motorcycle on the line between two lanes is in both."""
        centers = self._centers
        present = centers[~np.isnan(centers)]
        half_lane = 0.5 * float(np.min(np.abs(np.diff(present)))) if len(present) > 1 else 1.75
        return np.abs(rows[:, COL["n"]] - centers[k]) < half_lane + 0.5 * rows[:, COL["width"]]

    def _safe(self, rows: np.ndarray, k: int, v: float, length: float, width: float,
              lead: tuple[int, str, float, float, float, float] | None) -> bool:
        c = self.config
        there = rows[self._occupies(rows, k)] if len(rows) else rows
        for row in there:
            ds, v_other = row[COL["ds"]], row[COL["v"]]
            gap = self._gap(ds, row[COL["length"]], length)
            if ds >= 0.0:
                need = max(c.min_change_gap, v * c.change_headway + 2.0 * max(0.0, v - v_other))
            else:
                need = max(c.min_change_gap, v_other * c.change_headway + 2.0 * max(0.0, v_other - v))
            if gap < need:
                return False
        front = there[there[:, COL["ds"]] > 0.0] if len(there) else there
        if len(front) and lead is not None:
            nearest = front[np.argmin(front[:, COL["ds"]])]
            if nearest[COL["ds"]] <= lead[2] + 10.0 and nearest[COL["v"]] <= lead[3] + 1.0:
                return False
        return True

    def _steering(self, n: float, v: float, xi: float, xi_dot: float, length: float, n_ref: float) -> float:
        c = self.config
        if v < 0.5:
            return self._steer
        l_r = min(0.5 * length, MAX_REAR_AXLE)
        beta_last = math.atan(0.5 * math.tan(self._steer))
        yaw_rate_last = v * math.sin(beta_last) / l_r
        road_turn = yaw_rate_last - xi_dot  # kappa * s_dot (rad/s)
        limit = min(c.lateral_speed, 0.1 * v)  # gentler at low speed
        n_dot = float(np.clip(-(n - n_ref) / c.lateral_time, -limit, limit))
        course_ref = math.asin(max(-0.5, min(0.5, n_dot / v)))  # direction of travel relative to the road
        # the course is xi + beta, and the new command's slip beta ~ yaw_rate l_r / v: solved for the new
        # command (not the last one's slip, which feeds back with alternating sign at low speed)
        yaw_rate = (road_turn + (course_ref - xi) / c.heading_time) / (1.0 + l_r / (v * c.heading_time))
        beta = math.asin(max(-1.0, min(1.0, yaw_rate * l_r / v)))
        steer = math.atan(2.0 * math.tan(beta))
        self._steer = float(np.clip(steer, *c.steering_range))
        return self._steer


def planner_for(env_settings: object, lane_centers: tuple[float, ...], **overrides: object) -> Planner:
    """A ``Planner`` matched to an env's ``EnvConfig`` (acceleration and steering ranges, period) and
    its map's ``lane_centers`` (``info["lane_centers"]``; pass ``lane_directions=info["lane_directions"]``
    and ``lane_kinds=info["lane_kinds"]`` on a two-way road); ``overrides`` set other ``PlannerConfig`` fields."""
    s = env_settings
    if getattr(s, "action", None) != "ContinuousAction":
        raise ValueError("the planner drives with action = 'ContinuousAction'; configure the env with it")
    if getattr(s, "normalize", False):
        raise ValueError("the planner reads unnormalised observations; configure the env with normalize = False")
    config = PlannerConfig(lane_centers=tuple(lane_centers), accel_range=tuple(s.acceleration_range),  # type: ignore[attr-defined]
                           steering_range=tuple(s.steering_range), period=1.0 / s.policy_frequency,  # type: ignore[attr-defined]
                           **overrides)  # type: ignore[arg-type]
    return Planner(config)


__all__ = ["Decision", "Planner", "PlannerConfig", "planner_for"]
