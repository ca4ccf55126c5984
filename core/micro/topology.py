"""Micro-mesh topology: the one canonical index space of unique micro-vertices of a base mesh
at given levels (the levels themselves, checked, balanced and flagged: ``core.micro.levels``).
One triangle at one level (grids, vertex orders, snapping) is ``core.micro.level_grid``, whose names
are imported here too. Nothing here looks at positions.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..mesh.trimesh import TriMesh
from .level_grid import (  # noqa: F401  (the per-level API, imported from here too)
    BUILD_MAX_LEVEL, MAX_LEVEL, LevelError, _edge_locals, level_grid_view, level_triangles_view,
    snap_targets_view, _snapped_k, barycentric_weights, bird_index, bird_order, level_grid,
    level_triangles, n_micro_triangles, n_micro_vertices, snap_targets, umajor_index)
from .levels import as_levels, edge_flags, edge_min_max


@dataclass(eq=False)
class MicroTopology:
    """The canonical index space of unique micro-vertices of a base mesh at given levels.

    Indices: base vertices first (index = base vertex), then edge-interior vertices edge by
    edge (``mesh.edges`` order, 2^(edge level) − 1 each, from ``edges[e, 0]`` to
    ``edges[e, 1]``), then face-interior vertices face by face (u-major).
    """

    levels: np.ndarray            # (nf,) int64
    flags: np.ndarray             # (nf,) uint8
    n_base_vertices: int
    n_vertices: int
    edge_levels: np.ndarray       # (E,) min level of each edge's faces
    edge_vertex_offset: np.ndarray  # (E+1,) first canonical index of each edge's interior
    face_interior_offset: np.ndarray  # (nf+1,) first canonical index of each face's interior
    face_vertex_ptr: np.ndarray   # (nf+1,)
    face_vertex_idx: np.ndarray   # global index per local u-major micro-vertex (snapped → target)
    interp: sp.csr_matrix         # (n_vertices, n_base_vertices) barycentric weights
    triangles: np.ndarray         # (T, 3) non-degenerate micro-triangles, sorted by base face
    triangle_face: np.ndarray     # (T,) base face
    triangle_local: np.ndarray    # (T,) index into level_triangles(level of the face)
    face_triangle_ptr: np.ndarray  # (nf+1,) triangles of face f: ptr[f]:ptr[f+1]
    vertex_face: np.ndarray       # (n_vertices,) a base face holding the vertex (-1: unused)
    vertex_bary: np.ndarray       # (n_vertices, 3) its (w, u, v) barycentrics in that face
    vertex_level: np.ndarray      # (n_vertices,) finest level of a face holding it (-1: unused)

    @property
    def n_faces(self) -> int:
        return len(self.levels)

    @property
    def n_triangles(self) -> int:
        return len(self.triangles)

    def face_vertices(self, f: int) -> np.ndarray:
        """Global indices of face f's micro-vertices in u-major order."""
        return self.face_vertex_idx[self.face_vertex_ptr[f]:self.face_vertex_ptr[f + 1]]


def build_topology(mesh: TriMesh, levels) -> MicroTopology:
    """Build the canonical micro-vertex space; levels must already be balanced."""
    lv = as_levels(mesh, levels)
    if lv.min() < 0 or lv.max() > MAX_LEVEL:
        raise LevelError(f"subdivision levels must lie in 0..{MAX_LEVEL}")
    emin, emax = edge_min_max(mesh, lv)
    if (emax - emin > 1).any():
        raise LevelError("levels of neighbouring faces differ by more than one; "
                         "call balance_levels first")
    nb, nf = mesh.n_vertices, mesh.n_faces
    faces, fe, edges = mesh.faces, mesh.face_edges, mesh.edges
    flags = edge_flags(mesh, lv)

    s_e = (1 << emin).astype(np.int64)
    n_e = s_e - 1
    edge_off = nb + np.concatenate([[0], np.cumsum(n_e)]).astype(np.int64)
    s_f = (1 << lv).astype(np.int64)
    n_int = (s_f - 1) * (s_f - 2) // 2
    face_off = edge_off[-1] + np.concatenate([[0], np.cumsum(n_int)]).astype(np.int64)
    n_vertices = int(face_off[-1])

    n_loc = (s_f + 1) * (s_f + 2) // 2
    fv_ptr = np.concatenate([[0], np.cumsum(n_loc)]).astype(np.int64)
    fv_idx = np.empty(int(fv_ptr[-1]), dtype=np.int64)

    vertex_face = np.full(n_vertices, -1, dtype=np.int64)
    vertex_bary = np.zeros((n_vertices, 3))
    vertex_level = np.full(n_vertices, -1, dtype=np.int64)
    tri_parts, tri_face_parts, tri_local_parts = [], [], []
    rows, cols, vals = [np.arange(nb)], [np.arange(nb)], [np.ones(nb)]

    for level in range(MAX_LEVEL + 1):
        fl = np.flatnonzero(lv == level)
        if len(fl) == 0:
            continue
        s = 1 << level
        n_l = n_micro_vertices(level)
        m = len(fl)
        F, FE, FL = faces[fl], fe[fl], flags[fl].astype(np.int64)
        glob = np.empty((m, n_l), dtype=np.int64)
        snapped = np.zeros((m, n_l), dtype=bool)
        e_loc, c_loc, i_loc = _edge_locals(level)
        for c in range(3):
            glob[:, c_loc[c]] = F[:, c]
        if s > 1:
            ks = np.arange(1, s, dtype=np.int64)
            snk = _snapped_k(level)
            for i in range(3):
                e = FE[:, i]
                flagged = ((FL >> i) & 1).astype(bool)
                le_s = np.where(flagged, s // 2, s)[:, None]
                kk = np.where(flagged[:, None], (snk // 2)[None, :], ks[None, :])
                a, b = F[:, i], F[:, (i + 1) % 3]
                forward = (edges[e, 0] == a)[:, None]
                j = np.where(forward, kk, le_s - kk)
                g = edge_off[e][:, None] + j - 1
                g = np.where(kk == 0, a[:, None], np.where(kk == le_s, b[:, None], g))
                glob[:, e_loc[i]] = g
                snapped[:, e_loc[i]] = flagged[:, None] & (ks % 2 == 1)[None, :]
        if len(i_loc):
            glob[:, i_loc] = face_off[fl][:, None] + np.arange(len(i_loc))[None, :]
            bw = barycentric_weights(level)[i_loc]
            rows.append(glob[:, i_loc].reshape(-1).repeat(3))
            cols.append(np.repeat(F[:, None, :], len(i_loc), axis=1).reshape(-1))
            vals.append(np.tile(bw.reshape(-1), m))
        fv_idx[(fv_ptr[fl][:, None] + np.arange(n_l)[None, :]).reshape(-1)] = glob.reshape(-1)

        keep = ~snapped
        gk = glob[keep]
        fk = np.broadcast_to(fl[:, None], glob.shape)[keep]
        vertex_face[gk] = fk
        vertex_bary[gk] = np.broadcast_to(barycentric_weights(level)[None], (m, n_l, 3))[keep]
        np.maximum.at(vertex_level, glob.reshape(-1), level)

        lt = level_triangles_view(level)
        t = glob[:, lt]  # (m, 4^l, 3)
        ok = (t[..., 0] != t[..., 1]) & (t[..., 1] != t[..., 2]) & (t[..., 2] != t[..., 0])
        tri_parts.append(t[ok])
        tri_face_parts.append(np.broadcast_to(fl[:, None], ok.shape)[ok])
        tri_local_parts.append(np.broadcast_to(np.arange(len(lt))[None, :], ok.shape)[ok])

    # edge-interior interpolation rows
    if n_e.sum():
        e_rep = np.repeat(np.arange(len(edges)), n_e)
        j = np.arange(int(n_e.sum())) - np.repeat(edge_off[:-1] - nb, n_e) + 1
        t = j / s_e[e_rep]
        gi = nb + np.arange(int(n_e.sum()))
        rows += [gi, gi]
        cols += [edges[e_rep, 0], edges[e_rep, 1]]
        vals += [1.0 - t, t]
    interp = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                           shape=(n_vertices, nb))
    interp.sum_duplicates()

    tris = np.concatenate(tri_parts).astype(np.int64)
    tface = np.concatenate(tri_face_parts).astype(np.int64)
    tloc = np.concatenate(tri_local_parts).astype(np.int64)
    order = np.argsort(tface, kind="stable")
    tris, tface, tloc = tris[order], tface[order], tloc[order]
    ft_ptr = np.concatenate([[0], np.cumsum(np.bincount(tface, minlength=nf))]).astype(np.int64)

    return MicroTopology(
        levels=lv, flags=flags, n_base_vertices=nb, n_vertices=n_vertices,
        edge_levels=emin, edge_vertex_offset=edge_off, face_interior_offset=face_off,
        face_vertex_ptr=fv_ptr, face_vertex_idx=fv_idx, interp=interp,
        triangles=tris, triangle_face=tface, triangle_local=tloc, face_triangle_ptr=ft_ptr,
        vertex_face=vertex_face, vertex_bary=vertex_bary, vertex_level=vertex_level,
    )
