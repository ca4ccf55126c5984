"""Height and normal maps on a UV atlas of the base (core.maps)."""
from __future__ import annotations

import numpy as np
import pytest

from core.maps import bake_maps, dilate, rebuild_error, texel_faces, uv_atlas
from core.mesh.trimesh import TriMesh
from core.micro.micromesh import MicroMesh
from core.mesh.primitives import icosphere


@pytest.fixture(scope="module")
def bumpy() -> MicroMesh:
    base = TriMesh(*icosphere(2))
    mm = MicroMesh.flat(base, np.full(base.n_faces, 3))
    p = mm.micro_vertex_base_positions()
    return mm.with_displacements(0.04 * np.sin(6 * p[:, 0]) * np.cos(5 * p[:, 2]))


def test_texels_know_their_face_and_barycentrics(bumpy):
    atlas = uv_atlas(bumpy.base, 256)
    face, bary = texel_faces(atlas, 256, 256)
    filled = face >= 0
    assert 0.3 < filled.mean() < 0.95
    b = bary[filled]
    assert np.allclose(b.sum(1), 1) and (b > -1e-6).all()
    ys, xs = np.nonzero(filled)
    uv = np.einsum("qk,qkc->qc", b, atlas.corner_uv[face[filled]])
    np.testing.assert_allclose(uv, np.stack([(xs + 0.5) / 256, (ys + 0.5) / 256], 1), atol=1e-9)
    assert atlas.vertex.max() < bumpy.base.n_vertices and len(atlas.faces) == bumpy.base.n_faces


def test_flat_micromesh_gives_zero_height_and_straight_up_normals():
    base = TriMesh(np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.0]]),
                   np.array([[0, 1, 2], [0, 2, 3]]))
    maps = bake_maps(MicroMesh.flat(base, [2, 2]), 128)
    assert np.abs(maps.height).max() < 1e-9
    n = maps.normal[maps.filled] * 2 - 1
    np.testing.assert_allclose(n, np.tile([0, 0, 1.0], (len(n), 1)), atol=1e-6)
    # a coarse sphere: the facets lean away from the interpolated normals, as they should
    sphere = TriMesh(*icosphere(1))
    facets = bake_maps(MicroMesh.flat(sphere, np.full(sphere.n_faces, 1)), 128)
    assert np.abs(facets.height).max() < 1e-9
    assert (facets.normal[facets.filled][:, 2] * 2 - 1 < 0.999).any()


def test_height_map_rebuilds_the_micromesh_better_with_resolution(bumpy):
    errs = []
    for res in (128, 512):
        d = rebuild_error(bumpy, bake_maps(bumpy, res))
        errs.append(np.sqrt((d ** 2).mean()) / bumpy.base.bbox_diagonal)
    assert errs[1] < errs[0] / 2 and errs[1] < 1e-3, errs


def test_normals_tilt_the_way_the_surface_does():
    # one flat triangle in the xy plane with UVs = xy, displaced so the surface rises along +x:
    # the tangent-space normal leans towards -u
    base = TriMesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]]), np.array([[0, 1, 2]]))
    mm = MicroMesh.flat(base, [2])
    mm = mm.with_displacements(0.3 * mm.micro_vertex_base_positions()[:, 0])
    maps = bake_maps(mm, 64, padding=0)
    n = maps.normal[maps.filled] * 2 - 1
    expect = np.array([-0.3, 0.0, 1.0]) / np.hypot(0.3, 1.0)
    # the atlas may rotate the chart: compare the tilt's size and the z component
    assert np.allclose(n[:, 2], expect[2], atol=1e-6)
    assert np.allclose(np.hypot(n[:, 0], n[:, 1]), -expect[0], atol=1e-6)


def test_dilate_fills_rings_around_the_charts():
    img = np.zeros((9, 9))
    filled = np.zeros((9, 9), bool)
    img[4, 4], filled[4, 4] = 5.0, True
    out = dilate(img, filled, 2)
    assert out[2:7, 2:7].min() == 5.0 and out[0, 0] == 0.0


def _spherical_uv(points: np.ndarray) -> np.ndarray:
    p = points / np.linalg.norm(points, axis=-1, keepdims=True)
    return np.stack([0.5 + np.arctan2(p[..., 1], p[..., 0]) / (2 * np.pi),
                     0.5 + np.arcsin(np.clip(p[..., 2], -1, 1)) / np.pi], -1)


def test_the_source_texture_is_carried_onto_the_atlas(bumpy):
    """A source sphere textured through a latitude/longitude map (colours a smooth function
    of the UVs): each filled texel of the carried texture holds the colour the source shows
    at the texel's micro-surface point."""
    from core.maps import TransferError, transfer_texture

    src = TriMesh(*icosphere(5))
    uv = _spherical_uv(src.vertices[src.faces])
    seam = np.ptp(uv[..., 0], axis=1) > 0.5                  # faces across the date line
    uv[seam, :, 0] = np.where(uv[seam, :, 0] < 0.5, uv[seam, :, 0] + 1.0, uv[seam, :, 0])
    h, w = 256, 512
    yy, xx = np.mgrid[0:h, 0:w]
    v, u = (yy + 0.5) / h, (xx + 0.5) / w
    image = np.stack([v, 0.5 + 0.5 * np.sin(2 * np.pi * u), 0.5 + 0.5 * np.cos(2 * np.pi * u)], -1)
    flat = MicroMesh.flat(bumpy.base, bumpy.levels)          # on the sphere's own surface
    maps = bake_maps(flat, 256)
    color = transfer_texture(flat, maps, src, uv, image)
    assert color.shape == (256, 256, 3) and color.dtype == np.float32
    face, bary = texel_faces(maps.atlas, 256, 256)
    filled = face >= 0
    p = np.einsum("qk,qkc->qc", bary[filled], flat.base.vertices[flat.base.faces[face[filled]]])
    want_uv = _spherical_uv(p)
    want = np.stack([want_uv[:, 1], 0.5 + 0.5 * np.sin(2 * np.pi * want_uv[:, 0]),
                     0.5 + 0.5 * np.cos(2 * np.pi * want_uv[:, 0])], -1)
    # Away from the poles and the date line, where this test's own mapping is singular.
    fair = ((np.abs(p[:, 2]) < 0.9 * np.linalg.norm(p, axis=1))
            & (np.abs(want_uv[:, 0] - 0.5) < 0.4))
    err = np.abs(color[filled] - want).max(1)[fair]
    assert fair.mean() > 0.7
    assert np.median(err) < 0.005 and np.percentile(err, 99.9) < 0.02, np.percentile(err, [50, 99.9])
    with pytest.raises(TransferError):
        transfer_texture(flat, maps, src, uv[:-1], image)
    # Several textures at once (base colour, a one-channel roughness): each as if alone.
    from core.maps import transfer_textures

    rough = image[..., 1]
    both = transfer_textures(flat, maps, src, uv, [image, rough])
    assert np.array_equal(both[0], color) and both[1].shape == (256, 256, 1)
    assert np.array_equal(both[1][..., 0], color[..., 1])
    twice = transfer_textures(flat, maps, src, uv, [image, rough, image])   # colour and alpha
    assert twice[0] is twice[2] and np.array_equal(twice[0], color)
    assert np.array_equal(twice[1], both[1])
    with pytest.raises(TransferError):
        transfer_textures(flat, maps, src, uv, [image, np.zeros((1, 8))])


def _grid(n: int) -> TriMesh:
    """The unit square in the xy plane as an n x n grid of triangle pairs."""
    g = np.linspace(0.0, 1.0, n + 1)
    x, y = np.meshgrid(g, g, indexing="ij")
    v = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], 1)
    i = np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]
    a, b, c, d = i, i + n + 1, i + n + 2, i + 1
    return TriMesh(v, np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3),
                                      np.stack([a, c, d], -1).reshape(-1, 3)]))


@pytest.mark.parametrize("mirrored", [False, True])
def test_a_source_normal_map_is_carried_into_the_atlas_tangent_frame(mirrored):
    """A flat source whose UVs are turned a quarter (or mirrored) against the xy plane, with a
    constant tangent-space tilt: on the atlas the carried map, read in the atlas' own frame
    (+u and +v of its charts in 3D, worked out here from the atlas UVs), is the same
    object-space normal the source's map gives."""
    from core.maps import transfer_normal_map

    src = _grid(16)
    P = src.vertices[src.faces]
    if mirrored:        # u = x, v = -y: +u is +x, +v is -y
        uv, du, dv = np.stack([P[..., 0], -P[..., 1]], -1), [1.0, 0, 0], [0, -1.0, 0]
    else:               # u = y, v = 1 - x: +u is +y, +v is -x
        uv, du, dv = np.stack([P[..., 1], 1 - P[..., 0]], -1), [0, 1.0, 0], [-1.0, 0, 0]
    tilt = np.array([0.5, 0.2, 1.0]) / np.linalg.norm([0.5, 0.2, 1.0])
    image = np.broadcast_to((tilt + 1) / 2, (4, 4, 3)).copy()
    want = tilt[0] * np.array(du) + tilt[1] * np.array(dv) + tilt[2] * np.array([0, 0, 1.0])
    base = TriMesh(np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.0]]),
                   np.array([[0, 1, 2], [0, 2, 3]]))
    flat = MicroMesh.flat(base, [2, 2])
    maps = bake_maps(flat, 64, padding=2)
    carried = transfer_normal_map(flat, maps, src, uv, image)
    assert carried.shape == (64, 64, 3) and carried.dtype == np.float32
    face, bary = texel_faces(maps.atlas, 64, 64)
    filled = face >= 0
    n = carried[filled] * 2.0 - 1.0
    # +u and +v of each base face's chart in 3D: [e1 e2] = [∂P/∂u ∂P/∂v] [d1 d2]
    V, T = base.vertices[base.faces], maps.atlas.corner_uv
    E = np.stack([V[:, 1] - V[:, 0], V[:, 2] - V[:, 0]], -1)            # (f, 3, 2)
    D = np.stack([T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]], -1)            # (f, 2, 2)
    G = E @ np.linalg.inv(D)                                             # (f, 3, 2)
    Tu = G[..., 0] / np.linalg.norm(G[..., 0], axis=1, keepdims=True)
    Bv = G[..., 1] / np.linalg.norm(G[..., 1], axis=1, keepdims=True)
    f = face[filled]
    got = n[:, :1] * Tu[f] + n[:, 1:2] * Bv[f] + n[:, 2:3] * np.array([0, 0, 1.0])
    np.testing.assert_allclose(got, np.broadcast_to(want, got.shape), atol=2e-3)
    with pytest.raises(ValueError):
        transfer_normal_map(flat, maps, src, uv, image[..., :2])
    # On a flat base the base's frame is the surface's: the same map.
    np.testing.assert_allclose(transfer_normal_map(flat, maps, src, uv, image, about_base=True),
                               carried, atol=1e-6)


def test_about_the_base_the_carried_normal_map_holds_the_relief_too(bumpy):
    """On a displaced micro-mesh whose source has a flat normal map (0.5, 0.5, 1: no tilt),
    the map about the base is the micro-detail map ``bake_maps`` makes (the relief seen from
    the base), up to facet against smooth normals; about the surface it is flat."""
    from core.maps import transfer_normal_map

    src = bumpy.tessellate().to_trimesh()
    uv = src.vertices[src.faces][..., :2]                      # any UVs: the map is flat
    image = np.full((4, 4, 3), [0.5, 0.5, 1.0])
    maps = bake_maps(bumpy, 128)
    surface = transfer_normal_map(bumpy, maps, src, uv, image)[maps.filled] * 2 - 1
    base = transfer_normal_map(bumpy, maps, src, uv, image, about_base=True)[maps.filled] * 2 - 1
    relief = maps.normal[maps.filled] * 2 - 1
    assert np.allclose(surface, [0, 0, 1.0], atol=1e-6)
    tilt = np.degrees(np.arccos(np.clip((base * relief).sum(1), -1, 1)))
    assert np.median(tilt) < 3.0 and np.degrees(np.arccos(relief[:, 2].min())) > 10.0


def test_the_base_own_uv_map_is_the_atlas_with_its_seams():
    """A base that has UVs (its islands cut at x = 0.5, the right one moved apart) gives the
    atlas those UVs: the vertices on the cut split, the rest shared; the maps bake on it. UVs
    laid twice over one place (a mirrored half) or outside the unit square are refused."""
    from core.maps import AtlasError, atlas_from_uvs

    base = _grid(4)
    P = base.vertices[base.faces]
    right = P[..., 0].mean(1) > 0.5
    uv = 0.05 + 0.8 * P[..., :2]
    uv[right, :, 0] += 0.1
    atlas = atlas_from_uvs(base, uv, 256)
    np.testing.assert_array_equal(atlas.corner_uv, uv)
    np.testing.assert_array_equal(atlas.vertex[atlas.faces], base.faces)
    assert len(atlas.uv) == base.n_vertices + 5                 # the 5 vertices on the cut
    flat = MicroMesh.flat(base, np.full(base.n_faces, 2))
    maps = bake_maps(flat, 256, atlas=atlas)
    assert maps.atlas is atlas and 0.5 < maps.filled.mean() < 0.8
    mirrored = uv.copy()
    mirrored[right, :, 0] = 0.05 + 0.8 * (1.0 - P[right][..., 0])   # onto the left island
    with pytest.raises(AtlasError, match="overlaps"):
        atlas_from_uvs(base, mirrored, 256)
    with pytest.raises(AtlasError, match="unit square"):
        atlas_from_uvs(base, uv + 0.5, 256)
    with pytest.raises(AtlasError):
        atlas_from_uvs(base, uv[:-1], 256)
