"""What a benchmark ran on: the machine, the software, the commit; peak memory; pinning to one core."""

from __future__ import annotations

import os
import platform
import resource
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from importlib import metadata
from pathlib import Path
from typing import Any

#: The repository (or installed tree) holding ``sim/``.
ROOT = Path(__file__).resolve().parents[2]
#: Thread-count variables of the numeric libraries, recorded when set.
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def cpu_model() -> str:
    """The CPU's model name (``/proc/cpuinfo``; else ``platform.processor()``; else the architecture)."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as fh:
            for line in fh:
                key, _, value = line.partition(":")
                if key.strip() in ("model name", "Hardware", "cpu model") and value.strip():
                    return value.strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown"


def usable_cpus() -> int:
    """CPUs this process may run on (its affinity; ``os.cpu_count()`` where there is none)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover (not Linux)
        return max(1, os.cpu_count() or 1)


def _version(dist: str) -> str | None:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return None


def _git(*argv: str) -> str | None:
    try:
        done = subprocess.run(["git", *argv], cwd=ROOT, capture_output=True, text=True, timeout=10, check=False)
    except (OSError, subprocess.SubprocessError):
        return None
    return done.stdout.strip() if done.returncode == 0 else None


def git_state() -> dict[str, Any] | None:
    """``commit`` (HEAD) and ``modified`` (tracked files changed against it, at most 20) of the
    checkout; ``None`` outside a git checkout or without git."""
    commit = _git("rev-parse", "HEAD")
    if commit is None:
        return None
    changed = _git("diff", "--name-only", "HEAD")
    files = changed.splitlines() if changed else []
    return {"commit": commit, "modified": files[:20], "modified_count": len(files)}


def machine() -> dict[str, Any]:
    """Cores, CPU model, OS, Python and library versions, thread settings, load and the git state."""
    try:
        load = [round(x, 2) for x in os.getloadavg()]
    except (AttributeError, OSError):  # pragma: no cover (not Unix)
        load = None
    return {
        "cores": os.cpu_count() or 1,
        "cores_usable": usable_cpus(),
        "cpu_model": cpu_model(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "numpy": _version("numpy"),
        "scipy": _version("scipy"),
        "stonesoup": _version("stonesoup"),
        "numba": _version("numba"),
        "threads_env": {k: os.environ[k] for k in THREAD_VARIABLES if k in os.environ},
        "load_average_at_start": load,
        "git": git_state(),
    }


def peak_memory_mb() -> dict[str, float]:
    """Peak resident memory (MB) of this process and of its finished child processes (``getrusage``)."""
    scale = 1.0 / (1024 * 1024) if sys.platform == "darwin" else 1.0 / 1024  # bytes on macOS, KiB on Linux
    return {
        "self_peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * scale, 1),
        "children_peak_rss_mb": round(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * scale, 1),
    }


@contextmanager
def one_core(enabled: bool = True) -> Iterator[int | None]:
    """Pin this process to its lowest usable CPU for the block (yields that CPU; ``None`` when not
    pinned: disabled, or no ``os.sched_setaffinity``); the affinity is restored afterwards."""
    if not enabled or not hasattr(os, "sched_setaffinity"):
        yield None
        return
    before = os.sched_getaffinity(0)
    cpu = min(before)
    os.sched_setaffinity(0, {cpu})
    try:
        yield cpu
    finally:
        os.sched_setaffinity(0, before)
