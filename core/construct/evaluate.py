"""The metrics of a finished micro-mesh (method §7), in the unit-sphere frame."""
from __future__ import annotations

import numpy as np
import torch

from ..bounds import DirectionBounds, shell_volume, tight_bounds
from ..cameras import fibonacci_cameras
from ..io.micromesh_export import quantization_error
from ..lod import effective_micro_triangles
from ..mesh import TriMesh
from ..metrics import crack_edges, geometric_error, isotropy, mmt_formula_bytes, storage_bytes
from ..micromesh import MicroMesh
from ..render import reference_images, render
from ..settings import ConstructSettings
from .frame import device as torch_device


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
    cams = fibonacci_cameras(s.eval_views, s.camera_radius, s.fov_y_deg, s.eval_resolution)
    X = torch.as_tensor(tess.vertices, dtype=torch.float32, device=device)
    T = torch.as_tensor(tess.triangles, dtype=torch.int64, device=device)
    if ref_images is None:
        rv = torch.as_tensor(reference_unit.vertices, dtype=torch.float32, device=device)
        rf = torch.as_tensor(reference_unit.faces, dtype=torch.int64, device=device)
    se, n = 0.0, 0
    with torch.no_grad():
        for b in range(0, len(cams), 4):
            sub = cams.subset(np.arange(b, min(b + 4, len(cams))))
            img = render(X, T, sub, kind=s.shading, antialias=s.antialias)
            ref = (ref_images[b:b + 4] if ref_images is not None
                   else reference_images(rv, rf, sub, antialias=s.antialias, kind=s.shading))
            se += float(((img - ref) ** 2).double().sum())
            n += img.numel()
    mse = se / max(n, 1)
    out["psnr"] = float(10 * np.log10(1.0 / mse)) if mse > 0 else float("inf")
    out["shell_volume"] = shell_volume(base.vertices, base.faces, mm_unit.directions, bounds_unit)
    if s.geom_error:
        out["geom_err"] = geometric_error(reference_unit.vertices, reference_unit.vertex_areas,
                                          tess.vertices, tess.triangles,
                                          reference_unit.bbox_diagonal)
    out["iso_base"] = isotropy(base.vertices, base.faces)
    out["iso_micro"] = isotropy(tess.vertices, tess.triangles)
    st = storage_bytes(mm_unit.levels, base.n_vertices)
    out["bytes"] = st["total"]
    out["bytes_values"] = st["values"]
    out["bytes_mmt"] = mmt_formula_bytes(mm_unit.levels, base.n_vertices)
    if mm_unit.levels.max(initial=0) <= 5:   # what an export stores (11-bit values)
        out["quantization_max"], out["quantization_rms"] = quantization_error(mm_unit, bounds_unit)
    out["micro_triangles"] = effective_micro_triangles(mm_unit.levels, base.face_adjacency)
    out["base_faces"] = int(base.n_faces)
    out["levels_hist"] = np.bincount(mm_unit.levels, minlength=6).tolist()
    eb = base.boundary_edges
    expected = int(np.sum(2 ** mm_unit.levels[base.edge_faces[eb, 0]])) if len(eb) else 0
    out["cracks"] = crack_edges(tess.triangles, tess.vertices, expected)
    return out
