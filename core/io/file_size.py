"""The bytes a micro-mesh's files take on disk (the ``.bin`` and the ``.bary``; the ``.gltf``
JSON apart), from its levels and its base's vertex count alone: what the construction's budget
counts.

:func:`micromesh_file_bytes` is what ``micromesh_export`` writes, to the byte (its tests write
the files and compare): the ``.bin`` holds the base's indices (u16 below 65,536 vertices, else
u32), float32 positions, normals and directions (bounds folded in) and a u8 of edge flags per
face; the ``.bary`` its header, a property table of four, the values (info + payload), one
group, a triangle record per face and per-face min/max. Each buffer view and property starts
on a 4-byte boundary.

:func:`mmt_file_bytes` is what NVlabs/micromesh-tools' ``meshreduce`` writes at exit (checked
on its outputs of the shared meshes): u32 indices, positions, normals, directions, a u8 level
view no accessor reads and the u8 flags, unpadded; the same ``.bary`` properties as ours.
"""
from __future__ import annotations

import numpy as np

from ..micro.metrics import packed11_block_bytes, values_per_triangle

U16_MAX_VERTICES = 65535       # u16 indices hold 0..65534 (glTF reserves 65535, a restart)
_BARY_HEADER, _PROPERTY_INFO = 40, 64
_VALUES_INFO, _GROUP, _TRIANGLE, _ELEMENT_INFO = 24, 56, 8, 16


def _align4(n) -> int:
    return int(n + 3) // 4 * 4


def index_bytes(n_base_vertices: int) -> int:
    """Bytes of one index in our ``.bin``: 2 where u16 holds every vertex, else 4."""
    return 2 if n_base_vertices <= U16_MAX_VERTICES else 4


def value_bytes(levels: np.ndarray, value_format: str = "r11") -> int:
    """The values' payload: 11-bit packed blocks (``r11``) or float32 (``float``)."""
    lv = np.asarray(levels, dtype=np.int64)
    if value_format == "r11":
        return int(packed11_block_bytes(lv).sum())
    if value_format == "float":
        return int(4 * values_per_triangle(lv).sum())
    raise ValueError(f"value format {value_format!r}: r11 or float")


def bary_bytes(levels: np.ndarray, value_format: str = "r11") -> int:
    """The ``.bary``: header, four property infos, values, one group, triangles, min/max (u16
    pairs for 11-bit values, float32 pairs for float)."""
    m = len(np.asarray(levels))
    minmax = (2 if value_format == "r11" else 4) * 2 * m
    props = [_VALUES_INFO + value_bytes(levels, value_format), _GROUP, _TRIANGLE * m,
             _ELEMENT_INFO + minmax]
    return _BARY_HEADER + _PROPERTY_INFO * len(props) + sum(_align4(p) for p in props)


def micromesh_file_bytes(levels: np.ndarray, n_base_vertices: int,
                         value_format: str = "r11") -> dict[str, int]:
    """{"bin", "bary", "values", "total"}: our files' bytes on disk (total = bin + bary)."""
    m, nv = len(np.asarray(levels)), int(n_base_vertices)
    binary = _align4(3 * m * index_bytes(nv)) + 3 * 12 * nv + _align4(m)
    bary = bary_bytes(levels, value_format)
    return {"bin": binary, "bary": bary, "values": value_bytes(levels, value_format),
            "total": binary + bary}


def mmt_file_bytes(levels: np.ndarray, n_base_vertices: int) -> int:
    """micromesh-tools' ``.bin`` + ``.bary`` for these levels on a base of
    ``n_base_vertices`` vertices: its formula (``metrics.mmt_formula_bytes``) plus the normals,
    the level view, the triangle records, min/max and the ``.bary``'s headers."""
    m, nv = len(np.asarray(levels)), int(n_base_vertices)
    binary = 12 * m + 3 * 12 * nv + 2 * m           # its u8 views are not padded
    return binary + bary_bytes(levels)
