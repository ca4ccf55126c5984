"""Error quadrics of a triangle mesh (Garland & Heckbert 1997), vectorised with numpy.

A quadric is the symmetric 4×4 matrix [[A, b], [bᵀ, c]] stored as 10 numbers
(A00, A01, A02, b0, A11, A12, b1, A22, b2, c); ``error(p) = pᵀAp + 2bᵀp + c`` is the weighted
sum of squared distances from p to its planes. Each vertex gets the planes of its faces
weighted by area, and ``weight[v]`` the sum of those areas, so ``Q / weight`` is the
area-weighted mean squared distance to the surface's planes around v: a length², the
same on every mesh in the unit-sphere frame.

Boundary edges, and creases sharper than ``feature_angle_deg``, add planes through the edge
perpendicular to its face(s), weighted by the edge length² times ``boundary_weight`` /
``crease_weight``: they hold an outline or a crease line in place the way the face planes
hold a surface. A crease plane weighs at least ``CREASE_AREA`` times the area of the edge's
two faces (twice the edge length² for an equilateral pair): a short edge between large
faces, as CAD tessellations make them, then holds its crease as firmly as the faces hold
their planes, where its length² alone let the collapses cut across the crease.
A crease is an edge sharper than the surface around it (:func:`crease_edges`): on a
coarsely tessellated curved surface, such as a thin tube of a few facets, every edge is
sharp, and holding them all kept the tessellation's facets in the base.
"""
from __future__ import annotations

import numpy as np

from ..mesh.trimesh import TriMesh

# Two equilateral triangles on an edge of length l have area √3/2 · l²: this weighs them
# 2 l² (the factor as measured in docs/results.md).
CREASE_AREA = 4.0 / np.sqrt(3.0)
# A crease's faces' other edges, creases aside, must be flatter than this (docs/results.md).
CREASE_ISOLATION_DEG = 35.0


def plane_quadrics(normals: np.ndarray, points: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """(k, 10) quadrics of the planes through ``points`` with unit ``normals``, weighted."""
    n = np.asarray(normals, dtype=np.float64)
    d = -(n * points).sum(1)
    w = np.asarray(weights, dtype=np.float64)
    a, b, c = n[:, 0], n[:, 1], n[:, 2]
    return w[:, None] * np.stack([a * a, a * b, a * c, a * d, b * b, b * c, b * d,
                                  c * c, c * d, d * d], axis=1)


def crease_edges(mesh: TriMesh, feature_angle_deg: float = 50.0,
                 isolation_deg: float | None = CREASE_ISOLATION_DEG) -> np.ndarray:
    """Indices into ``mesh.edges`` of the creases: manifold edges whose faces meet at more
    than ``feature_angle_deg`` while every other edge of those two faces that is not itself
    such an edge bends by less than ``isolation_deg`` (None: no such condition). A box's
    edges and a thin plate's rims qualify; the facets of a coarse tube or of a coarse
    sphere, whose other edges bend nearly as much, do not."""
    ef = mesh.edge_faces
    man = np.flatnonzero(mesh.edge_face_count == 2)
    fn = mesh.face_normals
    bend = np.zeros(len(mesh.edges))
    cos = np.clip((fn[ef[man, 0]] * fn[ef[man, 1]]).sum(1), -1.0, 1.0)
    bend[man] = np.degrees(np.arccos(cos))
    sharp = man[bend[man] > feature_angle_deg]
    if isolation_deg is None or len(sharp) == 0:
        return sharp
    others = bend.copy()
    others[sharp] = 0.0
    around = others[mesh.face_edges].max(1)          # per face, its sharpest non-crease edge
    return sharp[np.maximum(around[ef[sharp, 0]], around[ef[sharp, 1]]) < isolation_deg]


def vertex_quadrics(mesh: TriMesh, boundary_weight: float = 4.0, crease_weight: float = 1.0,
                    feature_angle_deg: float = 50.0,
                    isolation_deg: float | None = CREASE_ISOLATION_DEG
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Per-vertex quadrics (n, 10) and weights (n,) (see the module docstring)."""
    V, F = mesh.vertices, mesh.faces
    nv = len(V)
    cross = mesh.face_normals_unnormalized
    dbl = np.linalg.norm(cross, axis=1)
    fn = cross / np.maximum(dbl, 1e-300)[:, None]
    area = 0.5 * dbl
    fq = plane_quadrics(fn, V[F[:, 0]], area)
    Q = np.zeros((nv, 10))
    W = np.zeros(nv)
    for c in range(3):
        np.add.at(Q, F[:, c], fq)
        np.add.at(W, F[:, c], area)

    edges = mesh.edges
    ef = mesh.edge_faces
    cnt = mesh.edge_face_count
    a, b = V[edges[:, 0]], V[edges[:, 1]]
    e = b - a
    length2 = (e * e).sum(1)
    pieces, where = [], []
    bnd = np.flatnonzero(cnt == 1)
    if boundary_weight > 0 and len(bnd):
        pieces.append(_edge_planes(e[bnd], fn[ef[bnd, 0]], a[bnd], boundary_weight * length2[bnd]))
        where.append(bnd)
    sharp = (crease_edges(mesh, feature_angle_deg, isolation_deg) if crease_weight > 0
             else np.empty(0, np.int64))
    if len(sharp):
        hold = np.maximum(length2[sharp], CREASE_AREA * area[ef[sharp]].sum(1))
        for side in (0, 1):
            pieces.append(_edge_planes(e[sharp], fn[ef[sharp, side]], a[sharp],
                                       crease_weight * hold))
            where.append(sharp)
    for q, idx in zip(pieces, where):
        np.add.at(Q, edges[idx, 0], q)
        np.add.at(Q, edges[idx, 1], q)
    return Q, W


def _edge_planes(e: np.ndarray, face_normal: np.ndarray, point: np.ndarray,
                 weight: np.ndarray) -> np.ndarray:
    m = np.cross(e, face_normal)
    m /= np.maximum(np.linalg.norm(m, axis=1), 1e-300)[:, None]
    return plane_quadrics(m, point, weight)


def quadric_error(q: np.ndarray, p: np.ndarray) -> np.ndarray:
    """error(p) of quadrics q (k, 10) at points p (k, 3)."""
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    return (q[:, 0] * x * x + 2 * q[:, 1] * x * y + 2 * q[:, 2] * x * z + 2 * q[:, 3] * x
            + q[:, 4] * y * y + 2 * q[:, 5] * y * z + 2 * q[:, 6] * y
            + q[:, 7] * z * z + 2 * q[:, 8] * z + q[:, 9])
