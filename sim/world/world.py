"""The simulated world: highway-env traffic on our road, advanced to arbitrary times, giving truth.

``World(spec, seed)`` builds the road, the highway-env ``RoadNetwork`` of ``FrenetLane``s and the
vehicles (the ego is id 0, the file's vehicles 1, 2, ... in order). ``advance(t)`` moves the traffic
forward on a fixed internal grid ``k * step`` (``step`` = 0.05 s by default): at each grid time every
vehicle decides its action (IDM/MOBIL, scripts), then all move by ``step`` (highway-env's kinematic
bicycle model, action held over the step). ``truth_at(t)`` returns a ``sim.world.truth.Snapshot`` at any
``t`` between grid times too, by evaluating the same held-action kinematics from the last grid state
over the remaining fraction of a step, without changing the simulation: so the traffic does not
depend on when, or how often, it is observed (lidar at 10 Hz, radars at 14 Hz out of phase, or
nothing), and the same scenario + seed gives bit-identical truth.

Truth per vehicle: ``ids``; centre ``xy`` (m, G); ``yaw`` (rad, wrapped; the body's real heading, about
``theta(s) + pi`` for a vehicle driving against ``s``, so its ``xi`` is about pi); ``v`` speed (m/s, >= 0);
``yaw_rate`` (rad/s) of the bicycle model over the current step; ``length``, ``width`` (m); ``s``, ``n``
(``Road.to_frenet`` of the centre, warm-started); ``xi = yaw - theta(s)`` (wrapped) and
``xi_dot = yaw_rate - kappa(s) * s_dot`` with ``s_dot = v cos(xi + beta) / (1 - kappa n)``.
``yaw`` is the body heading (the rectangle's orientation); highway-env's bicycle model moves the
centre along ``yaw + beta``, ``beta = atan(tan(steering) / 2)`` the slip angle, so a car keeping its
lane on a steady curve has ``xi ~ -beta ~ -l_r kappa`` with ``l_r = min(L / 2, 3 m)`` the centre to
rear axle distance (``sim.world.traffic.MAX_REAR_AXLE``; -0.04 rad for a 4.8 m car at R 60 m),
while ``Snapshot.velocity`` (speed along ``yaw``) differs from the centre's true velocity by ``beta``.

Open roads: a vehicle whose centre passes the end of the road in its direction (``s > length``; ``s < 0``
for a vehicle driving against ``s`` in an oncoming lane, which enters the road at its far end) leaves
the world (its id no longer appears; ``removed`` records when). The ego never leaves: validation rejects scenarios where it could
reach the end, and if it does anyway ``advance`` raises ``ValueError``. Closed roads: ``s`` wraps.
Collisions: highway-env's collision impulses are off (they would move vehicles outside their
kinematics); overlapping rectangles are recorded in ``collisions`` as ``(t, id_a, id_b)`` when an
overlap starts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim.world.ground import RoadGround
from sim.world.lanes import build_network
from sim.world.scenario import ScenarioSpec, polygons_overlap
from sim.world.traffic import TrafficRoad, make_vehicle
from sim.world.truth import EgoPose, Snapshot, rectangle_corners
from tracker import Road
from tracker.angles import wrap_angle

#: Default internal step (s).
DEFAULT_STEP = 0.05
#: Stream tag mixed into the seed for highway-env's random generator (kept apart from the sensors').
WORLD_STREAM = 0x574F524C  # "WORL"
#: Slack (s) when comparing times.
TIME_TOLERANCE = 1e-9


@dataclass(frozen=True)
class VehicleState:
    """Truth of one vehicle: ``vid``; centre ``x, y`` (m, G); ``yaw`` (rad); ``v`` (m/s);
    ``yaw_rate`` (rad/s); ``length``, ``width`` (m); ``s``, ``n`` (m); ``xi`` (rad); ``xi_dot`` (rad/s);
    ``lane`` (0 = rightmost)."""

    vid: int
    x: float
    y: float
    yaw: float
    v: float
    yaw_rate: float
    length: float
    width: float
    s: float
    n: float
    xi: float
    xi_dot: float
    lane: int


class World:
    """highway-env traffic on the scenario's road; see the module notes.

    ``spec`` must be concrete or carry a generator or family (then ``sim.world.generator.realize(spec, seed)`` draws
    the road/traffic first; ``world.spec`` is the drawn scenario). ``seed`` also seeds highway-env's
    ``np_random`` (``numpy.random.Generator``). ``step`` is the internal step (s, in (0, 0.1])."""

    def __init__(self, spec: ScenarioSpec, seed: int = 0, *, step: float = DEFAULT_STEP) -> None:
        if not isinstance(spec, ScenarioSpec):
            raise ValueError(f"World needs a sim.world.scenario.ScenarioSpec; got {type(spec).__name__}")
        if not (isinstance(step, (int, float)) and 0.0 < step <= 0.1):
            raise ValueError(f"World step must be in (0, 0.1] s; got {step!r}")
        if spec.replay is not None:
            raise ValueError(f"{spec.name}: a replay of recorded traffic; its world is sim.world.replay.ReplayWorld")
        if not spec.concrete:
            from sim.world.generator import realize

            spec = realize(spec, seed)
        assert spec.road is not None and spec.ego is not None
        self.spec = spec
        self.seed = int(seed)
        self.step = float(step)
        self.road = spec.build_road()
        network, projector = build_network(self.road, spec.road.to_config())
        rng = np.random.default_rng(np.random.SeedSequence(self.seed, spawn_key=(WORLD_STREAM,)))
        self.traffic = TrafficRoad(network, projector, self.road, np_random=rng, dt=self.step)
        ego = make_vehicle(self.traffic, 0, spec.ego, spec.ego.mobil)
        others = [make_vehicle(self.traffic, i + 1, v, v.mobil) for i, v in enumerate(spec.vehicles)]
        self.traffic.vehicles = [ego, *others]
        self.ego = ego
        #: heights (m) by vehicle id, and the road surface when it has a grade or bank (3-D lidar only)
        self.heights = {0: spec.ego.box_height, **{i + 1: v.box_height for i, v in enumerate(spec.vehicles)}}
        sloped = spec.road.grade != 0.0 or spec.road.bank != 0.0
        self.ground = RoadGround(self.road, spec.road.grade, spec.road.bank) if sloped else None
        self._k = 0
        self.t = 0.0
        self.removed: dict[int, float] = {}
        self.collisions: list[tuple[float, int, int]] = []
        self._overlapping: set[tuple[int, int]] = set()
        self._check_collisions()
        self.traffic.time = 0.0
        self.traffic.act()

    # -- time -----------------------------------------------------------------------------------
    @property
    def grid_time(self) -> float:
        """Time (s) of the last internal grid state."""
        return self._k * self.step

    def advance(self, t: float) -> None:
        """Move the world forward to time ``t`` (s); ``t`` must not be earlier than the last one."""
        t = forward_time(t, self.t, "World.advance")
        while (self._k + 1) * self.step <= t + TIME_TOLERANCE:
            self._grid_step()
        self.t = max(t, self.t)

    def _grid_step(self) -> None:
        traffic = self.traffic
        traffic.step(self.step)
        self._k += 1
        now = self._k * self.step
        traffic.time = now
        if not self.road.closed:
            end = self.road.length
            if self.ego.frenet_s > end or self.ego.frenet_s < 0.0:
                name = self.spec.source or self.spec.name
                raise ValueError(
                    f"{name}: the ego reached the end of the open road (s = {self.ego.frenet_s:.1f} m, outside "
                    f"[0, {end:.1f}] m) at t = {now:.2f} s; lengthen the road or shorten the duration"
                )
            leaving = [v for v in traffic.vehicles if (v.frenet_s > end if v.direction > 0 else v.frenet_s < 0.0)]
            for v in leaving:
                traffic.vehicles.remove(v)
                self.removed[v.vid] = now
        self._check_collisions()
        traffic.act()

    def _check_collisions(self) -> None:
        vehicles = self.traffic.vehicles
        count = len(vehicles)
        if count < 2:
            self._overlapping.clear()
            return
        xy = np.array([v.position for v in vehicles])
        diag = np.array([v.diagonal for v in vehicles])
        d = np.hypot(xy[:, None, 0] - xy[None, :, 0], xy[:, None, 1] - xy[None, :, 1])
        near = np.argwhere(np.triu(d < 0.5 * (diag[:, None] + diag[None, :]), k=1))
        now_overlapping: set[tuple[int, int]] = set()
        if len(near):
            corners = rectangle_corners(
                xy,
                np.array([v.heading for v in vehicles]),
                np.array([v.LENGTH for v in vehicles]),
                np.array([v.WIDTH for v in vehicles]),
            )
            for i, j in near:
                if polygons_overlap(corners[i], corners[j]):
                    pair = tuple(sorted((vehicles[i].vid, vehicles[j].vid)))
                    now_overlapping.add(pair)  # type: ignore[arg-type]
                    if pair not in self._overlapping:
                        self.collisions.append((self.grid_time, pair[0], pair[1]))
        self._overlapping = now_overlapping

    # -- truth ----------------------------------------------------------------------------------
    def _state(self, vehicle: object, fraction: float) -> VehicleState:
        """Truth of ``vehicle`` ``fraction`` s after the last grid time (held action, no mutation)."""
        return VehicleState(*held_state(vehicle, fraction, self.road, self.traffic))

    def states(self) -> list[VehicleState]:
        """Truth of every vehicle in the world at the current time ``t``, the ego first."""
        fraction = max(self.t - self.grid_time, 0.0)
        return [self._state(v, fraction) for v in self.traffic.vehicles]

    def snapshot(self) -> Snapshot:
        """The truth ``Snapshot`` at the current time ``t``: the ego pose and the other vehicles."""
        return self._snapshot(road_coordinates=True)

    def truth_at(self, t: float) -> Snapshot:
        """Advance to ``t`` (s), then return the truth ``Snapshot`` there (what the sensor rig calls)."""
        self.advance(t)
        return self.snapshot()

    def poses_at(self, t: float) -> Snapshot:
        """Advance to ``t`` (s), then return the other vehicles' poses there: a ``Snapshot`` whose road
        coordinates (``s``, ``n``, ``xi``, ``xi_dot``) are NaN and ``z`` 0, the rest (and the ego pose)
        as ``truth_at``'s. What a radar needs, without projecting every vehicle onto the road
        (``SensorRig.frames(..., poses_at=...)``)."""
        self.advance(t)
        return self._snapshot(road_coordinates=False)

    def _snapshot(self, road_coordinates: bool) -> Snapshot:
        fraction = max(self.t - self.grid_time, 0.0)
        vehicles = self.traffic.vehicles
        road_, traffic = self.road, self.traffic
        ego = held_state(vehicles[0], fraction, road_, traffic)
        if road_coordinates:
            others = [held_state(v, fraction, road_, traffic) for v in vehicles[1:]]
        else:
            others = [held_pose(v, fraction) for v in vehicles[1:]]
        # one array of the others' numbers (x, y, yaw, v, yaw_rate, length, width[, s, n, xi, xi_dot]),
        # then each field as a contiguous row of its transpose
        width = 11 if road_coordinates else 7
        cols = np.array([r[1:1 + width] for r in others], dtype=float).reshape(-1, width).T.copy()
        road = {}
        if road_coordinates:
            road = dict(s=cols[7], n=cols[8], xi=cols[9], xi_dot=cols[10],
                        z=np.zeros(len(others)) if self.ground is None else self.ground.height_at(cols[7], cols[8]))
        return Snapshot(
            t=self.t,
            ego=EgoPose(x=ego[1], y=ego[2], yaw=ego[3], v=ego[4], yaw_rate=ego[5], length=ego[6], width=ego[7],
                        z=0.0 if self.ground is None else float(self.ground.height_at(ego[8], ego[9])),
                        height=self.heights[0]),
            ids=np.array([r[0] for r in others], dtype=int),
            xy=np.ascontiguousarray(cols[:2].T),
            yaw=cols[2],
            v=cols[3],
            yaw_rate=cols[4],
            length=cols[5],
            width=cols[6],
            height=np.array([self.heights.get(r[0], 1.5) for r in others]),
            **road,
        )

    def ego_state(self) -> VehicleState:
        """The ego's truth at the current time, with its road coordinates."""
        return self._state(self.ego, max(self.t - self.grid_time, 0.0))

    def run(self, times: np.ndarray | list[float]) -> list[Snapshot]:
        """Snapshots at increasing ``times`` (s)."""
        return [self.truth_at(float(t)) for t in times]


def forward_time(t: object, now: float, where: str) -> float:
    """``t`` (s) as a float, checked: a finite number not earlier than ``now`` (s); ``ValueError`` naming ``where``."""
    if not (isinstance(t, (int, float, np.floating)) and math.isfinite(t)):
        raise ValueError(f"{where}: t must be a finite number of seconds; got {t!r}")
    t = float(t)
    if t < now - TIME_TOLERANCE:
        raise ValueError(f"{where}: time only moves forward; asked for t = {t!r} s after t = {now!r} s")
    return t


def held_pose(vehicle: object, fraction: float) -> tuple:
    """``(vid, x, y, yaw, v, yaw_rate, length, width)`` of the highway-env ``vehicle`` ``fraction`` s after
    its last grid state (its held action over the bicycle model, without moving it), then the heading
    before wrapping and the slip angle (for ``held_state``)."""
    v = vehicle
    action = v.action  # type: ignore[attr-defined]
    steering = float(action["steering"])
    acceleration = float(action["acceleration"])
    speed = float(v.speed)  # type: ignore[attr-defined]
    if speed > v.MAX_SPEED:  # type: ignore[attr-defined]  (highway-env's clip_actions)
        acceleration = min(acceleration, v.MAX_SPEED - speed)  # type: ignore[attr-defined]
    beta = math.atan(0.5 * math.tan(steering))
    yaw_rate = speed * math.sin(beta) / v.rear_axle  # type: ignore[attr-defined]
    heading = float(v.heading)  # type: ignore[attr-defined]
    x, y = float(v.position[0]), float(v.position[1])  # type: ignore[attr-defined]
    if fraction > 0.0:
        x += speed * math.cos(heading + beta) * fraction
        y += speed * math.sin(heading + beta) * fraction
        heading += yaw_rate * fraction
        speed = max(speed + acceleration * fraction, 0.0)
    return (v.vid, x, y, float(wrap_angle(heading)), speed, yaw_rate, float(v.LENGTH), float(v.WIDTH),  # type: ignore[attr-defined]
            heading, beta)


def held_state(vehicle: object, fraction: float, road: Road, traffic: TrafficRoad) -> tuple:
    """``VehicleState``'s fields (a plain tuple, in its order) of ``vehicle`` ``fraction`` s after its last
    grid state on ``road`` (``held_pose`` plus the road coordinates; ``traffic`` gives the lane)."""
    v = vehicle
    vid, x, y, yaw, speed, yaw_rate, length, width, heading, beta = held_pose(vehicle, fraction)
    if fraction > 0.0:
        s, n = road.to_frenet((x, y), s_hint=v.frenet_s)  # type: ignore[attr-defined]
    else:
        s, n = v.frenet_s, v.frenet_n  # type: ignore[attr-defined]
    _, _, c, sn, kappa = road.frame1(float(s))  # scalar fast path of tracker.Road
    theta = math.atan2(sn, c)
    xi = float(wrap_angle(heading - theta))
    s_dot = speed * math.cos(xi + beta) / max(1.0 - kappa * n, 1e-6)
    return (vid, x, y, yaw, speed, yaw_rate, length, width, float(s), float(n), xi, yaw_rate - kappa * s_dot,
            traffic.lane_of(float(n), float(s)))
