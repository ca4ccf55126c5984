"""Register every class of the operators package, the scene properties and the handlers."""
from __future__ import annotations

import bpy
from bpy.app.handlers import persistent

from ..install import deps
from . import base_ops, check_op, construct_op, files_op, job, maps_op, misc_ops, props, warmup
from .prefs import site_dir

CLASSES = (*base_ops.CLASSES, *check_op.CLASSES, *construct_op.CLASSES, *misc_ops.CLASSES, *files_op.CLASSES,
           *maps_op.CLASSES)


@persistent
def _stop_on_load(*_args):
    """Closing or reloading the file stops a running construction."""
    job.stop_active()


def register():
    import atexit

    deps.ensure_on_path(site_dir())
    atexit.register(job.stop_active)  # quitting stops the worker
    props.register()
    for c in CLASSES:
        bpy.utils.register_class(c)
    for menu, draw in files_op.MENUS:
        menu.append(draw)
    bpy.app.handlers.load_pre.append(_stop_on_load)
    atexit.register(warmup.stop)
    warmup.start()            # interactive Blender: compile the kernels before a first Construct


def unregister():
    import atexit

    job.stop_active()
    atexit.unregister(job.stop_active)
    warmup.stop()
    atexit.unregister(warmup.stop)
    if _stop_on_load in bpy.app.handlers.load_pre:
        bpy.app.handlers.load_pre.remove(_stop_on_load)
    for menu, draw in files_op.MENUS:
        menu.remove(draw)
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)
    props.unregister()
