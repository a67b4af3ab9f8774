"""``njit``: how every compiled kernel of the package is built, and the on-disk cache that is never stale.

The tracker's stages are numba kernels (numba is a dependency): at its sizes (a few to a few dozen
clusters and components per frame) numpy's cost is the number of calls, not the arithmetic, and one
compiled call per stage does the work of dozens of numpy calls. Each kernel lives in the module of the
stage it implements (``tracker.ukf``, ``tracker.centerline``, ...); ``docs/contributing.md`` says
where. ``NUMBA_DISABLE_JIT=1`` runs every kernel as plain Python, to step through it in a debugger.

Kernels compile on first use and are cached (``cache=True``: next to their module, or under
``NUMBA_CACHE_DIR``); ``tracker.warmup.warm_up`` compiles or loads them all at once.

The cache is never stale. numba stores a compiled kernel under a stamp of the kernel's own source file
and checks only that stamp when it loads it; a kernel that calls kernels of other modules would load
stale machine code after one of those modules changed. Every kernel built with this ``njit`` is
stamped instead by the contents of its own module and of every module of this project that it imports,
directly or through others (``imported_files``: the ``import`` statements at the modules' top level,
where numba finds the kernels a kernel calls). Editing a kernel recompiles, on their next call, exactly
the kernels of the modules that import it, with no manual step.
"""

from __future__ import annotations

import ast
import functools
import hashlib
import importlib.util
import os
from pathlib import Path

import numba

#: Top-level packages whose modules a stamp follows (the project's own; the rest are installed libraries).
PROJECT_PACKAGES = ("tracker", "sim")
_FILES: set[str] = set()  # files holding kernels built with this njit
_IMPORTS: dict[tuple[str, int, int], tuple[str, ...]] = {}  # (file, mtime, size) -> files it imports
_INSTALLED = False


def njit(*args, **kwargs):
    """``numba.njit(cache=True, no_cfunc_wrapper=True, ...)``, keyed in the cache by ``stamp`` (no
    kernel is passed around as a C function pointer, so numba's C-callable wrapper is not built).
    Small helpers that only other kernels call take ``inline="always"``: they compile into their
    callers (faster than a kernel of their own) and take their callers' flags (``fastmath``, error model)."""
    kwargs.setdefault("cache", True)
    kwargs.setdefault("no_cfunc_wrapper", True)
    if not kwargs["cache"]:
        return numba.njit(*args, **kwargs)
    _install()

    def decorate(function):
        _FILES.add(os.path.abspath(function.__code__.co_filename))
        return numba.njit(**kwargs)(function)

    return decorate(args[0]) if args and callable(args[0]) else decorate


@functools.lru_cache(maxsize=None)
def _module_file(name: str) -> str | None:
    """The source file of module ``name`` of the project (None for other packages or where not found)."""
    if name.split(".")[0] not in PROJECT_PACKAGES:
        return None
    try:
        spec = importlib.util.find_spec(name)
    except (ImportError, ValueError):
        return None
    origin = spec.origin if spec is not None else None
    return os.path.abspath(origin) if origin and origin.endswith(".py") else None


def _direct_imports(py_file: str) -> tuple[str, ...]:
    """The project's module files that ``py_file`` imports at its top level (``import a.b``,
    ``from a.b import c``, where ``a.b.c`` may itself be a module)."""
    st = os.stat(py_file)
    key = (py_file, st.st_mtime_ns, st.st_size)
    if key not in _IMPORTS:
        found: set[str] = set()
        for node in ast.parse(Path(py_file).read_bytes()).body:
            paths: list[str | None] = []
            if isinstance(node, ast.Import):
                paths = [_module_file(a.name) for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
                # ``from a.b import c``: the module ``a.b.c`` where it is one, else ``a.b`` (where ``c`` is defined)
                paths = [_module_file(f"{node.module}.{a.name}") or _module_file(node.module) for a in node.names]
            found.update(path for path in paths if path is not None)
        _IMPORTS[key] = tuple(sorted(found - {py_file}))
    return _IMPORTS[key]


def imported_files(py_file: str) -> list[str]:
    """``py_file`` and every module file of the project it imports, directly or through others
    (the top-level imports only), sorted."""
    seen = {os.path.abspath(py_file)}
    todo = list(seen)
    while todo:
        for path in _direct_imports(todo.pop()):
            if path not in seen:
                seen.add(path)
                todo.append(path)
    return sorted(seen)


def stamp(py_file: str) -> bytes:
    """SHA-256 over the names and contents of ``imported_files(py_file)``."""
    digest = hashlib.sha256()
    for path in imported_files(py_file):
        digest.update(Path(path).name.encode())
        digest.update(hashlib.sha256(Path(path).read_bytes()).digest())
    return digest.digest()


def _locator(base: type) -> type:
    class ImportStampLocator(base):
        """numba's locator for the files of ``njit``'s kernels, stamped by ``stamp``."""

        def get_source_stamp(self):
            return stamp(self._py_file)

        @classmethod
        def from_function(cls, py_func, py_file):
            if os.path.abspath(py_file) not in _FILES:
                return None
            return super().from_function(py_func, py_file)

    ImportStampLocator.__name__ = ImportStampLocator.__qualname__ = f"ImportStamp{base.__name__.lstrip('_')}"
    return ImportStampLocator


def _install() -> None:
    """Put the import-stamp locators first in numba's locator list (once per process)."""
    global _INSTALLED
    if _INSTALLED:
        return
    from numba.core import caching

    impl = getattr(caching, "CacheImpl", None) or caching._CacheImpl
    bases = [getattr(caching, name, None) or getattr(caching, f"_{name}")
             for name in ("UserProvidedCacheLocator", "InTreeCacheLocator")]
    impl._locator_classes[:0] = [_locator(base) for base in bases]
    _INSTALLED = True

