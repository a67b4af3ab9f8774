"""Optional compiled kernels (numba) for the tracker's per-frame fixed costs.

At the tracker's sizes (a few to a few dozen clusters and components per frame) numpy's cost is the
number of calls, not the arithmetic: preparing one cluster takes as long as preparing ten. The kernels
here do the same work as their numpy references in one compiled call each. They are an optional extra
(``pip install -e ".[fast]"``); without numba, or with the environment variable ``EOT_NUMBA=0``, the
tracker runs the numpy code, which stays the reference: ``tests/test_compiled.py`` checks every kernel
against it (the same discrete decisions, the numbers within 1e-9; sums run in another order).

``enabled()`` says whether the kernels are used; ``require()`` raises a clear error when they are asked
for and numba is missing. The kernels compile on first use and are cached next to this package
(``cache=True``), so a fresh checkout compiles once (a few seconds) and later processes load them.
"""

from __future__ import annotations

import os

try:  # pragma: no cover - exercised by whichever environment runs the tests
    import numba as _numba
except ImportError:  # pragma: no cover
    _numba = None

ENV_SWITCH = "EOT_NUMBA"


def available() -> bool:
    """Whether numba is installed."""
    return _numba is not None


def enabled() -> bool:
    """Whether the tracker uses the compiled kernels: numba installed and ``EOT_NUMBA`` not ``0``."""
    return _numba is not None and os.environ.get(ENV_SWITCH, "1").strip() not in ("0", "false", "no", "off")


def require() -> None:
    """Raise a clear error when numba is not installed."""
    if _numba is None:
        raise RuntimeError('the compiled kernels need numba: pip install -e ".[fast]" (or set EOT_NUMBA=0)')


def njit(*args, **kwargs):
    """``numba.njit(cache=True, ...)``; without numba a decorator that leaves the function as it is (the
    kernels are then never called by the tracker, but stay importable and testable as plain Python)."""
    kwargs.setdefault("cache", True)
    if _numba is None:
        if args and callable(args[0]):
            return args[0]
        return lambda f: f
    return _numba.njit(*args, **kwargs)
