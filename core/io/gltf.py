"""A minimal glTF 2.0 container: build a document with one binary buffer, read accessors back,
pack and unpack ``.glb``. Only what micro-mesh files need (no images, no animation)."""
from __future__ import annotations

import base64
import binascii
import json
import struct
from pathlib import Path
from urllib.parse import unquote

import numpy as np

COMPONENTS = {5120: "i1", 5121: "u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4",
              5131: "<f2"}
_TYPES = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}
_CODE = {np.dtype("u1"): 5121, np.dtype("<u2"): 5123, np.dtype("<u4"): 5125,
         np.dtype("<f4"): 5126}
GLB_MAGIC, JSON_CHUNK, BIN_CHUNK = 0x46546C67, 0x4E4F534A, 0x004E4942


class GltfError(ValueError):
    """A glTF file that cannot be read, with where and why."""


class Builder:
    """Collects buffer views and accessors into one binary buffer."""

    def __init__(self) -> None:
        self.doc: dict = {"asset": {"version": "2.0", "generator": "Micro-Mesh Builder"},
                          "accessors": [], "bufferViews": [], "buffers": []}
        self.blob = bytearray()

    def view(self, data: bytes, name: str | None = None, target: int | None = None) -> int:
        self.blob += b"\0" * (-len(self.blob) % 4)
        v = {"buffer": 0, "byteOffset": len(self.blob), "byteLength": len(data)}
        if name:
            v["name"] = name
        if target:
            v["target"] = target
        self.blob += data
        self.doc["bufferViews"].append(v)
        return len(self.doc["bufferViews"]) - 1

    def accessor(self, array: np.ndarray, dtype: str, name: str, target: int | None = None,
                 bounds: bool = False) -> int:
        a = np.ascontiguousarray(array, dtype=dtype)
        comps = 1 if a.ndim == 1 else a.shape[1]
        acc = {"bufferView": self.view(a.tobytes(), name, target),
               "componentType": _CODE[a.dtype], "count": int(len(a)),
               "type": {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4"}[comps], "name": name}
        if bounds and len(a):
            acc["min"] = [float(x) for x in np.atleast_1d(a.min(0))]
            acc["max"] = [float(x) for x in np.atleast_1d(a.max(0))]
        self.doc["accessors"].append(acc)
        return len(self.doc["accessors"]) - 1

    def finish(self, bin_uri: str | None) -> tuple[dict, bytes]:
        """The document and its buffer (``bin_uri`` None: the GLB's own chunk)."""
        self.blob += b"\0" * (-len(self.blob) % 4)
        buf = {"byteLength": len(self.blob)}
        if bin_uri is not None:
            buf["uri"] = bin_uri
        self.doc["buffers"] = [buf]
        return self.doc, bytes(self.blob)


def pack_glb(doc: dict, blob: bytes) -> bytes:
    js = json.dumps(doc, separators=(",", ":")).encode()
    js += b" " * (-len(js) % 4)
    blob = blob + b"\0" * (-len(blob) % 4)
    total = 12 + 8 + len(js) + 8 + len(blob)
    return (struct.pack("<3I", GLB_MAGIC, 2, total) + struct.pack("<2I", len(js), JSON_CHUNK) + js
            + struct.pack("<2I", len(blob), BIN_CHUNK) + blob)


class Document:
    """A glTF document read from ``.gltf`` (external or data-less buffers) or ``.glb``."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        data = self.path.read_bytes()
        self.glb_bin: bytes | None = None
        if data[:4] == struct.pack("<I", GLB_MAGIC):
            data = self._unpack_glb(data)
        try:
            self.doc = json.loads(data.decode("utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError) as e:
            raise GltfError(f"{self.path.name}: not valid glTF JSON ({e})") from None
        if not isinstance(self.doc, dict) or str(self.doc.get("asset", {}).get("version", "")) \
                [:1] != "2":
            raise GltfError(f"{self.path.name}: not a glTF 2.0 document")
        self._buffers: dict[int, bytes] = {}

    def _unpack_glb(self, data: bytes) -> bytes:
        if len(data) < 20:
            raise GltfError(f"{self.path.name}: GLB shorter than its header")
        _, version, total = struct.unpack_from("<3I", data)
        if version != 2 or total > len(data):
            raise GltfError(f"{self.path.name}: GLB version {version} or length {total} is wrong")
        pos, js = 12, None
        while pos + 8 <= total:
            n, kind = struct.unpack_from("<2I", data, pos)
            if pos + 8 + n > total:
                raise GltfError(f"{self.path.name}: GLB chunk runs past the end of the file")
            chunk = data[pos + 8:pos + 8 + n]
            if kind == JSON_CHUNK and js is None:
                js = chunk
            elif kind == BIN_CHUNK and self.glb_bin is None:
                self.glb_bin = chunk
            pos += 8 + _align4(n)
        if js is None:
            raise GltfError(f"{self.path.name}: GLB without a JSON chunk")
        return js

    def item(self, kind: str, i) -> dict:
        """``doc[kind][i]``, refused with the reason when it does not exist."""
        items = self.doc.get(kind, [])
        if not isinstance(i, int) or not 0 <= i < len(items):
            raise GltfError(f"{self.path.name}: {kind}[{i}] does not exist")
        return items[i]

    def buffer(self, i: int) -> bytes:
        if i not in self._buffers:
            b = self.item("buffers", i)
            if "uri" not in b:
                if self.glb_bin is None:
                    raise GltfError(f"{self.path.name}: buffer {i} has no uri and no GLB chunk")
                data = self.glb_bin
            else:
                data = self.external(b["uri"])
            if len(data) < b.get("byteLength", 0):
                raise GltfError(f"{self.path.name}: buffer {i} is shorter than its byteLength")
            self._buffers[i] = data
        return self._buffers[i]

    def external(self, uri: str) -> bytes:
        """A file the document names (relative to it), or a base64 data URI's bytes."""
        if uri.startswith("data:"):
            head, _, payload = uri.partition(",")
            if not head.endswith(";base64"):
                raise GltfError(f"{self.path.name}: a data URI that is not base64")
            try:
                return base64.b64decode(payload, validate=True)
            except binascii.Error:
                raise GltfError(f"{self.path.name}: a data URI whose base64 is damaged") from None
        p = self.path.parent / unquote(uri)
        if not p.is_file():
            raise GltfError(f"{self.path.name}: the file it names, {uri}, is missing")
        return p.read_bytes()

    def view(self, i: int) -> bytes:
        v = self.item("bufferViews", i)
        buf = self.buffer(v.get("buffer", 0))
        off, n = v.get("byteOffset", 0), v.get("byteLength", 0)
        if off + n > len(buf):
            raise GltfError(f"{self.path.name}: bufferView {i} lies outside its buffer")
        return buf[off:off + n]

    def accessor(self, i: int) -> np.ndarray:
        """(count,) or (count, k) float64/int64 array, normalized integers scaled to [0, 1]."""
        a = self.item("accessors", i)
        if "sparse" in a or "bufferView" not in a:
            raise GltfError(f"{self.path.name}: accessor {i} is sparse or has no bufferView")
        dtype = np.dtype(COMPONENTS.get(a.get("componentType"), "V0"))
        comps = _TYPES.get(a.get("type"))
        if dtype.itemsize == 0 or comps is None:
            raise GltfError(f"{self.path.name}: accessor {i} has an unknown type")
        view, count = self.view(a["bufferView"]), int(a.get("count", 0))
        stride = self.item("bufferViews", a["bufferView"]).get("byteStride") or \
            dtype.itemsize * comps
        off = a.get("byteOffset", 0)
        if count and off + stride * (count - 1) + dtype.itemsize * comps > len(view):
            raise GltfError(f"{self.path.name}: accessor {i} reads past its bufferView")
        raw = np.frombuffer(view, np.uint8, count * stride, off) if count else np.zeros(0, np.uint8)
        rows = raw.reshape(count, stride)[:, :dtype.itemsize * comps].copy()
        arr = rows.view(dtype).reshape(count, comps)
        if a.get("normalized") and dtype.kind in "iu":
            arr = np.maximum(arr / float(np.iinfo(dtype).max), -1.0)
        arr = arr.astype(np.float64 if arr.dtype.kind == "f" else np.int64)
        return arr[:, 0] if comps == 1 else arr


def _align4(n: int) -> int:
    return (n + 3) // 4 * 4
