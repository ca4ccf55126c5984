"""Screened solve (I + λL) x = b: scipy SuperLU vs torch Jacobi-PCG (cold and warm-started).

Meshes: icospheres of about 10k / 100k / 1M vertices, uniform Laplacian, λ = 9 and 19.
Per method: the one-off setup (factorisation or building the torch CSR matrix) and the median
solve time for 1 and 3 right-hand-side columns (float32 torch tensors, as the optimiser uses).
"warm" CG solves start from the previous solution after the right-hand side moved by 1% (an
optimiser step); "cold" CG starts from zero. ``splu-colamd`` is scipy's default ordering,
the simplest alternative; ``splu`` is what ``ScreenedSolver`` uses (symmetric mode, MMD(A+Aᵀ)).

    python bench/solver_bench.py [--sizes 10000 100000 1000000] [--json FILE]
"""
from __future__ import annotations

import numpy as np
import scipy.sparse.linalg as spla

from _common import icosphere_with_vertices, median_time, parser, print_table, timed, write_json
from core.solvers.laplacian import uniform_laplacian
from core.solvers.screened import ScreenedSolver
from core.runtime.threads import set_threads


def main() -> None:
    ap = parser(__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000, 1_000_000])
    ap.add_argument("--lams", type=float, nargs="+", default=[9.0, 19.0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--methods", nargs="+", default=["splu", "splu-colamd", "cg"],
                    help="splu-colamd takes many minutes at 1M vertices")
    args = ap.parse_args()
    threads = set_threads(args.threads)
    import torch

    rng = np.random.default_rng(0)
    records = []
    for size in args.sizes:
        v, f = icosphere_with_vertices(size)
        n = len(v)
        L = uniform_laplacian(n, f)
        # Smooth-ish geometry-like right-hand sides.
        b3 = v + 0.05 * rng.normal(size=v.shape)
        for lam in args.lams:
            rows = []
            ref = None
            for method in args.methods:
                if method == "splu-colamd":
                    M = ScreenedSolver(L, lam, method="cg").M.tocsc()
                    setup, lu = timed(lambda: spla.splu(M))
                    solve = {k: (lambda k=k: lu.solve(np.asfortranarray(b3[:, :k]))) for k in (1, 3)}
                    fill = lu.L.nnz + lu.U.nnz
                else:
                    setup, S = timed(lambda: ScreenedSolver(L, lam, method=method))
                    if method == "cg":
                        t0, _ = timed(lambda: S._torch_matrix(torch.device("cpu"), torch.float32))
                        setup += t0
                    fill = (S._lu.L.nnz + S._lu.U.nnz) if method == "splu" else S.M.nnz
                    solve = {k: (lambda k=k: S.solve_torch(torch.from_numpy(b3[:, :k].astype(np.float32))))
                             for k in (1, 3)}
                rec = {"n": n, "lam": lam, "method": method, "setup_s": setup, "nnz_factor": fill}
                for k in (1, 3):
                    if method == "cg":
                        S._warm.clear()
                        rec[f"solve{k}_cold_s"] = median_time(lambda: (S._warm.clear(), solve[k]()),
                                                              repeat=args.repeat, warmup=0,
                                                              max_seconds=20)
                        rec[f"iters{k}_cold"] = S.last_iterations
                        base = b3[:, :k].astype(np.float32)
                        S._warm.clear()
                        S.solve_torch(torch.from_numpy(base))

                        def warm_step(base=base):
                            step = 0.01 * base.std() * rng.normal(size=base.shape).astype(np.float32)
                            base += step
                            return S.solve_torch(torch.from_numpy(base))

                        rec[f"solve{k}_warm_s"] = median_time(warm_step, repeat=args.repeat, warmup=1,
                                                              max_seconds=20)
                        rec[f"iters{k}_warm"] = S.last_iterations
                        x = S.solve_torch(torch.from_numpy(b3[:, :k].astype(np.float32))).numpy()
                    else:
                        rec[f"solve{k}_s"] = median_time(solve[k], repeat=args.repeat, warmup=1,
                                                         max_seconds=20)
                        x = np.asarray(solve[k]())
                    if ref is None or ref.shape[1] < k:
                        ref = np.asarray(x, dtype=np.float64).reshape(n, -1)
                    rec[f"relerr{k}"] = float(np.linalg.norm(x.reshape(n, -1) - ref[:, :k])
                                              / np.linalg.norm(ref[:, :k]))
                rows.append(rec)
                records.append(rec)
                print(f"  n={n} lam={lam:g} {method}: done", flush=True)
            print_table(rows, ["n", "lam", "method", "setup_s", "nnz_factor", "solve1_s", "solve3_s",
                               "solve1_cold_s", "iters1_cold", "solve1_warm_s", "iters1_warm",
                               "solve3_cold_s", "solve3_warm_s", "iters3_warm", "relerr1"],
                        title=f"\nscreened solve, icosphere n={n}, lam={lam:g}, threads={threads}")
    write_json(args.json, records, threads=threads, benchmark="solver_bench")


if __name__ == "__main__":
    main()
