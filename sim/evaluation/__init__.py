"""Evaluation: one run of world -> sensors -> tracker scored against the truth, and what is made of it.

Above ``sim.world``, ``sim.sensors`` and ``sim.baselines``; below ``sim.env`` and ``sim.studies``. Modules:

- ``sim.evaluation.runner``: ``run_scenario`` -> ``Result``: one run, scored frame by frame;
- ``sim.evaluation.variants``: the named tracker variants (``eot run --variant``, the studies);
- ``sim.evaluation.records``: ``FrameRecord``, one scored frame (what everything after a run reads);
- ``sim.evaluation.metrics``: GOSPA with its parts, matched-target errors, ID switches;
- ``sim.evaluation.dropouts``: coasting and re-acquisition through a lidar dropout (``fault_dropout_*``);
- ``sim.evaluation.long_vehicles``: the hard suite's long-vehicle length target;
- ``sim.evaluation.observability``: the seen pairs split by whether the vehicle has shown its length;
- ``sim.evaluation.results``: writing ``metrics.json`` and the CSVs of a run;
- ``sim.evaluation.plots``: figures of a run (GOSPA, bird's-eye view, per-target, GIF);
- ``sim.evaluation.inspect``: diagnostics of a written run (losses, label changes, worst intervals).
"""
