"""Exact closest point on a mesh: the numba BVH (``core.spatial.closest``) vs the previous method.

References: a procedural noisy sphere of ~300k triangles and, where present, igea_269k.ply
from ../shared/meshes; both normalised into the unit sphere. Points: ``near`` = random surface
points (area-weighted) moved along their face normal by N(0, 0.01); ``far`` = moved by ±0.3
(a third of the radius). ``bvh`` is ``ClosestPointIndex.query`` (one warm call: kernels
loaded and index built before; ``build_s`` is the one-off build). ``ckdtree`` is the simplest alternative and what
``core.spatial.bake.nearest_points`` did before: a cKDTree over centroids, k nearest centroids + the
exact point–triangle distance, with a certificate that escalates k (then a ball query) until
exact. It is timed on the first ``--baseline-points`` points (index build included) and scaled
linearly to n (column ``scaled``); its distances are checked against the BVH's on that subset.
The first call of the process loads (or, with an empty cache, compiles) the numba kernels:
``jit_s`` is reported on its own.

    python bench/closest_bench.py [--points 100000 1000000] [--threads N] [--json FILE]
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from _common import MESHES, noisy_sphere, parser, print_table, timed, write_json
from core.spatial.closest import ClosestPointIndex
from core.mesh.trimesh import TriMesh
from core.mesh.normalization import unit_sphere_normalization
from core.runtime.threads import set_threads


def closest_points_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray,
                                c: np.ndarray) -> np.ndarray:
    """Exact closest point on triangle (a, b, c) to p, row-wise (Voronoi-region tests)."""
    ab, ac, ap = b - a, c - a, p - a
    d1 = np.einsum("ij,ij->i", ab, ap)
    d2 = np.einsum("ij,ij->i", ac, ap)
    bp = p - b
    d3 = np.einsum("ij,ij->i", ab, bp)
    d4 = np.einsum("ij,ij->i", ac, bp)
    cp = p - c
    d5 = np.einsum("ij,ij->i", ab, cp)
    d6 = np.einsum("ij,ij->i", ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2

    def ratio(num, den):
        ok = den != 0
        return np.where(ok, num / np.where(ok, den, 1.0), 0.0)

    denom = va + vb + vc
    v_in = ratio(vb, denom)
    w_in = ratio(vc, denom)
    out = a + ab * v_in[:, None] + ac * w_in[:, None]                      # face interior
    w_bc = np.clip(ratio(d4 - d3, (d4 - d3) + (d5 - d6)), 0, 1)
    m = (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0)
    out = np.where(m[:, None], b + (c - b) * w_bc[:, None], out)           # edge bc
    w_ac = np.clip(ratio(d2, d2 - d6), 0, 1)
    m = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
    out = np.where(m[:, None], a + ac * w_ac[:, None], out)                # edge ac
    m = (d6 >= 0) & (d5 <= d6)
    out = np.where(m[:, None], c, out)                                     # vertex c
    v_ab = np.clip(ratio(d1, d1 - d3), 0, 1)
    m = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
    out = np.where(m[:, None], a + ab * v_ab[:, None], out)                # edge ab
    m = (d3 >= 0) & (d4 <= d3)
    out = np.where(m[:, None], b, out)                                     # vertex b
    m = (d1 <= 0) & (d2 <= 0)
    out = np.where(m[:, None], a, out)                                     # vertex a
    return out


class CKDTreeCandidates:
    """The previous exact nearest-point method (kept here as the benchmark's baseline).

    A triangle's distance to q is at least |q − centroid| − R (R: the largest centroid-to-vertex
    distance), so once the k-th centroid is farther than best + R no unseen triangle can win;
    points without that certificate retry with more candidates, then with a ball query.
    """

    def __init__(self, mesh: TriMesh) -> None:
        self.tri = mesh.vertices[mesh.faces]
        self.centroids = self.tri.mean(axis=1)
        self.radius = float(np.linalg.norm(self.tri - self.centroids[:, None], axis=2).max())
        self.tree = cKDTree(self.centroids)

    def _eval(self, q, cand):
        n, k = cand.shape
        valid = cand < len(self.tri)
        cf = np.where(valid, cand, 0).reshape(-1)
        qq = np.repeat(q, k, axis=0)
        t = self.tri[cf]
        cp = closest_points_on_triangles(qq, t[:, 0], t[:, 1], t[:, 2])
        d2 = np.einsum("ij,ij->i", cp - qq, cp - qq).reshape(n, k)
        d2[~valid] = np.inf
        j = np.argmin(d2, axis=1)
        rows = np.arange(n)
        return cp.reshape(n, k, 3)[rows, j], cand[rows, j], np.sqrt(d2[rows, j])

    def _ball(self, q, best, workers, budget=1 << 21):
        m = len(self.tri)
        counts = self.tree.query_ball_point(q, best + self.radius + 1e-12, workers=workers,
                                            return_length=True)
        p, f, d = np.empty((len(q), 3)), np.empty(len(q), np.int64), np.empty(len(q))
        start = 0
        while start < len(q):
            csum = np.cumsum(counts[start:])
            stop = start + max(1, int(np.searchsorted(csum, budget, side="right")))
            balls = self.tree.query_ball_point(q[start:stop], best[start:stop] + self.radius + 1e-12,
                                               workers=workers)
            lens = np.array([len(b) for b in balls])
            cand = np.full((stop - start, int(lens.max())), m, np.int64)
            cand[np.arange(cand.shape[1])[None, :] < lens[:, None]] = np.concatenate(balls)
            p[start:stop], f[start:stop], d[start:stop] = self._eval(q[start:stop], cand)
            start = stop
        return p, f, d

    def query(self, q, k=8, chunk=1 << 19, workers=1):
        n, m = len(q), len(self.tri)
        point, face, dist = np.empty((n, 3)), np.empty(n, np.int64), np.empty(n)
        k = min(k, m)
        step = max(1, chunk // k)
        for s in range(0, n, step):
            qs = q[s:s + step]
            dk, cand = self.tree.query(qs, k=k, workers=workers)
            dk, cand = dk.reshape(len(qs), -1), cand.reshape(len(qs), -1)
            p, f, d = self._eval(qs, cand)
            todo = np.flatnonzero((dk[:, -1] - self.radius < d) & (k < m))
            kk = k
            while len(todo) and kk < min(512, m):
                kk = min(4 * kk, m)
                dk2, cand2 = self.tree.query(qs[todo], k=kk, workers=workers)
                p2, f2, d2 = self._eval(qs[todo], cand2)
                p[todo], f[todo], d[todo] = p2, f2, d2
                todo = todo[(dk2[:, -1] - self.radius < d2) & (kk < m)]
            if len(todo):
                p[todo], f[todo], d[todo] = self._ball(qs[todo], d[todo], workers)
            point[s:s + step], face[s:s + step], dist[s:s + step] = p, f, d
        return point, face, dist


def references(n_faces: int) -> list[tuple[str, TriMesh]]:
    v, f = noisy_sphere(n_faces)
    out = [(f"noisy_sphere_{len(f) // 1000}k", TriMesh(unit_sphere_normalization(v).apply(v), f))]
    p = MESHES / "igea_269k.ply"
    if p.exists():
        from core.io.mesh_files import read_mesh

        m = read_mesh(p)
        out.append(("igea_269k", TriMesh(unit_sphere_normalization(m.vertices).apply(m.vertices),
                                         m.faces)))
    else:
        print(f"({p} absent: igea skipped)")
    return out


def surface_points(mesh: TriMesh, n: int, offset: str, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    area = mesh.face_areas
    fid = rng.choice(mesh.n_faces, n, p=area / area.sum())
    bc = rng.dirichlet([1, 1, 1], size=n)
    p = np.einsum("nk,nkj->nj", bc, mesh.vertices[mesh.faces[fid]])
    if offset == "near":
        h = rng.normal(0, 0.01, n)
    else:
        h = 0.3 * rng.choice([-1.0, 1.0], n)
    return p + h[:, None] * mesh.face_normals[fid]


def main() -> None:
    ap = parser(__doc__.split("\n")[0])
    ap.add_argument("--points", type=int, nargs="+", default=[100_000, 1_000_000])
    ap.add_argument("--faces", type=int, default=300_000, help="noisy sphere triangle count")
    ap.add_argument("--baseline-points", type=int, default=2_000,
                    help="the cKDTree baseline runs on this many points; its time is scaled to n")
    args = ap.parse_args()
    threads = set_threads(args.threads)

    jit_s, _ = timed(lambda: ClosestPointIndex(np.eye(3), np.array([[0, 1, 2]])).query(np.zeros((1, 3))))

    rows = []
    for name, mesh in references(args.faces):
        build_s, idx = timed(lambda: ClosestPointIndex(mesh.vertices, mesh.faces))
        for offset in ("near", "far"):
            for n in args.points:
                q = surface_points(mesh, n, offset)
                t_bvh, (_, _, d_bvh) = timed(lambda: idx.query(q))  # one warm call
                sub = min(n, args.baseline_points)
                t_old, (_, _, d_old) = timed(lambda: CKDTreeCandidates(mesh).query(q[:sub], workers=threads))
                err = float(np.abs(d_old - d_bvh[:sub]).max())
                base = {"mesh": name, "faces": mesh.n_faces, "points": offset, "n": n}
                rows.append({**base, "method": "bvh", "seconds": t_bvh, "us_per_point": 1e6 * t_bvh / n,
                             "build_s": build_s, "measured_n": n, "scaled": "no",
                             "mean_dist": float(d_bvh.mean())})
                rows.append({**base, "method": "ckdtree", "seconds": t_old * n / sub,
                             "us_per_point": 1e6 * t_old / sub, "measured_n": sub,
                             "scaled": "yes" if sub < n else "no", "max_abs_diff": err})
                rows[-2]["speedup"] = rows[-1]["seconds"] / t_bvh
    print_table(rows, ["mesh", "faces", "points", "n", "method", "seconds", "us_per_point",
                       "speedup", "build_s", "measured_n", "scaled", "max_abs_diff"],
                title=f"closest point, {threads} thread(s); jit (first call, cache load or compile) "
                      f"{jit_s:.2f} s")
    write_json(args.json, rows, threads=threads, jit_s=jit_s)


if __name__ == "__main__":
    main()
