"""``kernel``: numba ``njit`` with an on-disk cache that is keyed by the module's import name.

The same source is imported under several names (``core`` in tests and benchmarks,
``micromesh.core`` through the scripts' alias, ``bl_ext.<repo>.micromesh...`` in Blender).
numba's own cache is keyed by file only and stores the import name, so an entry written under
one name fails to load under another (ModuleNotFoundError). Putting the import name into the
cache file name keeps one valid entry per name.

numba also checks only the kernel's own file: a kernel that inlines a kernel from another
module keeps serving the old callee after that module changes. The cache file name therefore
carries a digest of every source file of ``core`` that defines kernels, so any change to one
of them recompiles them all.
"""
from __future__ import annotations

import hashlib
from functools import lru_cache
from pathlib import Path
from typing import Callable

from numba import njit
from numba.core.caching import CompileResultCacheImpl, FunctionCache


@lru_cache(maxsize=1)
def source_digest() -> str:
    """A short digest of the source files of this package (``core``) that define kernels."""
    h = hashlib.sha1()
    root = Path(__file__).resolve().parents[1]
    for f in sorted(root.rglob("*.py")):
        text = f.read_bytes()
        if b"@kernel(" in text:
            h.update(f.relative_to(root).as_posix().encode())
            h.update(text)
    return h.hexdigest()[:10]


class _NamedImpl(CompileResultCacheImpl):
    def __init__(self, py_func) -> None:
        self._import_name = py_func.__module__
        super().__init__(py_func)

    def get_filename_base(self, fullname: str, abiflags: str) -> str:
        prefix = self._import_name.rsplit(".", 1)[0]
        return super().get_filename_base(f"{prefix}.{source_digest()}.{fullname}", abiflags)


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
