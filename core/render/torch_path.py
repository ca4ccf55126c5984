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
    return index, face, beta / s, clip[..., 2]


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


def antialias_torch(color: torch.Tensor, verts: torch.Tensor, faces: torch.Tensor,
                    nbr: torch.Tensor, mvp: torch.Tensor, tri_id: torch.Tensor,
                    depth: torch.Tensor) -> torch.Tensor:
    """nvdiffrast-style analytic antialiasing of (B, H, W, C) ``color``.

    For each horizontal and vertical pair of neighbouring pixels with different face ids, the
    face of the nearer pixel is tested for a silhouette edge (boundary, or the neighbour face
    ``nbr`` faces the other way in this view) crossing the segment between the two pixel centres at t in [0, 1]. The pixel whose box the edge cuts gets
    the other pixel's colour blended in by the cut fraction |t - 1/2|; t depends on the edge's
    projected vertices, so gradients reach them. Same rule as ``antialias.py``.
    """
    nb, height, width, nc = color.shape
    out = color
    dt = verts.dtype
    f_all = faces.long()
    facing = face_facing(verts, faces, mvp, width, height)
    for axis in (2, 1):  # horizontal pairs (along W), then vertical pairs (along H)
        ida = tri_id.narrow(axis, 0, tri_id.shape[axis] - 1)
        idb = tri_id.narrow(axis, 1, tri_id.shape[axis] - 1)
        da = depth.narrow(axis, 0, depth.shape[axis] - 1)
        db = depth.narrow(axis, 1, depth.shape[axis] - 1)
        diff = ida != idb
        bi, ri, ci = torch.nonzero(diff, as_tuple=True)
        if len(bi) == 0:
            continue
        fa, fb = ida[bi, ri, ci].long(), idb[bi, ri, ci].long()
        near_a = (fb < 0) | ((fa >= 0) & ((da[bi, ri, ci] < db[bi, ri, ci]) |
                                           ((da[bi, ri, ci] == db[bi, ri, ci]) & (fa < fb))))
        occ = torch.where(near_a, fa, fb)
        m = mvp.to(dt)[bi]  # (P, 4, 4)
        fv = f_all[occ]
        v = verts[fv]
        clip = torch.einsum("prk,pik->pir", m[:, (0, 1, 3), :3], v) + m[:, None, (0, 1, 3), 3]
        wv = clip[..., 2]
        good_w = (wv > 0).all(1)
        wsafe = torch.where(wv > 0, wv, torch.ones_like(wv))
        sx = (clip[..., 0] / wsafe + 1.0) * (0.5 * width)
        sy = (1.0 - clip[..., 1] / wsafe) * (0.5 * height)
        if axis == 2:  # pair along x at fixed row
            fixed = ri.to(dt) + 0.5
            p0 = ci.to(dt) + 0.5
            along, across = sx, sy
        else:
            fixed = ci.to(dt) + 0.5
            p0 = ri.to(dt) + 0.5
            along, across = sy, sx
        t = torch.full_like(fixed, -1.0)
        for e in range(3):
            i, j = e, (e + 1) % 3
            with torch.no_grad():
                nf = nbr[occ, e]
                sil = (nf < 0) | (facing[bi, nf.clamp(min=0)] != facing[bi, occ])
            ya, yb = across[:, i], across[:, j]
            straddle = ((ya <= fixed) & (fixed < yb)) | ((yb <= fixed) & (fixed < ya))
            steep = (yb - ya).abs() - (along[:, j] - along[:, i]).abs()
            straddle &= (steep > 0) if axis == 1 else (steep >= 0)  # one direction per edge
            den = torch.where(straddle, yb - ya, torch.ones_like(ya))
            cross = along[:, i] + (fixed - ya) * (along[:, j] - along[:, i]) / den
            te = cross - p0
            ok = straddle & sil & good_w & (te >= 0) & (te <= 1) & (t < 0)
            t = torch.where(ok, te, t)
        valid = t >= 0
        if not bool(valid.any()):
            continue
        bi, ri, ci, t = bi[valid], ri[valid], ci[valid], t[valid]
        ia = (bi * height + ri) * width + ci
        ib = ia + (1 if axis == 2 else width)
        flat = out.reshape(-1, nc)
        ca, cb = color.reshape(-1, nc)[ia], color.reshape(-1, nc)[ib]
        to_b = t >= 0.5
        alpha = torch.where(to_b, t - 0.5, 0.5 - t)[:, None]
        dst = torch.where(to_b, ib, ia)
        delta = alpha * torch.where(to_b[:, None], ca - cb, cb - ca)
        out = flat.index_add(0, dst, delta.to(flat.dtype)).view(nb, height, width, nc)
    return out
