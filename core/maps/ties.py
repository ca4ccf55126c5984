"""Seams along texel lines, closed by tying texels rather than by constraints.

Where both sides of a seam edge run from texel centre to texel centre along a row, a column or
a diagonal of the map, in the same number of steps (``core.maps.blocks`` lays out every edge
so), a bilinear lookup on the edge reads only the texels on that line, or, on a diagonal, the
line and the texels beside it. Such an edge is closed at every tessellation level exactly
when:

- the texels along its two sides are equal, step by step (``equal``);
- on a diagonal, the texel of each straddled cell that lies off the face ("outside") is
  a + b − c of the cell's two texels on the line (a, b) and the one on the face (c): the
  lookup along the line is then linear between a and b (``follow``).

A fit that gives each group of equal texels one unknown and computes the followers
(``core.maps.texels.TexelGrid``) closes these seams with no constraint rows; the others stay
with ``core.maps.seams``' rows.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..mesh.trimesh import TriMesh
from .atlas import Atlas
from .seams import seam_half_edges

# How near a texel centre an edge's end must be, in texels, to count as on it.
ON_CENTRE = 1e-6


@dataclass(eq=False)
class TexelTies:
    """``equal`` (e, 2) flat texel numbers that must hold the same value; ``follow`` (r, 4)
    flat texels (t, a, b, c) with t = a + b − c; ``closed`` (s,) bool per seam pair of
    ``seams.seam_half_edges``: the ones these ties close."""

    equal: np.ndarray
    follow: np.ndarray
    closed: np.ndarray

    @classmethod
    def none(cls, seams: int = 0) -> "TexelTies":
        return cls(np.zeros((0, 2), np.int64), np.zeros((0, 4), np.int64),
                   np.zeros(seams, bool))


def texel_ties(base: TriMesh, atlas: Atlas, width: int, height: int,
               covered: np.ndarray) -> TexelTies:
    """The ties that close ``atlas``' texel-aligned seams (module doc) on a (height, width)
    map; ``covered`` (H, W) bool: the texels inside some face's UV triangle (a diagonal's
    outside texels must not be, nor be another diagonal's)."""
    _, a, b = seam_half_edges(base, atlas)
    if len(a) == 0:
        return TexelTies.none()
    size = np.array([width, height], np.float64)
    ends = np.stack([atlas.uv[a], atlas.uv[b]], 1) * size - 0.5        # (s, side, end, 2)
    centre = np.rint(ends)
    step = centre[:, :, 1] - centre[:, :, 0]                            # (s, side, 2)
    n = np.abs(step).max(2)
    line = (step[..., 0] == 0) | (step[..., 1] == 0) | \
        (np.abs(step[..., 0]) == np.abs(step[..., 1]))
    ok = (np.abs(ends - centre).max((2, 3)) < ON_CENTRE).all(1) & line.all(1) \
        & (n[:, 0] == n[:, 1]) & (n[:, 0] > 0)
    cover = covered.reshape(-1)
    equal, follow, closed = [], [], np.zeros(len(a), bool)
    for k in np.unique(n[ok, 0]).astype(np.int64):          # the seams of k steps at a time
        s = np.flatnonzero(ok & (n[:, 0] == k))
        t = np.arange(k + 1)[None, :, None]
        pts = [(centre[s, j, 0][:, None] + t * step[s, j][:, None] / k).astype(np.int64)
               for j in (0, 1)]                             # (m, k + 1, 2) per side
        (row0, fit0), (row1, fit1) = (_diagonal_rows(p, cover, width) for p in pts)
        good = fit0 & fit1
        for row in (row0, row1):
            row = np.concatenate([row, np.repeat(s[:, None, None], k, 1)], -1)[good]
            follow.append(row[row[..., 0] >= 0])
        pair = np.stack([_flat(pts[0], width), _flat(pts[1], width),
                         np.repeat(s[:, None], k + 1, 1)], -1)[good]
        equal.append(pair.reshape(-1, 3))
        closed[s[good]] = True
    equal = np.concatenate(equal) if equal else np.zeros((0, 3), np.int64)
    follow = np.concatenate(follow) if follow else np.zeros((0, 5), np.int64)
    t, count = np.unique(follow[:, 0], return_counts=True)
    clash = np.unique(follow[np.isin(follow[:, 0], t[count > 1]), 4])
    closed[clash] = False          # an outside texel two diagonals want: both left open
    return TexelTies(equal[closed[equal[:, 2]], :2], follow[closed[follow[:, 4]], :4], closed)


def _diagonal_rows(pts: np.ndarray, cover: np.ndarray, width: int
                   ) -> tuple[np.ndarray, np.ndarray]:
    """For edges (m, k + 1, 2) texel points: (rows (m, k, 4) (t, a, b, c) of each straddled
    cell on the diagonal ones, -1 on the others; fits (m,): an edge that is straight along
    a row or column, or a diagonal with one texel of each cell off its face's cover)."""
    d = pts[:, 1:] - pts[:, :-1]
    diagonal = (d[..., 0] != 0).all(1) & (d[..., 1] != 0).all(1)
    height = len(cover) // width
    q1 = np.stack([pts[:, :-1, 0] + d[..., 0], pts[:, :-1, 1]], -1)
    q2 = np.stack([pts[:, :-1, 0], pts[:, :-1, 1] + d[..., 1]], -1)
    inside = ((q1 >= 0) & (q1 < [width, height])).all(-1) & \
        ((q2 >= 0) & (q2 < [width, height])).all(-1)         # (a cell past the map's edge)
    f1 = _flat(np.where(inside[..., None], q1, 0), width)
    f2 = _flat(np.where(inside[..., None], q2, 0), width)
    out1, out2 = ~cover[f1] & cover[f2], cover[f1] & ~cover[f2]
    fits = ~diagonal | ((out1 | out2) & inside).all(1)
    rows = np.stack([np.where(out1, f1, f2), _flat(pts[:, :-1], width),
                     _flat(pts[:, 1:], width), np.where(out1, f2, f1)], -1)
    rows[~diagonal] = -1
    return rows, fits


def _flat(pts: np.ndarray, width: int) -> np.ndarray:
    return pts[..., 1] * width + pts[..., 0]
