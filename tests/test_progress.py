"""Progress bars (sim.progress) and their callers: a bar whose total comes with the first call draws
nothing before it (no "0it" line), then always ``done/total``; the runner and the figures announce
their totals with a first ``(0, total)`` and count every step up to it."""

from __future__ import annotations

import io
import re

from oracle_tracker import OracleFactory

from sim import load_scenario
from sim.evaluation.runner import run_scenario
from sim.progress import ProgressBar


def _lines(text: str) -> list[str]:
    return [line for line in re.split(r"[\r\n]+", text) if line.strip()]


def test_a_bar_without_a_total_draws_nothing_until_it_has_one():
    stream = io.StringIO()
    bar = ProgressBar(0, "frames", stream=stream)
    assert stream.getvalue() == ""  # no "frames: 0it [00:00, ?it/s]"
    bar(0, 21)
    for k in range(1, 22):
        bar(k, 21)
    bar.close()
    lines = _lines(stream.getvalue())
    assert lines and all("/21" in line for line in lines) and "it/s]" in lines[-1]
    # a count-less bar's "0it [" (a rate such as "425509.10it/s" ends in "0it" too: the digit before it)
    assert not re.search(r"(?<![0-9.])0it\b", stream.getvalue())
    assert "21/21" in lines[-1] and "100%" in lines[-1]
    assert bar.done == bar.total == 21


def test_a_bar_never_called_prints_nothing():
    stream = io.StringIO()
    with ProgressBar(0, "figures", stream=stream):
        pass
    assert stream.getvalue() == ""


def test_a_bar_that_never_learns_its_total_still_counts():
    stream = io.StringIO()
    with ProgressBar(0, "steps", stream=stream) as bar:
        bar(2)
        bar(5)
    assert bar.done == 5 and bar.total == 0 and "5it" in stream.getvalue()


def test_the_runner_announces_its_total_then_counts_every_frame():
    spec = load_scenario("curve-single")
    ticks: list[tuple[int, int]] = []
    result = run_scenario(spec, 0, duration=0.5, tracker_factory=OracleFactory(spec, 0),
                          progress=lambda d, n: ticks.append((d, n)))
    total = len(result.frames)
    assert ticks == [(k, total) for k in range(total + 1)]
    stream = io.StringIO()
    with ProgressBar(0, "curve-single", stream=stream) as bar:
        run_scenario(spec, 0, duration=0.5, tracker_factory=OracleFactory(spec, 0), progress=bar)
    assert bar.done == bar.total == total
    assert all(f"/{total}" in line for line in _lines(stream.getvalue()))
