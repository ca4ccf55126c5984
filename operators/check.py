"""What in a base mesh will hurt the micro-mesh: found with numpy, selected in Edit Mode.

Non-manifold edges, flipped faces (inconsistent winding with a neighbour, or a closed part
turned inside out), slivers (isotropy 2r/R below a threshold) and near-degenerate triangles,
vertices of extreme valence, and components / genus that differ from the source.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..core.mesh.trimesh import TriMesh

SLIVER_ISOTROPY = 0.1     # 2r/R of an equilateral triangle is 1
DEGENERATE_AREA = 1e-10   # relative to the squared bounding-box diagonal
VALENCE_RANGE = (3, 12)


@dataclass
class CheckReport:
    nonmanifold_edges: np.ndarray
    boundary_edges: np.ndarray
    flipped_faces: np.ndarray
    sliver_faces: np.ndarray
    degenerate_faces: np.ndarray
    valence_vertices: np.ndarray
    components: tuple[int, int | None]
    genus: tuple[int | None, int | None]
    lines: list[str] = field(default_factory=list)

    @property
    def n_problems(self) -> int:
        n = sum(len(a) for a in (self.nonmanifold_edges, self.flipped_faces, self.sliver_faces,
                                 self.degenerate_faces, self.valence_vertices))
        n += self.components[1] is not None and self.components[0] != self.components[1]
        n += self.genus[1] is not None and self.genus[0] != self.genus[1]
        return int(n)


def _isotropy(m: TriMesh) -> np.ndarray:
    v = m.vertices[m.faces]
    l0 = np.linalg.norm(v[:, 1] - v[:, 0], axis=1)
    l1 = np.linalg.norm(v[:, 2] - v[:, 1], axis=1)
    l2 = np.linalg.norm(v[:, 0] - v[:, 2], axis=1)
    a = m.face_areas
    den = (l0 + l1 + l2) * l0 * l1 * l2
    return np.where(den > 0, 16 * a * a / np.maximum(den, 1e-300), 0.0)


def flipped_faces(m: TriMesh) -> np.ndarray:
    """Faces on the minority side of inconsistent windings, plus closed parts turned inward."""
    f = m.faces
    he = np.stack([f, np.roll(f, -1, axis=1)], axis=2).reshape(-1, 2)
    fe = m.face_edges.reshape(-1)
    manifold = m.edge_face_count[fe] == 2
    forward = he[:, 0] < he[:, 1]
    # An edge is consistent when its two faces traverse it in opposite directions.
    dir_sum = np.bincount(fe[manifold], weights=np.where(forward[manifold], 1, -1),
                          minlength=len(m.edges))
    bad_edge = dir_sum != 0
    face_bad = np.bincount(np.repeat(np.arange(m.n_faces), 3)[bad_edge[fe]], minlength=m.n_faces)
    flipped = set(np.flatnonzero(face_bad >= 2).tolist())
    # Closed parts with negative signed volume are inside out.
    v = m.vertices[f]
    signed = np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2])) / 6.0
    comp = m.components
    vol = np.bincount(comp, weights=signed)
    closed = np.ones(comp.max() + 1, bool)
    closed[comp[np.flatnonzero((m.edge_face_count[m.face_edges] != 2).any(1))]] = False
    for c in np.flatnonzero(closed & (vol < 0)):
        flipped.update(np.flatnonzero(comp == c).tolist())
    return np.array(sorted(flipped), dtype=np.int64)


def check_base(base: TriMesh, source: TriMesh | None = None) -> CheckReport:
    """Analyse ``base`` (and compare with ``source``)."""
    iso = _isotropy(base)
    area = base.face_areas
    degenerate = np.flatnonzero(area <= DEGENERATE_AREA * base.bbox_diagonal ** 2)
    slivers = np.setdiff1d(np.flatnonzero(iso < SLIVER_ISOTROPY), degenerate)
    ptr, _ = base.vertex_neighbors_csr
    valence = np.diff(ptr)
    used = np.zeros(base.n_vertices, bool)
    used[base.faces.reshape(-1)] = True
    lo, hi = VALENCE_RANGE
    on_boundary = np.zeros(base.n_vertices, bool)
    on_boundary[base.edges[base.boundary_edges].reshape(-1)] = True
    bad_val = np.flatnonzero(used & ((valence > hi) | ((valence < lo) & ~on_boundary)))
    comps = (base.n_components, source.n_components if source is not None else None)
    genus = (base.genus, source.genus if source is not None else None)
    r = CheckReport(base.nonmanifold_edges, base.boundary_edges, flipped_faces(base), slivers,
                    degenerate, bad_val, comps, genus)
    r.lines = [
        f"{len(r.nonmanifold_edges)} non-manifold edges",
        f"{len(r.boundary_edges)} boundary edges",
        f"{len(r.flipped_faces)} flipped faces",
        f"{len(r.sliver_faces)} slivers (2r/R < {SLIVER_ISOTROPY})",
        f"{len(r.degenerate_faces)} near-degenerate triangles",
        f"{len(r.valence_vertices)} vertices of valence outside {lo}..{hi}",
        f"components {comps[0]}" + (f" (source {comps[1]})" if comps[1] is not None else ""),
        f"genus {genus[0]}" + (f" (source {genus[1]})" if source is not None else ""),
    ]
    return r
