"""Construction quality and speed: the optimiser's presets against the staged baseline.

For each mesh from ../shared/meshes: a base of about 1/32 of the input faces (Blender's
Decimate modifier, cached under $MICROMESH_CACHE or /tmp/micromesh_bench_cache), a budget of
about twice the input faces in micro-triangles. Rows:
- ``staged``: uniform level 3 (64 micro-triangles per base face = 2x input), area-weighted
  normals, projection baking, tight bounds, no optimisation (the simplest alternative);
- ``<preset>``: ``core.construct.construct`` with that preset, the same base and the same
  micro-triangle budget (levels up to 4 where the adaptive LOD spends the budget).
Metrics are the method's §7 (24 Fibonacci views at 512², unit-sphere frame); ``time_s`` is the
construction's wall time (reference images, optimisation, LOD, bounds; evaluation excluded).

    python bench/construct_bench.py [--meshes rocker_arm_20k ...] [--presets default fast]
        [--set key=value ...] [--ablations] [--json FILE]
"""
from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

import numpy as np

from _common import MESHES, ROOT, parser, print_table
from core.construct import construct, staged_baseline
from core.mesh import TriMesh
from core.meshio import read_mesh
from core.settings import apply_overrides, preset
from core.threads import set_threads

DEFAULT_MESHES = ["rocker_arm_20k", "fertility_60k", "bunny_69k", "armadillo_100k", "igea_269k"]
CACHE = Path(os.environ.get("MICROMESH_CACHE", "/tmp/micromesh_bench_cache"))

ABLATIONS = {  # the paper's Tab. 2 rows (supplement §3) on the paper preset
    "full": [],
    "no_reparam": ["reparameterize=false", "laplacian_weight=1.0"],
    "no_progressive": ["progressive=false"],   # uniform finest level within the budget
    "no_L_iso": ["w_iso=0"],
    "no_L_sv": ["w_sv=0"],
    "chamfer_lod": ["lod_criterion=chamfer"],
    "interpolate_init": ["init_new_levels=interpolate"],  # paper's init instead of baking
    "init_zero": ["init_bake=false", "init_new_levels=interpolate"],  # no baking at all
}


def base_mesh(name: str, ref: TriMesh, target: int) -> tuple[TriMesh, str]:
    """The decimated base (cached); Blender's Decimate where bpy imports."""
    CACHE.mkdir(parents=True, exist_ok=True)
    path = CACHE / f"{name}_{target}.npz"
    if path.exists():
        z = np.load(path)
        return TriMesh(z["v"], z["f"]), str(z["how"])
    sys.path.insert(0, str(ROOT))
    import micromesh_path
    micromesh_path.ensure_package()
    from micromesh.operators.bl_mesh import decimate
    v, f = decimate(ref.vertices, ref.faces, target_faces=target)
    np.savez(path, v=v, f=f, how="blender_decimate")
    return TriMesh(v, f), "blender_decimate"


def record(mesh: str, method: str, m: dict) -> dict:
    return {"mesh": mesh, "method": method, "psnr": round(m["psnr"], 3),
            "shell_volume": round(m["shell_volume"], 5),
            "geom_err": float(f"{m.get('geom_err', float('nan')):.4g}"),
            "iso_base": round(m["iso_base"], 4), "bytes": int(m["bytes"]),
            "micro_tris": int(m["micro_triangles"]), "time_s": round(m["time_s"], 1),
            "cracks": int(m["cracks"])}


def main() -> None:
    p = parser(__doc__.splitlines()[0])
    p.add_argument("--meshes", nargs="+", default=DEFAULT_MESHES)
    p.add_argument("--presets", nargs="+", default=["default"])
    p.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE",
                   help="settings overrides applied to every preset row")
    p.add_argument("--ablations", action="store_true",
                   help="also run the paper preset's ablation rows (slow)")
    p.add_argument("--ablation-preset", default="paper")
    p.add_argument("--no-baseline", action="store_true")
    args = p.parse_args()
    set_threads(args.threads)
    rows = []

    def flush():
        if args.json:
            Path(args.json).write_text(json.dumps(rows, indent=1))

    for name in args.meshes:
        path = MESHES / f"{name}.ply"
        if not path.exists():
            print(f"skip {name}: {path} not found")
            continue
        ref = read_mesh(path)
        base, how = base_mesh(name, ref, max(4, ref.n_faces // 32))
        budget = 2 * ref.n_faces
        print(f"{name}: {ref.n_faces} faces, base {base.n_faces} faces ({how}), "
              f"budget {budget} micro-triangles", flush=True)
        if not args.no_baseline:
            b = staged_baseline(ref, base, 3, preset("default"))
            rows.append(record(name, "staged", b.metrics))
            print(rows[-1], flush=True)
            flush()
        runs = [(pr, list(args.set)) for pr in args.presets]
        if args.ablations:
            runs += [(f"{args.ablation_preset}:{k}", list(args.set) + v) for k, v in ABLATIONS.items()]
        for label, overrides in runs:
            pname = label.split(":")[0]
            s = apply_overrides(preset(pname), [f"budget_micro_triangles={budget}"] + overrides)
            t0 = time.perf_counter()
            r = construct(ref, base, None, s)
            rec = record(name, label, r.metrics)
            rec["levels"] = r.metrics["levels_hist"]
            rec["phases"] = {k: round(v, 1) for k, v in r.timings.items()}
            rows.append(rec)
            print(rec, f"(wall incl. metrics {time.perf_counter() - t0:.0f}s)", flush=True)
            flush()
    cols = ["mesh", "method", "psnr", "shell_volume", "geom_err", "iso_base", "bytes",
            "micro_tris", "time_s", "cracks"]
    print_table(rows, cols, title="construction: presets vs staged baseline")
    by = {}
    for r in rows:
        by.setdefault(r["method"], {})[r["mesh"]] = r["psnr"]
    for meth, d in by.items():
        if meth == "staged":
            continue
        common = [m for m in d if m in by.get("staged", {})]
        if common:
            gain = np.mean([d[m] - by["staged"][m] for m in common])
            print(f"{meth}: mean PSNR gain over staged on {len(common)} meshes: {gain:+.2f} dB")
    flush()


if __name__ == "__main__":
    main()
