"""A small text progress bar on stderr (no dependency).

``ProgressBar(total, label)`` is called as ``bar(done)`` or ``bar(done, total)`` (the runner's and
the Monte Carlo's ``progress`` callback signature) and redraws at most every ``min_interval``
seconds. On a terminal it redraws one line in place (carriage return); elsewhere (logs, CI, pipes)
it prints a plain line only at the first step and every 10 % so logs stay short. ``enabled=False``
silences it.
"""

from __future__ import annotations

import sys
import time
from typing import TextIO


class ProgressBar:
    """Progress of ``total`` steps labelled ``label``, written to ``stream`` (stderr)."""

    def __init__(
        self,
        total: int,
        label: str = "",
        *,
        stream: TextIO | None = None,
        enabled: bool = True,
        width: int = 30,
        min_interval: float = 0.1,
    ) -> None:
        self.total = max(int(total), 0)
        self.label = label
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = enabled
        self.width = width
        self.min_interval = min_interval
        self.done = 0
        self._start = time.perf_counter()
        self._last_draw = -1e9
        self._last_decile = -1
        self._tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self._closed = False
        self._drawn = False

    def __call__(self, done: int, total: int | None = None) -> None:
        if total is not None:
            self.total = max(int(total), 0)
        self.done = int(done)
        if not self.enabled:
            return
        now = time.perf_counter()
        finished = self.total and self.done >= self.total
        if self._tty:
            if finished or now - self._last_draw >= self.min_interval:
                self._draw(now, end="\n" if finished else "")
        else:
            decile = int(10 * self.done / self.total) if self.total else 0
            if decile != self._last_decile or finished:
                self._last_decile = decile
                self._draw(now, end="\n")
        if finished:
            self._closed = True

    def _text(self, now: float) -> str:
        elapsed = now - self._start
        frac = min(self.done / self.total, 1.0) if self.total else 0.0
        filled = int(round(self.width * frac))
        bar = "#" * filled + "-" * (self.width - filled)
        eta = ""
        if 0 < self.done < self.total:
            eta = f" eta {elapsed * (self.total - self.done) / self.done:5.1f} s"
        label = f"{self.label} " if self.label else ""
        return f"{label}[{bar}] {self.done}/{self.total} {elapsed:6.1f} s{eta}"

    def _draw(self, now: float, end: str) -> None:
        self._last_draw = now
        self._drawn = True
        prefix = "\r" if self._tty else ""
        self.stream.write(prefix + self._text(now) + end)
        self.stream.flush()

    def close(self) -> None:
        """End the line on a terminal if the bar did not reach its total."""
        if self.enabled and self._tty and self._drawn and not self._closed:
            self.stream.write("\n")
            self.stream.flush()
        self._closed = True

    def __enter__(self) -> ProgressBar:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


__all__ = ["ProgressBar"]
