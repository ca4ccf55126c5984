"""Height and normal maps of a micro-mesh on a UV atlas of its base (``atlas``, ``bake``), and
the source's textures carried onto that atlas in one pass (``carry``; plain images:
``transfer``, a tangent-space normal map: ``normal_transfer``)."""
from .atlas import Atlas, AtlasError, atlas_from_uvs, dilate, texel_faces, uv_atlas
from .bake import (Maps, MapsCancelled, bake_maps, rebuild_error, rebuilt_positions, sample,
                   unit_directions, vertex_tangents)
from .carry import Carry, carry, transfer_normal_map, transfer_texture, transfer_textures
from .transfer import TransferError

__all__ = ["Atlas", "AtlasError", "Carry", "Maps", "MapsCancelled", "TransferError", "atlas_from_uvs",
           "bake_maps", "carry", "dilate", "rebuild_error", "rebuilt_positions", "sample", "texel_faces",
           "transfer_normal_map", "transfer_texture", "transfer_textures", "unit_directions",
           "uv_atlas", "vertex_tangents"]
