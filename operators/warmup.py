"""Kernels compiled before the first Construct: when the add-on is enabled in an interactive
Blender, a process of its own (``core.construct.warm.command``, at a low priority) checks the
kernel cache and, where it is cold for this CPU, compiles every kernel a default construction
calls. A Construct pressed meanwhile waits for it (phase "compiling kernels") instead of
compiling the same kernels a second time beside it. Its output goes to ``warm.log`` beside
the dependency folder. Not started in background mode (``blender -b``, ``batch.py``), where
the run compiles what it needs itself."""
from __future__ import annotations

import os
import subprocess
import time
from typing import Callable

from ..install import deps
from .prefs import site_dir

_PROC: subprocess.Popen | None = None


def start() -> subprocess.Popen | None:
    """Start the warm-up process (once); None in background mode, or where it cannot start
    (no writable log, no Python executable): the first Construct then compiles as it goes."""
    global _PROC
    import bpy

    if bpy.app.background or _PROC is not None:
        return _PROC
    from ..core.construct.warm import command

    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    package = __package__.rsplit(".", 1)[0]
    log = os.path.join(os.path.dirname(deps.log_path(site_dir())), "warm.log")
    try:
        with open(log, "w", encoding="utf-8") as out:
            _PROC = subprocess.Popen(command(root, package, [site_dir()]), stdout=out,
                                     stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
    except OSError:
        _PROC = None
    return _PROC


def running() -> bool:
    return _PROC is not None and _PROC.poll() is None


def wait(progress: Callable, should_stop: Callable[[], bool]) -> None:
    """Until the warm-up process has finished (at once where none runs), reporting phase
    "compiling kernels"; stops waiting when ``should_stop()``."""
    t0 = time.monotonic()
    while running() and not should_stop():
        progress({"phase": "compiling kernels", "iteration": int(time.monotonic() - t0),
                  "total": 0})
        time.sleep(0.25)


def stop() -> None:
    """End the warm-up process (the add-on is disabled or Blender quits)."""
    global _PROC
    if running():
        _PROC.terminate()
    _PROC = None
