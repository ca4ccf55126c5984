"""Direction bounds, normalised values and prismoid shell volume."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from shapes import icosphere
from core.micro.bounds import (BoundsError, DirectionBounds, baked, micromesh_shell_volume,
                               normalized_values, prismoid_volumes, shell_volume, tight_bounds)
from core.micro.least_volume import lp_bounds, shell_weights
from core.micro.micromesh import MicroMesh


def enclosed_volume(v, f) -> float:
    p = v[f]
    return float(np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6)


def test_prism_by_hand():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    f = np.array([[0, 1, 2]])
    d = np.tile([0, 0, 1.0], (3, 1))
    b = DirectionBounds(np.zeros(3), np.ones(3))
    assert np.isclose(prismoid_volumes(v, f, d, b)[0], 0.5)
    # bias shifts, scale stretches; the winding does not matter (absolute volumes)
    b2 = DirectionBounds(np.full(3, 5.0), np.full(3, 2.0))
    assert np.isclose(shell_volume(v, f[:, ::-1], d, b2), 1.0)
    # a wedge: scale 0 at one vertex → 1/3 of the prism... vertex 0 height 0: V = A·(0+1+1)/3
    b3 = DirectionBounds(np.zeros(3), np.array([0.0, 1.0, 1.0]))
    assert np.isclose(shell_volume(v, f, d, b3), 0.5 * 2 / 3)


def test_radial_shell_is_scaled_polyhedron_and_tends_to_sphere_shell():
    h = 0.1
    errs = []
    for k in (0, 1, 2, 3):
        m = icosphere(k)
        b = DirectionBounds(np.zeros(m.n_vertices), np.full(m.n_vertices, h))
        vol = shell_volume(m.vertices, m.faces, m.vertices, b)
        # exact: the prismoids are differences of cones from the origin
        assert np.isclose(vol, enclosed_volume(m.vertices, m.faces) * ((1 + h) ** 3 - 1))
        errs.append(abs(vol - 4 * np.pi / 3 * ((1 + h) ** 3 - 1)))
    assert all(e1 < e0 for e0, e1 in zip(errs, errs[1:])) and errs[-1] / errs[0] < 0.05


def test_displaced_sphere_shell_volume():
    m = icosphere(1)
    vols = []
    for level in (1, 2, 3):
        mm = MicroMesh.flat(m, level, directions=m.vertices)
        base = mm.micro_vertex_base_positions()
        mm = mm.with_displacements(1 / np.linalg.norm(base, axis=1) - 1)  # onto the sphere
        bd = tight_bounds(mm)
        assert np.allclose(bd.bias, 0, atol=1e-15)  # base vertices are on the sphere
        assert (normalized_values(mm, bd, clip=False) >= -1e-9).all()
        assert (normalized_values(mm, bd, clip=False) <= 1 + 1e-9).all()
        vols.append(micromesh_shell_volume(mm, bd))
    gap = 4 * np.pi / 3 - enclosed_volume(m.vertices, m.faces)  # sphere minus polyhedron
    # the shell holds the sphere cap over each face: at least the gap, at most a few times it
    assert all(gap < v < 4 * gap for v in vols)
    assert vols[0] <= vols[1] <= vols[2] + 1e-12  # finer sampling finds the true maxima


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2 ** 31 - 1))
def test_tight_bounds_contain_values(seed):
    rng = np.random.default_rng(seed)
    m = icosphere(1)
    mm = MicroMesh.flat(m, rng.integers(0, 3, m.n_faces), np.tile(rng.standard_normal(3),
                                                                     (m.n_vertices, 1)))
    mm = mm.with_displacements(rng.standard_normal(mm.n_vertices) * 0.1)
    bd = tight_bounds(mm)
    t = normalized_values(mm, bd, clip=False)
    assert t.min() >= -1e-9 and t.max() <= 1 + 1e-9   # parallel directions: exact containment
    # each base vertex's bounds are tight: attained by values in its star
    top = mm.topology
    for v in rng.integers(0, m.n_vertices, 5):
        star = np.flatnonzero((m.faces == v).any(1))
        vals = np.concatenate([mm.displacements[top.face_vertices(f)] for f in star])
        assert np.isclose(bd.bias[v], vals.min()) and np.isclose(bd.bias[v] + bd.scale[v],
                                                                 vals.max())
    # positions are reproduced from the normalised values
    D, P = mm.directions, m.vertices
    rec = top.interp @ (P + D * bd.bias[:, None]) + (top.interp @ (D * bd.scale[:, None])) * \
        t[:, None]
    assert np.allclose(rec, mm.micro_vertex_positions(), atol=1e-12)


def _parallel_micromesh(seed: int) -> MicroMesh:
    """A micro-mesh on an icosphere with random levels 0-2, one random direction for every
    vertex and random displacements."""
    rng = np.random.default_rng(seed)
    m = icosphere(1)
    mm = MicroMesh.flat(m, rng.integers(0, 3, m.n_faces), np.tile(rng.standard_normal(3),
                                                                     (m.n_vertices, 1)))
    return mm.with_displacements(rng.standard_normal(mm.n_vertices) * 0.1)


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2 ** 31 - 1))
def test_lp_bounds_contain_every_value_in_a_thinner_shell(seed):
    """Under parallel directions the least-volume bounds still hold every micro-vertex
    (values in [0, 1]), their shell is no thicker than the tight bounds' and, with a bump in
    a spike near one corner of a face, far thinner (tight bounds give its height to all three
    vertices of the faces around it, the programme mostly to the corner nearest it)."""
    mm = _parallel_micromesh(seed)
    m = mm.base
    lp, tight = lp_bounds(mm), tight_bounds(mm)
    t = normalized_values(mm, lp, clip=False)
    assert t.min() >= -1e-6 and t.max() <= 1 + 1e-6
    assert micromesh_shell_volume(mm, lp) <= micromesh_shell_volume(mm, tight) * (1 + 1e-9)

    flat = MicroMesh.flat(m, 3, np.tile([0.0, 0.0, 1.0], (m.n_vertices, 1)))
    inner = flat.topology.face_vertices(0)
    weights = flat.topology.interp[inner].toarray()
    spike = inner[np.argmax(np.where((weights > 0).sum(1) == 3, weights.max(1), 0))]
    flat = flat.with_displacements(0.1 * (np.arange(flat.n_vertices) == spike))  # near a corner
    lp, tight = lp_bounds(flat), tight_bounds(flat)
    assert normalized_values(flat, lp, clip=False).max() <= 1 + 1e-6
    assert micromesh_shell_volume(flat, lp) < 0.5 * micromesh_shell_volume(flat, tight)


def test_vertex_normals_values_mostly_inside_and_clipped():
    m = icosphere(1)
    rng = np.random.default_rng(0)
    mm = MicroMesh.flat(m, 2)
    mm = mm.with_displacements(0.05 * rng.standard_normal(mm.n_vertices))
    bd = tight_bounds(mm)
    raw = normalized_values(mm, bd, clip=False)
    assert raw.min() > -0.1 and raw.max() < 1.1   # varying directions: small excursions only
    t = normalized_values(mm, bd)
    assert t.min() >= 0 and t.max() <= 1


def test_flat_mesh_min_scale_and_errors():
    m = icosphere(0)
    mm = MicroMesh.flat(m, 1)
    bd = tight_bounds(mm, min_scale=1e-3)
    assert np.allclose(bd.scale, 1e-3) and np.allclose(bd.bias, 0)
    with pytest.raises(BoundsError):
        DirectionBounds(np.zeros(3), np.zeros(4))
    with pytest.raises(BoundsError):
        normalized_values(mm, DirectionBounds(np.zeros(3), np.ones(3)))
    with pytest.raises(BoundsError):
        prismoid_volumes(m.vertices, m.faces, m.vertices[:3], bd)


def _curved_micromesh(seed: int) -> MicroMesh:
    """A micro-mesh on an icosphere with random levels 1-3, its normals as directions and
    random displacements: directions differ across every face."""
    rng = np.random.default_rng(seed)
    m = icosphere(1)
    mm = MicroMesh.flat(m, rng.integers(1, 4, m.n_faces))
    return mm.with_displacements(rng.standard_normal(mm.n_vertices) * 0.05)


def _folded_along(mm: MicroMesh, b: DirectionBounds) -> tuple[np.ndarray, np.ndarray]:
    """Per micro-vertex: where the folded lower and upper bounds, lerp(D·bias) and
    lerp(D·(bias + scale)), lie along its interpolated direction lerp(D), in its units."""
    W, D = mm.topology.interp, mm.directions
    L = W @ D
    nn = (L * L).sum(1)
    return tuple(((W @ (D * x[:, None])) * L).sum(1) / nn for x in (b.bias, b.bias + b.scale))


def _edge_terms(mm: MicroMesh, b: DirectionBounds) -> tuple[float, float]:
    """(volume term Σ w (upper − lower), smoothing term Σ c (|Δ lower| + |Δ upper|)) of the
    programmes of ``lp_bounds`` (up to the factor μ)."""
    w, length = shell_weights(mm)
    i, j = mm.base.edges.T
    unit = mm.directions / length[:, None]
    c = 0.5 * (w[i] + w[j]) * np.linalg.norm(unit[i] - unit[j], axis=1)
    up = b.bias + b.scale
    return float(w @ b.scale), float(c @ (abs(b.bias[i] - b.bias[j]) + abs(up[i] - up[j])))


@settings(max_examples=5, deadline=None)
@given(seed=st.integers(0, 2 ** 31 - 1))
def test_smoothed_least_volume_bounds(seed):
    """Smoothing (``lp_bounds(smoothing=μ)``) keeps every micro-vertex within the bounds
    as a file folds them, along its interpolated direction; a larger μ trades shell volume
    for bounds that differ less where the directions differ; under parallel directions it
    changes nothing."""
    mm = _curved_micromesh(seed)
    terms = []
    for mu in (0.0, 0.5, 2.0):
        b = lp_bounds(mm, smoothing=mu)
        low, high = _folded_along(mm, b)
        assert np.all(low <= mm.displacements + 1e-7) and np.all(high >= mm.displacements - 1e-7)
        terms.append(_edge_terms(mm, b))
    volume, smooth = np.array(terms).T
    assert np.all(np.diff(volume) >= -1e-9 * volume[0])
    assert np.all(np.diff(smooth) <= 1e-9 * smooth[0])
    assert smooth[-1] < smooth[0]

    par = _parallel_micromesh(seed)
    v0 = _edge_terms(par, lp_bounds(par))[0]
    assert np.isclose(_edge_terms(par, lp_bounds(par, smoothing=2.0))[0], v0, rtol=1e-6)


def test_smoothed_bounds_bake_more_exactly():
    """Folding bounds into the base and directions (``baked``) moves micro-vertices where
    the bounds and the directions both differ across a face; the smoothed bounds move them
    less."""
    mm = _curved_micromesh(7)

    def moved(b):
        return np.sqrt(np.mean(np.sum((baked(mm, b).micro_vertex_positions()
                                       - mm.micro_vertex_positions()) ** 2, axis=1)))

    assert moved(lp_bounds(mm, smoothing=2.0)) < 0.8 * moved(lp_bounds(mm))
