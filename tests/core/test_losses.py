"""L_sv, L_iso and the Laplacian smoothing term: values and finite-difference gradients."""
import numpy as np
import pytest
import scipy.sparse as sp
import torch

from core.construct.losses import (isotropy_loss, laplacian_smoothing_loss, mean_edge_length,
                                   scipy_to_torch_sparse, shell_range_loss, shell_volume_loss,
                                   vertex_groups)

TET_V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
TET_F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


def _fd_check(fn, x, eps=1e-6, tol=1e-5):
    x = x.clone().double().requires_grad_(True)
    fn(x).backward()
    g = x.grad.clone()
    flat = x.detach().clone().reshape(-1)
    num = torch.zeros_like(flat)
    for i in range(len(flat)):
        p, m = flat.clone(), flat.clone()
        p[i] += eps
        m[i] -= eps
        num[i] = (fn(p.reshape(x.shape)) - fn(m.reshape(x.shape))) / (2 * eps)
    assert torch.allclose(g.reshape(-1), num, atol=tol, rtol=1e-4)


def test_isotropy_zero_for_equilateral_and_value_by_hand():
    eq = torch.tensor([[0, 0, 0], [1, 0, 0], [0.5, np.sqrt(3) / 2, 0]], dtype=torch.float64)
    f = torch.tensor([[0, 1, 2]])
    assert float(isotropy_loss(eq, f)) == pytest.approx(0.0, abs=1e-12)
    rt = torch.tensor([[0, 0, 0], [3, 0, 0], [0, 4, 0]], dtype=torch.float64)  # lengths 3, 5, 4
    assert float(isotropy_loss(rt, f)) == pytest.approx(np.var([3, 5, 4]))
    assert float(isotropy_loss(rt * 2, f, h=2.0)) == pytest.approx(np.var([3, 5, 4]))  # scale-free


def test_isotropy_gradient_fd():
    rng = np.random.default_rng(0)
    v = torch.tensor(TET_V + 0.1 * rng.standard_normal(TET_V.shape))
    f = torch.tensor(TET_F)
    _fd_check(lambda x: isotropy_loss(x, f, h=0.7), v)


def _groups_single_level():
    # Base = tetrahedron at "level 0": each base face's micro-vertices are its corners.
    ptr = np.arange(0, 3 * len(TET_F) + 1, 3)
    idx = TET_F.reshape(-1)
    return vertex_groups(TET_F, 4, ptr, idx, 4)


def test_shell_volume_by_hand():
    g = _groups_single_level()
    d = torch.tensor([0.0, 1.0, 2.0, 3.0], dtype=torch.float64)
    # Every base vertex of a tetrahedron sees all four vertices: variance of 0..3 = 1.25.
    assert float(shell_volume_loss(d, g)) == pytest.approx(1.25)
    assert float(shell_volume_loss(d, g, h=0.5)) == pytest.approx(5.0)
    assert float(shell_volume_loss(torch.full((4,), 7.0, dtype=torch.float64), g)) == pytest.approx(0)


def test_shell_volume_groups_dedupe_and_fd():
    # Two triangles sharing an edge; face 0 has micro-vertices {0,1,2,4}, face 1 {1,3,2,4}.
    faces = np.array([[0, 1, 2], [1, 3, 2]])
    ptr = np.array([0, 4, 8])
    idx = np.array([0, 1, 2, 4, 1, 3, 2, 4])
    g = vertex_groups(faces, 4, ptr, idx, 5)
    assert g.count.tolist() == [4, 5, 5, 4]
    d = torch.tensor([0.3, -0.1, 0.2, 0.5, 0.0], dtype=torch.float64)
    expect = np.mean([np.var([0.3, -0.1, 0.2, 0.0]), np.var([0.3, -0.1, 0.2, 0.5, 0.0]),
                      np.var([0.3, -0.1, 0.2, 0.5, 0.0]), np.var([-0.1, 0.5, 0.2, 0.0])])
    assert float(shell_volume_loss(d, g)) == pytest.approx(expect)
    _fd_check(lambda x: shell_volume_loss(x, g, h=0.3), d)


def test_laplacian_smoothing_value_and_fd():
    L = sp.csr_matrix(np.array([[1, -1, 0], [-1, 2, -1], [0, -1, 1]], float))
    Lt = scipy_to_torch_sparse(L, dtype=torch.float64)
    x = torch.tensor([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]], dtype=torch.float64)
    assert float(laplacian_smoothing_loss(x, Lt)) == pytest.approx(2.0 / 3.0)  # rows -1, 0, 1
    x2 = torch.tensor([[0.0, 0, 0], [1, 1, 0], [2, 0, 0]], dtype=torch.float64)
    _fd_check(lambda y: laplacian_smoothing_loss(y, Lt, h=2.0), x2)


def test_mean_edge_length():
    f = np.array([[0, 1, 2]])
    v = np.array([[0, 0, 0], [3, 0, 0], [0, 4, 0]], float)
    assert mean_edge_length(v, f) == pytest.approx(4.0)


def test_shell_range_equals_tight_bounds_scale_and_fd():
    """The range term is the mean scale of core.micro.bounds.tight_bounds (the metric's shell), and
    its gradient (away from ties) matches finite differences."""
    from core.micro.bounds import tight_bounds
    from core.mesh.trimesh import TriMesh
    from core.micro.micromesh import MicroMesh

    mm = MicroMesh.flat(TriMesh(TET_V, TET_F), np.array([2, 1, 2, 2]))
    rng = np.random.default_rng(1)
    d = rng.standard_normal(mm.n_vertices)
    t = mm.topology
    g = vertex_groups(TET_F, 4, t.face_vertex_ptr, t.face_vertex_idx, t.n_vertices)
    want = tight_bounds(mm.with_displacements(d)).scale.mean()
    assert float(shell_range_loss(torch.tensor(d), g)) == pytest.approx(want)
    assert float(shell_range_loss(torch.tensor(d) * 3, g, h=3.0)) == pytest.approx(want)
    _fd_check(lambda x: shell_range_loss(x, g, h=0.5), torch.tensor(d), eps=1e-7)


def test_shell_terms_gradients_do_not_depend_on_memory_layout():
    """Bitwise-equal gradients for the same displacements at different buffer offsets, on all
    cores and with more pairs than torch's parallel grain: the construction's
    reproducibility rests on it (advanced indexing's backward failed this)."""
    from core.mesh.trimesh import TriMesh
    from core.micro.micromesh import MicroMesh
    from core.mesh.primitives import icosphere
    from core.runtime.threads import default_threads, set_threads

    v, f = icosphere(4)
    mm = MicroMesh.flat(TriMesh(v, f), np.full(len(f), 3))
    t = mm.topology
    g = vertex_groups(f, len(v), t.face_vertex_ptr, t.face_vertex_idx, t.n_vertices)
    assert len(g.member) > 32768
    d = np.random.default_rng(0).standard_normal(t.n_vertices).astype(np.float32)
    before = torch.get_num_threads()
    set_threads(default_threads())
    try:
        for loss in (shell_volume_loss, shell_range_loss):
            grads = []
            for off in range(8):
                buf = np.empty(len(d) + 8, np.float32)
                buf[off:off + len(d)] = d
                x = torch.from_numpy(buf[off:off + len(d)]).requires_grad_(True)
                loss(x, g).backward()
                grads.append(x.grad.clone())
            assert all(torch.equal(grads[0], gr) for gr in grads[1:]), loss.__name__
    finally:
        set_threads(before)
