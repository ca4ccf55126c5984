"""The add-on's preferences as the operators read them: compute device, thread count, cache
folder, and the dependency folder (``ui.preferences`` draws and registers them).

Threads go through ``core.runtime.threads.set_threads`` (the one place that pins torch's and our
pools). The cache folder defaults to the extension's user folder
(``bpy.utils.extension_path_user``), which Blender keeps across upgrades of the extension.
"""
from __future__ import annotations

import os

import bpy

PACKAGE = __package__.rsplit(".", 1)[0]           # the add-on's package


def get_prefs() -> "bpy.types.AddonPreferences | None":
    addon = bpy.context.preferences.addons.get(PACKAGE)
    return addon.preferences if addon else None


def site_dir() -> str:
    """The folder the Python dependencies are installed into: ``<extension user
    folder>/site-packages`` (``install.deps``)."""
    from ..install.deps import FALLBACK_SITE

    try:
        return bpy.utils.extension_path_user(PACKAGE, path="site-packages", create=True)
    except (ValueError, RuntimeError):  # not loaded as an extension (scripts, tests)
        return FALLBACK_SITE


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
    from ..core.runtime.threads import set_threads

    prefs = get_prefs()
    return set_threads(prefs.threads if prefs else 0)
