"""Image files of the maps, without Blender: PNG (8 or 16 bits, grey, RGB or RGBA) and
OpenEXR (half float, one channel, ZIP), and a height map's 16-bit code.

Our arrays keep row 0 at v = 0, the image's bottom (Blender's and OpenGL's order); PNG and
EXR store the top row first, so both writers flip the rows.
"""
from __future__ import annotations

import os
import struct
import tempfile
import zlib
from dataclasses import dataclass

import numpy as np

_PNG_COLOUR = {1: 0, 3: 2, 4: 6}    # grey, RGB, RGBA


def png(pixels: np.ndarray, bits: int = 16) -> bytes:
    """A PNG of ``pixels`` in [0, 1]: (H, W) grey or (H, W, 1 | 3 | 4), row 0 at the bottom,
    8 or 16 bits per channel."""
    px = np.asarray(pixels)
    if px.ndim == 2:
        px = px[..., None]
    if px.ndim != 3 or px.shape[2] not in _PNG_COLOUR or bits not in (8, 16):
        raise ValueError(f"png: (H, W[, 1|3|4]) pixels and 8 or 16 bits, got "
                         f"{np.shape(pixels)}, {bits}")
    h, w, c = px.shape
    top = (1 << bits) - 1
    q = np.rint(np.clip(px[::-1], 0.0, 1.0) * top).astype(">u2" if bits == 16 else np.uint8)
    raw = np.concatenate([np.zeros((h, 1), np.uint8), q.reshape(h, -1).view(np.uint8)], 1)

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + \
            struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    header = struct.pack(">2I5B", w, h, bits, _PNG_COLOUR[c], 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header)
            + chunk(b"IDAT", zlib.compress(raw.tobytes(), 6)) + chunk(b"IEND", b""))


def exr_half(values: np.ndarray, channel: str = "Y") -> bytes:
    """An OpenEXR file of ``values`` (H, W), row 0 at the bottom: one half-float channel
    (``channel``; "Y" is what readers take for a grey image), ZIP-compressed scanlines."""
    import OpenEXR

    v = np.asarray(values)
    if v.ndim != 2:
        raise ValueError(f"exr_half: (H, W) values, got {v.shape}")
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    data = np.ascontiguousarray(v[::-1].astype(np.float16))
    fd, path = tempfile.mkstemp(suffix=".exr")      # the binding writes files, not bytes
    os.close(fd)
    try:
        with OpenEXR.File(header, {channel: data}) as f:
            f.write(path)
        with open(path, "rb") as fh:
            return fh.read()
    finally:
        os.unlink(path)


@dataclass(frozen=True)
class HeightCode:
    """How a 16-bit texture holds heights: h = offset + factor · value, value in [0, 1] (glTF's
    ``KHR_materials_displacement`` factor and offset, USD's ``UsdUVTexture`` scale and
    bias)."""

    offset: float
    factor: float

    @classmethod
    def spanning(cls, height: np.ndarray) -> "HeightCode":
        """The code whose 65,536 steps span ``height``'s range (one step where it is flat)."""
        lo, hi = float(np.min(height)), float(np.max(height))
        return cls(lo, hi - lo if hi > lo else 1.0)

    def values(self, height: np.ndarray) -> np.ndarray:
        """``height`` as values in [0, 1] (what :func:`png` quantises)."""
        return (np.asarray(height, dtype=np.float64) - self.offset) / self.factor

    def heights(self, values: np.ndarray) -> np.ndarray:
        return self.offset + self.factor * np.asarray(values, dtype=np.float64)
