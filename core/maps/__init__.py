"""Height and normal maps of a micro-mesh on a UV atlas of its base (``atlas``, ``bake``)."""
from .atlas import Atlas, AtlasError, dilate, texel_faces, uv_atlas
from .bake import (Maps, MapsCancelled, bake_maps, rebuild_error, rebuilt_positions, sample,
                   unit_directions, vertex_tangents)

__all__ = ["Atlas", "AtlasError", "Maps", "MapsCancelled", "bake_maps", "dilate",
           "rebuild_error", "rebuilt_positions", "sample", "texel_faces", "unit_directions",
           "uv_atlas", "vertex_tangents"]
