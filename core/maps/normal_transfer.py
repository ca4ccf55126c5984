"""A tangent-space normal map of the source carried onto the base's atlas.

The source's map tilts its shading normal in the tangent frame of the source's UVs: at a
surface point, (x, y, z) = 2 · RGB − 1 means x·T + y·B + z·N with N the interpolated vertex
normal, T the direction of +u made orthogonal to N and B = ±(N × T) (− where the UVs are
mirrored). On the atlas, the same surface point has the atlas' tangent frame about the same
N: the carried map holds the same tilted normal in that frame. Applied through a normal-map
node on the displaced micro-surface (which follows the source), it tilts the shading as the
source's map did. ``about_base``: the frame is the base's instead (about its interpolated
direction, as ``bake``'s micro-detail map): for the undisplaced base of an engine, where the
map must carry the micro-surface's relief and the source's map together. The frames are
per-face UV gradients interpolated as ``bake`` does for the atlas, not MikkTSpace's: they
agree where the UVs are not strongly sheared.
"""
from __future__ import annotations

import numpy as np

from ..mesh.trimesh import TriMesh
from ..micro.micromesh import MicroMesh
from .atlas import dilate
from .bake import Maps, face_tangents, orthogonal_tangent, sample, unit, vertex_tangents
from .transfer import SourcePoints, checked_image


class NormalSink:
    """A tangent-space normal map of the source (H, W, >=3, RGB in [0, 1]) in the atlas'
    tangent frame, about the surface or, ``about_base``, about the base."""

    def __init__(self, mm: MicroMesh, maps: Maps, source: TriMesh, uv: np.ndarray, image,
                 about_base: bool = False) -> None:
        self.image = checked_image(image)
        if self.image.shape[2] < 3:
            raise ValueError("a normal map needs three channels")
        self.faces, self.atlas_faces, self.about_base = source.faces, maps.atlas.faces, about_base
        self.src_t, self.src_sign = face_tangents(source.vertices[source.faces], uv)
        self.src_n = source.vertex_normals
        self.atlas_t = vertex_tangents(mm, maps.atlas)                 # (m, 4): tangent, sign
        res = maps.height.shape[0]
        self.out = np.zeros((res, res, 3))
        self.out[..., 2] = 1.0

    def add(self, p: SourcePoints, at: np.ndarray) -> None:
        N = unit(np.einsum("qk,qkc->qc", p.bary, self.src_n[self.faces[p.face]]))
        T, B = _frame(N, self.src_t[p.face], self.src_sign[p.face])
        t = sample(self.image[..., :3], at) * 2.0 - 1.0
        n = unit(t[:, :1] * T + t[:, 1:2] * B + t[:, 2:3] * N)
        corners = self.atlas_t[self.atlas_faces[p.texel_face]]     # (q, 3, 4)
        Na = p.direction if self.about_base else N
        Ta, Ba = _frame(Na, np.einsum("qk,qkc->qc", p.texel_bary, corners[..., :3]),
                        corners[:, 0, 3])
        self.out[p.y, p.x] = np.stack([(n * Ta).sum(1), (n * Ba).sum(1), (n * Na).sum(1)], 1)

    def done(self, maps: Maps, padding: int) -> np.ndarray:
        return ((dilate(self.out, maps.filled, padding) + 1.0) * 0.5).astype(np.float32)


def _frame(N: np.ndarray, tangent: np.ndarray, sign: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray]:
    """(T, B) about unit normals ``N``: the unit tangent orthogonal to N, B = sign · N × T."""
    T = orthogonal_tangent(N, tangent)
    return T, np.cross(N, T) * np.asarray(sign, dtype=np.float64)[:, None]
