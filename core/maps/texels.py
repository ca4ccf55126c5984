"""Texels as unknowns: bilinear sampling of a map as a sparse matrix over the texels a fit
solves for, and the smoothness that holds the texels no sample reaches.

A map is (H, W) with row 0 at v = 0 (``core.maps.atlas``); a texel's flat number is
``y * W + x``. Sampling is a GPU's bilinear filter with clamp-to-edge: the texel centres sit
at ((x + 0.5) / W, (y + 0.5) / H), as glTF, Blender and :func:`core.maps.bake.sample` use.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..fit.triangle_sums import f64
from ..runtime.jit import kernel


def bilinear_taps(uv: np.ndarray, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """The four texels a bilinear lookup at each ``uv`` reads and their weights.

    Args:
        uv: (q, 2) texture coordinates, v = 0 at row 0.
        width, height: the map's size in texels (at least 2 each).
    Returns:
        (texels (q, 4) int64 flat numbers, weights (q, 4) float64 summing to 1 per row), in
        the order (x0, y0), (x0 + 1, y0), (x0, y0 + 1), (x0 + 1, y0 + 1).
    """
    x = np.clip(uv[:, 0] * width - 0.5, 0, width - 1)
    y = np.clip(uv[:, 1] * height - 0.5, 0, height - 1)
    x0 = np.minimum(x.astype(np.int64), width - 2)
    y0 = np.minimum(y.astype(np.int64), height - 2)
    fx, fy = x - x0, y - y0
    row = y0 * width + x0
    texels = np.stack([row, row + 1, row + width, row + width + 1], 1)
    weights = np.stack([(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy], 1)
    return texels, weights


@dataclass(eq=False)
class TexelGrid:
    """The texels of a (height, width) map that a fit solves for, numbered 0..n-1.

    ``number`` (H * W,) int64: each texel's unknown number, -1 where it is not one;
    ``texels`` (n,) int64: the flat texel number of each unknown.
    """

    width: int
    height: int
    number: np.ndarray
    texels: np.ndarray

    @classmethod
    def covering(cls, width: int, height: int, mask: np.ndarray, *taps: np.ndarray
                 ) -> "TexelGrid":
        """The texels of ``mask`` (H, W) bool and every texel in ``taps`` (flat numbers)."""
        flat = np.asarray(mask, dtype=bool).reshape(-1).copy()
        for t in taps:
            flat[np.asarray(t).reshape(-1)] = True
        texels = np.flatnonzero(flat)
        number = np.full(width * height, -1, np.int64)
        number[texels] = np.arange(len(texels))
        return cls(int(width), int(height), number, texels)

    @property
    def n(self) -> int:
        return len(self.texels)

    def sampling(self, texels: np.ndarray, weights: np.ndarray) -> sp.csr_matrix:
        """(q, n) the lookups of :func:`bilinear_taps` as rows over the unknowns (every tap
        must be an unknown: :meth:`covering` made with those taps)."""
        cols = self.number[texels]
        if (cols < 0).any():
            raise ValueError("a lookup reads a texel that is not an unknown")
        q, k = texels.shape
        m = sp.csr_matrix((weights.reshape(-1), cols.reshape(-1), np.arange(0, q * k + 1, k)),
                          shape=(q, self.n))
        m.sum_duplicates()
        return m

    def membrane(self) -> "Membrane":
        """Σ (x_i − x_j)² over the pairs of 4-neighbouring unknowns: the smoothness that
        gives the texels no lookup reads a value between their neighbours'."""
        y, x = np.divmod(self.texels, self.width)
        pairs = []
        for dy, dx in ((0, 1), (1, 0)):
            ok = (x + dx < self.width) & (y + dy < self.height)
            j = np.full(self.n, -1, np.int64)
            j[ok] = self.number[(y[ok] + dy) * self.width + x[ok] + dx]
            i = np.flatnonzero(j >= 0)
            pairs.append(np.stack([i, j[i]], 1))
        kind = np.int32 if self.n < 2 ** 31 else np.int64
        return Membrane(np.concatenate(pairs).astype(kind), self.n)

    def image(self, values: np.ndarray, fill: np.ndarray) -> np.ndarray:
        """(H, W) ``fill`` (H, W) with the unknowns' ``values`` (n,) put in."""
        out = np.array(fill, dtype=np.float64).reshape(-1)
        out[self.texels] = values
        return out.reshape(self.height, self.width)


@dataclass(eq=False)
class Membrane:
    """The (n, n) matrix GᵀG of Σ (x_i − x_j)² over ``pairs`` (e, 2), applied from the pairs
    (a quarter of its CSR's memory)."""

    pairs: np.ndarray
    n: int

    def __matmul__(self, v: np.ndarray) -> np.ndarray:
        out = np.zeros(self.n)
        _apply_pairs(self.pairs, f64(v), out)
        return out

    def diagonal(self) -> np.ndarray:
        return np.bincount(self.pairs.reshape(-1), minlength=self.n).astype(np.float64)


@kernel(cache=True)
def _apply_pairs(pairs, v, out):  # pragma: no cover
    """out += GᵀG v: (v_i − v_j) added at i and taken at j, pair by pair, in order (one
    thread: the sums do not depend on the thread count)."""
    for k in range(pairs.shape[0]):
        i, j = pairs[k, 0], pairs[k, 1]
        s = v[i] - v[j]
        out[i] += s
        out[j] -= s
