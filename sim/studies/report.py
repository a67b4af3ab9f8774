"""``results/REPORT.md`` and its figures from a comparison study (``sim.studies.study.CompareData``).

``write_report(data, out)`` writes ``out/REPORT.md`` and, in ``out/report/``, the figures
(``FIGURES``) and ``summary.csv`` (per scenario, variant and metric: n, mean and 95 % interval) and
``paired.csv`` (every paired comparison of the claims). Sections: how it was made (command, settings,
wall times, skipped variants), the claims (``sim.studies.claims``: one paragraph each, from the numbers), the
per-scenario tables (``TABLE_METRICS``, mean and 95 % t interval over seeds), the figures, the
per-run wall time per variant (to budget a study) and, when it ran, the hard suite.

Figures (matplotlib's Agg canvas, never pyplot, as ``sim.evaluation.plots``):

- ``fused_vs_lidar.png``: GOSPA and cardinality over time on curvy-multi, fused vs lidar-only;
- ``curvilinear_vs_cartesian.png``: GOSPA and yaw error over time on curve-single;
- ``chicane_follow.png``: the followed car's position error, yaw, length and width against the truth
  on chicane-follow, every variant (point variants have no length/width);
- ``gospa_variants.png``: mean GOSPA per scenario of every variant side by side, with 95 % intervals;
- ``runtime.png``: mean tracker time per frame of every variant with 95 % intervals.

GOSPA: alpha 2, p 2, c 5 m on rectangle centres; its parts are p-th-power sums (m^2).
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from sim.studies.claims import ClaimResult, evaluate_claims, fmt
from sim.studies.study import CompareData, Interval, mean_interval
from tracker.angles import wrap_angle

#: Metrics of the per-scenario tables: (runs.csv key, column title).
TABLE_METRICS: tuple[tuple[str, str], ...] = (
    ("gospa_mean", "GOSPA (m)"),
    ("gospa_localization_mean", "loc. (m²)"),
    ("gospa_missed_mean", "missed (m²)"),
    ("gospa_false_mean", "false (m²)"),
    ("cardinality_error_mean", "card. err."),
    ("pos_rmse_m", "pos. (m)"),
    ("yaw_rmse_deg", "yaw (deg)"),
    ("speed_rmse_mps", "speed (m/s)"),
    ("length_rmse_m", "length (m)"),
    ("width_rmse_m", "width (m)"),
    ("id_switches", "ID sw."),
    ("tracker_ms_mean", "ms/frame"),
)
FIGURES = ("fused_vs_lidar.png", "curvilinear_vs_cartesian.png", "chicane_follow.png", "gospa_variants.png", "runtime.png")
_COLORS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22"]


def _figure(width: float, height: float) -> Figure:
    fig = Figure(figsize=(width, height), dpi=110)
    FigureCanvasAgg(fig)
    return fig


def _color(variants: Sequence[str], name: str) -> str:
    return _COLORS[list(variants).index(name) % len(_COLORS)] if name in variants else "#000000"


def _series(series: Sequence[dict[str, Any]], scenario: str, variant: str) -> dict[str, np.ndarray]:
    rows = [r for r in series if r["scenario"] == scenario and r["variant"] == variant]
    keys = rows[0].keys() if rows else ()
    return {k: np.array([r[k] for r in rows]) for k in keys if k not in ("scenario", "variant")}


def _no_data(ax: Any, text: str) -> None:
    ax.text(0.5, 0.5, text, ha="center", va="center", transform=ax.transAxes, fontsize=9, color="grey")


def plot_fused_vs_lidar(data: CompareData, path: Path) -> Path:
    """GOSPA and cardinality over time on curvy-multi: curvilinear-fused vs curvilinear-lidar."""
    variants = data.meta.get("variants", [])
    fig = _figure(8.5, 6.0)
    ax_g, ax_c = fig.subplots(2, 1, sharex=True)
    truth_drawn = False
    for v in ("curvilinear-fused", "curvilinear-lidar"):
        s = _series(data.series, "curvy-multi", v)
        if not s:
            continue
        ax_g.plot(s["t"], s["gospa"], color=_color(variants, v), lw=1.2, label=v)
        ax_c.plot(s["t"], s["n_tracks"], color=_color(variants, v), lw=1.2, drawstyle="steps-post", label=f"{v} estimated")
        if not truth_drawn:
            ax_c.plot(s["t"], s["n_truth"], color="black", lw=1.6, ls="--", drawstyle="steps-post", label="true", zorder=3)
            truth_drawn = True
    if not truth_drawn:
        _no_data(ax_g, "curvy-multi or the variants were not in this study")
    ax_g.set_ylabel("GOSPA (m)")
    ax_c.set_ylabel("number of targets")
    ax_c.set_xlabel("t (s)")
    for ax in (ax_g, ax_c):
        ax.grid(alpha=0.3)
        if truth_drawn:
            ax.legend(fontsize=8, loc="best")
    seed = data.meta.get("settings", {}).get("seed0", 0)
    ax_g.set_title(f"curvy-multi, seed {seed}: fused vs lidar-only (GOSPA alpha 2, p 2, c 5 m)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    return path


def plot_curvilinear_vs_cartesian(data: CompareData, path: Path) -> Path:
    """GOSPA and the target's yaw error over time on curve-single: curvilinear vs Cartesian."""
    variants = data.meta.get("variants", [])
    fig = _figure(8.5, 6.0)
    ax_g, ax_y = fig.subplots(2, 1, sharex=True)
    drawn = False
    for v in ("curvilinear-fused", "cartesian-fused"):
        s = _series(data.series, "curve-single", v)
        if not s:
            continue
        drawn = True
        ax_g.plot(s["t"], s["gospa"], color=_color(variants, v), lw=1.2, label=v)
        ax_y.plot(s["t"], np.degrees(wrap_angle(s["est_yaw"] - s["truth_yaw"])), color=_color(variants, v), lw=1.2, label=v)
    if not drawn:
        _no_data(ax_g, "curve-single or the variants were not in this study")
    ax_g.set_ylabel("GOSPA (m)")
    ax_y.set_ylabel("yaw error (deg)")
    ax_y.axhline(0.0, color="black", lw=0.8)
    ax_y.set_xlabel("t (s)")
    for ax in (ax_g, ax_y):
        ax.grid(alpha=0.3)
        if drawn:
            ax.legend(fontsize=8, loc="best")
    seed = data.meta.get("settings", {}).get("seed0", 0)
    ax_g.set_title(f"curve-single (R 150 m), seed {seed}: curvilinear vs Cartesian state", fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    return path


def plot_chicane(data: CompareData, path: Path) -> Path:
    """Position error, yaw, length and width of the followed car on chicane-follow, every variant."""
    variants = data.meta.get("variants", [])
    fig = _figure(9.0, 10.0)
    axes = fig.subplots(4, 1, sharex=True)
    truth = None
    for v in variants:
        s = _series(data.series, "chicane-follow", v)
        if not s:
            continue
        truth = truth if truth is not None else s
        c = _color(variants, v)
        axes[0].plot(s["t"], np.hypot(s["est_x"] - s["truth_x"], s["est_y"] - s["truth_y"]), color=c, lw=1.1, label=v)
        ref = np.unwrap(np.nan_to_num(s["truth_yaw"]))
        axes[1].plot(s["t"], np.degrees(ref + np.angle(np.exp(1j * (s["est_yaw"] - ref)))), color=c, lw=1.1)
        if np.isfinite(s["est_length"]).any():
            axes[2].plot(s["t"], s["est_length"], color=c, lw=1.1)
            axes[3].plot(s["t"], s["est_width"], color=c, lw=1.1)
    if truth is None:
        _no_data(axes[0], "chicane-follow was not in this study")
    else:
        t = truth["t"]
        axes[1].plot(t, np.degrees(np.unwrap(np.nan_to_num(truth["truth_yaw"]))) * np.where(np.isnan(truth["truth_yaw"]), np.nan, 1.0),
                     color="black", lw=2.0, ls="--", label="truth")
        axes[2].plot(t, truth["truth_length"], color="black", lw=2.0, ls="--", label="truth")
        axes[3].plot(t, truth["truth_width"], color="black", lw=2.0, ls="--", label="truth")
        axes[0].legend(fontsize=7, ncol=2, loc="upper right")
        axes[1].legend(fontsize=7, loc="best")
    for ax, name in zip(axes, ("position error (m)", "yaw (deg)", "length (m)", "width (m)")):
        ax.set_ylabel(name)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("t (s)")
    seed = data.meta.get("settings", {}).get("seed0", 0)
    axes[0].set_title(f"chicane-follow (R 50 m), seed {seed}: the followed car; point trackers have no length/width",
                      fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    return path


def _scenarios(rows: Sequence[dict[str, Any]]) -> list[str]:
    return list(dict.fromkeys(r["scenario"] for r in rows))


def interval_table(rows: Sequence[dict[str, Any]], metric: str) -> dict[tuple[str, str], Interval]:
    """``(scenario, variant) -> Interval`` of ``metric`` over seeds."""
    groups: dict[tuple[str, str], list[Any]] = {}
    for r in rows:
        groups.setdefault((r["scenario"], r["variant"]), []).append(r.get(metric))
    return {k: mean_interval(v) for k, v in groups.items()}


def _bars(ax: Any, groups: list[str], variants: Sequence[str], table: dict[tuple[str, str], Interval]) -> None:
    width = 0.8 / max(1, len(variants))
    x = np.arange(len(groups))
    for k, v in enumerate(variants):
        ivs = [table.get((g, v), Interval(0, None, None, None)) for g in groups]
        means = np.array([iv.mean if iv.mean is not None else np.nan for iv in ivs])
        err = np.array([iv.half_width if iv.half_width is not None else 0.0 for iv in ivs])
        ax.bar(x + (k - 0.5 * (len(variants) - 1)) * width, means, width, yerr=err, capsize=2,
               color=_color(variants, v), label=v)
    ax.set_xticks(x)
    ax.set_xticklabels(groups, rotation=20, ha="right", fontsize=8)
    ax.grid(alpha=0.3, axis="y")


def plot_gospa_variants(data: CompareData, path: Path) -> Path:
    """Mean GOSPA per scenario and variant with 95 % intervals."""
    variants = data.meta.get("variants", [])
    fig = _figure(10.0, 4.8)
    ax = fig.subplots()
    _bars(ax, _scenarios(data.rows), variants, interval_table(data.rows, "gospa_mean"))
    ax.set_ylabel("GOSPA mean (m)")
    ax.legend(fontsize=7, ncol=min(4, max(1, len(variants))))
    ax.set_title("GOSPA of every variant (mean over seeds, 95 % t interval; alpha 2, p 2, c 5 m)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    return path


def plot_runtime(data: CompareData, path: Path) -> Path:
    """Mean tracker time per frame per variant (all scenarios) with 95 % intervals."""
    variants = data.meta.get("variants", [])
    ivs = [mean_interval([r.get("tracker_ms_mean") for r in data.rows if r["variant"] == v]) for v in variants]
    fig = _figure(8.0, 4.0)
    ax = fig.subplots()
    x = np.arange(len(variants))
    ax.bar(x, [iv.mean if iv.mean is not None else np.nan for iv in ivs],
           yerr=[iv.half_width or 0.0 for iv in ivs], capsize=3, color=[_color(variants, v) for v in variants])
    ax.axhline(100.0, color="black", ls="--", lw=1.0, label="10 Hz lidar period")
    ax.set_xticks(x)
    ax.set_xticklabels(variants, rotation=20, ha="right", fontsize=8)
    ax.set_ylabel("tracker ms per frame")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, axis="y")
    ax.set_title("Runtime per frame (mean over runs, 95 % t interval)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    return path


# -- tables and CSVs -------------------------------------------------------------------------------
def _cell(iv: Interval, digits: int = 2) -> str:
    if iv.mean is None:
        return "n/a"
    if iv.half_width is None:
        return fmt(iv.mean, digits)
    return f"{fmt(iv.mean, digits)} ± {fmt(iv.half_width, digits)}"


def scenario_tables(rows: Sequence[dict[str, Any]], variants: Sequence[str]) -> str:
    """Markdown: per scenario a table, a row per variant, ``TABLE_METRICS`` as mean ± 95 % half-width."""
    tables = {m: interval_table(rows, m) for m, _ in TABLE_METRICS}
    out = []
    for scenario in _scenarios(rows):
        n = max((tables["gospa_mean"].get((scenario, v), Interval(0, None, None, None)).n for v in variants), default=0)
        out.append(f"#### {scenario} ({n} runs per variant)\n")
        out.append("| variant | " + " | ".join(t for _, t in TABLE_METRICS) + " |")
        out.append("|---|" + "---|" * len(TABLE_METRICS))
        for v in variants:
            cells = [_cell(tables[m].get((scenario, v), Interval(0, None, None, None))) for m, _ in TABLE_METRICS]
            out.append(f"| {v} | " + " | ".join(cells) + " |")
        out.append("")
    return "\n".join(out)


def write_summary_csv(rows: Sequence[dict[str, Any]], path: Path) -> Path:
    """Per scenario, variant and ``TABLE_METRICS`` metric: n, mean, ci95_low, ci95_high."""
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(["scenario", "variant", "metric", "n", "mean", "ci95_low", "ci95_high"])
        for metric, _ in TABLE_METRICS:
            for (scenario, variant), iv in interval_table(rows, metric).items():
                w.writerow([scenario, variant, metric, iv.n, *("" if x is None else repr(x) for x in (iv.mean, iv.low, iv.high))])
    return path


def write_paired_csv(claims: Sequence[ClaimResult], path: Path) -> Path:
    """Every paired comparison of the claims: claim, metric, A, B, scenarios, n, mean A - B, interval, verdict."""
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(["claim", "metric", "a", "b", "scenarios", "n", "mean_diff", "ci95_low", "ci95_high", "a_mean", "b_mean",
                    "claimed_sign", "verdict"])
        for c in claims:
            for comp in c.comparisons:
                p, d = comp.paired, comp.paired.diff
                w.writerow([c.number, p.metric, p.a, p.b, " ".join(p.scenarios), d.n,
                            *("" if x is None else repr(x) for x in (d.mean, d.low, d.high, p.a_mean, p.b_mean)),
                            comp.sign, comp.verdict])
    return path


def wall_time_table(rows: Sequence[dict[str, Any]], variants: Sequence[str]) -> str:
    """Markdown: per variant the mean wall time of one run (s) per scenario and one pass of the suite."""
    scenarios = _scenarios(rows)
    out = ["| variant | " + " | ".join(scenarios) + " | suite (sum) |", "|---|" + "---|" * (len(scenarios) + 1)]
    for v in variants:
        means = []
        for s in scenarios:
            iv = mean_interval([r.get("wall_s") for r in rows if r["variant"] == v and r["scenario"] == s])
            means.append(iv.mean)
        total = sum(m for m in means if m is not None)
        out.append(f"| {v} | " + " | ".join(fmt(m, 1) for m in means) + f" | {fmt(total, 1)} |")
    return "\n".join(out)


def _suite_section(rows: Sequence[dict[str, Any]], title: str, what: str, metrics: Sequence[tuple[str, str]],
                   variants: Sequence[str]) -> str:
    """A per-scenario table (mean ± 95 % half-width) of ``metrics`` ((key, column title) pairs) over ``rows``."""
    if not rows:
        return ""
    tables = {m: interval_table(rows, m) for m, _ in metrics}
    out = [f"## {title}\n\n{(what + ' ') if what else ''}Mean ± 95 % half-width.\n",
           "| scenario | variant | " + " | ".join(t for _, t in metrics) + " |", "|---|---|" + "---|" * len(metrics)]
    for scenario in _scenarios(rows):
        for v in variants:
            cells = [_cell(tables[m].get((scenario, v), Interval(0, None, None, None))) for m, _ in metrics]
            out.append(f"| {scenario} | {v} | " + " | ".join(cells) + " |")
    return "\n".join(out) + "\n"


def _hard_section(data: CompareData, variants: Sequence[str]) -> str:
    settings = data.meta.get("settings", {})
    metrics = (("gospa_mean", "GOSPA (m)"), ("pos_rmse_m", "pos. (m)"), ("yaw_rmse_deg", "yaw (deg)"),
               ("length_rmse_m", "length (m)"), ("id_switches", "ID sw."))
    return _suite_section(data.hard_rows, "The hard suite", f"{settings.get('hard_runs')} runs per scenario and variant "
                          f"(`{settings.get('hard_suite')}`: trucks, buses, motorcycles, emergency braking, stop-and-go, "
                          "a standing vehicle, tight curves).", metrics, variants)


def pooled(rows: Sequence[dict[str, Any]]) -> dict[str, float | None]:
    """Numbers of a set of runs taken together: frame-weighted means of ``gospa_seen_mean`` and
    ``cardinality_error_seen_mean``, RMSEs over all their matched pairs (``pos_rmse_seen_m`` over the pairs
    of visible vehicles; ``length_rmse_m``, ``width_rmse_m``, ``yaw_rmse_deg`` over all), ID switches per
    1,000 frames and the median of the runs' median tracker ms per frame."""
    def value(r: dict[str, Any], key: str) -> float:
        v = r.get(key)
        return float(v) if isinstance(v, (int, float)) and math.isfinite(float(v)) else float("nan")

    frames = np.array([value(r, "frames") for r in rows])
    pairs = np.array([value(r, "matched_pairs") for r in rows])
    seen = pairs - np.nan_to_num(np.array([value(r, "matched_pairs_hidden") for r in rows]))

    def mean(key: str) -> float | None:
        v = np.array([value(r, key) for r in rows])
        ok = np.isfinite(v) & (frames > 0)
        return float(np.sum(v[ok] * frames[ok]) / np.sum(frames[ok])) if ok.any() else None

    def rms(key: str, weight: np.ndarray) -> float | None:
        v = np.array([value(r, key) for r in rows])
        ok = np.isfinite(v) & (weight > 0)
        return float(math.sqrt(np.sum(v[ok] ** 2 * weight[ok]) / np.sum(weight[ok]))) if ok.any() else None

    total = float(np.nansum(frames))
    ms = [value(r, "tracker_ms_median") for r in rows]
    # the seen pairs split by whether the vehicle has shown its length (sim.evaluation.observability)
    seen_pairs = np.array([value(r, "matched_pairs_seen") for r in rows])
    shown = np.array([value(r, "matched_pairs_seen_length_shown") for r in rows])
    unshown = seen_pairs - shown
    known = np.isfinite(seen_pairs) & np.isfinite(shown)
    faces = np.array([value(r, "matched_pairs_seen_width_shown") for r in rows])  # ... and whether its width
    known_faces = np.isfinite(seen_pairs) & np.isfinite(faces)
    return {"gospa_seen": mean("gospa_seen_mean"), "pos_seen": rms("pos_rmse_seen_m", seen),
            "shown_share": float(shown[known].sum() / seen_pairs[known].sum()) if known.any() and seen_pairs[known].sum() else None,
            "pos_shown": rms("pos_rmse_seen_length_shown_m", shown), "pos_unshown": rms("pos_rmse_seen_length_unshown_m", unshown),
            "length_shown": rms("length_rmse_seen_shown_m", shown), "length_unshown": rms("length_rmse_seen_unshown_m", unshown),
            "width_shown_share": (float(faces[known_faces].sum() / seen_pairs[known_faces].sum())
                                  if known_faces.any() and seen_pairs[known_faces].sum() else None),
            "width_shown": rms("width_rmse_seen_shown_m", faces), "width_unshown": rms("width_rmse_seen_unshown_m", seen_pairs - faces),
            "yaw": rms("yaw_rmse_deg", pairs), "length": rms("length_rmse_m", pairs), "width": rms("width_rmse_m", pairs),
            "card_seen": mean("cardinality_error_seen_mean"),
            "switches_per_1000": 1000.0 * float(np.nansum([value(r, "id_switches") for r in rows])) / total if total else None,
            "ms_median": float(np.nanmedian(ms)) if np.isfinite(ms).any() else None}


def side_by_side_table(suites: Sequence[tuple[str, Sequence[dict[str, Any]]]], variants: Sequence[str]) -> str:
    """One row per (suite, variant): the ``pooled`` numbers of its runs."""
    cols = (("gospa_seen", "seen GOSPA (m)"), ("pos_seen", "pos., seen (m)"), ("yaw", "yaw (deg)"), ("length", "length (m)"),
            ("width", "width (m)"), ("card_seen", "seen card. err."), ("switches_per_1000", "ID sw. / 1000 frames"),
            ("ms_median", "tracker ms (median)"))
    out = ["| suite | variant | " + " | ".join(t for _, t in cols) + " |", "|---|---|" + "---|" * len(cols)]
    for name, rows in suites:
        for v in variants:
            mine = [r for r in rows if r.get("variant") == v]
            if not mine:
                continue
            p = pooled(mine)
            out.append(f"| {name} | {v} | " + " | ".join(fmt(p[k], 2) if p[k] is not None else "n/a" for k, _ in cols) + " |")
    return "\n".join(out) + "\n"


def observability_table(suites: Sequence[tuple[str, Sequence[dict[str, Any]]]], variants: Sequence[str]) -> str:
    """One row per (suite, extended variant): the share of its seen pairs whose vehicle has shown its length
    (a side seen whole, ``sim.evaluation.observability``), and the position and length RMSEs of both parts;
    the share whose vehicle has shown its width (an end seen whole), and the width RMSEs of both parts."""
    cols = (("shown_share", "length shown (share of seen pairs)"), ("pos_shown", "pos., shown (m)"),
            ("pos_unshown", "pos., not shown (m)"), ("length_shown", "length, shown (m)"),
            ("length_unshown", "length, not shown (m)"), ("width_shown_share", "width shown (share)"),
            ("width_shown", "width, shown (m)"), ("width_unshown", "width, not shown (m)"))
    out = ["| suite | variant | " + " | ".join(t for _, t in cols) + " |", "|---|---|" + "---|" * len(cols)]
    for name, rows in suites:
        for v in variants:
            p = pooled([r for r in rows if r.get("variant") == v])
            if p["shown_share"] is None:
                continue  # a point tracker, or no seen pair
            out.append(f"| {name} | {v} | " + " | ".join(fmt(p[k], 2) if p[k] is not None else "n/a" for k, _ in cols) + " |")
    return "\n".join(out) + "\n"


def _real_section(data: CompareData, variants: Sequence[str]) -> str:
    settings = data.meta.get("settings", {})
    if not data.real_rows:
        return ""
    metrics = (("gospa_seen_mean", "seen GOSPA (m)"), ("pos_rmse_seen_m", "pos. seen (m)"), ("length_rmse_m", "length (m)"),
               ("width_rmse_m", "width (m)"), ("cardinality_error_seen_mean", "seen card. err."), ("id_switches", "ID sw."))
    suites = [(settings.get("suite", "standard"), data.rows)]
    if data.hard_rows:
        suites.append((settings.get("hard_suite", "hard"), data.hard_rows))
    suites.append((settings.get("real_suite", "real"), data.real_rows))
    head = ("## Real recorded traffic\n\n"
            f"{settings.get('real_runs')} runs per recording and variant (`{settings.get('real_suite')}`: NGSIM traffic "
            "on its CommonRoad lane maps, US-101 freeway and Lankershim Boulevard, replayed through the simulated "
            "sensors, smoothed truth, no simulated roadside objects; the seeds vary the sensor noise only). Side by side with the simulated suites, "
            "every run of a suite taken together (means weighted by frames, RMSEs over all matched pairs; seen: the "
            "vehicles the lidar sees, against the tracks not kept on hidden ones):\n\n"
            + side_by_side_table(suites, variants) + "\n"
            "A vehicle seen only from behind or ahead shows its width but not its length, and its centre, half a length "
            "from the seen end, inherits half the length prior's error. The seen pairs split by whether the vehicle's "
            "side has been seen whole so far, and, for the width (a vehicle seen only from the side), whether an end "
            "has (truth geometry decides, not the tracker):\n\n"
            + observability_table(suites, variants) + "\n")
    return head + _suite_section(data.real_rows, "Real recorded traffic, per recording", "Each recording's runs.", metrics,
                                 variants)


def _fmt_s(seconds: Any) -> str:
    if not isinstance(seconds, (int, float)) or not math.isfinite(seconds):
        return "-"
    return f"{seconds:.0f} s ({seconds / 60:.1f} min)"


def render_report(data: CompareData, claims: Sequence[ClaimResult], figures_dir: str = "report") -> str:
    """The Markdown text of REPORT.md."""
    meta, settings = data.meta, data.meta.get("settings", {})
    variants = meta.get("variants", [])
    skipped = meta.get("skipped", {})
    n_runs = len(data.rows)
    duration = settings.get("duration")
    duration_text = "each scenario's full duration" if duration is None else f"{duration:g} s per run"
    lines = [
        "# frenet-eot: the paper's claims, by Monte Carlo",
        "",
        "Every variant sees the same simulated data for the same scenario and seed, so differences are **paired** "
        "(variant A minus variant B per scenario and seed) with a 95 % Student t interval over the pairs (an interval pooled over several scenarios treats "
        "every (scenario, seed) pair as one sample). Tables give "
        "mean ± the 95 % interval's half-width over seeds. GOSPA: alpha 2, p 2, c 5 m on rectangle centres; its parts "
        "(localisation, missed, false) are p-th-power sums (m²). Generated by `eot compare`; do not edit by hand.",
        "",
        "## How this was made",
        "",
        f"- command: `{meta.get('command', 'eot compare')}`",
        f"- suite `{settings.get('suite')}`, {settings.get('runs')} runs (seeds {settings.get('seed0')}.."
        f"{int(settings.get('seed0', 0)) + int(settings.get('runs', 1)) - 1}) per scenario and variant, "
        f"{duration_text}; "
        f"{n_runs} runs; backend {settings.get('backend')}, {settings.get('workers')} worker(s)",
        f"- wall time: study {_fmt_s(meta.get('study_wall_s'))}, figure runs {_fmt_s(meta.get('figure_wall_s'))}"
        + (f", hard suite {_fmt_s(meta.get('hard_wall_s'))}" if meta.get("hard_wall_s") else "")
        + (f", real-traffic suite {_fmt_s(meta.get('real_wall_s'))}" if meta.get("real_wall_s") else "")
        + f"; total {_fmt_s(meta.get('total_wall_s'))}",
        f"- variants: {', '.join(variants)}",
        f"- {seed_provenance(int(settings.get('seed0', 0)), int(settings.get('runs', 1)))}",
    ]
    if meta.get("commit"):
        lines.append(f"- commit: `{meta['commit']}`")
    for v, reason in skipped.items():
        lines.append(f"- **skipped** `{v}`: {reason}")
    if meta.get("figure_runs_match") is False:
        lines.append("- **warning**: a figure run did not reproduce its runs.csv row (runs should be deterministic)")
    lines += ["", "## The claims", ""]
    for c in claims:
        lines += [f"### {c.number}. {c.title}", "", c.text, ""]
    lines += ["Every paired comparison is in `report/paired.csv`; per-scenario means and intervals in `report/summary.csv`; "
              "every run in `report/runs.csv`.", "", "## Figures", ""]
    captions = {
        "fused_vs_lidar.png": "GOSPA and cardinality over time, fused vs lidar-only, curvy-multi (the paper's simulation case).",
        "curvilinear_vs_cartesian.png": "GOSPA and yaw error over time, curvilinear vs Cartesian state, curve-single.",
        "chicane_follow.png": "The followed car on chicane-follow (the paper's Monza comparison): position error, yaw, "
                              "length and width against the truth (dashed), every variant.",
        "gospa_variants.png": "GOSPA of every variant, per scenario.",
        "runtime.png": "Tracker time per frame of every variant.",
    }
    for name in FIGURES:
        lines += [f"![{name}]({figures_dir}/{name})", "", captions[name], ""]
    lines += ["## Per-scenario results", "", "Columns: GOSPA mean and its parts, cardinality error |N_est - N_true|, RMSE of "
              "position, yaw, speed, length and width over GOSPA-assigned pairs, ID switches per run, mean tracker ms per "
              "frame. `n/a`: no value (point trackers estimate no extent).", "", scenario_tables(data.rows, variants),
              "## Wall time per run (to budget a study)", "",
              f"Mean wall seconds of one run (world, sensors, tracker, scoring) with {settings.get('workers')} worker(s) "
              "sharing the machine; a study of R runs per scenario and variant on W workers takes about "
              "R x (sum over variants of the suite column) / W.", "", wall_time_table(data.rows, variants), ""]
    for section in (_hard_section(data, variants), _real_section(data, variants)):
        if section:
            lines += [section]
    return "\n".join(lines).rstrip() + "\n"


#: The seeds on which the tracker's default configuration was chosen (standard and hard suites).
TUNING_SEEDS = range(0, 20)


def seed_provenance(seed0: int, runs: int) -> str:
    """One line saying whether the study's seeds ``seed0 .. seed0 + runs - 1`` include the seeds the
    tracker's defaults were tuned on (``TUNING_SEEDS``): numbers on tuning seeds are in-sample."""
    seeds = range(seed0, seed0 + runs)
    overlap = len(set(seeds) & set(TUNING_SEEDS))
    tuning = f"{TUNING_SEEDS.start}..{TUNING_SEEDS.stop - 1}"
    if overlap == 0:
        return f"held-out seeds: none of them is among the seeds {tuning} the tracker's defaults were tuned on"
    return (f"**in-sample**: {overlap} of the {runs} seeds are among the seeds {tuning} the tracker's defaults were "
            f"tuned on; use seeds from {TUNING_SEEDS.stop} or above (`--seed 1000`) for held-out numbers")


def write_report(data: CompareData, out: str | Path, figures_dir: str = "report") -> dict[str, Path]:
    """Write ``out/REPORT.md``, the figures and ``summary.csv`` / ``paired.csv`` into ``out/figures_dir``."""
    out = Path(out)
    fig_dir = out / figures_dir
    fig_dir.mkdir(parents=True, exist_ok=True)
    variants = data.meta.get("variants", [])
    claims = evaluate_claims(data.rows, variants, data.meta.get("skipped", {}), data.meta.get("curvature", {}))
    paths = {
        "fused_vs_lidar": plot_fused_vs_lidar(data, fig_dir / "fused_vs_lidar.png"),
        "curvilinear_vs_cartesian": plot_curvilinear_vs_cartesian(data, fig_dir / "curvilinear_vs_cartesian.png"),
        "chicane_follow": plot_chicane(data, fig_dir / "chicane_follow.png"),
        "gospa_variants": plot_gospa_variants(data, fig_dir / "gospa_variants.png"),
        "runtime": plot_runtime(data, fig_dir / "runtime.png"),
        "summary": write_summary_csv(data.rows, fig_dir / "summary.csv"),
        "paired": write_paired_csv(claims, fig_dir / "paired.csv"),
    }
    paths["report"] = out / "REPORT.md"
    paths["report"].write_text(render_report(data, claims, figures_dir), encoding="utf-8")
    return paths


__all__ = ["FIGURES", "TABLE_METRICS", "interval_table", "render_report", "scenario_tables", "wall_time_table",
           "write_report"]
