"""A micro-mesh to files other tools read: glTF 2.0 (``.gltf`` + ``.bin`` + ``.bary``, or one
``.glb`` with the ``.bary`` in a buffer view) with ``NV_micromaps`` and
``NV_displacement_micromap``.

Identity triangle mapping (no ``mapIndices``, ``mapOffset`` 0), one group, one value format per
file: what NVIDIA's reference reader supports. Values are stored in [0, 1] between per-vertex
direction bounds folded into the positions and directions, as micromesh-tools writes them
(``core.micro.bounds.baked``): a micro-vertex is ``lerp(P + D·bias) + lerp(D·scale)·value``, the
same surface a ``directionBounds`` accessor would give, without one. Each datum is written once:
directions and edge flags as accessors (not again as ``.bary`` mesh properties), the levels in
the ``.bary``'s triangle records, indices as u16 where they fit. ``core.io.file_size`` counts
the bytes.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..micro.bounds import DirectionBounds, baked, normalized_values, tight_bounds
from ..mesh.float32_origin import node_translation, relative
from ..micro.micromesh import MicroMesh
from ..micro.level_grid import BUILD_MAX_LEVEL
from ..micro.levels import edge_flags
from .bary import (LAYOUT_BIRD, LAYOUT_UMAJOR, R11_UNORM_PACK16, R11_UNORM_PACKED_ALIGN32,
                   BaryFile, Group, TRIANGLE, encode)
from .bary_values import FORMAT_NAMES, encode_values, quantize11
from .file_size import index_bytes
from .gltf import Builder, pack_glb

LAYOUTS = {"bird": LAYOUT_BIRD, "umajor": LAYOUT_UMAJOR}
EXTENSIONS = ["NV_micromaps", "NV_displacement_micromap"]
# Blender's Z-up to glTF's Y-up, as Blender's own glTF exporter does: (x, y, z) → (x, z, −y).
Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


class ExportError(ValueError):
    """Options or a micro-mesh that cannot be written."""


@dataclass
class ExportReport:
    files: list[Path]
    bytes: int
    quantization_max: float  # over the bounding-box diagonal
    quantization_rms: float


def stored_values(mm: MicroMesh, bounds: DirectionBounds, value_format: str) -> np.ndarray:
    """(n,) the value each micro-vertex is stored as, decoded back to [0, 1] (11-bit values
    rounded, float values as float32)."""
    return _stored(normalized_values(mm, bounds), value_format)


def _stored(t: np.ndarray, value_format: str) -> np.ndarray:
    if value_format == "r11":
        return quantize11(t) / 2047.0
    return t.astype(np.float32).astype(np.float64)


def decoded_positions(mm: MicroMesh, bounds: DirectionBounds, values: np.ndarray) -> np.ndarray:
    """(n, 3) micro-vertex positions a reader computes from the stored values."""
    interp, D = mm.topology.interp, mm.directions
    return interp @ (mm.base.vertices + D * bounds.bias[:, None]) + \
        (interp @ (D * bounds.scale[:, None])) * values[:, None]


def quantization_error(mm: MicroMesh, bounds: DirectionBounds | None = None,
                       value_format: str = "r11") -> tuple[float, float]:
    """(max, RMS) distance between the stored and the exact micro-vertex positions, over the
    base's bounding-box diagonal."""
    b = tight_bounds(mm) if bounds is None else bounds
    err = np.linalg.norm(decoded_positions(mm, b, stored_values(mm, b, value_format))
                         - mm.micro_vertex_positions(), axis=1)
    diag = float(np.linalg.norm(np.ptp(mm.base.vertices, axis=0))) or 1.0
    return float(err.max(initial=0.0)) / diag, float(np.sqrt((err ** 2).mean())) / diag


def to_bary(mm: MicroMesh, value_format: str = "r11", layout: str = "bird") -> BaryFile:
    """The ``.bary`` of a micro-mesh whose bounds are folded in (``core.micro.bounds.baked``: its
    displacements are the values, in [0, 1]): values, one group, triangles and per-triangle
    min/max (the directions and flags are the glTF's accessors)."""
    fmt = FORMAT_NAMES[value_format]
    ptr, _ = mm.face_values(layout)
    values = _stored(np.clip(mm.displacements, 0.0, 1.0), value_format)
    _, per_face = mm.with_displacements(values).face_values(layout)
    payload, offsets, count, size = encode_values(fmt, mm.levels, ptr, per_face)
    tri = np.zeros(len(mm.levels), TRIANGLE)
    tri["offset"], tri["level"] = offsets, mm.levels
    starts = ptr[:-1]
    lo, hi = np.minimum.reduceat(per_face, starts), np.maximum.reduceat(per_face, starts)
    if fmt == R11_UNORM_PACKED_ALIGN32:
        minmax = np.stack([quantize11(lo), quantize11(hi)], 1).astype("<u2").tobytes()
        mm_fmt = R11_UNORM_PACK16
    else:
        minmax, mm_fmt = np.stack([lo, hi], 1).astype("<f4").tobytes(), fmt
    group = Group(0, len(mm.levels), 0, count, int(mm.levels.min(initial=0)),
                  int(mm.levels.max(initial=0)))
    return BaryFile(fmt, LAYOUTS[layout], count, size, payload, [group], tri, minmax, mm_fmt)


def micromesh_files(path: str | os.PathLike, mm: MicroMesh,
                    bounds: DirectionBounds | None = None, *, value_format: str = "r11",
                    layout: str = "bird", y_up: bool = False
                    ) -> tuple[list[tuple[Path, bytes]], ExportReport]:
    """The files of ``path`` (``.gltf``: with ``.bin`` and ``.bary`` beside it, named from its
    stem; ``.glb``: one file) as (path, bytes), the ``.gltf`` last, and the report.
    ``y_up`` turns Blender's Z-up into glTF's Y-up."""
    path = Path(path)
    if path.suffix.lower() not in (".gltf", ".glb"):
        raise ExportError(f"export to .gltf or .glb, not '{path.suffix}'")
    if value_format not in FORMAT_NAMES or layout not in LAYOUTS:
        raise ExportError(f"value format must be one of {sorted(FORMAT_NAMES)} and layout one of "
                          f"{sorted(LAYOUTS)}, got {value_format!r}, {layout!r}")
    if mm.levels.max(initial=0) > BUILD_MAX_LEVEL:
        raise ExportError(f"subdivision levels above {BUILD_MAX_LEVEL} cannot be written: "
                          "NVIDIA's reader and the ray-tracing hardware stop there")
    b = tight_bounds(mm) if bounds is None else bounds
    qmax, qrms = quantization_error(mm, b, value_format)
    mm = baked(mm, b)                  # the bounds folded in: the values, in [0, 1]
    if y_up:
        mm = mm.transformed(Y_UP)
    bary = encode(to_bary(mm, value_format, layout))
    glb = path.suffix.lower() == ".glb"
    doc, blob = _document(mm, path, bary if glb else None)
    files = [(path, pack_glb(doc, blob))] if glb else [
        (path.with_suffix(".bary"), bary), (path.with_suffix(".bin"), blob),
        (path, json.dumps(doc, indent=1).encode())]
    return files, ExportReport([p for p, _ in files], sum(len(d) for _, d in files), qmax, qrms)


def write_micromesh(path: str | os.PathLike, mm: MicroMesh, bounds: DirectionBounds | None = None,
                    **options) -> ExportReport:
    """Write :func:`micromesh_files`: each file under a temporary name first, then renamed,
    the ``.gltf`` last, so a reader never finds one whose companions are missing."""
    files, report = micromesh_files(path, mm, bounds, **options)
    _write_all(files)
    return report


def _document(mm: MicroMesh, path: Path, embedded: bytes | None):
    g = Builder()
    base = mm.base
    idx = g.accessor(base.faces.reshape(-1), f"<u{index_bytes(base.n_vertices)}", "indices",
                     target=34963)
    local, origin = relative(base.vertices)    # far from the origin: a node translation
    pos = g.accessor(local, "<f4", "positions", target=34962, bounds=True)
    nrm = g.accessor(_unit(base.vertex_normals), "<f4", "normals", target=34962)
    dirs = g.accessor(mm.directions, "<f4", "directions")
    flags = g.accessor(edge_flags(base, mm.levels), "u1", "primitive_flags")
    micromap = {"uri": path.with_suffix(".bary").name}
    if embedded is not None:
        micromap = {"bufferView": g.view(embedded, "micromap"), "mimeType": "model/vnd.bary"}
    doc, blob = g.finish(None if embedded is not None else path.with_suffix(".bin").name)
    doc["meshes"] = [{"name": path.stem, "primitives": [{
        "attributes": {"POSITION": pos, "NORMAL": nrm}, "indices": idx, "mode": 4,
        "extensions": {"NV_displacement_micromap": {"micromap": 0, "directions": dirs,
                                                    "primitiveFlags": flags}}}]}]
    doc["nodes"] = [{"mesh": 0, "name": path.stem, **node_translation(origin)}]
    doc["scenes"], doc["scene"] = [{"nodes": [0]}], 0
    doc["extensions"] = {"NV_micromaps": {"micromaps": [micromap]}}
    doc["extensionsUsed"] = list(EXTENSIONS)
    return doc, blob


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=1, keepdims=True)
    return np.where(n > 0, v / np.maximum(n, 1e-300), np.array([0.0, 0.0, 1.0]))


def _write_all(outputs: list[tuple[Path, bytes]]) -> None:
    temps = []
    try:
        for p, data in outputs:
            tmp = p.with_name(f".{p.name}.{os.getpid()}.tmp")
            temps.append(tmp)
            with open(tmp, "wb") as f:
                f.write(data)
                f.flush()
                os.fsync(f.fileno())
        for (p, _), tmp in zip(outputs, temps):
            os.replace(tmp, p)
    except OSError as e:
        for tmp in temps:
            tmp.unlink(missing_ok=True)
        raise ExportError(f"cannot write {outputs[-1][0]}: {e.strerror or e}") from None
