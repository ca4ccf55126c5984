"""What the caller's cameras see of the reference, checked before the reference images are
made: a camera that sees nothing of it (pointed away, clipped, too far) adds nothing, and one
inside a surface sees only its back faces. Fibonacci cameras need no check (they surround the
unit sphere)."""
from __future__ import annotations

import numpy as np
import torch

from ..render.cameras import Cameras
from ..mesh.trimesh import TriMesh
from ..render import rasterize
from .types import ConstructError

# Image size of the check (the coverage of a view, not its detail).
_RESOLUTION = 96
# A view "sees the inside" when at least this share of its covered pixels are back faces.
_INSIDE_SHARE = 0.9


def view_coverage(reference: TriMesh, cams: Cameras, device) -> tuple[np.ndarray, np.ndarray]:
    """(covered pixels (B,), back-facing pixels (B,)) of each camera at a small resolution.

    A pixel is back-facing where the face it shows turns away from the camera (the camera is
    on the side its normal points away from).
    """
    small = cams.with_resolution(_RESOLUTION, max(1, round(_RESOLUTION * cams.height / cams.width)))
    V = torch.as_tensor(reference.vertices, dtype=torch.float32, device=device)
    F = torch.as_tensor(reference.faces, dtype=torch.int64, device=device)
    centroid = reference.vertices[reference.faces].mean(1)
    normal = reference.face_normals
    eye = small.eye
    covered = np.zeros(len(small), np.int64)
    back = np.zeros(len(small), np.int64)
    for b in range(0, len(small), 8):
        idx = np.arange(b, min(b + 8, len(small)))
        tri = rasterize(V, F, small.subset(idx)).tri_id.cpu().numpy()
        for k, i in enumerate(idx):
            seen = tri[k][tri[k] >= 0]
            covered[i] = len(seen)
            away = ((eye[i] - centroid[seen]) * normal[seen]).sum(1) < 0
            back[i] = int(away.sum())
    return covered, back


def check_views(reference: TriMesh, cams: Cameras, device) -> list[str]:
    """Warnings, in words, about the caller's cameras (``reference`` and ``cams`` in one frame).

    Raises :class:`ConstructError` when no camera sees the reference at all.
    """
    covered, back = view_coverage(reference, cams, device)
    n = len(cams)
    blind = covered == 0
    if blind.all():
        raise ConstructError(f"none of the {n} cameras sees the object (pointed away, clipped "
                             "by their clip distances, or too far): place cameras around it "
                             "(Place Cameras) or construct without scene cameras")
    warnings = []
    if blind.any():
        warnings.append(f"{int(blind.sum())} of {n} cameras see nothing of the object "
                        f"(cameras {_list(np.flatnonzero(blind))}, counted from 0 in name "
                        "order): they add nothing to the construction")
    inside = ~blind & (back >= _INSIDE_SHARE * np.maximum(covered, 1))
    if inside[~blind].all():
        warnings.append(f"every camera that sees the object ({int((~blind).sum())} of {n}) "
                        "sees only the back of its surface (they are inside it): the "
                        "construction matches what is seen from inside; place cameras outside "
                        "(Place Cameras) for the outside")
    elif inside.any():
        warnings.append(f"{int(inside.sum())} of {n} cameras see only the back of the surface "
                        f"(cameras {_list(np.flatnonzero(inside))}, counted from 0 in name "
                        "order: inside the object)")
    return warnings


def _list(index: np.ndarray, most: int = 8) -> str:
    shown = ", ".join(str(int(i)) for i in index[:most])
    return shown + (", …" if len(index) > most else "")
