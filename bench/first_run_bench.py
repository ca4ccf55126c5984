"""First run: seconds from the start of a process to the first optimisation iteration of a
default construction (50k-triangle noisy sphere), from an empty kernel cache (cold: every
kernel compiled on the way) next to the same after the warm-up (``core.construct.warm``, what
the add-on runs in the background when it is enabled), and the warm-up's own time. Target
(issue 13): the first iteration within 15 s of the start.

Each case runs in a fresh process with its own cache folder (``NUMBA_CACHE_DIR``).

    python bench/first_run_bench.py [--json FILE]
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile

from _common import ROOT, parser, print_table, write_json

TARGET_S = 15.0

CHILD = r"""
import json, sys, time
t0 = time.perf_counter()
sys.path.insert(0, sys.argv[1])
from numba.core import event
compiled = []
class Rec(event.Listener):
    def on_start(self, ev): pass
    def on_end(self, ev): compiled.append(1)
event.register("numba:compile", Rec())
from core.runtime import precompile
missing = sum(not precompile.cached(e) for e in precompile.load())
threads = int(sys.argv[3])
if sys.argv[2] == "warm":
    from core.construct.warm import warm
    warm()
    print(json.dumps({"seconds": time.perf_counter() - t0, "compiled": len(compiled),
                      "missing": missing}))
    sys.exit(0)
from core.construct import construct, preset
from core.mesh import TriMesh
from core.mesh.primitives import noisy_sphere
class First(Exception):
    pass
def progress(p):
    if p.phase == "optimize":
        raise First
v, f = noisy_sphere(50_000)
try:
    construct(TriMesh(v, f), None, None, preset("default", threads=threads), progress=progress)
except First:
    pass
print(json.dumps({"seconds": time.perf_counter() - t0, "compiled": len(compiled),
                  "missing": missing}))
"""


def child(mode: str, cache: str, threads: int) -> dict:
    env = {**os.environ, "NUMBA_CACHE_DIR": cache}
    r = subprocess.run([sys.executable, "-c", CHILD, str(ROOT), mode, str(threads or 0)],
                       capture_output=True, text=True, env=env, timeout=1800)
    if r.returncode != 0:
        raise SystemExit(r.stderr)
    return json.loads(r.stdout.strip().splitlines()[-1])


def main() -> None:
    args = parser(__doc__.split("\n\n")[0]).parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as cold, tempfile.TemporaryDirectory() as warmed:
        for label, mode, cache in (("cold cache: to the first iteration", "first", cold),
                                   ("warm-up (background, at enable)", "warm", warmed),
                                   ("after the warm-up: to the first iteration", "first",
                                    warmed)):
            r = child(mode, cache, args.threads)
            rows.append({"case": label, "seconds": r["seconds"], "listed_missing": r["missing"],
                         "compiled_in_run": r["compiled"]})
            print(f"{label}: {r['seconds']:.1f} s, {r['missing']} listed kernels not cached "
                  f"at the start, {r['compiled']} compilations in the run's own process",
                  flush=True)
    for row in rows:
        if row["case"].endswith("first iteration"):
            row["target_15s"] = "met" if row["seconds"] <= TARGET_S else "not met"
    print_table(rows, title="first run, default preset, noisy sphere 50k")
    write_json(args.json, rows)


if __name__ == "__main__":
    main()
