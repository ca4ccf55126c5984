"""Least-squares fitting of displacements: closer to the reference than projection baking,
exact where the reference is reachable, smoother with more smoothness."""
import numpy as np
import pytest

from core.mesh import primitives
from core.spatial.bake import bake_displacements
from core.spatial.closest import ClosestPointIndex
from core.fit import (FitError, fit_displacements, fit_micromesh, fit_samples, normal_equations,
                      reference_samples, surface_errors)
from core.solvers.laplacian import uniform_laplacian
from core.mesh.trimesh import TriMesh
from core.micro.micromesh import MicroMesh
from core.micro.levels import balance_levels


def mean_distance(reference: TriMesh, mm: MicroMesh) -> float:
    """Area-weighted mean distance from dense reference samples to the micro-surface."""
    pts, _, w = reference_samples(reference).arrays()
    t = mm.tessellate()
    _, _, d = ClosestPointIndex(t.vertices, t.triangles).query(pts)
    return float((d * w).sum() / w.sum())


@pytest.fixture(scope="module")
def bumpy():
    v, f = primitives.noisy_sphere(30000, amplitude=0.06, seed=2)
    ref = TriMesh(v, f)
    bv, bf = primitives.icosphere(4)
    mm = MicroMesh.flat(TriMesh(bv, bf), np.full(len(bf), 2))
    baked = bake_displacements(mm.micro_vertex_base_positions(), mm.micro_vertex_directions(),
                               ref, max_distance=0.5).displacement
    return ref, mm.with_displacements(baked)


def test_fit_is_closer_than_baking(bumpy):
    ref, baked = bumpy
    fitted = baked.with_displacements(fit_displacements(baked, ref))
    before, after = mean_distance(ref, baked), mean_distance(ref, fitted)
    assert after < 0.85 * before, (before, after)


def test_fit_reproduces_a_reachable_surface():
    """The reference is itself a displaced micro-mesh of the base: the fit finds it again."""
    bv, bf = primitives.icosphere(3)
    mm = MicroMesh.flat(TriMesh(bv, bf), np.full(len(bf), 2))
    rng = np.random.default_rng(0)
    truth = 0.01 * rng.standard_normal(mm.n_vertices)
    ref = mm.with_displacements(truth).tessellate().to_trimesh()
    got = fit_displacements(mm.with_displacements(np.zeros(mm.n_vertices)), ref,
                            smoothness=0.0, iterations=3)
    np.testing.assert_allclose(got, truth, atol=1e-4)


def test_smoothness_smooths(bumpy):
    ref, baked = bumpy
    L = uniform_laplacian(baked.n_vertices, baked.topology.triangles)
    rough = fit_displacements(baked, ref, smoothness=0.0)
    smoother = [np.linalg.norm(L @ fit_displacements(baked, ref, smoothness=w)) for w in (1.0, 30.0)]
    assert np.linalg.norm(L @ rough) > smoother[0] > 1.5 * smoother[1]


def test_slopes_bring_the_shading_normals_closer(bumpy):
    """The slope term trades a little distance for micro-triangles that lie in the
    reference's tangent planes: the squared normal differences (what flat shading shows) fall,
    and more weight lowers them further."""
    ref, baked = bumpy
    samples = fit_samples(baked, ref)
    errors = [surface_errors(baked.with_displacements(
        fit_displacements(baked, ref, samples=samples, slopes=w)), samples)
        for w in (0.0, 0.1, 1.0)]
    normal = [e[1].sum() for e in errors]
    assert normal[0] > 1.02 * normal[1] > 1.02 * normal[2], normal
    distance = [e[0].sum() for e in errors]
    assert distance[1] < 1.5 * distance[0], distance


def test_moving_the_base_too_brings_the_surface_closer(bumpy):
    """With the base vertices as unknowns (held by a stiffness) the fit reaches what one
    displacement per micro-vertex cannot: lower distance and normal errors than the
    displacements alone, with base vertices that move a little and stay well shaped; with
    no stiffness to speak of they are where the displacements-only fit leaves them."""
    from core.micro.metrics import triangle_isotropy

    ref, baked = bumpy
    samples = fit_samples(baked, ref)
    alone = baked.with_displacements(fit_displacements(baked, ref, samples=samples))
    joint = fit_micromesh(baked, ref, samples=samples, base_stiffness=1e-3)
    e_alone, e_joint = surface_errors(alone, samples), surface_errors(joint, samples)
    assert e_joint[0].sum() < 0.97 * e_alone[0].sum(), (e_joint[0].sum(), e_alone[0].sum())
    assert e_joint[1].sum() < e_alone[1].sum()
    move = np.linalg.norm(joint.base.vertices - baked.base.vertices, axis=1)
    edge = np.sqrt(baked.base.face_areas.mean())
    assert 1e-4 * edge < move.max() < 0.5 * edge
    q0 = triangle_isotropy(baked.base.vertices, baked.base.faces)[0].mean()
    q1 = triangle_isotropy(joint.base.vertices, joint.base.faces)[0].mean()
    assert q1 > q0 - 0.01
    stiff = fit_micromesh(baked, ref, samples=samples, base_stiffness=1e6)
    assert np.abs(stiff.base.vertices - baked.base.vertices).max() < 1e-6 * edge
    np.testing.assert_allclose(stiff.displacements, alone.displacements, atol=1e-3 * edge)


def test_fixed_base_vertices_stay_exactly_where_they_are(bumpy):
    """The base round with some base vertices fixed: those keep their positions bit for bit,
    the others move as before, and the fit is no worse than with every vertex fixed."""
    ref, baked = bumpy
    samples = fit_samples(baked, ref)
    free = fit_micromesh(baked, ref, samples=samples, base_stiffness=1e-3)
    moved = np.linalg.norm(free.base.vertices - baked.base.vertices, axis=1)
    fixed = moved > np.median(moved)                  # the half that moves most
    held = fit_micromesh(baked, ref, samples=samples, base_stiffness=1e-3, fixed_base=fixed)
    assert np.array_equal(held.base.vertices[fixed], baked.base.vertices[fixed])
    assert (np.linalg.norm(held.base.vertices - baked.base.vertices, axis=1)[~fixed] > 0).any()
    alone = baked.with_displacements(fit_displacements(baked, ref, samples=samples))
    assert surface_errors(held, samples)[0].sum() < surface_errors(alone, samples)[0].sum()


@pytest.mark.parametrize("mixed", [False, True])
def test_the_compiled_systems_are_the_rows_system(bumpy, mixed):
    """The rounds sum their normal equations in compiled passes (per micro-triangle; with the
    base also per micro-vertex and base face): the same least squares as the rows' sparse
    products, over the displacements alone and with the base vertices (moved by some offsets
    already), on uniform and on mixed levels (micro-vertices on edges between levels)."""
    ref, baked = bumpy
    if mixed:
        levels = np.where(np.arange(baked.base.n_faces) % 3 == 0, 3, 2)
        mm = MicroMesh.flat(baked.base, balance_levels(baked.base, levels))
        baked = mm.with_displacements(bake_displacements(
            mm.micro_vertex_base_positions(), mm.micro_vertex_directions(), ref,
            max_distance=0.5).displacement)
    samples = fit_samples(baked, ref)
    n, nb = baked.n_vertices, baked.base.n_vertices
    offsets = 0.01 * np.random.default_rng(4).standard_normal((nb, 3))
    for slopes in (0.0, 0.1):
        M, b = normal_equations(baked, baked.displacements, samples, 1e-3, slopes)
        Mr, br = normal_equations(baked, baked.displacements, samples, 1e-3, slopes,
                                  by_rows=True, chunk=5000)
        scale = abs(M).max()
        assert abs(M - Mr).max() < 1e-12 * scale
        np.testing.assert_allclose(b, br, rtol=0, atol=1e-12 * abs(b).max())
        assert M.shape == (n, n) and abs(M - M.T).max() < 1e-12 * scale
        Mj, bj = normal_equations(baked, baked.displacements, samples, 1e-3, slopes,
                                  base_stiffness=1e-3, offsets=offsets)
        Mjr, bjr = normal_equations(baked, baked.displacements, samples, 1e-3, slopes,
                                    base_stiffness=1e-3, offsets=offsets, by_rows=True,
                                    chunk=5000)
        scale = abs(Mjr).max()
        assert Mj.shape == (n + 3 * nb, n + 3 * nb)
        assert abs(Mj - Mjr).max() < 1e-12 * scale and abs(Mj - Mj.T).max() < 1e-12 * scale
        np.testing.assert_allclose(bj, bjr, rtol=0, atol=1e-12 * abs(bjr).max())


def test_micro_vertices_no_sample_holds_are_kept_where_they_are(bumpy):
    """A micro-vertex no sample holds (here the lower half of a sphere fitted to the upper
    half of the reference) is kept, weakly, at its displacement; the held ones are not; the
    base's round is left as it was."""
    import scipy.sparse as sp

    from core.fit.system import _KEEP

    ref, baked = bumpy
    top = ref.vertices[ref.faces].mean(1)[:, 2] > 0.2
    cap = TriMesh(ref.vertices, ref.faces[top])
    samples = fit_samples(baked, cap)
    d = baked.displacements
    M, b = normal_equations(baked, d, samples, 0.0, 0.1)
    plain, b_plain = normal_equations(baked, d, samples, 0.0, 0.1, by_rows=True)  # no keeping
    held = plain.diagonal() - 1e-9              # the samples' share (the system adds 1e-9 I)
    firm = np.median(held[held > 0])
    extra = (M - plain).diagonal()
    kept = np.flatnonzero(extra > 0.5 * _KEEP * firm)
    z = baked.micro_vertex_positions()[:, 2]
    assert (z[kept] < 0.3).all() and np.isin(np.flatnonzero(z < -0.2), kept).all()
    np.testing.assert_allclose(extra[kept], _KEEP * firm, rtol=1e-9)
    np.testing.assert_allclose((b - b_plain)[kept], _KEEP * firm * d[kept], rtol=1e-6)
    rest = M - plain - sp.diags(np.where(extra > 0.5 * _KEEP * firm, extra, 0.0))
    assert abs(rest).max() < 1e-9 * abs(M).max()
    joint, _ = normal_equations(baked, d, samples, 0.0, 0.1, base_stiffness=1e-3)
    joint_rows, _ = normal_equations(baked, d, samples, 0.0, 0.1, base_stiffness=1e-3,
                                     by_rows=True)
    assert abs(joint - joint_rows).max() < 1e-9 * abs(joint).max()


def _tilted(mm: MicroMesh, degrees: float, seed: int = 0) -> MicroMesh:
    """``mm`` with each base direction turned by ``degrees`` about a random tangent axis."""
    rng = np.random.default_rng(seed)
    D = mm.directions / np.linalg.norm(mm.directions, axis=1, keepdims=True)
    t = np.cross(D, rng.standard_normal(D.shape))
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    a = np.radians(degrees)
    return mm.with_directions(np.cos(a) * D + np.sin(a) * t)


def test_turning_the_directions_reaches_what_one_displacement_cannot(bumpy):
    """Directions tilted off the surface's normals, displacements fitted under them: the
    direction round lowers the distance and the shading error and turns the directions back
    towards the normals; a tiny damping turns them further, a huge one not at all (then it is
    a displacements' round)."""
    from core.fit import fit_directions

    ref, baked = bumpy
    samples = fit_samples(baked, ref)
    tilted = _tilted(baked, 25.0)
    tilted = tilted.with_displacements(fit_displacements(tilted, ref, samples=samples))
    normals = baked.directions / np.linalg.norm(baked.directions, axis=1, keepdims=True)

    def off(mm):            # mean angle of the directions from the normals, degrees
        D = mm.directions / np.linalg.norm(mm.directions, axis=1, keepdims=True)
        return float(np.degrees(np.arccos(np.clip((D * normals).sum(1), -1, 1))).mean())

    turned = fit_directions(tilted, samples)
    e0, e1 = surface_errors(tilted, samples), surface_errors(turned, samples)
    assert e1[0].sum() < 0.97 * e0[0].sum(), (e0[0].sum(), e1[0].sum())
    assert e1[1].sum() < 0.99 * e0[1].sum(), (e0[1].sum(), e1[1].sum())
    assert off(turned) < off(tilted) - 1.0, (off(tilted), off(turned))
    assert off(fit_directions(tilted, samples, damping=0.05)) < off(turned)
    held = fit_directions(tilted, samples, damping=1e9)
    np.testing.assert_allclose(held.directions, tilted.directions, atol=1e-6)


def test_a_direction_that_would_widen_the_shell_is_put_back(bumpy, monkeypatch):
    """Where a turned direction's micro-vertices span more length along it than before
    (times ``WIDENING``), the direction is put back: with no widening allowed, every one."""
    import core.fit.directions as dirs

    ref, baked = bumpy
    samples = fit_samples(baked, ref)
    tilted = _tilted(baked, 25.0)
    tilted = tilted.with_displacements(fit_displacements(tilted, ref, samples=samples))
    turned = dirs.fit_directions(tilted, samples)
    assert (np.abs(turned.directions - tilted.directions).max(1) > 0).mean() > 0.5
    monkeypatch.setattr(dirs, "WIDENING", 0.0)
    kept = dirs.fit_directions(tilted, samples)
    np.testing.assert_array_equal(kept.directions, tilted.directions)


def test_turning_the_directions_holds_what_no_sample_holds(bumpy):
    """The lower half of a sphere fitted to the upper half of the reference: no sample holds
    its micro-vertices, and turning the directions leaves them where they were (without the
    hold they swing)."""
    from core.fit import fit_directions

    ref, baked = bumpy
    top = ref.vertices[ref.faces].mean(1)[:, 2] > 0.2
    samples = fit_samples(baked, TriMesh(ref.vertices, ref.faces[top]))
    tilted = _tilted(baked, 25.0)
    low = np.flatnonzero(tilted.micro_vertex_positions()[:, 2] < -0.4)
    X0 = tilted.micro_vertex_positions()[low]
    moved = [np.abs(fit_directions(tilted, samples, hold=h).micro_vertex_positions()[low]
                    - X0).max() for h in (0.03, 0.0)]
    edge = np.sqrt(baked.base.face_areas.mean())
    assert moved[0] < 0.01 * edge and moved[1] > 0.1 * edge, moved


def test_samples_made_a_run_of_faces_at_a_time_sum_the_same_system(bumpy):
    """The samples are made in chunks (whole faces of one level), in one order whatever the
    chunk size; the fit's sums over them, chunk by chunk, are the same bits as in one go."""
    ref, baked = bumpy
    samples = reference_samples(ref, sample_area=0.2 * ref.face_areas.mean())
    assert len(np.unique(samples.level)) > 1                 # mixed levels, several groups
    pts, normals, w = samples.arrays()
    small = list(samples.chunks(7))
    assert len(small) > 10 and small[0][0].start == 0 and small[-1][0].stop == len(samples)
    np.testing.assert_array_equal(np.concatenate([p for _, p, _, _ in small]), pts)
    np.testing.assert_array_equal(np.concatenate([n for _, _, n, _ in small]), normals)
    assert np.isclose(w.sum(), len(w)) and len(w) == len(samples)
    faces = ref.faces[np.flatnonzero(samples.level == samples.level.min())[0]]
    assert np.allclose(pts[:4].mean(0), ref.vertices[faces].mean(0))   # centroids of the face
    for stiffness in (0.0, 1e-3):
        M, b = normal_equations(baked, baked.displacements, samples, 1e-3, 0.1,
                                base_stiffness=stiffness)
        Mc, bc = normal_equations(baked, baked.displacements, samples, 1e-3, 0.1,
                                  base_stiffness=stiffness, chunk=50)
        assert (M != Mc).nnz == 0 and np.array_equal(b, bc)
    e, ec = surface_errors(baked, samples), surface_errors(baked, samples, chunk=50)
    np.testing.assert_allclose(e[0], ec[0], rtol=1e-12)
    np.testing.assert_allclose(e[1], ec[1], rtol=1e-12)


def test_bad_settings(bumpy):
    ref, baked = bumpy
    with pytest.raises(FitError):
        fit_displacements(baked, ref, smoothness=-1)
    with pytest.raises(FitError):
        fit_displacements(baked, ref, density=0)
    with pytest.raises(FitError):
        fit_displacements(baked, ref, slopes=-0.1)
    with pytest.raises(FitError):
        fit_micromesh(baked, ref, base_stiffness=-1.0)
    with pytest.raises(FitError):
        reference_samples(ref, sample_area=0.0)


def _roof() -> TriMesh:
    """A V-shaped roof of four big triangles, crease along x = 0.5."""
    v = np.array([[0, 0, .2], [.5, 0, 0], [1, 0, .2], [0, 1, .2], [.5, 1, 0], [1, 1, .2]], float)
    return TriMesh(v, np.array([[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4]]))


def test_large_reference_faces_are_sampled_densely():
    """A crease between big flat faces (as CAD exports them) crossing a base face: with
    samples as dense as the micro-triangles the fit follows it; four samples per reference
    face leave most micro-vertices to the smoothness term, which rounds it off."""
    ref = _roof()
    pts, _, w = reference_samples(ref, sample_area=1e-3).arrays()
    assert len(pts) >= 1000 and np.isclose(w.sum(), len(w))
    bv = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    mm = MicroMesh.flat(TriMesh(bv, np.array([[0, 1, 2], [0, 2, 3]])), np.array([4, 4]))
    mm = mm.with_displacements(np.zeros(mm.n_vertices))
    dense = mm.with_displacements(fit_displacements(mm, ref, iterations=3))
    sparse = mm.with_displacements(fit_displacements(mm, ref, iterations=3,
                                                     samples=reference_samples(ref)))
    X = dense.tessellate().vertices
    truth = 0.4 * np.abs(X[:, 0] - 0.5)
    err_dense = np.abs(X[:, 2] - truth).max()
    Xs = sparse.tessellate().vertices
    err_sparse = np.abs(Xs[:, 2] - 0.4 * np.abs(Xs[:, 0] - 0.5)).max()
    assert err_dense < 0.01 and err_sparse > 2 * err_dense, (err_dense, err_sparse)


def test_the_solve_matches_a_factorisation_and_falls_back_to_one_or_stops_early():
    """CG from a start point gives the factorisation's answer; where it cannot converge in
    the iterations allowed, the factorisation's answer is returned, or, if asked, its last
    iterate."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    from core.fit import solve_normal_equations

    bv, bf = primitives.icosphere(4)
    L = uniform_laplacian(len(bv), bf)
    M = (sp.eye(len(bv)) * 1e-3 + L.T @ L).tocsr()
    b = np.random.default_rng(0).standard_normal(len(bv))
    exact = spla.spsolve(M.tocsc(), b)
    got = solve_normal_equations(M, b, np.zeros(len(bv)))
    np.testing.assert_allclose(got, exact, rtol=1e-6, atol=1e-8 * np.abs(exact).max())
    steps = []
    short = solve_normal_equations(M, b, np.zeros(len(bv)), maxiter=2,
                                   callback=lambda _: steps.append(1))
    assert len(steps) == 2
    np.testing.assert_allclose(short, exact, rtol=1e-9, atol=1e-12 * np.abs(exact).max())
    # exact=False: the iterate after maxiter steps, not the factorisation's answer, and a
    # better one than the start by the system's energy ½xᵀMx − bᵀx.
    partial = solve_normal_equations(M, b, np.zeros(len(bv)), maxiter=2, exact=False)
    energy = lambda x: 0.5 * x @ (M @ x) - b @ x  # noqa: E731
    assert np.abs(partial - exact).max() > 1e-3 * np.abs(exact).max()
    assert energy(exact) <= energy(partial) < energy(np.zeros(len(bv)))
