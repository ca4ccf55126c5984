"""The add-on's preferences: compute device, thread count, cache folder, which torch build
Install Dependencies fetches, and the dependencies' status (``operators.prefs`` reads them).
"""
from __future__ import annotations

import bpy
from bpy.props import EnumProperty, IntProperty, StringProperty

from ..install import deps
from ..install.platforms import PLATFORMS
from ..operators import install_op
from ..operators.prefs import PACKAGE, site_dir

# The CUDA build's download (install/platforms.py, measured by bench/install_sizes.py).
_CUDA_GB = max(p.cuda_download_mb for p in PLATFORMS) / 1000


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
            box.label(text="Target folder: " + site_dir())
        else:
            box.label(text="All Python dependencies found", icon="CHECKMARK")
        install_op.draw_install(box, self, offer=bool(missing))


CLASSES = (MICROMESH_AP_preferences,)


_register, _unregister = bpy.utils.register_classes_factory(CLASSES)


def register(on_installed=None) -> None:
    """The preferences and Install Dependencies; ``on_installed()`` after an install."""
    install_op.register(on_installed)
    _register()


def unregister() -> None:
    _unregister()
    install_op.unregister()
