"""The reference made consistent for a construction and for the maps: coincident vertices welded
(``core.mesh.weld``: a triangle soup is one surface), loose vertices, faces of no area, repeated
faces and sheets of no thickness left out, the winding made consistent (``core.mesh.orient``), and in words
what was changed and what the base cannot keep (the caller's mesh is not changed)."""
from __future__ import annotations

import numpy as np

from .orient import orient
from .trimesh import MeshError, TriMesh
from .weld import TOLERANCE, weld


MANY_PARTS = 10     # from this many connected components on, a warning says what they cost


def oriented_reference(reference: TriMesh) -> tuple[TriMesh, list[str]]:
    """The reference with coincident vertices welded, with consistent winding, closed parts
    facing out (``core.mesh.orient``), and in words what was welded, left out and turned, which
    edges no surface can keep and whether it has many parts (the caller's mesh is not
    changed)."""
    try:
        w = weld(reference)
    except MeshError as e:
        raise MeshError(f"the input has no surface: {e}") from None
    reference, warnings = _without_loose_and_duplicates(w.mesh)
    warnings = [w.warning()] + warnings if w.merged else warnings
    o = orient(reference)
    warnings += o.warnings()
    parts = reference.n_components
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
    far away shrinks the object in every view), without faces of no area (a face along a
    line or on a point, within the weld's tolerance: nothing to see, but an edge it lies on
    would look non-manifold),
    without repeated faces (the same three
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
    flat = _flat(mesh)
    repeated -= int((~keep & ~sheet & flat).sum())
    keep &= ~flat
    used = np.zeros(mesh.n_vertices, bool)
    used[faces] = True
    loose = int((~used).sum())               # in no face of the input (a sheet's tip is not)
    faces = faces[keep]
    used[:] = False
    used[faces] = True
    warnings = []
    if loose:
        warnings.append(f"{loose} vertices in no face (loose vertices or edges) were left out")
    if flat.any():
        warnings.append(f"{int(flat.sum())} faces of no area (degenerate) were left out")
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


def _flat(mesh: TriMesh) -> np.ndarray:
    """The faces of no area: each corner within the weld's tolerance of the line through the
    other two (a face on a line or a point; one read back from float32 is not exactly flat)."""
    tri = mesh.vertices[mesh.faces]
    longest = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).max(axis=1)
    height = 2 * mesh.face_areas / np.maximum(longest, np.finfo(float).tiny)
    return height <= TOLERANCE * mesh.bbox_diagonal


def _rotated_to_smallest(faces: np.ndarray) -> np.ndarray:
    """Each face's vertices cycled so the smallest comes first (the winding kept)."""
    shift = np.argmin(faces, axis=1)
    idx = (shift[:, None] + np.arange(3)[None, :]) % 3
    return np.take_along_axis(faces, idx, axis=1)
