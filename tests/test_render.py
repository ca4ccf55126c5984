"""Renderer: visibility agreement between backends, API contracts, robustness."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from core.cameras import fibonacci_cameras
from core.render import Raster, RenderError, rasterize, reference_images, render, render_loss
from core.threads import set_threads
from tests.render_meshes import icosphere, tensors


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


def test_shapes_and_kinds(sphere):
    v, f = sphere
    cams = fibonacci_cameras(2, width=32)
    r = rasterize(v, f, cams)
    assert isinstance(r, Raster)
    for kind, c in (("shaded", 3), ("normal", 3), ("mask", 1), ("depth", 1)):
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
