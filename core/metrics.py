"""How constructions are measured (method §7): PSNR, shell volume, geometric error, isotropy,
storage of the 11-bit packed encoding, cracks, and a per-phase wall-clock timer.
"""
from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree


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
def point_triangle_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Euclidean distance from points ``p`` (n,3) to triangles (a, b, c) (n,3 each), row-wise
    (Ericson's closest-point regions, vectorised)."""
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = (ab * ap).sum(1), (ac * ap).sum(1)
    bp = p - b
    d3, d4 = (ab * bp).sum(1), (ac * bp).sum(1)
    cp = p - c
    d5, d6 = (ab * cp).sum(1), (ac * cp).sum(1)
    vc = d1 * d4 - d3 * d2
    vb = d5 * d2 - d1 * d6
    va = d3 * d6 - d5 * d4
    den = va + vb + vc
    safe = np.where(np.abs(den) > 1e-300, den, 1.0)
    v = vb / safe
    w = vc / safe
    q = a + ab * v[:, None] + ac * w[:, None]                       # interior
    # edges
    t_ab = np.where(d1 - d3 != 0, d1 / np.where(d1 - d3 != 0, d1 - d3, 1), 0)
    t_ac = np.where(d2 - d6 != 0, d2 / np.where(d2 - d6 != 0, d2 - d6, 1), 0)
    e = (d4 - d3) + (d5 - d6)
    t_bc = np.where(e != 0, (d4 - d3) / np.where(e != 0, e, 1), 0)
    m_ab = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
    m_ac = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
    m_bc = (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0)
    q = np.where(m_bc[:, None], b + (c - b) * t_bc[:, None], q)
    q = np.where(m_ac[:, None], a + ac * t_ac[:, None], q)
    q = np.where(m_ab[:, None], a + ab * t_ab[:, None], q)
    # vertices
    q = np.where(((d6 >= 0) & (d5 <= d6))[:, None], c, q)
    q = np.where(((d3 >= 0) & (d4 <= d3))[:, None], b, q)
    q = np.where(((d1 <= 0) & (d2 <= 0))[:, None], a, q)
    return np.linalg.norm(p - q, axis=1)


def distance_to_mesh(points: np.ndarray, vertices: np.ndarray, triangles: np.ndarray,
                     candidates: int = 16, chunk: int = 200_000) -> np.ndarray:
    """Distance from each point to the triangle mesh, exact over the ``candidates`` triangles
    whose centroids are nearest (a KD-tree; exact for dense meshes of even triangles)."""
    v = np.asarray(vertices, dtype=np.float64)
    t = np.asarray(triangles, dtype=np.int64)
    t = t[(t[:, 0] != t[:, 1]) & (t[:, 1] != t[:, 2]) & (t[:, 0] != t[:, 2])]
    cen = v[t].mean(axis=1)
    tree = cKDTree(cen)
    k = min(candidates, len(t))
    pts = np.asarray(points, dtype=np.float64)
    out = np.empty(len(pts))
    for s in range(0, len(pts), chunk):
        p = pts[s:s + chunk]
        _, idx = tree.query(p, k=k)
        idx = idx.reshape(len(p), k)
        tri = t[idx.reshape(-1)]
        pr = np.repeat(p, k, axis=0)
        d = point_triangle_distance(pr, v[tri[:, 0]], v[tri[:, 1]], v[tri[:, 2]])
        out[s:s + chunk] = d.reshape(len(p), k).min(axis=1)
    return out


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


def _align4(n: int) -> int:
    return (n + 3) // 4 * 4


def storage_bytes(levels: np.ndarray, n_base_vertices: int) -> dict[str, int]:
    """Bytes of a micro-mesh as .bary (11-bit packed values, triangles, min/max, mesh
    directions, direction bounds, triangle flags) plus the glTF buffers (float32 positions,
    u32 indices, u8 subdivision levels). Headers and property infos included."""
    lv = np.asarray(levels, dtype=np.int64)
    m = len(lv)
    values = int(packed11_block_bytes(lv).sum())
    parts = {
        "values": 24 + values,                       # values info + payload
        "groups": 56,
        "triangles": 8 * m,
        "minmax": 16 + _align4(2 * 2 * m),           # element info + u16 min/max per triangle
        "directions": 16 + 12 * n_base_vertices,
        "direction_bounds": 16 + 8 * n_base_vertices,
        "triangle_flags": 16 + _align4(m),
    }
    bary = 40 + 64 * len(parts) + sum(_align4(v) for v in parts.values())
    gltf = 12 * n_base_vertices + 12 * m + _align4(m)
    return {"bary": int(bary), "gltf_buffers": int(gltf), "values": values,
            "total": int(bary + gltf)}


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
