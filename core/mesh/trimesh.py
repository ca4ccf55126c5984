"""Triangle mesh with the topology the micro-mesh method needs.

Arrays in, arrays out: vertices are float64 (n, 3), faces int64 (m, 3). Topology is
computed lazily and cached; a ``TriMesh`` is treated as immutable (make a new one after
moving vertices with :meth:`TriMesh.with_vertices`, which keeps the cached topology).

Compressed adjacency lists use CSR pairs ``(ptr, idx)``: the neighbours of item ``i`` are
``idx[ptr[i]:ptr[i + 1]]``.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components


class MeshError(ValueError):
    """The mesh cannot be used (empty, bad indices, NaNs...)."""


def _csr(rows: np.ndarray, cols: np.ndarray, n_rows: int) -> tuple[np.ndarray, np.ndarray]:
    """Group ``cols`` by ``rows`` into a CSR (ptr, idx) pair, idx sorted within a row."""
    order = np.lexsort((cols, rows))
    rows, cols = rows[order], cols[order]
    ptr = np.zeros(n_rows + 1, dtype=np.int64)
    np.add.at(ptr, rows + 1, 1)
    return np.cumsum(ptr), cols.astype(np.int64)


@dataclass(eq=False)
class TriMesh:
    """An indexed triangle mesh. Edge ``i`` of face ``f`` is ``(f[i], f[(i + 1) % 3])``.

    Args:
        vertices: (n, 3) positions, stored as float64.
        faces: (m, 3) vertex indices, stored as int64; at least one face, every index in range.

    Raises:
        MeshError: arrays of other shapes, no faces, or an index out of range.
    """

    vertices: np.ndarray
    faces: np.ndarray

    def __post_init__(self) -> None:
        v = np.ascontiguousarray(self.vertices, dtype=np.float64)
        f = np.ascontiguousarray(self.faces, dtype=np.int64)
        if v.ndim != 2 or v.shape[1] != 3:
            raise MeshError(f"vertices must be (n, 3), got {v.shape}")
        if f.ndim != 2 or f.shape[1] != 3:
            raise MeshError(f"faces must be (m, 3) triangles, got {f.shape}")
        if len(f) == 0 or len(v) == 0:
            raise MeshError("mesh has no faces")
        if f.min() < 0 or f.max() >= len(v):
            raise MeshError("face index out of range")
        if not np.isfinite(v).all():
            raise MeshError("vertices contain NaN or infinity")
        self.vertices, self.faces = v, f

    @property
    def n_vertices(self) -> int:
        return len(self.vertices)

    @property
    def n_faces(self) -> int:
        return len(self.faces)

    def with_vertices(self, vertices: np.ndarray) -> "TriMesh":
        """Same topology, new positions (topology caches are shared)."""
        m = TriMesh(vertices, self.faces)
        if m.vertices.shape != self.vertices.shape:
            raise MeshError("with_vertices needs the same number of vertices")
        # Every cached_property of this class is topology: share them.
        for k, v in self.__dict__.items():
            if k not in ("vertices", "faces"):
                m.__dict__[k] = v
        return m

    # ------------------------------------------------------------------ edges
    @cached_property
    def _edge_table(self) -> tuple[np.ndarray, np.ndarray]:
        f = self.faces
        he = np.stack([f, np.roll(f, -1, axis=1)], axis=2).reshape(-1, 2)  # (3m, 2)
        key = np.sort(he, axis=1)
        edges, inverse = np.unique(key, axis=0, return_inverse=True)
        return edges.astype(np.int64), inverse.reshape(-1).astype(np.int64)

    @cached_property
    def edges(self) -> np.ndarray:
        """Unique undirected edges (E, 2), each sorted (low, high)."""
        return self._edge_table[0]

    @cached_property
    def face_edges(self) -> np.ndarray:
        """(m, 3) edge index of edge i = (f[i], f[i+1]) of each face."""
        return self._edge_table[1].reshape(-1, 3)

    @cached_property
    def edge_faces_csr(self) -> tuple[np.ndarray, np.ndarray]:
        """Faces around each edge (CSR); more than two means a non-manifold edge."""
        fe = self.face_edges.reshape(-1)
        fid = np.repeat(np.arange(self.n_faces), 3)
        return _csr(fe, fid, len(self.edges))

    @cached_property
    def edge_face_count(self) -> np.ndarray:
        ptr, _ = self.edge_faces_csr
        return np.diff(ptr)

    @cached_property
    def edge_faces(self) -> np.ndarray:
        """(E, 2) the first two faces of each edge, -1 where there is none."""
        ptr, idx = self.edge_faces_csr
        out = np.full((len(self.edges), 2), -1, dtype=np.int64)
        cnt = np.diff(ptr)
        has1 = cnt >= 1
        out[has1, 0] = idx[ptr[:-1][has1]]
        has2 = cnt >= 2
        out[has2, 1] = idx[ptr[:-1][has2] + 1]
        return out

    @cached_property
    def boundary_edges(self) -> np.ndarray:
        """Indices of edges with exactly one face."""
        return np.flatnonzero(self.edge_face_count == 1)

    @cached_property
    def nonmanifold_edges(self) -> np.ndarray:
        """Indices of edges with three or more faces."""
        return np.flatnonzero(self.edge_face_count > 2)

    @cached_property
    def face_adjacency(self) -> np.ndarray:
        """(m, 3) the face across edge i of each face, -1 on a boundary or non-manifold edge."""
        fe = self.face_edges
        ef = self.edge_faces
        manifold = self.edge_face_count[fe] == 2
        a, b = ef[fe, 0], ef[fe, 1]
        me = np.arange(self.n_faces)[:, None]
        other = np.where(a == me, b, a)
        return np.where(manifold, other, -1)

    @cached_property
    def edge_neighbors_csr(self) -> tuple[np.ndarray, np.ndarray]:
        """Faces sharing an edge with each face (every other face of a non-manifold edge;
        itself excluded), CSR."""
        m = self.n_faces
        rows, cols = np.repeat(np.arange(m), 3), self.face_edges.reshape(-1)
        fe = sp.csr_matrix((np.ones(3 * m), (rows, cols)), shape=(m, len(self.edges)))
        ff = (fe @ fe.T).tocoo()
        keep = ff.row != ff.col
        return _csr(ff.row[keep].astype(np.int64), ff.col[keep].astype(np.int64), m)

    # --------------------------------------------------------------- vertices
    @cached_property
    def vertex_faces_csr(self) -> tuple[np.ndarray, np.ndarray]:
        """Faces around each vertex (the vertex star), CSR."""
        return _csr(self.faces.reshape(-1), np.repeat(np.arange(self.n_faces), 3), self.n_vertices)

    @cached_property
    def vertex_neighbors_csr(self) -> tuple[np.ndarray, np.ndarray]:
        """Vertex one-ring (vertices sharing an edge), CSR."""
        e = self.edges
        return _csr(np.concatenate([e[:, 0], e[:, 1]]), np.concatenate([e[:, 1], e[:, 0]]),
                    self.n_vertices)

    @cached_property
    def face_neighbors_csr(self) -> tuple[np.ndarray, np.ndarray]:
        """Face one-ring: faces sharing at least one vertex with each face (itself excluded)."""
        m = self.n_faces
        fv = sp.csr_matrix((np.ones(3 * m), (np.repeat(np.arange(m), 3), self.faces.reshape(-1))),
                           shape=(m, self.n_vertices))
        ff = (fv @ fv.T).tocoo()
        keep = ff.row != ff.col
        return _csr(ff.row[keep].astype(np.int64), ff.col[keep].astype(np.int64), m)

    @cached_property
    def components(self) -> np.ndarray:
        """Connected-component label per face (faces connected through shared vertices)."""
        ptr, idx = self.face_neighbors_csr
        adj = sp.csr_matrix((np.ones(len(idx)), idx, ptr), shape=(self.n_faces, self.n_faces))
        _, labels = connected_components(adj, directed=False)
        return labels.astype(np.int64)

    @property
    def n_components(self) -> int:
        return int(self.components.max()) + 1

    @cached_property
    def is_closed_manifold(self) -> bool:
        return bool((self.edge_face_count == 2).all())

    @cached_property
    def euler_characteristic(self) -> int:
        used = np.unique(self.faces).size
        return int(used - len(self.edges) + self.n_faces)

    @cached_property
    def genus(self) -> int | None:
        """Total genus for a closed manifold mesh, None otherwise."""
        if not self.is_closed_manifold:
            return None
        return int((2 * self.n_components - self.euler_characteristic) // 2)

    # -------------------------------------------------------------- geometry
    @property
    def face_normals_unnormalized(self) -> np.ndarray:
        """Cross products (twice the area times the unit normal), (m, 3)."""
        v = self.vertices[self.faces]
        return np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])

    @property
    def face_areas(self) -> np.ndarray:
        return 0.5 * np.linalg.norm(self.face_normals_unnormalized, axis=1)

    @property
    def face_normals(self) -> np.ndarray:
        n = self.face_normals_unnormalized
        return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)

    @property
    def vertex_normals(self) -> np.ndarray:
        """Area-weighted vertex normals (unit; zero where undefined)."""
        return self._vertex_mean_direction(self.face_normals_unnormalized)

    @property
    def direction_normals(self) -> np.ndarray:
        """The displacement directions: per vertex the plain mean of its faces' unit normals
        (unit; zero where undefined). Unlike area weighting, a few large faces do not outvote
        the small ones at a crease (``docs/results.md``)."""
        return self._vertex_mean_direction(self.face_normals)

    def _vertex_mean_direction(self, face_vectors: np.ndarray) -> np.ndarray:
        """(n, 3) per vertex, the unit sum of its faces' ``face_vectors`` (zero where none)."""
        out = np.zeros_like(self.vertices)
        for i in range(3):
            np.add.at(out, self.faces[:, i], face_vectors)
        return out / np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-30)

    @property
    def vertex_areas(self) -> np.ndarray:
        """One third of the area of the faces around each vertex."""
        a = np.repeat(self.face_areas / 3.0, 3)
        return np.bincount(self.faces.reshape(-1), weights=a, minlength=self.n_vertices)

    @property
    def bbox_diagonal(self) -> float:
        return float(np.linalg.norm(self.vertices.max(0) - self.vertices.min(0)))
