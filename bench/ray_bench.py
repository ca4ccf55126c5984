"""Throughput of ``batch.py`` over a folder: the serial run (one process, every core) against
``--ray`` on a real local Ray cluster of 1 and of 2 worker nodes (``tests/local_ray.py``:
a head that only schedules, each worker node ``--cpus`` CPUs, each input a task of that many
threads), the same generated inputs and options each time; inputs per minute (the driver's
wall time: the cluster's own start-up is left out, each input's process start-up is in), and
whether every ``.bary`` is byte for byte the serial run's.

On one machine the worker nodes share its cores: 2 nodes of 1 CPU on a 2-core machine is
the whole machine, as the serial run is; the figures show what a task costs beside a
serial input (its own process: bpy, torch and the kernel cache loaded per input) more than
what a cluster of machines gains.

    python bench/ray_bench.py [--inputs 6] [--faces 2560] [--cpus 1] [--json FILE]
"""
from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _common import ROOT, noisy_sphere, parser, print_table, write_json

sys.path.insert(0, str(ROOT / "tests"))
from local_ray import LocalCluster  # noqa: E402

from core.io.ply import write_ply  # noqa: E402

# a small optimised run: the fast preset, shorter, without its time limit (the same bytes
# whatever the machine's speed)
OPTIONS = ("--preset", "fast", "--set", "time_limit_s=0", "--set", "iterations=30",
           "--set", "subdivide_at=5,12,20", "--target-faces", "160", "--base-error", "0")


def _batch(*args, env=None) -> float:
    """Seconds of one ``batch.py`` run (which must succeed)."""
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, str(ROOT / "batch.py"), *map(str, args)],
                       capture_output=True, text=True, cwd=ROOT, env=env)
    seconds = time.perf_counter() - t0
    if r.returncode != 0:
        raise SystemExit(f"batch.py {' '.join(map(str, args))} failed:\n{r.stdout[-3000:]}"
                         f"\n{r.stderr[-3000:]}")
    return seconds


def _record(run: str, nodes: int, cpus: int, seconds: float, n: int, folder: Path,
            serial: Path) -> dict:
    same = all((folder / p.name).read_bytes() == p.read_bytes() for p in serial.glob("*.bary"))
    return {"run": run, "worker_nodes": nodes, "cpus": cpus, "inputs": n,
            "seconds": round(seconds, 1), "inputs_per_minute": round(60 * n / seconds, 2),
            "bary_identical": same}


def main() -> None:
    p = parser(__doc__.split("\n\n")[0])
    p.add_argument("--inputs", type=int, default=6, help="generated inputs (default 6)")
    p.add_argument("--faces", type=int, default=2560, help="faces of each (default 2560)")
    p.add_argument("--cpus", type=int, default=1, help="CPUs of each worker node (default 1)")
    args = p.parse_args()
    cores = len(os.sched_getaffinity(0))
    with tempfile.TemporaryDirectory(prefix="ray_bench") as tmp:
        tmp = Path(tmp)
        lib = tmp / "lib"
        lib.mkdir()
        for i in range(args.inputs):
            write_ply(lib / f"in{i}.ply", *noisy_sphere(args.faces, seed=i))
        serial = tmp / "serial"
        threads = ["--threads", str(args.threads)] if args.threads else []
        records = [_record("serial", 0, args.threads or cores,
                           _batch("--input", lib, "--output", serial, *OPTIONS, *threads),
                           args.inputs, serial, serial)]
        for workers in (1, 2):
            out = tmp / f"ray{workers}"
            with LocalCluster(workers=workers, cpus=args.cpus) as cluster:
                seconds = _batch("--input", lib, "--output", out, *OPTIONS, "--threads",
                                 args.cpus, "--ray", cluster.address, env=cluster.env)
            records.append(_record("ray", workers, workers * args.cpus, seconds, args.inputs,
                                   out, serial))
    base = records[0]["inputs_per_minute"]
    for r in records:
        r["vs_serial"] = round(r["inputs_per_minute"] / base, 2)
    print_table(records, title=f"batch.py on {args.inputs} inputs of {args.faces} faces, "
                               f"{cores} cores")
    write_json(args.json, records, options=list(OPTIONS), cores=cores)


if __name__ == "__main__":
    main()
