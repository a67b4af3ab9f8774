"""Diagnostics of a run (``sim.evaluation.inspect``, ``eot inspect``): oracle runs with hand-made losses, label
changes, coasting and merges give exactly those events with the documented causes; a hand-written
run folder checks the merge heuristic and the GOSPA attribution (duplicate, clutter, missed); the
CLI writes its files and fails with one line on a bad folder."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from oracle_tracker import OracleTracker

from sim import cli, load_scenario
from sim.evaluation.inspect import (
    FAILED_GATE,
    GOSPA_CAUSES,
    MERGED,
    NEWBORN,
    OCCLUDED_UNTRACKED,
    TRACKED,
    VISIBLE_UNTRACKED,
    InspectError,
    analyse,
    inspect_run,
    load_run,
    summary_text,
    vehicle_costs,
    write_inspection,
)
from sim.evaluation.metrics import gospa
from sim.evaluation.results import TIMESERIES_COLUMNS, TRACK_COLUMNS, TRUTH_COLUMNS, write_results
from sim.evaluation.runner import run_scenario

DROP = (1.0, 2.0)  # vehicle DROPPED's track is not reported in [1.0, 2.0) s
RELABEL_T = 2.0  # vehicle RELABELLED gets label 100 + id from 2.0 s on


class PerturbedOracle(OracleTracker):
    """The oracle with known faults: ``drop`` (vehicle id, t0, t1) not reported in [t0, t1);
    ``relabel_at`` (vehicle id, t) new label ``100 + id`` from t; with ``events=True`` it also exposes
    ``last_events`` ("missed" for the dropped label and ``coast`` (vehicle id, t0, t1) reported but
    missed; ``merge`` (vehicle id, kept vehicle id, t): not reported from t, merged at t)."""

    def __init__(self, spec, seed, road, *, drop=None, relabel_at=None, coast=None, merge=None, events=False):  # noqa: ANN001
        super().__init__(spec, seed, road)
        self.drop, self.relabel_at, self.coast, self.merge, self.events = drop, relabel_at, coast, merge, events
        self._labels_before: set[int] = set()
        if events:
            self.last_events = None

    def _label(self, vid: int, t: float) -> int:
        if self.relabel_at and vid == self.relabel_at[0] and t >= self.relabel_at[1] - 1e-9:
            return 100 + vid
        return vid

    def step(self, frame):  # noqa: ANN001, ANN201
        self.relabel = self._label
        tracks = super().step(frame)
        t = frame.t
        gone = set()
        if self.drop and self.drop[1] - 1e-9 <= t < self.drop[2] - 1e-9:
            gone.add(self.drop[0])
        if self.merge and t >= self.merge[2] - 1e-9:
            gone.add(self.merge[0])
        tracks = [tr for tr in tracks if tr.label not in gone]
        if self.events:
            labels = {tr.label for tr in tracks}
            missed = sorted(gone & self._labels_before)
            if self.coast and self.coast[1] - 1e-9 <= t < self.coast[2] - 1e-9:
                missed.append(self.coast[0])
            merged = [(self.merge[0], self.merge[1])] if self.merge and abs(t - self.merge[2]) < 1e-9 else []
            self.last_events = {"born": sorted(labels - self._labels_before), "updated": sorted(labels - set(missed)),
                                "missed": missed, "dropped": [], "merged": merged}
            self._labels_before = labels | (gone & self._labels_before)
        return tracks


def _run(duration=4.0, **kwargs):
    spec = load_scenario("curvy-multi")
    return run_scenario(spec, 0, duration=duration,
                        tracker_factory=lambda road, config: PerturbedOracle(spec, 0, road, **kwargs))


def _events(folder):
    with open(folder / "events.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def _pick(result):
    """Two vehicles scored and visible over 0.5-3 s with no other vehicle within 8 m (so nothing can
    look like a merge), for the drop and the relabel."""
    ok = []
    for vid in result.frames[0].truth.ids.tolist():
        good = True
        for f in result.frames:
            if not 0.5 <= f.t <= 3.0:
                continue
            i = int(np.flatnonzero(f.truth.ids == vid)[0])
            others = np.delete(f.truth.xy, i, axis=0)
            near = np.min(np.linalg.norm(others - f.truth.xy[i], axis=1)) if len(others) else np.inf
            good &= bool(f.scored[i] and f.visible[i] and near > 8.0)
        if good:
            ok.append(int(vid))
    assert len(ok) >= 2, "curvy-multi should have two separated visible vehicles over 0.5-3 s"
    return ok[0], ok[1]


@pytest.fixture(scope="module")
def picks():
    return _pick(_run(duration=3.0))


def test_known_loss_and_label_change(picks, tmp_path):
    dropped, relabelled = picks
    result = _run(drop=(dropped, *DROP), relabel_at=(relabelled, RELABEL_T))
    write_results(result, tmp_path)
    insp = inspect_run(tmp_path)
    paths = write_inspection(insp, tmp_path)
    assert all(p.exists() for p in paths.values())
    rows = _events(tmp_path)
    interesting = [(float(r["t"]), int(r["truth_id"]), int(r["label"]), r["event"], r["cause"]) for r in rows
                   if r["event"] in ("lost", "label_change", "reacquired", "coasting")]
    assert interesting == [
        (pytest.approx(1.0), dropped, dropped, "lost", FAILED_GATE),
        (pytest.approx(2.0), dropped, dropped, "reacquired", ""),
        (pytest.approx(2.0), relabelled, 100 + relabelled, "label_change", NEWBORN),
    ]
    # the label change is the run's one ID switch; the timeline shows the gap as visible-untracked
    assert result.metrics["id_switches"] == 1
    v = int(np.searchsorted(insp.data.vehicle_ids, dropped))
    t = insp.data.t
    gap = (t >= 1.0 - 1e-9) & (t < 2.0 - 1e-9)
    assert np.all(insp.states[gap, v] == VISIBLE_UNTRACKED) and np.all(insp.states[~gap & (t > 0.05), v] == TRACKED)
    # every vehicle in range at the start is confirmed in the first frame (the oracle needs no birth)
    confirmed = {int(r["truth_id"]): float(r["t"]) for r in rows if r["event"] == "confirmed"}
    assert confirmed[dropped] == 0.0 and confirmed[relabelled] == 0.0
    # worst interval: exactly the dropped second, all of it "missed while visible" (one car: c^2/2 each frame)
    worst = insp.intervals[0]
    assert (worst.t_start, worst.t_end) == (pytest.approx(1.0), pytest.approx(1.9))
    assert worst.dominant == "missed while visible" and worst.shares[GOSPA_CAUSES.index("missed while visible")] == 1.0
    assert worst.cost == pytest.approx(10 * 12.5 * 0.1)
    assert f"vehicle {dropped} lost ({FAILED_GATE})" in worst.events
    text = summary_text(insp)
    assert f"1.0 s lost label {dropped} (failed gate)" in text and f"label {relabelled} -> {100 + relabelled} (replaced by newborn)" in text


def test_tracker_events_give_coasting_and_merge(picks, tmp_path):
    a, b = picks
    result = _run(coast=(a, 0.5, 1.0), merge=(b, a, 2.5), events=True)
    assert result.frames[3].tracker_events is not None
    paths = write_results(result, tmp_path)
    with open(paths["tracker_events"], newline="") as fh:
        ev = list(csv.DictReader(fh))
    assert {"t": "2.5", "label": str(b), "event": "merged", "other_label": str(a)} in ev
    assert sum(r["event"] == "missed" and r["label"] == str(a) for r in ev) == 5
    insp = inspect_run(tmp_path)
    write_inspection(insp, tmp_path)
    rows = [r for r in _events(tmp_path) if r["event"] in ("lost", "coasting")]
    assert [(float(r["t"]), int(r["truth_id"]), r["event"], r["cause"]) for r in rows] == [
        (pytest.approx(0.5), a, "coasting", FAILED_GATE),
        (pytest.approx(2.5), b, "lost", MERGED),
    ]
    assert f"merged label {b} into label {a}" in rows[1]["detail"]


def _folder(tmp_path, truth, tracks, *, frames=11, dt=0.1, visible=None, size=None):
    """A run folder by hand: ``truth[vid] = (x, y)`` fixed, heading along x; ``tracks`` = (label, t0, t1, x,
    y) shown in [t0, t1]; assignment and GOSPA by ``sim.evaluation.metrics.gospa``; ``visible[vid]`` (bool)
    default True; ``size[vid] = (length, width)`` (m) default (4.5, 2.0)."""
    visible = visible or {}
    size = size or {}
    ts, tk, tr = [], [], []
    ids = sorted(truth)
    for k in range(frames):
        t = round(k * dt, 10)
        txy = np.array([truth[v] for v in ids], dtype=float)
        shown = [(lb, x, y) for lb, t0, t1, x, y in tracks if t0 - 1e-9 <= t <= t1 + 1e-9]
        exy = np.array([(x, y) for _, x, y in shown], dtype=float).reshape(-1, 2)
        g = gospa(txy, exy)
        assigned = np.full(len(shown), -1)
        assigned[g.estimate_index] = np.array(ids)[g.truth_index]
        ts.append([t, len(ids), len(ids), len(shown), g.gospa, g.localization, g.missed, g.false, g.gospa,
                   g.localization, g.missed, g.false, 1.0, 0.0, 0.0, 0.0, 0.0])
        for (lb, x, y), a in zip(shown, assigned):
            tk.append([t, lb, 1.0, x, y, 20.0, 0.0, 0.0, 4.5, 2.0, x, x, y, 0.0, 0.0, int(a), 0])
        for v in ids:
            vis = visible.get(v, True)
            tr.append([t, v, *truth[v], 0.0, 20.0, 0.0, *size.get(v, (4.5, 2.0)), truth[v][0], truth[v][1], 0.0, 1, int(vis),
                       20 if vis else 0])
    for name, header, rows in (("timeseries.csv", TIMESERIES_COLUMNS, ts), ("tracks.csv", TRACK_COLUMNS, tk),
                               ("truth.csv", TRUTH_COLUMNS, tr)):
        with open(tmp_path / name, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(header)
            w.writerows(rows)
    (tmp_path / "metrics.json").write_text(json.dumps({"scenario": "hand", "variant": "x", "seed": 0, "gospa_c_m": 5.0,
                                                       "gospa_p": 2.0, "id_switches": 0}))
    return tmp_path


def test_merge_heuristic_and_gospa_causes(tmp_path):
    # vehicles 1 and 2 side by side (3.5 m apart); label 10 on 1 vanishes at 0.5 s next to label 11 on 2
    folder = _folder(tmp_path, {1: (50.0, 0.0), 2: (50.0, 3.5)},
                     [(10, 0.0, 0.4, 50.2, 0.0), (11, 0.0, 1.0, 50.0, 3.3), (12, 0.2, 0.3, 51.0, 3.5),
                      (13, 0.8, 0.8, 120.0, 40.0)])
    insp = inspect_run(folder, threshold=0.5)
    lost = [e for e in insp.events if e.event == "lost"]
    assert [(e.t, e.truth_id, e.label, e.cause) for e in lost] == [(pytest.approx(0.5), 1, 10, MERGED)]
    assert "label 11 of vehicle 2" in lost[0].detail
    # attribution: duplicate (label 12 is 1 m from vehicle 2, which has label 11), clutter (13), missed
    c = {name: insp.cause_cost[:, i] for i, name in enumerate(GOSPA_CAUSES)}
    np.testing.assert_allclose(insp.cause_cost.sum(axis=1), insp.data.gospa**2, atol=1e-9)
    assert np.flatnonzero(c["duplicate"]).tolist() == [2, 3] and c["duplicate"][2] == 12.5
    assert np.flatnonzero(c["clutter"]).tolist() == [8]
    assert np.flatnonzero(c["missed while visible"]).tolist() == [5, 6, 7, 8, 9, 10]
    # frames 2-3 (duplicate) and 5-10 (missed) join across the one good frame 4
    worst = insp.intervals[0]
    assert (worst.t_start, worst.t_end) == (pytest.approx(0.2), pytest.approx(1.0))
    assert worst.dominant == "missed while visible" and worst.cost == pytest.approx(0.1 * float(np.sum(insp.data.gospa[2:11] ** 2)))
    assert "duplicate 22 % (label 12 on vehicle 2 0.2 s)" in worst.detail


def test_vehicle_costs_split_the_run_cost_by_vehicle(tmp_path):
    """The merge scene of the test above: vehicle 1 is tracked 0.2 m off for 5 frames (0.04 m^2 each) and
    missed for 6 (12.5 m^2 each); vehicle 2 tracked 0.2 m off for 11 frames and duplicated for 2 (12.5 m^2
    each); the clutter track (1 frame) is no vehicle's. Costs are m^2 s (frames of 0.1 s)."""
    folder = _folder(tmp_path, {1: (50.0, 0.0), 2: (50.0, 3.5)},
                     [(10, 0.0, 0.4, 50.2, 0.0), (11, 0.0, 1.0, 50.0, 3.3), (12, 0.2, 0.3, 51.0, 3.5),
                      (13, 0.8, 0.8, 120.0, 40.0)])
    insp = inspect_run(folder, threshold=0.5)
    costs = vehicle_costs(insp)
    assert [vid for vid, _, _ in costs] == [1, 2]
    (_, c1, by1), (_, c2, by2) = costs
    loc, missed, dup = (GOSPA_CAUSES.index(n) for n in ("localisation", "missed while visible", "duplicate"))
    assert by1[loc] == pytest.approx(0.1 * 5 * 0.04) and by1[missed] == pytest.approx(0.1 * 6 * 12.5)
    assert by2[loc] == pytest.approx(0.1 * 11 * 0.04) and by2[dup] == pytest.approx(0.1 * 2 * 12.5)
    assert c1 == pytest.approx(by1.sum()) and c2 == pytest.approx(by2.sum())
    total = 0.1 * float(np.sum(insp.data.gospa**2))
    assert c1 + c2 + 0.1 * 12.5 == pytest.approx(total)  # and the clutter track's frame
    text = summary_text(insp)
    assert "missed while occluded, 0 % of it, left out" in text
    assert f"vehicle   1: {100 * c1 / total:.0f} % (missed while visible 100 %)" in text
    assert f"vehicle   2: {100 * c2 / total:.0f} % (duplicate 98 %, localisation 2 %)" in text


def test_a_track_on_a_long_trucks_body_is_charged_to_the_truck(tmp_path):
    """A 19.8 m semi-trailer at x = 50 (body 40.1 .. 59.9 m) tracked with a car's rectangle on its rear:
    the track's centre, at x = 42.5, is 7.5 m from the truck's centre (beyond the cut-off c = 5, so
    unassigned) but inside its body, so it is the truck's *displaced track* and the truck's missed part
    goes there too; 3.4 m behind the rear (x = 36.7) it is still on the truck, 3.6 m (x = 36.5) it is
    clutter and the truck is *missed while visible*. The car beside, 4.5 m long, is tracked exactly."""
    size = {1: (19.8, 2.6)}
    for x, cause in ((42.5, "displaced track"), (36.7, "displaced track"), (36.5, "clutter")):
        folder = tmp_path / f"x{x}"
        folder.mkdir()
        _folder(folder, {1: (50.0, 0.0), 2: (50.0, 3.5)}, [(10, 0.0, 1.0, x, 0.0), (11, 0.0, 1.0, 50.0, 3.5)],
                size=size)
        insp = inspect_run(folder, threshold=0.5)
        c = {name: insp.cause_cost[:, i].sum() for i, name in enumerate(GOSPA_CAUSES)}
        missed = "missed while visible"
        assert c[cause] == pytest.approx(11 * (25.0 if cause == "displaced track" else 12.5)), x
        assert c[missed] == pytest.approx(0.0 if cause == "displaced track" else 11 * 12.5), x
        assert c["localisation"] == 0.0
        (truck,) = [total for vid, total, _ in vehicle_costs(insp) if vid == 1]  # m^2 s, frames of 0.1 s
        assert truck == pytest.approx(1.1 * (25.0 if cause == "displaced track" else 12.5)), x


def test_occluded_loss_and_never_tracked(tmp_path):
    # vehicle 1 hidden from 0.5 s on, its track vanishes then; vehicle 3 in range, visible, never tracked
    folder = _folder(tmp_path, {1: (50.0, 0.0), 3: (80.0, 0.0)}, [(10, 0.0, 0.4, 50.2, 0.0)])
    rows = []
    with open(folder / "truth.csv", newline="") as fh:
        reader = csv.reader(fh)
        header = next(reader)
        for r in reader:
            if r[1] == "1" and float(r[0]) >= 0.5 - 1e-9:
                r[header.index("visible")], r[header.index("lidar_points")] = "0", "0"
            rows.append(r)
    with open(folder / "truth.csv", "w", newline="") as fh:
        csv.writer(fh).writerows([header, *rows])
    insp = inspect_run(folder)
    by = {(e.truth_id, e.event): e for e in insp.events}
    assert by[(1, "lost")].cause == "occluded" and by[(1, "lost")].t == pytest.approx(0.5)
    assert by[(3, "never_tracked")].cause == FAILED_GATE
    assert np.all(insp.states[5:, 0] == OCCLUDED_UNTRACKED)
    miss = insp.cause_cost[:, GOSPA_CAUSES.index("missed while occluded")]
    assert np.flatnonzero(miss).tolist() == list(range(5, 11))


def test_bad_folders_are_clear_errors(tmp_path):
    with pytest.raises(InspectError, match="no such folder"):
        load_run(tmp_path / "nope")
    with pytest.raises(InspectError, match="has no timeseries.csv"):
        load_run(tmp_path)
    folder = _folder(tmp_path, {1: (50.0, 0.0)}, [(10, 0.0, 1.0, 50.0, 0.0)])
    text = (folder / "tracks.csv").read_text().replace("truth_id", "truth")
    (folder / "tracks.csv").write_text(text)
    with pytest.raises(InspectError, match=r"tracks.csv lacks the column\(s\) truth_id"):
        load_run(folder)
    other = tmp_path / "other"
    other.mkdir()
    with pytest.raises(InspectError, match="threshold"):
        analyse(load_run(_folder(other, {1: (50.0, 0.0)}, [])), threshold=float("nan"))


def test_eot_inspect_cli(tmp_path, capsys, picks):
    result = _run(duration=2.5, drop=(picks[0], *DROP))
    write_results(result, tmp_path)
    code = cli.main(["inspect", str(tmp_path), "--top", "2"])
    out = capsys.readouterr().out
    assert code == 0
    assert f"vehicle {picks[0]:>3}:" in out and "worst GOSPA intervals" in out and "#1 1.0-1.9 s" in out
    for name in ("events.csv", "worst_intervals.csv", "events.png"):
        assert (tmp_path / name).exists(), name
    assert (tmp_path / "events.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with open(tmp_path / "worst_intervals.csv", newline="") as fh:
        worst = list(csv.DictReader(fh))
    assert 1 <= len(worst) <= 2 and worst[0]["dominant_cause"] == "missed while visible"


def test_eot_inspect_bad_folder_is_one_line(tmp_path, capsys):
    code = cli.main(["inspect", str(tmp_path / "missing")])
    captured = capsys.readouterr()
    assert code == 2 and captured.out == ""
    assert captured.err.count("\n") == 1 and "no such folder" in captured.err and "eot inspect" in captured.err
    code = cli.main(["inspect", str(tmp_path)])
    captured = capsys.readouterr()
    assert code == 2 and captured.err.count("\n") == 1 and "has no timeseries.csv" in captured.err


def test_events_figure_legends_outside_and_title_matches_the_shading(tmp_path, picks):
    from matplotlib.patches import Polygon, Rectangle

    from sim.evaluation.inspect import events_figure
    from sim.evaluation.plots import vehicle_color

    result = _run(duration=2.5, drop=(picks[0], *DROP))
    write_results(result, tmp_path)
    for threshold, shaded in ((None, True), (1e6, False)):  # the drop makes worst intervals; none above 1e6 m
        insp = inspect_run(tmp_path, threshold=threshold)
        assert bool(insp.intervals) == shaded
        fig = events_figure(insp)
        fig.canvas.draw()
        timeline, ax_g, ax_c = fig.axes
        spans = [p for p in ax_g.patches if isinstance(p, (Polygon, Rectangle))]
        assert len(spans) == len(insp.intervals)
        assert ("shaded" in ax_g.get_title()) == shaded and ("no worst interval" in ax_g.get_title()) == (not shaded)
        renderer = fig.canvas.get_renderer()
        for ax in (ax_g, ax_c):  # each legend lies beside its panel, over none of the data
            legend = ax.get_legend().get_window_extent(renderer)
            assert legend.x0 >= ax.get_window_extent(renderer).x1
            assert all(ax.get_ylabel() for ax in fig.axes) and "(s)" in ax_c.get_xlabel()
        # the vehicles are named in their colours (the run's other figures use the same)
        for tick in timeline.get_yticklabels():
            assert tick.get_color() == vehicle_color(int(tick.get_text().split()[-1]))
        lo, hi = timeline.get_xlim()
        assert lo < insp.data.t[0] and hi > insp.data.t[-1]  # markers at the first frame are not cut
