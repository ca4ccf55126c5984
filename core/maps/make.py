"""The maps of a result, as every caller makes them (Bake Maps, ``batch.py --maps``, the
benchmark): the atlas, the height map fitted to the source (``height_fit``) and the normal
map of the surface that height map draws (``bake.drawn_normal_map``)."""
from __future__ import annotations

from typing import Callable

from ..mesh.reference import oriented_reference
from ..mesh.trimesh import TriMesh
from ..micro.micromesh import MicroMesh
from .atlas import Atlas
from .blocks import block_atlas
from .bake import Maps, drawn_normal_map
from .height_fit import LEVEL, fit_height_map


def make_maps(mm: MicroMesh, reference: TriMesh | None, resolution: int,
              atlas: Atlas | None = None, level: int = LEVEL,
              progress: Callable[[dict], None] = lambda p: None,
              should_stop: Callable[[], bool] = lambda: False) -> Maps:
    """The maps of ``mm`` at ``resolution``² on ``atlas`` (default: a new ``block_atlas``,
    whose seams the fit closes by tying texels).

    Args:
        mm: the result (world space): its base and unit directions carry the maps.
        reference: the source as read (world space; cleaned here as the construction cleans
            it); None where it is gone: the height map is fitted to ``mm`` itself.
        resolution: a power of two within 64..16384.
        level: the tessellation level the height map is fitted for.
    Returns:
        :class:`Maps`: the fitted height, the normal map of the surface it draws at
        ``level``, the charts' texels, and the fit's notes (seam gaps among them).
    """
    if atlas is None:
        atlas = block_atlas(mm.base, resolution)
    if reference is None:
        reference = mm.tessellate().to_trimesh()
    else:
        reference = oriented_reference(reference)[0]
    hm = fit_height_map(mm, reference, atlas, resolution, level, progress=progress,
                        should_stop=should_stop)
    normal, filled = drawn_normal_map(mm, hm.surface, atlas, resolution,
                                      should_stop=should_stop)
    return Maps(atlas, hm.height, normal, filled, hm.notes)
