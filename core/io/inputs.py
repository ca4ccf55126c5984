"""The table of input formats: the files a construction reads, by suffix, with the reader
that turns one into a triangle mesh without Blender and the count of its triangles read
without reading the mesh (a Ray task's memory). ``batch.py``'s inputs, the headless source
and the Ray memory estimate all read it (trimesh's loader table is the model): adding a
format is its reader's module and one :func:`register` call.

A row without a reader, or whose reader returns None for a file (a glTF that is not a
micro-mesh), is read by Blender's importer named in the row (``operators/sources.py``).
Meshes we read keep the file's own coordinates; Blender's importers turn Y-up into Z-up.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Callable

from .polygons import MeshFileError

if TYPE_CHECKING:      # the readers import what they read with when they run
    from ..mesh.trimesh import TriMesh

BYTES_PER_TRIANGLE = 20      # the size rule for formats whose counts need Blender
_HEADER_CHUNK = 1 << 16


@dataclass(frozen=True)
class InputFormat:
    """One row: ``key``, ``suffixes`` (lower case), ``read(path) -> TriMesh | None`` (None, or
    a None result: Blender's ``importer`` reads it), ``triangles(path) -> int`` (None: the
    size rule, :data:`BYTES_PER_TRIANGLE` a triangle, more than most such files hold),
    ``importer``: Blender's ("gltf", "fbx", "usd", "blend")."""

    key: str
    suffixes: tuple[str, ...]
    read: Callable[[Path], TriMesh | None] | None = None
    triangles: Callable[[Path], int] | None = None
    importer: str | None = None


INPUTS: dict[str, InputFormat] = {}


IMPORTERS = ("gltf", "fbx", "usd", "blend")      # Blender's, as operators/sources.py has them


def register(fmt: InputFormat) -> InputFormat:
    """Add ``fmt`` to the table (replacing a row of the same key); ValueError for a row that
    nothing would read or whose suffix another row has."""
    if fmt.read is None and fmt.importer is None:
        raise ValueError(f"input format {fmt.key!r}: a reader or Blender's importer is needed")
    if fmt.importer is not None and fmt.importer not in IMPORTERS:
        raise ValueError(f"input format {fmt.key!r}: Blender's importer is one of "
                         f"{', '.join(IMPORTERS)}, not {fmt.importer!r}")
    taken = {s: f.key for f in INPUTS.values() if f.key != fmt.key for s in f.suffixes}
    clash = [s for s in fmt.suffixes if s in taken]
    if clash:
        raise ValueError(f"input format {fmt.key!r}: {', '.join(clash)} is "
                         f"{taken[clash[0]]!r}'s")
    INPUTS[fmt.key] = fmt
    return fmt


def suffixes() -> tuple[str, ...]:
    """Every suffix an input may have, in the table's order."""
    return tuple(s for f in INPUTS.values() for s in f.suffixes)


def format_of(path: str | os.PathLike) -> InputFormat | None:
    """The row of ``path``'s suffix (None: not an input)."""
    suffix = Path(path).suffix.lower()
    return next((f for f in INPUTS.values() if suffix in f.suffixes), None)


def read_mesh(path: str | os.PathLike) -> "TriMesh":
    """``path`` as a triangle mesh by our own reader (``.ply`` ASCII or binary, ``.obj``,
    ``.stl`` ASCII or binary as the triangle soup it lists, a micro-mesh glTF as its
    tessellation); :class:`MeshFileError` (a ValueError) names what is wrong, or that Blender
    must read it."""
    path = Path(path)
    if not path.is_file():
        raise MeshFileError(f"{path}: no such file")
    from .gltf import GltfError
    from .micromesh_import import MicromeshFileError

    fmt = format_of(path)
    try:
        mesh = fmt.read(path) if fmt is not None and fmt.read is not None else None
    except (GltfError, MicromeshFileError) as e:
        raise MeshFileError(str(e)) from None
    if mesh is None:
        ours = ", ".join(s for f in INPUTS.values() if f.read and not f.importer
                         for s in f.suffixes)
        raise MeshFileError(f"{path}: unsupported mesh format {path.suffix.lower()!r} "
                            f"(use {ours}, or a micro-mesh glTF)")
    return mesh


def count_triangles(path: Path) -> int:
    """About how many triangles ``path`` holds (exact for triangle PLY/STL/OBJ/glTF)."""
    fmt = format_of(path)
    try:
        if fmt is not None and fmt.triangles is not None:
            return fmt.triangles(path)
    except (OSError, ValueError, KeyError, TypeError):
        pass                 # unreadable here: the run says why; the size rule meanwhile
    return max(1, path.stat().st_size // BYTES_PER_TRIANGLE)


def _arrays(reader):
    """A reader of (vertices, faces) as one of a checked :class:`TriMesh`."""
    def read(path: Path) -> TriMesh:
        from ..mesh.trimesh import MeshError, TriMesh

        verts, faces = reader(path)
        if verts is None or faces is None:
            raise MeshFileError(f"{path}: missing vertex or face data")
        try:
            return TriMesh(verts, faces)
        except MeshError as e:
            raise MeshFileError(f"{path}: {e}") from None
    return read


def _ply(path: Path) -> TriMesh:
    from .ply import read_ply

    return _arrays(read_ply)(path)


def _obj(path: Path) -> TriMesh:
    from .obj import read_obj

    return _arrays(read_obj)(path)


def _stl(path: Path) -> TriMesh:
    from .stl import read_stl

    return _arrays(read_stl)(path)


def _ply_faces(path: Path) -> int:
    from .ply_header import parse_header

    data = b""
    with open(path, "rb") as f:
        while b"end_header" not in data:
            chunk = f.read(_HEADER_CHUNK)
            if not chunk or len(data) > 64 * _HEADER_CHUNK:
                raise ValueError("no PLY header")
            data += chunk
    _, elements, _ = parse_header(data, path)
    return next(e.count for e in elements if e.name == "face")


def _stl_facets(path: Path) -> int:
    size = path.stat().st_size
    with open(path, "rb") as f:
        head = f.read(84)
    n = int.from_bytes(head[80:84], "little") if len(head) == 84 else -1
    if size == 84 + 50 * n:                  # binary, as core.io.stl tells it
        return n
    return path.read_bytes().count(b"endfacet")


def _obj_faces(path: Path) -> int:
    n = 0
    with open(path, "rb") as f:
        for line in f:
            if line.startswith(b"f ") or line.startswith(b"f\t"):
                n += max(1, len(line.split()) - 3)      # a polygon of k corners: k - 2
    return n


def _gltf(path: Path) -> TriMesh | None:
    """A micro-mesh glTF's tessellation (its own surface is the reference); any other glTF,
    checked first (``gltf_check``: what would make the importer fail or turn infinite
    positions into zeros), is left to Blender's importer."""
    from .gltf_check import check_gltf
    from .micromesh_import import is_micromesh_file, read_micromesh

    if is_micromesh_file(path):
        return read_micromesh(path).micromesh().tessellate().to_trimesh()
    check_gltf(path)
    return None


def _gltf_triangles(path: Path) -> int:
    from .gltf import Document
    from .micromesh_import import is_micromesh_file, read_micromesh

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


register(InputFormat("ply", (".ply",), _ply, _ply_faces))
register(InputFormat("obj", (".obj",), _obj, _obj_faces))
register(InputFormat("stl", (".stl",), _stl, _stl_facets))
register(InputFormat("gltf", (".glb", ".gltf"), _gltf, _gltf_triangles, importer="gltf"))
register(InputFormat("fbx", (".fbx",), importer="fbx"))
register(InputFormat("usd", (".usd", ".usda", ".usdc", ".usdz"), importer="usd"))
register(InputFormat("blend", (".blend",), importer="blend"))
