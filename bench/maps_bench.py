"""Height and normal maps: how well a height map rebuilds the micro-mesh, and what baking costs.

For each micro-mesh file given (``NAME.gltf`` as ``batch.py`` writes it), bakes the maps at
each resolution and reports the RMS and maximum distance between the micro-vertices and the
same points rebuilt from the base and the height map (``core.maps.rebuilt_positions``, over the
bounding-box diagonal), beside the simplest alternative in the same run: the height sampled at
the nearest texel instead of bilinearly. With ``--judge-json`` (the judge's JSON of the same
file) it prints the micro-mesh's own geometric error against its reference, the yardstick.

    python bench/maps_bench.py OUT/NAME.gltf [...] [--res 2048 4096] [--json FILE]
        [--source MESH.ply]

With ``--source`` (the micro-mesh's reference), it also times carrying the source's images onto
the atlas as ``batch.py --maps`` does for a textured, normal-mapped source (a 1024² RGBA
texture, and a 1024² normal map about the surface and about the base; seeded random images and
UVs): in one pass over the texels (``core.maps.carry``) beside one pass per image.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from _common import parser, print_table, timed, write_json
from core.io.micromesh_import import read_micromesh
from core.io.mesh_files import read_mesh
from core.maps import Carry, bake_maps, carry, rebuild_error


def main() -> None:
    p = parser(__doc__.split("\n")[0])
    p.add_argument("files", nargs="+")
    p.add_argument("--res", type=int, nargs="+", default=[2048, 4096])
    p.add_argument("--source", default=None, help="the reference mesh: also time carrying images")
    args = p.parse_args()
    source = read_mesh(args.source) if args.source else None
    rows = []
    for f in args.files:
        path = Path(f)
        mm = read_micromesh(path).micromesh()
        diag = mm.base.bbox_diagonal
        judged = path.parent / f"judge_{path.stem}.json"
        geom = (json.loads(judged.read_text())["geom_error"]["ref_to_mm"]["avg"]
                if judged.exists() else float("nan"))
        for res in args.res:
            secs, maps = timed(lambda: bake_maps(mm, res))
            d = rebuild_error(mm, maps) / diag
            dn = rebuild_error(mm, maps, nearest=True) / diag
            rows.append({"mesh": path.stem, "res": res, "bake_s": round(secs, 1),
                         "rms": float(np.sqrt((d ** 2).mean())), "max": float(d.max()),
                         "rms_nearest": float(np.sqrt((dn ** 2).mean())),
                         "geom_err_vs_ref": geom})
            if source is not None:
                rows[-1].update(carry_times(mm, maps, source))
            print(rows[-1], flush=True)
            write_json(args.json, rows)
    print_table(rows, ["mesh", "res", "bake_s", "rms", "rms_nearest", "max", "geom_err_vs_ref"]
                + (["carry_one_pass_s", "carry_per_image_s"] if source is not None else []),
                title="height map -> micro-mesh (distances over the bounding-box diagonal)")


def carry_times(mm, maps, source) -> dict:
    """Seconds to carry a texture and a normal map (about the surface and about the base) onto
    ``maps``' atlas: one pass for all three, and one pass per image."""
    rng = np.random.default_rng(0)
    uv = rng.random((source.n_faces, 3, 2))
    color, normal = rng.random((1024, 1024, 4)), rng.random((1024, 1024, 3))
    items = [Carry(color), Carry(normal, normal=True), Carry(normal, normal=True, about_base=True)]
    one, _ = timed(lambda: carry(mm, maps, source, uv, items))
    each, _ = timed(lambda: [carry(mm, maps, source, uv, [it]) for it in items])
    return {"carry_one_pass_s": round(one, 1), "carry_per_image_s": round(each, 1)}


if __name__ == "__main__":
    main()
