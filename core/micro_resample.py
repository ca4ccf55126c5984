"""Values carried to other levels: a micro-mesh's displacements resampled onto the
micro-vertices of the same base at new levels, keeping its surface."""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .micro_locate import locate
from .microtopology import MicroTopology

if TYPE_CHECKING:
    from .micromesh import MicroMesh


def resampled_values(mm: "MicroMesh", topo: MicroTopology) -> tuple[np.ndarray, np.ndarray]:
    """The displacements of ``topo``'s micro-vertices (``mm``'s base, other levels) that keep
    ``mm``'s surface: d = D·(X − P)/|D|² at each new vertex, X the old surface point there
    (the old values, interpolated, where D is zero), and the old value itself where the vertex
    was a micro-vertex before. Returns (values (n,), kept (n,) bool: True where the vertex
    was one before)."""
    nb = topo.n_base_vertices
    out = np.zeros(topo.n_vertices)
    kept = np.zeros(topo.n_vertices, bool)
    out[:nb] = mm.displacements[:nb]  # base vertices keep their value (used or not)
    kept[:nb] = True
    sel = np.flatnonzero(topo.vertex_face >= 0)
    sel = sel[sel >= nb]
    if len(sel) == 0:
        return out, kept
    idx, w = locate(mm.topology, topo.vertex_face[sel], topo.vertex_bary[sel])
    old = mm.micro_vertex_positions()
    X = np.einsum("qk,qkc->qc", w, old[idx])
    P = topo.interp[sel] @ mm.base.vertices
    D = topo.interp[sel] @ mm.directions
    nn = (D * D).sum(1)
    lin = (w * mm.displacements[idx]).sum(1)
    d = np.where(nn > 1e-300, (D * (X - P)).sum(1) / np.maximum(nn, 1e-300), lin)
    k = w.argmax(1)
    same = w[np.arange(len(k)), k] >= 1.0 - 1e-12
    d[same] = mm.displacements[idx[np.arange(len(k)), k]][same]
    out[sel] = d
    kept[sel] = same
    return out, kept
