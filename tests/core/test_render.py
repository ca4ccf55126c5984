"""Renderer: visibility agreement between backends, API contracts, robustness."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from core.render.cameras import fibonacci_cameras
from core.render import (Raster, RenderError, interpolate, rasterize, reference_images, render,
                         render_loss)


def icosphere(subdivisions: int = 2, noise: float = 0.0, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Unit icosphere (optionally with radial noise): vertices (n, 3) float64, faces (m, 3) int64."""
    t = (1 + 5 ** 0.5) / 2
    v = [np.array(p, float) for p in [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t],
                                      [0, 1, t], [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1],
                                      [-t, 0, -1], [-t, 0, 1]]]
    f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
         [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9],
         [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    for _ in range(subdivisions):
        mids: dict[tuple[int, int], int] = {}

        def mid(a: int, b: int) -> int:
            k = (min(a, b), max(a, b))
            if k not in mids:
                mids[k] = len(v)
                v.append((v[a] + v[b]) / 2)
            return mids[k]

        nf = []
        for a, b, c in f:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            nf += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        f = nf
    vv = np.array(v)
    vv /= np.linalg.norm(vv, axis=1, keepdims=True)
    if noise:
        vv *= 1 + noise * np.random.default_rng(seed).standard_normal((len(vv), 1))
    return vv, np.array(f, dtype=np.int64)


def tensors(v: np.ndarray, f: np.ndarray, dtype=torch.float32) -> tuple[torch.Tensor, torch.Tensor]:
    return torch.tensor(v, dtype=dtype), torch.tensor(f, dtype=torch.int64)


@pytest.fixture(scope="module")
def sphere():
    return tensors(*icosphere(3, noise=0.03))


def test_triangle_ids_numba_equal_torch(sphere):
    v, f = sphere
    cams = fibonacci_cameras(6, width=96, height=80)
    a = rasterize(v, f, cams, backend="numba")
    b = rasterize(v, f, cams, backend="torch")
    assert a.tri_id.shape == (6, 80, 96) and a.tri_id.dtype == torch.int32
    agree = (a.tri_id == b.tri_id).float().mean().item()
    assert agree >= 0.9999
    cover = a.tri_id >= 0
    assert 0.3 < cover.float().mean() < 0.95
    assert torch.equal(a.depth[cover & (a.tri_id == b.tri_id)], b.depth[cover & (a.tri_id == b.tri_id)])
    d = a.depth[cover]
    assert float(d.min()) > 3.5 - 1.2 and float(d.max()) < 3.5 + 0.2  # view-space depth
    assert torch.isinf(a.depth[~cover]).all()


@pytest.mark.parametrize("fine_first", [True, False])
def test_sparse_and_dense_raster_batches_equal_torch(fine_first):
    """A mesh of a fine part (sub-pixel faces: the numba rasteriser's pre-pass batches) and a
    coarse part (faces over many pixels: the direct batches), in both orders, so that the
    switch happens mid-view either way; every pixel must still match the plain-torch z-buffer."""
    fv, ff = icosphere(5, noise=0.01)  # 20480 faces, about 0.1 px each at 64 px
    cv, cf = icosphere(4, noise=0.01)  # 5120 faces
    fv = fv * 0.6 + np.array([0.5, 0.0, 0.0])
    cv = cv * 1.4 - np.array([0.6, 0.0, 0.0])
    parts = [(fv, ff), (cv, cf)] if fine_first else [(cv, cf), (fv, ff)]
    v = np.concatenate([parts[0][0], parts[1][0]])
    f = np.concatenate([parts[0][1], parts[1][1] + len(parts[0][0])])
    vt, ft = tensors(v, f)
    for width in (64, 400):
        cams = fibonacci_cameras(4, width=width)
        a = rasterize(vt, ft, cams, backend="numba")
        b = rasterize(vt, ft, cams, backend="torch")
        assert torch.equal(a.tri_id, b.tri_id)
        assert torch.equal(a.depth, b.depth)
        assert (a.tri_id >= len(parts[0][1])).any() and (a.tri_id[a.tri_id >= 0] < len(parts[0][1])).any()


def test_shapes_and_kinds(sphere):
    v, f = sphere
    cams = fibonacci_cameras(2, width=32)
    r = rasterize(v, f, cams)
    assert isinstance(r, Raster)
    for kind, c in (("shaded", 3), ("flat", 3), ("normal", 3), ("mask", 1), ("depth", 1)):
        img = render(v, f, cams, kind=kind, raster=r)
        assert img.shape == (2, 32, 32, c) and torch.isfinite(img).all()
        hard = render(v, f, cams, kind=kind, raster=r, antialias=False)
        assert (hard[~r.mask] == 0).all() and (hard[r.mask].abs().sum(-1) > 0).all()
        assert 0 < (img != hard).any(-1).sum() < (~r.mask).sum()  # AA touches edge pixels only
    ref = reference_images(v, f, cams)
    assert ref.shape == (2, 32, 32, 3) and not ref.requires_grad
    with pytest.raises(RenderError):
        render(v, f, cams, kind="albedo")
    with pytest.raises(RenderError):
        render_loss(v, f, cams, torch.zeros(2, 31, 32, 3))
    with pytest.raises(RenderError):
        rasterize(v, f + len(v), cams)


def test_interpolated_positions_lie_on_the_pixel_rays(sphere):
    v, f = sphere
    v = v.double()
    cams = fibonacci_cameras(2, width=24)
    r = rasterize(v, f, cams)
    pos = interpolate(v, v, f, cams, raster=r)  # world position of each pixel's surface point
    hom = torch.cat([pos, torch.ones_like(pos[..., :1])], -1)
    clip = torch.einsum("bij,bhwj->bhwi", torch.from_numpy(cams.mvp), hom)
    m = r.mask
    ndc_x = clip[..., 0][m] / clip[..., 3][m]
    cols = torch.arange(24, dtype=torch.float64).expand(2, 24, 24)[m]
    assert torch.allclose(ndc_x, (cols + 0.5) / 12 - 1, atol=1e-9)
    depth = render(v, f, cams, kind="depth", raster=r, antialias=False)[..., 0]
    assert torch.allclose(clip[..., 3][m], depth[m], atol=1e-9)
    assert (pos[~m] == 0).all()


@pytest.mark.parametrize("kind", ["flat", "shaded"])
def test_reference_images_a_few_views_at_a_time_are_one_call_over_all(kind):
    """The reference images are rendered a few views per call (the rasteriser's buffers):
    bit for bit the images of one render over every view, in view order."""
    from core.render.api import _VIEWS_PER_CALL

    v, f = icosphere(3, noise=0.05)
    v, f = torch.as_tensor(v, dtype=torch.float32), torch.as_tensor(f)
    cams = fibonacci_cameras(2 * _VIEWS_PER_CALL + 1, 3.0, 40.0, 48)
    got = reference_images(v, f, cams, kind=kind)
    assert got.shape == (len(cams), 48, 48, 3) and float(got.max()) > 0
    with torch.no_grad():
        assert torch.equal(got, render(v, f, cams, kind=kind))
