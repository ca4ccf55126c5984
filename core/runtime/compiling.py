"""The listed kernels compiled in processes of their own while a construction goes on.

:func:`start` launches one process per usable core (at most 4) on the listed kernels that
the cache lacks (``precompile``). Each process takes its kernels in the order a construction
first calls them: by the phase each was first compiled in (``kernels.json``), in
:data:`PHASES` order. :meth:`Compiling.wait` returns once the kernels of the phases named are
compiled, so a construction builds its base while the renderer's kernels are still being
compiled, and starts optimising while the fit's are. :meth:`Compiling.close` ends the
processes still running (a cancel, a failure, the end of the construction).

A kernel that a construction calls before its process has compiled it is compiled by the
construction itself: the same result, only the time is lost.
"""
from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Callable, Collection

from . import precompile
from .child import command, here

PHASES = ("reference", "base", "views", "optimize")
"""A construction's phases up to its first iteration, in their order; the kernels first
compiled in the later phases (the fit, the bounds, the metrics) come after these."""


def _rank(entry: dict) -> int:
    phase = entry.get("phase")
    return PHASES.index(phase) if phase in PHASES else len(PHASES)


def plan(missing: list[dict], n: int) -> list[list[dict]]:
    """``missing`` in ``n`` parts, each in the order of :data:`PHASES`: the kernels of each
    phase in turn split over the parts (a module's kernels together, ``precompile.split``),
    the part with the fewest seconds so far taking the largest share."""
    parts: list[list[dict]] = [[] for _ in range(n)]
    for rank in sorted({_rank(e) for e in missing}):
        shares = precompile.split([e for e in missing if _rank(e) == rank], n)
        loads = [sum(e["seconds"] for e in p) for p in parts]
        order = sorted(range(n), key=lambda k: loads[k])
        for k, share in zip(order, sorted(shares, key=lambda s: -sum(e["seconds"] for e in s))):
            parts[k].extend(share)
    return [p for p in parts if p]


class Compiling:
    """Processes compiling ``missing`` (listed kernels with their "index" in the list)."""

    def __init__(self, missing: list[dict], n: int):
        self.missing = missing
        self._folder = tempfile.TemporaryDirectory()
        root, package = here()
        paths = [p for p in sys.path if p and p != root]
        self._procs, self._logs = [], []
        try:
            for k, part in enumerate(plan(missing, n)):
                self._logs.append(Path(self._folder.name) / f"{k}.log")
                with open(self._logs[-1], "wb") as out:   # the process keeps its own handle
                    self._procs.append(subprocess.Popen(
                        command(root, package, paths, "core.runtime.precompile",
                                "compile_listed", *(e["index"] for e in part)),
                        stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT))
        except BaseException:
            self.close()
            raise

    def done(self) -> set[int]:
        """The indices of the kernels compiled so far."""
        found: set[int] = set()
        for log in self._logs:
            try:
                found |= precompile.done_indices(log.read_bytes())
            except OSError:
                pass
        return found

    def wait(self, phases: Collection[str] | None = None,
             progress: Callable[[int, int], None] | None = None,
             should_stop: Callable[[], bool] | None = None) -> float:
        """Until the kernels first compiled in ``phases`` (None: all) are compiled, the
        processes have ended or ``should_stop()``; ``progress(done, total)`` (of those kernels)
        about twice a second. Returns the seconds it waited."""
        t0 = time.perf_counter()
        need = {e["index"] for e in self.missing if phases is None or e.get("phase") in phases}
        tick = 0
        while any(p.poll() is None for p in self._procs):
            left = need - self.done()
            if not left or (should_stop is not None and should_stop()):
                break
            if progress is not None and tick % 5 == 0:
                progress(len(need) - len(left), len(need))
            tick += 1
            time.sleep(0.1)
        return time.perf_counter() - t0

    def close(self) -> None:
        """End the processes still running and say where one failed (that costs time only:
        the construction compiles what is left itself)."""
        for p, log in zip(self._procs, self._logs):
            if p.poll() is None:
                p.terminate()
            elif p.returncode != 0:
                print("precompile: a compiling process failed:\n"
                      + log.read_bytes().decode(errors="replace")[-2000:], file=sys.stderr)
            p.wait()
        self._procs = []
        self._folder.cleanup()


_early: Compiling | None = None


def start_early() -> None:
    """Start compiling now, for the next :func:`start` to take over: a command line calls it
    before its imports and its inputs' reading. :func:`close_early` ends the processes where
    no construction took them."""
    global _early
    if _early is None:
        _early = start()


def close_early() -> None:
    global _early
    if _early is not None:
        _early.close()
        _early = None


def start(processes: int | None = None) -> Compiling | None:
    """Start compiling the listed kernels the cache lacks in ``processes`` processes (default:
    one per usable core, at most 4), or hand over those :func:`start_early` started; None
    where there is nothing to do (all cached, one core: the construction then compiles as it
    goes, or while recording the list)."""
    global _early
    if _early is not None:
        early, _early = _early, None
        return early
    if precompile.recording():
        return None
    missing = [dict(e, index=i) for i, e in enumerate(precompile.load())
               if not precompile.cached(e)]
    n = min(processes or min(precompile.usable_cores(), 4), len(missing))
    if n <= 1:
        return None
    try:
        return Compiling(missing, n)
    except OSError as e:        # no process could start: the construction compiles as it goes
        print(f"precompile: no compiling process: {e}", file=sys.stderr)
        return None
