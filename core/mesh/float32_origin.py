"""Where to put the origin of a mesh that float32 coordinates would blur: Blender's meshes
and glTF's positions are float32, whose step at 1e6 is 0.06, so an object of one unit
that far from the origin loses its shape. Such a mesh is stored relative to a point near its
centre (an object's location, a glTF node's translation) that float32 holds exactly, so the
stored coordinates are small and the sum, taken in float64, is exact to float32's step at
the object's own size."""
from __future__ import annotations

import numpy as np

LOSS = 1e-6   # the largest float32 step, over the bounding-box diagonal, left as it is


def float32_origin(vertices: np.ndarray) -> np.ndarray | None:
    """(3,) float64 the bounding-box centre of ``vertices`` rounded to float32 (exact in
    either), where float32 coordinates would be coarser there than ``LOSS`` of the box's
    diagonal; None where they are fine as they are (or the box is empty or not finite)."""
    v = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    if len(v) == 0 or not np.isfinite(v).all():
        return None
    lo, hi = v.min(axis=0), v.max(axis=0)
    diag = float(np.linalg.norm(hi - lo))
    step = float(np.spacing(np.float32(np.abs(v).max())))
    if step <= LOSS * diag:
        return None
    return ((lo + hi) / 2).astype(np.float32).astype(np.float64)


def relative(vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """(``vertices`` less their :func:`float32_origin`, that origin); (``vertices``, None)
    where float32 holds them as they are."""
    origin = float32_origin(vertices)
    v = np.asarray(vertices, dtype=np.float64)
    return (v if origin is None else v - origin), origin


def as_stored(vertices: np.ndarray) -> np.ndarray:
    """(n, 3) float64: ``vertices`` as an object that stores them in float32 about their
    :func:`float32_origin` (its location) gives them back in world space, to the bit as
    ``operators.bl_mesh.mesh_to_arrays`` reads such an object (the same float64 sums)."""
    local, origin = relative(vertices)
    m = np.eye(4)
    if origin is not None:
        m[:3, 3] = origin
    return local.astype(np.float32).astype(np.float64) @ m[:3, :3].T + m[:3, 3]


def node_translation(origin: np.ndarray | None) -> dict:
    """A glTF node's ``translation`` to ``origin`` (nothing where None)."""
    return {} if origin is None else {"translation": [float(x) for x in origin]}
