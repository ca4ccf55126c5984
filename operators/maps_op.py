"""Bake Maps: a height map fitted to the source and a normal map on a UV atlas of the result's
base (``core.maps``), and ``<source>_maps``: the base displaced by them as Blender renders
displacement (``maps_object``). Images are packed into the ``.blend`` (``batch.py --maps``
also writes them as files)."""
from __future__ import annotations

from functools import partial

import bpy
from bpy.props import IntProperty

from ..core.maps import AtlasError
from ..core.maps.atlas import checked_resolution
from . import bl_mesh, job, source_texture, writeback
from .files_op import result_object
from .maps_object import maps_object
from .maps_work import bake_with_textures, own_atlas


class MICROMESH_OT_bake_maps(bpy.types.Operator):
    """Fit a height map to the source and bake a normal map on a UV atlas of the result's
    base, and make an object that renders the detail from them"""
    bl_idname = "micromesh.bake_maps"
    bl_label = "Bake Maps"
    bl_options = {"REGISTER", "UNDO"}
    resolution: IntProperty(name="Resolution", default=2048, min=64, max=16384,
                            description="Texels per side: a power of two")

    @classmethod
    def poll(cls, context):
        return result_object(context) is not None and job.active_job() is None

    def _work(self, context):
        res = result_object(context)
        out = writeback.load_outcome(res)
        src = res.micromesh_source
        self._result, self._mm = res, out.micromesh
        self._textures = source_texture.read(src) if src is not None else None
        atlas, self._atlas_note = own_atlas(res.micromesh_base, out.micromesh, self.resolution)
        self._own_uvs = atlas is not None
        # fitted to the source; where it is gone, to the micro-mesh itself
        reference = bl_mesh.mesh_to_arrays(src) if src is not None else None
        return partial(bake_with_textures, out.micromesh, reference, self.resolution,
                       self._textures, atlas=atlas)

    def _finish(self, context, baked):
        maps, carried = baked.maps, baked.carried
        src = self._result.micromesh_source or self._result
        obj = maps_object(context, src, self._mm, maps, f"{src.name}_maps")
        what = "height and normal maps" + (
            f" on '{self._result.micromesh_base.name}''s own UVs" if self._own_uvs else "")
        if self._atlas_note:
            self.report({"WARNING"}, self._atlas_note)
        if carried:
            source_texture.carry_textures(obj, self._textures, carried)
            names = ", ".join(t.socket.lower() for t in self._textures.images)
            what += f", and '{src.name}''s textures ({names}) carried onto their atlas"
        self.report({"INFO"}, f"{obj.name}: {self.resolution}² {what}")
        return {"FINISHED"}

    def _refused(self) -> bool:
        """A resolution no map takes, said before any work."""
        try:
            checked_resolution(self.resolution)
        except AtlasError as e:
            self.report({"ERROR"}, str(e))
            return True
        return False

    def execute(self, context):
        if self._refused():
            return {"CANCELLED"}
        try:                      # bad input (core's errors are ValueErrors): said, not raised
            baked = self._work(context)(lambda p: None, lambda: False)
        except ValueError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        return self._finish(context, baked)

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        if self._refused():
            return {"CANCELLED"}
        return {"RUNNING_MODAL"} if job.start_modal(self, context, self._work(context)) \
            else {"CANCELLED"}

    def modal(self, context, event):
        if event.type == "ESC" and event.value == "PRESS":
            self._job.cancel()
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        state = self._job.poll()
        context.workspace.status_text_set(state.status_text())
        if not state.done:
            return {"PASS_THROUGH"}
        job.end_modal(self, context)
        if state.cancelled or state.error:
            self.report({"WARNING"} if state.cancelled else {"ERROR"},
                        "Baking cancelled; nothing was changed" if state.cancelled
                        else state.error)
            return {"CANCELLED"}
        return self._finish(context, state.result)


CLASSES = (MICROMESH_OT_bake_maps,)
