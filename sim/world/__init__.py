"""The simulated world: scenario files, the road and traffic on it (simulated or recorded), the ground, and the truth.

The lowest part of ``sim``: it imports only ``tracker`` and third-party packages, never another part
of ``sim``. Modules:

- ``sim.world.scenario``: scenario files (TOML, validated into ``ScenarioSpec``); the shipped ones;
- ``sim.world.generator``: random scenarios, a new road and/or traffic per seed (``[generator]``);
- ``sim.world.families``: safety-critical scenario families, a new road, conflict and traffic per seed (``[family]``);
- ``sim.world.world``: ``World``, highway-env traffic on our road advanced to any time, giving truth;
- ``sim.world.traffic``: highway-env vehicle classes per behaviour (IDM/MOBIL, constant, scripted);
- ``sim.world.lanes``: highway-env lanes (``FrenetLane``) over our ``tracker.Road``;
- ``sim.world.ground``: the ground surface (flat, planar, road-following with grade and bank);
- ``sim.world.recording``: recorded traffic (``Recording``), the CommonRoad reader and the default ego;
- ``sim.world.smoothing``: physical truth from noisy recordings (an RTS smoother, a car width bound);
- ``sim.world.replay``: ``ReplayWorld``, recorded traffic as the truth of a run, and its road;
- ``sim.world.driven``: ``DrivenReplayWorld``, recorded traffic with an ego of one's own (the closed loop's);
- ``sim.world.truth``: ``Snapshot``, the truth handed to the sensors and the evaluator.
"""
