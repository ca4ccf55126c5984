"""Topology of a mesh in the terms a user checks a base mesh by, and the differences between
an input and its base in words."""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..mesh import TriMesh


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
