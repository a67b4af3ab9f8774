"""The gymnasium environment ``eot/TrackedRoad-v0``: highway-env's ``AbstractEnv`` with our world,
sensors and tracker inside ``step``; observations are the tracker's tracks in road coordinates.

``import sim`` registers it, so ``gym.make("eot/TrackedRoad-v0")`` works after that import and
``gym.make("sim:eot/TrackedRoad-v0")`` from a fresh interpreter. Modules: ``sim.env.core``
(``TrackedRoadEnv``: the loop, reward, termination), ``sim.env.config`` (``EnvConfig``: typed,
validated keys), ``sim.env.observation`` (the rows and columns), ``sim.env.vehicles`` (the ego and
its actions), ``sim.env.render`` (headless ``rgb_array`` frames).
"""

from sim import ENV_ID
from sim.env.config import ConfigError, EnvConfig
from sim.env.core import TrackedRoadEnv
from sim.env.observation import COL, COLUMNS

__all__ = ["COL", "COLUMNS", "ConfigError", "ENV_ID", "EnvConfig", "TrackedRoadEnv"]
