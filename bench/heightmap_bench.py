"""Height maps as renderers draw them: ours (fitted to the source) against the conventional
bake on the same base, UVs and texels, and against our micro-mesh, all scored by the judge.

For each mesh it runs ``python batch.py --input MESH --output DIR --maps 2048`` in a
subprocess, exactly as a user would (default preset, no overrides), then with the judge's
``heightmap.py``:

- ``tess --level 4`` on the ``NAME_base.gltf`` it wrote (the height map through
  ``KHR_materials_displacement``, sampled as a renderer does) and the judge's PSNR;
- ``bake --res R`` on the same glTF: the conventional bake (rays both ways from each texel,
  as Blender's Selected-to-Active bake), tessellated and judged the same way (its time is the
  simplest alternative's: ``bake_s``);
- the same bake on xatlas' charts of the same base (``psnr_bake_charts``): our atlas puts
  every face in a texel-aligned block (``core.maps.blocks``), which the bake may like less
  than charts; ``dpsnr_best`` is ours against the better of the two bakes;
- the judge on our micro-mesh (``NAME.gltf`` + ``.bary``);
- the seam gaps ``tess`` prints at levels 3, 4 and 5 (over the diagonal).

At the other resolutions (``--res``, default 512 1024 2048) the maps stage runs again on the
same result in a child process, as ``--maps R`` would run it (``core.maps.make_maps``; the
construction does not depend on ``--maps``), which also measures its time and its peak
memory above what the inputs take (``maps_s``, ``maps_mb``; at 2048 its files are not used,
the product's are). Bytes: the height PNG at each resolution beside the micro-mesh's
``.bin`` + ``.bary``: the rate-distortion table.

    python bench/heightmap_bench.py [--meshes NAME ...] [--generated [NAME ...]]
        [--res 512 1024 2048] [--reuse DIR] [--judge-python PATH] [--out DIR] [--json FILE]

``--reuse DIR`` takes each mesh's micro-mesh from an earlier ``batch.py`` run's output
folder (``DIR/NAME.gltf``, ``.bin``, ``.bary``, ``.metrics.json``) instead of constructing
it: the maps stage then runs in the child only, at every resolution (no ``product_maps_s``).

The judge needs its own environment (``--judge-python`` or ``$MICROMESH_JUDGE_PYTHON``,
as ``construct_bench.py``).
"""
from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

from _common import MESHES, ROOT, add_child_option, parser, print_table, write_json
from construct_bench import judge
from generated_meshes import GENERATED, write as write_generated

SHARED = MESHES.parent
HEIGHTMAP = SHARED / "judge" / "heightmap.py"
PRODUCT_RES = 2048


def child(case: dict) -> dict:
    """The maps stage at ``case["res"]`` on a result (``NAME.gltf``) and its source, written
    beside ``case["out"]`` as ``batch.py --maps`` writes it: seconds and peak MB above the
    inputs."""
    from core.io import formats
    from core.io.mesh_files import read_mesh
    from core.io.micromesh_import import read_micromesh
    import numpy as np

    from core.maps import Maps, uv_atlas
    from core.maps.make import make_maps

    mm = read_micromesh(case["result"]).micromesh()
    source = read_mesh(case["source"])
    before = _rss_mb(reset=True)
    t0 = time.perf_counter()
    maps = make_maps(mm, source, case["res"])
    secs = time.perf_counter() - t0
    peak = _rss_mb(peak=True) - before
    product = formats.Product(mm, maps=maps)
    out = Path(case["out"])
    out.parent.mkdir(parents=True, exist_ok=True)
    for key in ("base-gltf", "height-png", "normal-png"):
        files, _ = formats.write(formats.FORMATS[key], product, out.name)
        for suffix, data in files.items():
            (out.parent / f"{out.name}{suffix}").write_bytes(data)
    charts = Maps(uv_atlas(mm.base, case["res"]), np.zeros_like(maps.height),
                  maps.normal, maps.filled)            # the base on xatlas' charts, for the bake
    files, _ = formats.write(formats.FORMATS["base-gltf"],
                             formats.Product(mm, maps=charts), f"{out.name}_charts")
    for suffix, data in files.items():
        (out.parent / f"{out.name}_charts{suffix}").write_bytes(data)
    return {"maps_s": round(secs, 1), "maps_mb": round(peak), "notes": maps.notes}


def _rss_mb(reset: bool = False, peak: bool = False) -> float:
    """This process's resident MB now (``reset``: the kernel's peak reset to it first), or
    its peak since (``peak``); Linux."""
    if reset:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")
    field = "VmHWM" if peak else "VmRSS"
    text = Path("/proc/self/status").read_text()
    return int(re.search(rf"{field}:\s+(\d+)", text).group(1)) / 1024


def run_child(case: dict) -> dict:
    r = subprocess.run([sys.executable, __file__, "--child", json.dumps(case)],
                       capture_output=True, text=True, cwd=ROOT)
    if r.returncode != 0:
        raise RuntimeError(f"maps stage failed: {r.stderr[-2000:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def heightmap(python: str, *args) -> tuple[str, float]:
    """(what ``heightmap.py`` printed, its seconds)."""
    t0 = time.perf_counter()
    r = subprocess.run([python, str(HEIGHTMAP), *map(str, args)], capture_output=True,
                       text=True)
    if r.returncode != 0:
        raise RuntimeError(f"heightmap.py {args[0]} failed: {r.stderr[-2000:]}")
    return r.stdout, time.perf_counter() - t0


def drawn(python: str, gltf: Path, mesh: Path, level: int = 4, score: bool = True) -> dict:
    """``gltf``'s base and height map tessellated at ``level``: the seam gap and (``score``)
    the judge's PSNR."""
    ply = gltf.with_name(f"{gltf.stem}_tess{level}.ply")
    text, _ = heightmap(python, "tess", "--gltf", gltf, "--level", level, "--out", ply)
    gap = float(re.search(r"gap max ([0-9.e+-]+)", text).group(1))
    out = {"gap": gap}
    if score:
        j = judge(python, mesh, ply, gltf.with_name(f"judge_{gltf.stem}_{level}.json"))
        out["psnr"] = j["render"]["psnr_full"]
    ply.unlink()
    return out


def run_batch(mesh: Path, out: Path) -> dict:
    """``batch.py --maps 2048`` on ``mesh`` (an earlier complete result is kept); its
    metrics."""
    metrics = out / f"{mesh.stem}.metrics.json"
    if not metrics.exists():
        cmd = [sys.executable, str(ROOT / "batch.py"), "--input", str(mesh), "--output",
               str(out), "--maps", str(PRODUCT_RES), "--force"]
        r = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
        (out / f"{mesh.stem}.log").write_text(r.stdout + r.stderr)
        if r.returncode != 0:
            raise RuntimeError(f"batch.py failed on {mesh.name}: {r.stderr[-2000:]}")
    return json.loads(metrics.read_text())["metrics"]


def one_mesh(mesh: Path, python: str, out: Path, resolutions: list[int],
             reuse: Path | None = None) -> list[dict]:
    name = mesh.stem
    if reuse is not None:
        for suffix in (".gltf", ".bin", ".bary", ".metrics.json"):
            if not (out / f"{name}{suffix}").exists():
                shutil.copyfile(reuse / f"{name}{suffix}", out / f"{name}{suffix}")
    m = run_batch(mesh, out)
    mm_judged = judge(python, mesh, out / f"{name}.gltf", out / f"judge_{name}.json")
    disk = mm_judged["storage"]["disk_bytes_bin_bary"]
    rows = [{"mesh": name, "form": "micro-mesh", "res": None, "bytes": disk,
             "psnr": round(mm_judged["render"]["psnr_full"], 2),
             "construct_s": round(m["time_s"], 1)}]
    for res in resolutions:
        stage = run_child({"result": str(out / f"{name}.gltf"), "source": str(mesh),
                           "res": res, "out": str(out / str(res) / name)})
        gltf = out / f"{name}_base.gltf"           # the product's, where batch.py made it
        if res != PRODUCT_RES or not gltf.exists():
            gltf = out / str(res) / f"{name}_base.gltf"
        png = gltf.with_name(f"{name}_height.png")
        ours = drawn(python, gltf, mesh)
        baked = gltf.with_name(f"{name}_bake.gltf")
        _, bake_s = heightmap(python, "bake", "--gltf", gltf, "--ref", mesh, "--res", res,
                              "--out", baked)
        theirs = drawn(python, baked, mesh)
        on_charts = out / str(res) / f"{name}_charts_bake.gltf"
        heightmap(python, "bake", "--gltf", out / str(res) / f"{name}_charts_base.gltf",
                  "--ref", mesh, "--res", res, "--out", on_charts)
        charts = drawn(python, on_charts, mesh)
        row = {"mesh": name, "form": "height map", "res": res, "bytes": png.stat().st_size,
               "psnr": round(ours["psnr"], 2), "psnr_bake": round(theirs["psnr"], 2),
               "dpsnr": round(ours["psnr"] - theirs["psnr"], 2),
               "psnr_bake_charts": round(charts["psnr"], 2),
               "dpsnr_best": round(ours["psnr"] - max(theirs["psnr"], charts["psnr"]), 2),
               "gap4": ours["gap"],
               "gap4_bake": theirs["gap"], "maps_s": stage["maps_s"],
               "maps_mb": stage["maps_mb"], "bake_s": round(bake_s, 1),
               "construct_s": round(m["time_s"], 1)}
        if res == PRODUCT_RES:
            if "maps" in m:
                row["product_maps_s"] = round(m["maps"]["time_s"], 1)
            row["gap3"] = drawn(python, gltf, mesh, 3, score=False)["gap"]
            row["gap5"] = drawn(python, gltf, mesh, 5, score=False)["gap"]
        rows.append(row)
    return rows


def main() -> None:
    p = parser(__doc__.splitlines()[0])
    add_child_option(p)
    p.add_argument("--meshes", nargs="+", default=None, help="default: every mesh in ../shared/meshes")
    p.add_argument("--generated", nargs="*", default=None, metavar="NAME",
                   help="the meshes of bench/generated_meshes.py (all, or those named)")
    p.add_argument("--res", type=int, nargs="+", default=[512, 1024, 2048])
    p.add_argument("--reuse", type=Path, default=None, metavar="DIR",
                   help="micro-meshes from an earlier batch.py output folder (no construction)")
    p.add_argument("--judge-python", default=os.environ.get(
        "MICROMESH_JUDGE_PYTHON", str(SHARED / "judge" / "venv" / "bin" / "python")))
    p.add_argument("--out", default="/tmp/micromesh_heightmap_bench")
    args = p.parse_args()
    if args.child:
        print(json.dumps(child(json.loads(args.child))))
        return
    shared = args.meshes is not None or args.generated is None
    if shared and not MESHES.exists():
        sys.exit(f"skip: {MESHES} not found")
    if not Path(args.judge_python).exists():
        sys.exit(f"the judge's interpreter {args.judge_python} was not found (see --help)")
    names = (args.meshes or sorted(f.stem for f in MESHES.glob("*.ply"))) if shared else []
    meshes = [MESHES / f"{n}.ply" for n in names]
    if args.generated is not None:
        meshes += [write_generated(n, Path(args.out) / "generated")
                   for n in args.generated or GENERATED]
    rows = []
    for mesh in meshes:
        out = Path(args.out) / mesh.stem
        out.mkdir(parents=True, exist_ok=True)
        for row in one_mesh(mesh, args.judge_python, out, args.res, args.reuse):
            rows.append(row)
            print(row, flush=True)
            write_json(args.json, rows)
    print_table(rows, ["mesh", "form", "res", "bytes", "psnr", "psnr_bake", "dpsnr",
                       "psnr_bake_charts", "dpsnr_best", "gap3",
                       "gap4", "gap5", "gap4_bake", "construct_s", "product_maps_s", "maps_s",
                       "maps_mb", "bake_s"],
                title="height maps (ours, fitted) vs the conventional bake vs the micro-mesh; "
                      "PSNR by the judge at tessellation level 4, gaps over the diagonal")
    maps = [r for r in rows if r["form"] == "height map" and r["res"] == PRODUCT_RES]
    if maps:
        worst = min(maps, key=lambda r: r["dpsnr_best"])
        print(f"at {PRODUCT_RES}²: ours - the better bake {worst['dpsnr_best']:+.2f} dB at worst "
              f"({worst['mesh']}), mean {sum(r['dpsnr_best'] for r in maps) / len(maps):+.2f} dB; "
              f"largest seam gap {max(max(r['gap3'], r['gap4'], r['gap5']) for r in maps):.1e}")


if __name__ == "__main__":
    main()
