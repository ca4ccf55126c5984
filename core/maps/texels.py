"""Texels as unknowns: bilinear sampling of a map as a sparse matrix over the texels a fit
solves for, and the smoothness that holds the texels no sample reaches.

A map is (H, W) with row 0 at v = 0 (``core.maps.atlas``); a texel's flat number is
``y * W + x``. Sampling is a GPU's bilinear filter with clamp-to-edge: the texel centres sit
at ((x + 0.5) / W, (y + 0.5) / H), as glTF, Blender and :func:`core.maps.bake.sample` use.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..fit.triangle_sums import f64
from ..runtime.jit import kernel
from .ties import TexelTies


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

    ``number`` (H * W,) int64: each texel's unknown number, -1 where it is not one (texels
    tied equal share one); ``texels`` (n,) int64: a flat texel number of each unknown;
    ``follow`` (r, 4) flat texels (t, a, b, c) computed as t = a + b − c, not unknowns
    (``core.maps.ties``).
    """

    width: int
    height: int
    number: np.ndarray
    texels: np.ndarray
    follow: np.ndarray = field(default_factory=lambda: np.zeros((0, 4), np.int64))

    @classmethod
    def covering(cls, width: int, height: int, mask: np.ndarray, *taps: np.ndarray,
                 ties: TexelTies | None = None) -> "TexelGrid":
        """The texels of ``mask`` (H, W) bool and every texel in ``taps`` (flat numbers),
        those of ``ties.equal`` sharing an unknown and its followers computed."""
        ties = ties if ties is not None else TexelTies.none()
        flat = np.asarray(mask, dtype=bool).reshape(-1).copy()
        for t in (*taps, ties.equal, ties.follow[:, 1:]):
            flat[np.asarray(t).reshape(-1)] = True
        flat[ties.follow[:, 0]] = False
        texels = np.flatnonzero(flat)
        number = np.full(width * height, -1, np.int64)
        if len(ties.equal):
            local = np.searchsorted(texels, ties.equal)
            graph = sp.coo_matrix((np.ones(len(local)), (local[:, 0], local[:, 1])),
                                  shape=(len(texels), len(texels)))
            _, label = connected_components(graph, directed=False)
            first = np.unique(label, return_index=True)[1]
            number[texels] = label
            texels = texels[first]
        else:
            number[texels] = np.arange(len(texels))
        return cls(int(width), int(height), number, texels, ties.follow)

    @property
    def n(self) -> int:
        return len(self.texels)

    def sampling(self, texels: np.ndarray, weights: np.ndarray) -> sp.csr_matrix:
        """(q, n) the lookups of :func:`bilinear_taps` as rows over the unknowns (every tap
        must be an unknown or a follower: :meth:`covering` made with those taps). A follower
        t = a + b − c read with weight w reads a, b and c with w, w and −w."""
        q, k = texels.shape
        kind = np.int32 if self.n < 2 ** 31 else np.int64
        cols = self.number[texels].astype(kind)
        extra = None
        if len(self.follow):
            hit = np.flatnonzero(cols.reshape(-1) < 0)
            order = np.argsort(self.follow[:, 0])
            at = np.clip(np.searchsorted(self.follow[order, 0], texels.reshape(-1)[hit]), 0,
                         len(order) - 1)
            found = self.follow[order[at], 0] == texels.reshape(-1)[hit]
            hit, f = hit[found], self.follow[order[at[found]]]
            cols.reshape(-1)[hit] = self.number[f[:, 1]]          # a in the tap's place
            w = weights.reshape(-1)[hit]
            rows = np.repeat(hit // k, 2)
            extra = sp.csr_matrix((np.stack([w, -w], 1).reshape(-1),
                                   (rows, np.stack([self.number[f[:, 2]], self.number[f[:, 3]]],
                                                   1).reshape(-1))), shape=(q, self.n))
        if (cols < 0).any():
            raise ValueError("a lookup reads a texel that is not an unknown")
        m = sp.csr_matrix((weights.reshape(-1), cols.reshape(-1),
                           np.arange(0, q * k + 1, k, dtype=kind)), shape=(q, self.n))
        if extra is not None and extra.nnz:
            m = m + extra
        m.sum_duplicates()
        return m

    def membrane(self) -> "Membrane":
        """Σ (x_i − x_j)² over the pairs of 4-neighbouring texels of different unknowns: the
        smoothness that gives the texels no lookup reads a value between their
        neighbours'."""
        flat = np.flatnonzero(self.number >= 0)
        y, x = np.divmod(flat, self.width)
        pairs = []
        for dy, dx in ((0, 1), (1, 0)):
            ok = (x + dx < self.width) & (y + dy < self.height)
            j = np.full(len(flat), -1, np.int64)
            j[ok] = self.number[(y[ok] + dy) * self.width + x[ok] + dx]
            i = self.number[flat]
            use = (j >= 0) & (j != i)
            pairs.append(np.stack([i[use], j[use]], 1))
        kind = np.int32 if self.n < 2 ** 31 else np.int64
        return Membrane(np.concatenate(pairs).astype(kind), self.n)

    def image(self, values: np.ndarray, fill: np.ndarray) -> np.ndarray:
        """(H, W) ``fill`` (H, W) with the unknowns' ``values`` (n,) put in, and the
        followers computed."""
        out = np.array(fill, dtype=np.float64).reshape(-1)
        flat = np.flatnonzero(self.number >= 0)
        out[flat] = values[self.number[flat]]
        f = self.follow
        out[f[:, 0]] = out[f[:, 1]] + out[f[:, 2]] - out[f[:, 3]]
        return out.reshape(self.height, self.width)

    def values(self, image: np.ndarray) -> np.ndarray:
        """(n,) each unknown's mean over its texels in ``image`` (H, W)."""
        flat = np.flatnonzero(self.number >= 0)
        num = self.number[flat]
        total = np.bincount(num, np.asarray(image, np.float64).reshape(-1)[flat], self.n)
        return total / np.bincount(num, minlength=self.n)

    def known(self) -> np.ndarray:
        """(H, W) bool: the texels the unknowns set (followers included)."""
        out = self.number >= 0
        out[self.follow[:, 0]] = True
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
