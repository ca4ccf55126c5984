"""Micro-mesh files to arrays: glTF/GLB + ``.bary`` as micromesh-tools and NVIDIA's tools write
them (u-major or bird curve, every uncompressed value format, direction bounds or bounds baked
into positions and directions, group bias and scale, ``mapIndices``/``mapOffset``, node
transforms). Malformed files raise :class:`MicromeshFileError` naming the problem.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..micro.level_grid import MAX_LEVEL, bird_order
from .bary import LAYOUT_BIRD, BaryError, decode
from .bary_values import decode_values
from .gltf import Document, GltfError
from .micromesh_file import MicromeshFile, MicromeshFileError, merge

__all__ = ["MicromeshFile", "MicromeshFileError", "is_micromesh_file", "read_micromesh"]


def is_micromesh_file(path: str | os.PathLike) -> bool:
    """Whether a ``.gltf``/``.glb`` has a primitive with ``NV_displacement_micromap`` (False
    for files that are not glTF at all: the caller's mesh reader says why)."""
    try:
        doc = Document(path)
    except (GltfError, OSError):
        return False
    return any("NV_displacement_micromap" in p.get("extensions", {})
               for m in doc.doc.get("meshes", []) for p in m.get("primitives", []))


def read_micromesh(path: str | os.PathLike) -> MicromeshFile:
    """Read a ``.gltf``/``.glb`` micro-mesh (every primitive with ``NV_displacement_micromap``
    in the default scene, node transforms applied, primitives merged)."""
    path = Path(path)
    try:
        doc = Document(path)
        return _read(doc)
    except (GltfError, BaryError) as e:
        raise MicromeshFileError(str(e)) from None
    except (KeyError, TypeError, ValueError, IndexError) as e:
        if isinstance(e, MicromeshFileError):
            raise
        raise MicromeshFileError(f"{path.name}: malformed micro-mesh glTF ({type(e).__name__}: "
                                 f"{e})") from None


def _read(doc: Document) -> MicromeshFile:
    maps = doc.doc.get("extensions", {}).get("NV_micromaps", {}).get("micromaps", [])
    barys: dict[int, object] = {}
    parts, skipped = [], 0
    for matrix, prim in _primitives(doc):
        ext = prim.get("extensions", {}).get("NV_displacement_micromap")
        if ext is None:
            skipped += 1
            continue
        m = ext["micromap"]
        if m not in barys:
            if not isinstance(m, int) or not 0 <= m < len(maps):
                raise MicromeshFileError(f"{doc.path.name}: micromap {m} is not listed")
            src = maps[m]
            data = doc.view(src["bufferView"]) if "bufferView" in src else doc.external(src["uri"])
            barys[m] = decode(data, src.get("uri", f"micromap {m}"))
        parts.append(_primitive(doc, prim, ext, barys[m], matrix))
    if not parts:
        raise MicromeshFileError(f"{doc.path.name}: no primitive has NV_displacement_micromap "
                                 "(a plain mesh: import it as a mesh)")
    out = merge(parts)
    if skipped:
        out.warnings.append(f"{skipped} primitives without a micromap were left out")
    return out


def _primitives(doc: Document):
    """(world matrix, primitive) of every mesh primitive in the default scene."""
    d = doc.doc
    scenes = d.get("scenes") or [{"nodes": list(range(len(d.get("nodes", []))))}]
    stack = [(np.eye(4), n) for n in scenes[d.get("scene", 0)].get("nodes", [])]
    while stack:
        parent, i = stack.pop()
        node = doc.item("nodes", i)
        m = np.asarray(node["matrix"], float).reshape(4, 4).T if "matrix" in node else _trs(node)
        world = parent @ m
        if "mesh" in node:
            for prim in doc.item("meshes", node["mesh"]).get("primitives", []):
                yield world, prim
        stack.extend((world, c) for c in node.get("children", []))


def _trs(node: dict) -> np.ndarray:
    x, y, z, w = node.get("rotation", [0, 0, 0, 1])
    r = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                  [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                  [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    m = np.eye(4)
    m[:3, :3] = r * np.asarray(node.get("scale", [1, 1, 1]), float)[None, :]
    m[:3, 3] = node.get("translation", [0, 0, 0])
    return m


def _primitive(doc, prim, ext, bf, matrix) -> MicromeshFile:
    P = doc.accessor(prim["attributes"]["POSITION"]).reshape(-1, 3)
    n = len(P)
    F = (doc.accessor(prim["indices"]) if "indices" in prim else np.arange(n)).reshape(-1, 3)
    if prim.get("mode", 4) != 4 or len(F) == 0 or F.min() < 0 or F.max() >= n:
        raise MicromeshFileError(f"{doc.path.name}: a primitive is not a valid triangle list")
    D = _per_vertex(doc, ext, "directions", bf.directions, n, 3)
    if D is None:
        if "NORMAL" not in prim["attributes"]:
            raise MicromeshFileError(f"{doc.path.name}: no directions and no normals")
        D = doc.accessor(prim["attributes"]["NORMAL"])
    D = D[:, :3]
    B = _per_vertex(doc, ext, "directionBounds", bf.direction_bounds, n, 2)
    lv_all, ptr_all, vals_all = decode_values(bf, doc.path.name)
    tri = np.arange(len(F)) if "mapIndices" not in ext else doc.accessor(ext["mapIndices"])
    group = bf.groups[ext.get("groupIndex", 0)]
    tri = tri.astype(np.int64) + ext.get("mapOffset", 0) + group.triangle_first
    if len(tri) != len(F) or tri.min() < 0 or tri.max() >= len(lv_all):
        raise MicromeshFileError(f"{doc.path.name}: triangles map outside the micromap")
    flags = _per_face(doc, ext, bf.triangle_flags, len(F))
    lv = lv_all[tri]
    if lv.max() > MAX_LEVEL:
        raise MicromeshFileError(f"{doc.path.name}: subdivision level {int(lv.max())} is over "
                                 f"{MAX_LEVEL}, the most this reader tessellates")
    counts = np.diff(ptr_all)[tri]
    ptr = np.concatenate([[0], np.cumsum(counts)])
    src = np.repeat(ptr_all[tri], counts) + np.arange(ptr[-1]) - np.repeat(ptr[:-1], counts)
    vals = vals_all[src]
    if bf.layout == LAYOUT_BIRD:
        vals = _bird_to_umajor(lv, ptr, vals)
    Pw = P @ matrix[:3, :3].T + matrix[:3, 3]
    Dw = D @ matrix[:3, :3].T
    if not (np.isfinite(Pw).all() and np.isfinite(Dw).all()):
        raise MicromeshFileError(f"{doc.path.name}: positions or directions are NaN or infinite")
    bias, scale = (np.zeros(n), np.ones(n)) if B is None else (B[:, 0], B[:, 1])
    return MicromeshFile(Pw, F, Dw, bias, scale, lv, flags & 7, ptr, vals)


def _per_vertex(doc, ext, key, prop, n, comps):
    if key in ext:
        a = doc.accessor(ext[key]).reshape(n, -1)
    elif prop is not None:
        off = ext.get(key + "Offset", 0)
        a = np.asarray(prop, float).reshape(len(prop), -1)[off:off + n]
    else:
        return None
    if len(a) != n or a.shape[1] < comps:
        raise MicromeshFileError(f"{doc.path.name}: {key} has the wrong size")
    return a


def _per_face(doc, ext, prop, m) -> np.ndarray:
    if "primitiveFlags" in ext:
        f = doc.accessor(ext["primitiveFlags"])
    elif prop is not None:
        off = ext.get("primitiveFlagsOffset", 0)
        f = np.asarray(prop)[off:off + m]
    else:
        return np.zeros(m, np.int64)
    if len(f) != m:
        raise MicromeshFileError(f"{doc.path.name}: primitiveFlags has the wrong size")
    return f.astype(np.int64)


def _bird_to_umajor(lv, ptr, vals):
    out = np.empty_like(vals)
    for level in np.unique(lv):
        fl = np.flatnonzero(lv == level)
        bo = bird_order(int(level))
        rows = ptr[fl][:, None]
        out[(rows + bo[None, :]).reshape(-1)] = vals[(rows + np.arange(len(bo))).reshape(-1)]
    return out
