"""Micro-Mesh Builder: a Blender extension that turns a high-poly mesh into a displaced micro-mesh.

Blender loads this package as ``bl_ext.<repo>.micromesh``; scripts load it as ``micromesh``
through ``micromesh_path.ensure_package()``. Nothing heavy is imported here: the Blender glue
(operators, UI, preferences) is imported by :func:`register`, so core-only users pay nothing.
"""
from __future__ import annotations


def _modules():
    from . import preferences
    from .operators import registry
    from .ui import panels
    return [preferences, registry, panels]


def register() -> None:
    for module in _modules():
        module.register()


def unregister() -> None:
    for module in reversed(_modules()):
        module.unregister()
