"""Height and normal maps of a micro-mesh on a UV atlas of its base (``atlas``, ``bake``), and
the source's textures carried onto that atlas (``transfer``; a tangent-space normal map:
``normal_transfer``)."""
from .atlas import Atlas, AtlasError, atlas_from_uvs, dilate, texel_faces, uv_atlas
from .bake import (Maps, MapsCancelled, bake_maps, rebuild_error, rebuilt_positions, sample,
                   unit_directions, vertex_tangents)
from .normal_transfer import transfer_normal_map
from .transfer import TransferError, transfer_texture, transfer_textures

__all__ = ["Atlas", "AtlasError", "Maps", "MapsCancelled", "TransferError", "atlas_from_uvs",
           "bake_maps", "dilate", "rebuild_error", "rebuilt_positions", "sample", "texel_faces",
           "transfer_normal_map", "transfer_texture", "transfer_textures", "unit_directions",
           "uv_atlas", "vertex_tangents"]
