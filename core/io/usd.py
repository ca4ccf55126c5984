"""The base mesh with its maps as USD (a ``.usda`` text layer, written without Blender or
``pxr``): points, vertex normals (the unit directions the heights point along), face-varying
UVs ``primvars:st``, no subdivision scheme, and a ``UsdPreviewSurface`` whose
``displacement`` is a ``UsdUVTexture`` of the 16-bit height map (scale and bias: the
:class:`~core.io.images.HeightCode`) and whose ``normal`` is the tangent-space normal map.

USD's ``st`` has t = 0 at the image's bottom, as our v: the UVs go in as they are. All of
``usd-core``'s validators (``pxr.UsdValidation``, what ``usdchecker`` runs) pass on it
(``tests/core/test_usd.py``).
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..mesh.float32_origin import relative
from ..maps import Maps, unit_directions
from ..micro.micromesh import MicroMesh
from .images import HeightCode
from .micromesh_export import Y_UP


def _name(stem: str) -> str:
    """A valid prim name from a file stem (letters, digits, underscores; not a digit first)."""
    n = re.sub(r"[^A-Za-z0-9_]", "_", stem) or "base"
    return "_" + n if n[0].isdigit() else n


def _array(values: np.ndarray, fmt: str, per_line: int = 8) -> str:
    """``values`` (n, k) or (n,) as a USDA array: tuples for k > 1."""
    v = np.asarray(values)
    items = [("(" + ", ".join(fmt % c for c in row) + ")") if v.ndim == 2 else fmt % row
             for row in v]
    lines = [", ".join(items[i:i + per_line]) for i in range(0, len(items), per_line)]
    return "[" + ",\n            ".join(lines) + "]"


def _translate(origin: np.ndarray | None) -> str:
    if origin is None:
        return ""
    o = ", ".join("%.17g" % c for c in origin)
    return (f'\n    double3 xformOp:translate = ({o})\n'
            '    uniform token[] xformOpOrder = ["xformOp:translate"]\n')


def base_usda(path: Path, mm: MicroMesh, maps: Maps, height_uri: str, normal_uri: str,
              code: HeightCode, y_up: bool = False) -> list[tuple[Path, bytes]]:
    """``path`` (.usda): the base (``mm.base`` in world units, ``y_up``: Blender's Z-up turned
    into Y-up, as the glTF files are) with UVs from ``maps.atlas`` and a material that
    displaces it by ``height_uri`` (h = code.offset + code.factor · value) and shades it with
    ``normal_uri``."""
    root = _name(path.stem)
    mat = f"/{root}/Materials/{root}_material"
    rot = Y_UP.T if y_up else np.eye(3)
    P, origin = relative(mm.base.vertices @ rot)     # far from the origin: a translation
    N = unit_directions(mm) @ rot
    at = maps.atlas
    lo, hi = P.min(0), P.max(0)
    scale = ", ".join(["%.9g" % code.factor] * 4)
    bias = ", ".join(["%.9g" % code.offset] * 4)
    text = f'''#usda 1.0
(
    defaultPrim = "{root}"
    doc = "Micro-Mesh Builder: a base mesh displaced by its height map"
    metersPerUnit = 1
    upAxis = "{'Y' if y_up else 'Z'}"
)

def Xform "{root}" (
    kind = "component"
)
{{{_translate(origin)}
    def Mesh "base" (
        prepend apiSchemas = ["MaterialBindingAPI"]
    )
    {{
        float3[] extent = [({lo[0]:.9g}, {lo[1]:.9g}, {lo[2]:.9g}), ({hi[0]:.9g}, {hi[1]:.9g}, {hi[2]:.9g})]
        int[] faceVertexCounts = {_array(np.full(mm.base.n_faces, 3), "%d", 32)}
        int[] faceVertexIndices = {_array(mm.base.faces.reshape(-1), "%d", 32)}
        rel material:binding = <{mat}>
        normal3f[] normals = {_array(N, "%.9g", 4)} (
            interpolation = "vertex"
        )
        uniform token orientation = "rightHanded"
        point3f[] points = {_array(P, "%.9g", 4)}
        texCoord2f[] primvars:st = {_array(at.uv, "%.9g", 6)} (
            interpolation = "faceVarying"
        )
        int[] primvars:st:indices = {_array(at.faces.reshape(-1), "%d", 32)}
        uniform token subdivisionScheme = "none"
    }}

    def Scope "Materials"
    {{
        def Material "{root}_material"
        {{
            token outputs:displacement.connect = <{mat}/surface.outputs:displacement>
            token outputs:surface.connect = <{mat}/surface.outputs:surface>

            def Shader "surface"
            {{
                uniform token info:id = "UsdPreviewSurface"
                float inputs:displacement.connect = <{mat}/height.outputs:r>
                normal3f inputs:normal.connect = <{mat}/normal.outputs:rgb>
                float inputs:roughness = 0.5
                token outputs:displacement
                token outputs:surface
            }}

            def Shader "uv"
            {{
                uniform token info:id = "UsdPrimvarReader_float2"
                string inputs:varname = "st"
                float2 outputs:result
            }}

            def Shader "height"
            {{
                uniform token info:id = "UsdUVTexture"
                float4 inputs:bias = ({bias})
                asset inputs:file = @{height_uri}@
                float4 inputs:scale = ({scale})
                token inputs:sourceColorSpace = "raw"
                float2 inputs:st.connect = <{mat}/uv.outputs:result>
                token inputs:wrapS = "clamp"
                token inputs:wrapT = "clamp"
                float outputs:r
            }}

            def Shader "normal"
            {{
                uniform token info:id = "UsdUVTexture"
                float4 inputs:bias = (-1, -1, -1, 0)
                asset inputs:file = @{normal_uri}@
                float4 inputs:scale = (2, 2, 2, 1)
                token inputs:sourceColorSpace = "raw"
                float2 inputs:st.connect = <{mat}/uv.outputs:result>
                token inputs:wrapS = "clamp"
                token inputs:wrapT = "clamp"
                float3 outputs:rgb
            }}
        }}
    }}
}}
'''
    return [(path, text.encode("utf-8"))]
