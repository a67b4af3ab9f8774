"""highway-env traffic on our road: vehicle classes per behaviour and the highway-env ``Road`` they share.

- ``idm`` -> ``IDMCar`` (highway-env ``IDMVehicle``: IDM car following, MOBIL lane changes when on);
- ``constant`` -> ``ConstantCar`` (highway-env ``ControlledVehicle`` holding its lane and speed,
  ignoring traffic);
- ``scripted`` -> ``ScriptedCar`` (an ``IDMVehicle`` without MOBIL, steered through
  ``target_lane_index`` / ``target_speed`` by its maneuvers: lane changes follow a quintic lateral
  profile that completes within the maneuver's duration; speed changes are rate-limited (``accel`` m/s^2 each way, then a smooth approach with highway-env's
  ``KP_A``); braking is a constant deceleration (``decel`` m/s^2) that lands exactly on the target speed
  (0 m/s: a stop, after which the vehicle stands still until a later maneuver); IDM's interaction term
  still keeps it from running into the vehicle ahead. A script's own rates may exceed highway-env's
  ``ACC_MAX`` (6 m/s^2): an emergency brake at 8 m/s^2 is not clipped to 6).

All of them share ``_FrenetCar``: per-vehicle ``LENGTH``/``WIDTH`` and ``rear_axle`` (the bicycle
model's centre-to-rear-axle distance: ``min(length / 2, MAX_REAR_AXLE)``, so trucks and buses do not
swing out of their lane on tight bends); after every step the vehicle's
road coordinates ``frenet_s``, ``frenet_n`` are projected with a warm start and its lane is the one
containing ``n`` (the same answer as highway-env's closest-lane search for parallel lanes, without
projecting on every lane); distances along the road are differences of ``s``, wrapped on a closed road, taken in the vehicle's
own direction (``direction`` -1 in an oncoming lane: the vehicle ahead has the smaller ``s``);
speed never goes below 0 (a braking vehicle stops instead of reversing, and a vehicle at 0 m/s with
nothing to accelerate it stays at 0: highway-env's ``MIN_SPEED`` of -40 m/s is never reached); the IDM
jam distance is 5 m bumper to bumper whatever the vehicles' lengths (highway-env assumes 5 m cars), so
18 m buses and 2.2 m motorcycles queue with the same gaps as cars. A ``constant`` vehicle at speed 0 is
a vehicle standing still on the road.

``TrafficRoad`` is highway-env's ``Road`` with a neighbour search on the stored ``(s, n)`` that wraps
on closed roads, ``time`` (s, set by the world) and ``dt`` (s, the world's step) for the scripts, and
no collision physics:
highway-env's impulses would move vehicles outside their kinematics; ``sim.world.world`` detects and
records overlaps instead.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from highway_env import utils
from highway_env.road.road import Road as HighwayRoad
from highway_env.road.road import RoadNetwork
from highway_env.utils import wrap_to_pi
from highway_env.vehicle.behavior import IDMVehicle
from highway_env.vehicle.controller import ControlledVehicle

from sim.world.lanes import NODE_FROM, NODE_TO, FrenetProjector, LaneTable, lane_index
from sim.world.scenario import Brake, LaneChange, SpeedChange, VehicleSpec
from tracker import Road

#: IDM jam distance between bumpers (m); highway-env's is 10 m between centres of 5 m cars.
JAM_GAP = 5.0
#: Default acceleration / deceleration limits (m/s^2) of a scripted vehicle's speed tracking.
SCRIPTED_ACCEL = 2.0
SCRIPTED_DECEL = 3.0
#: Largest lateral speed (m/s) the lane-keeping controller commands. highway-env's gain alone asks
#: for ~6 m/s at the start of a MOBIL lane change (a 1.6 rad/s yaw rate at 20 m/s); drivers change
#: lanes at ~1 m/s over 3-4 s. Scripted lane changes add their profile's rate as feed-forward.
MAX_LATERAL_SPEED = 1.5
#: Default step (s) over which a vehicle's action is held (``sim.world.world`` passes its own step).
DEFAULT_DT = 0.05
#: Largest distance (m) from a vehicle's rectangle centre to the rear axle of the kinematic bicycle
#: model. highway-env puts the axles at the bumpers (``l_r = length / 2``), which for a 12 m truck on a
#: R 40 m bend turns the body 0.15 rad off its path and swings its corners out of the lane; real rigid
#: trucks and buses have overhangs (rear axle ~3 m behind the centre). Vehicles up to 6 m long keep
#: highway-env's ``length / 2`` exactly.
MAX_REAR_AXLE = 3.0
#: Extra bumper-to-bumper clearance (m) a ``wait_for_gap`` lane change needs in the target lane.
GAP_CLEARANCE = 3.0


class TrafficRoad(HighwayRoad):
    """highway-env ``Road`` over ``FrenetLane``s: neighbour search on stored road coordinates
    (wrapping on closed roads), no collision physics, and the simulated ``time`` (s)."""

    def __init__(self, network: RoadNetwork, projector: FrenetProjector, road: Road, np_random: Any,
                 dt: float = DEFAULT_DT) -> None:
        super().__init__(network=network, vehicles=[], np_random=np_random, record_history=False)
        if not (isinstance(dt, (int, float)) and 0.0 < dt <= 1.0):
            raise ValueError(f"TrafficRoad dt must be a step in (0, 1] s; got {dt!r}")
        self.projector = projector
        self.geometry = road
        self.time = 0.0
        self.dt = float(dt)
        self.closed = road.closed
        self.period = road.length
        self.lanes = network.graph[NODE_FROM][NODE_TO]
        #: per lane: direction (+1 along s, -1 against)
        self.directions = [int(lane.direction) for lane in self.lanes]
        #: the lanes' centres, widths and the lane of an offset at each s (``sim.world.lanes.LaneTable``)
        self.table = LaneTable.of(road)

    def center(self, lane: int, s: float) -> float:
        """Offset ``n`` (m) of lane ``lane``'s centre at ``s``."""
        return self.table.centre(lane, s)

    def width_of(self, lane: int, s: float) -> float:
        """Width (m) of lane ``lane`` at ``s``."""
        return self.table.width(lane, s)

    def wrap(self, ds: float) -> float:
        """A difference of ``s`` (m) wrapped into ``[-length/2, length/2)`` on a closed road."""
        if self.closed:
            half = 0.5 * self.period
            return (ds + half) % self.period - half
        return ds

    def lane_of(self, n: float, s: float = 0.0) -> int:
        """The lane (0..lanes-1) whose span contains lateral offset ``n`` (at ``s`` where the lanes vary;
        clamped at the edges)."""
        return self.table.lane_of(n, s)

    def step(self, dt: float) -> None:
        """Move every vehicle by ``dt`` seconds (no collision handling; see the module notes)."""
        self.projector.clear()
        for vehicle in self.vehicles:
            vehicle.step(dt)

    def neighbour_vehicles(self, vehicle: Any, lane_index: tuple | None = None) -> tuple[Any, Any]:
        """The vehicles just ahead and just behind ``vehicle`` in lane ``lane_index`` (default: its
        own): highway-env's rule (a vehicle is in a lane within lane width / 2 + 1 m of its centre)
        on stored ``(s, n)``, with wrapped distances on a closed road."""
        lane_index = lane_index or vehicle.lane_index
        if not lane_index:
            return None, None
        s = vehicle.frenet_s
        centre = self.center(lane_index[2], s)
        reach = 0.5 * self.width_of(lane_index[2], s) + 1.0
        backward = self.directions[lane_index[2]] < 0
        front = rear = None
        d_front = d_rear = math.inf
        closed, period, half = self.closed, self.period, 0.5 * self.period
        for other in self.vehicles:
            if other is vehicle or abs(other.frenet_n - centre) > reach:
                continue
            ds = other.frenet_s - s
            if closed:
                ds = (ds + half) % period - half
            if backward:
                ds = -ds
            if ds >= 0.0:
                if ds < d_front:
                    d_front, front = ds, other
            elif -ds < d_rear:
                d_rear, rear = -ds, other
        return front, rear


class _FrenetCar:
    """Behaviour shared by our vehicle classes (mixed in before highway-env's class)."""

    road: TrafficRoad
    vid: int
    frenet_s: float
    frenet_n: float
    #: +1: drives along ``s``; -1: against it (a vehicle of an oncoming lane); lane changes keep it
    direction: int = 1
    #: Lateral offset (m) of its path from the target lane's centre, to the left of its driving direction
    lane_offset: float = 0.0

    def _setup(self, vid: int, length: float, width: float) -> None:
        self.vid = int(vid)
        self.LENGTH = float(length)
        self.WIDTH = float(width)
        self.diagonal = math.hypot(self.LENGTH, self.WIDTH)
        self.rear_axle = min(self.LENGTH / 2, MAX_REAR_AXLE)
        self.frenet_s = math.nan
        self._locate(None)

    def _locate(self, hint: float | None) -> None:
        road = self.road
        s, n = road.projector.prime(float(self.position[0]), float(self.position[1]), hint)
        self.frenet_s, self.frenet_n = s, n
        k = road.lane_of(n, s)
        self.lane_index = (NODE_FROM, NODE_TO, k)
        self.lane = road.lanes[k]

    def on_state_update(self) -> None:
        """After a step: project the new position (warm start from the previous ``s``), set the lane."""
        self._locate(self.frenet_s)

    # -- the hot path, in plain Python (the same equations as highway-env's numpy code) --------
    def _move(self, dt: float) -> None:
        """highway-env's ``Vehicle.step``: kinematic bicycle model with the held action (yaw rate
        ``v sin(beta) / rear_axle``), then the state update; speed is kept >= 0. (No collision
        impulses: see the module notes.)"""
        self.clip_actions()  # type: ignore[attr-defined]
        beta = math.atan(0.5 * math.tan(self.action["steering"]))  # type: ignore[attr-defined]
        speed, heading = self.speed, self.heading  # type: ignore[attr-defined]
        position = self.position  # type: ignore[attr-defined]
        position[0] += speed * math.cos(heading + beta) * dt
        position[1] += speed * math.sin(heading + beta) * dt
        self.heading = heading + speed * math.sin(beta) / self.rear_axle * dt
        self.speed = max(speed + self.action["acceleration"] * dt, 0.0)  # type: ignore[attr-defined]
        self.on_state_update()

    def step(self, dt: float) -> None:
        self._move(dt)

    def lane_distance_to(self, other: Any, lane: Any = None) -> float:
        """Signed distance along the road (m) from this vehicle's centre to ``other``'s (wrapped)."""
        if not other:
            return math.nan
        if self.direction < 0:
            return -self.road.wrap(other.frenet_s - self.frenet_s)
        return self.road.wrap(other.frenet_s - self.frenet_s)

    def desired_gap(self, ego_vehicle: Any, front_vehicle: Any = None, projected: bool = True) -> float:
        """IDM desired centre distance (m): jam gap between bumpers + half lengths + time gap term."""
        ab = -IDMVehicle.COMFORT_ACC_MAX * IDMVehicle.COMFORT_ACC_MIN
        if projected:  # (v_ego - v_front) . direction_ego
            dv = ego_vehicle.speed - front_vehicle.speed * math.cos(front_vehicle.heading - ego_vehicle.heading)
        else:
            dv = ego_vehicle.speed - front_vehicle.speed
        d0 = JAM_GAP + 0.5 * (ego_vehicle.LENGTH + front_vehicle.LENGTH)
        return d0 + ego_vehicle.speed * IDMVehicle.TIME_WANTED + ego_vehicle.speed * dv / (2.0 * math.sqrt(ab))

    def acceleration(self, ego_vehicle: Any, front_vehicle: Any = None, rear_vehicle: Any = None) -> float:
        """IDM acceleration (m/s^2) of ``ego_vehicle`` behind ``front_vehicle`` (highway-env's model;
        our lanes have no speed limit)."""
        if not ego_vehicle:
            return 0.0
        target = getattr(ego_vehicle, "target_speed", 0.0)
        acc = IDMVehicle.COMFORT_ACC_MAX * (1.0 - (max(ego_vehicle.speed, 0.0) / abs(utils.not_zero(target))) ** IDMVehicle.DELTA)
        if front_vehicle:
            d = ego_vehicle.lane_distance_to(front_vehicle)
            acc -= IDMVehicle.COMFORT_ACC_MAX * (self.desired_gap(ego_vehicle, front_vehicle) / utils.not_zero(d)) ** 2
        return acc

    def lateral_reference(self) -> tuple[float, float]:
        """Reference lateral offset from the target lane centre (m) and its rate (m/s): ``lane_offset``, 0."""
        return self.lane_offset, 0.0

    def steering_control(self, target_lane_index: tuple) -> float:
        """highway-env's cascaded lateral controller (lateral position -> lateral speed -> heading ->
        steering), tracking ``lateral_reference()`` with its rate as feed-forward; the feedback part of
        the lateral speed command is limited to ``MAX_LATERAL_SPEED``."""
        target_lane = self.road.network.get_lane(target_lane_index)
        s, lateral = target_lane.local_coordinates(self.position)  # type: ignore[attr-defined]
        reference, reference_rate = self.lateral_reference()
        speed = utils.not_zero(self.speed)  # type: ignore[attr-defined]
        feedback = -ControlledVehicle.KP_LATERAL * (lateral - reference)
        lateral_speed_command = reference_rate + min(max(feedback, -MAX_LATERAL_SPEED), MAX_LATERAL_SPEED)
        heading_command = math.asin(min(max(lateral_speed_command / speed, -1.0), 1.0))
        future = s + self.speed * ControlledVehicle.TAU_PURSUIT  # type: ignore[attr-defined]
        heading_ref = target_lane.heading_at(future) + min(max(heading_command, -math.pi / 4), math.pi / 4)
        heading_rate_command = ControlledVehicle.KP_HEADING * utils.wrap_to_pi(heading_ref - self.heading)  # type: ignore[attr-defined]
        slip = math.asin(min(max(self.rear_axle / speed * heading_rate_command, -1.0), 1.0))
        steering = math.atan(2.0 * math.tan(slip))
        limit = ControlledVehicle.MAX_STEERING_ANGLE
        return float(min(max(steering, -limit), limit))


class IDMCar(_FrenetCar, IDMVehicle):
    """highway-env ``IDMVehicle`` on our road (behaviour ``idm``)."""

    def act(self, action: Any = None) -> None:
        """``IDMVehicle.act`` without numpy scalars: MOBIL (when on), lane keeping, IDM in the current
        lane and, while changing lanes, also in the target lane (the smaller acceleration wins)."""
        self.follow_road()
        if self.enable_lane_change:
            self.change_lane_policy()
        steering = self.steering_control(self.target_lane_index)
        front, rear = self.road.neighbour_vehicles(self, self.lane_index)
        acc = self.acceleration(ego_vehicle=self, front_vehicle=front, rear_vehicle=rear)
        if self.lane_index != self.target_lane_index:
            front, rear = self.road.neighbour_vehicles(self, self.target_lane_index)
            acc = min(acc, self.acceleration(ego_vehicle=self, front_vehicle=front, rear_vehicle=rear))
        low, high = self.acceleration_limits()
        self.action = {"steering": steering, "acceleration": min(max(acc, low), high)}

    def acceleration_limits(self) -> tuple[float, float]:
        """Bounds (m/s^2) of the commanded acceleration: highway-env's ``[-ACC_MAX, ACC_MAX]``."""
        return -self.ACC_MAX, self.ACC_MAX

    def step(self, dt: float) -> None:
        self.timer += dt
        self._move(dt)


class ConstantCar(_FrenetCar, ControlledVehicle):
    """Keeps its lane at constant speed, ignoring other vehicles (behaviour ``constant``)."""

    def act(self, action: Any = None) -> None:
        """Lane keeping (highway-env's controller) and no acceleration."""
        self.follow_road()
        self.action = {"steering": self.steering_control(self.target_lane_index), "acceleration": 0.0}


def _smoothstep(u: float) -> tuple[float, float]:
    """Quintic 10u^3 - 15u^4 + 6u^5 on [0, 1] and its derivative (zero slope and curvature at ends)."""
    if u >= 1.0:
        return 1.0, 0.0
    if u <= 0.0:
        return 0.0, 0.0
    return u * u * u * (10.0 + u * (-15.0 + 6.0 * u)), 30.0 * u * u * (1.0 - u) ** 2


class ScriptedCar(IDMCar):
    """An ``IDMVehicle`` without MOBIL that follows timed maneuvers (behaviour ``scripted``).

    ``maneuvers`` run in order when ``road.time`` reaches their ``t`` (a lane change also waits
    for a running lane change to finish, and with ``wait_for_gap`` for a gap; later maneuvers wait
    behind it): ``LaneChange`` sets
    ``target_lane_index`` and steers along a quintic lateral profile from the current offset to the
    target lane centre over ``duration`` s (feed-forward lateral speed + highway-env's cascaded
    lateral/heading controller); ``SpeedChange`` sets ``target_speed`` and the rate limit ``accel``
    both ways (approached smoothly, gain ``KP_A``); ``Brake`` sets ``target_speed`` and decelerates at
    exactly ``decel`` until the speed lands on the target within one step (``road.dt``), then holds it.
    ``started`` records ``(maneuver index, start time)`` of every maneuver that ran."""

    def configure(self, maneuvers: Sequence[LaneChange | SpeedChange | Brake]) -> None:
        """Set the script (sorted by time) and the default speed-tracking limits."""
        self.enable_lane_change = False
        self.maneuvers = list(maneuvers)
        self._next = 0
        self.started: list[tuple[int, float]] = []
        self.accel_limit = SCRIPTED_ACCEL
        self.decel_limit = SCRIPTED_DECEL
        self.braking = False  # a Brake is running: constant deceleration landing on target_speed
        self._profile: tuple[float, float, float] | None = None  # start time, duration, start offset

    def act(self, action: Any = None) -> None:
        self._run_script()
        super().act(action)

    def acceleration_limits(self) -> tuple[float, float]:
        """highway-env's ``[-ACC_MAX, ACC_MAX]`` widened to the script's own rates, so an 8 m/s^2
        emergency brake (or a hard speed change) is not clipped to 6 m/s^2."""
        return -max(self.ACC_MAX, self.decel_limit), max(self.ACC_MAX, self.accel_limit)

    def _run_script(self) -> None:
        now = self.road.time + 1e-9
        while self._next < len(self.maneuvers) and self.maneuvers[self._next].t <= now:
            m = self.maneuvers[self._next]
            if isinstance(m, LaneChange):
                if self._profile is not None and self.road.time < self._profile[0] + self._profile[1] - 1e-9:
                    return  # one lane change at a time: wait for the running one to finish
                if m.wait_for_gap and not self.gap_is_clear(m.lane):
                    return  # try again next step; later maneuvers wait behind this one
                target = lane_index(m.lane)
                lat0 = self.direction * (self.frenet_n - self.road.center(m.lane, self.frenet_s))  # in the lane's own frame
                self.target_lane_index = target
                self._profile = (self.road.time, m.duration, lat0)
            elif isinstance(m, SpeedChange):
                self.target_speed = m.speed
                self.accel_limit = self.decel_limit = m.accel
                self.braking = False
            elif isinstance(m, Brake):
                self.target_speed = m.speed
                self.decel_limit = m.decel
                self.braking = True
            self.started.append((self._next, self.road.time))
            self._next += 1

    def gap_is_clear(self, lane: int) -> bool:
        """Whether lane ``lane`` has room alongside: no vehicle overlapping it within half lengths +
        ``GAP_CLEARANCE`` m, and MOBIL's safe-braking test for this car and its new follower."""
        road = self.road
        centre = road.center(lane, self.frenet_s)
        width = road.width_of(lane, self.frenet_s)
        for other in road.vehicles:
            if other is self:
                continue
            if abs(other.frenet_n - centre) >= 0.5 * (width + other.WIDTH):
                continue
            if abs(road.wrap(other.frenet_s - self.frenet_s)) < 0.5 * (self.LENGTH + other.LENGTH) + GAP_CLEARANCE:
                return False
        front, rear = road.neighbour_vehicles(self, lane_index(lane))
        limit = -self.LANE_CHANGE_MAX_BRAKING_IMPOSED
        if rear is not None and self.acceleration(ego_vehicle=rear, front_vehicle=self) < limit:
            return False
        if front is not None and self.acceleration(ego_vehicle=self, front_vehicle=front) < limit:
            return False
        return True

    def lateral_reference(self) -> tuple[float, float]:
        """The lane-change profile: offset from the target lane centre (m) and its rate (m/s), from the
        offset at the start of the change to ``lane_offset``."""
        if self._profile is None:
            return self.lane_offset, 0.0
        t0, duration, lat0 = self._profile
        u = (self.road.time - t0) / duration
        if u >= 1.0:
            self._profile = None
            return self.lane_offset, 0.0
        p, dp = _smoothstep(u)
        return lat0 + (self.lane_offset - lat0) * p, (self.lane_offset - lat0) * dp / duration

    def acceleration(self, ego_vehicle: Any, front_vehicle: Any = None, rear_vehicle: Any = None) -> float:
        """For itself: rate-limited tracking of ``target_speed`` plus IDM's interaction term with the
        vehicle ahead; for another vehicle (MOBIL's what-ifs): plain IDM."""
        if ego_vehicle is not self:
            return _FrenetCar.acceleration(self, ego_vehicle, front_vehicle, rear_vehicle)
        if self.braking and self.speed > self.target_speed:
            # constant deceleration, landing exactly on the target speed at the end of a step
            free = -min(self.decel_limit, (self.speed - self.target_speed) / self.road.dt)
        else:
            free = self.KP_A * (self.target_speed - self.speed)
        acc = min(max(free, -self.decel_limit), self.accel_limit)
        if front_vehicle:
            d = self.lane_distance_to(front_vehicle)
            acc -= self.COMFORT_ACC_MAX * (self.desired_gap(self, front_vehicle) / utils.not_zero(d)) ** 2
        return acc


def make_vehicle(road: TrafficRoad, vid: int, spec: VehicleSpec, mobil: bool) -> _FrenetCar:
    """Build the vehicle ``spec`` (id ``vid``) on ``road``: placed at its lane centre at ``s``,
    heading in its lane's direction (along the road, or against it in an oncoming lane; turned round
    when ``facing = "backward"``), at ``speed``, ``offset`` m off the centre; ``mobil`` switches MOBIL on for ``idm``."""
    lane = road.lanes[spec.lane]
    local = spec.s if lane.direction > 0 else lane.length - spec.s
    position = lane.position(local, spec.offset)
    heading = lane.heading_at(local)
    if spec.facing == "backward":
        heading = float(wrap_to_pi(heading + math.pi))
    index = lane_index(spec.lane)
    vehicle: Any
    if spec.behaviour == "idm":
        vehicle = IDMCar(road, position, heading, spec.speed, target_lane_index=index,
                         target_speed=spec.cruise_speed, enable_lane_change=mobil)
    elif spec.behaviour == "constant":
        vehicle = ConstantCar(road, position, heading, spec.speed, target_lane_index=index, target_speed=spec.speed)
    else:
        vehicle = ScriptedCar(road, position, heading, spec.speed, target_lane_index=index,
                              target_speed=spec.cruise_speed, enable_lane_change=False)
        vehicle.configure(spec.maneuvers)
    vehicle.target_speed = spec.speed if spec.behaviour == "constant" else spec.cruise_speed  # 0 is a valid target
    vehicle.direction = lane.direction
    vehicle.lane_offset = float(spec.offset)
    vehicle._setup(vid, spec.length, spec.width)
    return vehicle
