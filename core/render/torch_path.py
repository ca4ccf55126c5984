"""Plain-torch implementation of every renderer op: the reference for tests and benchmarks,
and the backend for CUDA tensors.

Visibility is a z-buffer by ``scatter_reduce(amin)`` on packed (float32 depth bits, face id)
int64 keys, so the nearest face wins and ties go to the smaller id, exactly like the numba
rasteriser. Everything after visibility is differentiable torch code; autograd does the backward.
"""
from __future__ import annotations

import torch

from .geometry import normalize, screen_coords
from .sh import shade_normals

_MAX_CANDIDATES = 1 << 23  # pixel candidates per chunk of faces (memory bound)
_KEY_BACKGROUND = torch.iinfo(torch.int64).max


def _face_setup(faces: torch.Tensor, sx, sy, w, z, width: int, height: int):
    """Per-face screen data of the faces that can cover a pixel centre (float64)."""
    f = faces.long()
    ax, ay, aw = sx[f], sy[f], w[f]
    ok = ((aw > 0) & (z[f] >= -aw)).all(1)  # all vertices in front of the near plane
    x0, y0, x1, y1, x2, y2 = ax[:, 0], ay[:, 0], ax[:, 1], ay[:, 1], ax[:, 2], ay[:, 2]
    area = (x1 - x0) * (y2 - y0) - (y1 - y0) * (x2 - x0)
    ok &= (area != 0) & torch.isfinite(area)
    c0 = torch.ceil(ax.min(1).values - 0.5).clamp(0, width)
    c1 = torch.floor(ax.max(1).values - 0.5).clamp(-1, width - 1)
    r0 = torch.ceil(ay.min(1).values - 0.5).clamp(0, height)
    r1 = torch.floor(ay.max(1).values - 0.5).clamp(-1, height - 1)
    nx, ny = (c1 - c0 + 1).clamp(min=0), (r1 - r0 + 1).clamp(min=0)
    count = torch.where(ok, nx * ny, torch.zeros_like(nx)).long()
    return f, ax, ay, aw, area, c0.long(), r0.long(), nx.long(), count


def _edge(fa, fb, xa, ya, xb, yb, px, py):
    """Edge function of the face edge a -> b, computed from the lower to the higher vertex id
    so that the two faces sharing an edge get exactly opposite values; tie flag for E == 0."""
    swap = fa > fb
    lx, ly = torch.where(swap, xb, xa), torch.where(swap, yb, ya)
    hx, hy = torch.where(swap, xa, xb), torch.where(swap, ya, yb)
    e = (hx - lx) * (py - ly) - (hy - ly) * (px - lx)
    return torch.where(swap, -e, e), ~swap


def rasterize_torch(verts: torch.Tensor, faces: torch.Tensor, mvp: torch.Tensor, width: int,
                    height: int) -> tuple[torch.Tensor, torch.Tensor]:
    """(tri_id int32 (B, H, W), depth float32 (B, H, W), +inf background)."""
    dev = verts.device
    nb = len(mvp)
    tri = torch.full((nb, height, width), -1, dtype=torch.int32, device=dev)
    depth = torch.full((nb, height, width), float("inf"), dtype=torch.float32, device=dev)
    if len(faces) == 0:
        return tri, depth
    for b in range(nb):
        sx, sy, w, z = screen_coords(verts, mvp[b], width, height)
        f, ax, ay, aw, area, c0, r0, nx, count = _face_setup(faces, sx, sy, w, z, width, height)
        keys = torch.full((height * width,), _KEY_BACKGROUND, dtype=torch.int64, device=dev)
        live = torch.nonzero(count > 0).squeeze(1)
        csum = torch.cumsum(count[live], 0)
        start = 0
        while start < len(live):
            base = int(csum[start - 1]) if start else 0
            stop = int(torch.searchsorted(csum, base + _MAX_CANDIDATES, right=True))
            stop = max(stop, start + 1)
            fid = live[start:stop]
            cnt = count[fid]
            rep = torch.repeat_interleave(fid, cnt)
            first = torch.cumsum(cnt, 0) - cnt
            k = torch.arange(len(rep), device=dev) - torch.repeat_interleave(first, cnt)
            col = c0[rep] + k % nx[rep]
            row = r0[rep] + k // nx[rep]
            px, py = col.to(torch.float64) + 0.5, row.to(torch.float64) + 0.5
            fv, xs, ys = f[rep], ax[rep], ay[rep]
            s = area[rep] > 0
            inside = torch.ones_like(s)
            lam = []
            for e in range(3):
                a, c = e, (e + 1) % 3
                ev, tie = _edge(fv[:, a], fv[:, c], xs[:, a], ys[:, a], xs[:, c], ys[:, c], px, py)
                es = torch.where(s, ev, -ev)
                inside &= (es > 0) | ((es == 0) & tie)
                lam.append(ev)
            ar = area[rep]
            iw = aw[rep].reciprocal()
            # lam[e] belongs to the vertex opposite edge e, i.e. vertex (e + 2) % 3
            inv_w = ((lam[1] * iw[:, 0] + lam[2] * iw[:, 1]) + lam[0] * iw[:, 2]) / ar
            inside &= inv_w > 0
            d32 = (1.0 / inv_w).to(torch.float32)
            key = (d32.view(torch.int32).to(torch.int64) << 32) | rep
            pix = (row * width + col)[inside]
            keys.scatter_reduce_(0, pix, key[inside], reduce="amin")
            start = stop
        hit = keys != _KEY_BACKGROUND
        tri[b].view(-1)[hit] = (keys[hit] & 0xFFFFFFFF).to(torch.int32)
        depth[b].view(-1)[hit] = (keys[hit] >> 32).to(torch.int32).view(torch.float32)
    return tri, depth


def pixel_ndc(index: torch.Tensor, width: int, height: int, dtype) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(view, ndc x, ndc y) of flat pixel indices into (B, H, W)."""
    b = index // (width * height)
    rem = index % (width * height)
    r, c = rem // width, rem % width
    x = (c.to(dtype) + 0.5) * (2.0 / width) - 1.0
    y = 1.0 - (r.to(dtype) + 0.5) * (2.0 / height)
    return b, x, y


def barycentrics_torch(verts: torch.Tensor, faces: torch.Tensor, mvp: torch.Tensor,
                       tri_id: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Perspective-correct barycentrics of the covered pixels, differentiable w.r.t. verts.

    They are the barycentrics of the pixel ray's hit with the visible face's plane: with clip
    coordinates (x_i, y_i, w_i) and pixel NDC (x, y), u_i = x_i - x w_i, t_i = y_i - y w_i and
    b_i is proportional to u_j t_k - u_k t_j. Returns (flat pixel index (P,), face (P,),
    bary (P, 3), clip w of the three vertices (P, 3)).
    """
    nb, height, width = tri_id.shape
    flat = tri_id.reshape(-1)
    index = torch.nonzero(flat >= 0).squeeze(1)
    face = flat[index].long()
    b, x, y = pixel_ndc(index, width, height, verts.dtype)
    m = mvp.to(verts.dtype)[b]  # (P, 4, 4)
    fv = faces.long()[face]  # (P, 3)
    v = verts[fv]  # (P, 3, 3)
    clip = torch.einsum("prk,pik->pir", m[:, (0, 1, 3), :3], v) + m[:, None, (0, 1, 3), 3]
    u = clip[..., 0] - x[:, None] * clip[..., 2]
    t = clip[..., 1] - y[:, None] * clip[..., 2]
    beta = torch.stack([u[:, 1] * t[:, 2] - u[:, 2] * t[:, 1],
                        u[:, 2] * t[:, 0] - u[:, 0] * t[:, 2],
                        u[:, 0] * t[:, 1] - u[:, 1] * t[:, 0]], 1)
    s = beta.sum(1, keepdim=True)
    tiny = torch.finfo(verts.dtype).tiny
    s = torch.where(s.abs() < tiny, torch.full_like(s, tiny), s)
    return index, face, beta * (1.0 / s), clip[..., 2]


def shade_torch(verts: torch.Tensor, faces: torch.Tensor, vnormals: torch.Tensor,
                mvp: torch.Tensor, tri_id: torch.Tensor, kind: str) -> torch.Tensor:
    """(B, H, W, C) image of ``kind`` ('shaded', 'normal', 'depth', 'mask'), background 0."""
    nb, height, width = tri_id.shape
    index, face, bary, w = barycentrics_torch(verts, faces, mvp, tri_id)
    if kind == "mask":
        val = torch.ones((len(index), 1), dtype=verts.dtype, device=verts.device)
    elif kind == "depth":
        val = (bary * w).sum(1, keepdim=True)
    else:
        n = normalize((bary[:, :, None] * vnormals[faces.long()[face]]).sum(1))
        val = shade_normals(n) if kind == "shaded" else n
    out = torch.zeros((nb * height * width, val.shape[1]), dtype=verts.dtype, device=verts.device)
    out = out.index_put((index,), val)
    return out.view(nb, height, width, -1)


def face_facing(verts: torch.Tensor, faces: torch.Tensor, mvp: torch.Tensor, width: int,
                height: int) -> torch.Tensor:
    """(B, M) int8 sign of each face's screen area per view (0: degenerate or crossing the near
    plane); same float64 arithmetic as the numba rasteriser."""
    f = faces.long()
    out = torch.empty((len(mvp), len(f)), dtype=torch.int8, device=verts.device)
    for b in range(len(mvp)):
        sx, sy, w, z = screen_coords(verts, mvp[b], width, height)
        x, y = sx[f], sy[f]
        area = (x[:, 1] - x[:, 0]) * (y[:, 2] - y[:, 0]) - (y[:, 1] - y[:, 0]) * (x[:, 2] - x[:, 0])
        ok = ((w[f] > 0) & (z[f] >= -w[f])).all(1)
        out[b] = torch.where(ok, torch.sign(area), torch.zeros_like(area)).to(torch.int8)
    return out


def _face_screen(verts, f_all, m, fidx, width, height):
    """Screen x, y (P, 3) of faces ``fidx`` (P,) under per-pair matrices m (P, 4, 4); ok (P,)."""
    v = verts[f_all[fidx]]
    clip = torch.einsum("prk,pik->pir", m[:, (0, 1, 3), :3], v) + m[:, None, (0, 1, 3), 3]
    w = clip[..., 2]
    ws = torch.where(w > 0, w, torch.ones_like(w))
    sx = (clip[..., 0] / ws + 1.0) * (0.5 * width)
    sy = (1.0 - clip[..., 1] / ws) * (0.5 * height)
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


MAX_WALK = 64
WALK_DEPTH_RATIO = 1.01


def antialias_torch(color: torch.Tensor, verts: torch.Tensor, faces: torch.Tensor,
                    nbr: torch.Tensor, mvp: torch.Tensor, tri_id: torch.Tensor,
                    depth: torch.Tensor) -> torch.Tensor:
    """nvdiffrast-style analytic antialiasing of (B, H, W, C) ``color``; the rule of
    ``antialias.py`` (silhouette edges by facing, one pair direction per edge, the walk across
    sub-pixel faces towards background or a clearly farther surface) in vectorised torch."""
    nb, height, width, nc = color.shape
    out = color
    dt = verts.dtype
    f_all = faces.long()
    nbr = nbr.long()
    facing = face_facing(verts, faces, mvp, width, height)
    vd = verts.detach()
    for axis in (2, 1):  # horizontal pairs (along W), then vertical pairs (along H)
        vertical = axis == 1
        ida = tri_id.narrow(axis, 0, tri_id.shape[axis] - 1)
        idb = tri_id.narrow(axis, 1, tri_id.shape[axis] - 1)
        bi, ri, ci = torch.nonzero(ida != idb, as_tuple=True)
        if len(bi) == 0:
            continue
        fa, fb = ida[bi, ri, ci].long(), idb[bi, ri, ci].long()
        da = depth.narrow(axis, 0, depth.shape[axis] - 1)[bi, ri, ci]
        db = depth.narrow(axis, 1, depth.shape[axis] - 1)[bi, ri, ci]
        near_a = (fb < 0) | ((fa >= 0) & ((da < db) | ((da == db) & (fa < fb))))
        walk = torch.where(near_a, (fb < 0) | (db > da * WALK_DEPTH_RATIO),
                           (fa < 0) | (da > db * WALK_DEPTH_RATIO))
        fixed = (ci if vertical else ri).to(dt) + 0.5
        p0 = (ri if vertical else ci).to(dt) + 0.5
        m = mvp.to(dt)[bi]
        with torch.no_grad():
            cur = torch.where(near_a, fa, fb)
            sx, sy, ok = _face_screen(vd, f_all, m, cur, width, height)
            t_all, steep = _crossings(sx, sy, vertical, fixed, p0)
            e, t, alive = _pick(t_all, (t_all >= 0) & (t_all <= 1), near_a)
            alive &= ok
            code = torch.full_like(cur, -1)
            for _ in range(MAX_WALK):
                n = nbr[cur, e]
                sil = (n < 0) | (facing[bi, n.clamp(min=0)] != facing[bi, cur])
                good = alive & sil & steep.gather(1, e[:, None])[:, 0]
                code = torch.where(good, cur * 3 + e, code)
                alive &= ~sil & walk
                if not bool(alive.any()):
                    break
                ia, ib = f_all[cur, e], f_all[cur, (e + 1) % 3]
                nxt = n.clamp(min=0)
                sx, sy, ok = _face_screen(vd, f_all, m, nxt, width, height)
                t_all, steep = _crossings(sx, sy, vertical, fixed, p0)
                fk = f_all[nxt]
                fk1 = fk.roll(-1, 1)
                came = ((fk == ia[:, None]) & (fk1 == ib[:, None])) | ((fk == ib[:, None]) & (fk1 == ia[:, None]))
                ahead = torch.where(near_a[:, None], t_all >= t[:, None], t_all <= t[:, None])
                e2, t2, found = _pick(t_all, (t_all >= 0) & (t_all <= 1) & ~came & ahead, near_a)
                alive &= found & ok
                cur = torch.where(alive, nxt, cur)
                e = torch.where(alive, e2, e)
                t = torch.where(alive, t2, t)
        valid = code >= 0
        if not bool(valid.any()):
            continue
        bi, ri, ci, code, fixed, p0, m = bi[valid], ri[valid], ci[valid], code[valid], fixed[valid], p0[valid], m[valid]
        occ, e = code // 3, code % 3
        sx, sy, _ = _face_screen(verts, f_all, m, occ, width, height)
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
        out = flat.index_add(0, dst, delta.to(flat.dtype)).view(nb, height, width, nc)
    return out
