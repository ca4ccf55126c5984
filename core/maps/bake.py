"""Height and normal maps of a micro-mesh on a UV atlas of its base: what most renderers and
engines can display today (a base mesh with UVs, a height map, a normal map).

Height at a surface point P of the base: the signed distance ``h`` along
``n = normalize(lerp(U))`` to the nearest crossing of the micro-surface (a ray cast both ways),
``U`` the unit vertex directions (``unit_directions``; exported as the base's normals, so a
renderer that displaces along interpolated vertex normals rebuilds the micro-surface). The
normal map holds the micro-triangles' normals in the tangent space of the base (the
interpolated vertex tangents of ``vertex_tangents``, +u of the UVs, orthogonalised against n;
bitangent n × tangent, flipped where the UVs are mirrored), encoded as RGB = (n + 1) / 2.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..spatial.bake import bake_displacements, nearest_points
from ..mesh.trimesh import TriMesh
from ..micro.micromesh import MicroMesh
from .atlas import Atlas, dilate, texel_faces, uv_atlas
from .lattice import DrawnSurface


@dataclass(eq=False)
class Maps:
    """The atlas and the maps, all (H, W[, C]) with row 0 at the bottom (v = 0)."""

    atlas: Atlas
    height: np.ndarray   # float32, world units
    normal: np.ndarray   # float32 in [0, 1], tangent space encoded
    filled: np.ndarray   # bool: texels inside a chart (the others are padding or empty)
    notes: dict = field(default_factory=dict)   # how the height map was made


def unit_directions(mm: MicroMesh) -> np.ndarray:
    """(nv, 3) the unit direction at each base vertex (the maps' vertex normals)."""
    d = mm.directions
    n = np.linalg.norm(d, axis=1, keepdims=True)
    return np.where(n > 0, d / np.maximum(n, 1e-300), mm.base.vertex_normals)


def base_point(base: TriMesh, U: np.ndarray, faces: np.ndarray, bary: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
    """(points (q, 3), unit directions (q, 3)) of the ``base`` surface at its ``faces`` (q,)
    and barycentrics ``bary`` (q, 3): where a map's texel sits and the way its height points
    (``U``: :func:`unit_directions`)."""
    tri = base.faces[faces]
    return (np.einsum("qk,qkc->qc", bary, base.vertices[tri]),
            unit(np.einsum("qk,qkc->qc", bary, U[tri])))


class MapsCancelled(RuntimeError):
    """``should_stop()`` turned true: no maps."""


def bake_maps(mm: MicroMesh, resolution: int = 2048, padding: int = 4,
              atlas: Atlas | None = None, chunk: int = 1 << 18,
              progress: Callable[[dict], None] = lambda p: None,
              should_stop: Callable[[], bool] = lambda: False) -> Maps:
    """Height and normal maps of ``mm`` at ``resolution``² on ``atlas`` (default: a new
    :func:`uv_atlas`), bled ``padding`` texels past the charts. ``progress`` gets
    ``{"phase": "maps", "iteration", "total"}``; :class:`MapsCancelled` once ``should_stop()``."""
    if not 16 <= int(resolution) <= 16384:
        raise ValueError(f"map resolution must be within 16..16384, got {resolution}")
    progress({"phase": "maps", "iteration": 0, "total": 1})
    atlas = atlas if atlas is not None else uv_atlas(mm.base, resolution, padding)
    face, bary = texel_faces(atlas, resolution, resolution)
    filled = face >= 0
    ys, xs = np.nonzero(filled)
    height = np.zeros(filled.shape)
    normal = np.zeros(filled.shape + (3,))
    normal[..., 2] = 1.0
    U = unit_directions(mm)
    tangents = vertex_tangents(mm, atlas)
    tess = mm.tessellate()
    surface = tess.to_trimesh()
    facet = surface.face_normals
    offsets = np.linalg.norm(tess.vertices - mm.micro_vertex_base_positions(), axis=1)
    reach = 2.0 * offsets.max(initial=0.0) + 1e-9 * mm.base.bbox_diagonal
    steps = range(0, len(ys), chunk)
    for i, s in enumerate(steps):
        if should_stop():
            raise MapsCancelled("map baking cancelled")
        progress({"phase": "maps", "iteration": i, "total": len(steps) + 1})
        y, x = ys[s:s + chunk], xs[s:s + chunk]
        f, b = face[y, x], bary[y, x]
        P, n = base_point(mm.base, U, f, b)
        hit = bake_displacements(P, n, surface, max_distance=reach)   # along ±n, nearest
        height[y, x] = hit.displacement
        normal[y, x] = _in_tangent_frame(facet[hit.face], n, tangents[atlas.faces[f]], b)
    height = dilate(height, filled, padding)
    normal = dilate(normal, filled, padding)
    return Maps(atlas, height.astype(np.float32), ((normal + 1.0) * 0.5).astype(np.float32),
                filled)


def drawn_normal_map(mm: MicroMesh, surface: DrawnSurface, atlas: Atlas, resolution: int,
                     padding: int = 4, chunk: int = 1 << 18,
                     should_stop: Callable[[], bool] = lambda: False
                     ) -> tuple[np.ndarray, np.ndarray]:
    """(normal (R, R, 3) float32 encoded, filled (R, R)): the normal map of ``surface``, what
    a height map on ``mm``'s base and unit directions draws (``core.maps.height_fit``), whose
    every point lies over its own base point: each texel holds the normal of the
    micro-triangle over its base point (:meth:`DrawnSurface.locate`, no ray), in the base's
    tangent frame as :func:`bake_maps` holds it."""
    face, bary = texel_faces(atlas, resolution, resolution)
    filled = face >= 0
    ys, xs = np.nonzero(filled)
    normal = np.zeros(filled.shape + (3,), np.float32)
    normal[..., 2] = 1.0
    U = unit_directions(mm)
    tangents = vertex_tangents(mm, atlas)
    for s in range(0, len(ys), chunk):
        if should_stop():
            raise MapsCancelled("map baking cancelled")
        y, x = ys[s:s + chunk], xs[s:s + chunk]
        f, b = face[y, x], bary[y, x]
        c = surface.X[surface.locate(f, b)[0]]
        m = unit(np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]))
        n = base_point(mm.base, U, f, b)[1]
        normal[y, x] = _in_tangent_frame(m, n, tangents[atlas.faces[f]], b)
    del face, bary
    return ((dilate(normal, filled, padding) + 1.0) * 0.5).astype(np.float32), filled


def _in_tangent_frame(m: np.ndarray, n: np.ndarray, tv: np.ndarray, b: np.ndarray
                      ) -> np.ndarray:
    """(q, 3) unit normals ``m`` in the tangent frame at base points of unit normal ``n``:
    the tangents ``tv`` (q, 3, 4) of the points' faces' atlas corners interpolated by ``b``
    (q, 3), made orthogonal to n; the bitangent n × t, its sign the corners'."""
    t = orthogonal_tangent(n, np.einsum("qk,qkc->qc", b, tv[..., :3]))
    bt = np.cross(n, t) * tv[:, 0, 3:4]
    return np.stack([(m * t).sum(1), (m * bt).sum(1), (m * n).sum(1)], 1)


def sample(image: np.ndarray, uv: np.ndarray, nearest: bool = False) -> np.ndarray:
    """Bilinear (or ``nearest``-texel) lookup of ``image`` (H, W[, C], row 0 at v = 0) at
    ``uv`` (q, 2), as a GPU samples a texture (clamped at the borders)."""
    h, w = image.shape[:2]
    x = np.clip(uv[:, 0] * w - 0.5, 0, w - 1)
    y = np.clip(uv[:, 1] * h - 0.5, 0, h - 1)
    if nearest:
        return image[np.rint(y).astype(np.int64), np.rint(x).astype(np.int64)]
    x0, y0 = np.minimum(x.astype(np.int64), w - 2), np.minimum(y.astype(np.int64), h - 2)
    fx, fy = x - x0, y - y0
    if image.ndim == 3:
        fx, fy = fx[:, None], fy[:, None]
    top = image[y0, x0] * (1 - fx) + image[y0, x0 + 1] * fx
    bot = image[y0 + 1, x0] * (1 - fx) + image[y0 + 1, x0 + 1] * fx
    return top * (1 - fy) + bot * fy


def rebuilt_positions(mm: MicroMesh, maps: Maps, nearest: bool = False) -> np.ndarray:
    """(n, 3) the micro-vertices as a renderer rebuilds them from the base and the height map:
    P + n·h(uv), at the same barycentrics (each micro-vertex seen from one face holding it)."""
    t = mm.topology
    f, b = t.vertex_face, t.vertex_bary
    used = f >= 0
    out = mm.micro_vertex_positions().copy()
    f, b = f[used], b[used]
    P, n = base_point(mm.base, unit_directions(mm), f, b)
    uv = np.einsum("qk,qkc->qc", b, maps.atlas.corner_uv[f])
    out[used] = P + n * sample(maps.height.astype(np.float64), uv, nearest)[:, None]
    return out


def vertex_tangents(mm: MicroMesh, atlas: Atlas) -> np.ndarray:
    """(m, 4) per atlas vertex: the unit tangent (+u, the faces' around it summed and made
    orthogonal to the unit direction) and ±1 for the bitangent, as glTF's TANGENT; baking and
    renderers interpolate the same vectors."""
    tangent, sign = _face_tangents(mm, atlas)
    m = len(atlas.uv)
    t = np.zeros((m, 3))
    s = np.zeros(m)
    for k in range(3):
        np.add.at(t, atlas.faces[:, k], tangent)
        np.add.at(s, atlas.faces[:, k], sign)
    t = orthogonal_tangent(unit_directions(mm)[atlas.vertex], t)
    return np.concatenate([t, np.where(s < 0, -1.0, 1.0)[:, None]], 1)


def orthogonal_tangent(n: np.ndarray, tangent: np.ndarray) -> np.ndarray:
    """(q, 3) ``tangent`` made orthogonal to the unit normals ``n`` and unit; where it has no
    part orthogonal to n (no UV gradient), any unit perpendicular."""
    t = tangent - n * (tangent * n).sum(1, keepdims=True)
    bad = np.linalg.norm(t, axis=1) < 1e-12
    if bad.any():
        alt = np.where(np.abs(n[bad, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
        t[bad] = np.cross(n[bad], alt)
    return unit(t)


def rebuild_error(mm: MicroMesh, maps: Maps, nearest: bool = False) -> np.ndarray:
    """(n,) distance from each point of :func:`rebuilt_positions` to the micro-surface: how far
    the surface a renderer rebuilds from the base and the height map lies from the micro-mesh
    (zero for an exact map: the rebuilt points need not be the micro-vertices)."""
    _, _, d = nearest_points(rebuilt_positions(mm, maps, nearest), mm.tessellate().to_trimesh())
    return d


def _face_tangents(mm: MicroMesh, atlas: Atlas) -> tuple[np.ndarray, np.ndarray]:
    return face_tangents(mm.base.vertices[mm.base.faces], atlas.corner_uv)


def face_tangents(V: np.ndarray, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per triangle of corners ``V`` (m, 3, 3) and corner UVs ``T`` (m, 3, 2): the direction of
    +u in 3D (not normalised; zero without a UV gradient) and ±1 (mirrored UVs: -1)."""
    e1, e2 = V[:, 1] - V[:, 0], V[:, 2] - V[:, 0]
    d1, d2 = T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]
    det = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
    r = np.where(np.abs(det) > 1e-20, 1.0 / np.where(det == 0, 1, det), 0.0)
    tangent = (e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) * r[:, None]
    return tangent, np.where(det < 0, -1.0, 1.0)


def unit(v: np.ndarray) -> np.ndarray:
    """Rows of ``v`` scaled to length 1 (zero rows stay zero)."""
    n = np.linalg.norm(v, axis=1, keepdims=True)
    return v / np.maximum(n, 1e-300)
