"""The add-on registers and unregisters cleanly when enabled the way Blender enables an
installed extension (module ``bl_ext.<repo>.micromesh``), and the built zip installs with
Blender's own extension installer and runs its operators from the installed copy."""
from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

bpy = pytest.importorskip("bpy")

from test_manifest import ROOT, build_extension_zip  # noqa: E402

OPERATORS = ("MICROMESH_OT_make_base", "MICROMESH_OT_check_base", "MICROMESH_OT_place_cameras",
             "MICROMESH_OT_construct", "MICROMESH_OT_cancel_construct",
             "MICROMESH_OT_set_face_level", "MICROMESH_OT_apply_preset",
             "MICROMESH_OT_open_report", "MICROMESH_OT_install_dependencies")
PANELS = ("MICROMESH_PT_main", "MICROMESH_PT_base", "MICROMESH_PT_cameras",
          "MICROMESH_PT_construct", "MICROMESH_PT_result", "MICROMESH_PT_export")


def _registered() -> dict[str, bool]:
    return {name: hasattr(bpy.types, name) for name in OPERATORS + PANELS}


@pytest.fixture
def repo(tmp_path):
    """A local extension repository in a temporary folder (removed afterwards)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    name = "mmtest_" + tmp_path.name[-12:].replace("-", "_").lower()
    r = bpy.context.preferences.extensions.repos.new(name=name, module=name, source="USER",
                                                     custom_directory=str(tmp_path / "repo"))
    yield r
    module = f"bl_ext.{r.module}.micromesh"
    if module in bpy.context.preferences.addons:
        bpy.ops.preferences.addon_disable(module=module)
    bpy.context.preferences.extensions.repos.remove(r)


def test_register_unregister_as_extension(repo):
    assert not any(_registered().values())
    os.makedirs(repo.directory, exist_ok=True)
    # The repository entry is named by the manifest id, whatever the checkout is called.
    os.symlink(ROOT, Path(repo.directory) / "micromesh", target_is_directory=True)
    module = f"bl_ext.{repo.module}.micromesh"
    assert bpy.ops.preferences.addon_enable(module=module) == {"FINISHED"}
    assert module in bpy.context.preferences.addons
    assert sys.modules[module].__file__ == str(Path(repo.directory) / "micromesh" / "__init__.py")
    assert all(_registered().values()), _registered()
    assert hasattr(bpy.types.Scene, "micromesh") and hasattr(bpy.types.Object, "micromesh_source")
    prefs = bpy.context.preferences.addons[module].preferences
    assert prefs.device == "AUTO" and prefs.threads == 0
    assert bpy.ops.preferences.addon_disable(module=module) == {"FINISHED"}
    assert not any(_registered().values()), _registered()
    assert not hasattr(bpy.types.Scene, "micromesh")


def test_install_zip_and_run_operators(repo, tmp_path):
    z = build_extension_zip(tmp_path / "dist")
    r = bpy.ops.extensions.package_install_files(repo=repo.module, filepath=str(z),
                                                 enable_on_install=True)
    assert r == {"FINISHED"}
    module = f"bl_ext.{repo.module}.micromesh"
    installed = Path(repo.directory) / "micromesh"
    assert (installed / "blender_manifest.toml").exists() and not (installed / "tests").exists()
    assert module in bpy.context.preferences.addons
    assert Path(sys.modules[module].__file__).parent == installed
    assert bpy.types.MICROMESH_OT_construct.__module__.startswith(module)
    try:
        bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=4)
        src = bpy.context.active_object
        s = bpy.context.scene.micromesh
        s.target_faces, s.camera_count, s.level = 80, 4, 1
        assert bpy.ops.micromesh.make_base() == {"FINISHED"}
        assert bpy.ops.micromesh.check_base() == {"FINISHED"}
        bpy.ops.object.mode_set(mode="OBJECT")
        assert bpy.ops.micromesh.place_cameras() == {"FINISHED"}
        assert bpy.ops.micromesh.construct(method="PROJECTION") == {"FINISHED"}
        res = bpy.data.objects[f"{src.name}_micromesh"]
        assert len(res.data.polygons) == 4 * len(s.base.data.polygons)
    finally:
        bpy.ops.preferences.addon_disable(module=module)
    assert not any(_registered().values())
