"""Images the add-on makes (maps, carried textures): from arrays, saved once as a file and
read back (Blender packs files, not buffers), packed into the ``.blend`` or left at a path."""
from __future__ import annotations

import os
import tempfile

import bpy
import numpy as np


def image(name: str, pixels: np.ndarray, path: str | None = None,
          colorspace: str = "Non-Color", float_buffer: bool = True) -> bpy.types.Image:
    """An image (replacing one of that name) from (H, W), (H, W, 3) or (H, W, 4) values, row 0
    at the bottom (alpha 1 where none is given): an OpenEXR (full float) for ``float_buffer``,
    else a PNG, in ``colorspace``; written to ``path`` when given, else packed."""
    old = bpy.data.images.get(name)
    if old is not None:
        bpy.data.images.remove(old)
    h, w = pixels.shape[:2]
    values = pixels[..., None] if pixels.ndim == 2 else pixels
    img = bpy.data.images.new(name, w, h, alpha=values.shape[2] == 4, float_buffer=float_buffer)
    img.colorspace_settings.name = colorspace     # first: a change regenerates the pixels
    rgba = np.ones((h, w, 4), np.float32)
    rgba[..., :max(3, values.shape[2])] = values  # grey values fill r, g and b
    img.pixels.foreach_set(rgba.reshape(-1))
    ext, fmt = (".exr", "OPEN_EXR") if float_buffer else (".png", "PNG")
    with tempfile.TemporaryDirectory() as tmp:
        target = path or os.path.join(tmp, name + ext)
        img.filepath_raw, img.file_format = target, fmt
        if float_buffer:
            img.use_half_precision = False
        img.save()
        bpy.data.images.remove(img)
        img = bpy.data.images.load(target)
        img.name = name
        img.colorspace_settings.name = colorspace
        if path is None:
            img.pack()
            img.filepath_raw = f"//{name}{ext}"
    return img
