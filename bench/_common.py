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


def add_child_option(p: argparse.ArgumentParser) -> None:
    """The hidden ``--child JSON`` option of benchmarks that run each case in a process of
    their own (the parent passes the case's keyword arguments)."""
    p.add_argument("--child", help=argparse.SUPPRESS)


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


# Procedural meshes live in core.mesh.primitives; re-exported for the benchmarks.
from core.mesh.primitives import (  # noqa: E402,F401
    icosahedron, icosphere, icosphere_with_vertices, noisy_sphere, subdivided_icosahedron, torus,
)
