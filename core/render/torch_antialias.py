"""The plain-torch antialiasing (``torch_path``'s second half): nvdiffrast-style analytic
antialiasing of silhouette pixel pairs, the rule of ``antialias.py``, vectorised over all pairs
of all views; the walk across sub-pixel faces steps all still-walking pairs together, or runs
as one Triton kernel on CUDA (``triton_walk``)."""
from __future__ import annotations

import torch

from . import triton_walk
from .scatter import scatter_add
from .silhouette import MAX_WALK, WALK_DEPTH_RATIO
from .torch_path import clip_xyw
from .torch_raster import _limits, _view_groups, fused_default, project


def face_facing(verts: torch.Tensor, faces: torch.Tensor, mvp: torch.Tensor, width: int,
                height: int) -> torch.Tensor:
    """(B, M) int8 sign of each face's screen area per view (0: degenerate or crossing the near
    plane); same float64 arithmetic as the numba rasteriser."""
    f = faces.long()
    out = torch.empty((len(mvp), len(f)), dtype=torch.int8, device=verts.device)
    for g0, g1 in _view_groups(len(mvp), len(f), _limits(verts.device)[1]):
        sx, sy, w, z = project(verts, mvp[g0:g1], width, height)
        x, y = sx[:, f], sy[:, f]
        area = (x[..., 1] - x[..., 0]) * (y[..., 2] - y[..., 0]) - (y[..., 1] - y[..., 0]) * (x[..., 2] - x[..., 0])
        ok = ((w[:, f] > 0) & (z[:, f] >= -w[:, f])).all(-1)
        out[g0:g1] = torch.where(ok, torch.sign(area), torch.zeros_like(area)).to(torch.int8)
    return out


def _face_screen(verts, f_all, mvp, b, face, width, height):
    """Screen x, y (P, 3) of faces ``face`` (P,) in views ``b`` (P,); ok (P,): all w > 0."""
    x, y, w = clip_xyw(verts, mvp, b, f_all[face])
    ws = torch.where(w > 0, w, torch.ones_like(w))
    sx = (x / ws + 1.0) * (0.5 * width)
    sy = (1.0 - y / ws) * (0.5 * height)
    return sx, sy, (w > 0).all(1)


def _crossings(sx, sy, vertical: bool, fixed, p0):
    """t (P, 3) where edge k of each face crosses its pair segment (NaN: no straddle) and
    whether the edge is steep enough for the pair direction (P, 3)."""
    along, across = (sy, sx) if vertical else (sx, sy)
    aa, ab = along, along.roll(-1, 1)
    ca, cb = across, across.roll(-1, 1)
    fx = fixed[:, None]
    straddle = ((ca <= fx) & (fx < cb)) | ((cb <= fx) & (fx < ca))
    den = torch.where(straddle, cb - ca, torch.ones_like(ca))
    t = aa + (fx - ca) * (ab - aa) / den - p0[:, None]
    steep = (cb - ca).abs() - (ab - aa).abs()
    return torch.where(straddle, t, torch.full_like(t, float("nan"))), (steep > 0) if vertical else (steep >= 0)


def _pick(t, valid, near_a):
    """Edge index with the first crossing going away from the occluding pixel, and its t."""
    key = torch.where(valid, torch.where(near_a[:, None], t, -t), torch.full_like(t, float("inf")))
    e = key.argmin(1)
    return e, t.gather(1, e[:, None])[:, 0], valid.any(1)


def _walk(vd, f_all, nbr, facing, m64, bi, cur, near_a, walk, fixed, p0, vertical, width, height,
          max_walk):
    """Silhouette edge code (face * 3 + edge, -1 for none) of every pair (no gradient).

    The walk across sub-pixel faces works on the shrinking set of still-walking pairs (index
    ``act`` into the pair arrays), so each step costs only what is still alive."""
    code = torch.full_like(cur, -1)
    sx, sy, ok = _face_screen(vd, f_all, m64, bi, cur, width, height)
    t_all, steep = _crossings(sx, sy, vertical, fixed, p0)
    e, t, alive = _pick(t_all, (t_all >= 0) & (t_all <= 1), near_a)
    act = torch.nonzero(alive & ok).squeeze(1)
    cur, e, t, steep = cur[act], e[act], t[act], steep[act]
    for _ in range(max_walk):
        if len(act) == 0:
            break
        b = bi[act]
        n = nbr[cur, e]
        sil = (n < 0) | (facing[b, n.clamp(min=0)] != facing[b, cur])
        good = sil & steep.gather(1, e[:, None])[:, 0]
        code[act[good]] = (cur * 3 + e)[good]
        keep = torch.nonzero(~sil & walk[act]).squeeze(1)
        if len(keep) == 0:
            break
        act, cur, e, t, n, b = act[keep], cur[keep], e[keep], t[keep], n[keep], b[keep]
        fx, q0, na = fixed[act], p0[act], near_a[act]
        ia, ib = f_all[cur, e], f_all[cur, (e + 1) % 3]
        sx, sy, ok = _face_screen(vd, f_all, m64, b, n, width, height)
        t_all, steep = _crossings(sx, sy, vertical, fx, q0)
        fk = f_all[n]
        fk1 = fk.roll(-1, 1)
        came = ((fk == ia[:, None]) & (fk1 == ib[:, None])) | ((fk == ib[:, None]) & (fk1 == ia[:, None]))
        ahead = torch.where(na[:, None], t_all >= t[:, None], t_all <= t[:, None])
        e2, t2, found = _pick(t_all, (t_all >= 0) & (t_all <= 1) & ~came & ahead, na)
        keep = torch.nonzero(found & ok).squeeze(1)
        act, cur, e, t, steep = act[keep], n[keep], e2[keep], t2[keep], steep[keep]
    return code


def antialias_torch(color: torch.Tensor, verts: torch.Tensor, faces: torch.Tensor,
                    nbr: torch.Tensor, mvp: torch.Tensor, tri_id: torch.Tensor,
                    depth: torch.Tensor, fused: bool | None = None) -> torch.Tensor:
    """nvdiffrast-style analytic antialiasing of (B, H, W, C) ``color``; the rule of
    ``antialias.py`` (silhouette edges by facing, one pair direction per edge, the walk across
    sub-pixel faces towards background or a clearly farther surface) in vectorised torch: all
    pixel pairs of all views at once, the walk stepping all still-walking pairs together
    (``fused``: the walk as one kernel, default ``fused_default``).

    Each stage runs for both pair directions before the next (pairs, walks, silhouette pairs,
    blends): the two selections that wait for the device (``nonzero``) come one after the
    other instead of four times apart. The blends add horizontal pairs first, as before."""
    fused = fused_default(verts.device) if fused is None else fused
    nb, height, width, nc = color.shape
    f_all = faces.long()
    vd = verts.detach().to(torch.float64)
    m64 = mvp.to(torch.float64)
    facing = triton_walk.facing(vd, f_all, m64, width, height) if fused else None
    if facing is None:
        facing = face_facing(verts, faces, mvp, width, height)
    axes = (2, 1)       # horizontal pairs (along W), then vertical pairs (along H)
    differ = [tri_id.narrow(a, 0, tri_id.shape[a] - 1) != tri_id.narrow(a, 1, tri_id.shape[a] - 1)
              for a in axes]
    pairs = [torch.nonzero(d, as_tuple=True) for d in differ]
    nbr, mdt = nbr.long(), mvp.to(verts.dtype)
    walked = [_walked(p, a, tri_id, depth, vd, f_all, nbr, facing, m64, fused)
              for p, a in zip(pairs, axes)]
    valid = [torch.nonzero(w[-1] >= 0).squeeze(1) if w is not None else None for w in walked]
    out = color
    for a, w, v in zip(axes, walked, valid):
        if v is not None and len(v):
            out = _blend(out, color, verts, f_all, mdt, a == 1, *(x[v] for x in w))
    return out


def _walked(pairs, axis: int, tri_id, depth, vd, f_all, nbr, facing, m64, fused: bool):
    """(bi, ri, ci, fixed, p0, code) of the pixel pairs ``pairs`` along ``axis`` whose faces
    differ: the silhouette edge each crosses (``code``: face * 3 + edge, -1 for none)."""
    bi, ri, ci = pairs
    if len(bi) == 0:
        return None
    vertical = axis == 1
    nb, height, width = tri_id.shape
    ida = tri_id.narrow(axis, 0, tri_id.shape[axis] - 1)
    idb = tri_id.narrow(axis, 1, tri_id.shape[axis] - 1)
    fa, fb = ida[bi, ri, ci].long(), idb[bi, ri, ci].long()
    da = depth.narrow(axis, 0, depth.shape[axis] - 1)[bi, ri, ci]
    db = depth.narrow(axis, 1, depth.shape[axis] - 1)[bi, ri, ci]
    near_a = (fb < 0) | ((fa >= 0) & ((da < db) | ((da == db) & (fa < fb))))
    walk = torch.where(near_a, (fb < 0) | (db > da * WALK_DEPTH_RATIO),
                       (fa < 0) | (da > db * WALK_DEPTH_RATIO))
    fixed = (ci if vertical else ri).to(torch.float64) + 0.5
    p0 = (ri if vertical else ci).to(torch.float64) + 0.5
    with torch.no_grad():
        cur = torch.where(near_a, fa, fb)
        args = (vd, f_all, nbr, facing, m64, bi, cur, near_a, walk, fixed, p0, vertical,
                width, height, MAX_WALK)
        code = triton_walk.walk_codes(*args) if fused else None
        if code is None:
            code = _walk(*args)
    return bi, ri, ci, fixed, p0, code


def _blend(out, color, verts, f_all, mdt, vertical: bool, bi, ri, ci, fixed, p0, code):
    """``out`` with each silhouette pair's coverage blend added (differentiable w.r.t. the
    colours and, through where the edge crosses the pair, the vertices)."""
    nb, height, width, nc = color.shape
    dt = verts.dtype
    fixed, p0 = fixed.to(dt), p0.to(dt)
    occ, e = code // 3, code % 3
    sx, sy, _ = _face_screen(verts, f_all, mdt, bi, occ, width, height)
    along, across = (sy, sx) if vertical else (sx, sy)
    j = (e + 1) % 3
    la, lb = along.gather(1, e[:, None])[:, 0], along.gather(1, j[:, None])[:, 0]
    ca, cb = across.gather(1, e[:, None])[:, 0], across.gather(1, j[:, None])[:, 0]
    t = la + (fixed - ca) * (lb - la) / (cb - ca) - p0
    ia = (bi * height + ri) * width + ci
    ib = ia + (width if vertical else 1)
    flat = out.reshape(-1, nc)
    ca_, cb_ = color.reshape(-1, nc)[ia], color.reshape(-1, nc)[ib]
    to_b = t >= 0.5
    alpha = torch.where(to_b, t - 0.5, 0.5 - t)[:, None]
    dst = torch.where(to_b, ib, ia)
    delta = alpha * torch.where(to_b[:, None], ca_ - cb_, cb_ - ca_)
    return scatter_add(flat, dst, delta.to(flat.dtype)).view(nb, height, width, nc)
