"""The micro-mesh: :class:`MicroMesh` (base, directions, per-face levels, one displacement per
micro-vertex), its index space (``topology``), one triangle's grids (``level_grid``), levels on
a base (``levels``), points located on it (``locate``), direction bounds and the shell
(``bounds``, ``least_volume``) and its measures (``metrics``)."""
from .micromesh import MicroMesh, MicroMeshError
from .topology import MicroTopology, build_topology

__all__ = ["MicroMesh", "MicroMeshError", "MicroTopology", "build_topology"]
