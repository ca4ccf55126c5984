"""Base-mesh building: the base a construction builds (``core.base.base_for`` with the
default preset, ``--set`` overrides on it) next to Blender's Decimate modifier at the same
face count (the simplest alternative; ``--no-blender`` leaves it out) and micromesh-tools'
bases (``../shared/baselines``, read from the judge's cached JSON when given).

Per mesh of ../shared/meshes (``--generated``: also or instead those of
``bench/generated_meshes.py``, as ``batch.py`` reads them): faces, time, base isotropy, the
mean and max distance from the reference vertices to the base (over the bounding-box
diagonal), the RMS bound the decimation ended with and whether components, holes and genus are
the input's.

    python bench/base_bench.py [--meshes NAME ...] [--generated [NAME ...]]
        [--set KEY=VALUE ...] [--no-blender] [--judged DIR] [--json FILE]
"""
from __future__ import annotations

import json
import time
from pathlib import Path


from _common import MESHES, ROOT, parser, print_table, write_json
from generated_meshes import GENERATED, write as write_generated
from core.base import topology
from core.base.build import base_for, welded
from core.settings import preset
from core.settings.overrides import apply_overrides
from core.spatial.closest import ClosestPointIndex
from core.mesh.trimesh import TriMesh
from core.mesh.normalization import unit_sphere_normalization
from core.io.mesh_files import read_mesh
from core.micro.metrics import isotropy


def measure(ref: TriMesh, base: TriMesh) -> dict:
    """Distances from the reference's vertices to the base (over the diagonal), isotropy and
    topology kept, in the reference's unit frame."""
    norm = unit_sphere_normalization(ref.vertices)
    r = welded(TriMesh(norm.apply(ref.vertices), ref.faces))
    b = TriMesh(norm.apply(base.vertices), base.faces)
    _, _, d = ClosestPointIndex(b.vertices, b.faces).query(r.vertices)
    d /= r.bbox_diagonal
    w = r.vertex_areas
    return {"faces": b.n_faces, "iso": round(isotropy(b.vertices, b.faces), 3),
            "err_mean": float(f"{(d * w).sum() / w.sum():.3g}"), "err_max": float(f"{d.max():.3g}"),
            "topology": topology(r) == topology(welded(b))}


def blender_decimate(ref: TriMesh, faces: int) -> tuple[TriMesh, float]:
    import sys

    sys.path.insert(0, str(ROOT))
    import micromesh_path

    micromesh_path.ensure_package()
    from micromesh.operators.bl_decimate import decimate

    t0 = time.perf_counter()
    v, f = decimate(ref.vertices, ref.faces, target_faces=faces)
    return TriMesh(v, f), time.perf_counter() - t0


def main() -> None:
    p = parser(__doc__.splitlines()[0])
    p.add_argument("--meshes", nargs="+", default=None)
    p.add_argument("--generated", nargs="*", default=None, metavar="NAME",
                   help="the meshes of bench/generated_meshes.py (all, or those named)")
    p.add_argument("--set", nargs="+", default=[], metavar="KEY=VALUE",
                   help="settings overrides on the default preset")
    p.add_argument("--no-blender", action="store_true", help="leave out Blender's Decimate")
    p.add_argument("--out", default="/tmp/mm_base_bench", help="where generated meshes go")
    p.add_argument("--judged", default="/tmp/mm_bench_full",
                   help="folder with the judge's theirs_NAME.json (bench/construct_bench.py)")
    args = p.parse_args()
    settings = apply_overrides(preset("default"), args.set)
    paths = []
    if args.meshes is not None or args.generated is None:
        paths += [MESHES / f"{n}.ply" for n in
                  (args.meshes or sorted(f.stem for f in MESHES.glob("*.ply")))]
    if args.generated is not None:
        paths += [write_generated(n, Path(args.out)) for n in args.generated or GENERATED]
    rows = []
    for path in paths:
        name = path.stem
        ref = read_mesh(path)
        first = len(rows)
        t0 = time.perf_counter()
        ours = base_for(ref, settings)
        t_ours = time.perf_counter() - t0
        rows.append({"mesh": name, "method": "core.base", **measure(ref, ours.mesh),
                     "rms_bound": ours.report["rms_bound"], "time_s": round(t_ours, 2)})
        if not args.no_blender:
            bl, t_bl = blender_decimate(ref, ours.mesh.n_faces)
            rows.append({"mesh": name, "method": "blender", **measure(ref, bl),
                         "time_s": round(t_bl, 2)})
        # construct_bench.py's cache: theirs_NAME_<hash of their file>.json (newest first)
        judged = sorted(Path(args.judged).glob(f"theirs_{name}_*.json"),
                        key=lambda f: f.stat().st_mtime, reverse=True)
        if judged:
            j = json.loads(judged[0].read_text())
            rows.append({"mesh": name, "method": "micromesh-tools",
                         "faces": j["counts"]["base_faces"],
                         "iso": round(j["isotropy"]["iso_base"], 3)})
        for r in rows[first:]:
            print(r, flush=True)
    print_table(rows, ["mesh", "method", "faces", "iso", "err_mean", "err_max", "rms_bound",
                       "topology", "time_s"],
                title="base meshes (error: reference vertices to the base / bbox diagonal)")
    write_json(args.json, rows)


if __name__ == "__main__":
    main()
