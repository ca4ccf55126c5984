"""Scale: time per phase and peak memory of what a user gets (``batch.py`` with no overrides)
against input size, with the construction's own estimate beside the measurement.

Inputs of about 20k, 100k, 300k, 1M and 2M faces: the shared scans rocker_arm_20k, lucy_100k
and igea_269k as they are; igea subdivided once (each face into four at its edge midpoints)
and displaced along its normals by a procedural ripple (1.08M faces); that mesh and a moved
copy of it as one input (2.15M faces, two parts). Without ../shared/meshes, noisy spheres of
those sizes. The generated meshes go to ``--out`` and are never part of the repository.

Each input runs ``python batch.py --input MESH --output DIR --force`` in a process of its own;
its peak resident memory is the process's (``wait4``), the phase times are the run's report.
Writes a table, ``--json`` and a PNG plot (time and peak memory against faces, log-log).

    python bench/scale_bench.py [--sizes 20k 100k 300k 1M 2M] [--out DIR] [--json FILE]
        [--plot FILE]
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from _common import MESHES, ROOT, parser, print_table, write_json
from core.mesh import primitives
from core.construct.estimate import estimate
from core.mesh.trimesh import TriMesh
from core.io.mesh_files import read_mesh, write_ply
from core.settings.fields import preset

SIZES = {"20k": 20_000, "100k": 100_000, "300k": 300_000, "1M": 1_000_000, "2M": 2_000_000}
SHARED = {"20k": "rocker_arm_20k", "100k": "lucy_100k", "300k": "igea_269k"}


def subdivided(mesh: TriMesh) -> TriMesh:
    """Each face split into four at its edge midpoints (shared midpoints: still watertight)."""
    mid = mesh.vertices[mesh.edges].mean(1)
    a, b, c = mesh.faces.T
    ab, bc, ca = _edge_index(mesh, a, b), _edge_index(mesh, b, c), _edge_index(mesh, c, a)
    faces = np.concatenate([np.stack([a, ab, ca], 1), np.stack([ab, b, bc], 1),
                            np.stack([ca, bc, c], 1), np.stack([ab, bc, ca], 1)])
    return TriMesh(np.vstack([mesh.vertices, mid]), faces)


def _edge_index(mesh: TriMesh, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Vertex index of the midpoint of edge (u, v) in :func:`subdivided`'s vertex array."""
    edges = np.sort(mesh.edges, axis=1)
    key = edges[:, 0] * mesh.n_vertices + edges[:, 1]
    order = np.argsort(key)
    want = np.minimum(u, v) * mesh.n_vertices + np.maximum(u, v)
    return mesh.n_vertices + order[np.searchsorted(key[order], want)]


def rippled(mesh: TriMesh, amplitude: float) -> TriMesh:
    """Vertices moved along their normals by a sum of sines of the position."""
    p = mesh.vertices / mesh.bbox_diagonal
    h = np.sin(40 * p[:, 0]) * np.sin(37 * p[:, 1]) + 0.5 * np.sin(90 * p[:, 2] + 3 * p[:, 0])
    return mesh.with_vertices(mesh.vertices + amplitude * mesh.bbox_diagonal * h[:, None]
                              * mesh.vertex_normals)


def make_input(size: str, out: Path) -> Path:
    path = out / f"scale_{size}.ply"
    if path.exists():
        return path
    if MESHES.exists():
        if size in SHARED:
            return MESHES / f"{SHARED[size]}.ply"
        big = rippled(subdivided(read_mesh(MESHES / "igea_269k.ply")), 5e-4)
        if size == "2M":
            shift = np.array([1.2 * np.ptp(big.vertices[:, 0]), 0.0, 0.0])
            big = TriMesh(np.vstack([big.vertices, big.vertices + shift]),
                          np.vstack([big.faces, big.faces + big.n_vertices]))
    else:
        big = TriMesh(*primitives.noisy_sphere(SIZES[size], amplitude=0.05, seed=3))
    write_ply(path, big.vertices, big.faces)
    return path


def run_batch(mesh: Path, out: Path) -> dict:
    """batch.py on one input in a process of its own: wall time, peak RSS, the run's report."""
    cmd = [sys.executable, str(ROOT / "batch.py"), "--input", str(mesh), "--output", str(out),
           "--force"]
    t0 = time.perf_counter()
    with open(out / "batch.log", "w") as log:
        p = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, cwd=ROOT)
        _, status, usage = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
    if os.waitstatus_to_exitcode(status) != 0:
        raise RuntimeError(f"batch.py failed on {mesh.name}: see {out / 'batch.log'}")
    report = json.loads((out / f"{mesh.stem}.report.json").read_text())
    metrics = json.loads((out / f"{mesh.stem}.metrics.json").read_text())["metrics"]
    return {"wall_s": wall, "peak_mb": usage.ru_maxrss / 1024, "phases": report["timings"],
            "micro_triangles": metrics["micro_triangles"], "psnr": metrics["psnr"],
            "base_faces": metrics["base_faces"], "reference_faces": metrics["reference_faces"]}


def plot(records: list[dict], path: Path) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 3.8), dpi=110)
    FigureCanvasAgg(fig)
    faces = [r["reference_faces"] for r in records]
    for i, (key, est, label) in enumerate((("wall_s", "estimate_s", "time (s)"),
                                           ("peak_mb", "estimate_mb", "peak memory (MB)"))):
        ax = fig.add_subplot(1, 2, i + 1)
        ax.loglog(faces, [r[key] for r in records], "o-", label="measured")
        ax.loglog(faces, [r[est] for r in records], "s--", label="estimated before the run")
        ax.set_xlabel("input faces")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    fig.suptitle("batch.py, default preset, 2x input faces micro-triangles")
    fig.tight_layout()
    fig.savefig(path)


def main() -> None:
    ap = parser(__doc__.splitlines()[0])
    ap.add_argument("--sizes", nargs="+", default=list(SIZES), choices=list(SIZES))
    ap.add_argument("--out", default="/tmp/micromesh_scale_bench")
    ap.add_argument("--plot", default=None, help="PNG path (default: OUT/scale.png)")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    records = []
    for size in args.sizes:
        mesh = make_input(size, out)
        faces = read_mesh(mesh).n_faces
        guess = estimate(faces, preset("default"))
        run_dir = out / size
        run_dir.mkdir(exist_ok=True)
        rec = {"size": size, "input": mesh.name, **run_batch(mesh, run_dir),
               "estimate_s": guess.seconds, "estimate_mb": guess.peak_bytes / 2 ** 20}
        rec["time_ratio"] = rec["wall_s"] / rec["estimate_s"]
        rec["memory_ratio"] = rec["peak_mb"] / rec["estimate_mb"]
        records.append(rec)
        print({k: v for k, v in rec.items() if k != "phases"}, flush=True)
        write_json(args.json, records, benchmark="scale_bench")
    phases = sorted({k for r in records for k in r["phases"]})
    rows = [{**{k: v for k, v in r.items() if k != "phases"},
             **{p: r["phases"].get(p, 0.0) for p in phases}} for r in records]
    print_table(rows, ["size", "reference_faces", "base_faces", "micro_triangles", "wall_s",
                       "estimate_s", "peak_mb", "estimate_mb", "psnr"] + phases,
                title="batch.py (default preset) against input size")
    plot(records, Path(args.plot) if args.plot else out / "scale.png")


if __name__ == "__main__":
    main()
