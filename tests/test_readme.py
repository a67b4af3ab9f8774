"""The README is a user's page: short, free of development history, its links alive, and its headline
numbers exactly those of the committed reference outputs (``results/report/runs.csv`` from
``eot compare``, ``results/bench.json`` from ``eot bench``).

``python tests/test_readme.py`` prints the two headline tables as the README must hold them, so that
after re-making the reference outputs the README is updated by pasting, not by hand-editing numbers.
"""

from __future__ import annotations

import csv
import json
import math
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"

#: The variants of the headline table, in its row order, with the note shown after the name.
HEADLINE_VARIANTS = (
    ("curvilinear-fused", " (default)"),
    ("curvilinear-lidar", ""),
    ("cartesian-fused", ""),
    ("paper", ""),
    ("point-gnn", ""),
    ("stonesoup-gmphd", ""),
)
#: (column title, runs.csv metric, decimals)
HEADLINE_COLUMNS = (
    ("GOSPA (m)", "gospa_mean", 2),
    ("position RMSE (m)", "pos_rmse_m", 2),
    ("yaw RMSE (deg)", "yaw_rmse_deg", 2),
    ("length RMSE (m)", "length_rmse_m", 2),
    ("ID switches per run", "id_switches", 2),
)
#: Vehicles in view of the speed table's columns (``results/bench.json`` ``tracker`` section).
SPEED_COUNTS = ("1", "5", "10", "20", "50")


def _mean(values: list[float]) -> float:
    finite = [v for v in values if math.isfinite(v)]
    return sum(finite) / len(finite) if finite else math.nan


def _fmt(value: float, decimals: int) -> str:
    return "n/a" if not math.isfinite(value) else f"{value:.{decimals}f}"


def headline_table(runs_csv: Path = ROOT / "results/report/runs.csv") -> str:
    """The README's accuracy table: per variant, the mean over the study's runs of each metric."""
    with open(runs_csv, newline="") as f:
        rows = list(csv.DictReader(f))
    lines = ["| variant | " + " | ".join(c[0] for c in HEADLINE_COLUMNS) + " |",
             "|---|" + "---:|" * len(HEADLINE_COLUMNS)]
    for variant, note in HEADLINE_VARIANTS:
        mine = [r for r in rows if r["variant"] == variant]
        assert mine, f"no runs of {variant} in {runs_csv}"
        cells = [_fmt(_mean([float(r[m]) if r[m] not in ("", None) else math.nan for r in mine]), d)
                 for _, m, d in HEADLINE_COLUMNS]
        lines.append(f"| `{variant}`{note} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def speed_table(bench_json: Path = ROOT / "results/bench.json") -> str:
    """The README's speed table: tracker ms per frame (median) by vehicles in view, and Stone Soup's
    GM-PHD on the same frames at 10 vehicles."""
    bench = json.loads(bench_json.read_text())
    results = bench["tracker"]["results"]
    lines = ["| vehicles in view | " + " | ".join(SPEED_COUNTS) + " |", "|---|" + "---:|" * len(SPEED_COUNTS)]
    for variant in ("curvilinear-fused", "curvilinear-lidar"):
        cells = [f"{results[variant][n]['ms_median']:.2f}" for n in SPEED_COUNTS]
        lines.append(f"| `{variant}`, ms per frame (median) | " + " | ".join(cells) + " |")
    soup = bench["stonesoup"]
    n = str(soup["targets"])
    cells = [f"{soup['stonesoup']['ms_median']:.1f}" if c == n else "" for c in SPEED_COUNTS]
    lines.append("| Stone Soup GM-PHD (points, UKF), same frames | " + " | ".join(cells) + " |")
    ratio = soup["ratio_stonesoup_over_ours"]["curvilinear-fused"]
    cells = [f"{ratio:.1f} x" if c == n else "" for c in SPEED_COUNTS]
    lines.append("| Stone Soup's time / `curvilinear-fused`'s | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def test_readme_is_short():
    assert len(README.read_text()) <= 15_000


def test_readme_headline_numbers_match_the_reference_outputs():
    text = README.read_text()
    assert headline_table() in text, "README's accuracy table differs from results/report/runs.csv: " \
                                     "paste the output of `python tests/test_readme.py`"
    assert speed_table() in text, "README's speed table differs from results/bench.json: " \
                                  "paste the output of `python tests/test_readme.py`"


def test_readme_claims_verdicts_match_the_report():
    """The README says all six claims are supported: the committed report must say so too."""
    assert "All six of the paper's claims" in README.read_text()
    verdicts = re.findall(r"^\*\*Verdict: ([a-z ]+)\.\*\*", (ROOT / "results/REPORT.md").read_text(), re.MULTILINE)
    assert verdicts == ["supported"] * 6, verdicts


def test_readme_and_docs_links_exist():
    pages = [README, *sorted((ROOT / "docs").glob("*.md")), ROOT / "results/README.md"]
    for page in pages:
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", page.read_text()):
            if "://" in target:
                continue
            assert (page.parent / target).exists(), f"{page.relative_to(ROOT)} links to missing {target}"


def test_no_development_history_in_the_product():
    """Docs and code say what things are; history lives in git and the issue notes."""
    pattern = re.compile(r"session [0-9]|issue [0-9]", re.IGNORECASE)
    paths = [README, *(ROOT / "docs").rglob("*.md"), *(ROOT / "sim").rglob("*.py"), *(ROOT / "tracker").rglob("*.py")]
    found = [f"{p.relative_to(ROOT)}:{i}" for p in paths for i, line in enumerate(p.read_text().splitlines(), 1)
             if pattern.search(line)]
    assert not found, found


if __name__ == "__main__":
    print(headline_table())
    print()
    print(speed_table())


def test_readme_real_traffic_numbers_match_the_reference_outputs():
    """The README's sentence on real recorded traffic quotes the committed real-suite runs, pooled as
    REPORT.md pools them (``sim.studies.report.pooled``)."""
    from sim.studies.montecarlo import read_runs
    from sim.studies.report import pooled

    text = " ".join(README.read_text().split())
    real = pooled([r for r in read_runs(ROOT / "results/report/real_runs.csv") if r["variant"] == "curvilinear-fused"])
    standard = pooled([r for r in read_runs(ROOT / "results/report/runs.csv") if r["variant"] == "curvilinear-fused"])
    expected = (f"seen GOSPA is {real['gospa_seen']:.1f} m ({standard['gospa_seen']:.2f} m on the standard suite), its "
                f"position error on seen vehicles {real['pos_seen']:.2f} m ({standard['pos_seen']:.2f} m), length "
                f"{real['length']:.1f} m ({standard['length']:.2f} m), width {real['width']:.2f} m ({standard['width']:.2f} m), "
                f"and it switches identities about {real['switches_per_1000']:.0f} times per 1,000 frames "
                f"({standard['switches_per_1000']:.2f})")
    assert expected in text, f"README's real-traffic sentence differs from the reference outputs: {expected}"
    split = (f"where a vehicle's side has been seen whole, the position error is {real['pos_shown']:.2f} m; on the "
             f"{100 * (1 - real['shown_share']):.0f} % of seen pairs whose length was never shown (a queue followed in "
             f"one lane), the centre inherits half the length prior's error, and it is {real['pos_unshown']:.2f} m")
    assert split in text, f"README's length-shown sentence differs from the reference outputs: {split}"
    widths = (f"where an end has been seen whole, the width error is {real['width_shown']:.2f} m, and "
              f"{real['width_unshown']:.2f} m on the {100 * (1 - real['width_shown_share']):.0f} % of seen pairs "
              "whose end was never seen whole (a side seen, or an end only in part)")
    assert widths in text, f"README's width-shown sentence differs from the reference outputs: {widths}"
