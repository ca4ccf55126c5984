"""Per-base-vertex direction bounds and the prismoid shell they span.

With bounds (bias b, scale s) a micro-vertex is stored as a value t in [0, 1]:
position = lerp(P + D·b) + lerp(D·s) · t (``docs/micromesh-format.md``). Tight bounds make a
thin shell: fast ray tracing and fine quantisation. The shell volume (sum of the prismoids
between the t = 0 and t = 1 triangles) is the metric of ``docs/method.md`` §7.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .micromesh import MicroMesh


class BoundsError(ValueError):
    """Bounds that do not fit the mesh."""


@dataclass(eq=False)
class DirectionBounds:
    """Per base vertex: displacement range [bias, bias + scale]."""

    bias: np.ndarray   # (nv,)
    scale: np.ndarray  # (nv,)

    def __post_init__(self) -> None:
        self.bias = np.ascontiguousarray(self.bias, dtype=np.float64)
        self.scale = np.ascontiguousarray(self.scale, dtype=np.float64)
        if self.bias.ndim != 1 or self.bias.shape != self.scale.shape:
            raise BoundsError(f"bias and scale must be (nv,) arrays of one shape, got "
                              f"{self.bias.shape} and {self.scale.shape}")


def tight_bounds(mm: MicroMesh, min_scale: float = 1e-6) -> DirectionBounds:
    """For each base vertex, min and max displacement over all micro-vertices of the base
    faces around it: bias = min, scale = max − min (at least ``min_scale``)."""
    t = mm.topology
    vals = mm.displacements[t.face_vertex_idx]
    starts = t.face_vertex_ptr[:-1]
    fmin, fmax = np.minimum.reduceat(vals, starts), np.maximum.reduceat(vals, starts)
    nv = mm.base.n_vertices
    vmin, vmax = np.full(nv, np.inf), np.full(nv, -np.inf)
    for i in range(3):
        np.minimum.at(vmin, mm.base.faces[:, i], fmin)
        np.maximum.at(vmax, mm.base.faces[:, i], fmax)
    unused = ~np.isfinite(vmin)
    vmin[unused], vmax[unused] = 0.0, 0.0
    return DirectionBounds(vmin, np.maximum(vmax - vmin, min_scale))


def reach(mm: MicroMesh) -> np.ndarray:
    """(nv,) per base vertex, the length its micro-vertices' displacements span along its
    direction (its tight bounds' range times |D|): its share of the shell's thickness."""
    return tight_bounds(mm, 0.0).scale * np.linalg.norm(mm.directions, axis=1)


def normalized_values(mm: MicroMesh, bounds: DirectionBounds, clip: bool = True) -> np.ndarray:
    """(n,) value t per micro-vertex with lerp(P + D·b) + lerp(D·s)·t closest (least squares
    along lerp(D·s)) to its position; clipped to [0, 1] unless ``clip`` is False (then values
    outside show where varying directions leave the shell)."""
    nv = mm.base.n_vertices
    if bounds.bias.shape != (nv,):
        raise BoundsError(f"bounds must have one entry per base vertex ({nv})")
    interp = mm.topology.interp
    D = mm.directions
    Q = interp @ (mm.base.vertices + D * bounds.bias[:, None])
    S = interp @ (D * bounds.scale[:, None])
    r = mm.micro_vertex_positions() - Q
    nn = (S * S).sum(1)
    t = (S * r).sum(1) / np.maximum(nn, 1e-300)
    t = np.where(nn > 1e-300, t, 0.0)
    return np.clip(t, 0.0, 1.0) if clip else t


def prismoid_volumes(base_vertices: np.ndarray, faces: np.ndarray, directions: np.ndarray,
                     bounds: DirectionBounds) -> np.ndarray:
    """(nf,) volume between the t = 0 triangle (P + D·b) and the t = 1 triangle
    (P + D·(b + s)) of each face, as three tetrahedra (absolute volumes)."""
    P = np.asarray(base_vertices, dtype=np.float64)
    D = np.asarray(directions, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    if P.shape != D.shape or P.ndim != 2 or P.shape[1] != 3:
        raise BoundsError("base_vertices and directions must both be (nv, 3)")
    if bounds.bias.shape != (len(P),):
        raise BoundsError(f"bounds must have one entry per base vertex ({len(P)})")
    A = P + D * bounds.bias[:, None]
    B = A + D * bounds.scale[:, None]
    a0, a1, a2 = A[f[:, 0]], A[f[:, 1]], A[f[:, 2]]
    b0, b1, b2 = B[f[:, 0]], B[f[:, 1]], B[f[:, 2]]

    def tet(p, q, r, s):
        return np.abs(np.einsum("ij,ij->i", q - p, np.cross(r - p, s - p))) / 6.0

    return tet(a0, a1, a2, b0) + tet(a1, a2, b0, b1) + tet(a2, b0, b1, b2)


def shell_volume(base_vertices: np.ndarray, faces: np.ndarray, directions: np.ndarray,
                 bounds: DirectionBounds) -> float:
    """Sum of :func:`prismoid_volumes`."""
    return float(prismoid_volumes(base_vertices, faces, directions, bounds).sum())


def micromesh_shell_volume(mm: MicroMesh, bounds: DirectionBounds | None = None) -> float:
    """Shell volume of a micro-mesh under its tight bounds (or the given ones)."""
    b = tight_bounds(mm) if bounds is None else bounds
    return shell_volume(mm.base.vertices, mm.base.faces, mm.directions, b)


def unit_bounds(n: int) -> DirectionBounds:
    """Bias 0, scale 1 for ``n`` vertices: the bounds of a :func:`baked` micro-mesh."""
    return DirectionBounds(np.zeros(n), np.ones(n))


def baked(mm: MicroMesh, bounds: DirectionBounds) -> MicroMesh:
    """The micro-mesh with its bounds folded into the base and the directions, as
    micromesh-tools writes its files: base P + D·bias, directions D·scale, each micro-vertex
    the value t in [0, 1] of :func:`normalized_values`. Under bounds that differ from vertex
    to vertex a file cannot say every position of ``mm`` exactly (the interpolated D·scale is
    not parallel to the interpolated D); the baked micro-mesh is what a file holds, and
    :func:`unit_bounds` express it exactly."""
    t = normalized_values(mm, bounds)
    base = mm.base.with_vertices(mm.base.vertices + mm.directions * bounds.bias[:, None])
    return MicroMesh(base, mm.directions * bounds.scale[:, None], mm.levels, t, mm._topology)
