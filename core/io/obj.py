"""OBJ meshes: vertices and faces (polygons as fans; texture and normal indices ignored)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .polygons import MeshFileError, fan


def read_obj(path: Path) -> tuple[np.ndarray, np.ndarray]:
    verts: list[list[float]] = []
    polys: list[np.ndarray] = []
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as e:
        raise MeshFileError(f"{path}: cannot read ({e})") from None
    for lineno, line in enumerate(text.splitlines(), 1):
        tok = line.split()
        if not tok:
            continue
        try:
            if tok[0] == "v":
                verts.append([float(t) for t in tok[1:4]])
                if len(verts[-1]) != 3:
                    raise ValueError
            elif tok[0] == "f":
                idx = np.array([int(t.split("/")[0]) for t in tok[1:]], dtype=np.int64)
                if (idx == 0).any() or len(idx) < 3:
                    raise ValueError
                # 1-based; negative indices count back from the vertices read so far.
                polys.append(np.where(idx < 0, len(verts) + idx, idx - 1))
        except ValueError:
            raise MeshFileError(f"{path}:{lineno}: bad OBJ line {line.strip()!r}") from None
    if not verts or not polys:
        raise MeshFileError(f"{path}: OBJ has no vertices or no faces")
    lens = {len(p) for p in polys}
    faces = fan(np.stack(polys)) if len(lens) == 1 else fan(polys)
    return np.asarray(verts, dtype=np.float64), faces
