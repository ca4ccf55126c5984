"""A height map fitted to the source: its texels are the unknowns of the micro-mesh fit.

A renderer draws a base with a height map by cutting each base triangle into the lattice of
some level L and moving every lattice point by the bilinearly sampled height along the
normalised interpolated normal. That is a micro-mesh of uniform level L with the unit vertex
normals as directions, whose displacement at micro-vertex k is d_k = h_k / |lerp(N)_k|; and
h = B x, B the bilinear lookups of the texels x at the lattice points' UVs. So the fit's
normal equations over d (``core.fit.system``: the reference's samples matched to the
micro-surface, point-to-plane and slope rows, smoothness) become, with d = S B x and
S = diag(1 / |lerp(N)|), a system over the texels:

    (Bᵀ S M S B + λ GᵀG + μ CᵀC) x = Bᵀ S b

GᵀG gives the texels no lattice point reads a value between their neighbours' (``texels``),
CᵀC ties the two sides of every UV seam at the lattice points of ``seam_level`` and every
coarser level (``seams``). It is solved by conjugate gradients from the conventional bake
(rays both ways along the interpolated normal from each texel), round after round as the fit
re-matches its samples; then x is projected onto C x = 0, so both sides of every seam give
the same height at those points, to rounding.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy import ndimage

from ..bake import bake_displacements
from ..fit.samples import fit_samples
from ..fit.system import normal_equations
from ..mesh import TriMesh
from ..micromesh import MicroMesh
from ..normalization import unit_sphere_normalization
from .atlas import Atlas, check_room, checked_resolution, texel_faces
from .bake import MapsCancelled, base_point, unit_directions
from .seams import seam_gap_max, seam_points
from .texels import TexelGrid, bilinear_taps

# The membrane's and the seams' weights, as fractions of the median micro-vertex's hold by
# its samples (the diagonal of the fit's system).
MEMBRANE = 1e-3
SEAM = 1.0
# Conjugate gradients stop at this residual, relative to the right-hand side's (bunny_69k at
# 2048²: 1e-4 and 1e-6 gave the same image, 41.90 dB, in a fifth of the iterations).
RTOL = 1e-4
MAX_CG = 400


@dataclass(eq=False)
class HeightMap:
    """A fitted height map and what it stands on.

    ``height`` (H, W) float32: world units along the normalised interpolated vertex normal,
    row 0 at v = 0; ``filled`` (H, W) bool: texels inside a chart; ``level``: the
    tessellation it was fitted for; ``surface``: that tessellation as a micro-mesh (uniform
    ``level``, the unit normals as directions, world space): what a renderer draws.
    """

    atlas: Atlas
    height: np.ndarray
    filled: np.ndarray
    level: int
    surface: MicroMesh
    notes: dict = field(default_factory=dict)


def fit_height_map(mm: MicroMesh, reference: TriMesh, atlas: Atlas, resolution: int,
                   level: int = 4, rounds: int = 3, smoothness: float = 1e-3,
                   slopes: float = 0.1, seam_level: int = 5,
                   progress: Callable[[dict], None] = lambda p: None,
                   should_stop: Callable[[], bool] = lambda: False) -> HeightMap:
    """The height map on ``atlas`` at ``resolution``² that draws ``reference`` best over
    ``mm``'s base and unit directions at tessellation ``level`` (see the module doc).

    Args:
        mm: the micro-mesh whose base and directions the map stands on (world space).
        reference: the source surface (world space, cleaned: ``core.construct.reference``).
        atlas: the base's UVs (``core.maps.uv_atlas`` or ``atlas_from_uvs``).
        resolution: the map's width and height in texels.
        level: the lattice level the fit samples (a renderer's tessellation).
        rounds: the fit's match-and-solve rounds.
        smoothness, slopes: the fit's weights (``core.fit``).
        seam_level: the seams are closed at the lattice points of this level and coarser.
    Returns:
        :class:`HeightMap`; ``notes``: rounds, CG iterations, seconds, the seam gaps.
    Raises:
        MapsCancelled: ``should_stop()`` turned true.
        AtlasError: a resolution that is not a power of two within 64..16384, or an atlas
            with less than a texel per base face.
    """
    began = time.perf_counter()
    res = checked_resolution(resolution)
    texels_per_face = check_room(atlas, res)
    total = rounds + 2
    progress({"phase": "height map", "iteration": 0, "total": total})
    frame = unit_sphere_normalization(reference.vertices)
    base = mm.base.with_vertices(frame.apply(mm.base.vertices))
    ref = reference.with_vertices(frame.apply(reference.vertices))
    U = unit_directions(mm)
    lattice = MicroMesh.flat(base, np.full(base.n_faces, int(level)), directions=U)
    topo = lattice.topology
    uv = np.einsum("qk,qkc->qc", topo.vertex_bary, atlas.corner_uv[topo.vertex_face])
    lt, lw = bilinear_taps(uv, res, res)
    seams = seam_points(base, atlas, seam_level)
    apart = np.any(seams.uv_a != seams.uv_b, axis=1)
    at, aw = bilinear_taps(seams.uv_a[apart], res, res)
    bt, bw = bilinear_taps(seams.uv_b[apart], res, res)
    face, bary = texel_faces(atlas, res, res)
    filled = face >= 0
    grid = TexelGrid.covering(res, res, ndimage.binary_dilation(filled, iterations=2), lt, at, bt)

    start = _bake(base, U, ref, face, bary, filled, lattice)
    x = start.reshape(-1)[grid.texels].copy()
    length = np.linalg.norm(lattice.micro_vertex_directions(), axis=1)
    SB = (sp.diags(1.0 / length) @ grid.sampling(lt, lw)).tocsr()
    SBT = SB.T.tocsr()
    C = (grid.sampling(at, aw) - grid.sampling(bt, bw)).tocsr()
    CtC = (C.T @ C).tocsr()
    membrane = grid.membrane()
    samples = fit_samples(lattice, ref)
    iterations = []
    for r in range(rounds):
        if should_stop():
            raise MapsCancelled("height map cancelled")
        progress({"phase": "height map", "iteration": r + 1, "total": total})
        M, b = normal_equations(lattice, SB @ x, samples, smoothness, slopes)
        hold = float(np.median(M.diagonal()))
        Q = (MEMBRANE * hold * membrane + SEAM * hold * CtC).tocsr()
        diag = SBT.multiply(SBT) @ M.diagonal() + Q.diagonal()
        x, its = _pcg(lambda v: SBT @ (M @ (SB @ v)) + Q @ v, SBT @ b, x, diag, should_stop)
        iterations.append(its)
    progress({"phase": "height map", "iteration": rounds + 1, "total": total})
    x = _closed(C, x)
    height = _padded(grid.image(x, start), grid) / frame.scale
    world = lattice.with_displacements(SB @ x / frame.scale).with_base_positions(
        mm.base.vertices)
    gaps = seam_gap_max(mm.base, atlas, height)
    notes = {"level": int(level), "resolution": res, "rounds": int(rounds),
             "cg_iterations": iterations, "texels_solved": int(grid.n),
             "lattice_points": int(topo.n_vertices), "texels_per_face": texels_per_face,
             "seam_edges": int(len(np.unique(seams.edge))),
             "seam_gap_max": {str(k): v / mm.base.bbox_diagonal for k, v in gaps.items()},
             "time_s": time.perf_counter() - began}
    return HeightMap(atlas, height.astype(np.float32), filled, int(level), world, notes)


def _bake(base: TriMesh, U: np.ndarray, ref: TriMesh, face: np.ndarray, bary: np.ndarray,
          filled: np.ndarray, lattice: MicroMesh) -> np.ndarray:
    """(H, W) the conventional bake in the unit frame: from each filled texel's base point a
    ray both ways along the interpolated unit normal, the nearer hit (the nearest point of
    the reference where none is within reach); every other texel the nearest filled one's."""
    ys, xs = np.nonzero(filled)
    P, n = base_point(lattice, U, face[ys, xs], bary[ys, xs])
    reach = 0.05 * ref.bbox_diagonal
    h = np.zeros(filled.shape)
    h[ys, xs] = bake_displacements(P, n, ref, max_distance=reach).displacement
    return _nearest_fill(h, filled)


def _nearest_fill(image: np.ndarray, known: np.ndarray) -> np.ndarray:
    if known.all() or not known.any():
        return image
    _, (iy, ix) = ndimage.distance_transform_edt(~known, return_indices=True)
    return image[iy, ix]


def _padded(image: np.ndarray, grid: TexelGrid) -> np.ndarray:
    """The texels outside the unknowns set to the nearest unknown's value (what a
    renderer's coarser mip levels and filtering read past the charts)."""
    known = np.zeros(image.size, bool)
    known[grid.texels] = True
    return _nearest_fill(image, known.reshape(image.shape))


def _pcg(A: Callable[[np.ndarray], np.ndarray], b: np.ndarray, x: np.ndarray,
         diag: np.ndarray, should_stop: Callable[[], bool]) -> tuple[np.ndarray, int]:
    """Jacobi-preconditioned conjugate gradients from ``x`` to a residual of :data:`RTOL`
    of ``b``'s (at most :data:`MAX_CG` steps); (x, steps)."""
    inv = np.where(diag > 0, 1.0 / np.where(diag > 0, diag, 1.0), 0.0)
    x = x.copy()
    r = b - A(x)
    z = inv * r
    p = z.copy()
    rz = float(r @ z)
    stop = RTOL * float(np.linalg.norm(b))
    for k in range(MAX_CG):
        if float(np.linalg.norm(r)) <= stop:
            return x, k
        if k % 16 == 15 and should_stop():
            raise MapsCancelled("height map cancelled")
        Ap = A(p)
        alpha = rz / float(p @ Ap)
        x += alpha * p
        r -= alpha * Ap
        z = inv * r
        rz, rz_old = float(r @ z), rz
        p = z + (rz / rz_old) * p
    return x, MAX_CG


def _closed(C: sp.csr_matrix, x: np.ndarray) -> np.ndarray:
    """``x`` moved the least (in the sum of squares) to satisfy C x = 0: both sides of every
    seam equal at its lattice points. (C Cᵀ may be singular where rows repeat, at the corners
    shared by several seam edges: a tiny ridge keeps it invertible, and three passes take the
    residual to rounding.)"""
    if C.shape[0] == 0:
        return x
    CCt = (C @ C.T).tocsc() + 1e-12 * sp.identity(C.shape[0], format="csc")
    lu = spla.splu(CCt)
    for _ in range(3):
        x = x - C.T @ lu.solve(C @ x)
    return x
