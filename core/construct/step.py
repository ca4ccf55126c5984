"""One optimiser iteration: render a batch of views, the losses (method §3), one step."""
from __future__ import annotations

import torch

from ..losses import isotropy_loss, laplacian_smoothing_loss, shell_range_loss, shell_volume_loss
from ..optim import clip_gradients
from ..render import render
from ..settings import ConstructSettings
from .params import Parameters, torch_vertex_normals


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
