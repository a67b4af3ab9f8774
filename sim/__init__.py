"""frenet-eot simulation testbed: scenarios, traffic, sensors, evaluation, CLI.

``sim`` imports ``tracker``; ``tracker`` never imports ``sim``. ``sim.run_scenario``,
``sim.run_recording`` (recorded traffic: ``sim.Recording``, ``sim.RecordedVehicle``,
``sim.read_commonroad_recording``) and ``sim.Result`` are imported on first use, so ``import sim`` stays light; it does register the
gymnasium environment ``eot/TrackedRoad-v0`` (``sim.env``, imported when the env is made).
"""

from typing import Any

from sim.world.scenario import ScenarioError, ScenarioSpec, load_scenario, load_suite

#: The gymnasium id of ``sim.env.TrackedRoadEnv``.
ENV_ID = "eot/TrackedRoad-v0"
#: ``max_episode_steps`` of its registration (gymnasium's ``TimeLimit`` under ``gym.make``): the default
#: episode, the default scenario curve-single's 20 s at the default 5 Hz policy frequency
#: (``sim.env.EnvConfig().episode_steps()``); longer episodes pass their own to ``gym.make``.
ENV_MAX_EPISODE_STEPS = 100


def _register_env() -> None:
    from gymnasium.envs.registration import register, registry

    if ENV_ID not in registry:
        register(id=ENV_ID, entry_point="sim.env:TrackedRoadEnv", max_episode_steps=ENV_MAX_EPISODE_STEPS)


_register_env()

__all__ = ["ENV_ID", "ENV_MAX_EPISODE_STEPS", "RecordedVehicle", "Recording", "Result", "ScenarioError", "ScenarioSpec",
           "load_scenario", "load_suite", "read_commonroad_recording", "run_recording", "run_scenario"]


def __getattr__(name: str) -> Any:
    if name in ("run_scenario", "run_recording", "Result"):
        from sim.evaluation import runner

        return getattr(runner, name)
    if name in ("Recording", "RecordedVehicle", "read_commonroad_recording"):
        from sim.world import recording

        return getattr(recording, name)
    raise AttributeError(f"module 'sim' has no attribute {name!r}")
