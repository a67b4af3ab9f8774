"""The comparison study (sim/studies/study.py, sim/studies/claims.py, sim/evaluation/variants.py): every
variant tracks the curve-single car, paired intervals against scipy, verdicts, variant probing (only a
missing optional dependency makes a variant unavailable; any other failure to build one is an error)."""

import sys

import numpy as np
import pytest
from scipy import stats

from sim import load_scenario
from sim.evaluation import variants as variants_module
from sim.evaluation.runner import run_scenario
from sim.evaluation.variants import VARIANTS, VariantUnavailableError, estimates_extent, probe_variant
from sim.studies.claims import paired_verdict
from sim.studies.study import Interval, mean_interval, paired_difference, paired_values, split_available
from tracker import TrackerConfig


@pytest.mark.parametrize("variant", VARIANTS)
def test_every_variant_tracks_the_curve_single_car(variant):
    reason = probe_variant(variant)
    if reason is not None:
        pytest.skip(f"{variant} cannot be built here: {reason}")
    m = run_scenario(load_scenario("curve-single"), 0, variant, duration=3.0, roadside=False).metrics
    assert m["frames"] == 31 and m["truth_count_mean"] == 1.0
    assert m["cardinality_error_mean"] <= 0.2
    if estimates_extent(variant):
        assert m["pos_rmse_m"] < 0.6 and m["yaw_rmse_deg"] < 5.0 and m["gospa_mean"] < 1.0
        assert m["length_rmse_m"] is not None and m["length_rmse_m"] < 1.0
    else:  # point trackers: a centroid, up to half a car length from the centre; no extent
        assert m["pos_rmse_m"] < 3.0
        assert m["length_rmse_m"] is None and m["width_rmse_m"] is None


def _rows():
    a = [1.0, 2.5, 0.7, 3.1, 2.2]
    b = [1.4, 2.4, 1.5, 3.9, 2.6]
    rows = []
    for seed, (x, y) in enumerate(zip(a, b)):
        rows.append({"scenario": "s1", "variant": "A", "seed": seed, "m": x})
        rows.append({"scenario": "s1", "variant": "B", "seed": seed, "m": y})
    rows.append({"scenario": "s1", "variant": "A", "seed": 9, "m": 5.0})  # B has no seed 9: unpaired
    rows.append({"scenario": "s2", "variant": "A", "seed": 0, "m": None})  # missing value: unpaired
    rows.append({"scenario": "s2", "variant": "B", "seed": 0, "m": 1.0})
    return rows, np.array(a), np.array(b)


def test_paired_interval_matches_scipy():
    rows, a, b = _rows()
    assert [(s, k) for s, k, _, _ in paired_values(rows, "m", "A", "B")] == [("s1", k) for k in range(5)]
    p = paired_difference(rows, "m", "A", "B")
    ci = stats.ttest_rel(a, b).confidence_interval(0.95)
    assert p.diff.n == 5 and p.scenarios == ("s1",)
    assert p.diff.mean == pytest.approx(float(np.mean(a - b)))
    assert p.diff.low == pytest.approx(ci.low) and p.diff.high == pytest.approx(ci.high)
    assert p.a_mean == pytest.approx(a.mean()) and p.b_mean == pytest.approx(b.mean())
    # restricted to a scenario with no pair: nothing
    assert paired_difference(rows, "m", "A", "B", ["s2"]).diff == Interval(0, None, None, None)


def test_mean_interval_matches_scipy_and_edge_cases():
    x = [0.3, 0.9, 0.4, 1.7, 1.1, 0.2]
    iv = mean_interval(x + [None, float("nan")])
    low, high = stats.t.interval(0.95, len(x) - 1, loc=np.mean(x), scale=stats.sem(x))
    assert iv.n == 6 and iv.low == pytest.approx(low) and iv.high == pytest.approx(high)
    assert iv.half_width == pytest.approx(0.5 * (high - low))
    assert mean_interval([2.0]) == Interval(1, 2.0, None, None)
    assert mean_interval([]) == Interval(0, None, None, None)


def test_verdicts_follow_the_interval():
    assert paired_verdict(Interval(5, -1.0, -1.5, -0.5), -1) == "supported"
    assert paired_verdict(Interval(5, -0.2, -1.5, 0.5), -1) == "not shown"
    assert paired_verdict(Interval(5, 1.0, 0.5, 1.5), -1) == "contradicted"
    assert paired_verdict(Interval(5, 1.0, 0.5, 1.5), +1) == "supported"
    assert paired_verdict(Interval(1, 1.0, None, None), -1) == "not evaluated"


def _register(monkeypatch, name, error):
    def build(road, config):
        raise error

    fake = variants_module.Variant(name, "a variant that cannot be built",
                                   lambda: TrackerConfig.for_variant("curvilinear-fused"), build)
    monkeypatch.setitem(variants_module._VARIANTS, name, fake)


def test_a_variant_missing_an_optional_dependency_is_reported_and_skipped(monkeypatch):
    _register(monkeypatch, "needs-extra", VariantUnavailableError("needs the package extra:  pip install extra"))
    assert probe_variant("needs-extra") == "needs the package extra: pip install extra"
    ok, skipped = split_available(["curvilinear-fused", "needs-extra"])
    assert ok == ["curvilinear-fused"] and skipped == {"needs-extra": "needs the package extra: pip install extra"}


@pytest.mark.parametrize("error", [ValueError("a bad setting"), TypeError("a wrong argument"), ImportError("no module x"),
                                   RuntimeError("a broken tracker")], ids=lambda e: type(e).__name__)
def test_a_variant_that_fails_to_build_is_an_error_not_a_skip(monkeypatch, error):
    _register(monkeypatch, "broken", error)
    with pytest.raises(type(error), match=str(error)):
        probe_variant("broken")
    with pytest.raises(type(error), match=str(error)):
        split_available(["curvilinear-fused", "broken"])


def test_missing_stonesoup_makes_its_variant_unavailable(monkeypatch):
    monkeypatch.setitem(sys.modules, "stonesoup.updater.pointprocess", None)  # its import fails
    reason = probe_variant("stonesoup-gmphd")
    assert reason is not None and "needs Stone Soup" in reason and "pip install" in reason


def test_only_variants_with_an_optional_dependency_may_be_unavailable():
    for name in VARIANTS:
        if name != "stonesoup-gmphd":
            assert probe_variant(name) is None, name
