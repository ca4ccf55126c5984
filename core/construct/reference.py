"""The reference made consistent for a construction: loose vertices, repeated faces and
sheets of no thickness left out, the winding made consistent (``core.orient``), and in words
what was changed and what the base cannot keep (the caller's mesh is not changed)."""
from __future__ import annotations

import numpy as np

from ..base.build import welded
from ..mesh import TriMesh
from ..orient import orient


MANY_PARTS = 10     # from this many connected components on, a warning says what they cost


def oriented_reference(reference: TriMesh) -> tuple[TriMesh, list[str]]:
    """The reference with consistent winding, closed parts facing out (``core.orient``), and
    in words what was turned, which edges no surface can keep and whether it has many parts
    (the caller's mesh is not changed)."""
    reference, warnings = _without_loose_and_duplicates(reference)
    o = orient(reference)
    warnings += o.warnings()
    parts = welded(reference).n_components      # seams split in the file are not parts
    if parts >= MANY_PARTS:
        warnings.append(f"the input has {parts} separate parts: the base keeps every one, so "
                        "small parts take base triangles and budget from the large ones")
    nm = int((reference.edge_face_count > 2).sum())
    if nm:
        warnings.append(f"the input has {nm} non-manifold edges (three or more faces on one "
                        "edge): the base and the micro-mesh cannot follow them exactly")
    return o.mesh, warnings


def _without_loose_and_duplicates(mesh: TriMesh) -> tuple[TriMesh, list[str]]:
    """``mesh`` without vertices no face uses (they would move the unit frame: a stray point
    far away shrinks the object in every view), without repeated faces (the same three
    vertices again, wound the same way: one stays) and without faces that have a copy wound
    the other way (a sheet of no thickness, a flap on the surface: all its copies go), and
    what was left out, in words."""
    faces = mesh.faces
    cycled = _rotated_to_smallest(faces)
    key = np.sort(faces, axis=1)
    _, group = np.unique(key, axis=0, return_inverse=True)
    group = group.reshape(-1)
    forward = cycled[:, 1] < cycled[:, 2]
    n_groups = group.max(initial=-1) + 1
    both = (np.bincount(group, weights=forward, minlength=n_groups) > 0) \
        & (np.bincount(group, weights=~forward, minlength=n_groups) > 0)
    sheet = both[group]
    _, first = np.unique(np.column_stack([group, forward]), axis=0, return_index=True)
    keep = np.zeros(len(faces), bool)
    keep[first] = True
    repeated = int((~keep & ~sheet).sum())
    keep &= ~sheet
    used = np.zeros(mesh.n_vertices, bool)
    used[faces] = True
    loose = int((~used).sum())               # in no face of the input (a sheet's tip is not)
    faces = faces[keep]
    used[:] = False
    used[faces] = True
    warnings = []
    if loose:
        warnings.append(f"{loose} vertices in no face (loose vertices or edges) were left out")
    if repeated:
        warnings.append(f"{repeated} repeated faces (the same three vertices again) were left "
                        "out")
    if sheet.any():
        warnings.append(f"{int(sheet.sum())} faces with a copy wound the other way (sheets of "
                        "no thickness) were left out")
    if used.all() and keep.all():
        return mesh, warnings
    index = np.cumsum(used) - 1
    return TriMesh(mesh.vertices[used], index[faces]), warnings


def _rotated_to_smallest(faces: np.ndarray) -> np.ndarray:
    """Each face's vertices cycled so the smallest comes first (the winding kept)."""
    shift = np.argmin(faces, axis=1)
    idx = (shift[:, None] + np.arange(3)[None, :]) % 3
    return np.take_along_axis(faces, idx, axis=1)
