"""A whole construction per device: the ``default`` preset with no other setting (what
``batch.py`` runs, through ``core`` without Blender) on the CPU and on CUDA, same input.

Per device, in a process of its own: wall time, the phase times of the run, the optimiser's
seconds per iteration, peak resident memory (and the GPU's peak), PSNR and micro-triangles, and
the micro-mesh as ``OUT/NAME_DEVICE.gltf`` + ``.bin`` + ``.bary`` for the independent judge.
The devices' results differ only in float summation order (the render is deterministic on
each): the table shows how far apart their PSNRs end.

    python bench/device_bench.py [--input MESH.ply] [--devices cpu cuda] [--out DIR] [--json FILE]
        [--profile]

Without ``--input``: a noisy sphere of about 40k faces.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

from _common import ROOT, add_child_option, parser, print_table, write_json


def run_one(mesh: str | None, device: str, out: str, profile: bool = False) -> dict:
    import torch

    from core.mesh import primitives
    from core.construct import construct
    from core.io.micromesh_export import write_micromesh
    from core.mesh.trimesh import TriMesh
    from core.io.mesh_files import read_mesh
    from core.settings.fields import preset

    ref = read_mesh(mesh) if mesh else TriMesh(*primitives.noisy_sphere(40_000, seed=3))
    name = Path(mesh).stem if mesh else "noisy_sphere"
    t0 = time.perf_counter()
    with optimiser_profile(profile, device) as on_progress:
        r = construct(ref, None, None, preset("default", device=device), progress=on_progress)
    wall = time.perf_counter() - t0
    path = Path(out) / f"{name}_{device}.gltf"
    write_micromesh(path, r.micromesh, r.bounds)
    it = max(len(r.history.get("iteration", [])), 1)
    gpu_peak = torch.cuda.max_memory_allocated() / 2 ** 20 if device == "cuda" else 0.0
    return {"input": name, "device": device,
            "device_name": torch.cuda.get_device_name() if device == "cuda" else cpu_name(),
            "wall_s": wall, "phases": r.timings, "optimize_s_per_iteration":
            r.timings.get("optimize", float("nan")) / it, "iterations": it,
            "psnr": r.metrics["psnr"], "micro_triangles": r.metrics["micro_triangles"],
            "base_faces": r.metrics["base_faces"], "gpu_peak_mb": gpu_peak, "file": str(path)}


@contextmanager
def optimiser_profile(enabled: bool, device: str):
    """A progress callback that, when ``enabled``, records optimiser iterations 21-25 with
    torch.profiler and prints the ops that took the most time (stderr), after the run."""
    if not enabled:
        yield None
        return
    from torch.profiler import ProfilerActivity, profile, schedule

    acts = [ProfilerActivity.CPU] + ([ProfilerActivity.CUDA] if device == "cuda" else [])
    with profile(activities=acts, schedule=schedule(wait=20, warmup=2, active=5, repeat=1)) as prof:
        yield lambda p: prof.step() if p.phase == "optimize" else None
    key = "cuda_time_total" if device == "cuda" else "cpu_time_total"
    print(prof.key_averages().table(sort_by=key, row_limit=25), file=sys.stderr)
    print(prof.key_averages().table(sort_by="cpu_time_total", row_limit=15), file=sys.stderr)


def cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    import platform

    return platform.processor() or platform.machine()


def main() -> None:
    ap = parser(__doc__.splitlines()[0])
    ap.add_argument("--input", default=None, help="a .ply or .obj (default: a noisy sphere of about 40k faces)")
    ap.add_argument("--devices", nargs="+", default=["cpu", "cuda"], choices=["cpu", "cuda"])
    ap.add_argument("--out", default="/tmp/micromesh_device_bench")
    ap.add_argument("--profile", action="store_true",
                    help="torch.profiler over optimiser iterations 21-25: the top ops in OUT/DEVICE.log")
    add_child_option(ap)
    a = ap.parse_args()
    from core.runtime.threads import set_threads

    threads = set_threads(a.threads or None)
    if a.child:
        print(json.dumps(run_one(**json.loads(a.child))))
        return
    Path(a.out).mkdir(parents=True, exist_ok=True)
    records = []
    for dev in a.devices:
        cfg = {"mesh": a.input, "device": dev, "out": a.out, "profile": a.profile}
        cmd = [sys.executable, __file__, "--child", json.dumps(cfg), "--threads", str(threads)]
        with open(Path(a.out) / f"{dev}.log", "w") as log:
            p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=log, text=True, cwd=ROOT)
            stdout = p.stdout.read()
            _, status, usage = os.wait4(p.pid, 0)
        if os.waitstatus_to_exitcode(status) != 0:
            raise SystemExit(f"the {dev} run failed: see {Path(a.out) / f'{dev}.log'}")
        rec = json.loads(stdout.strip().splitlines()[-1])
        rec["peak_mb"] = usage.ru_maxrss / 1024
        records.append(rec)
        print(f"done {dev}: {rec['wall_s']:.1f} s, PSNR {rec['psnr']:.2f}", file=sys.stderr,
              flush=True)
    rows = [{"device": r["device"], "wall s": r["wall_s"], "optimize s/it": r["optimize_s_per_iteration"],
             **{f"{k} s": v for k, v in r["phases"].items() if v >= 1.0},
             "PSNR": r["psnr"], "micro-tris": r["micro_triangles"], "peak MB": r["peak_mb"],
             "GPU peak MB": r["gpu_peak_mb"]} for r in records]
    print_table(rows, title=f"default construction of {records[0]['input']} per device "
                            f"({', '.join(sorted({r['device_name'] for r in records}))}; "
                            f"{threads} CPU threads)")
    write_json(a.json, records, threads=threads)


if __name__ == "__main__":
    main()
