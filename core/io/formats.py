"""The table of output formats: what a result can be written as, the files each writes beside
``NAME`` and its writer. ``batch.py``'s options, a result's output set and the export
operators all read it (trimesh's exporter table is the model): adding a format is one writer
and one :func:`register` call.

Two groups: the micro-mesh (``batch.py --export``: one of them) and the maps (``--maps``:
all of them). A writer is bpy-free: it takes the :class:`Product` and the result's name and
returns its files' bytes by suffix, and what the metrics record of them.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Callable

import numpy as np

from .images import HeightCode, exr_half, png

if TYPE_CHECKING:      # the writers import what they write with when they run: the table
    from ..maps import Maps                # is read at batch.py's start, before the heavy
    from ..micro.micromesh import MicroMesh      # imports

MICROMESH, MAPS = "micromesh", "maps"
# The source's textures carried onto the atlas, by glTF material slot: their files' suffixes.
TEXTURE_SUFFIXES = {"baseColorTexture": "_basecolor.png",
                    "metallicRoughnessTexture": "_metallicroughness.png",
                    "emissiveTexture": "_emissive.png"}


@dataclass(eq=False)
class Product:
    """What the writers draw from: the micro-mesh (world space) and its bounds, how its values
    are stored, and, for the maps, the maps, the normal map engines get and the carried
    textures ({glTF slot: (R, R, C) in [0, 1]}). ``y_up``: Blender's Z-up turned into glTF's
    and USD's Y-up."""

    micromesh: "MicroMesh"
    bounds: object = None
    y_up: bool = False
    values: str = "r11"
    layout: str = "bird"
    maps: "Maps | None" = None
    normal_map: np.ndarray | None = None
    textures: dict = field(default_factory=dict)

    @property
    def height_code(self) -> HeightCode:
        return HeightCode.spanning(self.maps.height)


Files = dict          # {suffix: bytes}


@dataclass(frozen=True)
class OutputFormat:
    """One row: ``key`` (``batch.py``'s name), ``group`` (:data:`MICROMESH` or :data:`MAPS`),
    ``label`` (what a menu shows), ``suffixes`` (the files beside NAME), ``optional`` (files
    written only where the product has them), ``write(product, name) -> (files, record)``."""

    key: str
    group: str
    label: str
    suffixes: tuple[str, ...]
    write: Callable[[Product, str], tuple[Files, dict]]
    optional: tuple[str, ...] = ()


FORMATS: dict[str, OutputFormat] = {}


def register(fmt: OutputFormat) -> OutputFormat:
    """Add ``fmt`` to the table (replacing a row of the same key)."""
    if fmt.group not in (MICROMESH, MAPS):
        raise ValueError(f"an output format's group is {MICROMESH!r} or {MAPS!r}")
    FORMATS[fmt.key] = fmt
    return fmt


def group(name: str) -> list[OutputFormat]:
    """The formats of one group, in the table's order."""
    return [f for f in FORMATS.values() if f.group == name]


def write(fmt: OutputFormat, product: Product, name: str) -> tuple[Files, dict]:
    """``fmt``'s files for ``product`` as ``name``, checked against its row."""
    files, record = fmt.write(product, name)
    unknown = set(files) - set(fmt.suffixes) - set(fmt.optional)
    if unknown:
        raise ValueError(f"the {fmt.key} writer wrote files its row does not name: "
                         f"{sorted(unknown)}")
    return files, record


def _by_suffix(name: str, written: list[tuple[Path, bytes]]) -> Files:
    return {p.name[len(name):]: data for p, data in written}


def _micromesh(container: str):
    def write_micromesh(product: Product, name: str) -> tuple[Files, dict]:
        from .micromesh_export import micromesh_files

        files, rep = micromesh_files(Path(name + container), product.micromesh, product.bounds,
                                     value_format=product.values, layout=product.layout,
                                     y_up=product.y_up)
        return _by_suffix(name, files), {
            "files": [p.name for p, _ in files], "bytes": rep.bytes, "values": product.values,
            "layout": product.layout, "quantization_max": rep.quantization_max,
            "quantization_rms": rep.quantization_rms}
    return write_micromesh


def _maps(product: Product) -> "Maps":
    if product.maps is None:
        raise ValueError("the maps' formats need maps (batch.py --maps, Bake Maps)")
    return product.maps


def _base_gltf(product: Product, name: str) -> tuple[Files, dict]:
    from .maps_files import base_gltf

    maps = _maps(product)
    textures = {slot: name + TEXTURE_SUFFIXES[slot] for slot in product.textures}
    files = _by_suffix(name, base_gltf(Path(name + "_base.gltf"), product.micromesh, maps,
                                       f"{name}_normal.png", f"{name}_height.png",
                                       product.height_code, y_up=product.y_up,
                                       textures=textures))
    for slot, pixels in product.textures.items():
        files[TEXTURE_SUFFIXES[slot]] = png(np.clip(pixels, 0.0, 1.0), bits=8)
    return files, {}


def _usd(product: Product, name: str) -> tuple[Files, dict]:
    from .usd import base_usda

    return _by_suffix(name, base_usda(Path(name + ".usda"), product.micromesh, _maps(product),
                                      f"{name}_height.png", f"{name}_normal.png",
                                      product.height_code, y_up=product.y_up)), {}


def _height_png(product: Product, name: str) -> tuple[Files, dict]:
    height = _maps(product).height
    code = product.height_code
    return {"_height.png": png(code.values(height))}, \
        {"height_offset": code.offset, "height_factor": code.factor}


def _height_exr(product: Product, name: str) -> tuple[Files, dict]:
    return {"_height.exr": exr_half(_maps(product).height)}, {}


def _normal_png(product: Product, name: str) -> tuple[Files, dict]:
    normal = product.normal_map if product.normal_map is not None else _maps(product).normal
    return {"_normal.png": png(normal)}, {}


register(OutputFormat("gltf", MICROMESH, "glTF Separate (.gltf + .bin + .bary)",
                      (".gltf", ".bin", ".bary"), _micromesh(".gltf")))
register(OutputFormat("glb", MICROMESH, "glTF Binary (.glb)", (".glb",), _micromesh(".glb")))
register(OutputFormat("height-png", MAPS, "Height map, 16-bit PNG (the glTF's and USD's)",
                      ("_height.png",), _height_png))
register(OutputFormat("height-exr", MAPS, "Height map, half-float OpenEXR (world units)",
                      ("_height.exr",), _height_exr))
register(OutputFormat("normal-png", MAPS, "Normal map, 16-bit PNG", ("_normal.png",),
                      _normal_png))
register(OutputFormat("base-gltf", MAPS, "Base + maps, glTF (KHR_materials_displacement)",
                      ("_base.gltf", "_base.bin"), _base_gltf,
                      optional=tuple(TEXTURE_SUFFIXES.values())))
register(OutputFormat("usd", MAPS, "Base + maps, USD (UsdPreviewSurface displacement)",
                      (".usda",), _usd))
