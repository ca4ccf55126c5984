"""The Construct operator: modal with a worker thread in the UI, synchronous in background.

All bpy reads happen in the main thread before the worker starts
(:func:`construct_scene.prepare`); the worker runs the bpy-free ``core.workflow``; the modal
timer drains the job's queue into the scene's run state (:func:`sync_state`) and, when done,
writes the result (:func:`construct_scene.finish`). Esc or the Cancel button stop the worker; nothing is written.
"""
from __future__ import annotations

import bpy
from bpy.props import EnumProperty

from ..core.settings.fields import SettingsError
from . import base_ops, job
from .construct_scene import Prepared, finish, prepare


def sync_state(scene, state: job.JobState) -> None:
    """Copy a job's progress into the scene's run state (what the panel shows)."""
    s = scene.micromesh
    s.progress = float(min(max(state.fraction, 0.0), 1.0))
    s.phase = str(state.phase)
    s.iteration = int(state.iteration)
    s.psnr = float(state.psnr) if state.psnr == state.psnr else 0.0
    s.eta_s = float(state.eta_s) if state.eta_s == state.eta_s else 0.0
    s.status = state.status_text()


def _summary(obj, outcome) -> str:
    m = outcome.metrics
    return (f"'{obj.name}': {m.get('micro_triangles', 0)} micro-triangles on "
            f"{m.get('base_faces', 0)} base faces, shell volume {m.get('shell_volume', 0):.4g}, "
            f"{m.get('time_s', 0):.1f} s ({outcome.method})")


class MICROMESH_OT_construct(bpy.types.Operator):
    """Construct the micro-mesh of the source on the base mesh (Esc cancels)"""
    bl_idname = "micromesh.construct"
    bl_label = "Construct Micro-Mesh"
    bl_options = {"REGISTER", "UNDO"}

    method: EnumProperty(name="Method", default="AUTO", items=[
        ("AUTO", "Auto", "The optimiser when available (it keeps face levels when asked), "
                         "else projection baking"),
        ("OPTIMIZE", "Optimise", "Differentiable-rendering optimisation (core.construct)"),
        ("PROJECTION", "Projection", "The staged baseline: uniform level, projection baking")])

    _job: job.Job | None = None
    _timer = None
    _prep: Prepared | None = None

    @classmethod
    def poll(cls, context):
        return job.active_job() is None and base_ops.source_object(context) is not None

    def _prepare(self, context) -> Prepared | None:
        try:
            from . import prefs

            prefs.apply_threads()
            return prepare(context, self.method.lower())
        except (ValueError, SettingsError) as e:
            self.report({"ERROR"}, str(e))
            return None

    def execute(self, context):
        prep = self._prepare(context)
        if prep is None:
            return {"CANCELLED"}
        scene = context.scene

        def progress(p):
            state = job.JobState()
            job.Job._progress_into(state, p)
            sync_state(scene, state)

        try:
            outcome = prep.work(progress, lambda: False)
        except Exception as e:  # noqa: BLE001 - one line to the user
            self.report({"ERROR"}, f"{type(e).__name__}: {e}")
            return {"CANCELLED"}
        obj = finish(context, prep.source, prep.base_obj, outcome)
        scene.micromesh.progress, scene.micromesh.phase = 1.0, "done"
        self.report({"INFO"}, _summary(obj, outcome))
        return {"FINISHED"}

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        prep = self._prepare(context)
        if prep is None:
            return {"CANCELLED"}
        if not job.start_modal(self, context, prep.work):
            return {"CANCELLED"}
        self._prep = prep
        context.scene.micromesh.running = True
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type == "ESC" and event.value == "PRESS":
            self._job.cancel()
            context.scene.micromesh.phase = "cancelling"
            return {"RUNNING_MODAL"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        state = self._job.poll()
        sync_state(context.scene, state)
        context.workspace.status_text_set(state.status_text())
        for area in context.screen.areas:
            if area.type == "VIEW_3D":
                area.tag_redraw()
        if not state.done:
            return {"PASS_THROUGH"}
        self._cleanup(context)
        if state.cancelled:
            self.report({"WARNING"}, "Construction cancelled; nothing was changed")
            return {"CANCELLED"}
        if state.error:
            self.report({"ERROR"}, state.error)
            return {"CANCELLED"}
        obj = finish(context, self._prep.source, self._prep.base_obj, state.result)
        for area in context.screen.areas:  # show the level colours in solid shading
            if area.type == "VIEW_3D" and area.spaces.active.shading.type == "SOLID":
                area.spaces.active.shading.color_type = "ATTRIBUTE"
        self.report({"INFO"}, _summary(obj, state.result))
        return {"FINISHED"}

    def _cleanup(self, context):
        job.end_modal(self, context)
        s = context.scene.micromesh
        s.running = False
        s.progress = 0.0 if not (self._job and self._job.state.result) else 1.0

    def cancel(self, context):  # Blender calls this when the operator is aborted (file closed)
        if self._job is not None:
            self._job.cancel()
        self._cleanup(context)


class MICROMESH_OT_cancel_construct(bpy.types.Operator):
    """Stop the running construction (the scene stays as it was)"""
    bl_idname = "micromesh.cancel_construct"
    bl_label = "Cancel"

    @classmethod
    def poll(cls, context):
        return job.active_job() is not None

    def execute(self, context):
        j = job.active_job()
        if j is not None:
            j.cancel()
        return {"FINISHED"}


CLASSES = (MICROMESH_OT_construct, MICROMESH_OT_cancel_construct)
