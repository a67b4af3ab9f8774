"""Cache keys of the compiled kernels that cover every kernel file, not only the kernel's own.

numba stores a compiled kernel in its on-disk cache under a stamp of the kernel's own source file and
checks only that stamp when it loads it. A kernel that calls kernels of other files (``pairs`` calls
``centerline``, ``structure``, ``kalman``, ...) would therefore load stale machine code after one of
those files changed. Here every kernel built with ``tracker.compiled.njit`` gets a stamp made of the
contents of its own file and of every ``.py`` file in ``tracker/compiled/``: editing any kernel file
makes every kernel recompile on its next call, with no manual step (at the cost of recompiling
kernels that did not depend on the edit).

``register(py_file)`` marks a file as holding such kernels (``njit`` calls it); ``install()`` puts the
two locators (numba's own, with this stamp) first in numba's list once per process.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

#: The folder whose ``.py`` files every kernel's stamp covers (``tracker/compiled``).
KERNEL_DIR = Path(__file__).resolve().parent
_FILES: set[str] = set()  # files holding kernels built with tracker.compiled.njit
_MEMO: dict[tuple, bytes] = {}  # (file, every covered file's mtime and size) -> stamp
_INSTALLED = False


def register(py_file: str) -> None:
    """Key the kernels of ``py_file`` by ``stamp(py_file)``."""
    _FILES.add(os.path.abspath(py_file))


def covered_files(py_file: str) -> list[Path]:
    """The files a kernel of ``py_file`` depends on: itself and every ``.py`` file of ``KERNEL_DIR``."""
    return sorted({Path(os.path.abspath(py_file)), *KERNEL_DIR.glob("*.py")})


def stamp(py_file: str) -> bytes:
    """SHA-256 over the paths and contents of ``covered_files(py_file)`` (memoised by their mtimes
    and sizes, so an edit during a process is seen)."""
    files = covered_files(py_file)
    stats = [f.stat() for f in files]
    key = (os.path.abspath(py_file), *((str(f), st.st_mtime_ns, st.st_size) for f, st in zip(files, stats)))
    if key not in _MEMO:
        digest = hashlib.sha256()
        for f in files:
            digest.update(str(f.relative_to(f.parent.parent)).encode())
            digest.update(hashlib.sha256(f.read_bytes()).digest())
        _MEMO[key] = digest.digest()
    return _MEMO[key]


def _locator(base: type) -> type:
    class PackageStampLocator(base):
        """numba's ``{base}`` for the registered kernel files, stamped by ``stamp``."""

        def get_source_stamp(self):
            return stamp(self._py_file)

        @classmethod
        def from_function(cls, py_func, py_file):
            if os.path.abspath(py_file) not in _FILES:
                return None
            return super().from_function(py_func, py_file)

    PackageStampLocator.__name__ = PackageStampLocator.__qualname__ = f"PackageStamp{base.__name__.lstrip('_')}"
    return PackageStampLocator


def install() -> None:
    """Put the package-stamp locators first in numba's locator list (once per process)."""
    global _INSTALLED
    if _INSTALLED:
        return
    from numba.core import caching

    impl = getattr(caching, "CacheImpl", None) or caching._CacheImpl
    bases = [getattr(caching, name, None) or getattr(caching, f"_{name}")
             for name in ("UserProvidedCacheLocator", "InTreeCacheLocator")]
    impl._locator_classes[:0] = [_locator(base) for base in bases]
    _INSTALLED = True
