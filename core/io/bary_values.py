"""Per-triangle displacement values to a ``.bary`` values payload and back.

Values are given per base triangle as CSR (``ptr`` (nf+1,), ``values``) in the file's layout
order (u-major or bird curve). Formats: ``eR11_unorm_packed_align32`` (value i of a triangle at
bit 11·i, LSB first, each triangle's block on a 4-byte boundary), ``eR11_unorm_pack16``,
``eR8_unorm``, ``eR16_unorm`` (unorm values in [0, 1]) and ``eR32_sfloat``.
"""
from __future__ import annotations

import numpy as np

from ..micro.metrics import packed11_block_bytes, values_per_triangle
from .bary import (R8_UNORM, R11_UNORM_PACK16, R11_UNORM_PACKED_ALIGN32, R16_UNORM, R32_SFLOAT,
                   BaryError, BaryFile)

MAX_FILE_LEVEL = 15  # what the format's u16 level can say; more is refused as malformed
_UNORM = {R8_UNORM: ("u1", 255), R16_UNORM: ("<u2", 65535), R11_UNORM_PACK16: ("<u2", 2047)}
FORMAT_NAMES = {"r11": R11_UNORM_PACKED_ALIGN32, "float": R32_SFLOAT}


def quantize11(t: np.ndarray) -> np.ndarray:
    """Unorm values in [0, 1] to 11-bit integers (round to nearest)."""
    return np.rint(np.clip(t, 0.0, 1.0) * 2047.0).astype(np.uint32)


def encode_values(fmt: int, levels: np.ndarray, ptr: np.ndarray, values: np.ndarray
                  ) -> tuple[bytes, np.ndarray, int, int]:
    """Payload, per-triangle offsets (bytes for the packed format, elements otherwise), value
    count and byte size for ``BaryFile``. Unorm formats expect values in [0, 1]."""
    lv = np.asarray(levels, np.int64)
    counts = values_per_triangle(lv)
    if not np.array_equal(np.diff(ptr), counts):
        raise ValueError("each triangle needs (2^l + 1)(2^l + 2)/2 values")
    if fmt == R32_SFLOAT:
        return np.asarray(values, "<f4").tobytes(), ptr[:-1].astype(np.uint32), len(values), 4
    if fmt != R11_UNORM_PACKED_ALIGN32:
        raise ValueError(f"writing value format {fmt} is not supported (r11 packed or float)")
    q = quantize11(values)
    block = packed11_block_bytes(lv)
    offsets = np.zeros(len(lv) + 1, np.int64)
    np.cumsum(block, out=offsets[1:])
    local = np.arange(len(q)) - np.repeat(ptr[:-1], counts)   # index within its triangle
    bit = np.repeat(offsets[:-1] * 8, counts) + 11 * local
    words = np.zeros(offsets[-1] // 4 + 1, np.uint64)
    shift = (bit & 31).astype(np.uint64)
    wide = q.astype(np.uint64) << shift                        # < 2^43: fits two words
    np.add.at(words, bit >> 5, wide & 0xFFFFFFFF)            # bits never overlap: add == or
    np.add.at(words, (bit >> 5) + 1, wide >> np.uint64(32))
    payload = words[:-1].astype("<u4").tobytes()
    return payload, offsets[:-1].astype(np.uint32), int(offsets[-1]), 1


def decode_values(bf: BaryFile, name: str = "the .bary file"
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(levels (nf,), ptr (nf+1,), values) of every triangle in group order, with each
    group's bias and scale applied. Refuses offsets, levels and counts that do not fit."""
    tri = bf.triangles
    lv = tri["level"].astype(np.int64)
    if len(lv) and lv.max() > MAX_FILE_LEVEL:
        raise BaryError(f"{name}: triangle level {int(lv.max())} is over {MAX_FILE_LEVEL}")
    if (tri["block"] != 0).any():
        raise BaryError(f"{name}: compressed triangle blocks are not supported")
    counts = values_per_triangle(lv)
    base = np.zeros(len(lv), np.int64)
    bias, scale = np.zeros(len(lv)), np.ones(len(lv))
    covered = np.zeros(len(lv), bool)
    for i, g in enumerate(bf.groups):
        lo, hi = g.triangle_first, g.triangle_first + g.triangle_count
        if hi > len(lv):
            raise BaryError(f"{name}: group {i} holds triangles {lo}..{hi - 1}, the file {len(lv)}")
        base[lo:hi], bias[lo:hi], scale[lo:hi] = g.value_first, g.bias[0], g.scale[0]
        covered[lo:hi] = True
    if not covered.all():
        raise BaryError(f"{name}: {int((~covered).sum())} triangles belong to no group")
    start = base + tri["offset"].astype(np.int64)
    ptr = np.zeros(len(lv) + 1, np.int64)
    np.cumsum(counts, out=ptr[1:])
    if bf.value_format == R11_UNORM_PACKED_ALIGN32:
        ends = start + packed11_block_bytes(lv)
        raw = _unpack11(bf.values, start, counts, ptr, ends, name) / 2047.0
    elif bf.value_format == R32_SFLOAT or bf.value_format in _UNORM:
        dtype, peak = _UNORM.get(bf.value_format, ("<f4", 1))
        if bf.value_byte_size != np.dtype(dtype).itemsize:
            raise BaryError(f"{name}: value byte size {bf.value_byte_size} does not fit format "
                            f"{bf.value_format}")
        elems = np.frombuffer(bf.values, dtype)
        if len(lv) and (start + counts).max() > len(elems):
            raise BaryError(f"{name}: a triangle's values run past the end of the values")
        idx = np.repeat(start, counts) + np.arange(ptr[-1]) - np.repeat(ptr[:-1], counts)
        raw = elems[idx] & 0x7FF if bf.value_format == R11_UNORM_PACK16 else elems[idx]
        raw = raw.astype(np.float64) / peak
    else:
        raise BaryError(f"{name}: unknown value format {bf.value_format}")
    values = raw * np.repeat(scale, counts) + np.repeat(bias, counts)
    if not np.isfinite(values).all():
        raise BaryError(f"{name}: values or group bias/scale are NaN or infinite")
    return lv, ptr, values


def _unpack11(payload: bytes, start, counts, ptr, ends, name) -> np.ndarray:
    if len(start) and ends.max() > len(payload):
        raise BaryError(f"{name}: a triangle's packed values run past the end of the values")
    buf = np.frombuffer(bytes(payload) + b"\0\0\0", np.uint8).astype(np.uint32)
    local = np.arange(ptr[-1]) - np.repeat(ptr[:-1], counts)
    bit = np.repeat(start * 8, counts) + 11 * local
    byte, sh = bit >> 3, (bit & 7).astype(np.uint32)
    word = buf[byte] | (buf[byte + 1] << 8) | (buf[byte + 2] << 16)
    return ((word >> sh) & 0x7FF).astype(np.float64)
