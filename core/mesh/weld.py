"""Coincident vertices welded: triangle soups (STL, many CAD and scanner exports: every
triangle with vertices of its own) and files split along UV seams or flat-shaded edges are
one connected surface again.

Vertices closer than ``tolerance`` times the bounding-box diagonal are merged; each merged
group keeps the position of its first vertex (the file's own value, not an average), faces
that then repeat a vertex are dropped. Vertices no face uses are not touched.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from .trimesh import MeshError, TriMesh

TOLERANCE = 1e-6    # of the bounding-box diagonal: far under any real edge, over float noise


@dataclass
class Welded:
    """The welded mesh; ``merged``: vertices (of those faces use) merged into another;
    ``dropped``: faces that lost a vertex to the weld (collapsed to a line or a point)."""

    mesh: TriMesh
    merged: int
    dropped: int

    def warning(self) -> str | None:
        """In words, for the user; None where nothing was welded."""
        if not self.merged:
            return None
        text = (f"{self.merged} coincident vertices (within {TOLERANCE:g} of the bounding-box "
                f"diagonal) were welded")
        if self.dropped:
            text += f", and {self.dropped} faces that collapsed were left out"
        return text


def weld(mesh: TriMesh, tolerance: float = TOLERANCE) -> Welded:
    """``mesh`` with the vertices faces use merged where they lie within ``tolerance`` × its
    bounding-box diagonal of each other (transitively); ``mesh`` itself when nothing merges.
    Raises :class:`~core.mesh.MeshError` where every face collapses."""
    faces = mesh.faces
    used = np.unique(faces)
    rep = np.arange(mesh.n_vertices)
    rep[used] = used[_groups(mesh.vertices[used], tolerance * mesh.bbox_diagonal)]
    leader = rep == np.arange(mesh.n_vertices)    # vertices no face uses stay, as they were
    merged = int((~leader).sum())
    if merged == 0:
        return Welded(mesh, 0, 0)
    index = np.cumsum(leader) - 1
    f = index[rep[faces]]
    keep = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])
    if not keep.any():
        raise MeshError("no face keeps three distinct vertices once coincident vertices are "
                        "welded")
    return Welded(TriMesh(mesh.vertices[leader], f[keep]), merged, int((~keep).sum()))

def _groups(points: np.ndarray, radius: float) -> np.ndarray:
    """For each point, the index of the first point of its group (points linked by chains of
    distances <= ``radius``; exact copies always)."""
    _, first, inverse = np.unique(points, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    leader = first[inverse]                       # exact copies onto their first
    distinct = np.sort(first)
    if radius > 0 and len(distinct) > 1:
        pairs = cKDTree(points[distinct]).query_pairs(radius, output_type="ndarray")
        if len(pairs):
            n = len(distinct)
            graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
            _, label = connected_components(graph, directed=False)
            head = np.full(label.max() + 1, n)
            np.minimum.at(head, label, np.arange(n))
            to_distinct = np.empty(len(points), np.int64)
            to_distinct[distinct] = np.arange(n)
            leader = distinct[head[label[to_distinct[leader]]]]
    return leader
