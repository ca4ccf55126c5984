"""The optimiser (method §3–§5): one iteration (render a batch of views, the losses, one
step) and the loop (per iteration the subdivisions the schedule has due, with their level of
detail, then one step on a random batch of the training views; the run's history and
progress as it goes)."""
from __future__ import annotations

import time
from typing import Callable

import numpy as np
import torch

from ..render import render
from ..settings.fields import ConstructSettings
from ..solvers.optim import clip_gradients
from .choose_levels import subdivide
from .losses import isotropy_loss, laplacian_smoothing_loss, shell_range_loss, shell_volume_loss
from .params import Parameters, torch_vertex_normals
from .schedule import Schedule
from .state import RunState
from .types import Progress


def step(params: Parameters, s: ConstructSettings, cams, target: torch.Tensor, h: float,
         frozen: bool, warm_up: bool) -> tuple[float, float, float]:
    """Render ``cams`` (a subset of the training views, ``target`` their reference images),
    add the regularisers, step the optimiser. Returns (loss, render loss, image MSE).

    ``h``: the length that scale-normalises L_sv, L_range and L_iso (the base's initial mean
    edge length in the unit frame), so their weights mean the same on every mesh and base;
    with ``s.paper_losses`` they are the paper's (unit frame, h = 1, L_iso in the loss).
    ``frozen``: the base does not move; ``warm_up``: only the base moves."""
    if s.paper_losses:
        h = 1.0
    opt = params.optimizer
    opt.zero_grad(set_to_none=True)
    P, N, D, X = params.geometry(detach_base=frozen)
    img = render(X, params.tris, cams, kind=s.shading, antialias=s.antialias)
    diff = img - target
    l_render = diff.abs().mean()
    loss = s.w_render * l_render
    if s.w_sv > 0 and not warm_up:
        loss = loss + s.w_sv * shell_volume_loss(D, params.groups, h)
    if s.w_range > 0 and not warm_up:
        loss = loss + s.w_range * shell_range_loss(D, params.groups, h)
    if not s.reparameterize and s.laplacian_weight > 0:
        reg = laplacian_smoothing_loss(X, params.micro_L)
        if not frozen:
            reg = reg + laplacian_smoothing_loss(P, params.base_L)
        loss = loss + s.laplacian_weight * reg
    if s.paper_losses and s.w_iso > 0 and not frozen:
        loss = loss + s.w_iso * isotropy_loss(P, params.F, h)
    loss.backward()
    trained = ([] if warm_up else [params.disp.param]) + ([] if frozen else [params.offsets.param])
    if frozen:
        params.offsets.param.grad = None
    if warm_up:
        params.disp.param.grad = None
    clip_gradients(trained, s.grad_clip)
    opt.step()
    total = float(loss.detach())
    if s.w_iso > 0 and not frozen and not s.paper_losses:
        total += _isotropy_step(params, s, h)
    mse = float((diff.detach() ** 2).mean())
    return total, float(l_render.detach()), mse


def _isotropy_step(params: Parameters, s: ConstructSettings, h: float) -> float:
    """Move the base offsets straight down L_iso's gradient, outside the optimiser: making
    edges equal is a per-vertex (high-frequency) change, which both the Large-Steps
    preconditioner (I + λL)^-2 and Uniform Adam's one step size per tensor suppress (L_iso
    then did nothing at any weight). The gradient g is taken in each vertex's tangent plane
    (the base slides along itself, it does not leave the surface); the step in the offsets is
    -w_iso · lr_base · g / max|g|, written into the parameter as (I + λL) of it. Returns the
    loss term's value."""
    P = (params.V0 + params.offsets.value().detach()).requires_grad_(True)
    l_iso = isotropy_loss(P, params.F, h)
    (g,) = torch.autograd.grad(l_iso, P)
    n = torch_vertex_normals(P.detach(), params.F)
    g = g - n * (g * n).sum(1, keepdim=True)
    top = float(g.abs().max())
    if top > 0:
        delta = g * (-s.w_iso * s.lr_base / top)
        if params.offsets.solver is not None:
            delta = params.offsets.solver.multiply(delta)
        with torch.no_grad():
            params.offsets.param.add_(delta)
    return s.w_iso * float(l_iso.detach())


def optimise(run: RunState, params: Parameters, schedule: Schedule, target,
             progress: Callable[[Progress], None] | None = None) -> int:
    """``run.s.iterations`` iterations, fewer where ``schedule`` runs out of time; ``target``:
    the reference images of ``run.scene.cams`` (the training views). Appends each iteration's
    loss and PSNR to ``run.history``; returns the iterations done."""
    s, cams, h = run.s, run.scene.cams, run.history
    rng = np.random.default_rng(s.seed)
    n_it, views = s.iterations, min(s.views_per_iter, len(cams))
    t_loop, done = time.perf_counter(), 0
    for it in range(n_it):
        run.check_stop()
        if schedule.out_of_time(it):
            break
        for _ in range(schedule.events_due(it)):
            if run.level < s.max_level:
                with run.timer.phase("subdivide"):
                    subdivide(run, params, it)
                run.check_stop()
        with run.timer.phase("optimize"):
            idx = np.sort(rng.choice(len(cams), views, replace=False))
            warm = s.base_warm_up and run.level == 0 and run.fixed is None
            loss, l_render, mse = step(params, s, cams.subset(idx), target[idx], run.h,
                                       schedule.frozen(it), warm)
        p = 10 * np.log10(1.0 / mse) if mse > 0 else float("inf")
        done += 1
        h["iteration"].append(it)
        h["loss"].append(loss)
        h["render"].append(l_render)
        h["psnr"].append(float(p))
        if progress is not None:
            el = time.perf_counter() - t_loop
            progress(Progress("optimize", it + 1, n_it, loss, float(p),
                              schedule.bounded_eta(el / done * (n_it - done))))
    return done
