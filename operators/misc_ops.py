"""Small operators: install dependencies, presets, face-level override, the run's report image."""
from __future__ import annotations

import os

import bpy
import numpy as np
from bpy.props import IntProperty, StringProperty

from . import writeback


class MICROMESH_OT_apply_preset(bpy.types.Operator):
    """Load a preset's main values into the panel (the preset also fixes the rest)"""
    bl_idname = "micromesh.apply_preset"
    bl_label = "Apply Preset"
    bl_options = {"REGISTER", "UNDO"}

    preset: StringProperty(name="Preset", default="default")

    def execute(self, context):
        from ..core.settings.fields import PRESETS, preset

        if self.preset not in PRESETS:
            self.report({"ERROR"}, f"unknown preset {self.preset!r}")
            return {"CANCELLED"}
        s = context.scene.micromesh
        st = preset(self.preset)
        s.preset = self.preset
        s.level = st.max_level
        s.camera_count, s.camera_fov, s.camera_radius = st.n_views, st.fov_y_deg, st.camera_radius
        s.overrides = ""
        return {"FINISHED"}


class MICROMESH_OT_set_face_level(bpy.types.Operator):
    """Set micromesh_level on the selected faces of the base mesh (Edit Mode)"""
    bl_idname = "micromesh.set_face_level"
    bl_label = "Set Face Level"
    bl_options = {"REGISTER", "UNDO"}

    level: IntProperty(name="Level", default=3, min=0, max=5)

    @classmethod
    def poll(cls, context):
        obj = context.active_object
        return obj is not None and obj.type == "MESH"

    def execute(self, context):
        obj = context.active_object
        edit = obj.mode == "EDIT"
        if edit:
            bpy.ops.object.mode_set(mode="OBJECT")
        mesh = obj.data
        sel = np.zeros(len(mesh.polygons), bool)
        mesh.polygons.foreach_get("select", sel)
        if "micromesh_level" in mesh.attributes:
            lv = writeback.read_attr(mesh, "micromesh_level", dtype=np.int32)
        else:
            lv = np.full(len(mesh.polygons), context.scene.micromesh.level, np.int32)
        lv[sel] = self.level
        writeback._attr(mesh, "micromesh_level", "INT", "FACE", lv)
        context.scene.micromesh.keep_levels = True
        if edit:
            bpy.ops.object.mode_set(mode="EDIT")
        self.report({"INFO"}, f"{int(sel.sum())} faces set to level {self.level}")
        return {"FINISHED"}


class MICROMESH_OT_open_report(bpy.types.Operator):
    """Open the run's report: renders and error maps, levels, loss and PSNR, metrics, warnings"""
    bl_idname = "micromesh.open_report"
    bl_label = "Open Report"

    @classmethod
    def poll(cls, context):
        obj = context.active_object
        return obj is not None and obj.get(writeback.DATA_KEY) is not None

    def execute(self, context):
        from . import prefs

        obj = context.active_object
        if obj.get(writeback.REPORT_KEY) is None:
            self.report({"ERROR"}, "This result has no report (metrics were off)")
            return {"CANCELLED"}
        path = os.path.join(prefs.cache_dir(), f"{bpy.path.clean_name(obj.name)}_report.png")
        with open(path, "wb") as f:
            f.write(bytes(obj[writeback.REPORT_KEY]))
        name = f"{obj.name}_report"
        if name in bpy.data.images:
            bpy.data.images.remove(bpy.data.images[name])
        img = bpy.data.images.load(path)
        img.name = name
        for area in context.screen.areas if context.screen else []:
            if area.type == "IMAGE_EDITOR":
                area.spaces.active.image = img
                break
        else:
            if context.window is not None and not bpy.app.background:
                bpy.ops.render.view_show("INVOKE_DEFAULT")
                for area in context.window_manager.windows[-1].screen.areas:
                    if area.type == "IMAGE_EDITOR":
                        area.spaces.active.image = img
        self.report({"INFO"}, f"Report: {path}")
        return {"FINISHED"}


CLASSES = (MICROMESH_OT_apply_preset,
           MICROMESH_OT_set_face_level, MICROMESH_OT_open_report)
