"""Consistent winding: faces turned so that every manifold edge is walked in opposite
directions by its two faces, and closed parts face outwards.

Scans and exports often come with some faces wound against their neighbours; their normals
then point in and out at random, which ruins rendering losses, displacement directions and
base building (half the faces flipped: 18.7 dB instead of 42.5). One breadth-first pass per
part decides each face's orientation relative to its part's first face; a closed part whose
signed volume is negative is turned whole; an open part keeps the orientation most of its
faces had. Non-orientable parts (a Möbius band) keep the conflicts a spanning tree leaves.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import breadth_first_order

from .trimesh import TriMesh


@dataclass
class Orientation:
    mesh: TriMesh          # the consistently wound mesh (the input itself when nothing changed)
    turned: int            # faces turned
    inconsistent_edges: int  # manifold edges whose two faces disagreed in the input
    inside_out_parts: int  # closed parts turned whole because they faced inwards

    def warnings(self) -> list[str]:
        out = []
        if self.inconsistent_edges:
            out.append(f"{self.inconsistent_edges} edges of the input join faces wound in "
                       f"opposite directions: {self.turned} faces were turned for the "
                       "construction (the source is unchanged)")
        elif self.inside_out_parts:
            out.append(f"{self.inside_out_parts} closed parts of the input faced inwards: "
                       "they were turned for the construction (the source is unchanged)")
        return out


def orient(mesh: TriMesh) -> Orientation:
    """:class:`Orientation` of ``mesh``."""
    F = mesh.faces
    nf = mesh.n_faces
    ptr, idx = mesh.edge_faces_csr
    two = np.flatnonzero(np.diff(ptr) == 2)
    fa, fb = idx[ptr[two]], idx[ptr[two] + 1]
    ea = mesh.edges[two]
    # direction of the edge in each face: +1 if the face walks it as edges[e] (a -> b)
    same = _walks_forward(F, fa, ea) == _walks_forward(F, fb, ea)    # same direction: a conflict
    comp = _components(nf, fa, fb)
    flip = _relative_flips(nf, fa, fb, same, comp) if same.any() else np.zeros(nf, bool)
    oriented = np.where(flip[:, None], F[:, ::-1], F)
    bnd_faces = np.zeros(nf, bool)
    bnd_faces[idx[ptr[np.flatnonzero(np.diff(ptr) == 1)]]] = True
    closed = ~np.bincount(comp, weights=bnd_faces, minlength=comp.max() + 1).astype(bool)
    vol = np.bincount(comp, weights=_signed_volumes(mesh.vertices, oriented),
                      minlength=len(closed))
    turn = np.zeros(len(closed), bool)
    turn[closed] = vol[closed] < 0
    inside_out = int(turn.sum())
    # open parts: keep the orientation most of their faces had
    kept = np.bincount(comp, weights=(~flip).astype(float), minlength=len(closed))
    size = np.bincount(comp, minlength=len(closed))
    turn |= ~closed & (kept < size / 2)
    flip ^= turn[comp]
    turned = int(flip.sum())
    if turned == 0:
        return Orientation(mesh, 0, int(same.sum()), 0)
    out = TriMesh(mesh.vertices, np.where(flip[:, None], F[:, ::-1], F))
    return Orientation(out, turned, int(same.sum()), inside_out)


def _walks_forward(F: np.ndarray, f: np.ndarray, e: np.ndarray) -> np.ndarray:
    """Whether face ``f`` has the directed edge e[0] -> e[1] among (v0 v1), (v1 v2), (v2 v0)."""
    tri = F[f]
    nxt = np.roll(tri, -1, axis=1)
    return ((tri == e[:, :1]) & (nxt == e[:, 1:])).any(axis=1)


def _relative_flips(nf: int, fa: np.ndarray, fb: np.ndarray, same: np.ndarray,
                    comp: np.ndarray) -> np.ndarray:
    """Per face, whether it must turn relative to the root of its part: the parity of the
    conflicts along the breadth-first tree from that root (one search from a virtual node
    joined to every part)."""
    roots = np.full(comp.max() + 1, nf)
    np.minimum.at(roots, comp, np.arange(nf))
    virt = nf
    rows = np.concatenate([fa, fb, np.full(len(roots), virt), roots])
    cols = np.concatenate([fb, fa, roots, np.full(len(roots), virt)])
    par = np.concatenate([same, same, np.zeros(2 * len(roots), bool)]).astype(np.int8) + 1
    _, first = np.unique(rows * (nf + 1) + cols, return_index=True)   # two faces, two edges
    G = sp.csr_matrix((par[first], (rows[first], cols[first])), shape=(nf + 1, nf + 1))
    _, pred = breadth_first_order(G, virt, directed=False, return_predecessors=True)
    pred = pred[:nf]
    p = np.where(pred < 0, virt, pred)
    acc = (np.asarray(G[np.arange(nf), p]).ravel() % 2 == 0)        # 2: a conflict
    acc = np.append(acc, False)
    p = np.append(p, virt)
    while (p != virt).any():                  # pointer jumping: parity to the root
        acc = acc ^ np.where(p != virt, acc[p], False)
        p = np.where(p != virt, p[p], virt)
    return acc[:nf]


def _components(nf: int, fa: np.ndarray, fb: np.ndarray) -> np.ndarray:
    from scipy.sparse.csgraph import connected_components

    G = sp.csr_matrix((np.ones(len(fa)), (fa, fb)), shape=(nf, nf))
    return connected_components(G, directed=False)[1]


def _signed_volumes(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Each face's signed volume about the bounding box's centre (a closed part's sum is the
    same about any point; about the world's origin, a part far from it would sum terms of
    its distance cubed, and round its sign away)."""
    V = V - (V.min(axis=0) + V.max(axis=0)) / 2
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    return np.einsum("ij,ij->i", a, np.cross(b, c)) / 6.0
