"""The "Micro-Mesh" tab of the 3D Viewport's sidebar, sections in workflow order:
Base Mesh, Cameras, Construct (presets, progress, cancel), Result (metrics, preview), Export."""
from __future__ import annotations

import json

import bpy

from ..operators import job
from ..operators.files_op import result_object as _result_object


class _Panel:
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Micro-Mesh"


class MICROMESH_PT_main(_Panel, bpy.types.Panel):
    bl_label = "Micro-Mesh"
    bl_idname = "MICROMESH_PT_main"

    def draw(self, context):
        s = context.scene.micromesh
        col = self.layout.column(align=True)
        col.prop(s, "source")
        col.prop(s, "base")
        from ..install import deps
        from ..operators import install_op

        missing = deps.missing_modules()
        if missing:  # e.g. torch: projection works, the optimiser needs it
            box = self.layout.box()
            box.label(text="Missing: " + ", ".join(missing), icon="ERROR")
            install_op.draw_install(box)


class MICROMESH_PT_base(_Panel, bpy.types.Panel):
    bl_label = "Base Mesh"
    bl_idname = "MICROMESH_PT_base"
    bl_parent_id = "MICROMESH_PT_main"

    def draw(self, context):
        s = context.scene.micromesh
        layout = self.layout
        layout.prop(s, "base_method", expand=True)
        layout.prop(s, "decimate_mode", expand=True)
        if s.decimate_mode != "ERROR":
            layout.prop(s, "target_faces" if s.decimate_mode == "TARGET" else "ratio")
        if s.base_method == "COLLAPSE":
            row = layout.row(align=True)
            row.prop(s, "base_max_error")
            row.prop(s, "base_max_distance")
            row.prop(s, "base_min_quality")
        else:
            row = layout.row()
            row.prop(s, "symmetry", expand=True)
            src = s.source or context.active_object
            if src is not None and src.type == "MESH":
                layout.prop_search(s, "vertex_group", src, "vertex_groups")
                if s.vertex_group:
                    row = layout.row(align=True)
                    row.prop(s, "vertex_group_factor")
                    row.prop(s, "invert_vertex_group", toggle=True)
        layout.operator("micromesh.make_base", icon="MOD_DECIM")
        layout.operator("micromesh.check_base", icon="VIEWZOOM")
        if s.check_report:
            box = layout.box()
            for line in s.check_report.split("; "):
                box.label(text=line)
        row = layout.row(align=True)
        row.operator("micromesh.set_face_level", icon="FACESEL")
        row.prop(s, "keep_levels", toggle=True)


class MICROMESH_PT_cameras(_Panel, bpy.types.Panel):
    bl_label = "Cameras"
    bl_idname = "MICROMESH_PT_cameras"
    bl_parent_id = "MICROMESH_PT_main"

    def draw(self, context):
        s = context.scene.micromesh
        col = self.layout.column(align=True)
        col.prop(s, "camera_count")
        col.prop(s, "camera_radius")
        col.prop(s, "camera_fov")
        self.layout.prop(s, "camera_collection")
        self.layout.prop(s, "use_scene_cameras")
        self.layout.operator("micromesh.place_cameras", icon="OUTLINER_OB_CAMERA")


class MICROMESH_PT_construct(_Panel, bpy.types.Panel):
    bl_label = "Construct"
    bl_idname = "MICROMESH_PT_construct"
    bl_parent_id = "MICROMESH_PT_main"

    def draw(self, context):
        s = context.scene.micromesh
        layout = self.layout
        row = layout.row(align=True)
        for name in ("fast", "default", "quality", "paper"):
            op = row.operator("micromesh.apply_preset", text=name.title(),
                              depress=(s.preset == name))
            op.preset = name
        row = layout.row(align=True)
        row.prop(s, "budget_mode", text="")
        if s.budget_mode != "NONE":
            row.prop(s, "budget_value")
        layout.prop(s, "level")
        layout.prop(s, "overrides")
        if job.active_job() is not None:
            # the job's own status: no PSNR or time left where it has none (the base, the fit)
            layout.progress(factor=s.progress, type="BAR", text=s.status)
            layout.operator("micromesh.cancel_construct", icon="CANCEL")
        else:
            layout.operator("micromesh.construct", icon="PLAY")
            text = _estimate_text(context)
            if text:
                layout.label(text=text, icon="TIME")


def _estimate_text(context) -> str:
    """The construction's time and memory estimate for the source (core.construct.estimate),
    or "" where there is no source or the settings do not read."""
    from ..core.construct.estimate import estimate
    from ..operators import base_ops, scene_settings

    src = base_ops.source_object(context)
    if src is None or src.type != "MESH":
        return ""
    me = src.data
    faces = len(me.loops) - 2 * len(me.polygons)          # its triangles, counted in O(1)
    try:
        settings = scene_settings.scene_settings(context.scene)
    except (ValueError, TypeError):
        return ""
    return "Estimate: " + estimate(max(faces, 1), settings).text()


class MICROMESH_PT_result(_Panel, bpy.types.Panel):
    bl_label = "Result"
    bl_idname = "MICROMESH_PT_result"
    bl_parent_id = "MICROMESH_PT_main"

    def draw(self, context):
        s = context.scene.micromesh
        obj = _result_object(context)
        if obj is None:
            self.layout.label(text="No result yet")
            return
        m = json.loads(obj.get("micromesh_metrics", "{}"))
        col = self.layout.column(align=True)
        col.label(text=obj.name, icon="MESH_DATA")
        for warning in m.get("warnings") or []:
            col.label(text=warning, icon="ERROR")
        for key, label, fmt in (("psnr", "PSNR", "{:.2f} dB"), ("shell_volume", "Shell volume", "{:.4g}"),
                                ("geom_err", "Geometric error", "{:.3g}"), ("iso_base", "Isotropy", "{:.3f}"),
                                ("bytes", "Bytes", "{:,}"), ("micro_triangles", "Micro-triangles", "{:,}"),
                                ("time_s", "Time", "{:.1f} s")):
            v = m.get(key)
            if isinstance(v, (int, float)):
                col.label(text=f"{label}: " + fmt.format(v))
        self.layout.prop(s, "preview_strength", slider=True)
        self.layout.operator("micromesh.open_report", icon="IMAGE_DATA")


class MICROMESH_PT_export(_Panel, bpy.types.Panel):
    bl_label = "Export"
    bl_idname = "MICROMESH_PT_export"
    bl_parent_id = "MICROMESH_PT_main"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        if _result_object(context) is None:
            layout.label(text="Construct a micro-mesh first")
        layout.operator("micromesh.export", icon="EXPORT")
        layout.operator("micromesh.bake_maps", icon="TEXTURE")
        layout.operator("micromesh.import_file", icon="IMPORT")
        layout.label(text="The .blend also keeps the micro-mesh", icon="INFO")


CLASSES = (MICROMESH_PT_main, MICROMESH_PT_base, MICROMESH_PT_cameras, MICROMESH_PT_construct,
           MICROMESH_PT_result, MICROMESH_PT_export)


register, unregister = bpy.utils.register_classes_factory(CLASSES)
