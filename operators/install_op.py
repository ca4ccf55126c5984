"""Install Dependencies: pip in the background (``install.pip_job.Install``) while Blender stays
responsive; progress in the preferences and the setup panel, Esc or Cancel stops it and leaves
the dependency folder as it was. From a script or ``blender -b`` it runs to the end at once.
"""
from __future__ import annotations

import textwrap

import bpy

from ..install import deps, platforms
from ..install.pip_job import Install, InstallState
from .prefs import site_dir

_ACTIVE: Install | None = None
_LAST: InstallState | None = None     # the last install's outcome, for the panels


def status() -> tuple[InstallState | None, bool]:
    """(the state to show, whether an install is running)."""
    if _ACTIVE is not None:
        return _ACTIVE.poll(), True
    return _LAST, False


def _start() -> Install:
    global _ACTIVE, _LAST
    from .prefs import get_prefs

    prefs = get_prefs()
    cuda = bool(prefs and getattr(prefs, "torch_build", "CPU") == "CUDA")
    _LAST = None
    _ACTIVE = Install(lambda folder: deps.pip_command(folder, cuda=cuda), site_dir(),
                      deps.log_path(site_dir()), cuda=cuda).start()
    return _ACTIVE


def _redraw() -> None:
    for window in bpy.context.window_manager.windows:
        for area in window.screen.areas:
            if area.type in ("PREFERENCES", "VIEW_3D"):
                area.tag_redraw()


class MICROMESH_OT_install_dependencies(bpy.types.Operator):
    """Install torch, scipy, numba, Embree, xatlas and matplotlib into the extension's user
    folder with pip, in the background (Esc cancels)"""
    bl_idname = "micromesh.install_dependencies"
    bl_label = "Install Dependencies"

    _timer = None

    @classmethod
    def poll(cls, context):
        return _ACTIVE is None

    def _refused(self) -> bool:
        here = platforms.current()
        if here is not None and not here.supported:
            self.report({"ERROR"}, f"{here.name} is not supported: {here.blocker}")
            return True
        if not bpy.app.online_access:
            self.report({"ERROR"}, "Online access is disabled (Preferences > System > Network)")
            return True
        return False

    def execute(self, context):          # scripts and background mode: to the end, blocking
        if self._refused():
            return {"CANCELLED"}
        _start().wait()
        return self._finish(context)

    def invoke(self, context, event):
        if self._refused():
            return {"CANCELLED"}
        _start()
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.25, window=context.window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type == "ESC" and _ACTIVE is not None:
            _ACTIVE.cancel()
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        _redraw()
        if _ACTIVE is None or not _ACTIVE.poll().done:
            return {"PASS_THROUGH"}
        context.window_manager.event_timer_remove(self._timer)
        return self._finish(context)

    def _finish(self, context):
        global _ACTIVE, _LAST
        state = _ACTIVE.poll()
        _ACTIVE, _LAST = None, state
        _redraw()
        if state.phase == "cancelled":
            self.report({"WARNING"}, "Install Dependencies: " + state.message)
            return {"CANCELLED"}
        if state.phase != "finished":
            self.report({"ERROR"}, "Install Dependencies failed: " + state.message)
            return {"CANCELLED"}
        deps.ensure_on_path(site_dir())
        missing = deps.missing_modules()
        if missing:
            self.report({"WARNING"}, "Still missing after the install: " + ", ".join(missing))
            return {"FINISHED"}
        if _ON_INSTALLED is not None:
            _ON_INSTALLED()
        self.report({"INFO"}, state.message)
        return {"FINISHED"}


class MICROMESH_OT_cancel_install(bpy.types.Operator):
    """Stop the running install; the dependency folder stays as it was"""
    bl_idname = "micromesh.cancel_install"
    bl_label = "Cancel Install"

    @classmethod
    def poll(cls, context):
        return _ACTIVE is not None

    def execute(self, context):
        _ACTIVE.cancel()
        return {"FINISHED"}


def download_note(here, torch_build: str = "CPU") -> str:
    """What Install Dependencies will download on this platform, in words (shown before it)."""
    if torch_build == "CUDA" and here.cuda_download_mb:
        return (f"About {here.cuda_download_mb / 1000:.1f} GB to download for {here.name} "
                "(torch with CUDA and NVIDIA's libraries)")
    return f"About {here.download_mb} MB to download for {here.name}"


def draw_install(layout, prefs=None, offer: bool = True) -> None:
    """Install Dependencies where it can work: the running install's progress (with Cancel)
    or the last one's outcome, then (``offer``) the button (with ``prefs``: the torch build to
    fetch and the log's path); on a platform without wheels, why not, instead of the button."""
    here = platforms.current()
    if offer and here is not None and not here.supported:
        reason = f"{here.name} is not supported: {here.blocker}"
        for i, line in enumerate(textwrap.wrap(reason, 70)):
            layout.label(text=line, icon="ERROR" if i == 0 else "BLANK1")
        return
    state, running = status()
    if running:
        layout.label(text=state.status_text(), icon="TIME")
        layout.operator("micromesh.cancel_install", icon="CANCEL")
        return
    if state is not None:
        icon = {"finished": "CHECKMARK", "cancelled": "INFO"}.get(state.phase, "ERROR")
        for i, line in enumerate(textwrap.wrap(state.message, 70)):
            layout.label(text=line, icon=icon if i == 0 else "BLANK1")
    if not offer:
        return
    if prefs is not None:
        layout.prop(prefs, "torch_build")
    if here is not None and here.download_mb:
        layout.label(text=download_note(here, getattr(prefs, "torch_build", "CPU")))
    layout.operator("micromesh.install_dependencies", icon="IMPORT")
    if prefs is not None:
        layout.label(text="Log: " + deps.log_path(site_dir()))


CLASSES = (MICROMESH_OT_install_dependencies, MICROMESH_OT_cancel_install)
_register, _unregister = bpy.utils.register_classes_factory(CLASSES)
_ON_INSTALLED = None        # what registers the rest of the add-on once its dependencies import


def register(on_installed=None) -> None:
    """The operators; ``on_installed()`` runs after a successful install (the add-on's
    ``register_glue``)."""
    global _ON_INSTALLED
    _ON_INSTALLED = on_installed
    _register()


def unregister() -> None:
    global _ON_INSTALLED
    _ON_INSTALLED = None
    _unregister()
