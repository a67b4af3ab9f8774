"""The ego of ``eot/TrackedRoad-v0``, driven by the agent's action, and its meta-action type.

Two ego classes share the road-coordinate bookkeeping of ``sim.world.traffic`` (``_FrenetCar``: ``frenet_s``,
``frenet_n``, its lane, the bicycle model with ``rear_axle = min(L / 2, 3 m)``):

- ``MetaEgo`` (``DiscreteMetaAction``): highway-env's ``MDPVehicle`` -- "FASTER"/"SLOWER" step the
  target speed through ``target_speeds``, "LANE_LEFT"/"LANE_RIGHT" set the target lane, a speed
  controller and highway-env's cascaded lane-keeping controller (with ``sim.world.traffic``'s lateral-speed
  limit) do the rest. Two departures, both documented: the speed controller's acceleration is
  clipped to ``acceleration_range`` (highway-env's is unbounded: -33 m/s^2 when asked to go from 20 to
  0 m/s), and "LANE_LEFT" means the driver's left (positive ``n``, lane index + 1 here, since our lane 0
  is the rightmost; docs/architecture.md). highway-env's own roads number lanes the other way round, which is why
  its "LANE_LEFT" decreases the index.
- ``ContinuousEgo`` (``ContinuousAction``): the action ``{"acceleration", "steering"}`` is held until
  the next one (highway-env's ``Vehicle``).

``install_ego(world, ...)`` replaces the world's ego (built by ``sim.world.world.World`` as an IDM car)
with one of these at the same state.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from highway_env.envs.common.action import DiscreteMetaAction
from highway_env.vehicle.controller import MDPVehicle
from highway_env.vehicle.kinematics import Vehicle

from sim.world.lanes import NODE_FROM, NODE_TO, lane_index
from sim.world.traffic import _FrenetCar
from sim.world.driven import DrivenReplayWorld
from sim.world.world import World

#: The driver's left/right in our convention (lane 0 rightmost) -> highway-env's index steps.
_HIGHWAY_LANE_ACTION = {"LANE_LEFT": "LANE_RIGHT", "LANE_RIGHT": "LANE_LEFT"}


class MetaEgo(_FrenetCar, MDPVehicle):
    """highway-env's ``MDPVehicle`` on our road (see the module notes); ``accel_limits`` (m/s^2)
    bound its speed controller."""

    accel_limits: tuple[float, float] = (-8.0, 4.0)

    def act(self, action: Any = None) -> None:
        """Apply a meta-action ("LANE_LEFT" = toward positive ``n``), then lane keeping and speed control."""
        if isinstance(action, str):
            action = _HIGHWAY_LANE_ACTION.get(action, action)
        super().act(action)

    def speed_control(self, target_speed: float) -> float:
        """highway-env's proportional speed controller, clipped to ``accel_limits`` (m/s^2)."""
        low, high = self.accel_limits
        return float(min(max(self.KP_A * (target_speed - self.speed), low), high))


class ContinuousEgo(_FrenetCar, Vehicle):
    """highway-env's ``Vehicle`` on our road: holds the last ``{"acceleration", "steering"}`` action."""


class MetaAction(DiscreteMetaAction):
    """highway-env's ``DiscreteMetaAction`` (0 LANE_LEFT, 1 IDLE, 2 LANE_RIGHT, 3 FASTER, 4 SLOWER) with
    ``get_available_actions`` in our lane convention (LANE_LEFT toward higher lane index)."""

    def get_available_actions(self) -> list[int]:
        """The meta-actions that change something now (IDLE always)."""
        vehicle = self.controlled_vehicle
        lanes = len(vehicle.road.network.graph[NODE_FROM][NODE_TO])
        lane = vehicle.target_lane_index[2]
        actions = [self.actions_indexes["IDLE"]]
        if self.lateral and lane + 1 < lanes:
            actions.append(self.actions_indexes["LANE_LEFT"])
        if self.lateral and lane > 0:
            actions.append(self.actions_indexes["LANE_RIGHT"])
        if self.longitudinal and vehicle.speed_index < vehicle.target_speeds.size - 1:
            actions.append(self.actions_indexes["FASTER"])
        if self.longitudinal and vehicle.speed_index > 0:
            actions.append(self.actions_indexes["SLOWER"])
        return actions


def install_ego(world: World | DrivenReplayWorld, action: str, *, target_speeds: tuple[float, ...],
                accel_limits: tuple[float, float]) -> Vehicle:
    """Replace ``world``'s ego (id 0; a ``World``'s or a ``DrivenReplayWorld``'s) by a ``MetaEgo``
    (``action == "DiscreteMetaAction"``) or a ``ContinuousEgo`` at the same position, heading, speed, lane,
    length and width; its first control is computed at once. Returns the new ego."""
    old = world.ego
    traffic = world.traffic
    position = np.array(old.position, dtype=float)
    lane = (getattr(old, "target_lane_index", None) or old.lane_index)[2]
    if action == "DiscreteMetaAction":
        ego: Any = MetaEgo(traffic, position, float(old.heading), float(old.speed), target_lane_index=lane_index(lane),
                           target_speed=float(old.speed), target_speeds=np.asarray(target_speeds, dtype=float))
        ego.accel_limits = (float(accel_limits[0]), float(accel_limits[1]))
    elif action == "ContinuousAction":
        ego = ContinuousEgo(traffic, position, float(old.heading), float(old.speed))
    else:
        raise ValueError(f"unknown action type {action!r}")
    ego._setup(0, old.LENGTH, old.WIDTH)
    traffic.vehicles[traffic.vehicles.index(old)] = ego
    world.ego = ego
    ego.act()
    return ego


__all__ = ["ContinuousEgo", "MetaAction", "MetaEgo", "install_ego"]
