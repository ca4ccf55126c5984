"""The kernels a construction compiles, listed, and the processes that compile them.

numba compiles one kernel at a time in a process: a default construction's kernels take a
few minutes in one process on a slow 2-core machine. The kernels a construction calls from
Python are listed in ``kernels.json`` with their signatures, the seconds each took to compile
(to balance the processes) and the construction's phase when it was first called (to compile
them in that order); the kernels they call are compiled inside them. ``compiling.start``
compiles the listed kernels that the on-disk cache lacks for this CPU in one process per core
(:func:`compile_listed`), which write them to the cache; the construction loads them from
there. On one core nothing is compiled ahead: the run compiles as it goes.

``python -m core.construct.warm --write`` records the list again from the warm-up
construction (``construct.warm``) in a fresh process with an empty cache; a test checks that the list
leaves the warm-up nothing to compile.
"""
from __future__ import annotations

import gc
import importlib
import json
import os
import sys
import time
from pathlib import Path
from typing import Callable

LIST = Path(__file__).with_name("kernels.json")
_CORE = __name__.rsplit(".", 2)[0]                         # <...>.core
_RECORDING = False                             # record(): nothing is compiled ahead


def load() -> list[dict]:
    """The listed kernels: {"module" (relative to core), "name", "signature", "seconds",
    "phase"}."""
    return json.loads(LIST.read_text(encoding="utf-8"))["kernels"]


def signature(text: str) -> tuple:
    """A signature as numba prints it (``repr`` of its tuple of types) back into types."""
    from numba.core import types

    names = {k: getattr(types, k) for k in dir(types) if not k.startswith("_")}
    names["bool"] = types.boolean
    sig = eval(text, {"__builtins__": {}}, names)          # noqa: S307  (our own list)
    return tuple(sig)


def _dispatcher(entry: dict):
    return getattr(importlib.import_module(f"{_CORE}.{entry['module']}"), entry["name"])


def cached(entry: dict) -> bool:
    """Whether the on-disk cache holds ``entry`` compiled for this CPU and this source."""
    from numba.core.registry import cpu_target

    cache = getattr(_dispatcher(entry), "_cache", None)
    try:
        key = cache._index_key(signature(entry["signature"]), cpu_target.target_context.codegen())
        return key in cache._cache_file._load_index()
    except Exception:  # noqa: BLE001  (no cache, or numba's internals moved: not cached)
        return False


def split(entries: list[dict], n: int) -> list[list[dict]]:
    """``entries`` in ``n`` parts of about equal seconds, a module's kernels in one part (they
    share the kernels they call, which a process compiles once: the base builder's two
    kernels take 4.2 s in one process, 6.4 s in two): the modules longest first, each to the
    part with the fewest seconds so far."""
    modules: dict[str, list[dict]] = {}
    for e in entries:
        modules.setdefault(e.get("module", e["name"]), []).append(e)
    parts: list[list[dict]] = [[] for _ in range(n)]
    loads = [0.0] * n
    for group in sorted(modules.values(), key=lambda g: -sum(e["seconds"] for e in g)):
        k = loads.index(min(loads))
        parts[k].extend(group)
        loads[k] += sum(e["seconds"] for e in group)
    return parts


# What a compiling process prints after each kernel, with its index: the caller reads these
# lines for what is done (asking the cache twice a second slowed the processes by a fifth).
_DONE = "precompile: compiled"


def compile_listed(*indices: str) -> None:
    """Compile the listed kernels at ``indices`` (their positions in the list) in this
    process, then end it; the entry point of each compiling process. Python's cycle
    collector is off while it compiles: numba's compiler makes a great many objects, and the
    collector's passes over them cost about a quarter of the time (``docs/results.md``). The
    process ends without Python's teardown, which took 2 s to free those objects one by one;
    numba has written each kernel to the cache as it was compiled. It runs below normal
    priority: the construction's own work (and its speed probe, ``runtime.speed``) comes first
    where they share the cores."""
    if hasattr(os, "nice"):
        os.nice(10)
    entries = load()
    gc.disable()
    for i in indices:
        e = entries[int(i)]
        _dispatcher(e).compile(signature(e["signature"]))
        print(_DONE, i, flush=True)
    sys.stderr.flush()
    os._exit(0)


def done_indices(log: bytes) -> set[int]:
    """The indices of the kernels a compiling process's output ``log`` says are compiled."""
    marker = _DONE.encode()
    return {int(line.split()[-1]) for line in log.splitlines() if line.startswith(marker)}


def recording() -> bool:
    """Whether :func:`record` is running (nothing is compiled ahead then)."""
    return _RECORDING


def usable_cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # macOS, Windows
        return os.cpu_count() or 1


def record(run: Callable[[Callable[[str], None]], None]) -> list[dict]:
    """The kernels ``run(progress)`` (the warm-up construction, ``construct.warm``) compiles
    from Python, with their signatures, seconds and the construction's phase at the time
    (``progress`` gets each phase's name). Run it with an empty cache: kernels loaded from the
    cache are not seen."""
    from numba.core import event

    from .jit import _NamedCache

    found, stack, phase = [], [], ["reference"]

    class Listener(event.Listener):
        def on_start(self, ev):
            stack.append(time.perf_counter())

        def on_end(self, ev):
            seconds = time.perf_counter() - stack.pop()
            d = ev.data["dispatcher"]
            if not stack and isinstance(getattr(d, "_cache", None), _NamedCache):
                found.append({"module": d.py_func.__module__[len(_CORE) + 1:],
                              "name": d.py_func.__name__, "signature": repr(ev.data["args"]),
                              "seconds": round(seconds, 2), "phase": phase[0]})

    global _RECORDING
    event.register("numba:compile", Listener())
    _RECORDING = True
    try:
        run(lambda p: phase.__setitem__(0, p))
    finally:
        _RECORDING = False
    return sorted(found, key=lambda e: (e["module"], e["name"], e["signature"]))


def write(entries: list[dict]) -> None:
    """``entries`` (:func:`record`'s) as the list."""
    if not entries:
        raise SystemExit("nothing compiled: the cache is warm; run with an empty NUMBA_CACHE_DIR")
    text = json.dumps({"about": "kernels a construction calls from Python, their signatures, "
                                "compile seconds and the construction's phase when first "
                                "called (python -m core.construct.warm --write, with an "
                                "empty cache)", "kernels": entries}, indent=1)
    LIST.write_text(text + "\n", encoding="utf-8")
    print(f"{len(entries)} kernels, {sum(e['seconds'] for e in entries):.1f} s, in {LIST}")
