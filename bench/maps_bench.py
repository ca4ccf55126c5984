"""Height and normal maps: how well a height map rebuilds the micro-mesh, and what baking costs.

For each micro-mesh file given (``NAME.gltf`` as ``batch.py`` writes it), bakes the maps at
each resolution and reports the RMS and maximum distance between the micro-vertices and the
same points rebuilt from the base and the height map (``core.maps.rebuilt_positions``, over the
bounding-box diagonal), beside the simplest alternative in the same run: the height sampled at
the nearest texel instead of bilinearly. With ``--judge-json`` (the judge's JSON of the same
file) it prints the micro-mesh's own geometric error against its reference, the yardstick.

    python bench/maps_bench.py OUT/NAME.gltf [...] [--res 2048 4096] [--json FILE]
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from _common import parser, print_table, timed, write_json
from core.io.micromesh_import import read_micromesh
from core.maps import bake_maps, rebuild_error


def main() -> None:
    p = parser(__doc__.split("\n")[0])
    p.add_argument("files", nargs="+")
    p.add_argument("--res", type=int, nargs="+", default=[2048, 4096])
    args = p.parse_args()
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
            print(rows[-1], flush=True)
            write_json(args.json, rows)
    print_table(rows, ["mesh", "res", "bake_s", "rms", "rms_nearest", "max", "geom_err_vs_ref"],
                title="height map -> micro-mesh (distances over the bounding-box diagonal)")


if __name__ == "__main__":
    main()
