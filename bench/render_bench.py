"""Renderer benchmark: one optimiser iteration (rasterise + shaded render + antialias + L1 loss,
then backward to the vertices) from 24 views, numba CPU kernels next to the plain-torch path;
on CUDA (``--device cuda``) the torch path with its fused Triton kernels next to without.

    python bench/render_bench.py                  # 20k / 200k / 1M triangles at 256² and 512²
    python bench/render_bench.py --quick          # 20k / 200k at 256², fewer repeats
    python bench/render_bench.py --json out.json  # records {backend, device, triangles, ...}
    python bench/render_bench.py --profile        # plus the numba iteration stage by stage
                                                  # (on CUDA: torch.profiler's table by op)

The mesh is ``_common.noisy_sphere`` with its vertices renumbered in order of first use (memory
locality like a micro-mesh's; the raw numbering is ~30 % slower to rasterise); the target is the
shaded render of the same sphere scaled by 1.01. Each configuration runs in its own child process so that ``peak_mb`` (the process's peak
resident memory during one more forward + backward after the timed ones, sampled every 2 ms)
is not polluted by the others. Like ``core.construct``, the child keeps large freed buffers in
the heap (``core.runtime.memory``). Times are medians over ``--repeat`` runs after one warm-up run.
"""
from __future__ import annotations

import json
import subprocess
import sys
import threading
import time

import _common as C  # noqa: E402  (puts the repository root on sys.path)


class PeakRSS:
    """Samples this process's resident memory in a thread; ``peak_mb`` after ``stop``."""

    def __init__(self, period: float = 0.002) -> None:
        self.period, self.peak, self._run = period, 0, True
        self._t = threading.Thread(target=self._loop, daemon=True)

    @staticmethod
    def rss() -> int:
        with open("/proc/self/statm") as fh:
            return int(fh.read().split()[1]) * 4096

    def _loop(self) -> None:
        while self._run:
            self.peak = max(self.peak, self.rss())
            time.sleep(self.period)

    def __enter__(self) -> "PeakRSS":
        self._t.start()
        return self

    def __exit__(self, *exc) -> None:
        self._run = False
        self._t.join()

    @property
    def peak_mb(self) -> float:
        return self.peak / 2 ** 20


def first_use_order(v, f):
    """Renumber vertices in order of first use by the faces (as the micro-mesh's canonical
    index space keeps each base face's micro-vertices together); faces keep their order."""
    import numpy as np

    _, first = np.unique(f.ravel(), return_index=True)
    order = np.argsort(first)
    new = np.empty(len(v), np.int64)
    new[order] = np.arange(len(v))
    return v[order], new[f]


def numba_stages(verts, faces, cams, target, repeat: int) -> dict:
    """Median seconds of each stage of a numba iteration, timed alone (their sum is about the
    iteration): z-buffer, vertex normals, fused shading forward / backward, antialias + L1
    forward / backward."""
    import torch

    from core.render import numba_path as NP
    from core.render import rasterize
    from core.render.numba_geometry import vertex_normals_numba

    t = lambda fn: C.median_time(fn, repeat=repeat, warmup=1)  # noqa: E731
    r = rasterize(verts, faces, cams, backend="numba")
    vn = vertex_normals_numba(verts, faces).detach().requires_grad_()
    img = NP._Shade.apply(verts, vn, faces, r.mvp, r.tri_id, 0)
    ones = torch.ones_like(img)
    color = img.detach().requires_grad_()
    loss = NP._Antialias.apply(color, verts, faces, r, target)
    return {
        "raster_s": t(lambda: rasterize(verts, faces, cams, backend="numba")),
        "normals_s": t(lambda: vertex_normals_numba(verts, faces)),
        "shade_forward_s": t(lambda: NP._Shade.apply(verts, vn, faces, r.mvp, r.tri_id, 0)),
        "shade_backward_s": t(lambda: torch.autograd.grad(img, (verts, vn), ones, retain_graph=True)),
        "antialias_l1_forward_s": t(lambda: NP._Antialias.apply(color, verts, faces, r, target)),
        "antialias_l1_backward_s": t(lambda: torch.autograd.grad(loss, (color, verts), retain_graph=True)),
    }


def run_one(backend: str, device: str, triangles: int, res: int, views: int, repeat: int,
            profile: bool = False) -> dict:
    import torch

    from core.render.cameras import fibonacci_cameras
    from core.runtime.memory import keep_large_allocations
    from core.render import rasterize, reference_images, render_loss

    keep_large_allocations()  # as core.construct runs the renderer
    name = backend
    if backend == "torch-plain":  # the torch path without its fused CUDA kernels
        from core.render import triton_kernels

        triton_kernels.available = lambda device: False
        backend = "torch"

    v, f = first_use_order(*C.noisy_sphere(triangles))
    cams = fibonacci_cameras(views, width=res)
    faces = torch.tensor(f, device=device)
    target = reference_images(torch.tensor(v * 1.01, dtype=torch.float32, device=device), faces, cams,
                              backend=backend)
    verts = torch.tensor(v, dtype=torch.float32, device=device, requires_grad=True)
    sync = torch.cuda.synchronize if device == "cuda" else (lambda: None)

    def forward():
        r = rasterize(verts, faces, cams, backend=backend)
        loss = render_loss(verts, faces, cams, target, raster=r, backend=backend)
        sync()
        return loss

    def forward_backward():
        verts.grad = None
        forward().backward()
        sync()

    fwd = C.median_time(forward, repeat=repeat, warmup=1)
    fb = C.median_time(forward_backward, repeat=repeat, warmup=1)
    with PeakRSS() as mem:  # a separate run: the sampling thread would steal time from the timed ones
        forward_backward()
    covered = int((rasterize(verts, faces, cams, backend=backend).tri_id >= 0).sum())
    rec = {"backend": name, "device": device, "triangles": len(f), "resolution": res,
           "views": views, "forward_s": fwd, "forward_backward_s": fb, "peak_mb": mem.peak_mb,
           "covered_pixels": covered}
    if device == "cuda":
        rec["gpu_peak_mb"] = torch.cuda.max_memory_allocated() / 2 ** 20
    if profile and backend == "numba":
        rec["stages"] = numba_stages(verts, faces, cams, target, repeat)
    if profile and device == "cuda":
        rec["cuda_profile"] = cuda_profile(forward_backward)
    return rec


def cuda_profile(forward_backward, iterations: int = 3) -> str:
    """torch.profiler's table of the GPU kernels of ``iterations`` forward + backward runs."""
    from torch.profiler import ProfilerActivity, profile

    with profile(activities=[ProfilerActivity.CPU, ProfilerActivity.CUDA]) as prof:
        for _ in range(iterations):
            forward_backward()
    return prof.key_averages().table(sort_by="cuda_time_total", row_limit=30)


def main() -> None:
    p = C.parser(__doc__.split("\n\n")[0])
    p.add_argument("--quick", action="store_true", help="20k / 200k triangles at 256², 2 repeats")
    p.add_argument("--sizes", type=int, nargs="+", default=None, help="triangle counts")
    p.add_argument("--res", type=int, nargs="+", default=None, help="image sizes (square)")
    p.add_argument("--views", type=int, default=24)
    p.add_argument("--repeat", type=int, default=None, help="timed runs per figure (numba)")
    p.add_argument("--torch-repeat", type=int, default=None,
                   help="timed runs per figure for the slow plain-torch path (default: --repeat)")
    p.add_argument("--backends", nargs="+", default=None,
                   choices=["numba", "torch", "torch-plain"],
                   help="default: numba torch on the CPU, torch torch-plain on CUDA (torch-plain: "
                        "the torch path without its fused Triton kernels)")
    p.add_argument("--device", default="cpu", help="cpu or cuda (cuda runs the torch backends only)")
    p.add_argument("--profile", action="store_true",
                   help="also time each stage of the numba iteration alone (second table)")
    C.add_child_option(p)
    a = p.parse_args()
    from core.runtime.threads import set_threads

    threads = set_threads(a.threads or None)
    if a.child:
        print(json.dumps(run_one(**json.loads(a.child))))
        return
    sizes = a.sizes or ([20_000, 200_000] if a.quick else [20_000, 200_000, 1_000_000])
    res = a.res or ([256] if a.quick else [256, 512])
    repeat = a.repeat or (2 if a.quick else 3)
    backends = a.backends or (["torch", "torch-plain"] if a.device == "cuda" else ["numba", "torch"])
    records, rows = [], []
    for n in sizes:
        for r in res:
            row = {"triangles": n, "res": r, "views": a.views}
            for be in backends:
                rep = a.torch_repeat if (be == "torch" and a.torch_repeat) else repeat
                cfg = dict(backend=be, device=a.device, triangles=n, res=r, views=a.views, repeat=rep,
                           profile=a.profile)
                cmd = [sys.executable, __file__, "--child", json.dumps(cfg), "--threads", str(threads)]
                out = subprocess.run(cmd, capture_output=True, text=True)
                if out.returncode:
                    print(out.stderr[-3000:], file=sys.stderr)
                    raise SystemExit(f"child failed: {cfg}")
                rec = json.loads(out.stdout.strip().splitlines()[-1])
                records.append(rec)
                row[f"{be} fwd s"] = rec["forward_s"]
                row[f"{be} fwd+bwd s"] = rec["forward_backward_s"]
                row[f"{be} peak MB"] = rec["peak_mb"]
            if len(backends) == 2:
                row["speed-up fwd+bwd"] = row[f"{backends[1]} fwd+bwd s"] / row[f"{backends[0]} fwd+bwd s"]
            rows.append(row)
            print(f"done {n} @ {r}: " + ", ".join(f"{k} {C._fmt(v)}" for k, v in row.items()),
                  file=sys.stderr, flush=True)
    C.print_table(rows, title=f"render iteration, {a.views} views, {threads} threads "
                              "(rasterise + shade + antialias + L1, forward / forward+backward)")
    stages = [{"triangles": rec["triangles"], "res": rec["resolution"], **rec["stages"]}
              for rec in records if "stages" in rec]
    if stages:
        C.print_table(stages, title="numba iteration by stage, each timed alone (s)")
    for rec in records:
        if "cuda_profile" in rec:
            print(f"\n{rec['backend']}, {rec['triangles']} triangles at {rec['resolution']}², "
                  f"{rec['views']} views: GPU time by op over 3 forward + backward runs\n"
                  f"{rec['cuda_profile']}")
    C.write_json(a.json, records, threads=threads)



if __name__ == "__main__":
    main()
