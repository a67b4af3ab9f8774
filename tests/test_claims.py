"""How the claims' verdicts are built (sim/studies/claims.py), from hand-made runs.csv rows: every claim gives
"supported", "not shown" and "contradicted" from rows made to show each; claims 3 and 6 just inside and
just outside their bounds; a claim's comparisons combine (``combine``) with "contradicted" first, then
"not shown", and only its primary comparisons count."""

from __future__ import annotations

from collections.abc import Sequence

import pytest

from sim.studies.claims import (
    CURVED_KAPPA,
    EXTENT_CLOSE_FRACTION,
    LIDAR_PERIOD_MS,
    TIGHT_KAPPA,
    bound_verdict,
    claim_extent,
    claim_fusion,
    claim_motion,
    claim_position,
    claim_runtime,
    claim_yaw,
    combine,
    curved,
    evaluate_claims,
    paired_verdict,
)
from sim.studies.study import Interval, mean_interval
from tracker.config import BirthConfig

FUSED, LIDAR, CARTESIAN = "curvilinear-fused", "curvilinear-lidar", "cartesian-fused"
PAPER_MOTION, PAPER, GNN, STONESOUP = "paper-motion", "paper", "point-gnn", "stonesoup-gmphd"

#: Paired differences A - B whose 95 % interval lies below zero, contains it, lies above it.
BELOW = (-1.0, -1.2, -0.8, -1.1, -0.9)
AROUND = (-1.0, 1.0, -0.5, 0.4, 0.2)
ABOVE = tuple(-d for d in BELOW)
DIFFS = {"supported": BELOW, "not shown": AROUND, "contradicted": ABOVE}  # claims that A is lower
#: Spread of the values made for a chosen interval end (claims 3 and 6).
OFFSETS = (-0.02, -0.01, 0.0, 0.01, 0.02)
#: How far "just inside" and "just outside" a bound lie from it.
EPS = 1e-9


def runs(metric: str, scenario: str, values: dict[str, Sequence[float | None]], seed0: int = 0) -> list[dict]:
    """runs.csv rows: ``values[variant][k]`` is ``metric`` of seed ``seed0 + k`` on ``scenario``."""
    return [{"scenario": scenario, "variant": variant, "seed": seed0 + k, "sim_s": 10.0, metric: v}
            for variant, vs in values.items() for k, v in enumerate(vs)]


def paired(metric: str, a: str, b: str, diffs: Sequence[float], scenario: str = "s1", base: float = 10.0,
           seed0: int = 0) -> list[dict]:
    """Rows where ``a - b`` of ``metric`` is ``diffs`` seed by seed."""
    return runs(metric, scenario, {a: [base + d for d in diffs], b: [base] * len(diffs)}, seed0)


def with_end(end: str, target: float) -> list[float]:
    """Values whose 95 % interval has its ``end`` (``"low"`` or ``"high"``) at ``target``."""
    shift = target - getattr(mean_interval(OFFSETS), end)
    values = [o + shift for o in OFFSETS]
    assert getattr(mean_interval(values), end) == pytest.approx(target, abs=EPS / 100)
    return values


def bound_values(verdict: str, bound: float) -> list[float]:
    """Values whose interval lies just below ``bound`` (supported), just reaches over it with its upper
    end (not shown, the lower end below), or lies just above it (contradicted)."""
    if verdict == "supported":
        return with_end("high", bound - EPS)
    if verdict == "not shown":
        values = with_end("high", bound + EPS)
        assert mean_interval(values).low < bound
        return values
    return with_end("low", bound + EPS)


def verdict_of(claim) -> str:
    assert claim.text.startswith(f"**Verdict: {claim.verdict}.**") or claim.verdict == "not evaluated", claim.text
    return claim.verdict


# -- the building blocks -------------------------------------------------------------------------
@pytest.mark.parametrize(("verdicts", "expected"), [
    ([], "not evaluated"),
    (["not evaluated"], "not evaluated"),
    (["not evaluated", "not evaluated"], "not evaluated"),
    (["supported"], "supported"),
    (["supported", "supported"], "supported"),
    (["supported", "not evaluated"], "supported"),
    (["not evaluated", "not shown"], "not shown"),
    (["supported", "not shown"], "not shown"),
    (["not shown", "supported"], "not shown"),
    (["not shown", "not shown"], "not shown"),
    (["contradicted"], "contradicted"),
    (["supported", "contradicted"], "contradicted"),
    (["contradicted", "supported"], "contradicted"),
    (["not shown", "contradicted", "supported"], "contradicted"),
    (["supported", "not evaluated", "contradicted"], "contradicted"),
], ids=lambda v: "+".join(x.replace(" ", "-") for x in v) or "none" if isinstance(v, list) else v.replace(" ", "-"))
def test_combine(verdicts, expected):
    assert combine(verdicts) == expected
    assert combine(list(reversed(verdicts))) == expected


def test_paired_verdict_at_zero():
    assert paired_verdict(Interval(5, -0.5, -1.0, -1e-12), -1) == "supported"
    assert paired_verdict(Interval(5, -0.5, -1.0, 0.0), -1) == "not shown"
    assert paired_verdict(Interval(5, 0.5, 0.0, 1.0), -1) == "not shown"
    assert paired_verdict(Interval(5, 0.5, 1e-12, 1.0), -1) == "contradicted"
    assert paired_verdict(Interval(5, 0.5, 1e-12, 1.0), +1) == "supported"
    assert paired_verdict(Interval(5, -0.5, -1.0, -1e-12), +1) == "contradicted"
    assert paired_verdict(Interval(0, None, None, None), -1) == "not evaluated"


def test_bound_verdict():
    assert bound_verdict(Interval(5, 0.9, 0.8, 1.0 - EPS), 1.0) == "supported"
    assert bound_verdict(Interval(5, 0.9, 0.8, 1.0), 1.0) == "not shown"
    assert bound_verdict(Interval(5, 1.0, 0.8, 1.2), 1.0) == "not shown"
    assert bound_verdict(Interval(5, 1.1, 1.0, 1.2), 1.0) == "not shown"
    assert bound_verdict(Interval(5, 1.1, 1.0 + EPS, 1.2), 1.0) == "contradicted"
    assert bound_verdict(Interval(1, 0.5, None, None), 1.0) == "not evaluated"
    assert bound_verdict(Interval(0, None, None, None), 1.0) == "not evaluated"


def test_curved_scenarios_by_curvature():
    kappa = {"at": CURVED_KAPPA, "under": CURVED_KAPPA * (1 - 1e-9), "tight": TIGHT_KAPPA, "straight": 0.0, "none": None}
    assert curved(kappa, CURVED_KAPPA) == ["at", "tight"]
    assert curved(kappa, TIGHT_KAPPA) == ["tight"]


# -- claim 1: fusion lowers GOSPA's localisation part ----------------------------------------------
@pytest.mark.parametrize("verdict", sorted(DIFFS))
def test_claim_1(verdict):
    rows = paired("gospa_localization_mean", FUSED, LIDAR, DIFFS[verdict])
    claim = claim_fusion(rows, [FUSED, LIDAR], {})
    assert verdict_of(claim) == verdict and len(claim.comparisons) == 1
    assert claim.comparisons[0].paired.diff.n == 5
    assert ("Likely reason" in claim.text) == (verdict != "supported")


def test_claim_1_pools_every_scenario_and_curvy_multi_is_information():
    # curvy-multi alone contradicts (fusion higher there), pooled with s1 the claim holds: the verdict is
    # the pooled comparison's
    rows = paired("gospa_localization_mean", FUSED, LIDAR, [-2.0, -2.1, -1.9, -2.0, -2.2, -1.8, -2.0, -2.05])
    rows += paired("gospa_localization_mean", FUSED, LIDAR, [0.1, 0.11, 0.09], scenario="curvy-multi")
    claim = claim_fusion(rows, [FUSED, LIDAR], {})
    pooled, info = claim.comparisons
    assert pooled.primary and pooled.paired.diff.n == 11 and pooled.verdict == "supported"
    assert not info.primary and info.paired.scenarios == ("curvy-multi",) and info.verdict == "contradicted"
    assert verdict_of(claim) == "supported"
    assert "For information, " in claim.text


def test_claim_1_without_a_variant_is_not_evaluated():
    rows = paired("gospa_localization_mean", FUSED, LIDAR, BELOW)
    claim = claim_fusion(rows, [FUSED], {LIDAR: "not installed here"})
    assert claim.verdict == "not evaluated" and not claim.comparisons
    assert "curvilinear-lidar (not installed here)" in claim.text
    # one pair only: no interval, nothing evaluated
    claim = claim_fusion(paired("gospa_localization_mean", FUSED, LIDAR, [-1.0]), [FUSED, LIDAR], {})
    assert claim.verdict == "not evaluated"


# -- claim 2: curvilinear yaw better than Cartesian on curved roads --------------------------------
CURVES = {"bend": 1 / 300, "straight": 0.0, "gentle": 1 / 2000}


@pytest.mark.parametrize("verdict", sorted(DIFFS))
def test_claim_2_counts_only_curved_roads(verdict):
    other = DIFFS["contradicted" if verdict == "supported" else "supported"]
    rows = paired("yaw_rmse_deg", FUSED, CARTESIAN, DIFFS[verdict], scenario="bend")
    rows += paired("yaw_rmse_deg", FUSED, CARTESIAN, other, scenario="straight")
    rows += paired("yaw_rmse_deg", FUSED, CARTESIAN, other, scenario="gentle")
    claim = claim_yaw(rows, [FUSED, CARTESIAN], {}, CURVES)
    assert verdict_of(claim) == verdict
    assert claim.comparisons[0].paired.scenarios == ("bend",)


def test_claim_2_curve_single_is_information():
    curvature = dict(CURVES, **{"curve-single": 1 / 100})
    rows = paired("yaw_rmse_deg", FUSED, CARTESIAN, [-2.0, -2.1, -1.9, -2.0, -2.2, -1.8, -2.0, -2.05], scenario="bend")
    rows += paired("yaw_rmse_deg", FUSED, CARTESIAN, [0.1, 0.11, 0.09], scenario="curve-single")
    claim = claim_yaw(rows, [FUSED, CARTESIAN], {}, curvature)
    assert [c.verdict for c in claim.comparisons] == ["supported", "contradicted"]
    assert verdict_of(claim) == "supported"
    # no curved scenario at all: not evaluated
    flat = paired("yaw_rmse_deg", FUSED, CARTESIAN, BELOW, scenario="straight")
    assert claim_yaw(flat, [FUSED, CARTESIAN], {}, {"straight": 0.0}).verdict == "not evaluated"


# -- claim 3: length and width close to the truth ---------------------------------------------------
LENGTH_BOUND = EXTENT_CLOSE_FRACTION * BirthConfig().length
WIDTH_BOUND = EXTENT_CLOSE_FRACTION * BirthConfig().width


def extent_rows(length: str | None, width: str | None) -> list[dict]:
    rows = []
    if length is not None:
        rows += runs("length_rmse_m", "s1", {FUSED: bound_values(length, LENGTH_BOUND)})
    if width is not None:
        rows += runs("width_rmse_m", "s1", {FUSED: bound_values(width, WIDTH_BOUND)})
    return rows


def test_claim_3_bound_is_ten_percent_of_the_nominal_car():
    assert EXTENT_CLOSE_FRACTION == 0.10
    assert (LENGTH_BOUND, WIDTH_BOUND) == pytest.approx((0.1 * BirthConfig().length, 0.1 * BirthConfig().width))


@pytest.mark.parametrize("verdict", sorted(DIFFS))
@pytest.mark.parametrize("metric", ["length", "width"])
def test_claim_3_just_inside_and_just_outside_the_bound(verdict, metric):
    rows = extent_rows(verdict, "supported") if metric == "length" else extent_rows("supported", verdict)
    claim = claim_extent(rows, [FUSED], {})
    assert verdict_of(claim) == verdict
    iv = claim.intervals[f"{FUSED} {metric}_rmse_m"]
    bound = LENGTH_BOUND if metric == "length" else WIDTH_BOUND
    assert abs((iv.high if verdict != "contradicted" else iv.low) - bound) < 2 * EPS
    assert ("Likely reason" in claim.text) == (verdict != "supported")


@pytest.mark.parametrize(("length", "width", "expected"), [
    ("supported", "not shown", "not shown"),
    ("not shown", "contradicted", "contradicted"),
    ("contradicted", "supported", "contradicted"),
    ("supported", None, "supported"),  # no width values: the length decides
    (None, "not shown", "not shown"),
    (None, None, "not evaluated"),
])
def test_claim_3_combines_length_and_width(length, width, expected):
    claim = claim_extent(extent_rows(length, width), [FUSED], {})
    assert claim.verdict == expected


def test_claim_3_ignores_other_variants_and_notes_point_trackers():
    rows = extent_rows("supported", "supported")
    rows += runs("length_rmse_m", "s1", {LIDAR: [5.0] * 5, GNN: [None] * 5})  # far off, but not the claim's variant
    claim = claim_extent(rows, [FUSED, LIDAR, GNN], {})
    assert verdict_of(claim) == "supported"
    assert "point-gnn reports no extent: its length/width RMSE is missing in 5 of 5 runs" in claim.text
    assert claim_extent(rows, [LIDAR], {}).verdict == "not evaluated"


# -- claim 4: the extended tracker beats the point trackers in position ------------------------------
@pytest.mark.parametrize(("gnn", "stonesoup", "expected"), [
    ("supported", "supported", "supported"),
    ("supported", "not shown", "not shown"),
    ("not shown", "not shown", "not shown"),
    ("supported", "contradicted", "contradicted"),
    ("contradicted", "not shown", "contradicted"),
    ("supported", None, "supported"),  # stonesoup-gmphd not in the study
    (None, "contradicted", "contradicted"),
])
def test_claim_4(gnn, stonesoup, expected):
    rows, variants = [], [FUSED]
    base = [10.0] * 5
    values = {FUSED: base}
    if gnn is not None:
        values[GNN] = [b - d for b, d in zip(base, DIFFS[gnn])]
        variants.append(GNN)
    if stonesoup is not None:
        values[STONESOUP] = [b - d for b, d in zip(base, DIFFS[stonesoup])]
        variants.append(STONESOUP)
    rows = runs("pos_rmse_m", "s1", values)
    skipped = {STONESOUP: "needs Stone Soup"} if stonesoup is None else {}
    claim = claim_position(rows, variants, skipped)
    assert verdict_of(claim) == expected
    assert [c.paired.b for c in claim.comparisons] == variants[1:]
    if stonesoup is None:
        assert "stonesoup-gmphd (needs Stone Soup)" in claim.text


def test_claim_4_without_point_trackers_is_not_evaluated():
    claim = claim_position(runs("pos_rmse_m", "s1", {FUSED: [1.0] * 5}), [FUSED], {})
    assert claim.verdict == "not evaluated" and not claim.comparisons


# -- claim 5: exact Frenet kinematics and the exact conversion, on tight curves ----------------------
KAPPA5 = {"hairpin": 1 / 50, "bend": 1 / 300, "straight": 0.0}


def motion_rows(motion: str, conversion: str, scenario: str = "hairpin", seed0: int = 0) -> list[dict]:
    """fused - paper-motion = DIFFS[motion], paper-motion - paper = DIFFS[conversion], in position and yaw."""
    rows = []
    for metric in ("pos_rmse_m", "yaw_rmse_deg"):
        paper = [10.0] * 5
        pm = [p + d for p, d in zip(paper, DIFFS[conversion])]
        fused = [p + d for p, d in zip(pm, DIFFS[motion])]
        rows += runs(metric, scenario, {FUSED: fused, PAPER_MOTION: pm, PAPER: paper}, seed0)
    return rows


@pytest.mark.parametrize(("motion", "conversion", "expected"), [
    ("supported", "supported", "supported"),
    ("supported", "not shown", "not shown"),
    ("not shown", "supported", "not shown"),
    ("contradicted", "supported", "contradicted"),
    ("supported", "contradicted", "contradicted"),
    ("not shown", "contradicted", "contradicted"),
])
def test_claim_5(motion, conversion, expected):
    # the bend and the straight road say the opposite; with a tight curve in the suite only it counts
    rows = motion_rows(motion, conversion)
    rows += motion_rows("contradicted" if expected == "supported" else "supported", "supported", "bend")
    rows += motion_rows("contradicted", "contradicted", "straight")
    claim = claim_motion(rows, [FUSED, PAPER_MOTION, PAPER], {}, KAPPA5)
    assert verdict_of(claim) == expected
    assert len(claim.comparisons) == 4 and all(c.paired.scenarios == ("hairpin",) for c in claim.comparisons)
    assert f"Motion model: {motion}; conversion: {conversion}." in claim.text


def test_claim_5_uses_the_curved_roads_without_a_tight_one():
    rows = motion_rows("supported", "supported", "bend") + motion_rows("contradicted", "contradicted", "straight")
    kappa = {"bend": 1 / 300, "straight": 0.0}
    assert claim_motion(rows, [FUSED, PAPER_MOTION, PAPER], {}, kappa).verdict == "supported"


def test_claim_5_with_one_comparison_missing():
    rows = motion_rows("not shown", "supported")
    claim = claim_motion(rows, [FUSED, PAPER_MOTION], {PAPER: "not asked"}, KAPPA5)
    assert claim.verdict == "not shown" and len(claim.comparisons) == 2
    assert "The conversion comparison (paper-motion vs paper) is not evaluated" in claim.text
    assert claim_motion(rows, [FUSED], {}, KAPPA5).verdict == "not evaluated"


# -- claim 6: real time, and the paper's ordering ---------------------------------------------------
def runtime_rows(realtime: str, ordering: str | None) -> list[dict]:
    """curvilinear-fused's tracker time per frame at ``realtime``'s place against the lidar period;
    point-gnn - curvilinear-fused = DIFFS[ordering] (the paper: point GNN faster)."""
    fused = bound_values(realtime, LIDAR_PERIOD_MS)
    values = {FUSED: fused}
    if ordering is not None:
        values[GNN] = [f + d for f, d in zip(fused, DIFFS[ordering])]
    return runs("tracker_ms_mean", "s1", values)


def test_claim_6_bound_is_the_lidar_period():
    assert LIDAR_PERIOD_MS == 100.0


@pytest.mark.parametrize("verdict", sorted(DIFFS))
def test_claim_6_just_inside_and_just_outside_real_time(verdict):
    claim = claim_runtime(runtime_rows(verdict, None), [FUSED], {})
    assert verdict_of(claim) == verdict
    iv = claim.intervals[FUSED]
    assert abs((iv.high if verdict != "contradicted" else iv.low) - LIDAR_PERIOD_MS) < 2 * EPS
    assert "point-gnn" in claim.text  # noted as not in the study


@pytest.mark.parametrize(("realtime", "ordering", "expected"), [
    ("supported", "supported", "supported"),
    ("supported", "not shown", "not shown"),
    ("supported", "contradicted", "contradicted"),
    ("not shown", "supported", "not shown"),
    ("contradicted", "supported", "contradicted"),
])
def test_claim_6_combines_real_time_and_the_ordering(realtime, ordering, expected):
    claim = claim_runtime(runtime_rows(realtime, ordering), [FUSED, GNN], {})
    assert verdict_of(claim) == expected
    assert claim.comparisons[0].verdict == ordering


def test_claim_6_without_the_extended_tracker():
    rows = runs("tracker_ms_mean", "s1", {GNN: [1.0, 1.1, 0.9]})
    claim = claim_runtime(rows, [GNN], {})
    assert claim.verdict == "not evaluated" and GNN in claim.intervals


# -- all six --------------------------------------------------------------------------------------
def test_evaluate_claims_on_one_study():
    rows = paired("gospa_localization_mean", FUSED, LIDAR, BELOW)
    rows += paired("yaw_rmse_deg", FUSED, CARTESIAN, AROUND, scenario="hairpin")
    rows += extent_rows("supported", "contradicted")
    rows += runs("pos_rmse_m", "s1", {FUSED: [1.0] * 5, GNN: [1.0 - d for d in BELOW]})
    rows += motion_rows("supported", "supported", seed0=100)
    rows += runtime_rows("supported", "supported")
    claims = evaluate_claims(rows, [FUSED, LIDAR, CARTESIAN, PAPER_MOTION, PAPER, GNN], {STONESOUP: "skipped"}, KAPPA5)
    assert [c.number for c in claims] == [1, 2, 3, 4, 5, 6]
    assert [c.verdict for c in claims] == ["supported", "not shown", "contradicted", "supported", "supported", "supported"]
