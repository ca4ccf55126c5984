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
import re
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


_ENTRY = re.compile(r"^(?:[\w]+\.)+?([0-9a-f]{10})\.[\w.]+-\d+\.py\d+(?:\.\d+)?\.nb[ic]$")


def prune_stale(folders) -> int:
    """Remove the cache entries of earlier sources (another digest than this source's) from
    ``folders`` (numba's cache folders of this package's kernels); returns how many went.
    Every change to a kernel source leaves a full set of entries behind otherwise."""
    current, gone = source_digest(), 0
    for folder in {Path(f) for f in folders}:
        for entry in folder.glob("*.nb[ic]") if folder.is_dir() else ():
            m = _ENTRY.match(entry.name)
            if m and m.group(1) != current:
                try:
                    entry.unlink()
                    gone += 1
                except OSError:
                    pass
    return gone


def cache_folders() -> list[str]:
    """numba's cache folders of this package's kernels (in the source tree, or where numba
    put them: NUMBA_CACHE_DIR, the user's cache)."""
    import sys

    folders = []
    package = __name__.rsplit(".", 2)[0]
    for name, module in list(sys.modules.items()):
        if not name.startswith(package + ".") or module is None:
            continue
        for obj in vars(module).values():
            cache = getattr(obj, "_cache", None)
            if isinstance(cache, _NamedCache):
                folders.append(cache._cache_path)
    return sorted(set(folders))


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
    """``@kernel(nogil=True, error_model="numpy")``: compiled with numba, cached per import name."""

    def wrap(fn):
        dispatcher = njit(**options)(fn)
        try:
            dispatcher._cache = _NamedCache(fn)
        except RuntimeError:  # no writable cache location: compile per process
            pass
        return dispatcher

    return wrap
