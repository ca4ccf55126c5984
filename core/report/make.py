"""The run report: ``NAME.report.png`` a user reads in a minute and ``NAME.report.json`` with
every number the picture shows: the images and the numbers here, the picture drawn by
``core.report.figure`` (matplotlib, Agg, no window).

Panels: reference | micro-mesh | per-pixel error from four of the evaluation views (one colour
scale, with its bar); the micro-mesh coloured by subdivision level and the level histogram (the
level colours of the N-panel); loss and PSNR over the iterations with the subdivision events
marked; the metrics table; the run's warnings in words.
"""
from __future__ import annotations

import numpy as np
import torch

from ..render.cameras import fibonacci_cameras
from ..construct.frame import device as torch_device
from .level_colors import LEVEL_COLORS
from ..mesh.trimesh import TriMesh
from ..micro.metrics import psnr
from ..micro.micromesh import MicroMesh
from ..mesh.orient import orient
from ..render import rasterize, reference_images, render
from .figure import ROWS, draw_report
from ..settings.fields import preset, to_dict
from ..runtime.threads import default_threads


def make_report(result, reference: TriMesh, metrics: dict, preset_name: str = "default"
                ) -> tuple[bytes, dict]:
    """(PNG bytes, JSON-ready dict) of a :class:`core.construct.ConstructResult` of
    ``reference`` (caller's frame) with the run's ``metrics``, its settings compared with
    ``preset_name``'s. The reference is wound as the construction saw it (``core.mesh.orient``)."""
    s = result.settings
    oriented = orient(reference).mesh
    ref_unit = TriMesh(result.normalization.apply(oriented.vertices), oriented.faces)
    images = report_images(result.micromesh_unit, ref_unit, s.eval_views, 256, s.shading,
                           s.camera_radius, s.fov_y_deg)
    try:
        base_settings = to_dict(preset(preset_name))
    except ValueError:
        base_settings = {}
    changed = {k: v for k, v in to_dict(s).items() if base_settings.get(k, v) != v}
    warnings = list(metrics.get("warnings", []))
    data = report_data(metrics, result.history or {}, result.micromesh.levels, changed,
                       preset_name, 12 * (reference.n_vertices + reference.n_faces),
                       result.timings or {}, warnings)
    data["device"] = str(torch_device(s.device))
    data["threads"] = int(s.threads or default_threads())
    data["images_psnr"] = [psnr(a, b) for a, b in zip(images["micromesh"], images["reference"])]
    title = (f"{result.micromesh.base.n_faces:,} base triangles, "
             f"{metrics.get('micro_triangles', 0):,} micro-triangles, "
             f"PSNR {metrics.get('psnr', float('nan')):.2f} dB")
    return draw_report(data, images, title), data


def report_images(mm_unit: MicroMesh, reference_unit: TriMesh, views: int = 24,
                  resolution: int = 256, shading: str = "flat", camera_radius: float = 3.0,
                  fov_y_deg: float = 40.0) -> dict[str, np.ndarray]:
    """Four of ``views`` Fibonacci views (0, N/4, N/2, 3N/4), in the unit frame: ``reference``
    and ``micromesh`` (4, H, W, 3), ``error`` (4, H, W) mean absolute difference, ``levels``
    (4, H, W, 3) the micro-mesh coloured by level and shaded."""
    cams = fibonacci_cameras(views, camera_radius, fov_y_deg, resolution).subset(
        np.array([0, views // 4, views // 2, 3 * views // 4]))
    tess = mm_unit.tessellate()
    X = torch.as_tensor(tess.vertices, dtype=torch.float32)
    T = torch.as_tensor(tess.triangles, dtype=torch.int64)
    with torch.no_grad():
        ours = render(X, T, cams, kind=shading).numpy()
        ref = reference_images(torch.as_tensor(reference_unit.vertices, dtype=torch.float32),
                               torch.as_tensor(reference_unit.faces, dtype=torch.int64), cams,
                               kind=shading).numpy()
        tri = rasterize(X, T, cams).tri_id.numpy()
    level = np.where(tri >= 0, mm_unit.levels[tess.triangle_face[np.maximum(tri, 0)]], -1)
    gray = ours.mean(-1, keepdims=True)
    colours = np.where((level >= 0)[..., None],
                       LEVEL_COLORS[np.clip(level, 0, 7)] * (0.35 + 0.65 * gray), 0.0)
    return {"reference": ref, "micromesh": ours, "error": np.abs(ours - ref).mean(-1),
            "levels": colours}


def report_data(metrics: dict, history: dict, levels: np.ndarray, settings_changed: dict,
                preset: str, input_bytes: int, timings: dict, warnings: list[str]) -> dict:
    """Every number of the picture, JSON-ready."""
    m = {k: metrics.get(k) for k, _, _ in ROWS if k in metrics}
    if metrics.get("bytes"):
        m["compression"] = input_bytes / metrics["bytes"]
    for key in ("residual_lod", "base_fit", "direction_fit", "fit_passes", "lp_bounds",
                "polish"):
        if isinstance(metrics.get(key), dict):
            m[key] = dict(metrics[key])
    return {"metrics": m, "levels_hist": np.bincount(levels, minlength=6).tolist(),
            "history": {k: list(history.get(k, [])) for k in ("iteration", "loss", "psnr")},
            "events": [e for e in history.get("events", []) if "level" in e],
            "timings": {k: float(v) for k, v in timings.items()}, "preset": preset,
            "settings_changed": settings_changed, "warnings": list(warnings),
            "input_bytes": int(input_bytes)}
