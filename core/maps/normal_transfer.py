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

from ..mesh import TriMesh
from ..micromesh import MicroMesh
from .atlas import dilate
from .bake import Maps, face_tangents, orthogonal_tangent, sample, unit, vertex_tangents
from .transfer import checked_image, checked_uv, source_points


def transfer_normal_map(mm: MicroMesh, maps: Maps, source: TriMesh, source_uv: np.ndarray,
                        image: np.ndarray, about_base: bool = False, padding: int = 4,
                        chunk: int = 1 << 20) -> np.ndarray:
    """The source's tangent-space normal map ``image`` (H, W, ≥3, row 0 at v = 0, RGB in
    [0, 1]) on ``maps``' atlas: (R, R, 3) float32, RGB = (n + 1) / 2 in the atlas' tangent
    frame. ``source_uv``: (source.n_faces, 3, 2) the UVs the map is laid out in."""
    uv = checked_uv(source, source_uv)
    img = checked_image(image)
    if img.shape[2] < 3:
        raise ValueError("a normal map needs three channels")
    src_t, src_sign = face_tangents(source.vertices[source.faces], uv)
    src_n = source.vertex_normals
    atlas_t = vertex_tangents(mm, maps.atlas)                 # (m, 4): tangent, sign
    res = maps.height.shape[0]
    out = np.zeros((res, res, 3))
    out[..., 2] = 1.0
    for p in source_points(mm, maps, source, chunk):
        N = unit(np.einsum("qk,qkc->qc", p.bary, src_n[source.faces[p.face]]))
        T, B = _frame(N, src_t[p.face], src_sign[p.face])
        at = np.einsum("qk,qkc->qc", p.bary, uv[p.face])
        t = sample(img[..., :3], at) * 2.0 - 1.0
        n = unit(t[:, :1] * T + t[:, 1:2] * B + t[:, 2:3] * N)
        corners = atlas_t[maps.atlas.faces[p.texel_face]]     # (q, 3, 4)
        Na = p.direction if about_base else N
        Ta, Ba = _frame(Na, np.einsum("qk,qkc->qc", p.texel_bary, corners[..., :3]),
                        corners[:, 0, 3])
        out[p.y, p.x] = np.stack([(n * Ta).sum(1), (n * Ba).sum(1), (n * Na).sum(1)], 1)
    return ((dilate(out, maps.filled, padding) + 1.0) * 0.5).astype(np.float32)


def _frame(N: np.ndarray, tangent: np.ndarray, sign: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray]:
    """(T, B) about unit normals ``N``: the unit tangent orthogonal to N, B = sign · N × T."""
    T = orthogonal_tangent(N, tangent)
    return T, np.cross(N, T) * np.asarray(sign, dtype=np.float64)[:, None]
