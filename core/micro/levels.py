"""Subdivision levels on a base mesh, before any micro-vertex exists: levels checked
(:func:`as_levels`), balanced so that faces sharing an edge differ by at most one, the
edge-decimation flags that follow from them, and the size of the micro-vertex index space
(``core.micro.topology`` builds that space).

The one definition of "balanced" every stage that sets levels uses: the faces on an edge are
*all* the faces on it (three or more on a non-manifold edge, one on a boundary), as
``TriMesh.edge_faces_csr`` lists them; :func:`edge_min_max` per edge and
:func:`face_edge_levels` per face's edge are the only ways levels are compared across edges
(``TriMesh.face_adjacency`` has no neighbour across a non-manifold edge: never for levels)."""
from __future__ import annotations

import numpy as np

from .level_grid import MAX_LEVEL, LevelError
from ..mesh.trimesh import TriMesh


def as_levels(mesh: TriMesh, levels) -> np.ndarray:
    """``levels`` (a scalar or one per face) as an (n_faces,) int64 array; shape checked."""
    lv = np.asarray(levels)
    if lv.ndim == 0:
        lv = np.full(mesh.n_faces, lv)
    if lv.shape != (mesh.n_faces,):
        raise LevelError(f"need one level per base face ({mesh.n_faces}), got shape {lv.shape}")
    if lv.dtype.kind not in "iub":
        if lv.dtype.kind != "f" or not np.all(np.isfinite(lv)) or np.any(lv != np.round(lv)):
            raise LevelError("subdivision levels must be integers")
    return lv.astype(np.int64)


def edge_min_max(mesh: TriMesh, lv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(ne,) lowest and highest level of the faces on each edge (``mesh.edges`` order)."""
    ptr, idx = mesh.edge_faces_csr
    vals = lv[idx]
    return np.minimum.reduceat(vals, ptr[:-1]), np.maximum.reduceat(vals, ptr[:-1])


def face_edge_levels(mesh: TriMesh, lv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(nf, 3) lowest and highest level among all the faces on each edge of each face (the
    face itself included: its own level alone across a boundary)."""
    emin, emax = edge_min_max(mesh, lv)
    fe = mesh.face_edges
    return emin[fe], emax[fe]


def raised_to_balance(mesh: TriMesh, levels) -> np.ndarray:
    """The lower side raised until the faces on every edge differ by at most one level; no
    clamping (``core.lod.expansion`` counts levels above ``MAX_LEVEL`` it never builds)."""
    lv = as_levels(mesh, levels)
    while True:
        new = np.maximum(lv, face_edge_levels(mesh, lv)[1].max(axis=1) - 1)
        if np.array_equal(new, lv):
            return lv
        lv = new


def balance_levels(mesh: TriMesh, levels) -> np.ndarray:
    """Clamp to 0..5, then raise the lower side until faces sharing an edge (all faces of a
    non-manifold edge) differ by at most one level. Never lowers a (clamped) level."""
    return raised_to_balance(mesh, np.clip(as_levels(mesh, levels), 0, MAX_LEVEL))


def is_balanced(mesh: TriMesh, levels) -> bool:
    lv = as_levels(mesh, levels)
    if lv.min() < 0 or lv.max() > MAX_LEVEL:
        return False
    emin, emax = edge_min_max(mesh, lv)
    return bool((emax - emin <= 1).all())


def edge_flags(mesh: TriMesh, levels) -> np.ndarray:
    """(nf,) uint8: bit i set ⇔ a face across edge i has a level one lower."""
    lv = as_levels(mesh, levels)
    low = face_edge_levels(mesh, lv)[0] == lv[:, None] - 1
    return (low[:, 0] * 1 + low[:, 1] * 2 + low[:, 2] * 4).astype(np.uint8)


def count_micro_vertices(mesh: TriMesh, levels) -> int:
    """Size of the canonical micro-vertex index space (without building it)."""
    lv = as_levels(mesh, levels)
    s_e = 1 << edge_min_max(mesh, lv)[0]
    s_f = 1 << lv
    return int(mesh.n_vertices + (s_e - 1).sum() + ((s_f - 1) * (s_f - 2) // 2).sum())
