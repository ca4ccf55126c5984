"""Small helpers shared by the benchmarks: timing, tables, ``--json`` output, procedural meshes.

Run benchmarks from the repository root (``python bench/xxx.py``); importing this module puts
the root on ``sys.path`` so ``core`` imports work.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

MESHES = Path(os.environ.get("MICROMESH_MESHES", ROOT.parent / "shared" / "meshes"))


def parser(description: str) -> argparse.ArgumentParser:
    """An argument parser with the common ``--json FILE`` and ``--threads N`` options."""
    p = argparse.ArgumentParser(description=description)
    p.add_argument("--json", metavar="FILE", help="write the records as JSON to FILE")
    p.add_argument("--threads", type=int, default=0, help="thread count (default: usable cores)")
    return p


def timed(fn: Callable[[], Any]) -> tuple[float, Any]:
    """(seconds, result) of one call."""
    t0 = time.perf_counter()
    out = fn()
    return time.perf_counter() - t0, out


def median_time(fn: Callable[[], Any], repeat: int = 5, warmup: int = 1,
                max_seconds: float | None = None) -> float:
    """Median wall time of ``repeat`` calls after ``warmup`` untimed ones.

    With ``max_seconds``, stops repeating once that much time was spent (at least one call).
    """
    for _ in range(warmup):
        fn()
    times: list[float] = []
    start = time.perf_counter()
    for _ in range(max(1, repeat)):
        times.append(timed(fn)[0])
        if max_seconds is not None and time.perf_counter() - start > max_seconds:
            break
    return float(np.median(times))


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        if v != v:
            return "nan"
        if v == 0:
            return "0"
        a = abs(v)
        if a >= 1e5 or a < 1e-3:
            return f"{v:.3g}"
        return f"{v:.4g}"
    return str(v)


def print_table(rows: Sequence[dict], columns: Iterable[str] | None = None, title: str | None = None) -> str:
    """Print (and return) rows of dicts as an aligned text table; missing cells are blank."""
    cols = list(columns) if columns is not None else list(dict.fromkeys(k for r in rows for k in r))
    cells = [[_fmt(r.get(c, "")) for c in cols] for r in rows]
    width = [max([len(c)] + [len(row[i]) for row in cells]) for i, c in enumerate(cols)]
    lines = []
    if title:
        lines.append(title)
    lines.append("  ".join(c.rjust(w) for c, w in zip(cols, width)))
    lines.append("  ".join("-" * w for w in width))
    lines += ["  ".join(x.rjust(w) for x, w in zip(row, width)) for row in cells]
    text = "\n".join(lines)
    print(text, flush=True)
    return text


def environment() -> dict:
    """Machine facts recorded next to the figures."""
    import scipy

    info = {"python": platform.python_version(), "machine": platform.machine(),
            "cpu_count": os.cpu_count(), "numpy": np.__version__, "scipy": scipy.__version__}
    try:
        import torch

        info["torch"] = torch.__version__
        info["torch_threads"] = torch.get_num_threads()
    except ImportError:
        pass
    return info


def write_json(path: str | os.PathLike | None, records: Sequence[dict], **meta: Any) -> None:
    """Write ``{"meta": ..., "records": [...]}`` to ``path`` (no-op for None)."""
    if not path:
        return
    doc = {"meta": {"argv": sys.argv, "time": time.strftime("%Y-%m-%dT%H:%M:%S"),
                    **environment(), **meta}, "records": list(records)}
    Path(path).write_text(json.dumps(doc, indent=2, default=_json_default))
    print(f"wrote {path}")


def _json_default(o: Any) -> Any:
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    return str(o)


# ----------------------------------------------------------------- procedural meshes
def icosahedron() -> tuple[np.ndarray, np.ndarray]:
    """Unit icosahedron (12 vertices, 20 outward-oriented faces)."""
    t = (1 + 5 ** 0.5) / 2
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
                  [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], float)
    f = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
                  [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
                  [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]], np.int64)
    return v / np.linalg.norm(v, axis=1, keepdims=True), f


def subdivided_icosahedron(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Icosahedron with each edge split into ``n`` segments (flat, not projected).

    10·n² + 2 vertices and 20·n² faces; vertices shared between faces are merged exactly.
    """
    if n < 1 or n >= 4096:
        raise ValueError("n must be in [1, 4095]")
    V, F = icosahedron()
    ii, jj = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
    keep = ii + jj <= n
    i, j = ii[keep], jj[keep]  # weights of corners 1 and 2; corner 0 gets n - i - j
    k = n - i - j
    local = -np.ones((n + 1, n + 1), np.int64)
    local[i, j] = np.arange(len(i))
    # Exact shared-vertex keys: sorted (corner id, weight) pairs, zero weights as id 12.
    w = np.stack([np.broadcast_to(k, (20, len(i))), np.broadcast_to(i, (20, len(i))),
                  np.broadcast_to(j, (20, len(i)))], axis=2)          # (20, p, 3)
    ids = np.where(w > 0, F[:, None, :], 12)
    pair = (ids << 12) | np.where(w > 0, w, 0)
    key = np.sort(pair, axis=2)
    key = (key[..., 0] << 32) | (key[..., 1] << 16) | key[..., 2]
    uniq, first, inv = np.unique(key.ravel(), return_index=True, return_inverse=True)
    pos = (w[..., :, None] * V[F][:, None, :, :]).sum(2) / n          # (20, p, 3)
    verts = pos.reshape(-1, 3)[first]
    gidx = inv.reshape(20, -1)
    a, b = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    up = a + b <= n - 1
    dn = a + b <= n - 2
    tri_up = np.stack([local[a[up], b[up]], local[a[up] + 1, b[up]], local[a[up], b[up] + 1]], 1)
    tri_dn = np.stack([local[a[dn] + 1, b[dn]], local[a[dn] + 1, b[dn] + 1], local[a[dn], b[dn] + 1]], 1)
    tri = np.concatenate([tri_up, tri_dn])
    faces = np.concatenate([gidx[fi][tri] for fi in range(20)])
    return verts, faces


def icosphere(n: int, radius: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Subdivided icosahedron projected onto a sphere: 10·n² + 2 vertices."""
    v, f = subdivided_icosahedron(n)
    return radius * v / np.linalg.norm(v, axis=1, keepdims=True), f


def icosphere_with_vertices(n_vertices: int, radius: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """The icosphere whose vertex count is nearest ``n_vertices``."""
    return icosphere(max(1, round(((n_vertices - 2) / 10) ** 0.5)), radius)


def noisy_sphere(n_faces: int, amplitude: float = 0.05, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Icosphere with about ``n_faces`` faces, radius modulated by smooth random waves."""
    v, f = icosphere(max(1, round((n_faces / 20) ** 0.5)))
    rng = np.random.default_rng(seed)
    r = np.ones(len(v))
    for _ in range(12):
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        r += amplitude / 4 * np.sin(rng.uniform(3, 25) * (v @ d) + rng.uniform(0, 2 * np.pi))
    return v * r[:, None], f
