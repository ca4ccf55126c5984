"""Differentiable multi-view renderer (issue 3): rasterise, shade, antialias, L1 loss.

CPU tensors run fused numba kernels with analytic backwards; CUDA tensors (or
``backend="torch"``) run the plain-torch path, which is also the reference in tests/benchmarks.
"""
from .api import (KINDS, interpolate, pixel_error, rasterize, reference_images, render, render_loss,
                  warm_up)
from .geometry import vertex_normals
from .sh import SH_COEFFS, shade_normals
from .types import Raster, RenderError

__all__ = ["KINDS", "Raster", "RenderError", "SH_COEFFS", "interpolate", "pixel_error", "rasterize",
           "reference_images", "render", "render_loss", "shade_normals", "vertex_normals", "warm_up"]
