"""A UV atlas on the base mesh (xatlas) and which base face and barycentrics each texel sees.

Args/Returns in the texture's pixel grid: row y counts from the bottom (v = (y + 0.5) / H, as
in Blender and OpenGL), column x from the left (u = (x + 0.5) / W).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..mesh.trimesh import TriMesh


class AtlasError(ValueError):
    """A base mesh that cannot be unwrapped."""


@dataclass(eq=False)
class Atlas:
    """UVs of the base mesh: ``uv`` (m, 2) per atlas vertex, ``faces`` (nf, 3) into it (same
    face order as the base), ``vertex`` (m,) the base vertex each atlas vertex copies (seams
    split vertices)."""

    uv: np.ndarray
    faces: np.ndarray
    vertex: np.ndarray

    @property
    def corner_uv(self) -> np.ndarray:
        """(nf, 3, 2) the UVs of each face's corners."""
        return self.uv[self.faces]


def uv_atlas(base: TriMesh, resolution: int, padding: int = 4) -> Atlas:
    """Charts cut and packed by xatlas for a ``resolution``² texture with ``padding`` texels
    between charts (room for the bleed that keeps filtering off the seams). xatlas sizes its
    atlas by its own texel density and its UVs span the square on each axis: an atlas wider
    than the texture has its padding shrunk by as much on that axis, one narrower grown
    (other packings tried: ``docs/heightmaps.md``)."""
    import xatlas

    if base.n_faces == 0:
        raise AtlasError("the base mesh has no faces")
    atlas = xatlas.Atlas()
    atlas.add_mesh(base.vertices.astype(np.float32), base.faces.astype(np.uint32))
    pack = xatlas.PackOptions()
    pack.resolution, pack.padding, pack.bilinear = int(resolution), int(padding), True
    atlas.generate(xatlas.ChartOptions(), pack)
    vmap, faces, uv = atlas[0]
    if atlas.atlas_count != 1 or faces.shape != base.faces.shape:
        raise AtlasError(f"no room for the base's UVs: xatlas packed its {base.n_faces} faces "
                         f"into {atlas.atlas_count} textures")
    return Atlas(np.asarray(uv, np.float64), np.asarray(faces, np.int64),
                 np.asarray(vmap, np.int64))


# A map's size: a power of two (what mipmaps and every texture API take) within these.
MIN_RESOLUTION, MAX_RESOLUTION = 64, 16384


def checked_resolution(resolution) -> int:
    """``resolution`` as an int, refused (:class:`AtlasError`) unless it is a power of two
    within :data:`MIN_RESOLUTION`..:data:`MAX_RESOLUTION`."""
    r = int(resolution) if float(resolution).is_integer() else -1
    if not MIN_RESOLUTION <= r <= MAX_RESOLUTION or r & (r - 1):
        raise AtlasError(f"a map's resolution must be a power of two within "
                         f"{MIN_RESOLUTION}..{MAX_RESOLUTION}, got {resolution}")
    return r


def check_room(atlas: Atlas, resolution: int) -> float:
    """The charts' area in texels per base face at ``resolution``²; refused
    (:class:`AtlasError`) below one: a base with more faces than the map has texels for."""
    c = atlas.corner_uv * resolution
    area = 0.5 * np.abs((c[:, 1, 0] - c[:, 0, 0]) * (c[:, 2, 1] - c[:, 0, 1])
                        - (c[:, 2, 0] - c[:, 0, 0]) * (c[:, 1, 1] - c[:, 0, 1])).sum()
    per_face = float(area) / max(len(atlas.faces), 1)
    if per_face < 1.0:
        raise AtlasError(f"no room for the base's UVs: its {len(atlas.faces)} faces get "
                         f"{per_face:.2f} texels each at {resolution}²; use a larger "
                         "resolution or a coarser base")
    return per_face


# Texels that two faces' UV triangles both claim, as a fraction of the charts' area in texels,
# above which a given UV map is refused (mirrored or stacked islands: one texel, two places).
MAX_OVERLAP = 0.02


def atlas_from_uvs(base: TriMesh, corner_uv: np.ndarray, resolution: int) -> Atlas:
    """The base's own UV map as the atlas: ``corner_uv`` (nf, 3, 2) per face corner, a vertex
    split wherever its corners' UVs differ (the map's seams). Refused (:class:`AtlasError`)
    where the UVs are not finite, leave [0, 1]², or overlap (more than :data:`MAX_OVERLAP` of
    the charts' texels at ``resolution`` claimed twice): a texel must stand for one point."""
    uv = np.asarray(corner_uv, dtype=np.float64)
    if uv.shape != (base.n_faces, 3, 2) or not np.isfinite(uv).all():
        raise AtlasError(f"the UV map must be finite, (3, 2) per face ({base.n_faces}), "
                         f"got {uv.shape}")
    if uv.min() < -1e-6 or uv.max() > 1 + 1e-6:
        raise AtlasError("the UV map leaves the unit square (tiles or wrapping)")
    key = np.concatenate([base.faces.reshape(-1, 1).astype(np.float64), uv.reshape(-1, 2)], 1)
    rows, inv = np.unique(key, axis=0, return_inverse=True)
    atlas = Atlas(rows[:, 1:].copy(), inv.reshape(-1, 3).astype(np.int64),
                  rows[:, 0].astype(np.int64))
    c = uv * resolution
    area = 0.5 * np.abs((c[:, 1, 0] - c[:, 0, 0]) * (c[:, 2, 1] - c[:, 0, 1])
                        - (c[:, 2, 0] - c[:, 0, 0]) * (c[:, 1, 1] - c[:, 0, 1])).sum()
    covered = int((texel_faces(atlas, resolution, resolution)[0] >= 0).sum())
    if area > 0 and covered < (1.0 - MAX_OVERLAP) * area - 4.0 * resolution:
        raise AtlasError(f"the UV map overlaps itself ({1 - covered / area:.0%} of its area "
                         "twice): a baked texel would stand for two places")
    return atlas


def texel_faces(atlas: Atlas, width: int, height: int, chunk: int = 1 << 20
                ) -> tuple[np.ndarray, np.ndarray]:
    """(face (H, W) int64, -1 where no face; bary (H, W, 3) float64): the base face whose UV
    triangle holds each texel centre and the texel's (w, u, v) barycentrics in it."""
    face = np.full((height, width), -1, np.int64)
    bary = np.zeros((height, width, 3))
    c = atlas.corner_uv * np.array([width, height]) - 0.5          # texel-centre coordinates
    lo = np.clip(np.floor(c.min(1)).astype(np.int64), 0, [width - 1, height - 1])
    hi = np.clip(np.ceil(c.max(1)).astype(np.int64), 0, [width - 1, height - 1])
    area = (hi - lo + 1).prod(1)
    order = np.arange(len(c))
    start = 0
    while start < len(order):
        stop = start + max(1, int(np.searchsorted(np.cumsum(area[start:]), chunk)))
        _raster(c[start:stop], lo[start:stop], hi[start:stop], area[start:stop],
                np.arange(start, min(stop, len(c))), face, bary)
        start = stop
    return face, bary


def _raster(c, lo, hi, area, fid, face, bary) -> None:
    n = area.sum()
    owner = np.repeat(np.arange(len(c)), area)
    k = np.arange(n) - np.repeat(np.cumsum(area) - area, area)
    wbox = (hi - lo + 1)[:, 0]
    x = lo[owner, 0] + k % wbox[owner]
    y = lo[owner, 1] + k // wbox[owner]
    a, b, d = c[owner, 0], c[owner, 1], c[owner, 2]
    e1, e2 = b - a, d - a
    px, py = x - a[:, 0], y - a[:, 1]
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    ok = np.abs(det) > 1e-12
    det = np.where(ok, det, 1.0)
    u = (px * e2[:, 1] - py * e2[:, 0]) / det
    v = (e1[:, 0] * py - e1[:, 1] * px) / det
    w = 1.0 - u - v
    tol = -1e-9
    inside = ok & (u >= tol) & (v >= tol) & (w >= tol)
    x, y = x[inside], y[inside]
    face[y, x] = fid[owner[inside]]
    bary[y, x] = np.stack([w[inside], u[inside], v[inside]], 1)


def dilate(image: np.ndarray, filled: np.ndarray, texels: int) -> np.ndarray:
    """``image`` (H, W[, C]) with the unfilled texels within ``texels`` of a filled one set to
    the mean of their filled neighbours, ring by ring (padding across seams)."""
    img = image.copy()
    done = filled.copy()
    for _ in range(texels):
        acc = np.zeros_like(img, dtype=np.float64)
        cnt = np.zeros(done.shape)
        for dy, dx in ((0, 1), (0, -1), (1, 0), (-1, 0), (1, 1), (1, -1), (-1, 1), (-1, -1)):
            m = np.roll(done, (dy, dx), axis=(0, 1))
            v = np.roll(img, (dy, dx), axis=(0, 1))
            acc += v * (m[..., None] if img.ndim == 3 else m)
            cnt += m
        grow = ~done & (cnt > 0)
        if not grow.any():
            break
        c = cnt[grow][:, None] if img.ndim == 3 else cnt[grow]
        img[grow] = acc[grow] / c
        done = done | grow
    return img
