"""The base with its maps as USD (core.io.usd): every validator of usd-core
(``pxr.UsdValidation``, what ``usdchecker`` runs) passes it, and USD reads back the base,
its UVs, its normals and the height map's texture with its scale and bias."""
from __future__ import annotations

import numpy as np
import pytest

from core.io import formats
from core.maps import Maps, unit_directions, uv_atlas
from core.mesh.trimesh import TriMesh
from core.micro.micromesh import MicroMesh
from core.mesh.primitives import noisy_sphere

pxr = pytest.importorskip("pxr", reason="usd-core is not installed (requirements.txt pins it)")
from pxr import Usd, UsdGeom, UsdShade, UsdValidation  # noqa: E402


def _product(far: bool = False) -> formats.Product:
    v, f = noisy_sphere(300, amplitude=0.1, seed=1)
    if far:
        v = v + [4.0e5, 0.0, 0.0]
    mm = MicroMesh.flat(TriMesh(v, f), np.zeros(len(f), int))
    atlas = uv_atlas(mm.base, 64)
    y, x = np.mgrid[0:64, 0:64] / 64.0
    height = (0.01 * np.sin(9 * x) * np.cos(7 * y) - 0.002).astype(np.float32)
    maps = Maps(atlas, height, np.full((64, 64, 3), 0.5, np.float32), np.ones((64, 64), bool))
    return formats.Product(mm, maps=maps, y_up=True)


def _write(tmp_path, product) -> str:
    for key in ("usd", "height-png", "normal-png"):
        files, _ = formats.write(formats.FORMATS[key], product, "rock")
        for suffix, data in files.items():
            (tmp_path / f"rock{suffix}").write_bytes(data)
    return str(tmp_path / "rock.usda")


def _errors(stage) -> list[str]:
    validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
    assert len(validators) >= 25
    errors = UsdValidation.ValidationContext(validators).Validate(stage)
    return [f"{e.GetName()}: {e.GetMessage()}" for e in errors]


@pytest.mark.parametrize("far", [False, True])
def test_every_validator_passes_and_usd_reads_the_base_and_its_maps(tmp_path, far):
    product = _product(far)
    stage = Usd.Stage.Open(_write(tmp_path, product))
    assert _errors(stage) == []
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y
    mesh = UsdGeom.Mesh(stage.GetDefaultPrim().GetChild("base"))
    world = UsdGeom.Xformable(mesh).ComputeLocalToWorldTransform(Usd.TimeCode.Default())
    points = np.array([world.Transform(p) for p in mesh.GetPointsAttr().Get()])
    mm, atlas = product.micromesh, product.maps.atlas
    y_up = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])        # Blender's Z-up as Y-up
    assert np.allclose(points, mm.base.vertices @ y_up.T, atol=1e-6 * (1 + far * 4e5))
    assert np.array_equal(np.array(mesh.GetFaceVertexIndicesAttr().Get()),
                          mm.base.faces.reshape(-1))
    assert mesh.GetSubdivisionSchemeAttr().Get() == "none"
    normals = np.array(mesh.GetNormalsAttr().Get())
    assert np.allclose(normals, unit_directions(mm) @ y_up.T, atol=1e-6)
    st = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("st")
    assert st.GetInterpolation() == "faceVarying"
    assert np.allclose(np.array(st.ComputeFlattened()), atlas.corner_uv.reshape(-1, 2),
                       atol=1e-7)
    material, _ = UsdShade.MaterialBindingAPI(mesh).ComputeBoundMaterial()
    surface = material.ComputeSurfaceSource()[0]
    assert surface.GetIdAttr().Get() == "UsdPreviewSurface"
    source = surface.GetInput("displacement").GetConnectedSource()[0]
    height = UsdShade.Shader(source.GetPrim())
    assert height.GetIdAttr().Get() == "UsdUVTexture"
    assert height.GetInput("file").Get().path == "rock_height.png"
    code = product.height_code
    assert np.allclose(height.GetInput("scale").Get(), [code.factor] * 4)
    assert np.allclose(height.GetInput("bias").Get(), [code.offset] * 4)


def test_the_validators_can_fail(tmp_path):
    """A material bound without MaterialBindingAPI, and a texture that is not there: errors."""
    path = _write(tmp_path, _product())
    text = open(path).read().replace('prepend apiSchemas = ["MaterialBindingAPI"]', "")
    open(path, "w").write(text)
    (tmp_path / "rock_normal.png").unlink()
    errors = _errors(Usd.Stage.Open(path))
    assert any("MaterialBindingAPI" in e for e in errors), errors
    assert any("rock_normal.png" in e for e in errors), errors
