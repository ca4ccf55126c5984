"""Compiling the listed kernels in parallel processes (core/runtime/precompile.py,
core/runtime/compiling.py): the list parses back into numba's types, its parts are balanced
and ordered by the phase that first calls them, and from an empty cache a construction
compiles the listed kernels in processes of their own (phase "compiling kernels") and itself
compiles none of them; a stop request ends those processes at once."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

COLD_RUN = r"""
import json, sys
sys.path.insert(0, sys.argv[1])
from numba.core import event
from core.runtime import precompile
from core.runtime.jit import _NamedCache
listed = {(e["module"], e["name"]) for e in precompile.load()}
here = []
class Rec(event.Listener):
    depth = 0
    def on_start(self, ev): Rec.depth += 1
    def on_end(self, ev):
        Rec.depth -= 1
        d = ev.data["dispatcher"]
        if Rec.depth == 0 and isinstance(getattr(d, "_cache", None), _NamedCache):
            here.append((d.py_func.__module__[len("core."):], d.py_func.__name__))
event.register("numba:compile", Rec())
missing = sum(not precompile.cached(e) for e in precompile.load())
from core.construct.warm import warm, is_warm
phases = []
warm(progress=phases.append)
print(json.dumps({"missing_before": missing, "phases": sorted(set(phases)),
                  "listed_compiled_here": sorted(set(here) & listed),
                  "cached_after": sum(precompile.cached(e) for e in precompile.load()),
                  "warm": is_warm()}))
"""

STOP = r"""
import sys, time
sys.path.insert(0, sys.argv[1])
from core.runtime import compiling
t = time.perf_counter()
c = compiling.start(processes=2)
c.wait(should_stop=lambda: True)
c.close()
print(len(c.missing), time.perf_counter() - t)
"""

EARLY = r"""
import os, sys, time
sys.path.insert(0, sys.argv[1])
from core.runtime import compiling
compiling.start_early()
early = compiling._early
taken = compiling.start()                 # what a construction's Kernels does
t = time.perf_counter()
while not taken.done() and time.perf_counter() - t < 60:
    time.sleep(0.05)
nice = []
for p in taken._procs:
    try:
        nice.append(os.getpriority(os.PRIO_PROCESS, p.pid) - os.getpriority(os.PRIO_PROCESS, 0))
    except ProcessLookupError:            # that process is already done
        pass
taken.close()
compiling.start_early()                   # none takes these: close_early ends them
procs = compiling._early._procs
compiling.close_early()
print(int(taken is early), int(compiling._early is None), min(nice),
      int(all(p.poll() is not None for p in procs)))
"""


def _child(code: str, cache: Path) -> str:
    r = subprocess.run([sys.executable, "-c", code, str(ROOT)], capture_output=True, text=True,
                       env={**os.environ, "NUMBA_CACHE_DIR": str(cache)}, timeout=1200)
    assert r.returncode == 0, r.stderr
    return r.stdout.strip().splitlines()[-1]


def test_listed_signatures_parse_back():
    from core.runtime import precompile

    entries = precompile.load()
    assert entries
    for e in entries:
        assert repr(precompile.signature(e["signature"])) == e["signature"]
        assert callable(precompile._dispatcher(e).py_func)


def test_split_balances_the_seconds():
    from core.runtime.precompile import split

    entries = [{"name": str(i), "seconds": s} for i, s in enumerate([9, 7, 5, 4, 3, 3, 1])]
    parts = split(entries, 2)
    assert sorted(e["name"] for p in parts for e in p) == sorted(e["name"] for e in entries)
    loads = [sum(e["seconds"] for e in p) for p in parts]
    assert max(loads) - min(loads) <= 2, loads
    assert split(entries[:1], 3)[1:] == [[], []]


def test_split_keeps_a_module_together():
    """Kernels of one module share the kernels they call, which one process compiles once."""
    from core.runtime.precompile import split

    entries = [{"module": m, "name": f"{m}{i}", "seconds": s}
               for i, (m, s) in enumerate([("a", 4), ("a", 4), ("b", 3), ("c", 3), ("d", 2)])]
    parts = split(entries, 2)
    where = {e["name"]: k for k, p in enumerate(parts) for e in p}
    assert where["a0"] == where["a1"]
    assert sorted(sum(e["seconds"] for e in p) for p in parts) == [8, 8]


def test_plan_orders_each_part_by_phase():
    """Each process compiles the kernels a construction calls first first: the base builder's
    spread over the processes, then the renderer's, then the fit's."""
    from core.runtime.compiling import PHASES, plan

    entries = [{"module": m, "name": f"{m}{i}", "seconds": s, "phase": ph} for i, (m, s, ph) in
               enumerate([("fit.a", 1, "fit"), ("render.a", 3, "views"), ("base.a", 4, "base"),
                          ("render.b", 3, "views"), ("base.b", 3, "base"), ("bvh", 1, "base")])]
    parts = plan(entries, 2)
    rank = {p: k for k, p in enumerate(PHASES)}
    assert sorted(e["name"] for p in parts for e in p) == sorted(e["name"] for e in entries)
    for p in parts:
        ranks = [rank.get(e["phase"], len(PHASES)) for e in p]
        assert ranks == sorted(ranks)
        assert p[0]["phase"] == "base"                 # both start on the base builder's
    assert sorted(sum(e["seconds"] for e in p if e["phase"] == "base") for p in parts) == [4, 4]


IMPORTS = r"""
import sys
sys.path.insert(0, sys.argv[1])
from core.runtime import precompile
for e in precompile.load():
    precompile._dispatcher(e)
print(sorted(m for m in ("torch", "scipy") if m in sys.modules))
"""


@pytest.mark.slow
def test_compiling_processes_import_no_torch(tmp_path):
    """A compiling process imports the listed kernels' modules only: no torch (a second or
    more of each process's start on 2 cores)."""
    assert "torch" not in _child(IMPORTS, tmp_path)


@pytest.mark.slow
def test_cold_cache_compiles_the_list_in_processes_of_its_own(tmp_path):
    """From an empty cache: every listed kernel is missing, the warm-up construction reports
    "compiling kernels", compiles none of the listed kernels itself and leaves all cached."""
    r = json.loads(_child(COLD_RUN, tmp_path))
    from core.runtime import precompile

    n = len(precompile.load())
    assert r["missing_before"] == n
    assert "compiling kernels" in r["phases"]
    assert r["listed_compiled_here"] == []
    assert r["cached_after"] == n and r["warm"]


@pytest.mark.skipif(not hasattr(os, "getpriority"), reason="process priorities are POSIX's")
@pytest.mark.slow
def test_processes_started_early_are_taken_over_or_ended(tmp_path):
    """``start_early`` (batch.py, before its imports): the next ``start`` takes its processes
    over, which compile below normal priority; ``close_early`` ends those none took."""
    taken, cleared, nice, ended = map(int, _child(EARLY, tmp_path).split())
    assert taken and cleared and ended
    assert nice >= 10


@pytest.mark.slow
def test_stop_ends_the_compiling_processes(tmp_path):
    n, seconds = _child(STOP, tmp_path).split()
    assert int(n) > 0 and float(seconds) < 20.0     # compiling them takes a minute or more
