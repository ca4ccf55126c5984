"""Add-on preferences: compute device, thread count, cache folder, optional dependencies.

Threads go through ``core.threads.set_threads`` (the one place that pins torch's and numba's
pools). The cache folder defaults to the extension's user folder
(``bpy.utils.extension_path_user``), which Blender keeps across upgrades of the extension.
"""
from __future__ import annotations

import os

import bpy
from bpy.props import EnumProperty, IntProperty, StringProperty

from .operators import deps

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
    from .core.threads import set_threads

    prefs = get_prefs()
    return set_threads(prefs.threads if prefs else 0)


class MICROMESH_OT_install_dependencies(bpy.types.Operator):
    """Install torch, scipy, numba and Embree into the extension's user folder with pip"""
    bl_idname = "micromesh.install_dependencies"
    bl_label = "Install Dependencies"

    def execute(self, context):
        if not bpy.app.online_access:
            self.report({"ERROR"}, "Online access is disabled (Preferences > System > Network)")
            return {"CANCELLED"}
        r = deps.install()
        if r.returncode != 0:
            self.report({"ERROR"}, "pip failed: " + (r.stderr.strip().splitlines() or ["?"])[-1])
            return {"CANCELLED"}
        missing = deps.missing_modules()
        if missing:
            self.report({"WARNING"}, "Still missing: " + ", ".join(missing))
            return {"FINISHED"}
        from . import register_glue

        register_glue()
        self.report({"INFO"}, "Dependencies installed in " + deps.site_dir())
        return {"FINISHED"}


class MICROMESH_AP_preferences(bpy.types.AddonPreferences):
    bl_idname = PACKAGE

    device: EnumProperty(name="Device", default="AUTO", items=[
        ("AUTO", "Auto", "CUDA when torch sees a GPU, else CPU"),
        ("CPU", "CPU", "Always the CPU"),
        ("CUDA", "CUDA", "An NVIDIA GPU through torch (fails if none)")])
    threads: IntProperty(name="Threads", default=0, min=0, max=256,
                         description="CPU threads for torch and numba (0: all usable cores)")
    cache_dir: StringProperty(name="Cache Folder", subtype="DIR_PATH", default="",
                              description="Where reports and caches go (empty: the extension's user folder)")

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
            box.operator("micromesh.install_dependencies", icon="IMPORT")
        else:
            box.label(text="All Python dependencies found", icon="CHECKMARK")


CLASSES = (MICROMESH_OT_install_dependencies, MICROMESH_AP_preferences)


register, unregister = bpy.utils.register_classes_factory(CLASSES)
