"""A height map fitted to the source: its texels are the unknowns of the micro-mesh fit.

A renderer draws a base with a height map by cutting each base triangle into the lattice of
some level L and moving every lattice point by the bilinearly sampled height along the
normalised interpolated normal. That is a micro-mesh of uniform level L with the unit vertex
normals as directions, whose displacement at micro-vertex k is d_k = h_k / |lerp(N)_k|; and
h = B x, B the bilinear lookups of the texels x at the lattice points' UVs. So the fit's
normal equations over d (``core.fit.system.displacement_blocks``: the reference's samples
matched to the micro-surface, point-to-plane and slope rows) become, with d = S B x and
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
from scipy import ndimage

from ..spatial.bake import bake_displacements
from ..fit.grouped import GroupedMatches, spatial_order
from ..fit.samples import Samples
from ..fit.system import displacement_blocks
from ..mesh.trimesh import TriMesh
from ..micro.micromesh import MicroMesh
from ..mesh.normalization import unit_sphere_normalization
from .atlas import Atlas, check_room, checked_resolution, texel_faces
from .bake import MapsCancelled, base_point, unit_directions
from .lattice import DrawnSurface, Lattice, moved_bound, reference_bounds
from .seams import seam_gap_max, seam_points
from .texel_solve import closed, pcg
from .texels import Membrane, TexelGrid, bilinear_taps
from .ties import texel_ties

# The texels are solved to this RMS height (the unit sphere's radius 1), where that is reached
# before the relative residual (texel_solve.RTOL): below float32's resolution of the drawn
# positions (6e-8). It stops the solve on a base that already draws the source (heights of
# 1e-6: gen_genus11_27k took 125 steps, 17 s, for heights of 1e-11), and leaves the others'.
HEIGHT_TOL = 1e-8
# The membrane's and the seams' weights, as fractions of the median micro-vertex's hold by
# its samples (the diagonal of the fit's system).
MEMBRANE = 1e-3
SEAM = 1.0
# The start's rays leave from this far towards the face's centre (``_bake``).
INSET = 1e-3
# Texels rasterised, baked and sampled at a time: each takes some hundred bytes of
# temporaries (a whole 2048² map at once added 1.2 GB to the stage's peak).
CHUNK = 1 << 18
# The tessellation level a height map is fitted for: what a renderer cuts each base triangle
# into where it shows the detail (the lattice of 4^4 triangles; judged there).
LEVEL = 4
# Reference samples per lattice triangle, at least (``core.fit.samples`` rounds a face's up
# to a power of 4): 2 gained 0.08 dB on bunny_69k for 1.5 times the samples, and took the
# 871k scan's stage to 4.1 GB (docs/heightmaps.md). Half as many where the map has fewer
# texels than a quarter of the lattice's triangles: the texels then limit what it draws
# (gen_parts86 at 2048², 0.2 texels a triangle: 31.11 dB against 31.12, the fit 100 s
# against 145 s; the flight helmet, 0.38, lost 0.08 dB at half).
DENSITY = 1.0


@dataclass(eq=False)
class HeightMap:
    """A fitted height map: ``height`` (H, W) float32, world units along the normalised
    interpolated vertex normal, row 0 at v = 0; ``level``: the tessellation it was fitted
    for; ``surface``: what a renderer draws at that level (world space)."""

    height: np.ndarray
    level: int
    surface: DrawnSurface
    notes: dict = field(default_factory=dict)


def fit_height_map(mm: MicroMesh, reference: TriMesh, atlas: Atlas, resolution: int,
                   level: int = LEVEL, rounds: int = 2, slopes: float = 0.1, seam_level: int = 5,
                   progress: Callable[[dict], None] = lambda p: None,
                   should_stop: Callable[[], bool] = lambda: False) -> HeightMap:
    """The height map on ``atlas`` at ``resolution``² that draws ``reference`` best over
    ``mm``'s base and unit directions at tessellation ``level`` (see the module doc).

    Args:
        mm: the micro-mesh whose base and directions the map stands on (world space).
        reference: the source surface (world space, cleaned: ``core.mesh.reference``).
        atlas: the base's UVs (``core.maps.uv_atlas`` or ``atlas_from_uvs``).
        resolution: the map's width and height in texels.
        level: the lattice level the fit samples (a renderer's tessellation).
        rounds: the fit's match-and-solve rounds (bunny_69k at 2048²: 41.92 dB after 2 and
            after 3; the third took 4 CG steps).
        slopes: the fit's weight of the micro-triangles' tilt (``core.fit``). The membrane
            over the texels smooths them: the fit's smoothness of the micro-vertices is left
            out (bunny_69k at 2048²: 41.90 dB with it at 1e-3 and without; its LᵀL was the
            round's largest matrix).
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
    progress({"phase": "height map", "iteration": 0, "total": rounds + 2})
    frame = unit_sphere_normalization(reference.vertices)
    base = mm.base.with_vertices(frame.apply(mm.base.vertices))
    v = frame.apply(reference.vertices)           # its faces in a spatial order (core.fit.grouped)
    ref = TriMesh(v, reference.faces[spatial_order(v[reference.faces].mean(1))])
    U = unit_directions(mm)
    lattice, uv = Lattice.over(base, U, atlas, level)
    texels = _Texels.set_up(lattice, uv, base, U, ref, atlas, res, seam_level)
    del uv
    d = texels.SB @ texels.x
    starved = texels_per_face < 4 ** level / 4     # under a texel per 4 lattice triangles
    samples, bound = reference_bounds(lattice, base, ref, d,
                                      DENSITY / 2 if starved else DENSITY)
    groups = lattice.groups(base)
    length = np.linalg.norm(lattice.D, axis=1)
    iterations = []
    for r in range(rounds):
        if should_stop():
            raise MapsCancelled("height map cancelled")
        progress({"phase": "height map", "iteration": r + 1, "total": rounds + 2})
        steps, dist, tri = texels.solve(lattice, d, groups, samples, bound, slopes,
                                        should_stop)
        iterations.append(steps)
        moved = texels.SB @ texels.x
        bound = moved_bound(dist, tri, lattice.triangles,
                             np.abs((moved - d) * length).astype(np.float32))
        del tri
        d = moved
    progress({"phase": "height map", "iteration": rounds + 1, "total": rounds + 2})
    x = closed(texels.C, texels.x)
    height = _padded(texels.grid.image(x, np.zeros((res, res))), texels.grid) / frame.scale
    gaps = seam_gap_max(mm.base, atlas, height)
    notes = {"level": int(level), "resolution": res, "rounds": int(rounds),
             "cg_iterations": iterations, "texels_solved": int(texels.grid.n),
             "lattice_points": int(lattice.n_vertices), "texels_per_face": texels_per_face,
             "samples": len(samples),
             "seam_edges": texels.seam_edges,
             "seam_gap_max": {str(k): v / mm.base.bbox_diagonal for k, v in gaps.items()},
             "time_s": time.perf_counter() - began}
    d = texels.SB @ x
    surface = lattice.drawn(frame.invert(lattice.P + lattice.D * d[:, None]))
    return HeightMap(height.astype(np.float32), int(level), surface, notes)


@dataclass(eq=False)
class _Texels:
    """The unknown texels and what ties them: ``grid`` (which texels), ``SB`` (n, q) the
    lattice's displacements from them, ``C`` the seams' rows, ``membrane``; ``x`` (q,) their
    current values (first the conventional bake's)."""

    grid: TexelGrid
    SB: sp.csr_matrix
    C: sp.csr_matrix
    CtC: sp.csr_matrix
    membrane: Membrane
    x: np.ndarray
    seam_edges: int

    @classmethod
    def set_up(cls, lattice: Lattice, uv: np.ndarray, base: TriMesh, U: np.ndarray,
               ref: TriMesh, atlas: Atlas, res: int, seam_level: int) -> "_Texels":
        face, bary = texel_faces(atlas, res, res, chunk=CHUNK)
        filled = face >= 0
        ties = texel_ties(base, atlas, res, res, filled)
        seams = seam_points(base, atlas, seam_level, skip=ties.closed)
        apart = np.any(seams.uv_a != seams.uv_b, axis=1)
        at, aw = bilinear_taps(seams.uv_a[apart], res, res)
        bt, bw = bilinear_taps(seams.uv_b[apart], res, res)
        read = ndimage.binary_dilation(filled, iterations=2).reshape(-1)
        for s in range(0, len(uv), 4 * CHUNK):     # (the lattice's taps: 16 bytes a point)
            read[bilinear_taps(uv[s:s + 4 * CHUNK], res, res)[0].reshape(-1)] = True
        grid = TexelGrid.covering(res, res, read.reshape(res, res), at, bt, ties=ties)
        del read
        start = _bake(base, U, ref, face, bary, filled)
        del face, bary
        length = np.linalg.norm(lattice.D, axis=1)
        SB = sp.vstack([grid.sampling(*_scaled(uv[s:s + 4 * CHUNK], length[s:s + 4 * CHUNK],
                                               res)) for s in range(0, len(uv), 4 * CHUNK)],
                       format="csr")                # S B: the lookups over |lerp(N)|
        C = (grid.sampling(at, aw) - grid.sampling(bt, bw)).tocsr()
        C.data[np.abs(C.data) < 1e-12] = 0.0        # both sides on tied texels
        C.eliminate_zeros()
        C = C[np.diff(C.indptr) > 0]
        return cls(grid, SB, C, (C.T @ C).tocsr(), grid.membrane(), grid.values(start),
                   int(len(np.unique(seams.edge[seams.edge >= 0]))) + int(ties.closed.sum()))

    def solve(self, lattice: Lattice, d: np.ndarray, groups: list, samples: Samples,
              bound: np.ndarray, slopes: float, should_stop: Callable[[], bool]
              ) -> tuple[int, np.ndarray]:
        """One round: the samples matched to the lattice the texels draw now (``d``: its
        displacements, SB x; ``bound``: a distance within which each sample has a triangle),
        the system over the texels solved from them; (the CG steps it took, each sample's
        distance to the lattice before)."""
        X = lattice.P + lattice.D * d[:, None]
        T = lattice.triangles
        matches = GroupedMatches(X, T, groups, samples, bound)
        M, b = displacement_blocks(matches, T, lattice.P, lattice.D, d, slopes)
        dist, tri = matches.distance, matches.triangle
        del X, matches
        hold = float(np.median(M.diagonal()))
        tied, seam = MEMBRANE * hold, SEAM * hold
        SB, membrane, CtC = self.SB, self.membrane, self.CtC
        squares = sp.csr_matrix((SB.data ** 2, SB.indices, SB.indptr), shape=SB.shape)
        diag = squares.T @ M.diagonal() + tied * membrane.diagonal() \
            + seam * CtC.diagonal()
        del squares
        floor = HEIGHT_TOL * float(np.median(diag)) * np.sqrt(len(diag))   # r ≈ diag·e
        self.x, steps = pcg(lambda v: SB.T @ (M @ (SB @ v)) + tied * (membrane @ v)
                             + seam * (CtC @ v), SB.T @ b, self.x, diag, should_stop, floor)
        return steps, dist, tri


def _scaled(uv: np.ndarray, length: np.ndarray, res: int) -> tuple[np.ndarray, np.ndarray]:
    """The bilinear taps of ``uv`` with their weights over ``length``."""
    taps, w = bilinear_taps(uv, res, res)
    return taps, w / length[:, None]


def _bake(base: TriMesh, U: np.ndarray, ref: TriMesh, face: np.ndarray, bary: np.ndarray,
          filled: np.ndarray) -> np.ndarray:
    """(H, W) the conventional bake in the unit frame: from each filled texel's base point a
    ray both ways along the interpolated unit normal, the nearer hit (the nearest point of
    the reference where none is within reach); every other texel the nearest filled one's.
    The rays start :data:`INSET` of the way to the face's centre: a texel on a base edge
    (every edge of ``blocks``' atlas has texels on it) that lies on a crease of the source
    sent its rays past both faces of the crease, into the far side of a CAD plate."""
    ys, xs = np.nonzero(filled)
    reach = 0.05 * ref.bbox_diagonal
    ref = TriMesh(ref.vertices, ref.faces)  # its ray scene and tree (cached on it) freed after
    h = np.zeros(filled.shape)
    for s in range(0, len(ys), CHUNK):
        y, x = ys[s:s + CHUNK], xs[s:s + CHUNK]
        P, n = base_point(base, U, face[y, x], bary[y, x] * (1.0 - INSET) + INSET / 3.0)
        h[y, x] = bake_displacements(P, n, ref, max_distance=reach).displacement
    return _nearest_fill(h, filled)


def _nearest_fill(image: np.ndarray, known: np.ndarray) -> np.ndarray:
    if known.all() or not known.any():
        return image
    _, (iy, ix) = ndimage.distance_transform_edt(~known, return_indices=True)
    return image[iy, ix]


def _padded(image: np.ndarray, grid: TexelGrid) -> np.ndarray:
    """The texels outside the unknowns set to the nearest unknown's value (what a
    renderer's coarser mip levels and filtering read past the charts)."""
    return _nearest_fill(image, grid.known())
