"""The renderer's public ops: rasterize, render, render_loss, pixel_error, reference_images.

Every op takes torch tensors (verts (N, 3) float, faces (M, 3) integer) and a
``core.render.cameras.Cameras`` batch, accepts a precomputed ``Raster`` and a ``backend``:
"auto" (numba kernels for CPU tensors, torch for CUDA), "numba" or "torch".
"""
from __future__ import annotations

import numpy as np
import torch

from . import torch_antialias, torch_path, torch_raster
from .geometry import vertex_normals
from .scatter import gather
from .topology import face_neighbours
from .types import Raster, RenderError, camera_mvp, check_backend, check_mesh, check_raster

KINDS = ("shaded", "flat", "normal", "mask", "depth")
SHADINGS = ("shaded", "flat")


def _numba():
    from . import numba_path  # compiled lazily: importing core.render stays cheap

    return numba_path


def rasterize(verts: torch.Tensor, faces: torch.Tensor, cams, *, backend: str = "auto") -> Raster:
    """Visible face id and view-space depth per pixel for every camera (no gradient).

    Args:
        verts: (N, 3) float vertex positions, world space (CPU: the numba backend; CUDA:
            torch and Triton).
        faces: (M, 3) int triangle indices into ``verts``.
        cams: a :class:`~core.render.cameras.Cameras` batch of B views of H x W pixels.
        backend: "auto", "numba" or "torch".

    Returns:
        A :class:`Raster`: ``tri_id`` (B, H, W) int32 (-1: background), ``depth`` (B, H, W),
        the (B, 4, 4) matrices it used.
    """
    verts, faces = check_mesh(verts, faces)
    be = check_backend(backend, verts.device)
    mvp = camera_mvp(cams, verts.device)
    flags = None
    with torch.no_grad():
        if be == "numba":
            tri, depth, flags = _numba().rasterize_numba(verts, faces, mvp, cams.width, cams.height)
        else:
            tri, depth = torch_raster.rasterize_torch(verts, faces, mvp, cams.width, cams.height)
    return Raster(tri, depth, mvp, int(cams.width), int(cams.height), len(faces), flags)


def _prepare(verts, faces, cams, raster, backend):
    verts, faces = check_mesh(verts, faces)
    be = check_backend(backend, verts.device)
    if raster is None:
        raster = rasterize(verts, faces, cams, backend=be)
    else:
        raster = check_raster(raster, faces, cams)
    return verts, faces, raster, be


def render(verts: torch.Tensor, faces: torch.Tensor, cams, *, kind: str = "shaded",
           raster: Raster | None = None, antialias: bool = True, backend: str = "auto") -> torch.Tensor:
    """An image per camera, differentiable w.r.t. ``verts``.

    Args:
        verts: (N, 3) float vertex positions, world space.
        faces: (M, 3) int triangle indices.
        cams: B views of H x W pixels (:class:`~core.render.cameras.Cameras`).
        kind: "shaded" (C=3, SH lighting of interpolated, normalised area-weighted vertex
            normals), "flat" (C=3, the same lighting of each face's own normal: facets, as a
            ray tracer shows micro-triangles without shading normals), "normal" (C=3,
            world-space unit normal), "mask" (C=1) or "depth" (C=1, view-space depth).
        raster: :func:`rasterize`'s result for the same mesh and cameras, to reuse (None:
            made here).
        antialias: silhouette edges antialiased (the gradient at silhouettes comes from it).
        backend: "auto", "numba" or "torch".

    Returns:
        (B, H, W, C) image; background 0.
    """
    if kind not in KINDS:
        raise RenderError(f"kind must be one of {KINDS}, got {kind!r}")
    verts, faces, raster, be = _prepare(verts, faces, cams, raster, backend)
    if be == "numba":
        return _numba().render_numba(verts, faces, raster, kind, antialias)
    vn = vertex_normals(verts, faces) if kind in ("shaded", "normal") else None
    img = torch_path.shade_torch(verts, faces, vn, raster.mvp, raster.tri_id, kind)
    if antialias:
        img = torch_antialias.antialias_torch(img, verts, faces, face_neighbours(faces),
                                              raster.mvp, raster.tri_id, raster.depth)
    return img


def interpolate(attr: torch.Tensor, verts: torch.Tensor, faces: torch.Tensor, cams, *,
                raster: Raster | None = None, backend: str = "auto") -> torch.Tensor:
    """(B, H, W, C) perspective-correct interpolation of per-vertex ``attr`` (N, C) at every
    pixel's visible surface point, differentiable w.r.t. ``attr`` and ``verts``; background 0.

    Generic (plain torch on every backend); the renders above use fused kernels instead.
    """
    verts, faces, raster, _ = _prepare(verts, faces, cams, raster, backend)
    if attr.ndim != 2 or len(attr) != len(verts):
        raise RenderError(f"attr must be (N, C) with N = {len(verts)} vertices, got {tuple(attr.shape)}")
    index, face, bary, _ = torch_path.barycentrics_torch(verts, faces, raster.mvp, raster.tri_id)
    val = (bary.to(attr.dtype)[:, :, None] * gather(attr, faces.long()[face])).sum(1)
    nb, height, width = raster.tri_id.shape
    out = torch.zeros((nb * height * width, attr.shape[1]), dtype=attr.dtype, device=attr.device)
    return out.index_put((index,), val).view(nb, height, width, -1)


def _check_target(target: torch.Tensor, raster: Raster, channels: int = 3) -> torch.Tensor:
    shape = (len(raster.tri_id), raster.height, raster.width, channels)
    if not isinstance(target, torch.Tensor) or tuple(target.shape) != shape:
        got = tuple(target.shape) if isinstance(target, torch.Tensor) else type(target).__name__
        raise RenderError(f"target must be a {shape} tensor, got {got}")
    return target


def _check_shading(kind: str) -> str:
    if kind not in SHADINGS:
        raise RenderError(f"shading kind must be one of {SHADINGS}, got {kind!r}")
    return kind


def render_loss(verts: torch.Tensor, faces: torch.Tensor, cams, target: torch.Tensor, *,
                raster: Raster | None = None, antialias: bool = True, kind: str = "shaded",
                backend: str = "auto") -> torch.Tensor:
    """The L1 image loss of :func:`render` against ``target`` (fused on the numba backend).

    Args:
        verts, faces, cams, raster, antialias, backend: as :func:`render`.
        target: (B, H, W, 3) reference images (:func:`reference_images`).
        kind: "shaded" or "flat".

    Returns:
        () scalar: the mean of |render - target| over B*H*W*3, differentiable w.r.t. ``verts``.
    """
    kind = _check_shading(kind)
    verts, faces, raster, be = _prepare(verts, faces, cams, raster, backend)
    target = _check_target(target, raster)
    if be == "numba":
        return _numba().loss_numba(verts, faces, raster, target, antialias, kind)
    img = render(verts, faces, cams, kind=kind, raster=raster, antialias=antialias, backend=be)
    return (img - target.to(img.dtype)).abs().mean()


def pixel_error(verts: torch.Tensor, faces: torch.Tensor, cams, target: torch.Tensor, *,
                raster: Raster | None = None, antialias: bool = True, kind: str = "shaded",
                backend: str = "auto") -> torch.Tensor:
    """Per-pixel L1 error of the ``kind`` render ("shaded" or "flat"); no gradient.

    Args: as :func:`render_loss`.

    Returns:
        (B, H, W): |render - target| summed over the 3 channels.
    """
    kind = _check_shading(kind)
    with torch.no_grad():
        verts, faces, raster, be = _prepare(verts.detach(), faces, cams, raster, backend)
        target = _check_target(target, raster)
        img = render(verts, faces, cams, kind=kind, raster=raster, antialias=antialias,
                     backend=be)
        return (img - target.to(img.dtype)).abs().sum(-1)


def reference_images(verts: torch.Tensor, faces: torch.Tensor, cams, *, antialias: bool = True,
                     kind: str = "shaded", backend: str = "auto") -> torch.Tensor:
    """(B, H, W, 3) images of ``kind`` ("shaded" or "flat", same lighting) of e.g. the
    high-poly reference; no gradient. Rendered ``_VIEWS_PER_CALL`` views at a time: the same
    images as one call over all views, but the rasteriser's buffers stay those of a few views
    (24 views at 512² of a 2M-face reference: about 300 MB less at the peak)."""
    kind = _check_shading(kind)
    n = len(cams)
    with torch.no_grad():
        return torch.cat([render(verts.detach(), faces,
                                 cams.subset(np.arange(b, min(b + _VIEWS_PER_CALL, n))),
                                 kind=kind, antialias=antialias, backend=backend)
                          for b in range(0, n, _VIEWS_PER_CALL)])


_VIEWS_PER_CALL = 4


def warm_up(device: str | torch.device = "cpu", *, antialias: bool = True) -> float:
    """Compile the CPU kernels on a tiny scene; returns the seconds it took.

    numba compiles each kernel at its first call (about a minute on a fresh checkout, a
    fraction of a second from the disk cache). Callers with a time limit or an ETA call this
    first, so that their clocks measure rendering, not compilation. No-op on CUDA.
    """
    import time

    from .cameras import fibonacci_cameras

    t0 = time.perf_counter()
    if torch.device(device).type != "cpu":
        return 0.0
    verts = torch.tensor([[0, 0, 0.6], [0.6, 0, -0.3], [-0.3, 0.5, -0.3], [-0.3, -0.5, -0.3]],
                         dtype=torch.float32, requires_grad=True)
    faces = torch.tensor([[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2]], dtype=torch.int64)
    cams = fibonacci_cameras(2, width=16)
    target = reference_images(verts.detach(), faces, cams, antialias=antialias)
    for kind in SHADINGS:    # what a construction calls (not render_loss's fused L1)
        render(verts, faces, cams, kind=kind, antialias=antialias).sum().backward()
        pixel_error(verts.detach(), faces, cams, target, antialias=antialias, kind=kind)
    return time.perf_counter() - t0
