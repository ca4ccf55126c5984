"""Micro-Mesh Builder: a Blender extension that turns a high-poly mesh into a displaced micro-mesh.

Blender loads this package as ``bl_ext.<repo>.micromesh``; scripts load it as ``micromesh``
through ``micromesh_path.ensure_package()``. Nothing heavy is imported here: the Blender glue
(operators, UI) is imported by :func:`register`, so core-only users pay nothing. Where the
Python dependencies are missing (a fresh Blender), only the preferences and a setup panel with
"Install Dependencies" are registered; the rest registers once they are installed.
"""
from __future__ import annotations

_glue: list = []


def register_glue() -> bool:
    """Register operators and panels if their dependencies import; True when registered."""
    if _glue:
        return True
    from .install import deps
    from .operators.prefs import site_dir

    deps.ensure_on_path(site_dir())
    if deps.missing_modules(deps.GLUE_MODULES):
        return False
    from .operators import registry
    from .ui import panels

    for module in (registry, panels):
        module.register()
        _glue.append(module)
    return True


def register() -> None:
    from .ui import preferences, setup_panel

    preferences.register(on_installed=register_glue)
    setup_panel.register()
    register_glue()


def unregister() -> None:
    from .ui import preferences, setup_panel

    while _glue:
        _glue.pop().unregister()
    setup_panel.unregister()
    preferences.unregister()
