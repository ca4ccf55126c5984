"""Renderer gradients: finite differences of interpolation, shading and antialiasing w.r.t. the
vertex positions (float64), silhouette-gradient sign, thread-count independence, robustness,
CPU/CUDA agreement."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from core.render.cameras import Cameras, fibonacci_cameras, look_at, perspective
from core.render import pixel_error, rasterize, render, render_loss
from core.render import scatter
from core.runtime.threads import set_threads
from tests.conftest import CUDA
from tests.core.test_render import icosphere, tensors

BACKENDS = ["numba", "torch"]


def front_camera(size: int = 24, eye=(0.0, 0.0, 3.0)) -> Cameras:
    view = look_at(np.array(eye), np.zeros(3), np.array([0.0, 1.0, 0.0]))
    return Cameras(view[None], perspective(40.0, 1.0, 0.5, 10.0)[None], size, size)


def fd_check(fn, verts: torch.Tensor, coords: list[tuple[int, int]], eps: float = 1e-6):
    """(analytic, central finite difference) of scalar fn(verts) at the listed coordinates."""
    v = verts.clone().requires_grad_(True)
    fn(v).backward()
    ana, num = [], []
    for i, j in coords:
        vp, vm = verts.clone(), verts.clone()
        vp[i, j] += eps
        vm[i, j] -= eps
        with torch.no_grad():
            num.append(float(fn(vp) - fn(vm)) / (2 * eps))
        ana.append(float(v.grad[i, j]))
    return np.array(ana), np.array(num)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("kind", ["shaded", "flat", "normal", "depth"])
def test_interpolation_gradients_match_finite_differences(backend, kind):
    v, f = tensors(*icosphere(1, noise=0.05), dtype=torch.float64)
    cams = fibonacci_cameras(2, width=20)
    r = rasterize(v, f, cams, backend=backend)  # fixed visibility: the smooth part only
    w = torch.randn((2, 20, 20, 1 if kind == "depth" else 3), generator=torch.Generator().manual_seed(1),
                    dtype=torch.float64)
    fn = lambda x: (render(x, f, cams, kind=kind, raster=r, antialias=False, backend=backend) * w).sum()
    coords = [(i, j) for i in range(0, len(v), 5) for j in range(3)]
    ana, num = fd_check(fn, v, coords)
    assert np.abs(ana).max() > 1e-3
    np.testing.assert_allclose(ana, num, rtol=1e-5, atol=1e-6 * np.abs(num).max())


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("kind", ["shaded", "flat", "mask"])
def test_antialias_gradients_match_finite_differences(backend, kind):
    # a single triangle in front of the background, and a sphere with occlusion edges
    tri_v = torch.tensor([[-0.61, -0.43, 0.0], [0.57, -0.52, 0.1], [0.07, 0.66, -0.1]], dtype=torch.float64)
    cases = [(tri_v, torch.tensor([[0, 1, 2]]), front_camera(24)),
             (*tensors(*icosphere(1, noise=0.05), dtype=torch.float64), fibonacci_cameras(2, width=20))]
    for v, f, cams in cases:
        r = rasterize(v, f, cams, backend=backend)
        shape = tuple(r.tri_id.shape) + ((1,) if kind == "mask" else (3,))
        w = torch.randn(shape, generator=torch.Generator().manual_seed(2), dtype=torch.float64)
        fn = lambda x: (render(x, f, cams, kind=kind, raster=r, backend=backend) * w).sum()
        coords = [(i, j) for i in range(len(v)) for j in range(3)][:60]
        ana, num = fd_check(fn, v, coords)
        assert np.abs(ana).max() > 1e-2
        np.testing.assert_allclose(ana, num, rtol=1e-4, atol=1e-5 * np.abs(num).max())


def subdivided_triangle(corners: torch.Tensor, n: int) -> tuple[torch.Tensor, torch.Tensor]:
    """The triangle split into n^2 coplanar faces (n segments per edge), consistently oriented."""
    idx, pts = {}, []
    for i in range(n + 1):
        for j in range(n + 1 - i):
            idx[i, j] = len(pts)
            pts.append(corners[0] + (corners[1] - corners[0]) * i / n + (corners[2] - corners[0]) * j / n)
    faces = []
    for i in range(n):
        for j in range(n - i):
            faces.append([idx[i, j], idx[i + 1, j], idx[i, j + 1]])
            if i + j < n - 1:
                faces.append([idx[i + 1, j], idx[i + 1, j + 1], idx[i, j + 1]])
    return torch.stack(pts), torch.tensor(faces)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("segments", [1, 24])  # 24: faces smaller than a pixel (the walk)
def test_translated_triangle_changes_coverage_and_gradient_sign(backend, segments):
    cams = front_camera(32)
    corners = torch.tensor([[-0.5, -0.45, 0.0], [0.45, -0.4, 0.0], [0.0, 0.5, 0.0]], dtype=torch.float64)
    base, f = subdivided_triangle(corners, segments)
    right = torch.zeros((1, 32, 32, 1), dtype=torch.float64)
    right[:, :, 16:] = 1.0  # loss: coverage of the right half of the picture

    def coverage(tx: float, with_grad: bool = False):
        v = (base + torch.tensor([tx, 0.0, 0.0], dtype=torch.float64)).requires_grad_(with_grad)
        cov = (render(v, f, cams, kind="mask", backend=backend) * right).sum()
        if with_grad:
            cov.backward()
            return float(cov.detach()), float(v.grad[:, 0].sum())
        return float(cov), None

    c0, g = coverage(0.0, True)
    px = 2 * 3.0 * np.tan(np.radians(20.0)) / 32  # world size of a pixel at the triangle
    c_plus, c_minus = coverage(2 * px)[0], coverage(-2 * px)[0]
    assert c_minus < c0 < c_plus  # moving right covers more of the right half
    fd = (c_plus - c_minus) / (4 * px)
    assert g > 0
    assert abs(g - fd) < 0.2 * fd
    # the antialiased mask's total is close to the exact projected area
    full = float(render(base, f, cams, kind="mask", backend=backend).sum())
    hard = float(render(base, f, cams, kind="mask", antialias=False, backend=backend).sum())
    e1, e2 = (corners[1] - corners[0]).numpy(), (corners[2] - corners[0]).numpy()
    area = 0.5 * abs(e1[0] * e2[1] - e1[1] * e2[0]) / px ** 2
    assert abs(full - area) < abs(hard - area) + 1.0 and abs(full - area) < 0.05 * area


def test_results_do_not_depend_on_thread_count():
    v, f = tensors(*icosphere(3, noise=0.03))
    cams = fibonacci_cameras(4, width=48)
    target = torch.rand((4, 48, 48, 3), generator=torch.Generator().manual_seed(0))
    out = []
    try:
        for n in (1, 2):
            set_threads(n)
            x = v.clone().requires_grad_(True)
            r = rasterize(x, f, cams)
            loss = render_loss(x, f, cams, target, raster=r)
            loss.backward()
            out.append((r.tri_id, float(loss.detach()), x.grad))
    finally:
        set_threads()
    assert torch.equal(out[0][0], out[1][0])
    assert out[0][1] == out[1][1]
    assert torch.equal(out[0][2], out[1][2])


@pytest.mark.parametrize("backend", BACKENDS)
def test_empty_views_inside_camera_and_degenerate_faces_give_no_nans(backend):
    v, f = tensors(*icosphere(2, noise=0.02))
    # degenerate faces: repeated vertex, and three collinear vertices
    extra_v = torch.tensor([[0.0, 0.0, 1.2], [0.1, 0.0, 1.2], [0.2, 0.0, 1.2]])
    v = torch.cat([v, extra_v])
    n = len(v)
    f = torch.cat([f, torch.tensor([[0, 0, 1], [n - 3, n - 2, n - 1], [5, 5, 5]])])
    away = Cameras(look_at(np.array([0.0, 0.0, 5.0]), np.array([0.0, 0.0, 10.0]),
                           np.array([0.0, 1.0, 0.0]))[None], perspective(30, 1, 0.1, 20)[None], 24, 24)
    inside = fibonacci_cameras(3, radius=0.3, width=24)
    for cams in (away, inside, fibonacci_cameras(3, width=24)):
        x = v.clone().requires_grad_(True)
        r = rasterize(x, f, cams, backend=backend)
        if cams is away:
            assert (r.tri_id < 0).all()
        if cams is inside:
            assert (r.tri_id >= 0).float().mean() > 0.5  # the inside of the sphere is visible
        target = torch.rand((len(cams), 24, 24, 3), generator=torch.Generator().manual_seed(3))
        loss = render_loss(x, f, cams, target, raster=r, backend=backend)
        loss.backward()
        assert torch.isfinite(loss) and torch.isfinite(x.grad).all()
        for kind in ("normal", "depth", "mask", "flat"):
            img = render(x, f, cams, kind=kind, raster=r, backend=backend)
            assert torch.isfinite(img).all()
        flat = render_loss(x, f, cams, target, raster=r, kind="flat", backend=backend)
        x.grad = None
        flat.backward()
        assert torch.isfinite(flat) and torch.isfinite(x.grad).all()
        err = pixel_error(x, f, cams, target, raster=r, backend=backend)
        assert err.shape == (len(cams), 24, 24) and torch.isfinite(err).all()


def test_numba_and_torch_backends_agree():
    v, f = tensors(*icosphere(3, noise=0.03), dtype=torch.float64)
    cams = fibonacci_cameras(3, width=40)
    target = torch.rand((3, 40, 40, 3), generator=torch.Generator().manual_seed(4), dtype=torch.float64)
    r = rasterize(v, f, cams)
    res = []
    for be in BACKENDS:
        x = v.clone().requires_grad_(True)
        loss = render_loss(x, f, cams, target, raster=r, backend=be)
        loss.backward()
        res.append((float(loss.detach()), x.grad))
    assert abs(res[0][0] - res[1][0]) < 1e-12
    torch.testing.assert_close(res[0][1], res[1][1], rtol=1e-9, atol=1e-12)
    flat = []
    for be in BACKENDS:
        x = v.clone().requires_grad_(True)
        render_loss(x, f, cams, target, raster=r, kind="flat", backend=be).backward()
        flat.append(x.grad)
    torch.testing.assert_close(flat[0], flat[1], rtol=1e-9, atol=1e-12)
    for kind in ("shaded", "flat", "normal", "mask", "depth"):  # the un-fused images too
        a, b = (render(v, f, cams, kind=kind, raster=r, backend=be) for be in BACKENDS)
        torch.testing.assert_close(a, b, rtol=1e-9, atol=1e-12)


def test_the_ordered_gather_has_the_gather_gradient():
    src = torch.randn(7, 3, dtype=torch.float64, requires_grad=True)
    index = torch.tensor([[0, 3, 3], [6, 0, 0], [3, 3, 3]])
    assert torch.equal(scatter._Gather.apply(src, index), src[index])
    assert torch.autograd.gradcheck(lambda x: scatter._Gather.apply(x, index), (src,))


@CUDA
@pytest.mark.gpu
@pytest.mark.parametrize("kind", ["shaded", "flat"])
def test_cuda_gradients_are_the_same_on_every_run(kind):
    """Colliding rows (a vertex shared by many pixels' faces, pixels on several silhouette
    pairs) are added in a fixed order on CUDA: the same loss and gradient, bit for bit."""
    v, f = tensors(*icosphere(4, noise=0.03))
    cams = fibonacci_cameras(8, width=128)
    v, f = v.cuda(), f.cuda()
    target = torch.rand((8, 128, 128, 3), generator=torch.Generator().manual_seed(2)).cuda()
    r = rasterize(v, f, cams)
    runs = []
    for _ in range(3):
        x = v.clone().requires_grad_(True)
        loss = render_loss(x, f, cams, target, raster=r, kind=kind)
        loss.backward()
        runs.append((loss.detach(), x.grad))
    for loss, grad in runs[1:]:
        assert torch.equal(loss, runs[0][0]) and torch.equal(grad, runs[0][1])


@CUDA
@pytest.mark.gpu
def test_cuda_fused_kernels_agree_with_the_plain_torch_path():
    """The rasteriser's pixel loop and the antialiasing walk as Triton kernels give the plain
    torch path's coverage and images (sub-pixel faces: long walks)."""
    from core.render import torch_antialias, torch_raster
    from core.render.topology import face_neighbours
    from core.render.types import camera_mvp

    if not torch_raster.fused_default(torch.device("cuda")):
        pytest.skip("Triton is not installed")
    v, f = tensors(*icosphere(6, noise=0.03))          # 82k faces
    v, f = v.cuda(), f.cuda()
    for width in (64, 256):
        cams = fibonacci_cameras(6, width=width)
        mvp = camera_mvp(cams, v.device)
        plain = torch_raster.rasterize_torch(v, f, mvp, width, width, fused=False)
        fused = torch_raster.rasterize_torch(v, f, mvp, width, width, fused=True)
        assert (plain[0] == fused[0]).float().mean() >= 0.9999
        img = render(v, f, cams, kind="shaded", antialias=False)
        nbr = face_neighbours(f)
        a = torch_antialias.antialias_torch(img, v, f, nbr, mvp, plain[0], plain[1], fused=False)
        b = torch_antialias.antialias_torch(img, v, f, nbr, mvp, plain[0], plain[1], fused=True)
        changed = (a != img).any(-1)
        assert changed.sum() > 100
        assert ((a - b).abs().amax(-1) > 1e-5).float().mean() < 1e-4
    from core.render import triton_kernels

    assert triton_kernels.failure is None, triton_kernels.failure


@CUDA
@pytest.mark.gpu
@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_cuda_fused_shading_and_normals_agree_with_the_plain_torch_path(dtype):
    """The shading ("shaded", "flat") and the vertex normals as Triton kernels with their
    fixed-order backward give the plain torch path's images and gradients (the plain path in
    float64: the kernels compute in float64 whatever the vertices' type)."""
    from core.render import fused_normals, fused_shade, geometry, torch_path, torch_raster
    from core.render.types import camera_mvp

    if not torch_raster.fused_default(torch.device("cuda")):
        pytest.skip("Triton is not installed")
    v, f = tensors(*icosphere(5, noise=0.03))
    v, f = v.cuda().to(dtype), f.cuda()
    cams = fibonacci_cameras(5, width=96)
    mvp = camera_mvp(cams, v.device)
    tri = torch_raster.rasterize_torch(v, f, mvp, 96, 96)[0]
    g = torch.randn((5, 96, 96, 3), generator=torch.Generator().manual_seed(3)).cuda().to(dtype)
    tol = dict(rtol=1e-5, atol=1e-6) if dtype == torch.float32 else dict(rtol=1e-9, atol=1e-12)
    for kind in ("shaded", "flat"):
        out = []
        for fused in (False, True):
            x = (v.double() if not fused else v).clone().requires_grad_(True)
            vn = geometry.vertex_normals(x, f) if kind == "shaded" else None
            img = torch_path.shade_torch(x, f, vn, mvp, tri, kind, fused=fused)
            (img * g.to(x.dtype)).sum().backward()
            out.append((img.detach().to(dtype), x.grad.to(dtype)))
        torch.testing.assert_close(out[1][0], out[0][0], **tol)
        err = float((out[1][1] - out[0][1]).norm() / out[0][1].norm())
        assert err < (1e-5 if dtype == torch.float32 else 1e-12), (kind, err)
    x1, x2 = v.clone().requires_grad_(True), v.clone().requires_grad_(True)
    n1 = fused_normals.normal_sums(x1, f)
    assert n1 is not None
    f64 = f.long()
    n2 = torch.zeros_like(x2)
    for k in range(3):
        n2 = n2.index_add(0, f64[:, k], torch.linalg.cross(x2[f64[:, 1]] - x2[f64[:, 0]],
                                                            x2[f64[:, 2]] - x2[f64[:, 0]]))
    gn = torch.randn_like(n1)
    (n1 * gn).sum().backward()
    (n2 * gn).sum().backward()
    torch.testing.assert_close(n1.detach(), n2.detach(), **tol)
    torch.testing.assert_close(x1.grad, x2.grad, **tol)
    from core.render import triton_kernels

    assert fused_shade.shade(v, f, None, mvp, tri, "flat") is not None
    assert triton_kernels.failure is None, triton_kernels.failure


@CUDA
@pytest.mark.gpu
def test_cuda_agrees_with_cpu():
    v, f = tensors(*icosphere(3, noise=0.03))
    cams = fibonacci_cameras(4, width=64)
    target = torch.rand((4, 64, 64, 3), generator=torch.Generator().manual_seed(5))
    rc = rasterize(v, f, cams)
    rg = rasterize(v.cuda(), f.cuda(), cams)
    assert (rc.tri_id == rg.tri_id.cpu()).float().mean() >= 0.9999
    xc, xg = v.clone().requires_grad_(True), v.cuda().requires_grad_(True)
    lc = render_loss(xc, f, cams, target, raster=rc)
    lg = render_loss(xg, f.cuda(), cams, target.cuda(), raster=rg)
    lc.backward()
    lg.backward()
    assert abs(float(lc) - float(lg)) < 1e-4
    torch.testing.assert_close(xg.grad.cpu(), xc.grad, rtol=1e-3, atol=1e-5)
    xc, xg = v.clone().requires_grad_(True), v.cuda().requires_grad_(True)
    render_loss(xc, f, cams, target, raster=rc, kind="flat").backward()
    render_loss(xg, f.cuda(), cams, target.cuda(), raster=rg, kind="flat").backward()
    torch.testing.assert_close(xg.grad.cpu(), xc.grad, rtol=1e-3, atol=1e-5)
