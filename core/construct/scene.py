"""The reference as the optimiser sees it: the unit-frame mesh, the cameras, cached reference
images, per-base-face image errors (the visual LOD criterion) and projection baking."""
from __future__ import annotations

import numpy as np
import torch

from ..spatial.bake import bake_displacements
from ..render.cameras import Cameras
from ..lod import chamfer_face_errors, face_error_sums
from ..mesh.trimesh import TriMesh
from ..micro.micromesh import MicroMesh
from ..render import pixel_error, rasterize, reference_images
from ..settings.fields import ConstructSettings
from .evaluate import eval_cameras, squared_error


class Scene:
    """Reference and cameras in the unit-sphere frame, with cached reference images."""

    def __init__(self, reference_unit: TriMesh, cams: Cameras, device, antialias: bool,
                 shading: str = "shaded"):
        self.ref = reference_unit
        self.cams = cams
        self.device = device
        self.antialias = antialias
        self.shading = shading
        self.rv = torch.as_tensor(reference_unit.vertices, dtype=torch.float32, device=device)
        self.rf = torch.as_tensor(reference_unit.faces, dtype=torch.int64, device=device)
        self._images: dict[tuple, torch.Tensor] = {}

    def images(self, cams: Cameras) -> torch.Tensor:
        """The reference's images from ``cams``, cached by the cameras themselves (poses,
        projections, size): equal cameras share one set."""
        key = (cams.width, cams.height, cams.view.tobytes(), cams.proj.tobytes())
        if key not in self._images:
            self._images[key] = reference_images(self.rv, self.rf, cams, antialias=self.antialias,
                                                 kind=self.shading)
        return self._images[key]


def face_errors(mm: MicroMesh, scene: Scene, cams: Cameras, s: ConstructSettings,
                ref_tree=None) -> np.ndarray:
    """Per base face error for the LOD criterion (visual: image L1 over the face's pixels)."""
    nf = mm.base.n_faces
    if s.lod_criterion == "chamfer":
        t = mm.topology
        return chamfer_face_errors(mm.micro_vertex_positions(), np.maximum(t.vertex_face, 0),
                                   scene.ref.vertices, nf, ref_tree)
    target = scene.images(cams)
    X = torch.as_tensor(mm.micro_vertex_positions(), dtype=torch.float32, device=scene.device)
    T = torch.as_tensor(mm.topology.triangles, dtype=torch.int64, device=scene.device)
    sums = np.zeros(nf)
    for b in range(0, len(cams), 8):  # chunks of views bound the memory
        sub = cams.subset(np.arange(b, min(b + 8, len(cams))))
        ras = rasterize(X, T, sub)
        err = pixel_error(X, T, sub, target[b:b + 8], raster=ras, antialias=s.antialias,
                          kind=s.shading)
        sums += face_error_sums(err.cpu().numpy(), ras.tri_id.cpu().numpy(),
                                mm.topology.triangle_face, nf)
    return sums


def image_error(mm: MicroMesh, scene: Scene, s: ConstructSettings) -> float:
    """The summed squared pixel error of ``mm`` from the metrics' views
    (``evaluate.eval_cameras``): what the report's PSNR measures, the reference images cached."""
    cams = eval_cameras(s)
    target = scene.images(cams)
    X = torch.as_tensor(mm.micro_vertex_positions(), dtype=torch.float32, device=scene.device)
    T = torch.as_tensor(mm.topology.triangles, dtype=torch.int64, device=scene.device)
    return squared_error(X, T, cams, s, target)[0]


def bake(mm: MicroMesh, reference: TriMesh, max_distance: float) -> np.ndarray:
    """Displacements of every micro-vertex of ``mm`` by projection onto the reference."""
    o = mm.micro_vertex_base_positions()
    d = mm.micro_vertex_directions()
    return bake_displacements(o, d, reference, max_distance=max_distance).displacement
