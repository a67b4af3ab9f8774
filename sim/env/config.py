"""Typed, validated configuration of ``eot/TrackedRoad-v0`` (``EnvConfig``).

highway-env keeps its configuration in a plain dict and silently ignores a misspelt key; here every
key is a field of a frozen dataclass with a documented default and unit, and ``EnvConfig.from_mapping``
rejects unknown keys and bad values with a ``ConfigError`` (a ``ValueError``) that names the key, the
value and what is allowed. highway-env's own spelling of the action is accepted too:
``{"action": {"type": "ContinuousAction", "acceleration_range": [-6, 3]}}`` sets ``action``,
``acceleration_range`` (and ``steering_range`` / ``target_speeds``).

Fields (SI units):

- ``scenario`` ("curve-single"): a scenario name of ``scenarios/`` or a path to a scenario file. A
  scenario with a ``[generator]`` table (e.g. "random-road") draws a new road and traffic for every
  ``reset(seed=...)``.
- ``variant`` ("curvilinear-fused"): the tracker variant (``sim.evaluation.variants``), used with
  ``perception = "tracks"``.
- ``perception`` ("tracks"): "tracks" (rows from the tracker's tracks) or "truth" (the same layout from
  ground truth; see ``sim.env.observation``).
- ``max_tracks`` (10): rows for other vehicles (the nearest along the road are kept); the observation
  has ``1 + max_tracks`` rows, the first being the ego, and ``info["labels"]`` one label per row.
- ``normalize`` (False): divide each column by the larger magnitude of its bounds
  (``sim.env.observation.scales``; the box becomes [-1, 1] or [0, 1]). Unnormalised, the columns are
  in SI units within physical bounds (``sim.env.observation.limits``: ``ds`` within twice the lidar
  range, ``n`` within 20 m, ``v`` in [0, 50] m/s, ...).
- ``action`` ("DiscreteMetaAction"): "DiscreteMetaAction" (highway-env's meta-actions) or
  "ContinuousAction" ([acceleration, steering] in [-1, 1]^2, mapped linearly onto the ranges below).
- ``target_speeds`` (0, 5, ..., 30 m/s): the speeds "FASTER"/"SLOWER" step through (meta-actions).
- ``acceleration_range`` (-8, 4) m/s^2: the continuous action's acceleration interval, and the limits of
  the meta-action ego's speed controller (highway-env's is unlimited).
- ``steering_range`` (-pi/4, pi/4) rad: the continuous action's steering interval (highway-env's).
- ``policy_frequency`` (5 Hz): actions per second. The world runs on its 0.05 s grid, the lidar at
  10 Hz and the radars at 14 Hz; the lidar rate must be a whole multiple of the policy frequency
  (10, 5, 2.5, 2, 1, ... Hz) so that every observation is made at a lidar frame.
- ``duration`` (None: the scenario's) s: truncation time, at most the scenario's duration; an episode
  has ``episode_steps()`` = ``ceil(duration * policy_frequency)`` steps (100 for the defaults: the
  registered ``max_episode_steps``).
- ``roadside`` (None: the scenario's ``sensors.roadside``): force roadside clutter on/off.
- ``faults`` (None: the scenario's ``[faults]``): sensor faults for the episode, a dict of
  ``sim.world.scenario.FaultsSpec`` fields (``lidar_dropout``, ``radar_dropout``, ``radar_missing``,
  ``lidar_time_offset``, ``lidar_spikes``) that replaces the scenario's; ``{}`` runs without faults.
  Duplicated frames are not supported in the loop (an observation falls on every lidar frame).
- Reward (highway-env's ``highway-v0`` terms): ``collision_reward`` (-1), ``high_speed_reward`` (0.4,
  linear in the speed along the road over ``reward_speed_range`` (20, 30) m/s), ``right_lane_reward``
  (0.1, for the rightmost lane = our lane 0), ``normalize_reward`` (True: mapped onto [0, 1]),
  ``offroad_terminal`` (False: leaving the road ends the episode when True; the reward is 0 off the road).
- Rendering: ``screen_width`` x ``screen_height`` (600 x 600 px), ``view_half_width`` (50 m each way
  around the ego).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields, replace
from typing import Any

from sim.evaluation.variants import DEFAULT_VARIANT, UnknownVariantError, check_variant

PERCEPTIONS = ("tracks", "truth")
ACTIONS = ("DiscreteMetaAction", "ContinuousAction")
#: The world's internal step (s): ``sim.world.world.DEFAULT_STEP``; highway-env calls its inverse the
#: simulation frequency.
SIMULATION_FREQUENCY = 20


def _steps(duration: float, frequency: float) -> int:
    """Policy steps in ``duration`` s at ``frequency`` Hz (the env truncates at the first step whose
    time reaches ``duration``)."""
    return max(1, math.ceil(duration * frequency - 1e-9))


class ConfigError(ValueError):
    """An invalid ``eot/TrackedRoad-v0`` configuration; the message names the key and what is allowed."""


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(float(value))


def _pair(key: str, value: Any, *, increasing: bool = True) -> tuple[float, float]:
    if not (isinstance(value, (list, tuple)) and len(value) == 2 and all(_number(v) for v in value)):
        raise ConfigError(f"config key {key!r} = {value!r}: must be a pair [low, high] of finite numbers")
    low, high = float(value[0]), float(value[1])
    if increasing and not low < high:
        raise ConfigError(f"config key {key!r} = {value!r}: low must be < high")
    return low, high


@dataclass(frozen=True)
class EnvConfig:
    """Configuration of ``TrackedRoadEnv``; the module docstring documents every field."""

    scenario: str = "curve-single"
    variant: str = DEFAULT_VARIANT
    perception: str = "tracks"
    max_tracks: int = 10
    normalize: bool = False
    action: str = "DiscreteMetaAction"
    target_speeds: tuple[float, ...] = (0.0, 5.0, 10.0, 15.0, 20.0, 25.0, 30.0)
    acceleration_range: tuple[float, float] = (-8.0, 4.0)
    steering_range: tuple[float, float] = (-math.pi / 4, math.pi / 4)
    policy_frequency: float = 5.0
    duration: float | None = None
    roadside: bool | None = None
    faults: Mapping[str, Any] | None = None
    collision_reward: float = -1.0
    high_speed_reward: float = 0.4
    right_lane_reward: float = 0.1
    reward_speed_range: tuple[float, float] = (20.0, 30.0)
    normalize_reward: bool = True
    offroad_terminal: bool = False
    screen_width: int = 600
    screen_height: int = 600
    view_half_width: float = 50.0

    def __post_init__(self) -> None:
        def bad(key: str, allowed: str) -> ConfigError:
            return ConfigError(f"config key {key!r} = {getattr(self, key)!r}: {allowed}")

        if not isinstance(self.scenario, str) or not self.scenario:
            raise bad("scenario", "must be a scenario name (see `eot scenarios`) or a path to a .toml file")
        try:
            check_variant(self.variant)
        except UnknownVariantError as exc:
            raise ConfigError(f"config key 'variant': {exc}") from None
        if self.perception not in PERCEPTIONS:
            raise bad("perception", f"must be one of {', '.join(map(repr, PERCEPTIONS))}")
        if isinstance(self.max_tracks, bool) or not isinstance(self.max_tracks, int) or not 1 <= self.max_tracks <= 200:
            raise bad("max_tracks", "must be an integer in [1, 200]")
        for key in ("normalize", "normalize_reward", "offroad_terminal"):
            if not isinstance(getattr(self, key), bool):
                raise bad(key, "must be true or false")
        if self.roadside is not None and not isinstance(self.roadside, bool):
            raise bad("roadside", "must be true, false or None (the scenario's setting)")
        if self.faults is not None:
            from pydantic import ValidationError

            from sim.world.scenario import FaultsSpec, format_validation_error

            if not isinstance(self.faults, Mapping):
                raise bad("faults", "must be a dict of sensor faults (sim.world.scenario.FaultsSpec fields) or None")
            try:
                spec = FaultsSpec.model_validate(dict(self.faults))
            except ValidationError as exc:
                raise ConfigError(f"config key 'faults': {' '.join(format_validation_error(exc, 'faults').split())}") from None
            if spec.duplicate_frames:
                raise bad("faults", "duplicate_frames is not supported in the loop (an observation falls on every lidar frame)")
            object.__setattr__(self, "faults", spec.model_dump())
        if self.action not in ACTIONS:
            raise bad("action", f"must be one of {', '.join(map(repr, ACTIONS))}")
        speeds = self.target_speeds
        if not (isinstance(speeds, (list, tuple)) and len(speeds) >= 2 and all(_number(v) for v in speeds)):
            raise bad("target_speeds", "must be a list of at least two speeds (m/s)")
        diffs = [b - a for a, b in zip(speeds, speeds[1:])]
        if speeds[0] < 0 or speeds[-1] > 40 or min(diffs) <= 0 or max(diffs) - min(diffs) > 1e-9 * max(1.0, speeds[-1]):
            raise bad("target_speeds", "must be evenly spaced, increasing, within [0, 40] m/s "
                                       "(highway-env's MDPVehicle assumes a uniform grid)")
        object.__setattr__(self, "target_speeds", tuple(float(v) for v in speeds))
        acc = _pair("acceleration_range", self.acceleration_range)
        if not (acc[0] < 0.0 < acc[1]):
            raise bad("acceleration_range", "must contain 0 (braking < 0 < accelerating), m/s^2")
        object.__setattr__(self, "acceleration_range", acc)
        steer = _pair("steering_range", self.steering_range)
        if not (-math.pi / 2 < steer[0] < 0.0 < steer[1] < math.pi / 2):
            raise bad("steering_range", "must satisfy -pi/2 < low < 0 < high < pi/2 (rad)")
        object.__setattr__(self, "steering_range", steer)
        object.__setattr__(self, "reward_speed_range", _pair("reward_speed_range", self.reward_speed_range))
        if not _number(self.policy_frequency) or not 0.0 < self.policy_frequency <= SIMULATION_FREQUENCY:
            raise bad("policy_frequency", f"must be a number of Hz in (0, {SIMULATION_FREQUENCY}]")
        object.__setattr__(self, "policy_frequency", float(self.policy_frequency))
        if self.duration is not None and (not _number(self.duration) or self.duration <= 0):
            raise bad("duration", "must be a positive number of seconds or None (the scenario's)")
        for key in ("collision_reward", "high_speed_reward", "right_lane_reward"):
            if not _number(getattr(self, key)):
                raise bad(key, "must be a finite number")
            object.__setattr__(self, key, float(getattr(self, key)))
        for key in ("screen_width", "screen_height"):
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, int) or not 64 <= value <= 4096:
                raise bad(key, "must be an integer number of pixels in [64, 4096]")
        if not _number(self.view_half_width) or not 5.0 <= self.view_half_width <= 500.0:
            raise bad("view_half_width", "must be a number of metres in [5, 500]")

    def episode_steps(self) -> int:
        """Steps in an episode: ``ceil(duration * policy_frequency)``, with the scenario's duration when
        ``duration`` is None (loads the scenario). Pass it as ``gym.make(..., max_episode_steps=...)``
        when it exceeds the registered 100."""
        duration = self.duration
        if duration is None:
            from sim.world.scenario import load_scenario

            duration = load_scenario(self.scenario).duration
        return _steps(float(duration), self.policy_frequency)

    # -- construction from user input -------------------------------------------------------------
    @classmethod
    def keys(cls) -> tuple[str, ...]:
        """The allowed configuration keys."""
        return tuple(f.name for f in fields(cls))

    def updated(self, mapping: Mapping[str, Any] | None) -> EnvConfig:
        """A copy with the keys of ``mapping`` replaced (validated; unknown keys are errors)."""
        if mapping is None:
            return self
        if isinstance(mapping, EnvConfig):
            return mapping
        if not isinstance(mapping, Mapping):
            raise ConfigError(f"config must be a dict of keys {', '.join(self.keys())} (or an EnvConfig); "
                              f"got {type(mapping).__name__}")
        values = dict(mapping)
        action = values.get("action")
        if isinstance(action, Mapping):  # highway-env's spelling: {"type": ..., "acceleration_range": ...}
            action = dict(action)
            if "type" not in action:
                raise ConfigError(f"config key 'action' = {mapping['action']!r}: a dict needs a 'type' "
                                  f"(one of {', '.join(map(repr, ACTIONS))})")
            values["action"] = action.pop("type")
            for key, value in action.items():
                if key not in ("acceleration_range", "steering_range", "target_speeds"):
                    raise ConfigError(f"config key 'action.{key}': not supported; allowed in 'action': type, "
                                      "acceleration_range, steering_range, target_speeds")
                values[key] = value
        unknown = [k for k in values if k not in self.keys()]
        if unknown:
            hint = ""
            if "observation" in unknown:
                hint = " (the observation is set with 'perception', 'max_tracks' and 'normalize')"
            elif "simulation_frequency" in unknown:
                hint = f" (the world runs on a fixed 0.05 s grid, {SIMULATION_FREQUENCY} Hz)"
            raise ConfigError(f"unknown config key{'s' if len(unknown) > 1 else ''} "
                              f"{', '.join(map(repr, unknown))}{hint}; allowed keys: {', '.join(self.keys())}")
        return replace(self, **values)

    def highway_config(self) -> dict[str, Any]:
        """The plain dict kept in ``env.config`` (highway-env's attribute): every field, plus the keys
        highway-env's ``AbstractEnv`` reads (``simulation_frequency``, ``action.type``, ...)."""
        out = asdict(self)
        out["action"] = {"type": self.action}
        out["observation"] = {"type": "TrackedRoad", "perception": self.perception, "max_tracks": self.max_tracks,
                              "normalize": self.normalize}
        out["simulation_frequency"] = SIMULATION_FREQUENCY
        out["manual_control"] = False
        out["offscreen_rendering"] = True
        out["real_time_rendering"] = False
        out["neighbour_vehicles_connected_lanes"] = False
        return out


__all__ = ["ACTIONS", "ConfigError", "EnvConfig", "PERCEPTIONS", "SIMULATION_FREQUENCY"]
