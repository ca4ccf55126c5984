"""Per-base-face subdivision criteria: image error summed over the pixels a face covers, the
relative gain of a level, and the two-sided Chamfer distance (the ablation's criterion)."""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree


class LodError(ValueError):
    """Inconsistent input to the level-of-detail algorithms."""


def face_error_sums(pixel_error: np.ndarray, tri_id: np.ndarray, triangle_face: np.ndarray,
                    n_faces: int) -> np.ndarray:
    """Sum of per-pixel errors over the pixels each *base* face covers (all cameras).

    ``tri_id`` is the rasteriser's micro-triangle id per pixel (-1 on background);
    ``triangle_face`` maps micro-triangles to base faces.
    """
    err = np.asarray(pixel_error, dtype=np.float64).reshape(-1)
    tid = np.asarray(tri_id).reshape(-1)
    if err.shape != tid.shape:
        raise LodError("pixel errors and triangle ids must have the same shape")
    hit = tid >= 0
    faces = np.asarray(triangle_face)[tid[hit]]
    return np.bincount(faces, weights=err[hit], minlength=n_faces)[:n_faces]


def relative_gain(err_coarse: np.ndarray, err_fine: np.ndarray, floor: float | None = None) -> np.ndarray:
    """SubdivisionCriterion: relative error improvement (E_coarse - E_fine) / E_coarse per face.

    ``floor`` (default: 1e-3 of the mean non-zero coarse error) keeps faces that are already
    nearly exact, or barely visible, from producing large noisy ratios: they get gain ≈ 0.
    """
    c = np.asarray(err_coarse, dtype=np.float64)
    f = np.asarray(err_fine, dtype=np.float64)
    if floor is None:
        nz = c[c > 0]
        floor = 1e-3 * float(nz.mean()) if nz.size else 1e-12
    return (c - f) / np.maximum(c, floor)


def chamfer_face_errors(micro_vertices: np.ndarray, micro_vertex_face: np.ndarray,
                        reference_points: np.ndarray, n_faces: int,
                        ref_tree: cKDTree | None = None) -> np.ndarray:
    """Per base face, a two-sided Chamfer distance between its patch and the reference.

    Side 1: mean distance of the face's micro-vertices to the nearest reference point.
    Side 2: mean distance of the reference points whose nearest micro-vertex is on the face.
    (Point-to-point against the dense reference vertices: the ablation criterion, Tab. 1a.)
    """
    mv = np.asarray(micro_vertices, dtype=np.float64)
    mf = np.asarray(micro_vertex_face, dtype=np.int64)
    rp = np.asarray(reference_points, dtype=np.float64)
    tree = ref_tree if ref_tree is not None else cKDTree(rp)
    d1, _ = tree.query(mv)
    s1 = np.bincount(mf, weights=d1, minlength=n_faces)[:n_faces]
    c1 = np.bincount(mf, minlength=n_faces)[:n_faces]
    d2, j = cKDTree(mv).query(rp)
    f2 = mf[j]
    s2 = np.bincount(f2, weights=d2, minlength=n_faces)[:n_faces]
    c2 = np.bincount(f2, minlength=n_faces)[:n_faces]
    return s1 / np.maximum(c1, 1) + s2 / np.maximum(c2, 1)
