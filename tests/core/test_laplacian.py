"""Uniform/cotangent Laplacians and the screened solver (numpy, torch, autograd)."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from core.solvers.laplacian import LaplacianError, cotangent_laplacian, uniform_laplacian
from core.solvers.screened import ScreenedSolver, from_mesh


def _octahedron():
    v = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    f = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4],
                  [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    return v, f


def _bumpy(seed=0):
    """Subdivided octahedron, jittered: irregular triangles, some obtuse."""
    v, f = _octahedron()
    for _ in range(2):  # midpoint subdivision
        e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        ue, inv = np.unique(e, axis=0, return_inverse=True)
        mid = len(v) + inv.reshape(3, -1).T
        v = np.concatenate([v, v[ue].mean(1)])
        a, b, c = f.T
        ab, bc, ca = mid.T
        f = np.concatenate([np.stack(x, 1) for x in ([a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca])])
    rng = np.random.default_rng(seed)
    v = v / np.linalg.norm(v, axis=1, keepdims=True) + 0.08 * rng.normal(size=v.shape)
    return v, f


@pytest.mark.parametrize("kind", ["uniform", "cotangent"])
def test_symmetric_rows_sum_zero_psd(kind):
    v, f = _bumpy()
    L = uniform_laplacian(len(v), f) if kind == "uniform" else cotangent_laplacian(v, f)
    D = L.toarray()
    assert np.isfinite(D).all()
    assert np.abs(D - D.T).max() < 1e-12
    assert np.abs(D.sum(1)).max() < 1e-10
    w = np.linalg.eigvalsh(D)
    assert w.min() > -1e-10 and w[1] > 1e-6  # PSD, one connected component: 1-dim kernel


def test_uniform_is_degree_minus_adjacency():
    v, f = _octahedron()
    D = uniform_laplacian(6, f).toarray()
    assert np.array_equal(np.diag(D), np.full(6, 4.0))  # every octahedron vertex has 4 neighbours
    assert D[0, 1] == 0 and D[0, 2] == -1 and D[4, 5] == 0


def test_cotangent_weights_by_hand():
    # Two triangles sharing edge (0, 1): right angle at 2 (cot 0) and 60° at 3 (cot 1/√3).
    v = np.array([[0, 0, 0], [2, 0, 0], [1, 1, 0], [1, -np.sqrt(3), 0]], float)
    f = np.array([[0, 1, 2], [1, 0, 3]])
    L = cotangent_laplacian(v, f).toarray()
    assert L[0, 1] == pytest.approx(-0.5 * (0.0 + 1 / np.sqrt(3)))
    # Edge (0, 2): angle at 1 is 45° (cot 1), only one face.
    assert L[0, 2] == pytest.approx(-0.5)
    # Edge (0, 3): angle at 1 is 60°.
    assert L[0, 3] == pytest.approx(-0.5 / np.sqrt(3))
    assert L[0, 0] == pytest.approx(-(L[0, 1] + L[0, 2] + L[0, 3]))


def test_cotangent_degenerate_faces_are_finite():
    v = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0], [1, 1, 0]], float)
    f = np.array([[0, 1, 2], [0, 1, 3], [1, 4, 3], [0, 0, 1]])  # collinear face, repeated index
    L = cotangent_laplacian(v, f)
    assert np.isfinite(L.data).all()
    assert np.abs(L.toarray().sum(1)).max() < 1e-12


def test_bad_input():
    with pytest.raises(LaplacianError):
        uniform_laplacian(3, np.array([[0, 1, 3]]))
    with pytest.raises(LaplacianError):
        cotangent_laplacian(np.full((3, 3), np.nan), np.array([[0, 1, 2]]))
    v, f = _octahedron()
    with pytest.raises(LaplacianError):
        ScreenedSolver(uniform_laplacian(6, f), -1.0)
    S = ScreenedSolver(uniform_laplacian(6, f), 2.0)
    with pytest.raises(LaplacianError):
        S.solve(np.zeros(5))
    with pytest.raises(LaplacianError):
        S.solve_torch(torch.zeros(6, dtype=torch.int64))


def test_auto_uses_splu_for_small_and_cg_for_large(monkeypatch):
    import core.solvers.screened as lap

    v, f = _bumpy(1)
    assert from_mesh(len(v), f, 9.0).method == "splu"
    monkeypatch.setattr(lap, "SPLU_MAX_VERTICES", len(v) - 1)
    S = from_mesh(len(v), f, 9.0)
    assert S.method == "cg"
    b = np.random.default_rng(0).normal(size=len(v))
    ref = from_mesh(len(v), f, 9.0, method="splu").solve(b)
    assert np.abs(S.solve(b) - ref).max() < 1e-8


@pytest.mark.parametrize("method", ["splu", "cg"])
@pytest.mark.parametrize("kind", ["uniform", "cotangent"])
def test_solver_matches_dense(method, kind):
    v, f = _bumpy(1)
    S = from_mesh(len(v), f, 19.0, kind, vertices=v, method=method)
    L = uniform_laplacian(len(v), f) if kind == "uniform" else cotangent_laplacian(v, f)
    Md = np.eye(len(v)) + 19.0 * L.toarray()
    rng = np.random.default_rng(2)
    b = rng.normal(size=(len(v), 3))
    ref = np.linalg.solve(Md, b)
    assert np.abs(S.solve(b) - ref).max() < 1e-8
    assert np.abs(S.solve(b[:, 0]) - ref[:, 0]).max() < 1e-8
    x64 = S.solve_torch(torch.from_numpy(b))
    assert x64.dtype == torch.float64 and torch.allclose(x64, torch.from_numpy(ref), atol=1e-8)
    x32 = S.solve_torch(torch.from_numpy(b).float())
    assert x32.dtype == torch.float32
    assert np.abs(x32.double().numpy() - ref).max() < 1e-4 * np.abs(ref).max()
    assert np.allclose(S.multiply(ref), b) and torch.allclose(S.multiply(x64), torch.from_numpy(b))


@pytest.mark.parametrize("method", ["splu", "cg"])
def test_autograd_backward_is_dense_inverse(method):
    v, f = _bumpy(3)
    n = len(v)
    S = ScreenedSolver.from_mesh(n, f, 9.0, method=method)
    Minv = np.linalg.inv(np.eye(n) + 9.0 * uniform_laplacian(n, f).toarray())
    rng = np.random.default_rng(4)
    u = torch.tensor(rng.normal(size=(n, 3)), requires_grad=True)
    w = torch.tensor(rng.normal(size=(n, 3)))
    loss = (S.apply(u) ** 2 * w).sum()
    loss.backward()
    x = Minv @ u.detach().numpy()
    expected = Minv @ (2 * x * w.numpy())  # M symmetric: grad_u = M⁻¹ grad_x
    assert np.abs(u.grad.numpy() - expected).max() < 1e-8
    # ...and a central finite difference on one entry agrees.
    def f_(uu):
        return float(((Minv @ uu) ** 2 * w.numpy()).sum())
    e = np.zeros((n, 3))
    e[5, 1] = 1e-6
    fd = (f_(u.detach().numpy() + e) - f_(u.detach().numpy() - e)) / 2e-6
    assert u.grad[5, 1].item() == pytest.approx(fd, rel=1e-5)
    # CG: gradcheck's fast mode (one random projection of the Jacobian, ~2 solves instead of
    # 2n); thousands of tiny torch ops per full check crawl when the 2 cores are contended.
    assert torch.autograd.gradcheck(lambda t: S.apply(t), (torch.tensor(rng.normal(size=(n,)), requires_grad=True),),
                                    eps=1e-6, atol=1e-6, nondet_tol=1e-9, fast_mode=method == "cg")


def test_cg_warm_start_reduces_iterations():
    v, f = _bumpy(5)
    S = ScreenedSolver.from_mesh(len(v), f, 19.0, method="cg")
    b = torch.tensor(np.random.default_rng(6).normal(size=(len(v), 3)))
    S.solve_torch(b)
    cold = S.last_iterations
    S.solve_torch(b * (1 + 1e-9))
    assert S.last_iterations < cold
