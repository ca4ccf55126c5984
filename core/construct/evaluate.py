"""The metrics of a finished micro-mesh (method §7), in the unit-sphere frame."""
from __future__ import annotations

import numpy as np
import torch

from ..micro.bounds import DirectionBounds, shell_volume, tight_bounds
from ..render.cameras import Cameras, fibonacci_cameras
from ..io.file_size import micromesh_file_bytes
from ..io.micromesh_export import quantization_error
from ..lod import effective_micro_triangles
from ..mesh.trimesh import TriMesh
from ..micro.metrics import crack_edges, geometric_error, isotropy, mmt_formula_bytes
from ..micro.micromesh import MicroMesh
from ..render import reference_images, render
from ..settings.fields import ConstructSettings
from .frame import device as torch_device


def eval_cameras(s: ConstructSettings) -> Cameras:
    """The views of the metrics' PSNR: ``s.eval_views`` Fibonacci views at
    ``s.eval_resolution`` (unit frame)."""
    return fibonacci_cameras(s.eval_views, s.camera_radius, s.fov_y_deg, s.eval_resolution)


def squared_error(X: torch.Tensor, T: torch.Tensor, cams: Cameras, s: ConstructSettings,
                  reference: torch.Tensor) -> tuple[float, int]:
    """(sum of squared differences, number of values) between the ``s.shading`` renders of
    the triangles ``T`` (m, 3) over ``X`` (n, 3) from ``cams`` and the (B, H, W, 3)
    ``reference`` images of those views (rendered four views at a time)."""
    se, n = 0.0, 0
    with torch.no_grad():
        for b in range(0, len(cams), 4):
            e = min(b + 4, len(cams))
            img = render(X, T, cams.subset(np.arange(b, e)), kind=s.shading,
                         antialias=s.antialias)
            se += float(((img - reference[b:e].to(img.dtype)) ** 2).double().sum())
            n += img.numel()
    return se, n


def evaluate(mm_unit: MicroMesh, reference_unit: TriMesh, s: ConstructSettings,
             bounds_unit: DirectionBounds | None = None, device=None,
             ref_images: torch.Tensor | None = None) -> dict:
    """PSNR over ``s.eval_views`` Fibonacci views, shell volume, geometric error, isotropy,
    storage, the 11-bit export's quantisation error (over the diagonal), level histogram and
    cracks of ``mm_unit`` against ``reference_unit``."""
    device = device or torch_device(s.device)
    bounds_unit = bounds_unit if bounds_unit is not None else tight_bounds(mm_unit)
    tess = mm_unit.tessellate()
    base = mm_unit.base
    out: dict = {}
    cams = eval_cameras(s)
    X = torch.as_tensor(tess.vertices, dtype=torch.float32, device=device)
    T = torch.as_tensor(tess.triangles, dtype=torch.int64, device=device)
    if ref_images is None:
        ref_images = reference_images(
            torch.as_tensor(reference_unit.vertices, dtype=torch.float32, device=device),
            torch.as_tensor(reference_unit.faces, dtype=torch.int64, device=device), cams,
            antialias=s.antialias, kind=s.shading)
    se, n = squared_error(X, T, cams, s, ref_images)
    mse = se / max(n, 1)
    out["psnr"] = float(10 * np.log10(1.0 / mse)) if mse > 0 else float("inf")
    out["shell_volume"] = shell_volume(base.vertices, base.faces, mm_unit.directions, bounds_unit)
    if s.geom_error:
        out["geom_err"] = geometric_error(reference_unit.vertices, reference_unit.vertex_areas,
                                          tess.vertices, tess.triangles,
                                          reference_unit.bbox_diagonal)
    out["iso_base"] = isotropy(base.vertices, base.faces)
    out["iso_micro"] = isotropy(tess.vertices, tess.triangles)
    st = micromesh_file_bytes(mm_unit.levels, base.n_vertices)    # .bin + .bary on disk
    out["bytes"] = st["total"]
    out["bytes_values"] = st["values"]
    out["bytes_mmt"] = mmt_formula_bytes(mm_unit.levels, base.n_vertices)
    if mm_unit.levels.max(initial=0) <= 5:   # what an export stores (11-bit values)
        out["quantization_max"], out["quantization_rms"] = quantization_error(mm_unit, bounds_unit)
    out["micro_triangles"] = effective_micro_triangles(mm_unit.levels, base)
    out["base_faces"] = int(base.n_faces)
    out["levels_hist"] = np.bincount(mm_unit.levels, minlength=6).tolist()
    eb = base.boundary_edges
    expected = int(np.sum(2 ** mm_unit.levels[base.edge_faces[eb, 0]])) if len(eb) else 0
    out["cracks"] = crack_edges(tess.triangles, tess.vertices, expected)
    return out
