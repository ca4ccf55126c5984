"""Triangle meshes: :class:`TriMesh` (float64 vertices, int64 faces, cached topology), and what
is done to a mesh as a whole: welding coincident vertices (``weld``), consistent winding
(``orient``), the unit-sphere frame (``normalization``), a float32-exact storage origin
(``float32_origin``) and procedural shapes with known geometry (``primitives``)."""
from .trimesh import MeshError, TriMesh

__all__ = ["MeshError", "TriMesh"]
