"""What a renderer draws from a base and a height map at one tessellation level, kept as the
height map's fit needs it: every base triangle cut into the lattice of that level (4^level
triangles), each micro-vertex with its base position, its direction (the unit vertex
normals interpolated, not normalised).

A micro-mesh's topology of millions of micro-vertices holds more than this (160 bytes a
micro-vertex on gen_scan_871k's lattice, where this keeps 100): the fit keeps these arrays
and draws its result as a :class:`DrawnSurface`, with no topology. The reference's samples
come with a distance within which the lattice has a triangle for each, as the lattice moves
round after round (:func:`reference_bounds`, :func:`moved_bound`): the grouped search
(``core.fit.grouped``) asks only the trees within it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..fit.grouped import GROUP, triangle_groups
from ..fit.samples import Samples, reference_samples
from ..mesh.trimesh import TriMesh
from ..micro.locate import grid_cell
from ..micro.micromesh import MicroMesh
from ..spatial.closest import ClosestPointIndex
from .atlas import Atlas

CHUNK = 1 << 18             # lattice triangles measured at a time (temporaries: 72 bytes each)


@dataclass(eq=False)
class Lattice:
    """``triangles`` (m, 3) int32 micro-vertices; ``P``, ``D`` (n, 3);
    ``face_triangle_ptr`` (nf + 1,): the triangles of base face f are ptr[f]:ptr[f + 1];
    ``face_vertices`` (nf, k) int32: each face's micro-vertices in u-major order."""

    level: int
    triangles: np.ndarray
    P: np.ndarray
    D: np.ndarray
    face_triangle_ptr: np.ndarray
    face_vertices: np.ndarray

    @classmethod
    def over(cls, base: TriMesh, directions: np.ndarray, atlas: Atlas, level: int
             ) -> tuple["Lattice", np.ndarray]:
        """The lattice of ``level`` on ``base`` with unit vertex ``directions`` (nv, 3), and
        (n, 2) its micro-vertices' UVs on ``atlas`` (in the face that holds each)."""
        t = MicroMesh.flat(base, np.full(base.n_faces, int(level)), directions).topology
        uv = np.einsum("qk,qkc->qc", t.vertex_bary, atlas.corner_uv[t.vertex_face])
        face_vertices = t.face_vertex_idx.astype(np.int32).reshape(base.n_faces, -1)
        return cls(int(level), t.triangles.astype(np.int32), t.interp @ base.vertices,
                   t.interp @ directions, t.face_triangle_ptr.copy(), face_vertices), uv

    @property
    def n_vertices(self) -> int:
        return len(self.P)

    def groups(self, base: TriMesh, size: int = GROUP) -> list:
        """The triangles in groups of about ``size`` at most over compact regions of
        ``base`` (:func:`core.fit.grouped.triangle_groups`)."""
        return triangle_groups(base.vertices[base.faces].mean(1), self.face_triangle_ptr,
                               size)

    def drawn(self, X: np.ndarray) -> "DrawnSurface":
        """The lattice's micro-vertices at ``X`` (n, 3)."""
        return DrawnSurface(self.level, X, self.face_vertices)


@dataclass(eq=False)
class DrawnSurface:
    """What a renderer draws from a base and a height map: the lattice of ``level`` on every
    base face, its micro-vertices at ``X`` (n, 3), ``face_vertices`` (nf, k) each face's
    micro-vertices in u-major order (the indices of ``MicroMesh.flat``'s topology at the
    same level, as :class:`Lattice`'s)."""

    level: int
    X: np.ndarray
    face_vertices: np.ndarray

    def locate(self, faces: np.ndarray, bary: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """((q, 3) micro-vertices, (q, 3) weights) of the micro-triangle holding each point
        of base ``faces`` (q,) and barycentrics ``bary`` (q, 3), as ``MicroMesh.locate``."""
        loc, w = grid_cell(self.level, bary)
        return self.face_vertices[np.asarray(faces)[:, None], loc], w


def moved_bound(dist: np.ndarray, tri: np.ndarray, triangles: np.ndarray,
                 move: np.ndarray) -> np.ndarray:
    """(s,) float32 a distance within which each sample has a triangle of the lattice after
    its micro-vertices moved by ``move`` (n,): its distance ``dist`` to its triangle ``tri``
    before, plus the most that triangle's corners moved (the largest move anywhere where it
    had none)."""
    bound = dist.copy()
    ok = tri >= 0
    bound[ok] += move[triangles[tri[ok]]].max(1)
    bound[~ok] += move.max()
    return bound * np.float32(1 + 1e-6)


def reference_bounds(lattice: Lattice, base: TriMesh, ref: TriMesh, d: np.ndarray,
                     density: float) -> tuple[Samples, np.ndarray]:
    """The reference's samples, at least ``density`` per micro-triangle of the lattice
    displaced by ``d`` (``core.fit.samples``), and a distance within which the lattice has a
    point for each (float32): its distance to its nearest base face plus the largest height
    over that face (the lattice triangle over its nearest point is within that height)."""
    X = lattice.P + lattice.D * d[:, None]
    area = 0.0
    for s in range(0, len(lattice.triangles), CHUNK):
        c = X[lattice.triangles[s:s + CHUNK]]
        area += 0.5 * np.linalg.norm(np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]),
                                     axis=1).sum()
    samples = reference_samples(ref, area / (density * len(lattice.triangles)))
    top = np.linalg.norm(X - lattice.P, axis=1)[lattice.face_vertices].max(1)
    del X
    index = ClosestPointIndex(base.vertices, base.faces)
    bound = np.empty(len(samples), np.float32)
    for part, pts, _, _ in samples.chunks():
        _, face, dist = index.query(pts)
        bound[part] = (dist + top[face]) * (1 + 1e-6)
    return samples, bound
