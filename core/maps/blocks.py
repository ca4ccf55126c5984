"""A texel-aligned atlas: every base face's corners on texel centres, every edge along a row,
a column or a diagonal of texels.

A renderer samples a height map bilinearly. Along a texel row the lookup is the linear
interpolation of that row's texels alone, so two faces whose common edge runs along a row of
k + 1 texels on each side draw the same heights along the whole edge, at every tessellation
level, exactly where those texels are equal (``core.maps.ties``). Charts cut by xatlas put
their edges anywhere between texels: closing them costs the texels near every seam their
freedom (gen_parts86 at 2048²: 31.11 dB closed, 32.42 left open; docs/heightmaps.md).

Here the faces are paired across an edge, and each pair fills a square block of
(k + 1)² texels, their common edge its diagonal: one bilinear patch over both. A face left
without a partner takes half a block. The blocks sit on a grid with ``GUTTER`` texels between
them, one size for all: k follows from the number of blocks and the resolution. A face's
texels are its lattice's points, spread as a renderer's tessellation spreads them (at k = 16,
the level-4 lattice lands on the texel centres).
"""
from __future__ import annotations

import numpy as np

from ..mesh.trimesh import TriMesh
from .atlas import Atlas, AtlasError

# Texels between blocks: what a renderer's lookup on a block's edge may touch past it, by
# rounding, holds values near the edge's own (the fit's membrane carries them there).
GUTTER = 2


def block_atlas(base: TriMesh, resolution: int) -> Atlas:
    """The base's faces in texel-aligned blocks (module doc) of a ``resolution``² map.

    Returns:
        :class:`Atlas`: UVs at texel centres, a vertex per block corner (a pair's two faces
        share their edge's two).
    Raises:
        AtlasError: more blocks than the map has room for at one texel a side.
    """
    faces = base.faces
    mate, across = face_pairs(base)
    lead = np.flatnonzero((mate < 0) | (np.arange(len(faces)) < mate))
    per_row = int(np.ceil(np.sqrt(len(lead))))
    pitch = resolution // per_row
    k = pitch - 1 - GUTTER
    if k < 1:
        raise AtlasError(f"no room for the base's UVs: its {base.n_faces} faces take "
                         f"{len(lead)} blocks, {per_row} a side, more than a {resolution}² "
                         "map holds; use a larger resolution or a coarser base")
    origin = (np.stack([np.arange(len(lead)) % per_row, np.arange(len(lead)) // per_row], 1)
              * pitch).astype(np.float64)
    # The lead face's corners: the one across from its partner's edge at (0, 0), the next
    # two at (k, 0) and (0, k); its partner's far corner at (k, k). Both stay anticlockwise.
    c = np.where(mate[lead] >= 0, across[lead], 0)
    a = faces[lead, c], faces[lead, (c + 1) % 3], faces[lead, (c + 2) % 3]
    square = np.array([[0, 0], [1, 0], [0, 1], [1, 1]], np.float64) * k
    corner = origin[:, None, :] + square[None]                         # (b, 4, 2)
    paired = mate[lead] >= 0
    b = np.where(paired, faces[np.maximum(mate[lead], 0),
                               np.maximum(across[np.maximum(mate[lead], 0)], 0)], -1)
    corners = np.stack([a[0], a[1], a[2], b], 1)                       # (b, 4) base vertices
    keep = np.ones((len(lead), 4), bool)
    keep[:, 3] = paired
    slot = np.cumsum(keep.reshape(-1)).reshape(keep.shape) - 1         # atlas vertex per corner
    uv = (corner[keep] + 0.5) / resolution
    vertex = corners[keep]
    out = np.zeros_like(faces)
    out[lead, c] = slot[:, 0]
    out[lead, (c + 1) % 3] = slot[:, 1]
    out[lead, (c + 2) % 3] = slot[:, 2]
    p = lead[paired]
    other = mate[p]
    for j in range(3):                     # the partner's corners by base vertex
        v = faces[other, j]
        hit = corners[paired] == v[:, None]
        out[other, j] = slot[paired][np.arange(len(p)), hit.argmax(1)]
    return Atlas(uv, out, vertex.astype(np.int64))


def face_pairs(base: TriMesh, rounds: int = 100) -> tuple[np.ndarray, np.ndarray]:
    """A matching of the faces across manifold edges: (mate (m,) the partner of each face,
    -1 where none; across (m,) the corner of each paired face opposite their common edge,
    -1 where none). Greedy in rounds: each unpaired face proposes to its unpaired neighbour
    with the fewest unpaired neighbours (ties by a fixed shuffle of the faces, so a strip of
    faces pairs everywhere at once, not from one end), and mutual proposals pair: faces with
    few chances go first. The face of least key pairs each round; at most ``rounds``."""
    adj = base.face_adjacency                               # (m, 3): across edge (i, i + 1)
    m = len(adj)
    mate = np.full(m, -1, np.int64)
    idx = np.arange(m)
    rank = np.random.default_rng(0).permutation(m)
    for _ in range(rounds):
        free = (adj >= 0) & (mate[np.maximum(adj, 0)] < 0) & (mate[:, None] < 0)
        degree = free.sum(1)
        if not (degree > 0).any():
            break
        key = np.where(free, degree[np.maximum(adj, 0)] * (m + 1) + rank[np.maximum(adj, 0)],
                       np.iinfo(np.int64).max)
        choice = key.argmin(1)
        want = np.where(degree > 0, adj[idx, choice], -1)
        mutual = (want >= 0) & (want[np.maximum(want, 0)] == idx)
        if not mutual.any():
            break
        mate[mutual] = want[mutual]
    _augment(adj, mate)
    across = np.full(m, -1, np.int64)
    has = mate >= 0
    edge = (adj[has] == mate[has, None]).argmax(1)          # the edge (i, i + 1) they share
    across[has] = (edge + 2) % 3
    return mate, across


def _augment(adj: np.ndarray, mate: np.ndarray, depth: int = 8) -> None:
    """Pairs more faces in place: from each unpaired face, a breadth-first search for a path
    that alternates unpaired and paired edges to another unpaired face (at most ``depth``
    pairs long), then each edge on it swapped (the greedy rounds leave some 8 %; this takes
    gen_parts86's base from 91.8 % to over 99 %)."""
    for u in np.flatnonzero(mate < 0):
        if mate[u] >= 0:
            continue
        parent = {int(u): -1}                # outer face -> the outer face before it
        frontier = [int(u)]
        end = -1
        for _ in range(depth):
            nxt = []
            for a in frontier:
                for b in adj[a]:
                    b = int(b)
                    if b < 0 or b == u or b in parent:
                        continue
                    if mate[b] < 0:
                        end, parent[b] = b, a
                        break
                    c = int(mate[b])
                    if c in parent:
                        continue
                    parent[b], parent[c] = a, b
                    nxt.append(c)
                if end >= 0:
                    break
            if end >= 0 or not nxt:
                break
            frontier = nxt
        while end >= 0:                      # end - a, then a's old partner onwards
            a = parent[end]
            before = parent[a] if a != u else -1
            mate[end], mate[a] = a, end
            end = before
