"""Uniform Adam, gradient clipping and the Large Steps reparameterisation (supplement Eq. 2)."""
import numpy as np
import pytest
import torch

from core.solvers.laplacian import uniform_laplacian
from core.solvers.screened import ScreenedSolver
from core.solvers.optim import Reparameterized, UniformAdam, clip_gradients

TET_F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


def _octa():
    v = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    f = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    return v, f


def test_reparameterised_sgd_step_is_closed_form_preconditioning():
    v, f = _octa()
    lam, eta = 9.0, 0.05
    L = uniform_laplacian(len(v), f)
    M = np.eye(len(v)) + lam * L.toarray()
    rng = np.random.default_rng(1)
    d0 = rng.standard_normal(len(v))
    target = rng.standard_normal(len(v))
    rp = Reparameterized(d0, ScreenedSolver(L, lam), dtype=torch.float64)
    assert np.allclose(rp.numpy(), d0)
    x = rp.value()
    loss = 0.5 * ((x - torch.as_tensor(target)) ** 2).sum() + (x ** 3).sum()
    loss.backward()
    g = (d0 - target) + 3 * d0 ** 2                      # ∂Φ/∂D at d0
    with torch.no_grad():
        rp.param -= eta * rp.param.grad                   # plain gradient step on D̄
    closed = d0 - eta * np.linalg.solve(M, np.linalg.solve(M, g))   # Eq. 2
    assert np.allclose(rp.numpy(), closed, atol=1e-10)


def test_identity_without_solver():
    rp = Reparameterized(np.array([1.0, 2.0]), None, dtype=torch.float64)
    assert rp.value() is rp.param
    assert np.allclose(rp.numpy(), [1, 2])


def test_uniform_adam_first_step_and_uniform_scaling():
    p = torch.nn.Parameter(torch.tensor([1.0, -2.0, 4.0], dtype=torch.float64))
    opt = UniformAdam([p], lr=0.1, eps=0.0)
    p.grad = torch.tensor([0.5, -1.0, 2.0], dtype=torch.float64)
    opt.step()
    # m̂ = g, v̂ = g², denom = max|g| = 2: the step keeps the gradient's shape (not sign(g)).
    assert torch.allclose(p.detach(), torch.tensor([1 - 0.025, -2 + 0.05, 4 - 0.1], dtype=torch.float64))


def test_uniform_adam_matches_reference_recursion():
    torch.manual_seed(0)
    p = torch.nn.Parameter(torch.zeros(5, dtype=torch.float64))
    opt = UniformAdam([p], lr=0.01, betas=(0.8, 0.9), eps=1e-8)
    m = np.zeros(5); v = np.zeros(5); x = np.zeros(5)
    for t in range(1, 6):
        g = np.sin(np.arange(5) * t + 1.0)
        p.grad = torch.tensor(g)
        opt.step()
        m = 0.8 * m + 0.2 * g
        v = 0.9 * v + 0.1 * g * g
        x -= 0.01 / (1 - 0.8 ** t) * m / (np.sqrt(v.max() / (1 - 0.9 ** t)) + 1e-8)
    assert np.allclose(p.detach().numpy(), x)
    opt.reset_state(p)
    assert p not in opt.state


def test_clip_gradients():
    a = torch.nn.Parameter(torch.zeros(2))
    b = torch.nn.Parameter(torch.zeros(2))
    a.grad = torch.tensor([3.0, 4.0])
    b.grad = torch.tensor([0.3, 0.4])
    worst = clip_gradients([a, b], 1.0)
    assert worst == pytest.approx(5.0)
    assert torch.allclose(a.grad, torch.tensor([0.6, 0.8]))
    assert torch.allclose(b.grad, torch.tensor([0.3, 0.4]))
    a.grad = torch.tensor([float("nan"), 1.0])
    clip_gradients([a], 10.0)
    assert torch.isfinite(a.grad).all()


def test_uniform_adam_rejects_bad_lr():
    with pytest.raises(ValueError):
        UniformAdam([torch.nn.Parameter(torch.zeros(1))], lr=0.0)


def test_uniform_adam_groups_keep_their_own_rates():
    a = torch.nn.Parameter(torch.zeros(2, dtype=torch.float64))
    b = torch.nn.Parameter(torch.zeros(2, dtype=torch.float64))
    opt = UniformAdam([{"params": [a], "lr": 0.1}, {"params": [b], "lr": 0.2}], lr=0.5)
    for p in (a, b):
        p.grad = torch.tensor([1.0, -1.0], dtype=torch.float64)
    opt.step()
    assert torch.allclose(b.detach(), 2 * a.detach()) and float(a.detach()[0]) < 0
    opt.zero_grad(set_to_none=True)
    assert a.grad is None and b.grad is None


@pytest.mark.slow
def test_uniform_adam_leaves_torchs_graph_compiler_unimported():
    """torch.optim.Optimizer's constructor imports torch._dynamo (about a second before a
    construction's first iteration); UniformAdam does without it."""
    import subprocess
    import sys
    from pathlib import Path

    code = ("import sys, torch; sys.path.insert(0, sys.argv[1]); from core.solvers.optim import "
            "UniformAdam; p = torch.nn.Parameter(torch.ones(3)); o = UniformAdam([p]); "
            "p.grad = torch.ones(3); o.step(); print('torch._dynamo' in sys.modules)")
    r = subprocess.run([sys.executable, "-c", code, str(Path(__file__).resolve().parents[2])],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split()[-1] == "False"

