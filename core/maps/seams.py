"""UV seams of an atlas: the base edges whose two faces take their texels from different
places, the points a renderer's tessellation samples along them from either side, and how far
apart a height map puts the two sides there.

A renderer cuts each base triangle into the uniform lattice of some level L (4^L triangles)
and samples the height map at each lattice point with that face's UVs. On a seam edge the
two faces sample different texels for the same point; where the heights differ, the surface
cracks. The lattice points of level L on an edge are its points k / 2^L, so those of level
``level`` include those of every coarser level.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..mesh.trimesh import TriMesh
from .atlas import Atlas
from .bake import sample


@dataclass(eq=False)
class SeamPoints:
    """The lattice points of one level on every seam edge, seen from both sides.

    ``uv_a``, ``uv_b`` (q, 2): the same surface point's UVs in the edge's first face and in
    another face of the edge (or a base vertex's first place in the atlas and another);
    ``edge`` (q,): the base edge (-1: a vertex); ``t`` (q,): the point's place along it,
    k / 2^level from its lower-numbered vertex.
    """

    uv_a: np.ndarray
    uv_b: np.ndarray
    edge: np.ndarray
    t: np.ndarray

    def __len__(self) -> int:
        return len(self.edge)

    def gaps(self, height: np.ndarray) -> np.ndarray:
        """(q,) |h_a − h_b|: how far apart the two sides of each point land, ``height``
        (H, W) sampled bilinearly from each side (the same base point and unit normal on
        both, so the height's difference is the distance)."""
        img = np.asarray(height, dtype=np.float64)
        return np.abs(sample(img, self.uv_a) - sample(img, self.uv_b))


def seam_half_edges(base: TriMesh, atlas: Atlas) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per pair of faces on a seam edge: (edge (s,), atlas vertices of the edge in its first
    face (s, 2), the same ends' atlas vertices in the other face (s, 2)), both ordered from
    the edge's lower-numbered base vertex. A non-manifold edge pairs each further face with
    its first."""
    nf = base.n_faces
    face = np.repeat(np.arange(nf), 3)
    corner = np.tile(np.arange(3), nf)
    edge = base.face_edges.reshape(-1)
    nxt = (corner + 1) % 3
    a, b = base.faces[face, corner], base.faces[face, nxt]
    ua, ub = atlas.faces[face, corner], atlas.faces[face, nxt]
    forward = a < b                                    # from the lower-numbered vertex
    lo = np.where(forward, ua, ub)
    hi = np.where(forward, ub, ua)
    order = np.argsort(edge, kind="stable")
    edge, lo, hi = edge[order], lo[order], hi[order]
    first = np.r_[True, edge[1:] != edge[:-1]] if len(edge) else np.zeros(0, bool)
    lead = np.flatnonzero(first)[np.cumsum(first) - 1]
    seam = ~first & ((lo != lo[lead]) | (hi != hi[lead]))
    i = np.flatnonzero(seam)
    return edge[i], np.stack([lo[lead[i]], hi[lead[i]]], 1), np.stack([lo[i], hi[i]], 1)


def seam_points(base: TriMesh, atlas: Atlas, level: int,
                skip: np.ndarray | None = None) -> SeamPoints:
    """The lattice points of ``level`` on every seam edge (both ends included), from both
    sides, and every base vertex that has several places in the atlas from each of them
    against its first (a vertex where fans of faces meet without an edge between them has
    no seam edge to tie them) (:class:`SeamPoints`; a vertex's ``edge`` is -1). ``skip``
    (s,) bool per pair of :func:`seam_half_edges`: seams left out (closed otherwise)."""
    edge, a, b = seam_half_edges(base, atlas)
    if skip is not None:
        edge, a, b = edge[~skip], a[~skip], b[~skip]
    t = np.arange((1 << level) + 1) / float(1 << level)
    uv = atlas.uv

    def along(ends):
        p0, p1 = uv[ends[:, 0]][:, None, :], uv[ends[:, 1]][:, None, :]
        return (p0 * (1.0 - t)[None, :, None] + p1 * t[None, :, None]).reshape(-1, 2)

    order = np.argsort(atlas.vertex, kind="stable")
    v = atlas.vertex[order]
    first = np.r_[True, v[1:] != v[:-1]] if len(v) else np.zeros(0, bool)
    lead = order[np.flatnonzero(first)[np.cumsum(first) - 1]]
    copy = order[~first]
    return SeamPoints(np.concatenate([along(a), uv[lead[~first]]]),
                      np.concatenate([along(b), uv[copy]]),
                      np.concatenate([np.repeat(edge, len(t)), np.full(len(copy), -1)]),
                      np.concatenate([np.tile(t, len(edge)), np.zeros(len(copy))]))


def seam_gap_max(base: TriMesh, atlas: Atlas, height: np.ndarray,
                 levels: tuple[int, ...] = (3, 4, 5)) -> dict[int, float]:
    """{level: the largest gap on the seams at that level's lattice points} in the height's
    units (0.0 where the atlas has no seam)."""
    out = {}
    for lv in levels:
        g = seam_points(base, atlas, lv).gaps(height)
        out[int(lv)] = float(g.max(initial=0.0))
    return out
