"""Compiling the kernels before they are needed (ahead of a first construction).

numba compiles a kernel at its first call and keeps it in its on-disk cache (``jit``); a first
construction on a fresh install pays for all of them before its first iteration. :func:`warm`
runs a tiny construction with the default preset, which calls every kernel a default
construction calls (base builder, closest points, baking, renderer forward and backward,
metrics), so they are compiled and cached (the construction compiles the listed ones in one
process per core first: ``runtime.precompile``, whose list ``python -m core.construct.warm
--write`` records from this construction); :func:`is_warm` says whether that is done for this
source and this import name. :func:`command` is the command line that does it in a process
of its own (the add-on starts it in the background when it is enabled).

numba keys each cache entry by the CPU it was compiled for (target triple, CPU name and
features): an entry compiled on another machine is never served, it is compiled again.
"""
from __future__ import annotations

import importlib
import os
import sys
import time
from typing import Callable

from ..runtime import child, precompile

def warm(progress: Callable[[str], None] | None = None) -> float:
    """Compile (or load from the cache) the kernels of a default construction; seconds taken."""
    import numpy as np

    from ..mesh.trimesh import TriMesh
    from ..mesh.primitives import icosphere
    from ..settings.fields import preset
    from .run import construct

    t = time.perf_counter()
    v, f = icosphere(3)
    v = v * (1.0 + 0.05 * np.sin(9.0 * v[:, :1]) * np.sin(7.0 * v[:, 1:2]))
    settings = preset("default", iterations=12, subdivide_at=(2, 4, 6, 8), train_resolution=32,
                      eval_resolution=32, eval_views=2, n_views=4, views_per_iter=2)
    report = (lambda p: progress(str(p.phase))) if progress else None
    construct(TriMesh(v, f), None, None, settings, progress=report)
    from ..runtime.jit import cache_folders, prune_stale

    prune_stale(cache_folders())             # entries of earlier sources
    return time.perf_counter() - t


def is_warm(entries: list[dict] | None = None) -> bool:
    """Whether the cache holds every listed kernel (``precompile.load()``, or ``entries``)
    compiled for this CPU, for this source and this import name."""
    return all(precompile.cached(e) for e in (precompile.load() if entries is None else entries))


def main(action: str = "warm") -> None:
    """Entry point of :func:`command`'s process."""
    cached = is_warm()
    if cached or action == "is_warm":
        print("warm: kernels cached:", cached, flush=True)
        return
    if hasattr(os, "nice"):
        os.nice(10)
    print(f"warm: kernels ready in {warm():.1f} s", flush=True)


def command(package_root: str, package_name: str, extra_paths: list[str],
            action: str = "warm") -> list[str]:
    """A command line that imports the package at ``package_root`` as ``package_name`` (so
    the cache entries carry the caller's import name) and, where the kernels are not cached
    for this CPU yet, warms them (``action`` "warm", at a low priority); "is_warm" only says
    whether they are. ``extra_paths`` go first on ``sys.path`` (the dependency folder)."""
    return child.command(package_root, package_name, extra_paths, "core.construct.warm", "main",
                         action)


if __name__ == "__main__":      # from the repository root, core importable as "core"
    if sys.argv[1:] != ["--write"]:
        raise SystemExit("usage: NUMBA_CACHE_DIR=<empty folder> python -m core.construct.warm "
                         "--write")
    precompile.write(precompile.record(importlib.import_module("core.construct.warm").warm))
