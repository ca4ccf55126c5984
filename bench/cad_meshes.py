"""CAD-like test parts, as a CAD program's STL export draws them: flat faces triangulated from
their boundary points only (long, thin triangles), holes and outlines as polygons, sharp
90° edges and filleted rims.

A part is an outline (a closed 2D loop, counter-clockwise) with holes (clockwise loops),
extruded between z = 0 and ``thickness``; ``fillet`` rounds the top edge of every loop with
a quarter circle of that radius (``rings`` steps). The top and bottom faces are a Delaunay
triangulation of the loops' points alone, split until every loop edge is one of its edges
(a conforming triangulation) and kept inside the outline and outside the holes.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import Delaunay


def rounded_rectangle(w: float, h: float, r: float, per_corner: int) -> np.ndarray:
    """(k, 2) a w × h rectangle about the origin with corners of radius ``r``, CCW: each
    corner an arc of ``per_corner`` segments, each side one straight edge."""
    pts = []
    for cx, cy, a0 in ((w / 2 - r, h / 2 - r, 0.0), (-w / 2 + r, h / 2 - r, 0.5 * np.pi),
                       (-w / 2 + r, -h / 2 + r, np.pi), (w / 2 - r, -h / 2 + r, 1.5 * np.pi)):
        a = a0 + np.linspace(0, 0.5 * np.pi, per_corner + 1)
        pts.append(np.stack([cx + r * np.cos(a), cy + r * np.sin(a)], 1))
    return np.concatenate(pts)


def circle(cx: float, cy: float, r: float, segments: int) -> np.ndarray:
    """(segments, 2) a hole's loop: clockwise."""
    a = -2 * np.pi * np.arange(segments) / segments
    return np.stack([cx + r * np.cos(a), cy + r * np.sin(a)], 1)


def _inward(loop: np.ndarray) -> np.ndarray:
    """(k, 2) each point's unit normal into the material (left of a CCW outline's walk,
    which is also the material's side of a clockwise hole)."""
    t = np.roll(loop, -1, 0) - np.roll(loop, 1, 0)
    n = np.stack([-t[:, 1], t[:, 0]], 1)
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def _cap(loops: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The flat face bounded by ``loops`` (outline first): (points (k, 2), triangles (t, 3)
    CCW seen from +z, the loops as split). Loop edges missing from the Delaunay
    triangulation are split at their middle until none is missing; the points are the split
    loops' own, in order."""
    loops = [np.asarray(l, float) for l in loops]
    for _ in range(20):
        pts = np.concatenate(loops)
        starts = np.cumsum([0] + [len(l) for l in loops])
        tri = Delaunay(pts).simplices
        have = {tuple(sorted(e)) for t in tri for e in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0]))}
        split = False
        for i, l in enumerate(loops):
            idx = np.arange(starts[i], starts[i + 1])
            missing = [k for k in range(len(l))
                       if tuple(sorted((idx[k], idx[(k + 1) % len(l)]))) not in have]
            if missing:
                split = True
                new = []
                for k in range(len(l)):
                    new.append(l[k])
                    if k in missing:
                        new.append(0.5 * (l[k] + l[(k + 1) % len(l)]))
                loops[i] = np.array(new)
        if not split:
            break
    else:
        raise RuntimeError("the loops did not conform")
    c = pts[tri].mean(1)
    inside = _winding(loops[0], c) != 0
    for hole in loops[1:]:
        inside &= _winding(hole, c) == 0
    tri = tri[inside]
    a = pts[tri]
    cross = np.cross(a[:, 1] - a[:, 0], a[:, 2] - a[:, 0])
    tri[cross < 0] = tri[cross < 0][:, ::-1]
    return pts, tri, loops


def _winding(loop: np.ndarray, p: np.ndarray) -> np.ndarray:
    """The winding number of ``loop`` around each point ``p`` (n, 2)."""
    a = loop[None, :, :] - p[:, None, :]
    b = np.roll(loop, -1, 0)[None, :, :] - p[:, None, :]
    ang = np.arctan2(a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0],
                     (a * b).sum(-1))
    return np.rint(ang.sum(1) / (2 * np.pi)).astype(int)


def extruded(outline: np.ndarray, holes: list[np.ndarray], thickness: float,
             fillet: float = 0.0, rings: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """A closed part: ``outline`` with ``holes`` between z = 0 and ``thickness``, the top
    edge of every loop rounded by ``fillet`` (see the module doc); (vertices, faces),
    outward oriented, one vertex per position."""
    bottom_pts, bottom_tri, loops = _cap([outline] + list(holes))
    top_loops = [l + fillet * _inward(l) for l in loops] if fillet > 0 else loops
    top_pts, top_tri, top_loops = _cap(top_loops)
    if any(len(a) != len(b) for a, b in zip(loops, top_loops)):
        raise RuntimeError("the top and the bottom loops differ; lower the fillet")
    verts, faces = [], []
    n = 0

    def add(p: np.ndarray) -> np.ndarray:
        nonlocal n
        verts.append(p)
        idx = np.arange(n, n + len(p))
        n += len(p)
        return idx

    b_idx = add(np.column_stack([bottom_pts, np.zeros(len(bottom_pts))]))
    faces.append(b_idx[bottom_tri[:, ::-1]])                      # facing -z
    t_idx = add(np.column_stack([top_pts, np.full(len(top_pts), thickness)]))
    faces.append(t_idx[top_tri])
    bs = np.cumsum([0] + [len(l) for l in loops])
    for i, loop in enumerate(loops):
        ring = [b_idx[bs[i]:bs[i + 1]]]                           # the bottom face's loop
        steps = [(0.0, thickness - fillet)] if fillet > 0 else []
        steps += [(fillet * (1 - np.cos(a)), thickness - fillet + fillet * np.sin(a))
                  for a in np.linspace(0, 0.5 * np.pi, rings + 1)[1:-1]] if fillet > 0 else []
        nrm = _inward(loop)
        for off, z in steps:
            ring.append(add(np.column_stack([loop + off * nrm, np.full(len(loop), z)])))
        ring.append(t_idx[bs[i]:bs[i + 1]])                       # the top face's loop
        for lo, hi in zip(ring[:-1], ring[1:]):
            a, b = lo, np.roll(lo, -1)
            c, d = hi, np.roll(hi, -1)
            # the wall faces outward: away from the material, right of the walk
            faces.append(np.stack([a, b, c], 1))
            faces.append(np.stack([b, d, c], 1))
    return np.concatenate(verts), np.concatenate(faces).astype(np.int64)


def cad_plate(genus: int, segments: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A 200 × 120 × 8 mm plate with rounded corners and ``genus`` round holes of mixed
    sizes on a jittered grid, each hole's top rim filleted (1 mm)."""
    rng = np.random.default_rng(seed)
    cols = int(np.ceil(np.sqrt(genus * 200 / 120)))
    rows = int(np.ceil(genus / cols))
    pitch = min(180 / cols, 100 / rows)
    holes = []
    for k in range(genus):
        i, j = k % cols, k // cols
        cx = (i - (cols - 1) / 2) * pitch + rng.uniform(-0.08, 0.08) * pitch
        cy = (j - (rows - 1) / 2) * pitch + rng.uniform(-0.08, 0.08) * pitch
        r = pitch * rng.uniform(0.18, 0.32)
        holes.append(circle(cx, cy, r, segments))
    return extruded(rounded_rectangle(200, 120, 10, 8), holes, 8.0, fillet=1.0, rings=3)


def bracket(segments: int) -> tuple[np.ndarray, np.ndarray]:
    """A 100 × 60 mm mounting bracket, 12 mm thick, with rounded corners, two 24 mm bores
    and two 10 mm bolt holes, every top rim filleted (2 mm): a mechanical part of genus 4."""
    holes = [circle(sx * 22, 0, 12, segments) for sx in (-1, 1)]
    holes += [circle(sx * 40, sy * 18, 5, segments // 2) for sx, sy in ((-1, 1), (1, -1))]
    return extruded(rounded_rectangle(100, 60, 12, 16), holes, 12.0, fillet=2.0, rings=6)
