"""The micro-mesh primitive: base mesh, per-vertex directions, per-face levels and one
scalar displacement per unique micro-vertex (``core.micro.topology`` index space).

Position of a micro-vertex = lerp(P) + lerp(D) · d, directions interpolated without
normalising (``docs/method.md`` §1). Changing levels resamples the displacements so the
piecewise-linear displaced surface is kept.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..mesh.trimesh import TriMesh
from .level_grid import BUILD_MAX_LEVEL, MAX_LEVEL, LevelError, bird_order
from .locate import locate
from .levels import as_levels, balance_levels, count_micro_vertices, is_balanced
from .topology import MicroTopology, build_topology


class MicroMeshError(ValueError):
    """A micro-mesh whose arrays do not fit together."""


@dataclass(eq=False)
class Tessellation:
    """A flat triangle mesh of a displaced micro-mesh (watertight: shared vertices)."""

    vertices: np.ndarray       # (n, 3)
    triangles: np.ndarray      # (T, 3)
    triangle_face: np.ndarray  # (T,) base face of each micro-triangle

    def to_trimesh(self) -> TriMesh:
        return TriMesh(self.vertices, self.triangles)


@dataclass(eq=False)
class MicroMesh:
    """Base mesh + directions (nv, 3) + levels (nf,) + displacements (n_vertices,)."""

    base: TriMesh
    directions: np.ndarray
    levels: np.ndarray
    displacements: np.ndarray
    _topology: MicroTopology | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if not isinstance(self.base, TriMesh):
            raise MicroMeshError("base must be a TriMesh")
        d = np.ascontiguousarray(self.directions, dtype=np.float64)
        if d.shape != (self.base.n_vertices, 3):
            raise MicroMeshError(f"directions must be ({self.base.n_vertices}, 3) (one per base "
                                 f"vertex), got {d.shape}")
        if not np.isfinite(d).all():
            raise MicroMeshError("directions contain NaN or infinity")
        try:
            lv = as_levels(self.base, self.levels)
        except LevelError as e:
            raise MicroMeshError(str(e)) from None
        if not is_balanced(self.base, lv):
            raise MicroMeshError(f"levels must lie in 0..{MAX_LEVEL} and differ by at most one "
                                 "across every edge (use balance_levels or MicroMesh.flat)")
        if self._topology is not None and not np.array_equal(self._topology.levels, lv):
            raise MicroMeshError("cached topology does not match the levels")
        n = (self._topology.n_vertices if self._topology is not None
             else count_micro_vertices(self.base, lv))
        disp = np.ascontiguousarray(self.displacements, dtype=np.float64)
        if disp.shape != (n,):
            raise MicroMeshError(f"displacements must have one value per micro-vertex ({n}), "
                                 f"got shape {disp.shape}")
        if not np.isfinite(disp).all():
            raise MicroMeshError("displacements contain NaN or infinity")
        self.directions, self.levels, self.displacements = d, lv, disp

    # ----------------------------------------------------------------- construction
    @classmethod
    def flat(cls, base: TriMesh, levels, directions: np.ndarray | None = None) -> "MicroMesh":
        """Zero displacements; directions default to ``base.direction_normals``; the levels
        are balanced first (raised where needed)."""
        lv = balance_levels(base, levels)
        dirs = base.direction_normals if directions is None else directions
        return cls(base, dirs, lv, np.zeros(count_micro_vertices(base, lv)))

    def with_displacements(self, displacements: np.ndarray) -> "MicroMesh":
        return MicroMesh(self.base, self.directions, self.levels, displacements, self._topology)

    def with_base_positions(self, vertices: np.ndarray) -> "MicroMesh":
        return MicroMesh(self.base.with_vertices(vertices), self.directions, self.levels,
                         self.displacements, self._topology)

    def transformed(self, matrix: np.ndarray) -> "MicroMesh":
        """Base positions and directions through the linear map ``matrix`` (3, 3) (an axis
        change, a rotation): the same micro-mesh in another frame, topology kept."""
        m = np.asarray(matrix, dtype=np.float64)
        return MicroMesh(self.base.with_vertices(self.base.vertices @ m.T), self.directions @ m.T,
                         self.levels, self.displacements, self._topology)

    def with_directions(self, directions: np.ndarray) -> "MicroMesh":
        return MicroMesh(self.base, directions, self.levels, self.displacements, self._topology)

    @property
    def topology(self) -> MicroTopology:
        if self._topology is None:
            self._topology = build_topology(self.base, self.levels)
        return self._topology

    @property
    def n_vertices(self) -> int:
        return len(self.displacements)

    # -------------------------------------------------------------------- geometry
    def micro_vertex_base_positions(self) -> np.ndarray:
        """(n, 3) undisplaced micro-vertex positions lerp(P)."""
        return self.topology.interp @ self.base.vertices

    def micro_vertex_directions(self) -> np.ndarray:
        """(n, 3) interpolated, not normalised, directions lerp(D)."""
        return self.topology.interp @ self.directions

    def micro_vertex_positions(self) -> np.ndarray:
        """(n, 3) lerp(P) + lerp(D) · d."""
        return self.micro_vertex_base_positions() + \
            self.micro_vertex_directions() * self.displacements[:, None]

    def tessellate(self) -> Tessellation:
        t = self.topology
        return Tessellation(self.micro_vertex_positions(), t.triangles.copy(),
                            t.triangle_face.copy())

    def locate(self, faces: np.ndarray, bary: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Micro-triangle holding base-barycentric points: (q, 3) canonical vertex indices and
        (q, 3) weights, so the displaced surface point is Σ w_k · position_k.

        ``bary`` is (w, u, v) in base face ``faces``. Near decimated edges the snapped
        (actual) micro-triangles are used, so the weights reproduce the point exactly.
        """
        return locate(self.topology, np.asarray(faces, np.int64), np.asarray(bary, float))

    def surface_at(self, faces: np.ndarray, bary: np.ndarray) -> np.ndarray:
        """(q, 3) points of the displaced piecewise-linear surface at base barycentrics."""
        idx, w = self.locate(faces, bary)
        return np.einsum("qk,qkc->qc", w, self.micro_vertex_positions()[idx])

    # ------------------------------------------------------------------ resampling
    def with_levels(self, levels) -> "MicroMesh":
        """New levels (up or down, must be balanced), displacements resampled so the surface
        is kept: d = D·(X − P)/|D|² at each new vertex, X the old surface point."""
        return self.resampled(levels)[0]

    def resampled(self, levels) -> tuple["MicroMesh", np.ndarray]:
        """:meth:`with_levels`, and a mask over the new micro-vertices: True where the vertex
        was a micro-vertex before (it keeps its value exactly), False where it is new."""
        lv = as_levels(self.base, levels)
        if not is_balanced(self.base, lv):
            raise MicroMeshError("with_levels needs balanced levels (use balance_levels)")
        if np.array_equal(lv, self.levels):
            return self.with_displacements(self.displacements.copy()), np.ones(self.n_vertices, bool)
        topo = build_topology(self.base, lv)
        values, kept = _resampled_values(self, topo)
        return MicroMesh(self.base, self.directions, lv, values, topo), kept

    def subdivided(self, mask: np.ndarray | None = None) -> "MicroMesh":
        """Faces in ``mask`` (bool (nf,) or face indices; default all) go up one level
        (capped at ``BUILD_MAX_LEVEL``), then the levels are rebalanced and displacements
        resampled."""
        lv = self.levels.copy()
        if mask is None:
            lv += 1
        else:
            mk = np.asarray(mask)
            if mk.dtype == bool and mk.shape != lv.shape:
                raise MicroMeshError(f"mask must be ({len(lv)},) bool or face indices")
            lv[mk] += 1
        return self.with_levels(balance_levels(self.base, np.minimum(lv, BUILD_MAX_LEVEL)))

    # ---------------------------------------------------------------------- export
    def face_values(self, order: str = "umajor") -> tuple[np.ndarray, np.ndarray]:
        """Per-face displacement arrays as CSR (ptr (nf+1,), values): face f's values are
        ``values[ptr[f]:ptr[f+1]]`` in u-major or bird-curve order. Shared-edge values are
        bit-identical in both faces (one canonical vertex)."""
        t = self.topology
        if order == "umajor":
            return t.face_vertex_ptr.copy(), self.displacements[t.face_vertex_idx]
        if order != "bird":
            raise ValueError(f"order must be 'umajor' or 'bird', got {order!r}")
        perm = np.empty(len(t.face_vertex_idx), dtype=np.int64)
        for level in np.unique(t.levels):
            fl = np.flatnonzero(t.levels == level)
            bo = bird_order(int(level))
            base = t.face_vertex_ptr[fl][:, None]
            perm[(base + np.arange(len(bo))).reshape(-1)] = (base + bo[None, :]).reshape(-1)
        return t.face_vertex_ptr.copy(), self.displacements[t.face_vertex_idx[perm]]


def _resampled_values(mm: MicroMesh, topo: MicroTopology) -> tuple[np.ndarray, np.ndarray]:
    """The displacements of ``topo``'s micro-vertices (``mm``'s base, other levels) that keep
    ``mm``'s surface: d = D·(X − P)/|D|² at each new vertex, X the old surface point there
    (the old values, interpolated, where D is zero), and the old value itself where the vertex
    was a micro-vertex before. Returns (values (n,), kept (n,) bool: True where the vertex
    was one before)."""
    nb = topo.n_base_vertices
    out = np.zeros(topo.n_vertices)
    kept = np.zeros(topo.n_vertices, bool)
    out[:nb] = mm.displacements[:nb]  # base vertices keep their value (used or not)
    kept[:nb] = True
    sel = np.flatnonzero(topo.vertex_face >= 0)
    sel = sel[sel >= nb]
    if len(sel) == 0:
        return out, kept
    idx, w = locate(mm.topology, topo.vertex_face[sel], topo.vertex_bary[sel])
    old = mm.micro_vertex_positions()
    X = np.einsum("qk,qkc->qc", w, old[idx])
    P = topo.interp[sel] @ mm.base.vertices
    D = topo.interp[sel] @ mm.directions
    nn = (D * D).sum(1)
    lin = (w * mm.displacements[idx]).sum(1)
    d = np.where(nn > 1e-300, (D * (X - P)).sum(1) / np.maximum(nn, 1e-300), lin)
    k = w.argmax(1)
    same = w[np.arange(len(k)), k] >= 1.0 - 1e-12
    d[same] = mm.displacements[idx[np.arange(len(k)), k]][same]
    out[sel] = d
    kept[sel] = same
    return out, kept
