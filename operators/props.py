"""Settings and run state of the add-on, stored in the scene (``scene.micromesh``).

Object pointers link the pieces: a base mesh and a result object point back to their source
(``Object.micromesh_source``), a result to its base (``Object.micromesh_base``).
"""
from __future__ import annotations

import bpy
from bpy.props import (BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty,
                       StringProperty)

from ..core.base import builders

PRESET_ITEMS = [
    ("fast", "Fast", "About a minute on a laptop CPU"),
    ("default", "Default", "A few minutes on a CPU"),
    ("quality", "Quality", "Slower, closer to the paper"),
    ("paper", "Paper", "The paper's method as published, for comparison (1600 iterations of "
                       "24 views, smooth shading, no fit; slow)"),
]


def _update_strength(settings, context) -> None:
    from . import preview

    preview.set_preview_strength(context.scene, settings.preview_strength)


def _is_mesh(_self, obj) -> bool:
    return obj.type == "MESH"


class MICROMESH_PG_settings(bpy.types.PropertyGroup):
    # ---- base mesh
    source: PointerProperty(type=bpy.types.Object, poll=_is_mesh, name="Source",
                            description="The high-poly reference object")
    base: PointerProperty(type=bpy.types.Object, poll=_is_mesh, name="Base",
                          description="The low-poly base mesh")
    base_method: EnumProperty(name="Method", default="COLLAPSE", items=[
        (b.key.upper(), b.label, b.description) for b in builders.BUILDERS.values()])
    decimate_mode: EnumProperty(name="Decimate By", default="RATIO", items=[
        ("RATIO", "Ratio", "A fraction of the source's triangles"),
        ("TARGET", "Triangles", "A target triangle count"),
        ("ERROR", "Error", "As few triangles as the error bound allows")])
    ratio: FloatProperty(name="Ratio", default=1 / 32, min=1e-4, max=1.0, precision=4)
    target_faces: IntProperty(name="Triangles", default=1000, min=4)
    base_max_error: FloatProperty(name="Max Error", default=1e-3, min=0.0, max=0.5, precision=5,
                                  description="Bound on the base's RMS distance to the source, "
                                              "as a fraction of its bounding-box diagonal "
                                              "(0: none)")
    base_max_distance: FloatProperty(name="Max Distance", default=4e-3, min=0.0, max=0.5,
                                     precision=4,
                                     description="Bound on the base's largest distance to the "
                                                 "source, as a fraction of its bounding-box "
                                                 "diagonal: the RMS error bound is tightened "
                                                 "until it holds (0: none)")
    base_min_quality: FloatProperty(name="Min Quality", default=0.4, min=0.0, max=0.99,
                                    description="Floor on the shape (2r/R) of new base triangles")
    budget_mode: EnumProperty(name="Budget", default="RATIO", items=[
        ("RATIO", "× Input", "The bytes on disk (.bin + .bary) micromesh-tools' files take "
                             "for its microexpansion (micro-triangles per source triangle) "
                             "on the base"),
        ("TRIANGLES", "Micro-Triangles", "A micro-triangle count"),
        ("BYTES", "Bytes", "Bytes on disk of the .bin + .bary"),
        ("NONE", "None", "No budget: the LOD's gain threshold alone decides")])
    budget_value: FloatProperty(name="Amount", default=2.0, min=0.0,
                                description="Micro-triangles per source triangle, micro-triangles "
                                            "or bytes, by the budget kind")
    symmetry: EnumProperty(name="Symmetry", default="NONE", items=[
        ("NONE", "None", ""), ("X", "X", ""), ("Y", "Y", ""), ("Z", "Z", "")])
    vertex_group: StringProperty(name="Vertex Group", default="",
                                 description="Weight the collapse by this vertex group of the source")
    vertex_group_factor: FloatProperty(name="Weight", default=1.0, min=0.0, max=1000.0)
    invert_vertex_group: BoolProperty(name="Invert", default=False)
    check_report: StringProperty(name="Check Report", default="")
    # ---- cameras
    camera_count: IntProperty(name="Cameras", default=24, min=1, max=512)
    camera_radius: FloatProperty(name="Radius Factor", default=3.5, min=1.01, max=100.0,
                                 description="Camera distance in units of the source's bounding-sphere radius")
    camera_fov: FloatProperty(name="Field of View", default=35.0, min=1.0, max=170.0)
    camera_collection: PointerProperty(type=bpy.types.Collection, name="Camera Collection")
    use_scene_cameras: BoolProperty(name="Use Camera Collection", default=True,
                                    description="Construct with the cameras of the collection "
                                                "(else the preset's Fibonacci cameras)")
    # ---- construct
    preset: EnumProperty(name="Preset", items=PRESET_ITEMS, default="default")
    overrides: StringProperty(name="Overrides", default="",
                              description="Extra settings as key=value, separated by spaces (e.g. iterations=200 subdivide_at=20,60)")
    level: IntProperty(name="Level", default=3, min=0, max=5,
                       description="Uniform subdivision level of the projection-baked micro-mesh")
    keep_levels: BoolProperty(name="Keep Face Levels", default=False,
                              description="Use the base mesh's micromesh_level face attribute "
                                          "and refine displacements only")
    # ---- run state (written by the modal operator)
    running: BoolProperty(default=False, options={"SKIP_SAVE"})
    progress: FloatProperty(name="Progress", default=0.0, min=0.0, max=1.0, subtype="FACTOR")
    phase: StringProperty(default="")
    iteration: IntProperty(default=0)
    psnr: FloatProperty(default=0.0)
    eta_s: FloatProperty(default=0.0)
    status: StringProperty(default="")
    # ---- result
    preview_strength: FloatProperty(name="Displacement Strength", default=1.0, min=-1.0, max=3.0,
                                    update=_update_strength)


CLASSES = (MICROMESH_PG_settings,)
_registered = False


def _unregister_at_exit() -> None:
    """The ``bpy`` module hangs at interpreter exit while these properties are still
    registered (seen with bpy 4.5); scripts that never unregister get it done here."""
    if _registered:
        try:
            unregister()
        except Exception:  # noqa: BLE001 - best effort at exit
            pass


def register():
    global _registered
    if not _registered:
        import atexit

        atexit.register(_unregister_at_exit)
    for c in CLASSES:
        bpy.utils.register_class(c)
    bpy.types.Scene.micromesh = PointerProperty(type=MICROMESH_PG_settings)
    bpy.types.Object.micromesh_source = PointerProperty(type=bpy.types.Object, name="Micro-Mesh Source")
    bpy.types.Object.micromesh_base = PointerProperty(type=bpy.types.Object, name="Micro-Mesh Base")
    _registered = True


def unregister():
    """Idempotent: the at-exit hook and Blender's own add-on disable may both call it."""
    global _registered
    if not _registered:
        return
    _registered = False
    del bpy.types.Object.micromesh_base
    del bpy.types.Object.micromesh_source
    del bpy.types.Scene.micromesh
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)
