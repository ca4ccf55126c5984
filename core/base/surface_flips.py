"""Edge flips that lay the base closer to the reference (ours).

The collapses leave each quad of the base split along whichever diagonal they made. Where the
reference bends along the other diagonal (a fillet or a ridge running across the quad), the
base cuts through the bend: the reference strays far from both triangles, the micro-vertices'
values span a wide range around the quad's corners and the prismoid shell there is thick.
Flipping the edge (same vertices, same face count; an edge flip keeps the topology) lays the
base along the bend instead. An edge (x, y) with faces (x, y, a) and (y, x, b) becomes (a, b)
where
- the reference vertices nearest to the two faces lie closer to the flipped pair: their
  vertex-area-weighted distance falls by more than ``GAIN_SHARE``;
- the worse of the two triangles' quality 2r/R stays at or above the floor and falls by at
  most ``QUALITY_SLACK`` (with the floor alone they cost the bases up to 0.03 of
  isotropy: ``docs/results.md``);
- both new faces stay within ``FOLD_DEG`` of the quad's mean normal;
- the two faces wind alike, the edge (a, b) does not exist yet, and x and y keep at least
  three neighbours;
in rounds (the largest gains first, no two flips of a round on one face, at most
``ROUND_SHARE`` of the faces), until none is left or after ``ROUNDS`` rounds.
"""
from __future__ import annotations

import numpy as np

from ..spatial.closest import ClosestPointIndex
from ..mesh.trimesh import TriMesh
from ..micro.metrics import triangle_isotropy
from ..spatial.point_triangle import pair_distances

GAIN_SHARE = 0.1      # a flip must bring the quad's reference this much closer
QUALITY_SLACK = 0.2   # and may lower the worse triangle's 2r/R by at most this
FOLD_DEG = 30.0       # the new faces' normals within this angle of the quad's
ROUND_SHARE = 0.05    # at most this fraction of the faces flipped in one round
ROUNDS = 4
BLOCK = 500_000     # (point, quad) pairs measured at once


def surface_flips(base: TriMesh, reference: TriMesh, min_quality: float,
                  rounds: int = ROUNDS) -> tuple[TriMesh, int]:
    """``base`` with the edges flipped where the flipped pair of faces lies closer to
    ``reference`` (module docstring); ``min_quality``: the floor on 2r/R. Returns the mesh
    and the number of edges flipped."""
    points, weights = reference.vertices, reference.vertex_areas
    mesh, flips = base, 0
    for _ in range(rounds):
        _, face, dist = ClosestPointIndex(mesh.vertices, mesh.faces).query(points)
        quads = _quads(mesh)
        quads = quads[_allowed(mesh, quads, min_quality)]
        gain = _gains(mesh, quads, points, weights, face, dist)
        chosen = _independent(mesh, quads, gain, max(1, int(ROUND_SHARE * mesh.n_faces)))
        if len(chosen) == 0:
            break
        mesh = _flipped(mesh, quads[chosen])
        flips += len(chosen)
    return mesh, flips


def _quads(mesh: TriMesh) -> np.ndarray:
    """(k, 6) per interior two-face edge: its faces f1, f2 and the corners x, y, a, b, with
    f1 = (x, y, a) and f2 holding b opposite the edge."""
    e = np.nonzero((mesh.edge_face_count == 2) & (mesh.edge_faces >= 0).all(axis=1))[0]
    f1, f2 = mesh.edge_faces[e, 0], mesh.edge_faces[e, 1]
    u, o = mesh.edges[e, 0], mesh.edges[e, 1]
    rows = np.arange(len(e))
    F1, F2 = mesh.faces[f1], mesh.faces[f2]
    pa = np.argmax((F1 != u[:, None]) & (F1 != o[:, None]), axis=1)
    pb = np.argmax((F2 != u[:, None]) & (F2 != o[:, None]), axis=1)
    x, y, a = F1[rows, (pa + 1) % 3], F1[rows, (pa + 2) % 3], F1[rows, pa]
    return np.stack([f1, f2, x, y, a, F2[rows, pb]], axis=1)


def _allowed(mesh: TriMesh, q: np.ndarray, min_quality: float) -> np.ndarray:
    """(k,) which flips keep the winding, the shapes (floor and slack), the fold limit, a
    new edge and three neighbours at x and y."""
    V, F = mesh.vertices, mesh.faces
    f1, f2, x, y, a, b = q.T
    F2 = F[f2]
    pos = np.argmax(F2 == b[:, None], axis=1)
    rows = np.arange(len(q))
    winds = (F2[rows, (pos + 1) % 3] == y) & (F2[rows, (pos + 2) % 3] == x)
    new = np.concatenate([np.stack([x, b, a], 1), np.stack([b, y, a], 1)])
    q_new = triangle_isotropy(V, new)[0].reshape(2, -1).min(axis=0)
    q_face = triangle_isotropy(V, F)[0]
    q_old = np.minimum(q_face[f1], q_face[f2])
    shapes = (q_new >= min_quality) & (q_new >= q_old - QUALITY_SLACK)
    mean = mesh.face_normals[f1] + mesh.face_normals[f2]
    mean /= np.maximum(np.linalg.norm(mean, axis=1), 1e-300)[:, None]
    n = np.cross(V[new[:, 1]] - V[new[:, 0]], V[new[:, 2]] - V[new[:, 0]])
    n /= np.maximum(np.linalg.norm(n, axis=1), 1e-300)[:, None]
    flat = (np.einsum("ij,ij->i", n, np.concatenate([mean, mean])).reshape(2, -1)
            > np.cos(np.radians(FOLD_DEG))).all(axis=0)
    nv = np.int64(mesh.n_vertices)
    keys = mesh.edges[:, 0] * nv + mesh.edges[:, 1]
    fresh = (a != b) & ~np.isin(np.minimum(a, b) * nv + np.maximum(a, b), keys)
    return winds & shapes & flat & fresh


def _gains(mesh: TriMesh, q: np.ndarray, points: np.ndarray, weights: np.ndarray,
           face: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """(k,) how much closer the reference vertices nearest to each quad's faces (``face``,
    at ``dist``) lie to the flipped pair (area-weighted distances), where that is more than
    ``GAIN_SHARE`` of the quad's; 0 elsewhere. The quads go in blocks of about ``BLOCK``
    (point, quad) pairs: memory stays bounded on inputs of millions of faces."""
    order = np.argsort(face, kind="stable")
    ptr = np.searchsorted(face[order], np.arange(mesh.n_faces + 1))
    count = ptr[1:] - ptr[:-1]
    ends = np.cumsum(count[q[:, 0]] + count[q[:, 1]])
    new = np.zeros(len(q))
    start = 0
    while start < len(q):
        before = ends[start - 1] if start else 0
        stop = max(start + 1, int(np.searchsorted(ends, before + BLOCK, side="right")))
        new[start:stop] = _flipped_distance(mesh, q[start:stop], points, weights, order, ptr)
        start = stop
    cost = np.bincount(face, weights * dist, mesh.n_faces)
    old = cost[q[:, 0]] + cost[q[:, 1]]
    gain = old - new
    return np.where(gain > GAIN_SHARE * old, gain, 0.0)


def _flipped_distance(mesh: TriMesh, q: np.ndarray, points: np.ndarray, weights: np.ndarray,
                      order: np.ndarray, ptr: np.ndarray) -> np.ndarray:
    """(k,) per quad, the area-weighted distance of the points nearest to its two faces
    (``order[ptr[f]:ptr[f + 1]]`` for face f) to its flipped pair."""
    faces = np.concatenate([q[:, 0], q[:, 1]])
    lengths = ptr[faces + 1] - ptr[faces]
    first = np.cumsum(lengths) - lengths
    members = order[np.repeat(ptr[faces] - first, lengths) + np.arange(lengths.sum())]
    rows = np.repeat(np.tile(np.arange(len(q)), 2), lengths)
    V, P = mesh.vertices, points[members]
    x, y, a, b = (V[q[rows, k]] for k in (2, 3, 4, 5))
    near = np.minimum(pair_distances(P, x, b, a), pair_distances(P, b, y, a))
    return np.bincount(rows, weights[members] * near, len(q))


def _independent(mesh: TriMesh, q: np.ndarray, gain: np.ndarray, most: int) -> np.ndarray:
    """Up to ``most`` flips with a gain, the largest first, no two on one face or making one
    edge, each leaving x and y three neighbours after the flips before it."""
    valence = np.diff(mesh.vertex_neighbors_csr[0]).copy()
    taken = np.zeros(mesh.n_faces, bool)
    made: set[tuple[int, int]] = set()
    out = []
    for k in np.argsort(-gain, kind="stable"):
        if len(out) >= most or gain[k] <= 0:
            break
        f1, f2, x, y, a, b = (int(v) for v in q[k])
        edge = (min(a, b), max(a, b))
        if taken[f1] or taken[f2] or edge in made or valence[x] <= 3 or valence[y] <= 3:
            continue
        taken[[f1, f2]] = True
        made.add(edge)
        valence[[x, y]] -= 1
        valence[[a, b]] += 1
        out.append(k)
    return np.asarray(out, dtype=np.int64)


def _flipped(mesh: TriMesh, q: np.ndarray) -> TriMesh:
    """The quads ``q`` split along (a, b): faces (x, b, a) and (b, y, a), winding kept."""
    f1, f2, x, y, a, b = q.T
    keep = np.ones(mesh.n_faces, bool)
    keep[f1] = keep[f2] = False
    faces = np.vstack([mesh.faces[keep], np.stack([x, b, a], 1), np.stack([b, y, a], 1)])
    return TriMesh(mesh.vertices, faces)
