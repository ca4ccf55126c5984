"""One optimiser iteration: render a batch of views, the losses (method §3), one step."""
from __future__ import annotations

import numpy as np
import torch

from ..losses import isotropy_loss, laplacian_smoothing_loss, shell_range_loss, shell_volume_loss
from ..optim import clip_gradients
from ..render import render
from ..settings import ConstructSettings
from .params import Parameters


def step(params: Parameters, s: ConstructSettings, cams, target: torch.Tensor,
         frozen: bool) -> tuple[float, float, float]:
    """Render ``cams`` (a subset of the training views, ``target`` their reference images),
    add the regularisers, step the optimiser. Returns (loss, render loss, image MSE)."""
    opt = params.optimizer
    opt.zero_grad(set_to_none=True)
    P, N, D, X = params.geometry(detach_base=frozen)
    img = render(X, params.tris, cams, antialias=s.antialias)
    diff = img - target
    l_render = diff.abs().mean()
    loss = s.w_render * l_render
    if s.w_sv > 0:
        loss = loss + s.w_sv * shell_volume_loss(D, params.groups)
    if s.w_range > 0:
        loss = loss + s.w_range * shell_range_loss(D, params.groups)
    if s.w_iso > 0 and not frozen:
        loss = loss + s.w_iso * isotropy_loss(P, params.F)
    if not s.reparameterize and s.laplacian_weight > 0:
        reg = laplacian_smoothing_loss(X, params.micro_L)
        if not frozen:
            reg = reg + laplacian_smoothing_loss(P, params.base_L)
        loss = loss + s.laplacian_weight * reg
    loss.backward()
    trained = [params.disp.param] + ([] if frozen else [params.offsets.param])
    if frozen:
        params.offsets.param.grad = None
    clip_gradients(trained, s.grad_clip)
    opt.step()
    mse = float((diff.detach() ** 2).mean())
    return float(loss.detach()), float(l_render.detach()), mse
