"""Test doubles for the runner (tests only): trackers that report the truth.

``OracleTracker`` runs its own copy of the scenario's ``World`` (the world is deterministic for a
scenario and seed, so the copy has the same truth as the runner's) and reports one ``Track`` per
vehicle whose centre is within ``max_range`` of the ego and on the road -- exactly the runner's truth
set -- at its true road state, optionally perturbed by fixed offsets, with label = vehicle id (or a
relabelling). It never sees the sensor data, so the evaluator's numbers are known in closed form.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sim.world.scenario import ScenarioSpec
from sim.world.world import World
from tracker import Frame, Road, Track, TrackerConfig


class OracleTracker:
    """Reports the true vehicles (see the module docstring). ``offset`` (7,) is added to every
    curvilinear mean ``[s, n, v, xi, xi_dot, L, W]``, and ``offset_of(vid, t) -> (7,)`` on top per
    vehicle; ``relabel(vid, t) -> label``; ``everyone`` reports every vehicle, in range or not."""

    def __init__(self, spec: ScenarioSpec, seed: int, road: Road, *, max_range: float = 100.0,
                 offset: np.ndarray | None = None, offset_of=None, relabel=None,  # noqa: ANN001
                 everyone: bool = False) -> None:
        self.world = World(spec, seed)
        self.road = road
        self.max_range = max_range
        self.offset = np.zeros(7) if offset is None else np.asarray(offset, dtype=float)
        self.offset_of = offset_of
        self.relabel = relabel
        self.everyone = everyone
        self.stats = {"frames": 0}

    def step(self, frame: Frame) -> list[Track]:
        self.stats["frames"] += 1
        snap = self.world.truth_at(frame.t)
        out = []
        for k, vid in enumerate(snap.ids):
            d = float(np.hypot(*(snap.xy[k] - (frame.ego.x, frame.ego.y))))
            on_road = self.road.right_edge <= snap.n[k] <= self.road.left_edge and 0.0 <= snap.s[k] <= self.road.length
            if not self.everyone and (d > self.max_range or not on_road):
                continue
            mean = np.array([snap.s[k], snap.n[k], snap.v[k], snap.xi[k], snap.xi_dot[k], snap.length[k],
                             snap.width[k]]) + self.offset
            if self.offset_of is not None:
                mean = mean + np.asarray(self.offset_of(int(vid), frame.t), dtype=float)
            label = int(vid) if self.relabel is None else int(self.relabel(int(vid), frame.t))
            out.append(Track(label, frame.t, mean, 0.01 * np.eye(7)))
        return out


@dataclass(frozen=True)
class OracleFactory:
    """A picklable ``tracker_factory(road, config)`` building an ``OracleTracker`` for ``spec`` and
    ``seed`` (for process workers)."""

    spec: ScenarioSpec
    seed: int
    kwargs: dict = field(default_factory=dict)

    def __call__(self, road: Road, config: TrackerConfig) -> OracleTracker:
        return OracleTracker(self.spec, self.seed, road, **self.kwargs)


class SilentTracker:
    """Reports no tracks at all."""

    def __init__(self, road: Road, config: TrackerConfig) -> None:
        self.stats = {"frames": 0}

    def step(self, frame: Frame) -> list[Track]:
        self.stats["frames"] += 1
        return []
