"""Height and normal maps on a UV atlas of the base (core.maps)."""
from __future__ import annotations

import numpy as np
import pytest

from core.maps import bake_maps, dilate, rebuild_error, texel_faces, uv_atlas
from core.mesh import TriMesh
from core.micromesh import MicroMesh
from core.primitives import icosphere


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
    with pytest.raises(TransferError):
        transfer_textures(flat, maps, src, uv, [image, np.zeros((1, 8))])
