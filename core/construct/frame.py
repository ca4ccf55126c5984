"""Inputs of a construction, checked and brought into the reference's unit-sphere frame, and
the result taken back to the caller's frame."""
from __future__ import annotations

import time
from typing import Callable

import numpy as np
import torch

from ..base import DecimateCancelled, builders, differences, topology
from ..mesh.normalization import Normalization
from ..mesh.reference import oriented_reference
from ..mesh.trimesh import MeshError, TriMesh
from ..micro.bounds import DirectionBounds
from ..micro.levels import balance_levels
from ..micro.micromesh import MicroMesh
from ..render.cameras import Cameras, fibonacci_cameras
from ..settings.fields import ConstructSettings
from .types import ConstructCancelled, ConstructError, Progress


def device(name: str) -> torch.device:
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name == "cuda" and not torch.cuda.is_available():
        raise ConstructError("device 'cuda' requested but no CUDA device is available")
    return torch.device(name)


def check_reference(reference: TriMesh) -> None:
    """Refuse a reference with nothing to see: no extent, or only degenerate faces."""
    if not isinstance(reference, TriMesh):
        raise ConstructError("the reference must be a core.mesh.TriMesh")
    diag = reference.bbox_diagonal
    area = reference.face_areas
    if not diag > 0 or not (area > 1e-12 * diag * diag).any():
        raise ConstructError(f"the input has no surface: all {reference.n_faces} faces are "
                             "degenerate (zero area)")


def oriented(reference: TriMesh) -> tuple[TriMesh, list[str]]:
    """``core.mesh.reference.oriented_reference``; a reference with no surface refused."""
    try:
        return oriented_reference(reference)
    except MeshError as e:
        raise ConstructError(str(e)) from None


def check_inputs(reference: TriMesh, base: TriMesh) -> None:
    if not isinstance(reference, TriMesh) or not isinstance(base, TriMesh):
        raise ConstructError("reference and base must be core.mesh.TriMesh")
    check_reference(reference)
    if base.n_faces > reference.n_faces * 4:
        raise ConstructError("the base mesh has more faces than the reference; is it swapped?")


def prepare_base(reference: TriMesh, base: TriMesh | None, s: ConstructSettings,
                 progress: Callable | None = None, should_stop: Callable[[], bool] | None = None
                 ) -> tuple[TriMesh, dict | None, list[str]]:
    """The base to build on and what to say of it: (base, the base builder's report or None,
    warnings in words). ``base`` None: the settings' base (``base_method``'s row of
    ``core.base.builders``), with progress reports of phase "base"; its warnings say where it
    stopped short or differs from the reference. A given base: its topology compared with the
    reference's."""
    if base is not None:
        return base, None, differences(topology(reference), topology(base))
    try:
        builder = builders.get(s.base_method)
    except ValueError as e:
        raise ConstructError(str(e)) from None
    if builder.takes != builders.ARRAYS:
        raise ConstructError(f"the base method {builder.key!r} ({builder.label}) works on the "
                             "source object in Blender: make the base first (Make Base, or "
                             f"batch.py --base-method {builder.key})")

    t0 = time.perf_counter()

    def report(fraction: float) -> None:
        # Time left at the pace so far, to the target face count: an upper bound where the
        # error bound stops the decimation first.
        if progress is not None:
            el = time.perf_counter() - t0
            eta = el * (1 - fraction) / fraction if fraction > 0.01 else float("nan")
            progress(Progress("base", int(100 * fraction), 100, 0.0, float("nan"), eta))

    report(0.0)           # before the welding and the quadrics: minutes on 2M faces
    try:
        built = builder.build(reference, s, report, should_stop)
    except DecimateCancelled:
        raise ConstructCancelled("construction cancelled") from None
    return built.mesh, built.report, list(built.report["warnings"])


def fixed_levels(base: TriMesh, levels) -> np.ndarray:
    """The artist's per-face levels, checked (one per base face, integers 0..5) and balanced."""
    lv = np.asarray(levels)
    if lv.shape != (base.n_faces,):
        raise ConstructError(f"levels must hold one value per base face ({base.n_faces}), "
                             f"got shape {lv.shape}")
    if lv.size and (not np.all(np.isfinite(lv)) or np.any(lv != np.round(lv))):
        raise ConstructError("levels must be whole numbers")
    lv = lv.astype(np.int64)
    if lv.size and (lv.min() < 0 or lv.max() > 5):
        raise ConstructError("levels must be within 0..5 (the hardware limit is 5)")
    return balance_levels(base, lv)


def similarity_matrix(norm: Normalization) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] *= norm.scale
    m[:3, 3] = -norm.center * norm.scale
    return m


def unit_cameras(cameras: Cameras | None, norm: Normalization, s: ConstructSettings,
                 resolution: int) -> Cameras:
    if cameras is None:
        return fibonacci_cameras(s.n_views, s.camera_radius, s.fov_y_deg, resolution)
    return cameras.transformed(similarity_matrix(norm)).at_resolution(resolution)


def to_caller_frame(mm: MicroMesh, bounds: DirectionBounds, norm: Normalization
                    ) -> tuple[MicroMesh, DirectionBounds]:
    """Positions back through the normalisation; displacements and bounds scale by 1/s."""
    base = mm.base.with_vertices(norm.invert(mm.base.vertices))
    inv = 1.0 / norm.scale
    out = MicroMesh(base, mm.directions, mm.levels, mm.displacements * inv, mm._topology)
    return out, DirectionBounds(bounds.bias * inv, bounds.scale * inv)
