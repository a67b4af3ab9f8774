"""The gymnasium environment ``eot/TrackedRoad-v0``: highway-env's ``AbstractEnv`` with our world,
sensors and tracker inside ``step``; observations are the tracker's tracks in road coordinates
(features with physical bounds; the rows' track labels in ``info["labels"]``).

``import sim`` registers it, so ``gym.make("eot/TrackedRoad-v0")`` works after that import and
``gym.make("sim:eot/TrackedRoad-v0")`` from a fresh interpreter; the registration's
``max_episode_steps`` is ``sim.ENV_MAX_EPISODE_STEPS`` (100, the default episode). Above
``sim.evaluation``; below ``sim.studies``. Modules:

- ``sim.env.core``: ``TrackedRoadEnv``, the loop, reward and termination;
- ``sim.env.config``: ``EnvConfig``, typed and validated keys;
- ``sim.env.observation``: the observation's rows, columns, bounds and labels;
- ``sim.env.vehicles``: the ego and its actions;
- ``sim.env.render``: headless ``rgb_array`` frames;
- ``sim.env.view``: ``EnvView``, what the observation and the renderer read of the environment;
- ``sim.env.planner``: a rule-based planner that drives the environment on its observation alone.
"""

from sim import ENV_ID, ENV_MAX_EPISODE_STEPS
from sim.env.config import ConfigError, EnvConfig
from sim.env.core import TrackedRoadEnv
from sim.env.observation import COL, COLUMNS, NO_LABEL, limits

__all__ = ["COL", "COLUMNS", "ConfigError", "ENV_ID", "ENV_MAX_EPISODE_STEPS", "EnvConfig", "NO_LABEL", "TrackedRoadEnv",
           "limits"]
