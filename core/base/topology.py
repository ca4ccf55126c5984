"""Topology of a mesh in the terms a user checks a base mesh by, and the differences between
an input and its base in words, and the vertices where the surface is pinched."""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..mesh.trimesh import TriMesh


@dataclass(frozen=True)
class Topology:
    """Components, boundary loops, Euler characteristic, genus (closed manifolds only) and
    non-manifold edges."""

    components: int
    boundary_loops: int
    euler: int
    genus: int | None
    nonmanifold_edges: int

    def as_dict(self) -> dict:
        return asdict(self)


def boundary_loops(mesh: TriMesh) -> int:
    """Connected pieces of the boundary-edge graph (one per hole of a manifold)."""
    e = mesh.edges[mesh.boundary_edges]
    if len(e) == 0:
        return 0
    used, inv = np.unique(e.reshape(-1), return_inverse=True)
    inv = inv.reshape(-1, 2)
    adj = sp.coo_matrix((np.ones(len(inv)), (inv[:, 0], inv[:, 1])), shape=(len(used),) * 2)
    return int(connected_components(adj, directed=False)[0])


def topology(mesh: TriMesh) -> Topology:
    return Topology(mesh.n_components, boundary_loops(mesh), mesh.euler_characteristic,
                    mesh.genus, len(mesh.nonmanifold_edges))


def differences(reference: Topology, base: Topology) -> list[str]:
    """The ways ``base`` differs from ``reference``, each in a sentence (empty when equal)."""
    out = []
    if base.components != reference.components:
        out.append(f"the base has {base.components} parts, the input {reference.components}")
    if base.boundary_loops != reference.boundary_loops:
        out.append(f"the base has {base.boundary_loops} holes (boundary loops), the input "
                   f"{reference.boundary_loops}")
    if base.euler != reference.euler:
        if base.genus is not None and reference.genus is not None:
            out.append(f"the base has genus {base.genus}, the input {reference.genus}")
        else:
            out.append(f"the base's Euler characteristic is {base.euler}, the input's "
                       f"{reference.euler} (handles or holes differ)")
    if base.nonmanifold_edges > reference.nonmanifold_edges:
        out.append(f"the base has {base.nonmanifold_edges} non-manifold edges, the input "
                   f"{reference.nonmanifold_edges}")
    return out


def locked_vertices(mesh: TriMesh) -> np.ndarray:
    """Vertices that may not move: on non-manifold edges, where several fans of faces meet
    (a pinch: two holes through one vertex), and next to a pinch. An edge between two of them
    never collapses, so no edge at a pinch does: the link condition assumes one fan, and
    collapsing a neighbour into a pinch could close one of its holes."""
    locked = np.zeros(mesh.n_vertices, bool)
    locked[mesh.edges[mesh.nonmanifold_edges].reshape(-1)] = True
    bnd = mesh.edges[mesh.boundary_edges].reshape(-1)
    nb = np.bincount(bnd, minlength=mesh.n_vertices)
    ptr, _ = mesh.vertex_faces_csr
    nbr, _ = mesh.vertex_neighbors_csr
    faces, valence = np.diff(ptr), np.diff(nbr)
    # a closed fan has valence faces, an open one one fewer
    pinch = (nb > 2) | (faces < valence - (nb > 0))
    e = mesh.edges
    locked[e[pinch[e[:, 0]] | pinch[e[:, 1]]].reshape(-1)] = True
    return locked | pinch
