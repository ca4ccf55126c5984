"""What a micro-mesh file says, as arrays (``MicromeshFile``), and the :class:`MicroMesh` it
makes: bounds baked in, one value per micro-vertex, the file's own inconsistencies warned
about. ``micromesh_import`` fills it from glTF + ``.bary``."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..mesh.trimesh import TriMesh
from ..micro.micromesh import MicroMesh, MicroMeshError
from ..micro.level_grid import LevelError, snap_targets
from ..micro.levels import edge_flags, is_balanced


class MicromeshFileError(ValueError):
    """A micro-mesh file that cannot be read, with why."""


@dataclass(eq=False)
class MicromeshFile:
    """Everything a file says, per base triangle in file order; ``values`` per face in u-major
    order (CSR ``ptr``), decoded (group bias/scale applied); ``bias``/``scale`` the direction
    bounds (zeros/ones where the file has none)."""

    positions: np.ndarray   # (nv, 3)
    faces: np.ndarray       # (nf, 3)
    directions: np.ndarray  # (nv, 3)
    bias: np.ndarray        # (nv,)
    scale: np.ndarray       # (nv,)
    levels: np.ndarray      # (nf,)
    flags: np.ndarray       # (nf,) edge bits
    ptr: np.ndarray         # (nf+1,)
    values: np.ndarray
    warnings: list[str] = field(default_factory=list)
    _micromesh: MicroMesh | None = field(default=None, repr=False)

    def micromesh(self) -> MicroMesh:
        """The file as a :class:`MicroMesh`: base P + D·bias, directions D·scale (bounds baked
        in, as micromesh-tools writes them), one value per micro-vertex. Shared-edge values that
        differ between the two triangles and flags that disagree with the levels are warned
        about in ``warnings`` (once: the micro-mesh is built on the first call)."""
        if self._micromesh is not None:
            return self._micromesh
        base = TriMesh(self.positions + self.directions * self.bias[:, None], self.faces)
        try:
            if not is_balanced(base, self.levels):
                raise MicromeshFileError("subdivision levels differ by more than one across "
                                         "an edge: not a watertight micro-mesh")
            mm = MicroMesh.flat(base, self.levels, self.directions * self.scale[:, None])
        except (LevelError, MicroMeshError) as e:
            raise MicromeshFileError(f"the file's base mesh and levels do not fit: {e}") from None
        t = mm.topology
        own = np.ones(len(t.face_vertex_idx), bool)   # local vertices not snapped away
        for level in np.unique(self.levels):
            for fg in np.unique(self.flags[self.levels == level]):
                tgt = snap_targets(int(level), int(fg))
                faces = np.flatnonzero((self.levels == level) & (self.flags == fg))
                rows = t.face_vertex_ptr[faces][:, None] + np.arange(len(tgt))
                own[rows.reshape(-1)] = np.tile(tgt == np.arange(len(tgt)), len(faces))
        idx, vals = t.face_vertex_idx[own], self.values[own]
        d = np.zeros(mm.n_vertices)
        d[idx[::-1]] = vals[::-1]                    # the first face holding a vertex wins
        # where two triangles store different values for one micro-vertex it lands in two
        # places (unless its direction is zero there): a gap in the file's own tessellation
        diag = float(np.linalg.norm(np.ptp(base.vertices, axis=0))) or 1.0
        lengths = np.linalg.norm(mm.micro_vertex_directions(), axis=1)
        gap = np.abs(vals - d[idx]) * lengths[idx] / diag
        if gap.max(initial=0.0) > 1e-7:
            n = len(np.unique(idx[gap > 1e-7]))
            self.warnings.append(f"{n} shared micro-vertices have different values in their "
                                 f"triangles (gaps up to {gap.max():.2g} of the diagonal): the "
                                 "file's own tessellation is open there; the first value is used")
        wrong = int((edge_flags(base, self.levels) != (self.flags & 7)).sum())
        if wrong:
            self.warnings.append(f"{wrong} triangles' edge flags disagree with their "
                                 "neighbours' levels; the flags implied by the levels are used")
        self._micromesh = mm.with_displacements(d)
        return self._micromesh


def merge(parts: list[MicromeshFile]) -> MicromeshFile:
    """Several primitives' files as one (faces and values renumbered)."""
    if len(parts) == 1:
        return parts[0]
    offs = np.cumsum([0] + [len(p.positions) for p in parts])
    ptr = [parts[0].ptr]
    for p in parts[1:]:
        ptr.append(p.ptr[1:] + ptr[-1][-1])
    cat = np.concatenate
    return MicromeshFile(cat([p.positions for p in parts]),
                         cat([p.faces + o for p, o in zip(parts, offs)]),
                         cat([p.directions for p in parts]), cat([p.bias for p in parts]),
                         cat([p.scale for p in parts]), cat([p.levels for p in parts]),
                         cat([p.flags for p in parts]), cat(ptr), cat([p.values for p in parts]))
