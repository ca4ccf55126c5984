"""``kernel``: numba ``njit`` with an on-disk cache that is keyed by the module's import name.

The same source is imported under several names (``core`` in tests and benchmarks,
``micromesh.core`` through the scripts' alias, ``bl_ext.<repo>.micromesh...`` in Blender).
numba's own cache is keyed by file only and stores the import name, so an entry written under
one name fails to load under another (ModuleNotFoundError). Putting the import name into the
cache file name keeps one valid entry per name.
"""
from __future__ import annotations

from typing import Callable

from numba import njit
from numba.core.caching import CompileResultCacheImpl, FunctionCache


class _NamedImpl(CompileResultCacheImpl):
    def __init__(self, py_func) -> None:
        self._import_name = py_func.__module__
        super().__init__(py_func)

    def get_filename_base(self, fullname: str, abiflags: str) -> str:
        prefix = self._import_name.rsplit(".", 1)[0]
        return super().get_filename_base(f"{prefix}.{fullname}", abiflags)


class _NamedCache(FunctionCache):
    _impl_class = _NamedImpl


def kernel(**options) -> Callable:
    """``@kernel(parallel=True)``: compiled with numba, cached per import name."""

    def wrap(fn):
        dispatcher = njit(**options)(fn)
        try:
            dispatcher._cache = _NamedCache(fn)
        except RuntimeError:  # no writable cache location: compile per process
            pass
        return dispatcher

    return wrap
