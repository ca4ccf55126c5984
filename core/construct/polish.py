"""Polishing: the folded micro-mesh's values refined against the images.

The fit is geometric (least squares to reference samples); what a renderer shows is the
micro-facets' shading. After the bounds are folded, ``s.polish_steps`` more optimiser steps
move each micro-vertex along its direction to lower the training's image loss (L1 of the
``s.shading`` renders of a batch of the training views, at the metrics' resolution), with
the optimiser's step size and smoothing (``lr_disp``, ``lambda_micro``). The values stay
within the folded bounds (t in [0, 1]): the shell cannot grow. The result is kept where the
metrics' image error (``scene.image_error``) falls.
"""
from __future__ import annotations

import time

import numpy as np
import torch

from ..solvers.laplacian import uniform_laplacian
from ..micro.micromesh import MicroMesh
from ..solvers.optim import Reparameterized, UniformAdam
from ..render import render
from ..solvers.screened import ScreenedSolver
from .scene import image_error
from .state import RunState


def polished(run: RunState, mm: MicroMesh, before: float | None = None) -> MicroMesh:
    """``mm`` (bounds folded: every value t in [0, 1]) after the polishing steps, or ``mm``
    where they do not lower the metrics' image error (``before``: mm's, where the caller has
    measured it, as the bounds' tries have). Polishing takes what is left before
    ``run.deadline``: none past it (the largest inputs), and a step after the first that
    would end past it is left out. ``run.notes["polish"]`` says what happened."""
    s = run.s
    began = time.perf_counter()
    if began >= run.deadline:
        run.notes["polish"] = {"steps": 0, "kept": False, "cut_by_time_limit": True}
        return mm
    if before is None:
        before = image_error(mm, run.scene, s)
    move = _Move(mm, s, run.scene.device)
    cams = run.scene.cams.at_resolution(s.eval_resolution)
    target = run.scene.images(cams)
    rng = np.random.default_rng(s.seed + 1)
    views = min(s.views_per_iter, len(cams))
    note: dict = {"steps": 0, "image_error_before": float(before)}
    for n in range(s.polish_steps):
        run.check_stop()
        now = time.perf_counter()
        if n and now + (now - began) / n > run.deadline:
            note["cut_by_time_limit"] = True
            break
        idx = np.sort(rng.choice(len(cams), views, replace=False))
        move.step(lambda X: (render(X, move.T, cams.subset(idx), kind=s.shading,
                                    antialias=s.antialias) - target[idx]).abs().mean())
        note["steps"] = n + 1
    out = move.micromesh()
    after = image_error(out, run.scene, s)
    keep = bool(after < before)
    note.update(image_error_after=float(after), kept=keep, time_s=time.perf_counter() - began)
    run.notes["polish"] = note
    return out if keep else mm


class _Move:
    """Each micro-vertex's move along its unit direction (unit-frame length), held as
    (I + λL) of it and stepped by Uniform Adam, clamped to the folded bounds after each
    step."""

    def __init__(self, mm: MicroMesh, s, device) -> None:
        self.mm = mm
        self.t0 = np.asarray(mm.displacements, dtype=np.float64)
        d = mm.micro_vertex_directions()
        self.length = np.maximum(np.linalg.norm(d, axis=1), 1e-12)
        self.lo, self.hi = -self.t0 * self.length, (1.0 - self.t0) * self.length
        topo = mm.topology
        solver = ScreenedSolver(uniform_laplacian(topo.n_vertices, topo.triangles),
                                s.lambda_micro) if s.reparameterize else None
        self.value = Reparameterized(np.zeros(topo.n_vertices), solver, device=device)
        self.opt = UniformAdam([self.value.param], lr=s.lr_disp, betas=s.betas)

        def f32(a):
            return torch.as_tensor(a, dtype=torch.float32, device=device)

        self.U = f32(d / self.length[:, None])
        self.X0 = f32(mm.micro_vertex_base_positions()) + self.U * f32(self.t0 * self.length)[:, None]
        self.T = torch.as_tensor(topo.triangles, dtype=torch.int64, device=device)
        self.bounds = f32(self.lo), f32(self.hi)

    def step(self, loss) -> None:
        """One optimiser step on ``loss(X)`` of the micro-vertex positions X (n, 3)."""
        self.opt.zero_grad(set_to_none=True)
        loss(self.X0 + self.U * self.value.value()[:, None]).backward()
        self.opt.step()
        with torch.no_grad():
            m = torch.minimum(torch.maximum(self.value.value(), self.bounds[0]), self.bounds[1])
            self.value.param.copy_(torch.as_tensor(self.value.encode(m.double().cpu().numpy()),
                                                   dtype=self.value.param.dtype,
                                                   device=self.value.param.device))

    def micromesh(self) -> MicroMesh:
        m = np.clip(self.value.numpy(), self.lo, self.hi)
        return self.mm.with_displacements(np.clip(self.t0 + m / self.length, 0.0, 1.0))
