"""How constructions are measured (method §7): PSNR, shell volume, geometric error, isotropy,
storage of the 11-bit packed encoding (micromesh-tools' formula; the files' bytes on disk are
``core.io.file_size``'s), cracks, and a per-phase wall-clock timer.
"""
from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np


# ---------------------------------------------------------------------------- images
def psnr(image: np.ndarray, reference: np.ndarray, peak: float = 1.0) -> float:
    """PSNR in dB of ``image`` against ``reference`` over all pixels (values in [0, peak])."""
    a = np.asarray(image, dtype=np.float64)
    b = np.asarray(reference, dtype=np.float64)
    if a.shape != b.shape:
        raise ValueError(f"image shapes differ: {a.shape} vs {b.shape}")
    mse = float(np.mean((a - b) ** 2))
    if mse <= 0:
        return float("inf")
    return 10.0 * np.log10(peak * peak / mse)


# -------------------------------------------------------------------------- isotropy
def triangle_isotropy(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per triangle 2r/R = 16 A² / ((l0 + l1 + l2) l0 l1 l2) (1 for equilateral) and the area."""
    v = np.asarray(vertices, dtype=np.float64)[np.asarray(faces)]
    l0 = np.linalg.norm(v[:, 1] - v[:, 0], axis=1)
    l1 = np.linalg.norm(v[:, 2] - v[:, 1], axis=1)
    l2 = np.linalg.norm(v[:, 0] - v[:, 2], axis=1)
    area = 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1)
    den = (l0 + l1 + l2) * l0 * l1 * l2
    q = np.where(den > 0, 16.0 * area ** 2 / np.maximum(den, 1e-300), 0.0)
    return np.clip(q, 0.0, 1.0), area


def isotropy(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Area-weighted mean of 2r/R over the triangles."""
    q, a = triangle_isotropy(vertices, faces)
    return float((q * a).sum() / max(a.sum(), 1e-300))


# ----------------------------------------------------------------- geometric error
def distance_to_mesh(points: np.ndarray, vertices: np.ndarray, triangles: np.ndarray
                     ) -> np.ndarray:
    """Exact distance from each point to the triangle mesh (``core.spatial.closest``'s BVH)."""
    from ..spatial.closest import ClosestPointIndex

    t = np.asarray(triangles, dtype=np.int64)
    t = t[(t[:, 0] != t[:, 1]) & (t[:, 1] != t[:, 2]) & (t[:, 0] != t[:, 2])]
    return ClosestPointIndex(vertices, t).query(points)[2]


def geometric_error(ref_vertices: np.ndarray, ref_vertex_areas: np.ndarray, vertices: np.ndarray,
                    triangles: np.ndarray, diagonal: float, percentile: float = 99.0) -> float:
    """Per reference vertex, the distance to the displaced micro-mesh over the reference
    bounding-box diagonal; vertex-area-weighted mean without the samples above the
    ``percentile`` (the micromesh-tools convention)."""
    d = distance_to_mesh(ref_vertices, vertices, triangles) / diagonal
    w = np.asarray(ref_vertex_areas, dtype=np.float64)
    keep = d <= np.percentile(d, percentile)
    return float((d[keep] * w[keep]).sum() / max(w[keep].sum(), 1e-300))


# --------------------------------------------------------------------------- storage
def values_per_triangle(level: np.ndarray | int) -> np.ndarray:
    n = 2 ** np.asarray(level, dtype=np.int64)
    return (n + 1) * (n + 2) // 2


def packed11_block_bytes(level: np.ndarray | int) -> np.ndarray:
    """Bytes of one triangle's 11-bit packed values (eR11_unorm_packed_align32)."""
    return (11 * values_per_triangle(level) + 31) // 32 * 4


def mmt_formula_bytes(levels: np.ndarray, n_base_vertices: int) -> int:
    """micromesh-tools' storage estimate (its ``out_size``): 24 B per base vertex, 13 B per
    base face, and the 11-bit packed values; the figure its statistics and the judge report."""
    lv = np.asarray(levels, dtype=np.int64)
    return int(24 * n_base_vertices + 13 * len(lv) + packed11_block_bytes(lv).sum())


# ----------------------------------------------------------------------------- cracks
def crack_edges(triangles: np.ndarray, positions: np.ndarray, base_boundary_micro_edges: int,
                tol: float = 0.0) -> int:
    """Open micro-edges beyond those expected on the base mesh's own boundary.

    Degenerate micro-triangles (edge decimation) are dropped; vertices at identical positions
    (within ``tol``) are merged first, so a split vertex does not hide a gap and a snapped one
    does not create one.
    """
    t = np.asarray(triangles, dtype=np.int64)
    p = np.asarray(positions, dtype=np.float64)
    if tol > 0:
        key = np.round(p / tol).astype(np.int64)
    else:
        key = p
    _, canon = np.unique(key, axis=0, return_inverse=True)
    t = canon.reshape(-1)[t]
    t = t[(t[:, 0] != t[:, 1]) & (t[:, 1] != t[:, 2]) & (t[:, 0] != t[:, 2])]
    e = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    return int(max(0, int((counts == 1).sum()) - base_boundary_micro_edges))


# ------------------------------------------------------------------------------ timing
@dataclass
class PhaseTimer:
    """Wall time per named phase (seconds, accumulated)."""

    times: dict[str, float] = field(default_factory=dict)

    @contextmanager
    def phase(self, name: str):
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.times[name] = self.times.get(name, 0.0) + time.perf_counter() - t0

    @property
    def total(self) -> float:
        return float(sum(self.times.values()))
