"""Normal runs emit no warning: numpy's overflow/invalid-value warnings leak to the user's
console and may hide a wrong weight, so a scenario run with every warning turned into an error must
complete (the dense and curved scenarios of the standard suite, shortened)."""

from __future__ import annotations

import warnings

import pytest

from sim import load_scenario, run_scenario


@pytest.mark.parametrize(("name", "seconds"), [("curvy-multi", 4.0), ("dense-highway", 3.0)])
def test_scenario_runs_without_any_warning(name, seconds):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result = run_scenario(load_scenario(name), 1, duration=seconds)
    assert result.metrics["frames"] == int(round(seconds * 10)) + 1
    assert result.metrics["track_count_mean"] > 0.5
