"""``TrackedRoadEnv`` (``eot/TrackedRoad-v0``): highway-env's ``AbstractEnv`` around our world, sensors
and tracker, whose observations are the tracker's tracks.

One ``step(action)`` (period ``1 / policy_frequency``, 0.2 s by default):

1. the action goes to the ego (``sim.env.vehicles``: meta-action or held acceleration/steering);
2. the world (``sim.world.world.World``) advances on its 0.05 s grid -- the other vehicles follow the
   scenario's behaviours (IDM/MOBIL, constant, scripted) -- while the sensor rig
   (``sim.sensors.SensorRig``: lidar at 10 Hz, radars at 14 Hz out of phase, roadside clutter, exactly
   as ``sim.evaluation.runner`` uses it; the scenario's ``[faults]`` or the ``faults`` key applied by
   ``sim.sensors.faults.FaultInjector``) makes a ``tracker.Frame`` at every lidar time and the tracker
   of ``variant`` (``sim.evaluation.variants``: its own factory, e.g. Stone Soup's, or ``tracker.Tracker``)
   steps on each (``perception = "truth"`` skips the tracker);
3. the observation (``sim.env.observation``) is built from the tracks (or the truth) at the last lidar
   frame, which falls on the end of the period.

Reward (highway-env's ``highway-v0``): ``collision_reward * crashed + high_speed_reward *
clip((v cos xi - v_lo) / (v_hi - v_lo), 0, 1) + right_lane_reward * (lanes - 1 - lane) / max(lanes - 1, 1)``
(``lane`` = the ego's target lane for meta-actions; our lane 0 is the rightmost), mapped onto [0, 1] with
``normalize_reward`` (from ``[collision_reward, high_speed_reward + right_lane_reward]``), then times
``on_road`` (the ego's centre between the road edges). The parts are in ``info["rewards"]``.
Termination: the ego's rectangle overlaps another vehicle's (``sim.world.world`` records it; ``crashed``), or
it left the road with ``offroad_terminal``. Truncation: the episode time reaches ``duration`` (the
scenario's by default), or, on an open road, the ego would reach the road's end within two periods.

Roads and traffic: any scenario, a lane map's road too (its lanes begin and end: ``info["lane_centers"]``
are the lanes at the ego's ``s``, NaN where one is absent). A replay of recorded traffic (a ``[replay]``
table, e.g. the ``real`` suite) runs as a driven replay (``sim.world.driven.DrivenReplayWorld``): the
recorded vehicles drive as recorded and do not react; the ego starts at the recording's planning
problem's initial state and the agent drives it; the episode lasts to the end of the goal's time
interval; ``info`` adds ``goal_reached`` (the ego's centre has entered the goal region).

Seeding: ``reset(seed=k)`` runs episode seed ``k``: the traffic, the sensors and the clutter draw from
the same streams as ``sim.run_scenario(spec, seed=k)``; ``reset()`` without a seed draws the episode
seed from the environment's ``np_random``. A generator scenario draws a new road and traffic per
episode seed. The same seed and actions give bit-identical observations.

Episode length: ``max_episode_steps`` = ``ceil(duration * policy_frequency)`` steps
(``EnvConfig.episode_steps``). ``gym.make`` wraps the env in gymnasium's ``TimeLimit`` with the
registered ``max_episode_steps`` (``sim.ENV_MAX_EPISODE_STEPS`` = 100: the default scenario
curve-single's 20 s at the default 5 Hz), which never cuts an episode of the defaults short; for a
longer one (e.g. ``circuit``, 80 s, or a higher ``policy_frequency``) pass
``gym.make(..., max_episode_steps=EnvConfig(...).episode_steps())``, or ``-1`` for no wrapper (the env
truncates at ``duration`` itself).

``info`` holds highway-env's ``speed``, ``crashed``, ``action``, ``rewards`` and: ``t`` (s),
``episode_seed``, ``on_road``, ``lane``, ``tracks`` (count), ``collisions`` (``(t, id_a, id_b)`` of
the episode so far), ``lane_centers`` (m), ``lane_directions`` (+1 along ``s``, -1 against) and
``lane_kinds`` (``"driving"``, ``"parking"``, ``"shoulder"``): the map a planner may use; and ``labels`` (int64,
``1 + max_tracks``: each observation row's track label or vehicle id, -1 for the ego and padding;
``sim.env.observation``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from highway_env import utils
from highway_env.envs.common.abstract import AbstractEnv
from highway_env.envs.common.action import ContinuousAction

from sim.env.config import ConfigError, EnvConfig, _steps
from sim.env.observation import TrackObservation
from sim.env.vehicles import MetaAction, install_ego
from sim.evaluation.runner import (
    SENSOR_STREAM,
    build_rig,
    default_tracker_factory,
    rig_config_for,
    tracker_config_for,
)
from sim.evaluation.variants import variant_factory
from sim.sensors import SensorRig
from sim.sensors.faults import FAULT_STREAM, FaultInjector
from sim.sensors.rig import SensorFrame
from sim.world.driven import DrivenReplayWorld, planned_run
from sim.world.scenario import FaultsSpec, ScenarioError, ScenarioSpec, load_scenario
from sim.world.world import DEFAULT_STEP, World
from tracker import Track

#: Slack (s) when comparing times.
_EPS = 1e-9


class TrackedRoadEnv(AbstractEnv):
    """Extended-object tracking in the loop: see the module docstring and ``sim.env.config``.

    ``config`` is a dict of ``EnvConfig`` keys (validated; unknown keys and bad values raise
    ``ConfigError`` naming the key) or an ``EnvConfig``; ``render_mode`` is ``None`` or ``"rgb_array"``."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 5}

    def __init__(self, config: Mapping[str, Any] | EnvConfig | None = None, render_mode: str | None = None) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ConfigError(f"render_mode = {render_mode!r}: must be None or 'rgb_array' (drawn offscreen with matplotlib)")
        self.settings = EnvConfig()
        self.spec_file: ScenarioSpec | None = None
        self.lidar_range = 100.0  # the scenario's lidar max_range (m), set by configure
        self.world: World | None = None
        self.rig: SensorRig | None = None
        self.tracker: Any = None
        self.tracks: list[Track] = []
        self.last_frame: SensorFrame | None = None
        #: (SensorFrame, tracks) of every lidar frame processed during the last ``reset``/``step``.
        self.step_frames: list[tuple[SensorFrame, list[Track]]] = []
        self.episode_seed = 0
        self._renderer: Any = None
        self._requested_seed: int | None = None
        super().__init__(config=config, render_mode=render_mode)  # type: ignore[arg-type]

    # -- configuration --------------------------------------------------------------------------
    @classmethod
    def default_config(cls) -> dict:
        """``EnvConfig()`` as highway-env's config dict (``EnvConfig.highway_config``)."""
        return EnvConfig().highway_config()

    def configure(self, config: Mapping[str, Any] | EnvConfig | None) -> None:
        """Validate ``config`` on top of the current settings (unknown keys and bad values raise
        ``ConfigError``), load the scenario, and refresh ``self.config``."""
        settings = self.settings.updated(config)  # type: ignore[arg-type]
        try:
            spec = load_scenario(settings.scenario)
        except ScenarioError as exc:
            raise ConfigError(f"config key 'scenario' = {settings.scenario!r}: {' '.join(str(exc).split())}") from None
        length = spec.duration
        if spec.replay is not None:  # the driven replay's own duration: to the end of the goal's time interval
            if spec.replay.ego is not None:
                raise ConfigError(f"config key 'scenario' = {settings.scenario!r}: its replay.ego = {spec.replay.ego} "
                                  "names a recorded vehicle; in the environment the ego is the recording's planning "
                                  "problem, driven by the agent (leave replay.ego out)")
            try:
                length = planned_run(spec.replay.file, spec.replay.truth)[0]
            except (ValueError, ImportError) as exc:
                raise ConfigError(f"config key 'scenario' = {settings.scenario!r}: {' '.join(str(exc).split())}") from None
        if settings.duration is not None and settings.duration > length + _EPS:
            raise ConfigError(f"config key 'duration' = {settings.duration!r}: must be at most the scenario's "
                              f"duration ({length:g} s)")
        faults = self._faults_for(spec, settings)
        if faults is not None and faults.duplicate_frames:
            raise ConfigError(f"config key 'scenario' = {settings.scenario!r}: its faults.duplicate_frames is not supported "
                              "in the loop (an observation falls on every lidar frame); override it with config key 'faults'")
        if faults is not None:
            try:
                faults.check_duration(settings.duration if settings.duration is not None else length)
            except ValueError as exc:
                raise ConfigError(f"config key 'faults': {exc}") from None
        rig, _ = rig_config_for(spec)
        ratio = rig.lidar.rate_hz / settings.policy_frequency
        if abs(ratio - round(ratio)) > 1e-6 or rig.lidar.phase_s != 0.0:
            raise ConfigError(
                f"config key 'policy_frequency' = {settings.policy_frequency:g}: the lidar rate "
                f"({rig.lidar.rate_hz:g} Hz, phase {rig.lidar.phase_s:g} s) must be a whole multiple of it with phase 0, "
                "so that every observation falls on a lidar frame (e.g. 10, 5, 2.5, 2 or 1 Hz)")
        period = 1.0 / settings.policy_frequency
        if abs(period / DEFAULT_STEP - round(period / DEFAULT_STEP)) > 1e-6:
            raise ConfigError(f"config key 'policy_frequency' = {settings.policy_frequency:g}: its period must be a "
                              f"multiple of the world's {DEFAULT_STEP:g} s step")
        self.settings = settings
        self.spec_file = spec
        self._scenario_duration = float(length)
        self.lidar_range = float(rig.lidar.max_range)
        self.config = settings.highway_config()

    @staticmethod
    def _faults_for(spec: ScenarioSpec, settings: EnvConfig) -> FaultsSpec | None:
        """The episode's sensor faults: ``settings.faults`` when given, else the scenario's; None when none is set."""
        faults = spec.faults if settings.faults is None else FaultsSpec.model_validate(dict(settings.faults))
        return faults if faults is not None and faults.active else None

    def define_spaces(self) -> None:
        """Action type from ``action`` (``MetaAction`` or highway-env's ``ContinuousAction``) and the
        ``Box`` observation of ``sim.env.observation``."""
        s = self.settings
        if s.action == "DiscreteMetaAction":
            self.action_type = MetaAction(self, target_speeds=np.array(s.target_speeds))
        else:
            self.action_type = ContinuousAction(self, acceleration_range=s.acceleration_range,
                                                steering_range=s.steering_range)
        self.observation_type = TrackObservation(self)  # type: ignore[assignment]
        self.observation_space = self.observation_type.space()
        self.action_space = self.action_type.space()

    # -- episode --------------------------------------------------------------------------------
    @property
    def period(self) -> float:
        """Seconds between actions."""
        return 1.0 / self.settings.policy_frequency

    @property
    def duration(self) -> float:
        """Truncation time of the episode (s)."""
        assert self.spec_file is not None
        return float(self.settings.duration if self.settings.duration is not None else self._scenario_duration)

    @property
    def max_episode_steps(self) -> int:
        """Steps until the episode is truncated at ``duration``: ``ceil(duration * policy_frequency)``."""
        return _steps(self.duration, self.settings.policy_frequency)

    @property
    def sim_time(self) -> float:
        """Simulated time of the episode (s)."""
        return self._policy_k * self.period if self.world is not None else 0.0

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        """Start an episode: ``seed`` is the episode seed (module docstring); ``options={"config": {...}}``
        reconfigures first."""
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0):
            raise ConfigError(f"reset(seed={seed!r}): the seed must be a non-negative integer or None")
        self._requested_seed = None if seed is None else int(seed)
        return super().reset(seed=seed, options=options)

    def _reset(self) -> None:
        s = self.settings
        assert self.spec_file is not None
        seed = self._requested_seed
        if seed is None:
            seed = int(self.np_random.integers(0, 2**31 - 1))
        self.episode_seed = seed
        world: World | DrivenReplayWorld
        if self.spec_file.replay is not None:
            world = DrivenReplayWorld.from_spec(self.spec_file, seed)
        else:
            world = World(self.spec_file, seed, step=DEFAULT_STEP)
        spec = world.spec  # the realised one when a generator drew it
        ego = install_ego(world, s.action, target_speeds=s.target_speeds, accel_limits=s.acceleration_range)
        self.world = world
        self.road = world.traffic
        self.controlled_vehicles = [ego]
        rig_cfg, clutter_cfg = rig_config_for(spec)
        self.rig = build_rig(rig_cfg, clutter_cfg, world.road, seed, s.roadside, world.ground)
        self.tracker = None
        if s.perception == "tracks":
            factory = variant_factory(s.variant) or default_tracker_factory
            self.tracker = factory(world.road, tracker_config_for(spec, s.variant, rig_cfg))
        faults = self._faults_for(spec, s)
        self._frames = self.rig.frames(world.truth_at, None, seed=np.random.SeedSequence(seed, spawn_key=(SENSOR_STREAM,)),
                                       poses_at=world.poses_at,
                                       lidar_delay=faults.lidar_time_offset if faults is not None else 0.0)
        self.fault_injector: FaultInjector | None = None
        if faults is not None:  # the same streams as sim.evaluation.runner
            fault_rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(FAULT_STREAM,)))
            self.fault_injector = FaultInjector(faults, rig_cfg.lidar, fault_rng)
            self._frames = self.fault_injector.apply(self._frames)
        self._frame_k = 0
        self._policy_k = 0
        self._seen_collisions = 0
        self.tracks = []
        self.last_frame = None
        self.step_frames = []
        self._consume_frames(0.0)

    def _consume_frames(self, t_end: float) -> None:
        """Make every lidar frame up to ``t_end`` (s), step the tracker on each, then advance the world
        to ``t_end`` and flag a collision of the ego."""
        assert self.world is not None and self.rig is not None
        rate = self.rig.config.lidar.rate_hz
        self.step_frames = []
        while self._frame_k / rate <= t_end + _EPS:
            sf = next(self._frames)
            self._frame_k += 1
            if self.tracker is not None:
                self.tracks = list(self.tracker.step(sf.frame))
            self.last_frame = sf
            self.step_frames.append((sf, self.tracks))
        self.world.advance(t_end)
        collisions = self.world.collisions
        for _, a, b in collisions[self._seen_collisions:]:
            if 0 in (a, b):
                self.vehicle.crashed = True
        self._seen_collisions = len(collisions)

    def _simulate(self, action: Any = None) -> None:
        """Apply ``action`` to the ego, then run one policy period (module docstring)."""
        if action is not None:
            self.action_type.act(action)
        self._policy_k += 1
        self._consume_frames(self._policy_k * self.period)
        self.steps += int(round(self.period / DEFAULT_STEP))

    # -- reward, termination --------------------------------------------------------------------
    @property
    def on_road(self) -> bool:
        """Whether the ego's centre lies between the road edges."""
        road = self.world.road  # type: ignore[union-attr]
        return bool(road.within_bounds(np.array([self.vehicle.frenet_s]), np.array([self.vehicle.frenet_n]))[0])

    def _lane(self) -> int:
        v = self.vehicle
        index = getattr(v, "target_lane_index", None) or v.lane_index
        return int(index[2])

    def _rewards(self, action: Any) -> dict[str, float]:
        s = self.settings
        lanes = self.world.road.lanes  # type: ignore[union-attr]
        ego = self.world.ego_state()  # type: ignore[union-attr]
        forward = ego.v * math.cos(ego.xi)
        scaled = utils.lmap(forward, list(s.reward_speed_range), [0, 1])
        return {
            "collision_reward": float(self.vehicle.crashed),
            "right_lane_reward": (lanes - 1 - self._lane()) / max(lanes - 1, 1),
            "high_speed_reward": float(np.clip(scaled, 0.0, 1.0)),
            "on_road_reward": float(self.on_road),
        }

    def _reward(self, action: Any) -> float:
        s = self.settings
        rewards = self._rewards(action)
        reward = (s.collision_reward * rewards["collision_reward"] + s.high_speed_reward * rewards["high_speed_reward"]
                  + s.right_lane_reward * rewards["right_lane_reward"])
        if s.normalize_reward:
            reward = utils.lmap(reward, [s.collision_reward, s.high_speed_reward + s.right_lane_reward], [0, 1])
        return float(reward * rewards["on_road_reward"])

    def _is_terminated(self) -> bool:
        return bool(self.vehicle.crashed or (self.settings.offroad_terminal and not self.on_road))

    def near_road_end(self) -> bool:
        """On an open road: whether the ego could reach the end within the next two periods."""
        road = self.world.road  # type: ignore[union-attr]
        if road.closed:
            return False
        v = self.vehicle
        reach = 2.0 * self.period * (v.speed + self.settings.acceleration_range[1] * 2.0 * self.period) + v.LENGTH
        return bool(v.frenet_s + reach >= road.length)

    def _is_truncated(self) -> bool:
        return bool(self.sim_time >= self.duration - _EPS or self.near_road_end())

    def _info(self, obs: Any, action: Any = None) -> dict:
        info = super()._info(obs, action)
        world = self.world
        assert world is not None
        info.update({
            "t": self.sim_time,
            "episode_seed": self.episode_seed,
            "on_road": self.on_road,
            "lane": self._lane(),
            "tracks": len(self.tracks),
            "collisions": list(world.collisions),
            "lane_centers": self.lane_centers(),
            "lane_directions": tuple(int(d) for d in world.road.lane_directions),
            "lane_kinds": tuple(world.road.layout.kinds),
            "labels": self.observation_type.labels.copy(),
        })
        if isinstance(world, DrivenReplayWorld):
            info["goal_reached"] = world.goal_reached_at is not None
        return info

    def lane_centers(self) -> tuple[float, ...]:
        """Every lane's centre offset ``n`` (m, lane 0 first) at the ego's ``s``: NaN for a lane absent there
        (a lane map's lanes begin and end; on other roads they are the same everywhere)."""
        road = self.world.road  # type: ignore[union-attr]
        if road.uniform:
            return tuple(float(c) for c in road.lane_centers)
        return tuple(float(c) for c in road.lane_centers_at(float(self.vehicle.frenet_s)))

    # -- rendering ------------------------------------------------------------------------------
    def render(self) -> np.ndarray | None:
        """The current frame as an ``(H, W, 3)`` uint8 array (``render_mode="rgb_array"``; drawn by
        ``sim.env.render`` with matplotlib's Agg canvas, so it works headless)."""
        if self.render_mode is None:
            import gymnasium as gym

            gym.logger.warn('TrackedRoadEnv.render: no render_mode; make the env with render_mode="rgb_array"')
            return None
        if self._renderer is None:
            from sim.env.render import Renderer

            self._renderer = Renderer(self)
        return self._renderer.draw()

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        self.done = True


__all__ = ["TrackedRoadEnv"]
