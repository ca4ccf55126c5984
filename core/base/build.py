"""The base-mesh builder: one call used by Make Base, by Construct without a base and by
``batch.py``.

It works in the reference's unit-sphere frame, with coordinates rounded to float32 there, so
copies of a mesh at any scale or position give the same base (up to that similarity), and on
the reference with coincident vertices merged (split UV seams or flat-shaded edges of an
imported file, triangle soups are one surface: ``core.mesh.weld``). The
target is a face count, a ratio of the input's faces, or only the error bound (both 0).
Afterwards it measures what it made: the distance from every reference vertex to the base
(relative to the bounding-box diagonal), the isotropy, and the topology against the input's,
with a warning in words for everything a user should know.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..spatial.closest import ClosestPointIndex
from ..mesh.trimesh import MeshError, TriMesh
from ..mesh.normalization import unit_sphere_normalization
from ..micro.metrics import isotropy
from ..settings.fields import ConstructSettings
from ..mesh.weld import weld
from .decimate import decimate
from .refine import refine as refined
from .surface_flips import surface_flips
from .topology import differences, topology


# Where the base's largest distance is over ``max_distance``, the RMS bound is multiplied by
# this and the decimation run again, at most this many times (the CAD plate of genus 11:
# 1.0e-3 -> 0.8e-3 -> ...; docs/performance.md).
TIGHTEN = 0.8
TIGHTEN_TRIES = 8


class BaseError(ValueError):
    """A base-mesh target that cannot be used."""


@dataclass
class BaseMesh:
    """A base mesh (caller's frame) and its report (see :func:`build_base`)."""

    mesh: TriMesh
    report: dict = field(default_factory=dict)

    @property
    def warnings(self) -> list[str]:
        return self.report.get("warnings", [])


def target_faces(n_faces: int, ratio: float = 0.0, faces: int = 0) -> int:
    """The face count asked for: ``faces`` if set, else ``ratio`` of ``n_faces``, else 1 (the
    error bound decides)."""
    if faces < 0 or not 0.0 <= ratio <= 1.0 or not np.isfinite(ratio):
        raise BaseError("the base target needs faces >= 0 and a ratio within [0, 1]")
    if faces > 0:
        return int(faces)
    if ratio > 0:
        return max(4, int(round(n_faces * ratio)))
    return 1


def welded(mesh: TriMesh) -> TriMesh:
    """``mesh`` with coincident vertices merged (``core.mesh.weld``) and the faces that then repeat a
    vertex dropped: files often split vertices along UV seams or flat-shaded edges, or are
    triangle soups, which would make every patch a part of its own."""
    try:
        return weld(mesh).mesh
    except MeshError as e:
        raise BaseError(str(e)) from None


def build_base(reference: TriMesh, ratio: float = 1 / 32, faces: int = 0,
               max_error: float = 1e-3, min_quality: float = 0.4, refine: float = 0.0,
               max_distance: float = 0.0,
               progress: Callable[[float], None] | None = None,
               should_stop: Callable[[], bool] | None = None) -> BaseMesh:
    """Decimate ``reference`` into a base mesh that keeps its topology.

    ``faces`` / ``ratio``: the target (see :func:`target_faces`). ``max_error``: bound on the
    RMS distance of merged vertices to the original planes, relative to the reference's
    bounding-box diagonal (0: none). ``min_quality``: floor on 2r/R of new triangles.
    After the collapses, edges are flipped where the other diagonal lies closer to the
    reference (:func:`core.base.surface_flips.surface_flips`).
    ``refine``: then edges split where a face's furthest reference vertex × its area is more
    than this many times the mean face's (:func:`core.base.refine.refine`; 0: none; not with
    a face count asked for).
    ``max_distance``: bound on the largest distance from a reference vertex to the base,
    relative to the diagonal (0: none; not with a face count asked for, nor without
    ``max_error``). Where the RMS bound leaves a vertex further, as on CAD parts whose flat
    faces hold the RMS down while their rims stay coarse, the decimation runs again with
    the RMS bound times ``TIGHTEN``, at most ``TIGHTEN_TRIES`` times.
    ``progress(fraction)``; ``should_stop()`` cancels (``DecimateCancelled``).

    The report: ``target_faces``, ``faces``, ``stopped`` ("target" or "limit"), ``flips``
    (the decimation's, of slivers), ``surface_flips``, ``splits``,
    ``error_mean`` / ``error_max`` (reference vertices to the base, over the diagonal; mean
    weighted by vertex area), ``rms_bound`` (the RMS bound the decimation last ran with),
    ``isotropy``, ``topology_input`` / ``topology_base``,
    ``warnings`` (sentences), ``time_s``.
    """
    t0 = time.perf_counter()
    if not np.isfinite(max_error) or max_error < 0:
        raise BaseError("max_error must be a finite number >= 0 (0: no bound)")
    if not 0 <= min_quality < 1:
        raise BaseError("min_quality must be within [0, 1)")
    if not np.isfinite(refine) or refine < 0:
        raise BaseError("refine must be a finite number >= 0 (0: none)")
    if not np.isfinite(max_distance) or max_distance < 0:
        raise BaseError("max_distance must be a finite number >= 0 (0: no bound)")
    target = target_faces(reference.n_faces, ratio, faces)
    norm = unit_sphere_normalization(reference.vertices)
    unit = welded(TriMesh(norm.apply(reference.vertices).astype(np.float32), reference.faces))
    n0 = reference.n_faces
    used = np.zeros(unit.n_vertices, bool)
    used[unit.faces.reshape(-1)] = True
    tries = TIGHTEN_TRIES if max_distance > 0 and max_error > 0 and faces == 0 else 0
    bound = max_error

    def report(n: int, tgt: int) -> None:
        if progress is not None:
            progress(min(1.0, (n0 - n) / max(n0 - tgt, 1)))

    for attempt in range(tries + 1):
        made = _collapsed(unit, used, target, bound, min_quality,
                          refine if faces == 0 else 0.0, report, should_stop)
        if attempt == tries or made.distance.max() <= max_distance:
            break
        bound *= TIGHTEN
    base_unit, dec, d, w = made.mesh, made.decimation, made.distance, unit.vertex_areas[used]
    topo_in, topo_base = topology(unit), topology(base_unit)
    rep = {"target_faces": target if target > 1 else None, "faces": base_unit.n_faces,
           "vertices": base_unit.n_vertices, "stopped": dec.stopped,
           "collapses": dec.collapses, "rejected": dec.rejected, "flips": dec.flips,
           "surface_flips": made.turned, "splits": made.splits,
           "max_error": max_error, "rms_bound": bound, "max_distance": max_distance,
           "min_quality": min_quality,
           "error_mean": float((d * w).sum() / max(w.sum(), 1e-300)),
           "error_max": float(d.max()), "isotropy": isotropy(base_unit.vertices, base_unit.faces),
           "topology_input": topo_in.as_dict(), "topology_base": topo_base.as_dict(),
           "warnings": differences(topo_in, topo_base),
           "notes": _notes(made, target, max_error, bound, max_distance),
           "time_s": time.perf_counter() - t0}
    return BaseMesh(TriMesh(norm.invert(base_unit.vertices), base_unit.faces), rep)


@dataclass
class _Collapsed:
    """A decimation (``core.base.decimate.Decimation``), then the mesh after its surface
    flips (``turned`` edges) and splits, and the distance (over the diagonal) to it from each
    reference vertex that a face uses."""

    mesh: TriMesh
    decimation: object
    turned: int
    splits: int
    distance: np.ndarray


def _collapsed(unit: TriMesh, used: np.ndarray, target: int, bound: float, min_quality: float,
               refine: float, report: Callable[[int, int], None],
               should_stop: Callable[[], bool] | None) -> _Collapsed:
    """One decimation of ``unit`` to ``target`` faces within the RMS ``bound`` (relative to
    the diagonal; 0: none), its surface flips and, with ``refine`` > 0, its splits; the
    distances from ``unit``'s vertices ``used`` (bool (n,)) to the result."""
    diag = unit.bbox_diagonal
    dec = decimate(unit, target, max_error=bound * diag if bound > 0 else np.inf,
                   min_quality=min_quality, progress=report, should_stop=should_stop)
    mesh, turned = surface_flips(TriMesh(dec.vertices, dec.faces), unit, min_quality)
    splits = 0
    if refine > 0:
        mesh, splits = refined(mesh, unit, refine)
    _, _, dist = ClosestPointIndex(mesh.vertices, mesh.faces).query(unit.vertices)
    return _Collapsed(mesh, dec, turned, splits, dist[used] / diag)


def _notes(made: _Collapsed, target: int, max_error: float, bound: float,
           max_distance: float) -> list[str]:
    """What a user should know of where the base stopped and of the bound it was made with."""
    notes = []
    faces = len(made.decimation.faces)
    if faces > target and target > 1:
        notes.append(f"the base stopped at {faces} faces instead of {target}: "
                     "no further collapse keeps the error bound, the topology and the "
                     "triangle shapes")
    if bound < max_error:
        far = float(made.distance.max())
        notes.append(f"the RMS error bound was tightened to {bound:.2g} of the diagonal so that "
                     f"the base lies within {max_distance:.2g} of every source vertex"
                     + ("" if far <= max_distance else
                        f"; it still misses that by up to {far:.2g}"))
    return notes


def base_for(reference: TriMesh, s: ConstructSettings,
             progress: Callable[[float], None] | None = None,
             should_stop: Callable[[], bool] | None = None) -> BaseMesh:
    """:func:`build_base` with the targets of construction settings (``base_*``)."""
    return build_base(reference, ratio=s.base_ratio, faces=s.base_faces,
                      max_error=s.base_max_error, min_quality=s.base_min_quality,
                      refine=s.base_refine, max_distance=s.base_max_distance,
                      progress=progress, should_stop=should_stop)
