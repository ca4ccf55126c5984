"""Edge splits where the reference strays furthest from the base (ours).

The collapses bound the base's RMS distance to the reference, which leaves a few faces far
from it: where the reference bulges between a face's corners (a relief on a flat CAD part, the
large smooth parts of a multi-part model) the micro-vertices' values span a wide range around
those faces' corners, and the prismoid shell there is thick. Splitting the longest edge of
the faces with the largest (furthest reference vertex × area), the new vertex on the
reference, thins exactly those prismoids; a split keeps the topology (an edge split never
changes genus, parts or boundary loops).
"""
from __future__ import annotations

import numpy as np

from ..spatial.closest import ClosestPointIndex
from ..mesh.trimesh import TriMesh

ROUND_SHARE = 0.05     # at most this fraction of the faces split in one round
MAX_EXTRA = 0.12       # and at most this fraction more faces in all


def thickness(base: TriMesh, points: np.ndarray) -> np.ndarray:
    """(F,) per base face, the largest distance from it of the points whose nearest face it
    is (0 where none)."""
    _, face, dist = ClosestPointIndex(base.vertices, base.faces).query(points)
    out = np.zeros(base.n_faces)
    np.maximum.at(out, face, dist)
    return out


def refine(base: TriMesh, reference: TriMesh, outlier: float) -> tuple[TriMesh, int]:
    """``base`` with the longest edge of each face whose score (the furthest reference vertex
    × its area) exceeds ``outlier`` times the mean score of ``base``'s faces split, round
    after round (at most ``ROUND_SHARE`` of the faces a round, no two splits of a round on
    one face), until no face does or the base has ``MAX_EXTRA`` more faces. Returns the mesh
    and the number of edges split.

    Where the reference is near every face alike little is split (at 8 times the mean:
    under 0.1 % of armadillo's base faces, 0.1-0.2 % of bunny's and the rocker arm's);
    where a few faces hold most of the score, those are (the CAD part's and the helmet's:
    3 % of the faces, 57-69 % of the score; ``docs/results.md``)."""
    cap = base.n_faces + int(MAX_EXTRA * base.n_faces)
    ref_index = ClosestPointIndex(reference.vertices, reference.faces)
    mesh, splits = base, 0
    score = thickness(mesh, reference.vertices) * mesh.face_areas
    limit = outlier * score.mean()
    while mesh.n_faces + 2 <= cap:
        most = max(1, min((cap - mesh.n_faces) // 2, int(ROUND_SHARE * mesh.n_faces)))
        edges = _independent_edges(mesh, np.where(score > limit, score, 0.0), most)
        if len(edges) == 0:
            break
        mesh = _split(mesh, edges, ref_index)
        splits += len(edges)
        score = thickness(mesh, reference.vertices) * mesh.face_areas
    return mesh, splits


def _independent_edges(mesh: TriMesh, score: np.ndarray, most: int) -> np.ndarray:
    """Up to ``most`` interior edges, each the longest of a face in ``score`` order (> 0), no
    two on one face."""
    E, fe, ef = mesh.edges, mesh.face_edges, mesh.edge_faces
    V = mesh.vertices
    length = np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1)
    longest = fe[np.arange(mesh.n_faces), np.argmax(length[fe], axis=1)]
    taken = np.zeros(mesh.n_faces, bool)
    out = []
    for f in np.argsort(-score, kind="stable"):
        if len(out) >= most or score[f] <= 0:
            break
        e = longest[f]
        pair = ef[e]
        if (pair < 0).any() or mesh.edge_face_count[e] != 2 or taken[pair].any():
            continue
        taken[pair] = True
        out.append(e)
    return np.asarray(out, dtype=np.int64)


def _split(mesh: TriMesh, edges: np.ndarray, ref_index: ClosestPointIndex) -> TriMesh:
    """Each edge (a, b) split at the reference's point nearest its midpoint (the midpoint
    itself where that point is further than half the edge away): its two faces become four,
    each keeping its winding."""
    V, F = mesh.vertices, mesh.faces
    a, b = mesh.edges[edges, 0], mesh.edges[edges, 1]
    mid = 0.5 * (V[a] + V[b])
    near, _, dist = ref_index.query(mid)
    far = dist > 0.5 * np.linalg.norm(V[a] - V[b], axis=1)
    near[far] = mid[far]
    new = mesh.n_vertices + np.arange(len(edges))
    faces = mesh.edge_faces[edges]                       # (k, 2)
    tri = F[faces.reshape(-1)]                           # (2k, 3)
    ends = np.repeat(np.stack([a, b], 1), 2, axis=0)
    # the corner opposite the edge: the one that is neither end
    opp = (tri != ends[:, :1]) & (tri != ends[:, 1:])
    r = np.argmax(opp, axis=1)                           # its position in the face
    t = tri[np.arange(len(tri))[:, None], (r[:, None] + np.arange(3)) % 3]   # (c, u, v)
    m = np.repeat(new, 2)
    halves = np.concatenate([np.stack([t[:, 0], t[:, 1], m], 1),
                             np.stack([t[:, 0], m, t[:, 2]], 1)])
    keep = np.ones(len(F), bool)
    keep[faces.reshape(-1)] = False
    return TriMesh(np.vstack([V, near]), np.vstack([F[keep], halves]))
