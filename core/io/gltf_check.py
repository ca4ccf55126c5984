"""A glTF file checked before Blender's importer reads it, so that what is wrong with it is
said in one line: not glTF or not valid JSON, a buffer file that is missing or too short,
an accessor that reads past its data, a face index past the vertices, NaN or infinite
positions (which Blender's importer would turn into zeros), a node or mesh that does not
exist, a node hierarchy with a cycle, a primitive mode glTF does not have. Only what this
reader reads is checked: compressed primitives (Draco, meshopt) and sparse accessors are left
to Blender's importer."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .gltf import Document, GltfError

_COMPRESSED = ("KHR_draco_mesh_compression",)


def check_gltf(path: str | os.PathLike) -> None:
    """Raise :class:`GltfError` naming the first problem of ``path`` (``.gltf`` or ``.glb``)
    that Blender's importer would fail on or hide."""
    path = Path(path)
    try:
        doc = Document(path)
        _check_nodes(doc)
        bad, total = 0, 0
        for m, mesh in enumerate(doc.doc.get("meshes", [])):
            for p, prim in enumerate(mesh.get("primitives", [])):
                where = f"mesh {m} primitive {p}"
                b, t = _check_primitive(doc, prim, where)
                bad, total = bad + b, total + t
    except GltfError:
        raise
    except (KeyError, TypeError, ValueError, IndexError, AttributeError, OverflowError) as e:
        raise GltfError(f"{path.name}: not valid glTF ({type(e).__name__}: {e})") from None
    if bad:
        raise GltfError(f"{path.name}: {bad} of {total} vertices have NaN or infinite "
                        "positions")


def _check_nodes(doc: Document) -> None:
    d = doc.doc
    for scene in d.get("scenes", []):
        for n in scene.get("nodes", []):
            doc.item("nodes", n)
    parent: dict[int, int] = {}
    for i, node in enumerate(d.get("nodes", [])):
        for c in node.get("children", []):
            doc.item("nodes", c)
            if c in parent:
                raise GltfError(f"{doc.path.name}: node {c} is a child of two nodes")
            parent[c] = i
        if "mesh" in node:
            doc.item("meshes", node["mesh"])
        values = [node.get(k, []) for k in ("matrix", "translation", "rotation", "scale")]
        if not np.isfinite(np.concatenate([np.asarray(v, float).ravel() for v in values])).all():
            raise GltfError(f"{doc.path.name}: node {i}'s transform is NaN or infinite")
    for i in parent:
        up, steps = i, 0
        while up in parent and steps <= len(parent):
            up, steps = parent[up], steps + 1
        if up in parent:
            raise GltfError(f"{doc.path.name}: node {i} is its own ancestor (a cycle)")


def _check_primitive(doc: Document, prim: dict, where: str) -> tuple[int, int]:
    """(vertices with NaN or infinite positions, vertices) of one primitive."""
    attrs = prim.get("attributes", {})
    if "POSITION" not in attrs:
        raise GltfError(f"{doc.path.name}: {where} has no POSITION")
    pos = doc.item("accessors", attrs["POSITION"])
    n = int(pos.get("count", 0))
    if prim.get("mode", 4) not in range(7):
        raise GltfError(f"{doc.path.name}: {where}'s mode {prim['mode']} is not a glTF mode")
    if any(e in prim.get("extensions", {}) for e in _COMPRESSED):
        return 0, n
    bad = 0
    if _readable(doc, pos):
        v = doc.accessor(attrs["POSITION"])
        bad = int((~np.isfinite(v.reshape(n, -1))).any(axis=1).sum())
    if "indices" in prim:
        acc = doc.item("accessors", prim["indices"])
        if _readable(doc, acc):
            idx = doc.accessor(prim["indices"])
            if len(idx) and (idx.min() < 0 or idx.max() >= n):
                raise GltfError(f"{doc.path.name}: {where}'s face index {int(idx.max())} is "
                                f"out of range ({n} vertices)")
    return bad, n


def _readable(doc: Document, acc: dict) -> bool:
    """Whether ``acc`` is a plain accessor this reader reads (not sparse, not compressed)."""
    if "sparse" in acc or "bufferView" not in acc:
        return False
    view = doc.item("bufferViews", acc["bufferView"])
    return not view.get("extensions")
