"""Studies: many runs and what they show, above ``sim.evaluation`` and ``sim.env``. Modules:

- ``sim.studies.montecarlo``: many runs (scenario x variant x seed) in local processes or on Ray;
- ``sim.studies.study``: the comparison study (``eot compare``): every variant over a suite;
- ``sim.studies.claims``: the paper's claims 1-6 checked against a study's paired runs;
- ``sim.studies.report``: ``results/REPORT.md`` and its figures from a comparison study;
- ``sim.studies.soak``: one long streamed run, recording what must stay bounded (``eot soak``);
- ``sim.studies.closed_loop``: the planner on truth vs on tracks over seeds (``eot closed-loop``).
"""
