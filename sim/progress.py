"""Progress bars: thin adapters from the runner's and the Monte Carlo's ``progress(done, total)``
callbacks to tqdm (terminals, notebooks and logs; nested bars).

``ProgressBar(total, label)`` is a tqdm bar called as ``bar(done)`` or ``bar(done, total)`` (absolute
counts). ``total = 0`` means unknown until a call gives it: nothing is drawn before, so the bar always
shows ``done/total`` (one that never learns its total is drawn without it from its first call).
Callers announce the total with ``bar(0, total)`` before the work starts. On a terminal it redraws
at most every 0.1 s; elsewhere (logs, CI, pipes) at most every ``LOG_INTERVAL`` s, so logs stay
short, and always once when it closes. ``enabled=False`` silences it. ``position`` stacks bars (0 is the top
line); a bar with ``leave=False`` is erased when it closes: ``NestedProgress`` uses that for the
Monte Carlo (a bar over all runs and, below it on a terminal, one bar per scenario).
"""

from __future__ import annotations

import sys
from typing import TextIO

from tqdm.auto import tqdm

#: Seconds between redraws when the stream is not a terminal.
LOG_INTERVAL = 10.0
#: Seconds between redraws on a terminal.
TTY_INTERVAL = 0.1


def _is_tty(stream: TextIO) -> bool:
    return bool(getattr(stream, "isatty", lambda: False)())


class ProgressBar:
    """A tqdm bar of ``total`` steps (0: unknown yet) labelled ``label`` on ``stream`` (stderr)."""

    def __init__(
        self,
        total: int,
        label: str = "",
        *,
        stream: TextIO | None = None,
        enabled: bool = True,
        position: int | None = None,
        leave: bool = True,
        unit: str = "it",
    ) -> None:
        stream = sys.stderr if stream is None else stream
        self._options = dict(
            desc=label or None,
            file=stream,
            disable=not enabled,
            position=position,
            leave=leave,
            unit=unit,
            mininterval=TTY_INTERVAL if _is_tty(stream) else LOG_INTERVAL,
            dynamic_ncols=True,
        )
        self.bar: tqdm | None = None  # the tqdm bar, made once the total is known (or at the first call)
        self.done = 0  # steps done so far (counted also when the bar is disabled)
        self.total = max(int(total), 0)  # steps in all (0 while unknown)
        if self.total:
            self._open()

    def _open(self) -> None:
        self.bar = tqdm(total=self.total or None, initial=self.done, **self._options)

    def __call__(self, done: int, total: int | None = None) -> None:
        done = int(done)
        if total is not None and max(int(total), 0) != self.total:
            self.total = max(int(total), 0)
            if self.bar is not None:
                self.bar.total = self.total or None
                self.bar.refresh()
        if self.bar is None:
            self.done = done
            self._open()
            return
        step = done - self.done
        self.done = done
        if step:
            self.bar.update(step)

    def close(self) -> None:
        """Draw the final state (unless ``leave=False``) and release the line; nothing when the bar
        was never drawn (no total and no call)."""
        if self.bar is not None:
            self.bar.close()

    def __enter__(self) -> ProgressBar:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class NestedProgress:
    """A bar over all runs of a study with one bar per group (e.g. scenario) below it; ``done(group)``
    counts one finished run of ``group``. ``groups`` maps each group to its number of runs."""

    def __init__(self, groups: dict[str, int], label: str, *, stream: TextIO | None = None, enabled: bool = True) -> None:
        total = sum(groups.values())
        stream = sys.stderr if stream is None else stream
        self.outer = ProgressBar(total, label, stream=stream, enabled=enabled, position=0, unit="run")
        width = max((len(g) for g in groups), default=0)
        nested = enabled and len(groups) > 1 and _is_tty(stream)  # in a log, stacked bars are only noise
        self.inner = {
            g: ProgressBar(n, f"  {g:<{width}}", stream=stream, enabled=nested, position=i + 1, leave=False, unit="run")
            for i, (g, n) in enumerate(groups.items())
        }

    def done(self, group: str) -> None:
        """One more run of ``group`` finished."""
        bar = self.inner[group]
        bar(bar.done + 1)
        self.outer(self.outer.done + 1)

    def close(self) -> None:
        """Close the group bars, then the outer one."""
        for bar in reversed(list(self.inner.values())):
            bar.close()
        self.outer.close()

    def __enter__(self) -> NestedProgress:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


__all__ = ["LOG_INTERVAL", "NestedProgress", "ProgressBar", "TTY_INTERVAL"]
