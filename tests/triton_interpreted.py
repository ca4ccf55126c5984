"""Run by ``test_triton_interpreted.py`` in a process of its own with ``TRITON_INTERPRET=1``
(Triton's interpreter must be chosen before the kernels are defined): the CUDA path's Triton
kernels on CPU tensors against the plain torch path. Prints one line per check; exits non-zero
(an AssertionError) where one fails."""
from __future__ import annotations

import sys
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from core.render.cameras import fibonacci_cameras  # noqa: E402
from core.render import (fused_normals, fused_shade, geometry, rasterize, render_loss,  # noqa: E402
                         reference_images, torch_antialias, torch_path, torch_raster,
                         triton_kernels, triton_walk)
from core.render.types import camera_mvp  # noqa: E402
from tests.core.test_render import icosphere, tensors  # noqa: E402


def rel(a: torch.Tensor, b: torch.Tensor) -> float:
    return float((a - b).norm() / b.norm())


def main() -> None:
    fused = triton_kernels.available
    triton_kernels.available = lambda device: True       # the fused path on CPU tensors
    v, f = tensors(*icosphere(3, noise=0.03))
    v = v.double()
    cams = fibonacci_cameras(3, width=40)
    mvp = camera_mvp(cams, v.device)
    tri = torch_raster.rasterize_torch(v, f, mvp, 40, 40, fused=False)[0]
    g = torch.rand((3, 40, 40, 3), generator=torch.Generator().manual_seed(1), dtype=v.dtype)
    for kind in ("shaded", "flat"):
        out = []
        for use in (False, True):
            x = v.clone().requires_grad_(True)
            vn = geometry.vertex_normals(x, f) if kind == "shaded" else None
            img = torch_path.shade_torch(x, f, vn, mvp, tri, kind, fused=use)
            (img * g).sum().backward()
            out.append((img.detach(), x.grad))
        print(kind, "image", rel(out[1][0], out[0][0]), "gradient", rel(out[1][1], out[0][1]))
        assert rel(out[1][0], out[0][0]) < 1e-12 and rel(out[1][1], out[0][1]) < 1e-12
    x1, x2 = v.clone().requires_grad_(True), v.clone().requires_grad_(True)
    n1 = fused_normals.normal_sums(x1, f)
    fl = f.long()
    n2 = sum(torch.zeros_like(x2).index_add(0, fl[:, k], torch.linalg.cross(
        x2[fl[:, 1]] - x2[fl[:, 0]], x2[fl[:, 2]] - x2[fl[:, 0]])) for k in range(3))
    gn = torch.rand(v.shape, generator=torch.Generator().manual_seed(2), dtype=v.dtype)
    (n1 * gn).sum().backward()
    (n2 * gn).sum().backward()
    print("normal sums", rel(n1.detach(), n2.detach()), "gradient", rel(x1.grad, x2.grad))
    assert rel(n1.detach(), n2.detach()) < 1e-12 and rel(x1.grad, x2.grad) < 1e-12
    facing = triton_walk.facing(v, fl, mvp, 40, 40)
    assert torch.equal(facing, torch_antialias.face_facing(v, f, mvp, 40, 40))
    assert fused_shade.shade(v, f, None, mvp, tri, "flat") is not None
    # the whole loss: rasteriser, shading, facing and walk kernels against the plain path
    target = reference_images(v * 1.01, f, cams, backend="numba")
    runs = []
    for available in (lambda device: False, lambda device: True):
        triton_kernels.available = available
        x = v.clone().requires_grad_(True)
        r = rasterize(x, f, cams, backend="torch")
        loss = render_loss(x, f, cams, target, raster=r, backend="torch")
        loss.backward()
        runs.append((r.tri_id, float(loss.detach()), x.grad))
    print("loss", runs[0][1], runs[1][1], "gradient", rel(runs[1][2], runs[0][2]))
    assert torch.equal(runs[0][0], runs[1][0]) and abs(runs[0][1] - runs[1][1]) < 1e-12
    assert rel(runs[1][2], runs[0][2]) < 1e-9
    assert triton_kernels.failure is None, triton_kernels.failure
    triton_kernels.available = fused
    print("ok")


if __name__ == "__main__":
    main()
