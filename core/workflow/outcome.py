"""A finished construction in world space, and how it is stored (compressed ``.npz`` bytes)
inside a ``.blend`` so it survives saving and can be exported without re-running."""
from __future__ import annotations

import io
from dataclasses import dataclass, field

import numpy as np

from ..micro.bounds import DirectionBounds
from ..mesh.trimesh import TriMesh
from ..micro.micromesh import MicroMesh


@dataclass
class Outcome:
    """What the worker hands to the main thread, and what a result object stores."""

    micromesh: MicroMesh
    bounds: DirectionBounds | None = None   # per base vertex (bias, scale)
    metrics: dict = field(default_factory=dict)
    settings: dict = field(default_factory=dict)
    history: dict = field(default_factory=dict)
    method: str = "projection"
    report_png: bytes | None = None          # core.report: the picture
    report: dict = field(default_factory=dict)   # and every number in it


def pack(out: Outcome) -> bytes:
    """The micro-mesh and its bounds as compressed ``.npz`` bytes."""
    mm = out.micromesh
    arrays = dict(base_vertices=mm.base.vertices, base_faces=mm.base.faces,
                  directions=mm.directions, levels=mm.levels, displacements=mm.displacements,
                  edge_flags=mm.topology.flags)
    if out.bounds is not None:
        arrays["bounds_bias"], arrays["bounds_scale"] = out.bounds.bias, out.bounds.scale
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    return buf.getvalue()


def unpack(data: bytes) -> tuple[MicroMesh, DirectionBounds | None]:
    """What :func:`pack` stored."""
    with np.load(io.BytesIO(bytes(data))) as z:
        d = {k: z[k] for k in z.files}
    mm = MicroMesh(TriMesh(d["base_vertices"], d["base_faces"]), d["directions"], d["levels"],
                   d["displacements"])
    bounds = DirectionBounds(d["bounds_bias"], d["bounds_scale"]) if "bounds_bias" in d else None
    return mm, bounds


def jsonable(x):
    """``x`` (dicts, lists, arrays, numpy scalars) as JSON takes it: non-finite floats as
    None, anything else as its string."""
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist())
    if isinstance(x, (np.floating, float)):
        v = float(x)
        return v if np.isfinite(v) else None
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (str, int, bool)) or x is None:
        return x
    return str(x)
