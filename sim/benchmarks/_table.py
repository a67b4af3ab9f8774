"""The readable table ``eot bench`` prints from its result (``sim.benchmarks._suite``)."""

from __future__ import annotations

from typing import Any


def _num(value: Any, digits: int = 2) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def _header(r: dict[str, Any]) -> list[str]:
    m = r["machine"]
    git = m.get("git") or {}
    commit = git.get("commit", "no git")[:10]
    if git.get("modified_count"):
        commit += f" (+{git['modified_count']} modified files)"
    pinned = f"pinned to CPU {r['pinned_cpu']}" if r.get("pinned_cpu") is not None else "not pinned"
    return [
        f"eot bench{' --quick (sizes shrunk: not benchmark numbers)' if r['quick'] else ''}: {r['started_utc']}, "
        f"commit {commit}",
        f"machine: {m['cores_usable']} of {m['cores']} cores, {m['cpu_model']}; Python {m['python']}, numpy {m['numpy']}, "
        f"scipy {m['scipy']}, numba {m.get('numba') or 'not installed'}; load {m['load_average_at_start']}; "
        f"{pinned} (all but the Monte Carlo)",
        f"compiled kernels: compile/load before timing {_num((r.get('kernels') or {}).get('warm_up_s'))} s",
    ]


def _tracker(t: dict[str, Any]) -> list[str]:
    variants = list(t["results"])
    counts = list(t["results"][variants[0]]) if variants else []
    rounds = f", fastest of {t['repeat']} rounds" if t.get("repeat", 1) > 1 else ""
    lines = [f"tracker ms per frame, median / p95 ({t['frames']} frames per count{rounds}):",
             f"  {'targets':>7} {'lanes':>5} {'in view':>7} " + " ".join(f"{v:>24}" for v in variants)]
    for c in counts:
        first = t["results"][variants[0]][c]
        cells = " ".join(f"{_num(t['results'][v][c]['ms_median']):>11} / {_num(t['results'][v][c]['ms_p95']):>10}"
                         for v in variants)
        lines.append(f"  {c:>7} {first['lanes']:>5} {first['in_view_mean']:>7.1f} {cells}")
    for v in variants[:1]:  # where the frame goes (Tracker.stage_seconds), at the count nearest 10 targets
        rows = {c: row for c, row in t["results"][v].items() if row.get("stage_ms")}
        if rows:
            c = min(rows, key=lambda k: abs(int(k) - 10))
            stages = ", ".join(f"{name} {ms:.3f}" for name, ms in rows[c]["stage_ms"].items())
            lines.append(f"  where a frame goes ({v}, {c} targets, mean {_num(rows[c]['ms_mean'], 3)} ms): {stages}")
    return lines


def _stonesoup(s: dict[str, Any]) -> list[str]:
    if "skipped" in s:
        return [f"Stone Soup comparison skipped: {s['skipped']}"]
    ss = s["stonesoup"]
    ratios = ", ".join(f"{v} {x}x" for v, x in s["ratio_stonesoup_over_ours"].items())
    return [f"Stone Soup {ss['version']} GM-PHD (UKF, {s['targets']} point targets, {s['frames']} frames): "
            f"{_num(ss['ms_median'])} ms/frame median; Stone Soup / ours: {ratios}"]


def _world(w: dict[str, Any]) -> list[str]:
    return ["world ms per simulated s: " + ", ".join(
        f"{k} {_num(v['ms_per_simulated_s'])} ({_num(v['real_time_factor'], 1)}x real time)" for k, v in w.items())]


def _e2e(e: dict[str, Any]) -> list[str]:
    return ["end to end, one core, simulated s per wall s (median of repeats; best; first run): " + ", ".join(
        f"{k} {_num(v['sim_s_per_wall_s'])} (tracker {100 * v['tracker_share']:.0f} %; best {_num(v['best_sim_s_per_wall_s'])}; "
        f"first {_num(v['first_sim_s_per_wall_s'])})" for k, v in e.items())]


def _mc(mc: dict[str, Any]) -> list[str]:
    rows = ", ".join(f"{w} worker(s) {_num(x['runs_per_min'], 1)} runs/min = {_num(x['sim_s_per_wall_s'])} sim s/wall s"
                     for w, x in mc["workers"].items())
    return [f"Monte Carlo {mc['scenario']}: {rows}"]


def _env(e: dict[str, Any]) -> list[str]:
    tr, truth = e["tracks"], e["truth"]
    return [f"env ({e['vehicles']} vehicles) steps per s: tracks {_num(tr['steps_per_s'], 1)} "
            f"({_num(tr['real_time_factor'], 1)}x real time, tracker {100 * tr['tracker_share']:.0f} %; "
            f"best {_num(tr['best_steps_per_s'], 1)} = {_num(tr['best_real_time_factor'], 1)}x), "
            f"truth {_num(truth['steps_per_s'], 1)}"]


def format_table(r: dict[str, Any]) -> str:
    """The result as lines of text, one block per section that ran."""
    lines = _header(r)
    if "tracker" in r:
        lines += _tracker(r["tracker"])
    if "stonesoup" in r:
        lines += _stonesoup(r["stonesoup"])
    if "lidar" in r:
        x = r["lidar"]
        lines.append(f"lidar scan {_num(x['scan_ms'])} ms ({x['rays']} rays; {x['scene']}), radar cycle {_num(x['radar_cycle_ms'])} ms")
    if "lidar3d" in r:
        for name, x in r["lidar3d"].items():
            g, st = x["ground_removal"], x["tracker_step"]
            lines.append(f"{name} scan {_num(x['scan']['median_ms'])} ms median ({x['scene']['rays']} rays, "
                         f"{x['scene']['points']} points, grade {x['scene']['grade']}, bank {x['scene']['bank']}); "
                         f"tracker: 3-D preprocessing {_num(x['preprocess']['median_ms'])} ms, whole step "
                         f"{_num(st['median_ms'])} ms median, p95 {_num(st['p95_ms'])} ms; ground removal recall "
                         f"{g['recall']:.4f}, precision {g['precision']:.4f}, vehicle points kept {g['vehicle_points_kept']:.4f}")
            pw = x.get("patchworkpp", {})
            if "median_ms" in pw:
                lines.append(f"  Patchwork++ on that cloud {_num(pw['median_ms'])} ms median; recall {pw['recall']:.4f}, "
                             f"precision {pw['precision']:.4f}, vehicle points kept {pw['vehicle_points_kept']:.4f}")
    if "world" in r:
        lines += _world(r["world"])
    if "end_to_end" in r:
        lines += _e2e(r["end_to_end"])
    if "montecarlo" in r:
        lines += _mc(r["montecarlo"])
    if "env" in r:
        lines += _env(r["env"])
    mem = r["memory"]
    lines.append(f"peak memory: {_num(mem['self_peak_rss_mb'], 0)} MB this process, "
                 f"{_num(mem['children_peak_rss_mb'], 0)} MB largest worker; total wall {_num(r['wall_s'], 1)} s")
    return "\n".join(lines)
