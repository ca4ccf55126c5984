"""Fused CUDA kernels (Triton) for the two loops that plain torch runs as thousands of small
kernels: the rasteriser's per-(view, face) pixel loop (here) and the antialiasing walk across
sub-pixel faces (``triton_walk``). Same rules and float64 arithmetic as ``torch_path`` and
``torch_antialias``, which stay the reference (tests compare them on a GPU) and the fallback:
where Triton is not installed, or a kernel fails to compile or launch, ``available()`` is
False and the plain path runs. The only atomics are the z-buffer's minimum (order-independent).

Every function takes torch tensors on one CUDA device.
"""
from __future__ import annotations

import functools
import warnings

import torch

try:
    import triton
    import triton.language as tl
except ImportError:  # pragma: no cover - CPU-only installs
    triton = tl = None

BLOCK_SIZE = 128
failure: str | None = None
"""Why a kernel failed to compile or launch (then none is used again in this process)."""


def available(device: torch.device) -> bool:
    """Whether the fused kernels can run on ``device`` (CUDA, Triton importable, none failed)."""
    return triton is not None and device.type == "cuda" and failure is None


def guarded(fn):
    """A kernel wrapper that returns None instead of raising where Triton fails (a compiler or
    driver it cannot use): the caller then runs the plain torch path, with a warning once."""
    @functools.wraps(fn)
    def run(*args, **kwargs):
        global failure
        try:
            return fn(*args, **kwargs)
        except Exception as exc:  # noqa: BLE001 - any compiler or driver error
            root = exc
            while root.__cause__ is not None:  # a compiler error's cause says what went wrong
                root = root.__cause__
            failure = f"{type(exc).__name__}: {exc}" + ("" if root is exc else f" ({root!r})")
            warnings.warn(f"the fused CUDA kernels cannot run here ({failure}); the renderer "
                          "uses its plain torch path", RuntimeWarning, stacklevel=3)
            return None
    return run


if triton is not None:
    @triton.jit
    def _corners(ptr, i0, i1, i2, mask):
        """The values at a face's three vertices of one per-vertex array."""
        return (tl.load(ptr + i0, mask=mask, other=0.0), tl.load(ptr + i1, mask=mask, other=0.0),
                tl.load(ptr + i2, mask=mask, other=0.0))

    @triton.jit
    def _raster_kernel(f_ptr, sx_ptr, sy_ptr, w_ptr, z_ptr, keys_ptr, n_items, n_faces, n_verts,
                       view0, width, height, BLOCK: tl.constexpr):
        pid = tl.program_id(0)
        item = pid * BLOCK + tl.arange(0, BLOCK)
        live = item < n_items
        g = item // n_faces               # view within the group
        face = item % n_faces
        i0 = tl.load(f_ptr + face * 3, mask=live, other=0)
        i1 = tl.load(f_ptr + face * 3 + 1, mask=live, other=0)
        i2 = tl.load(f_ptr + face * 3 + 2, mask=live, other=0)
        o = g * n_verts
        x0, x1, x2 = _corners(sx_ptr + o, i0, i1, i2, live)
        y0, y1, y2 = _corners(sy_ptr + o, i0, i1, i2, live)
        w0, w1, w2 = _corners(w_ptr + o, i0, i1, i2, live)
        z0, z1, z2 = _corners(z_ptr + o, i0, i1, i2, live)
        ok = live & (w0 > 0) & (w1 > 0) & (w2 > 0) & (z0 >= -w0) & (z1 >= -w1) & (z2 >= -w2)
        area = (x1 - x0) * (y2 - y0) - (y1 - y0) * (x2 - x0)
        ok = ok & (area != 0) & (area == area) & (tl.abs(area) < float("inf"))
        fw = width * 1.0
        fh = height * 1.0
        c0 = tl.minimum(tl.maximum(tl.ceil(tl.minimum(tl.minimum(x0, x1), x2) - 0.5), 0.0), fw)
        c1 = tl.minimum(tl.maximum(tl.floor(tl.maximum(tl.maximum(x0, x1), x2) - 0.5), -1.0), fw - 1)
        r0 = tl.minimum(tl.maximum(tl.ceil(tl.minimum(tl.minimum(y0, y1), y2) - 0.5), 0.0), fh)
        r1 = tl.minimum(tl.maximum(tl.floor(tl.maximum(tl.maximum(y0, y1), y2) - 0.5), -1.0), fh - 1)
        nx = tl.maximum(c1 - c0 + 1, 0.0).to(tl.int32)
        ny = tl.maximum(r1 - r0 + 1, 0.0).to(tl.int32)
        count = tl.where(ok, nx * ny, 0)
        sa = tl.where(area > 0, 1.0, -1.0)
        # canonical edges: from the lower vertex id to the higher (exactly opposite values on
        # the two faces of an edge); s: edge sign with the face's orientation; t: owns E == 0
        sw0 = i0 > i1
        lx0 = tl.where(sw0, x1, x0)
        ly0 = tl.where(sw0, y1, y0)
        dx0 = tl.where(sw0, x0, x1) - lx0
        dy0 = tl.where(sw0, y0, y1) - ly0
        sw1 = i1 > i2
        lx1 = tl.where(sw1, x2, x1)
        ly1 = tl.where(sw1, y2, y1)
        dx1 = tl.where(sw1, x1, x2) - lx1
        dy1 = tl.where(sw1, y1, y2) - ly1
        sw2 = i2 > i0
        lx2 = tl.where(sw2, x0, x2)
        ly2 = tl.where(sw2, y0, y2)
        dx2 = tl.where(sw2, x2, x0) - lx2
        dy2 = tl.where(sw2, y2, y0) - ly2
        g0 = tl.where(sw0, -1.0, 1.0)
        g1 = tl.where(sw1, -1.0, 1.0)
        g2 = tl.where(sw2, -1.0, 1.0)
        wq0 = g1 * (1.0 / w0)
        wq1 = g2 * (1.0 / w1)
        wq2 = g0 * (1.0 / w2)
        s0 = g0 * sa
        s1 = g1 * sa
        s2 = g2 * sa
        c0i = c0.to(tl.int32)
        r0i = r0.to(tl.int32)
        nxs = tl.maximum(nx, 1)
        hw = width * height
        pix0 = (view0 + g).to(tl.int64) * hw
        n_max = tl.max(count, axis=0)
        k = 0
        while k < n_max:
            run = k < count
            col = c0i + k % nxs
            row = r0i + k // nxs
            px = col.to(tl.float64) + 0.5
            py = row.to(tl.float64) + 0.5
            e0 = dx0 * (py - ly0) - dy0 * (px - lx0)
            e1 = dx1 * (py - ly1) - dy1 * (px - lx1)
            e2 = dx2 * (py - ly2) - dy2 * (px - lx2)
            es0 = e0 * s0
            es1 = e1 * s1
            es2 = e2 * s2
            ins = ((es0 > 0) | ((es0 == 0) & ~sw0)) & ((es1 > 0) | ((es1 == 0) & ~sw1)) \
                & ((es2 > 0) | ((es2 == 0) & ~sw2))
            inv_w = ((e1 * wq0 + e2 * wq1) + e0 * wq2) / area
            ins = ins & run & (inv_w > 0)
            d32 = (1.0 / inv_w).to(tl.float32)
            key = (d32.to(tl.int32, bitcast=True).to(tl.int64) << 32) | face.to(tl.int64)
            tl.atomic_min(keys_ptr + pix0 + row * width + col, key, mask=ins)
            k += 1


@guarded
def rasterize_keys(keys: torch.Tensor, f: torch.Tensor, sx, sy, w, z, view0: int, width: int,
                   height: int) -> bool:
    """Fold the (float32 depth bits << 32 | face) keys of every covered pixel of the views
    ``view0 .. view0 + G`` into ``keys`` (B * H * W,) by atomic minimum; ``sx, sy, w, z`` (G, N)
    float64 screen coordinates of those views, ``f`` (M, 3) int64 faces. True when done."""
    g, n = sx.shape
    items = g * len(f)
    if items == 0:
        return True
    grid = (triton.cdiv(items, BLOCK_SIZE),)
    _raster_kernel[grid](f.contiguous(), sx.contiguous(), sy.contiguous(), w.contiguous(),
                         z.contiguous(), keys, items, len(f), n, view0, width, height,
                         BLOCK=BLOCK_SIZE)
    return True

