"""The least-squares fit's solve (``core.fit``): Jacobi-preconditioned CG from the current
displacements (what the fit uses) against scipy's sparse LU (``spsolve``, the simplest
alternative), on the same normal equations.

A noisy sphere of about four reference faces per micro-triangle; a micro-mesh on an icosphere
base at uniform levels, its displacements baked by projection (as a construction's are close
to the answer when the fit starts). Per size: samples, unknowns, assembling the system (closest
points, then the sums per micro-triangle the fit uses, and beside them the simplest way: the
sparse products of its rows; the same two with the base vertices as unknowns too, the base
round's system), each solve, the CG iterations and the relative difference of
the solutions; then the whole fit (two rounds) as a construction runs it.

    python bench/fit_bench.py [--levels 3 4 5] [--json FILE]
"""
from __future__ import annotations

import numpy as np
import scipy.sparse.linalg as spla

from _common import parser, print_table, timed, write_json
from core.mesh import primitives
from core.spatial.bake import bake_displacements
from core.fit import fit_displacements, fit_samples, normal_equations, solve_normal_equations
from core.mesh.trimesh import TriMesh
from core.micro.micromesh import MicroMesh
from core.runtime.threads import set_threads


def case(level: int) -> tuple[TriMesh, MicroMesh]:
    bv, bf = primitives.icosphere(4)                          # 1280 base faces
    mm = MicroMesh.flat(TriMesh(bv, bf), np.full(len(bf), level))
    v, f = primitives.noisy_sphere(4 * len(bf) * 4 ** level, amplitude=0.03, seed=1)
    ref = TriMesh(v, f)
    d = bake_displacements(mm.micro_vertex_base_positions(), mm.micro_vertex_directions(), ref,
                           max_distance=0.5).displacement
    return ref, mm.with_displacements(d)


def main() -> None:
    ap = parser(__doc__.splitlines()[0])
    ap.add_argument("--levels", type=int, nargs="+", default=[3, 4, 5])
    args = ap.parse_args()
    threads = set_threads(args.threads)
    records = []
    for level in args.levels:
        ref, mm = case(level)
        samples = fit_samples(mm, ref)
        t_asm, (M, b) = timed(lambda: normal_equations(mm, mm.displacements, samples, 1e-3, 0.1))
        t_rows, (Mr, _) = timed(lambda: normal_equations(mm, mm.displacements, samples, 1e-3,
                                                         0.1, by_rows=True))
        assert abs(M - Mr).max() < 1e-12 * abs(M).max(), "the two assemblies differ"
        t_joint, (Mj, _) = timed(lambda: normal_equations(mm, mm.displacements, samples, 1e-3,
                                                          0.1, base_stiffness=1e-3))
        t_joint_rows, (Mjr, _) = timed(lambda: normal_equations(
            mm, mm.displacements, samples, 1e-3, 0.1, base_stiffness=1e-3, by_rows=True))
        assert abs(Mj - Mjr).max() < 1e-12 * abs(Mjr).max(), "the two joint assemblies differ"
        del Mj, Mjr
        t_lu, x_lu = timed(lambda: spla.spsolve(M.tocsc(), b))
        iters = []
        t_cg, x_cg = timed(lambda: solve_normal_equations(M, b, mm.displacements,
                                                          callback=lambda _: iters.append(1)))
        t_fit, _ = timed(lambda: fit_displacements(mm, ref, samples=samples))
        rec = {"level": level, "micro_vertices": mm.n_vertices, "samples": len(samples),
               "assemble_s": t_asm, "assemble_rows_s": t_rows, "assemble_joint_s": t_joint,
               "assemble_joint_rows_s": t_joint_rows, "superlu_s": t_lu, "cg_s": t_cg,
               "cg_iterations": len(iters),
               "speed_up": t_lu / t_cg,
               "relative_difference": float(np.linalg.norm(x_cg - x_lu) / np.linalg.norm(x_lu)),
               "fit_s": t_fit}
        records.append(rec)
        print(f"  level {level}: done", flush=True)
    print_table(records, list(records[0]), title=f"\nfit solve, threads={threads}")
    write_json(args.json, records, threads=threads, benchmark="fit_bench")


if __name__ == "__main__":
    main()
