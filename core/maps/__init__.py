"""Height and normal maps on a UV atlas of a micro-mesh's base (``atlas``; texel-aligned:
``blocks``): the height map fitted to the source as a renderer draws it (``height_fit``, over
the texels of ``texels``, its UV seams closed by tied texels, ``ties``, or constraint rows,
``seams``), the normal map and the micro-mesh's own heights baked from
a micro-surface (``bake``), and the source's textures carried onto that atlas in one pass
(``carry``; plain images: ``transfer``, a tangent-space normal map: ``normal_transfer``)."""
from .atlas import Atlas, AtlasError, atlas_from_uvs, dilate, texel_faces, uv_atlas
from .blocks import block_atlas
from .bake import (Maps, MapsCancelled, bake_maps, rebuild_error, rebuilt_positions, sample,
                   unit_directions, vertex_tangents)
from .carry import Carry, carry, transfer_normal_map, transfer_texture, transfer_textures
from .height_fit import HeightMap, fit_height_map
from .seams import SeamPoints, seam_gap_max, seam_points
from .texels import TexelGrid, bilinear_taps
from .transfer import TransferError

__all__ = ["Atlas", "AtlasError", "Carry", "HeightMap", "Maps", "MapsCancelled", "SeamPoints",
           "TexelGrid", "TransferError", "atlas_from_uvs", "bake_maps", "block_atlas", "bilinear_taps", "carry",
           "dilate", "fit_height_map", "rebuild_error", "rebuilt_positions", "sample",
           "seam_gap_max", "seam_points", "texel_faces", "transfer_normal_map",
           "transfer_texture", "transfer_textures", "unit_directions", "uv_atlas",
           "vertex_tangents"]
