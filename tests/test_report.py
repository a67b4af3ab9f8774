"""REPORT.md from a tiny comparison study (sim/studies/report.py, sim/studies/study.py): every section and figure,
the paired CSV, the skipped-variant note, the hard-suite section, and the files round-trip."""

from pathlib import Path

import pytest

from sim.evaluation import variants as variants_module
from sim.studies.report import FIGURES, write_report
from sim.studies.study import CompareSettings, read_compare, run_compare, write_compare
from sim.world.scenario import SCENARIO_DIR


def _suite(folder: Path, name: str, scenarios: list[str]) -> str:
    path = folder / f"{name}.toml"
    listed = ", ".join(f'"{SCENARIO_DIR / (s + ".toml")}"' for s in scenarios)
    path.write_text(f'name = "{name}"\ndescription = "tiny suite for the report test"\nscenarios = [{listed}]\n')
    return str(path)


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    folder = tmp_path_factory.mktemp("compare")
    suite = _suite(folder, "tiny", ["curvy-multi", "curve-single", "chicane-follow"])
    hard = _suite(folder, "tiny-hard", ["truck-hairpin"])

    def broken(road, config):
        raise variants_module.VariantUnavailableError("needs a package not installed in this test")

    mp = pytest.MonkeyPatch()
    mp.setitem(variants_module._VARIANTS, "broken",
               variants_module.Variant("broken", "cannot be built here", variants_module._paper_motion, broken))
    warnings = []
    settings = CompareSettings(suite=suite, runs=2, duration=1.5, hard_suite=hard, hard_runs=1, workers=1,
                               variants=("curvilinear-fused", "curvilinear-lidar", "cartesian-fused", "stonesoup-gmphd",
                                         "broken"))
    try:
        data = run_compare(settings, warn=warnings.append)
    finally:
        mp.undo()
    data.meta["command"] = "eot compare (test)"
    out = folder / "results"
    files = write_compare(data, out / "report")
    paths = write_report(data, out)
    return data, out, files, paths, warnings


def test_study_pairs_every_variant_on_the_same_seeds(study):
    data, _, _, _, warnings = study
    assert warnings == ["skipping variant broken: needs a package not installed in this test"]
    assert data.meta["variants"] == ["curvilinear-fused", "curvilinear-lidar", "cartesian-fused", "stonesoup-gmphd"]
    keys = {(r["scenario"], r["seed"]) for r in data.rows}
    assert keys == {(s, k) for s in ("curvy-multi", "curve-single", "chicane-follow") for k in (0, 1)}
    assert len(data.rows) == 3 * 4 * 2 and len(data.hard_rows) == 4
    assert data.meta["figure_runs_match"] is True
    # figure series: fused/lidar on curvy-multi, curvilinear/Cartesian on curve-single, every variant on chicane-follow
    runs = {(r["scenario"], r["variant"]) for r in data.series}
    assert runs == {("curvy-multi", "curvilinear-fused"), ("curvy-multi", "curvilinear-lidar"),
                    ("curve-single", "curvilinear-fused"), ("curve-single", "cartesian-fused")} | {
        ("chicane-follow", v) for v in data.meta["variants"]}
    assert data.meta["curvature"]["chicane-follow"] == pytest.approx(0.02)


def test_report_has_every_section_and_figure(study):
    data, out, _, paths, _ = study
    text = (out / "REPORT.md").read_text()
    for heading in ("## How this was made", "## The claims", "## Figures", "## Per-scenario results",
                    "## Wall time per run", "## The hard suite", "#### curvy-multi", "#### chicane-follow"):
        assert heading in text
    for k in range(1, 7):
        assert f"### {k}. " in text
    assert "**skipped** `broken`: needs a package not installed in this test" in text
    assert "**Verdict: " in text and "not evaluated" in text  # paper-motion/point-gnn were not in this study
    for name in FIGURES:
        png = out / "report" / name
        assert f"(report/{name})" in text and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "| stonesoup-gmphd |" in text and "n/a" in text  # no extent for the point baseline
    paired = (out / "report" / "paired.csv").read_text().splitlines()
    assert paired[0].startswith("claim,metric,a,b") and any(",curvilinear-fused,curvilinear-lidar," in ln for ln in paired)


def test_report_rebuilds_identically_from_its_files(study):
    data, out, _, _, _ = study
    first = (out / "REPORT.md").read_text()
    again = read_compare(out / "report")
    assert len(again.rows) == len(data.rows) and len(again.series) == len(data.series)
    write_report(again, out)
    assert (out / "REPORT.md").read_text() == first


def test_seed_provenance_says_in_sample_or_held_out():
    from sim.studies.report import TUNING_SEEDS, seed_provenance

    assert seed_provenance(1000, 20).startswith("held-out seeds")
    assert seed_provenance(TUNING_SEEDS.stop, 5).startswith("held-out seeds")
    text = seed_provenance(TUNING_SEEDS.stop - 3, 10)
    assert text.startswith("**in-sample**") and "3 of the 10 seeds" in text
    assert "20 of the 20 seeds" in seed_provenance(0, 20)


def test_pooled_numbers_and_the_real_traffic_section():
    """``pooled`` takes runs together as the hand computation does; the real-traffic section shows them
    beside the simulated suite's."""
    from sim.studies.report import pooled, render_report
    from sim.studies.study import CompareData

    def row(scenario, variant, seed, frames, gospa_seen, pos_seen, pairs, hidden, length, switches, width=0.1, yaw=1.0,
            card=0.5, ms=2.0):
        return {"scenario": scenario, "variant": variant, "seed": seed, "frames": frames, "gospa_seen_mean": gospa_seen,
                "pos_rmse_seen_m": pos_seen, "matched_pairs": pairs, "matched_pairs_hidden": hidden, "length_rmse_m": length,
                "width_rmse_m": width, "yaw_rmse_deg": yaw, "cardinality_error_seen_mean": card, "id_switches": switches,
                "tracker_ms_median": ms, "gospa_mean": gospa_seen}

    real = [row("real-a", "curvilinear-fused", 0, 100, 2.0, 0.3, 50, 10, 1.0, 1, width=0.2, yaw=2.0, card=1.0, ms=1.0),
            row("real-b", "curvilinear-fused", 0, 300, 4.0, 0.6, 130, 10, 0.5, 3, width=0.1, yaw=4.0, card=0.2, ms=5.0),
            row("real-c", "curvilinear-fused", 0, 200, 3.0, None, 0, 0, None, 0, width=None, yaw=None, card=0.4, ms=3.0)]
    p = pooled(real)
    assert p["gospa_seen"] == pytest.approx((100 * 2.0 + 300 * 4.0 + 200 * 3.0) / 600)
    assert p["pos_seen"] == pytest.approx(((40 * 0.3**2 + 120 * 0.6**2) / 160) ** 0.5)  # over the seen pairs
    assert p["length"] == pytest.approx(((50 * 1.0 + 130 * 0.25) / 180) ** 0.5)
    assert p["width"] == pytest.approx(((50 * 0.04 + 130 * 0.01) / 180) ** 0.5)
    assert p["yaw"] == pytest.approx(((50 * 4.0 + 130 * 16.0) / 180) ** 0.5)
    assert p["card_seen"] == pytest.approx((100 * 1.0 + 300 * 0.2 + 200 * 0.4) / 600)
    assert p["switches_per_1000"] == pytest.approx(1000 * 4 / 600)
    assert p["ms_median"] == pytest.approx(3.0)
    real = real[:2]
    simulated = [row("curve-single", "curvilinear-fused", 0, 200, 0.1, 0.05, 200, 0, 0.1, 0)]
    data = CompareData(simulated, [], [], {"settings": {"suite": "standard", "real_suite": "real", "real_runs": 1},
                                           "variants": ["curvilinear-fused"]}, real)
    text = render_report(data, [])
    assert "## Real recorded traffic" in text and "| real-b | curvilinear-fused |" in text
    assert "| standard | curvilinear-fused | 0.10 |" in text and "| real | curvilinear-fused | 3.50 |" in text
    assert "## Real recorded traffic" not in render_report(CompareData(simulated, [], [], data.meta), [])


def test_pooled_length_shown_split_and_its_table():
    """``pooled`` takes the shown / not-shown parts of runs together over their pairs; the table has a row per
    suite and extended variant, none for a tracker without the split (a point tracker)."""
    from sim.studies.report import observability_table, pooled

    def row(variant, seen, shown, pos_shown, pos_unshown, len_shown, len_unshown, faces=None, w_shown=None,
            w_unshown=None):
        return {"variant": variant, "frames": 10, "matched_pairs_seen": seen, "matched_pairs_seen_length_shown": shown,
                "pos_rmse_seen_length_shown_m": pos_shown, "pos_rmse_seen_length_unshown_m": pos_unshown,
                "length_rmse_seen_shown_m": len_shown, "length_rmse_seen_unshown_m": len_unshown,
                "matched_pairs_seen_width_shown": faces, "width_rmse_seen_shown_m": w_shown,
                "width_rmse_seen_unshown_m": w_unshown}

    rows = [row("curvilinear-fused", 100, 40, 0.1, 0.5, 0.05, 0.8, 90, 0.03, 0.3),
            row("curvilinear-fused", 50, 30, 0.2, 0.3, 0.1, 0.6, 10, 0.05, 0.2),
            row("stonesoup-gmphd", 80, 0, None, None, None, None) | {"matched_pairs_seen": None}]
    p = pooled(rows[:2])
    assert p["shown_share"] == pytest.approx(70 / 150)
    assert p["pos_shown"] == pytest.approx(((40 * 0.01 + 30 * 0.04) / 70) ** 0.5)
    assert p["pos_unshown"] == pytest.approx(((60 * 0.25 + 20 * 0.09) / 80) ** 0.5)
    assert p["length_unshown"] == pytest.approx(((60 * 0.64 + 20 * 0.36) / 80) ** 0.5)
    assert p["width_shown_share"] == pytest.approx(100 / 150)
    assert p["width_shown"] == pytest.approx(((90 * 0.03**2 + 10 * 0.05**2) / 100) ** 0.5)
    assert p["width_unshown"] == pytest.approx(((10 * 0.3**2 + 40 * 0.2**2) / 50) ** 0.5)
    assert pooled(rows[2:])["shown_share"] is None and pooled(rows[2:])["width_shown_share"] is None
    table = observability_table([("real", rows)], ["curvilinear-fused", "stonesoup-gmphd"])
    assert "| real | curvilinear-fused | 0.47 | " in table and "stonesoup-gmphd" not in table
    assert table.splitlines()[2].endswith(" | 0.67 | 0.03 | 0.22 |")
