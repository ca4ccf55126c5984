"""Differentiable multi-view renderer (issue 3): rasterise, shade, antialias, L1 loss.

CPU tensors run fused numba kernels with analytic backwards; CUDA tensors (or
``backend="torch"``) run the plain-torch path, which is also the reference in tests/benchmarks.

The names below load on first use (PEP 562): a process that only compiles the numba kernels
(``core.runtime.precompile``) imports their modules without torch.
"""
from importlib import import_module

_FROM = {"KINDS": "api", "interpolate": "api", "pixel_error": "api", "rasterize": "api",
         "reference_images": "api", "render": "api", "render_loss": "api", "warm_up": "api",
         "vertex_normals": "geometry", "SH_COEFFS": "sh", "shade_normals": "sh",
         "Raster": "types", "RenderError": "types"}

__all__ = sorted(_FROM)


def __getattr__(name: str):
    if name not in _FROM:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(f".{_FROM[name]}", __name__), name)
    globals()[name] = value
    return value
