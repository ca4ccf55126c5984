"""Add-on preferences: compute device, thread count, cache folder, optional dependencies.

Threads go through ``core.runtime.threads.set_threads`` (the one place that pins torch's and our
pools). The cache folder defaults to the extension's user folder
(``bpy.utils.extension_path_user``), which Blender keeps across upgrades of the extension.
"""
from __future__ import annotations

import os

import bpy
from bpy.props import EnumProperty, IntProperty, StringProperty

from .install import deps
from .install.platforms import PLATFORMS
from .operators import install_op

# The CUDA build's download (install/platforms.py, measured by bench/install_sizes.py).
_CUDA_GB = max(p.cuda_download_mb for p in PLATFORMS) / 1000

PACKAGE = __package__


def get_prefs() -> "MICROMESH_AP_preferences | None":
    addon = bpy.context.preferences.addons.get(PACKAGE)
    return addon.preferences if addon else None


def cache_dir() -> str:
    """The cache folder: the preference if set, else ``<extension user folder>/cache``."""
    prefs = get_prefs()
    if prefs and prefs.cache_dir:
        path = bpy.path.abspath(prefs.cache_dir)
    else:
        try:
            path = bpy.utils.extension_path_user(PACKAGE, path="cache", create=True)
        except (ValueError, RuntimeError):  # loaded as a script package, not an extension
            path = os.path.join(bpy.app.tempdir or "/tmp", "micromesh_cache")
    os.makedirs(path, exist_ok=True)
    return path


def device() -> str:
    prefs = get_prefs()
    return prefs.device.lower() if prefs else "auto"


def apply_threads() -> int:
    """Pin the native pools to the preference's thread count (0: all cores); returns it."""
    from .core.runtime.threads import set_threads

    prefs = get_prefs()
    return set_threads(prefs.threads if prefs else 0)


class MICROMESH_AP_preferences(bpy.types.AddonPreferences):
    bl_idname = PACKAGE

    device: EnumProperty(name="Device", default="AUTO", items=[
        ("AUTO", "Auto", "CUDA when torch sees a GPU, else CPU"),
        ("CPU", "CPU", "Always the CPU"),
        ("CUDA", "CUDA", "An NVIDIA GPU through torch (fails if none)")])
    threads: IntProperty(name="Threads", default=0, min=0, max=256,
                         description="CPU threads for torch and the kernels (0: all usable cores)")
    cache_dir: StringProperty(name="Cache Folder", subtype="DIR_PATH", default="",
                              description="Where reports and caches go (empty: the extension's user folder)")
    torch_build: EnumProperty(name="torch", default="CPU", items=[
        ("CPU", "CPU build", "PyTorch's CPU build: about 190 MB to download, 750 MB installed"),
        ("CUDA", "CUDA build", "The default PyPI build, with CUDA on Linux (NVIDIA GPUs): "
                               f"about {_CUDA_GB:.1f} GB to download")],
        description="Which torch Install Dependencies fetches")

    def draw(self, context):
        col = self.layout.column()
        col.prop(self, "device")
        col.prop(self, "threads")
        col.prop(self, "cache_dir")
        box = self.layout.box()
        missing = deps.missing_modules()
        if missing:
            box.label(text="Missing Python modules: " + ", ".join(missing), icon="ERROR")
            box.label(text="Target folder: " + deps.site_dir())
        else:
            box.label(text="All Python dependencies found", icon="CHECKMARK")
        install_op.draw_install(box, self, offer=bool(missing))


CLASSES = (MICROMESH_AP_preferences,)


_register, _unregister = bpy.utils.register_classes_factory(CLASSES)


def register() -> None:
    install_op.register()
    _register()


def unregister() -> None:
    _unregister()
    install_op.unregister()
