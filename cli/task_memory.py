"""The memory one input's Ray task asks for: the construction's estimate
(``core.construct.estimate``, the figure ``batch.py`` prints per input) from the input's
triangle count, read without reading the mesh where the format says it: a PLY's header, a
binary STL's size, an OBJ's face lines, a glTF's index counts (a micro-mesh glTF's
micro-triangles from its levels). Blender's other formats (.fbx, .blend, .usd*) are counted
from their size, 20 bytes a triangle: more than most such files hold, so the task asks for
too much rather than too little.
"""
from __future__ import annotations

from pathlib import Path

BYTES_PER_TRIANGLE = 20      # the size rule for formats whose counts need Blender
_HEADER_CHUNK = 1 << 16


def triangles(path: Path) -> int:
    """About how many triangles ``path`` holds (exact for triangle PLY/STL/OBJ/glTF)."""
    suffix = path.suffix.lower()
    try:
        if suffix == ".ply":
            return _ply(path)
        if suffix == ".stl":
            return _stl(path)
        if suffix == ".obj":
            return _obj(path)
        if suffix in (".gltf", ".glb"):
            return _gltf(path)
    except (OSError, ValueError, KeyError, TypeError):
        pass                 # unreadable here: the run says why; the size rule meanwhile
    return max(1, path.stat().st_size // BYTES_PER_TRIANGLE)


def task_memory(path: Path, settings) -> int:
    """Bytes of memory the input's construction is estimated to peak at."""
    from ..core.construct.estimate import estimate

    return int(estimate(triangles(path), settings, speed=1.0).peak_bytes)


def _ply(path: Path) -> int:
    from ..core.io.ply_header import parse_header

    data = b""
    with open(path, "rb") as f:
        while b"end_header" not in data:
            chunk = f.read(_HEADER_CHUNK)
            if not chunk or len(data) > 64 * _HEADER_CHUNK:
                raise ValueError("no PLY header")
            data += chunk
    _, elements, _ = parse_header(data, path)
    return next(e.count for e in elements if e.name == "face")


def _stl(path: Path) -> int:
    size = path.stat().st_size
    with open(path, "rb") as f:
        head = f.read(84)
    n = int.from_bytes(head[80:84], "little") if len(head) == 84 else -1
    if size == 84 + 50 * n:                  # binary, as core.io.stl tells it
        return n
    return path.read_bytes().count(b"endfacet")


def _obj(path: Path) -> int:
    n = 0
    with open(path, "rb") as f:
        for line in f:
            if line.startswith(b"f ") or line.startswith(b"f\t"):
                n += max(1, len(line.split()) - 3)      # a polygon of k corners: k - 2
    return n


def _gltf(path: Path) -> int:
    from ..core.io.gltf import Document
    from ..core.io.micromesh_import import is_micromesh_file, read_micromesh

    if is_micromesh_file(path):         # read as its tessellation: 4^level per base triangle
        return int((4 ** read_micromesh(path).levels.astype("int64")).sum())
    doc = Document(path).doc
    accessors = doc.get("accessors", [])
    n = 0
    for mesh in doc.get("meshes", []):
        for prim in mesh.get("primitives", []):
            if prim.get("mode", 4) != 4:          # triangles only
                continue
            i = prim.get("indices", prim["attributes"]["POSITION"])
            n += int(accessors[i]["count"]) // 3
    return n
