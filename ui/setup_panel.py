"""The "Micro-Mesh" tab before the Python dependencies are installed (imports nothing heavy)."""
from __future__ import annotations

import bpy

from ..install import deps
from ..operators import install_op


class MICROMESH_PT_setup(bpy.types.Panel):
    bl_label = "Micro-Mesh Setup"
    bl_idname = "MICROMESH_PT_setup"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Micro-Mesh"

    @classmethod
    def poll(cls, context):
        return bool(deps.missing_modules())

    def draw(self, context):
        box = self.layout.box()
        box.label(text="Missing: " + ", ".join(deps.missing_modules()), icon="ERROR")
        install_op.draw_install(box)


def register():
    bpy.utils.register_class(MICROMESH_PT_setup)


def unregister():
    bpy.utils.unregister_class(MICROMESH_PT_setup)
