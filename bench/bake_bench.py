"""Projection baking throughput: Embree two-way rays (+ fallback) vs nearest-point projection only.

References: procedural noisy spheres of ~200k and ~1M triangles and, where present,
igea_269k.ply from ../shared/meshes (normalised into the unit sphere). Points: 100k and 1M
samples on a coarse base (icosphere of radius 0.9, or a radius-1.05 sphere around igea) with
interpolated normals as directions, like micro-vertices. ``bake`` is
``core.spatial.bake.bake_displacements`` (warm: Embree scene cached; ``scene_s`` is the one-off build);
``nearest-only`` is the simplest alternative: the exact nearest surface point of every point
(cKDTree over centroids + point-triangle distance), including its index build, timed on
the first ``--nearest-points`` points and scaled linearly.

    python bench/bake_bench.py [--points 100000 1000000] [--json FILE]
"""
from __future__ import annotations

import numpy as np

from _common import MESHES, icosphere, median_time, noisy_sphere, parser, print_table, timed, write_json
from core.spatial import bake as bake_mod
from core.spatial.bake import SOURCE_NEAREST, bake_displacements, nearest_points
from core.mesh.trimesh import TriMesh
from core.mesh.normalization import unit_sphere_normalization
from core.runtime.threads import set_threads


def samples(base: TriMesh, n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    bc = rng.dirichlet([1, 1, 1], size=n)
    fid = rng.integers(0, base.n_faces, n)
    o = np.einsum("nk,nkj->nj", bc, base.vertices[base.faces[fid]])
    d = np.einsum("nk,nkj->nj", bc, base.vertex_normals[base.faces[fid]])
    return o, d


def references(faces: list[int]) -> list[tuple[str, TriMesh, float]]:
    out = []
    for m in faces:
        v, f = noisy_sphere(m)
        out.append((f"noisy_sphere_{len(f) // 1000}k", TriMesh(v, f), 0.9))
    p = MESHES / "igea_269k.ply"
    if p.exists():
        from core.io.mesh_files import read_mesh

        mesh = read_mesh(p)
        mesh = TriMesh(unit_sphere_normalization(mesh.vertices).apply(mesh.vertices), mesh.faces)
        out.append(("igea_269k", mesh, 1.05))
    else:
        print(f"igea_269k.ply not in {MESHES}: real-mesh row skipped")
    return out


def main() -> None:
    ap = parser(__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, nargs="+", default=[100_000, 1_000_000])
    ap.add_argument("--ref-faces", type=int, nargs="+", default=[200_000, 1_000_000])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--nearest-points", type=int, default=20_000,
                    help="nearest-only runs on this many points; its time is scaled to all points")
    args = ap.parse_args()
    threads = set_threads(args.threads)
    records = []
    for name, ref, base_r in references(args.ref_faces):
        bv, bf = icosphere(4, base_r)
        base = TriMesh(bv, bf)
        for n in args.points:
            o, d = samples(base, n)
            bake_mod._SCENE_CACHE.pop(ref, None)
            bake_mod._NEAREST_CACHE.pop(ref, None)
            first, res = timed(lambda: bake_displacements(o, d, ref, threads=threads))
            t = median_time(lambda: bake_displacements(o, d, ref, threads=threads),
                            repeat=args.repeat, warmup=0, max_seconds=30)
            scene = bake_mod._SCENE_CACHE[ref]
            scene_s, _ = timed(lambda: bake_mod._RayScene(ref))
            del scene
            bake_mod._NEAREST_CACHE.pop(ref, None)
            sub = min(n, args.nearest_points)  # the alternative is slow far from the surface
            t_near, _ = timed(lambda: nearest_points(o[:sub], ref, workers=threads))
            t_near *= n / sub
            fb = float(np.mean(res.source == SOURCE_NEAREST))
            for method, secs, extra in (("bake", t, {"scene_s": scene_s, "first_call_s": first,
                                                     "fallback_frac": fb}),
                                        ("nearest-only", t_near, {})):
                rec = {"reference": name, "ref_faces": ref.n_faces, "points": n, "method": method,
                       "seconds": secs, "Mpts_per_s": n / secs / 1e6, **extra}
                records.append(rec)
            print(f"  {name} n={n}: done", flush=True)
    print_table(records, ["reference", "ref_faces", "points", "method", "seconds", "Mpts_per_s",
                          "scene_s", "first_call_s", "fallback_frac"],
                title=f"\nprojection baking, threads={threads}")
    write_json(args.json, records, threads=threads, benchmark="bake_bench")


if __name__ == "__main__":
    main()
