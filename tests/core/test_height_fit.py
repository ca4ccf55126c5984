"""The height map fitted to the source (core.maps.height_fit): its texels sampled as a
renderer samples them, its seams closed, and what it draws against the conventional bake on
the same base, UVs and texels."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from core.spatial.bake import bake_displacements
from core.render.cameras import fibonacci_cameras
from core.io.images import HeightCode
from core.maps import (AtlasError, MapsCancelled, TexelGrid, bilinear_taps, block_atlas,
                       fit_height_map,
                       sample, seam_points, texel_faces, unit_directions, uv_atlas)
from core.maps.atlas import checked_resolution
from core.maps.bake import base_point
from core.mesh.trimesh import TriMesh
from core.micro.micromesh import MicroMesh
from core.mesh.primitives import icosphere, noisy_sphere
from core.render import reference_images, render

RES = 256


@pytest.fixture(scope="module", params=["charts", "blocks"])
def case(request):
    """A ridged sphere of 20k faces (the source) over an 80-face icosphere (the base), on
    xatlas' charts (seams closed by constraint rows) and on texel-aligned blocks (by tied
    texels)."""
    v, f = noisy_sphere(20000, amplitude=0.03, seed=3)
    n = v / np.linalg.norm(v, axis=1, keepdims=True)
    v = v + n * (0.02 * np.sin(9 * n[:, 0]) * np.cos(7 * n[:, 1]))[:, None]
    ref = TriMesh(v, f)
    bv, bf = icosphere(2)
    mm = MicroMesh.flat(TriMesh(bv, bf), np.zeros(len(bf), int))
    atlas = (uv_atlas if request.param == "charts" else block_atlas)(mm.base, RES)
    return ref, mm, atlas


@pytest.fixture(scope="module")
def fitted(case):
    ref, mm, atlas = case
    return fit_height_map(mm, ref, atlas, RES, level=3)


def test_the_sampling_matrix_is_the_bilinear_lookup():
    rng = np.random.default_rng(0)
    img = rng.random((32, 64))
    uv = rng.uniform(-0.1, 1.1, (500, 2))
    taps, w = bilinear_taps(uv, 64, 32)
    grid = TexelGrid.covering(64, 32, np.ones((32, 64), bool))
    got = grid.sampling(taps, w) @ img.reshape(-1)[grid.texels]
    assert np.allclose(got, sample(img, uv), atol=1e-12)


def test_the_membrane_sums_the_squared_steps_between_neighbouring_unknowns():
    rng = np.random.default_rng(2)
    mask = rng.random((24, 40)) < 0.6
    grid = TexelGrid.covering(40, 24, mask)
    x = rng.random(grid.n)
    img = np.full((24, 40), np.nan)
    img.reshape(-1)[grid.texels] = x
    steps = np.r_[(img[:, 1:] - img[:, :-1]).reshape(-1), (img[1:] - img[:-1]).reshape(-1)]
    membrane = grid.membrane()
    assert np.isclose(x @ (membrane @ x), np.nansum(steps ** 2))
    e = np.eye(grid.n)[:, :50]
    assert np.allclose(membrane.diagonal()[:50], [c @ (membrane @ c) for c in e.T])


def test_seams_are_closed_at_levels_3_4_and_5(case, fitted):
    _, mm, atlas = case
    diag = mm.base.bbox_diagonal
    assert fitted.notes["seam_edges"] > 10                 # the sphere's atlas has seams
    code = HeightCode.spanning(fitted.height)
    stored = code.heights(np.rint(code.values(fitted.height) * 65535) / 65535)   # 16-bit PNG
    for level in (3, 4, 5):
        pts = seam_points(mm.base, atlas, level)
        apart = np.abs(pts.uv_a - pts.uv_b).max(1) > 0
        assert apart.sum() > 100
        assert pts.gaps(fitted.height.astype(np.float64)).max() < 1e-6 * diag
        assert pts.gaps(stored).max() <= 1e-5 * diag
        assert fitted.notes["seam_gap_max"][str(level)] < 1e-6
    # without the seams' rows, the same points open (the check can fail)
    raw = np.zeros(fitted.height.shape)
    face, bary = texel_faces(atlas, RES, RES)
    ys, xs = np.nonzero(face >= 0)
    raw[ys, xs] = np.sin(40 * bary[ys, xs, 0])
    assert seam_points(mm.base, atlas, 4).gaps(raw).max() > 1e-3


def _drawn_error(ref: TriMesh, surface: MicroMesh) -> float:
    """Mean squared pixel error of the surface's flat-shaded renders against the source's,
    from 12 views at 192²."""
    cams = fibonacci_cameras(12, 3.5, 35.0, 192)
    f32 = dict(dtype=torch.float32)
    target = reference_images(torch.as_tensor(ref.vertices, **f32),
                              torch.as_tensor(ref.faces), cams, kind="flat")
    X = torch.as_tensor(surface.micro_vertex_positions(), **f32)
    T = torch.as_tensor(surface.topology.triangles)
    with torch.no_grad():
        return float(((render(X, T, cams, kind="flat") - target) ** 2).mean())


def test_the_fit_draws_the_source_better_than_the_conventional_bake(case, fitted):
    ref, mm, atlas = case
    # the conventional bake on the same base, UVs and texels: rays both ways along the
    # interpolated unit normal from each texel centre, drawn at the same lattice
    face, bary = texel_faces(atlas, RES, RES)
    ys, xs = np.nonzero(face >= 0)
    U = unit_directions(mm)
    P, n = base_point(mm.base, U, face[ys, xs], bary[ys, xs])
    baked = np.zeros((RES, RES))
    baked[ys, xs] = bake_displacements(P, n, ref, max_distance=0.05 * ref.bbox_diagonal
                                       ).displacement
    drawn = fitted.surface                  # the same lattice as a micro-mesh of level 3
    lattice = MicroMesh.flat(mm.base, np.full(mm.base.n_faces, fitted.level), U)
    t = lattice.topology
    uv = np.einsum("qk,qkc->qc", t.vertex_bary, atlas.corner_uv[t.vertex_face])
    length = np.linalg.norm(lattice.micro_vertex_directions(), axis=1)
    bake_surface = lattice.with_displacements(sample(baked, uv) / length)
    P, D = lattice.micro_vertex_base_positions(), lattice.micro_vertex_directions()
    ours = lattice.with_displacements(((drawn.X - P) * D).sum(1) / (D * D).sum(1))
    assert np.allclose(ours.micro_vertex_positions(), drawn.X, atol=1e-9)   # X = P + D d
    f = np.repeat(np.arange(mm.base.n_faces), 5)
    b = np.random.default_rng(1).dirichlet(np.ones(3), len(f))
    idx, w = drawn.locate(f, b)
    assert np.allclose(np.einsum("qk,qkc->qc", w, drawn.X[idx]), ours.surface_at(f, b))
    # the fitted surface is the map as sampled at the lattice, and it draws the source better
    assert np.allclose(ours.displacements * length,
                       sample(fitted.height.astype(np.float64), uv), atol=1e-6)
    ours, theirs = _drawn_error(ref, ours), _drawn_error(ref, bake_surface)
    assert ours < 0.8 * theirs, (ours, theirs)


def test_bad_resolutions_and_a_base_without_room_are_refused(case):
    ref, mm, atlas = case
    for bad in (100, 32, 32768, 2048.5):
        with pytest.raises(AtlasError, match="power of two"):
            checked_resolution(bad)
    assert checked_resolution(2048) == 2048
    with pytest.raises(AtlasError, match="power of two"):
        fit_height_map(mm, ref, atlas, 300)
    v, f = icosphere(40)                                   # 32,000 faces on 64² texels
    big = MicroMesh.flat(TriMesh(v, f), np.zeros(len(f), int))
    with pytest.raises(AtlasError, match="no room"):
        fit_height_map(big, ref, uv_atlas(big.base, 64), 64)


def test_a_stop_request_cancels(case):
    ref, mm, atlas = case
    with pytest.raises(MapsCancelled):
        fit_height_map(mm, ref, atlas, RES, level=3, should_stop=lambda: True)


def test_a_vertex_where_two_fans_meet_lands_in_one_place():
    """Two fans of faces that share a vertex but no edge (a pinched vertex the base keeps):
    the atlas gives the vertex a place in each chart, and no seam edge ties them; the fit
    ties them at the vertex itself."""
    fan = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    v = np.concatenate([fan, -fan[1:]])
    f = np.array([[0, 1, 2], [0, 2, 3], [0, 4, 5], [0, 5, 6]])
    base = TriMesh(v, f)
    mm = MicroMesh.flat(base, np.zeros(4, int), directions=np.tile([0.0, 0, 1], (7, 1)))
    g = np.linspace(-1.2, 1.2, 61)
    x, y = np.meshgrid(g, g)
    z = 0.05 * np.sin(5 * x) * np.cos(4 * y) + 0.03 * (x > 0)      # each fan its own height
    q = np.arange(61 * 61).reshape(61, 61)
    quads = np.stack([q[:-1, :-1], q[:-1, 1:], q[1:, 1:], q[1:, :-1]], -1).reshape(-1, 4)
    ref = TriMesh(np.stack([x, y, z], -1).reshape(-1, 3),
                  np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]]))
    atlas = uv_atlas(base, 128)
    assert (atlas.vertex == 0).sum() == 2                      # the vertex in both charts
    pts = seam_points(base, atlas, 5)
    assert (pts.edge == -1).sum() == 1                         # tied at the vertex itself
    hm = fit_height_map(mm, ref, atlas, 128, level=3)
    at0 = atlas.uv[atlas.vertex == 0]
    h = sample(hm.height.astype(np.float64), at0)
    assert abs(h[0] - h[1]) < 1e-7 and abs(h[0] - 0.015) < 0.02, h


def test_a_map_with_few_texels_for_its_lattice_takes_half_the_samples(case, monkeypatch):
    import core.maps.height_fit as hf
    ref, mm, _ = case
    asked = []
    original = hf.reference_bounds
    monkeypatch.setattr(hf, "reference_bounds", lambda *a: asked.append(a[-1]) or original(*a))
    rich = fit_height_map(mm, ref, uv_atlas(mm.base, RES), RES, level=3, rounds=1)
    starved = fit_height_map(mm, ref, uv_atlas(mm.base, 64), 64, level=4, rounds=1)
    assert rich.notes["texels_per_face"] >= 64 / 4         # level 3: 64 lattice triangles
    assert starved.notes["texels_per_face"] < 256 / 4      # level 4: 256
    assert asked == [hf.DENSITY, hf.DENSITY / 2]
    assert starved.notes["samples"] < rich.notes["samples"] * 4 / 2


def test_a_base_on_the_creases_of_its_source_gets_a_flat_map():
    """A box drawn exactly by its base, whose directions at two corners lie nearly in the top
    face (94° from its normal, as the construction's can on a CAD plate's rims): a flat map,
    the blocks' texels on the base's edges, on the source's creases, included. (The rays of
    the start from such texels of gen_genus11_27k's base, 1e-9 off its source, went on to the
    far side of the plate: ``height_fit.INSET``; the box's do not.)"""
    v = np.array([[x, y, z] for x in (0.0, 2) for y in (0.0, 1) for z in (0.0, 0.5)])
    f = np.array([[0, 2, 3], [0, 3, 1], [4, 5, 7], [4, 7, 6], [0, 1, 5], [0, 5, 4],
                  [2, 6, 7], [2, 7, 3], [0, 4, 6], [0, 6, 2], [1, 3, 7], [1, 7, 5]])
    box = TriMesh(v, f)
    d = box.vertex_normals.copy()
    d[[1, 5]] = [0.0, 1.0, -0.07]                  # the top front edge: y = 0, z = 0.5
    mm = MicroMesh.flat(box, np.zeros(len(f), int), directions=d)
    atlas = block_atlas(box, 128)
    hm = fit_height_map(mm, box, atlas, 128, level=3)
    face, _ = texel_faces(atlas, 128, 128)
    assert np.abs(hm.height[face >= 0]).max() < 1e-5 * box.bbox_diagonal
