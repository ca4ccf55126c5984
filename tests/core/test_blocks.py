"""The texel-aligned atlas (core.maps.blocks) and the ties that close its seams
(core.maps.ties): whatever values the fit gives its unknowns, both sides of every seam draw
the same heights at every tessellation level."""
from __future__ import annotations

import numpy as np
import pytest

from core.maps import (AtlasError, TexelGrid, bilinear_taps, sample, seam_points, texel_faces,
                       uv_atlas)
from core.maps.blocks import GUTTER, block_atlas, face_pairs
from core.maps.seams import seam_half_edges
from core.maps.ties import texel_ties
from core.mesh.primitives import icosphere, torus
from core.mesh.trimesh import TriMesh

RES = 256


def _meshes():
    v, f = icosphere(4)                                        # 320 faces, closed
    tv, tf = torus(10, 7, 1.0, 0.3)                           # 140 faces, genus 1
    open_ = TriMesh(v, f[f[:, 0] % 5 != 0])                   # holes: faces with 1 and 2
    return {"sphere": TriMesh(v, f), "torus": TriMesh(tv, tf), "open": open_}   # neighbours


@pytest.fixture(params=["sphere", "torus", "open"])
def base(request):
    return _meshes()[request.param]


def test_faces_pair_across_their_edges(base):
    mate, across = face_pairs(base)
    paired = np.flatnonzero(mate >= 0)
    assert np.array_equal(mate[mate[paired]], paired)
    assert len(paired) >= 0.9 * base.n_faces
    for i in paired:
        j = mate[i]
        assert j in base.face_adjacency[i]
        assert base.faces[i, across[i]] not in base.faces[j]           # the far corner


def test_every_face_sits_on_texel_centres_with_edges_along_texel_lines(base):
    atlas = block_atlas(base, RES)
    c = atlas.corner_uv * RES - 0.5
    assert np.allclose(c, np.rint(c), atol=0, rtol=0)                # on texel centres
    assert np.array_equal(base.faces, atlas.vertex[atlas.faces])      # same corners
    e = np.rint(np.roll(c, -1, axis=1) - c)
    assert np.all((e[..., 0] == 0) | (e[..., 1] == 0) | (np.abs(e[..., 0]) == np.abs(e[..., 1])))
    cross = e[:, 0, 0] * (c[:, 2, 1] - c[:, 0, 1]) - e[:, 0, 1] * (c[:, 2, 0] - c[:, 0, 0])
    assert np.all(cross > 0)                                          # anticlockwise
    # a pair's faces share one square block; blocks lie GUTTER texels apart or more
    mate, _ = face_pairs(base)
    lo, hi = c.min(1), c.max(1)
    lead = np.flatnonzero((mate < 0) | (np.arange(base.n_faces) < mate))
    box_lo = np.array([lo[[f, mate[f]]].min(0) if mate[f] >= 0 else lo[f] for f in lead])
    box_hi = np.array([hi[[f, mate[f]]].max(0) if mate[f] >= 0 else hi[f] for f in lead])
    k = box_hi - box_lo
    assert np.all(k == k[0, 0]) and k[0, 0] >= 1                   # one size for all
    apart = (box_lo[:, None] > box_hi[None] + GUTTER) | (box_hi[:, None] + GUTTER < box_lo[None])
    assert np.all(apart.any(2) | np.eye(len(lead), dtype=bool))
    assert box_hi.max() < RES


def test_any_values_of_the_unknowns_close_every_seam(base):
    atlas = block_atlas(base, RES)
    face, _ = texel_faces(atlas, RES, RES)
    ties = texel_ties(base, atlas, RES, RES, face >= 0)
    edge, _, _ = seam_half_edges(base, atlas)
    assert len(edge) > base.n_faces / 3 and ties.closed.all()
    pts = seam_points(base, atlas, 5)
    taps, w = bilinear_taps(pts.uv_a, RES, RES)
    grid = TexelGrid.covering(RES, RES, face >= 0, taps, ties=ties)
    rng = np.random.default_rng(4)
    img = grid.image(rng.normal(size=grid.n), np.zeros((RES, RES)))
    for level in (0, 3, 4, 5, 7):
        at = seam_points(base, atlas, level)
        on_edges = at.edge >= 0         # (a vertex where fans meet with no edge between
        assert on_edges.sum() > 0       # them is the fit's constraint rows' to close)
        assert at.gaps(img)[on_edges].max() < 1e-12, level
    # each side's lookups are the grid's sampling of the unknowns
    got = grid.sampling(taps, w) @ grid.values(img)
    assert np.allclose(got, sample(img, pts.uv_a), atol=1e-12)
    # without the ties the same random texels open the seams (the check can fail)
    loose = rng.normal(size=(RES, RES))
    assert seam_points(base, atlas, 4).gaps(loose).max() > 0.1


def test_charts_cut_anywhere_are_not_tied():
    b = _meshes()["sphere"]
    atlas = uv_atlas(b, RES)
    face, _ = texel_faces(atlas, RES, RES)
    ties = texel_ties(b, atlas, RES, RES, face >= 0)
    assert len(ties.closed) > 0 and not ties.closed.any() and len(ties.equal) == 0


def test_a_base_too_fine_for_the_map_is_refused():
    v, f = icosphere(20)                                   # 8,000 faces on 64² texels
    with pytest.raises(AtlasError, match="no room"):
        block_atlas(TriMesh(v, f), 64)
