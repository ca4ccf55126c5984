"""The plain-torch rasteriser (``torch_path``'s first half): one z-buffer for all B views by
``scatter_reduce(amin)`` on packed (float32 depth bits << 32 | face id) int64 keys, so the
nearest face wins and ties go to the smaller id, exactly like the numba rasteriser (same
float64 coverage arithmetic). Vectorised over views and pixels; views go in groups only to
bound memory. On CUDA the per-(view, face) pixel loop runs as one Triton kernel
(``triton_kernels``).
"""
from __future__ import annotations

import torch

from . import triton_kernels

_MAX_CANDIDATES = 1 << 21
"""(pixel, face) candidates expanded at once on the CPU (~400 bytes of temporaries each)."""
_MAX_FACE_VIEWS = 1 << 22
"""face x view setups held at once on the CPU (~600 bytes each); views go in groups of at most
this many."""
_GPU_SHARE = 16
"""On a GPU each of the two is sized to use at most this fraction of the free memory (fewer,
larger batches: fewer kernel launches and host syncs), never below the CPU's."""
_KEY_BACKGROUND = torch.iinfo(torch.int64).max


def project(verts: torch.Tensor, mvp: torch.Tensor, width: int, height: int
            ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Exact float64 (sx, sy, w, z), each (B, N), of (N, 3) verts under (B, 4, 4) mvp: the
    arithmetic order of ``geometry.screen_coords`` and the numba rasteriser, all views at once."""
    v = verts.detach().to(torch.float64)
    vx, vy, vz = v[:, 0], v[:, 1], v[:, 2]
    m = mvp.to(torch.float64)

    def row(r: int) -> torch.Tensor:
        return ((m[:, r, 0, None] * vx + m[:, r, 1, None] * vy) + m[:, r, 2, None] * vz) + m[:, r, 3, None]

    x, y, z, w = row(0), row(1), row(2), row(3)
    return (x / w + 1.0) * (0.5 * width), (1.0 - y / w) * (0.5 * height), w, z


def _limits(device: torch.device) -> tuple[int, int]:
    """(candidates, face x view setups) held at once on ``device``."""
    if device.type != "cuda":
        return _MAX_CANDIDATES, _MAX_FACE_VIEWS
    free = torch.cuda.mem_get_info(device)[0] // _GPU_SHARE
    return max(_MAX_CANDIDATES, free // 400), max(_MAX_FACE_VIEWS, free // 600)


def _view_groups(n_views: int, n_faces: int, max_face_views: int = _MAX_FACE_VIEWS):
    step = max(1, max_face_views // max(n_faces, 1))
    for b0 in range(0, n_views, step):
        yield b0, min(n_views, b0 + step)


def _live_faces(f: torch.Tensor, sx, sy, w, z, width: int, height: int):
    """Per (view, face) of a view group whose pixel-centre box is not empty: a float64 pack
    (L, 22) [canonical edges (low x, low y, dx, dy) x 3, edge sign x 3, tie x 3, 1/w x 3, area]
    and an int64 pack (L, 5) [c0, r0, box width, view in group, face], and counts (L,).

    Edge e (vertices e, e + 1) is evaluated from its lower to its higher vertex id, so the two
    faces sharing an edge get exactly opposite values (E == 0 belongs to the face that walks it
    upwards in id: ``tie``); the signs fold in the face's orientation. Multiplying by +-1 is
    exact, so coverage and depth are bit-identical to the numba rasteriser's."""
    ax, ay, aw = sx[:, f], sy[:, f], w[:, f]  # (G, M, 3)
    ok = ((aw > 0) & (z[:, f] >= -aw)).all(-1)  # all vertices in front of the near plane
    x0, y0, x1, y1, x2, y2 = ax[..., 0], ay[..., 0], ax[..., 1], ay[..., 1], ax[..., 2], ay[..., 2]
    area = (x1 - x0) * (y2 - y0) - (y1 - y0) * (x2 - x0)
    ok &= (area != 0) & torch.isfinite(area)
    c0 = torch.ceil(ax.min(-1).values - 0.5).clamp(0, width)
    c1 = torch.floor(ax.max(-1).values - 0.5).clamp(-1, width - 1)
    r0 = torch.ceil(ay.min(-1).values - 0.5).clamp(0, height)
    r1 = torch.floor(ay.max(-1).values - 0.5).clamp(-1, height - 1)
    nx, ny = (c1 - c0 + 1).clamp(min=0), (r1 - r0 + 1).clamp(min=0)
    count = torch.where(ok, nx * ny, torch.zeros_like(nx)).reshape(-1)
    live = torch.nonzero(count > 0).squeeze(1)
    m = f.shape[0]
    lb, lf = live // m, live % m
    x, y = ax.reshape(-1, 3)[live], ay.reshape(-1, 3)[live]
    iw = aw.reshape(-1, 3)[live].reciprocal()
    ar = area.reshape(-1)[live]
    fv = f[lf]
    sa = torch.where(ar > 0, 1.0, -1.0).to(torch.float64)
    cols_e, cols_s, cols_t, sg = [], [], [], []
    for e in range(3):
        a, c = e, (e + 1) % 3
        swap = fv[:, a] > fv[:, c]
        lx, ly = torch.where(swap, x[:, c], x[:, a]), torch.where(swap, y[:, c], y[:, a])
        hx, hy = torch.where(swap, x[:, a], x[:, c]), torch.where(swap, y[:, a], y[:, c])
        cols_e += [lx, ly, hx - lx, hy - ly]
        sg.append(torch.where(swap, -1.0, 1.0).to(torch.float64))
        cols_s.append(sg[-1] * sa)
        cols_t.append((~swap).to(torch.float64))
    # inv_w = ((lam1 iw0 + lam2 iw1) + lam0 iw2) / area with lam_e = sg_e E_e (vertex opposite e)
    wq = [sg[1] * iw[:, 0], sg[2] * iw[:, 1], sg[0] * iw[:, 2]]
    fpack = torch.stack(cols_e + cols_s + cols_t + wq + [ar], 1)
    ipack = torch.stack([c0.reshape(-1)[live].long(), r0.reshape(-1)[live].long(),
                         nx.reshape(-1)[live].long(), lb, lf], 1)
    return fpack, ipack, count[live].long()


def fused_default(device: torch.device) -> bool:
    """Whether the torch path runs its two loops as fused kernels (``triton_kernels``) on
    ``device``: on CUDA where Triton is."""
    return triton_kernels.available(device)


def rasterize_torch(verts: torch.Tensor, faces: torch.Tensor, mvp: torch.Tensor, width: int,
                    height: int, fused: bool | None = None) -> tuple[torch.Tensor, torch.Tensor]:
    """(tri_id int32 (B, H, W), depth float32 (B, H, W), +inf background). ``fused``: the
    per-(view, face) pixel loop as one kernel (default: ``fused_default``)."""
    dev = verts.device
    fused = fused_default(dev) if fused is None else fused
    nb, hw = len(mvp), height * width
    keys = torch.full((nb * hw,), _KEY_BACKGROUND, dtype=torch.int64, device=dev)
    f = faces.long()
    max_candidates, max_face_views = _limits(dev)
    for g0, g1 in _view_groups(nb if len(f) else 0, len(f), max_face_views):
        sx, sy, w, z = project(verts, mvp[g0:g1], width, height)
        if fused and triton_kernels.rasterize_keys(keys, f, sx, sy, w, z, g0, width, height):
            continue
        fpack, ipack, count = _live_faces(f, sx, sy, w, z, width, height)
        del sx, sy, w, z
        csum = torch.cumsum(count, 0)
        first = csum - count
        start, n_live = 0, len(count)
        while start < n_live:
            base = int(first[start])
            stop = max(int(torch.searchsorted(csum, base + max_candidates, right=True)), start + 1)
            rep = torch.repeat_interleave(torch.arange(start, stop, device=dev), count[start:stop])
            k = torch.arange(base, base + len(rep), device=dev) - first[rep]
            ip, fp = ipack[rep], fpack[rep]
            nxr = ip[:, 2]
            col = ip[:, 0] + k % nxr
            row = ip[:, 1] + k // nxr
            px, py = col.to(torch.float64) + 0.5, row.to(torch.float64) + 0.5
            inside, lam = None, []
            for e in range(3):
                lx, ly, dx, dy = fp[:, 4 * e], fp[:, 4 * e + 1], fp[:, 4 * e + 2], fp[:, 4 * e + 3]
                ev = dx * (py - ly) - dy * (px - lx)  # canonical edge function
                es = ev * fp[:, 12 + e]
                ins = (es > 0) | ((es == 0) & (fp[:, 15 + e] > 0))
                inside = ins if inside is None else inside & ins
                lam.append(ev)
            inv_w = ((lam[1] * fp[:, 18] + lam[2] * fp[:, 19]) + lam[0] * fp[:, 20]) / fp[:, 21]
            inside &= inv_w > 0
            sel = torch.nonzero(inside).squeeze(1)
            d32 = (1.0 / inv_w[sel]).to(torch.float32)
            ips = ip[sel]
            key = (d32.view(torch.int32).to(torch.int64) << 32) | ips[:, 4]
            pix = (ips[:, 3] + g0) * hw + row[sel] * width + col[sel]
            keys.scatter_reduce_(0, pix, key, reduce="amin")
            start = stop
    hit = keys != _KEY_BACKGROUND
    tri = torch.where(hit, keys & 0xFFFFFFFF, torch.full_like(keys, -1)).to(torch.int32)
    depth = torch.where(hit, (keys >> 32).to(torch.int32).view(torch.float32),
                        torch.full((1,), float("inf"), device=dev))
    return tri.view(nb, height, width), depth.view(nb, height, width)
