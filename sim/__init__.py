"""frenet-eot simulation testbed: scenarios, traffic, sensors, evaluation, CLI.

``sim`` imports ``tracker``; ``tracker`` never imports ``sim``.
"""

from sim.scenario import ScenarioError, ScenarioSpec, load_scenario, load_suite

__all__ = ["ScenarioError", "ScenarioSpec", "load_scenario", "load_suite"]
