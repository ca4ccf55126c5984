"""The run's report image: loss / PSNR history and the level histogram, drawn with numpy.

Written as a PNG into the cache folder and loaded as a Blender image, so it opens in an
Image Editor and stays next to the ``.blend``'s other data.
"""
from __future__ import annotations

import json

import bpy
import numpy as np

from . import writeback

W, H = 640, 360
BG, AXIS = (0.12, 0.12, 0.12), (0.5, 0.5, 0.5)
COLORS = [(0.95, 0.55, 0.15), (0.3, 0.7, 1.0)]


def _plot(img: np.ndarray, ys: np.ndarray, box, color) -> None:
    x0, y0, x1, y1 = box
    ys = np.asarray(ys, dtype=np.float64)
    ys = ys[np.isfinite(ys)]
    if len(ys) < 2:
        return
    lo, hi = ys.min(), ys.max()
    span = hi - lo if hi > lo else 1.0
    xs = np.linspace(x0, x1 - 1, 4 * (x1 - x0))
    yi = np.interp(xs, np.linspace(x0, x1 - 1, len(ys)), ys)
    py = (y0 + (yi - lo) / span * (y1 - y0 - 1)).astype(int)
    img[py, xs.astype(int)] = color
    img[np.minimum(py + 1, H - 1), xs.astype(int)] = color


def _bars(img: np.ndarray, counts: np.ndarray, box) -> None:
    x0, y0, x1, y1 = box
    n = len(counts)
    if n == 0 or counts.max() <= 0:
        return
    w = (x1 - x0) // n
    for i, c in enumerate(counts):
        h = int((y1 - y0) * c / counts.max())
        img[y0:y0 + h, x0 + i * w + 2:x0 + (i + 1) * w - 2] = writeback.LEVEL_COLORS[i][:3]


def render_report(obj: bpy.types.Object) -> np.ndarray:
    """(H, W, 4) float RGBA image (row 0 at the bottom, Blender's order)."""
    img = np.zeros((H, W, 4), np.float32)
    img[..., :3], img[..., 3] = BG, 1.0
    history = json.loads(obj.get("micromesh_history", "{}"))
    left, right = (20, 30, 420, 340), (450, 30, 620, 340)
    for box in (left, right):
        img[box[1], box[0]:box[2], :3] = AXIS
        img[box[1]:box[3], box[0], :3] = AXIS
    series = [history.get(k) for k in ("loss", "psnr") if isinstance(history.get(k), list)]
    for ys, col in zip(series, COLORS):
        _plot(img[..., :3], np.array([y if y is not None else np.nan for y in ys], float), left, col)
    out = writeback.load_outcome(obj)
    counts = np.bincount(out.micromesh.levels, minlength=6)[:6]
    _bars(img[..., :3], counts.astype(float), right)
    return img


def write_report(obj: bpy.types.Object, path: str) -> bpy.types.Image:
    pixels = render_report(obj)
    name = f"{obj.name}_report"
    img = bpy.data.images.get(name)
    if img is None or tuple(img.size) != (W, H):
        if img is not None:
            bpy.data.images.remove(img)
        img = bpy.data.images.new(name, W, H, alpha=True)
    img.pixels.foreach_set(pixels.reshape(-1))
    img.filepath_raw = path
    img.file_format = "PNG"
    img.save()
    return img
