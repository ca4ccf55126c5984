"""The ``.bary`` container (``docs/micromesh-format.md``): a :class:`BaryFile` to bytes and
back. Only the container: the values stay as stored (packed bytes or typed elements);
``bary_values`` packs and unpacks them, ``micromesh_files`` maps a micro-mesh to and from it.

Everything is little-endian. Property data ranges are 4-byte aligned, ascending and do not
overlap; each property's info struct (if it has one) comes first, then the payload at its
alignment.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass, field

import numpy as np

MAGIC = bytes([0xAB, 0x42, 0x41, 0x52, 0x59, 0x20, 0x30, 0x30, 0x31, 0x30, 0x30, 0xBB,
               0x0D, 0x0A, 0x1A, 0x0A])
HEADER_BYTES, INFO_BYTES = 40, 64

UUIDS = {
    "values": (0xB44DAA04, 0xC9E044D5, 0x9A944DE0, 0xCFD8FE35),
    "groups": (0x39EE40D0, 0x9DC44517, 0x8E5AB15D, 0xB09C74BC),
    "triangles": (0x00458E68, 0xEE59426C, 0xB3BF1B7F, 0x749DEB8E),
    "minmax": (0x23010706, 0x56744EB7, 0x8C0D6CED, 0x5138D2F9),
    "directions": (0xF262D687, 0xB9284AEB, 0xA706803C, 0xCBEDAE52),
    "direction_bounds": (0x25BF3C65, 0x29234AE1, 0x95EFE43C, 0xEB87066C),
    "triangle_flags": (0x90F9EED3, 0x4EC34974, 0x970C755C, 0xAF5B53A3),
}
_NAMES = {v: k for k, v in UUIDS.items()}

# Value and element formats (Vulkan's numbering, as the format uses).
R8_UNORM, R8_UINT, R16_UNORM, R32_SFLOAT = 9, 13, 70, 100
R32G32_SFLOAT, R32G32B32_SFLOAT = 103, 106
R11_UNORM_PACK16, R11_UNORM_PACKED_ALIGN32, DISPC1_COMPRESSED = 1000397001, 1000397002, 1000397000
LAYOUT_UMAJOR, LAYOUT_BIRD = 1, 2
FREQUENCY_PER_VERTEX = 1

# Mesh-property element formats: (format, numpy dtype, components).
_ELEMENTS = {
    "directions": (R32G32B32_SFLOAT, "<f4", 3),
    "direction_bounds": (R32G32_SFLOAT, "<f4", 2),
    "triangle_flags": (R8_UINT, "u1", 1),
}
GROUP = struct.Struct("<6I4f4f")
TRIANGLE = np.dtype([("offset", "<u4"), ("level", "<u2"), ("block", "<u2")])
VALUES_INFO = struct.Struct("<6I")
ELEMENT_INFO = struct.Struct("<4I")


class BaryError(ValueError):
    """A .bary file that does not follow the format, with where and why."""


@dataclass
class Group:
    triangle_first: int
    triangle_count: int
    value_first: int
    value_count: int
    min_level: int
    max_level: int
    bias: tuple = (0.0, 0.0, 0.0, 0.0)
    scale: tuple = (1.0, 1.0, 1.0, 1.0)


@dataclass(eq=False)
class BaryFile:
    """The properties of one file. ``values`` is the raw payload (bytes for packed formats,
    ``count × byte_size`` bytes otherwise); ``triangles`` a structured array (offset, level,
    block); ``minmax`` raw bytes with its element format; mesh properties optional arrays."""

    value_format: int
    layout: int
    value_count: int
    value_byte_size: int
    values: bytes
    groups: list[Group]
    triangles: np.ndarray
    minmax: bytes | None = None
    minmax_format: int = R11_UNORM_PACK16
    directions: np.ndarray | None = None        # (nv, 3) float32
    direction_bounds: np.ndarray | None = None  # (nv, 2) float32: bias, scale
    triangle_flags: np.ndarray | None = None    # (nf,) uint8
    extra: dict = field(default_factory=dict)   # properties kept as bytes (uuid → payload)


def _align(n: int, a: int = 4) -> int:
    return (n + a - 1) // a * a


def _pad(b: bytes, a: int = 4) -> bytes:
    return b + b"\0" * (_align(len(b), a) - len(b))


def encode(bf: BaryFile) -> bytes:
    """The file's bytes."""
    props: list[tuple[str, bytes]] = []
    props.append(("values", _pad(VALUES_INFO.pack(bf.value_format, bf.layout, FREQUENCY_PER_VERTEX,
                                                  bf.value_count, bf.value_byte_size, 4))
                  + bytes(bf.values)))
    props.append(("groups", b"".join(GROUP.pack(g.triangle_first, g.triangle_count, g.value_first,
                                                g.value_count, g.min_level, g.max_level,
                                                *g.bias, *g.scale) for g in bf.groups)))
    props.append(("triangles", np.ascontiguousarray(bf.triangles, TRIANGLE).tobytes()))
    if bf.minmax is not None:
        size = 2 if bf.minmax_format == R11_UNORM_PACK16 else 4
        props.append(("minmax", ELEMENT_INFO.pack(bf.minmax_format, len(bf.minmax) // size, size,
                                                  4) + bytes(bf.minmax)))
    for name, (fmt, dtype, comps) in _ELEMENTS.items():
        arr = getattr(bf, name)
        if arr is None:
            continue
        a = np.ascontiguousarray(arr, dtype=dtype).reshape(-1, comps)
        size = np.dtype(dtype).itemsize * comps
        props.append((name, ELEMENT_INFO.pack(fmt, len(a), size, 4) + a.tobytes()))
    table_end = HEADER_BYTES + INFO_BYTES * len(props)
    infos, blobs, pos = [], [], table_end
    for name, data in props:
        infos.append(struct.pack("<4I2QI4xQ2Q", *UUIDS[name], pos, len(data), 0, 0, 0, 0))
        blobs.append(_pad(data))
        pos += len(blobs[-1])
    header = MAGIC + struct.pack("<3Q", pos, HEADER_BYTES, INFO_BYTES * len(props))
    return header + b"".join(infos) + b"".join(blobs)


def decode(data: bytes, name: str = "the .bary file") -> BaryFile:
    """Parse and check a file; :class:`BaryError` names what is wrong."""
    data = bytes(data)
    if len(data) < HEADER_BYTES or data[:16] != MAGIC:
        raise BaryError(f"{name}: not a .bary file (bad magic or shorter than its header)")
    total, t_off, t_len = struct.unpack_from("<3Q", data, 16)
    if total != len(data):
        raise BaryError(f"{name}: header says {total} bytes, the file has {len(data)}")
    if t_off < HEADER_BYTES or t_len % INFO_BYTES or t_off + t_len > total:
        raise BaryError(f"{name}: property table ({t_off}, {t_len}) outside the file")
    found, last_end = {}, t_off + t_len
    for i in range(t_len // INFO_BYTES):
        u0, u1, u2, u3, off, length, scheme, _, _, _ = struct.unpack_from(
            "<4I2QI4xQ2Q", data, t_off + INFO_BYTES * i)
        if scheme != 0:
            raise BaryError(f"{name}: property {i} is supercompressed (scheme {scheme})")
        if off % 4 or off < last_end or off + length > total:
            raise BaryError(f"{name}: property {i} range ({off}, {length}) is misaligned, "
                            "overlaps another or lies outside the file")
        last_end = off + length
        found[(u0, u1, u2, u3)] = data[off:off + length]
    for req in ("values", "groups", "triangles"):
        if UUIDS[req] not in found:
            raise BaryError(f"{name}: the mandatory {req} property is missing")
    return _from_props(found, name)


def _element(blob: bytes, what: str, name: str) -> tuple[int, int, int, bytes]:
    if len(blob) < ELEMENT_INFO.size:
        raise BaryError(f"{name}: the {what} property is shorter than its info")
    fmt, count, size, align = ELEMENT_INFO.unpack_from(blob)
    start = _align(ELEMENT_INFO.size, max(int(align), 1))
    if start + count * size > len(blob):
        raise BaryError(f"{name}: the {what} property holds fewer bytes than count × size")
    return fmt, count, size, blob[start:start + count * size]


def _from_props(found: dict, name: str) -> BaryFile:
    vblob = found[UUIDS["values"]]
    if len(vblob) < VALUES_INFO.size:
        raise BaryError(f"{name}: the values property is shorter than its info")
    fmt, layout, freq, count, size, align = VALUES_INFO.unpack_from(vblob)
    if fmt == DISPC1_COMPRESSED:
        raise BaryError(f"{name}: compressed values (eDispC1) are not supported")
    if layout not in (LAYOUT_UMAJOR, LAYOUT_BIRD) or freq != FREQUENCY_PER_VERTEX:
        raise BaryError(f"{name}: layout {layout} / frequency {freq} not supported "
                        "(u-major or bird curve, per vertex)")
    start = _align(VALUES_INFO.size, max(int(align), 1))
    if start + count * size > len(vblob):
        raise BaryError(f"{name}: the values property holds fewer bytes than count × size")
    values = vblob[start:start + count * size]
    gblob = found[UUIDS["groups"]]
    if len(gblob) % GROUP.size:
        raise BaryError(f"{name}: the groups property is not a whole number of groups")
    groups = [Group(*g[:6], tuple(g[6:10]), tuple(g[10:14]))
              for g in GROUP.iter_unpack(gblob)]
    tblob = found[UUIDS["triangles"]]
    if len(tblob) % TRIANGLE.itemsize:
        raise BaryError(f"{name}: the triangles property is not a whole number of triangles")
    bf = BaryFile(fmt, layout, count, size, values, groups,
                  np.frombuffer(tblob, TRIANGLE).copy())
    if UUIDS["minmax"] in found:
        bf.minmax_format, _, _, bf.minmax = _element(found[UUIDS["minmax"]], "min/max", name)
    for prop, (efmt, dtype, comps) in _ELEMENTS.items():
        if UUIDS[prop] in found:
            f, n, sz, blob = _element(found[UUIDS[prop]], prop, name)
            if f != efmt or sz != np.dtype(dtype).itemsize * comps:
                raise BaryError(f"{name}: {prop} in format {f} ({sz} bytes) is not supported")
            arr = np.frombuffer(blob, dtype)
            setattr(bf, prop, arr.reshape(n, comps) if comps > 1 else arr.reshape(n))
    bf.extra = {u: b for u, b in found.items() if u not in _NAMES}
    return bf
