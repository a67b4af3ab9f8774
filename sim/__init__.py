"""frenet-eot simulation testbed: scenarios, traffic, sensors, evaluation, CLI.

``sim`` imports ``tracker``; ``tracker`` never imports ``sim``. ``sim.run_scenario`` (and
``sim.Result``) are imported on first use, so ``import sim`` stays light.
"""

from typing import Any

from sim.scenario import ScenarioError, ScenarioSpec, load_scenario, load_suite

__all__ = ["Result", "ScenarioError", "ScenarioSpec", "load_scenario", "load_suite", "run_scenario"]


def __getattr__(name: str) -> Any:
    if name in ("run_scenario", "Result"):
        from sim import runner

        return getattr(runner, name)
    raise AttributeError(f"module 'sim' has no attribute {name!r}")
