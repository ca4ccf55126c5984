"""Construction quality: what a user gets from ``batch.py`` with no overrides, against
NVlabs/micromesh-tools run with its defaults, both scored by the independent judge.

For each mesh of ../shared/meshes it runs ``python batch.py --input MESH --output DIR --ply``
(plus the row's ``--set`` overrides, if any) in a subprocess, exactly as a user would, then
``../shared/judge/judge.py`` on the micro-mesh file it wrote (``NAME.gltf`` + ``.bary``) and
on micromesh-tools' (``../shared/baselines/NAME/out_NAME.gltf``; judged once and cached): PSNR,
geometric error, shell volume (tight), storage (micromesh-tools' ``out_size`` formula: ``storage``;
the ``.bin`` + ``.bary`` files on disk: ``disk``), base isotropy and cracks are the judge's for
both. ``file_vs_ply`` is the judge's PSNR of our file
minus that of our float tessellation (``--ply``): what the 11-bit file loses. ``--staged`` adds our staged baseline
(``--method projection``, level 3 uniform, on the same default base) as the simplest
alternative.

``--meshreduce PATH`` (or ``$MICROMESH_MESHREDUCE``) runs micromesh-tools itself in the same run,
right after ours on each mesh: its ``meshreduce`` (built as ``docs/micromesh-tools.md`` says) on
the mesh written as OBJ, with ``../shared/baselines/cmds.txt``, as that folder's README ran it.
Its wall time then stands beside ours (``time_mmt``, ``time_x``: ours over its), and its files
are the ones judged. Without it, ``time_mmt`` is the wall time recorded with the shared
baselines (``run.json``, another day's machine: ``time_src`` says which).

    python bench/construct_bench.py [--meshes NAME ...] [--generated [NAME ...]]
        [--set key=value ...] [--staged] [--baselines DIR] [--meshreduce PATH]
        [--judge-python PATH] [--out DIR] [--json FILE]

``--generated`` runs the meshes ``bench/generated_meshes.py`` makes (high genus, many parts,
a 871k-face scan-like surface and the same surface without its noise), judged against
themselves; micromesh-tools' columns stay empty until its outputs for them are in
``../shared/baselines/NAME/`` or in the folder ``--baselines`` names (its
``NAME/out_NAME.gltf``, made as ``../shared/baselines/README.md`` says).

The judge needs its own environment (``python3 -m venv V && V/bin/pip install -r
../shared/judge/requirements.txt``); give its interpreter with ``--judge-python`` or
``$MICROMESH_JUDGE_PYTHON``.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
import zlib
from pathlib import Path

import numpy as np

from _common import MESHES, ROOT, parser, print_table, write_json
from core.io.ply import read_ply
from generated_meshes import GENERATED, write as write_generated

SHARED = MESHES.parent
BASELINES = SHARED / "baselines"
JUDGE = SHARED / "judge" / "judge.py"


def judge(python: str, ref: Path, mm: Path, out_json: Path) -> dict:
    """The judge's JSON for ``mm`` against ``ref`` (cached in ``out_json``)."""
    if not out_json.exists():
        r = subprocess.run([python, str(JUDGE), "--ref", str(ref), "--mm", str(mm), "--json",
                            str(out_json), "--quiet"], capture_output=True, text=True)
        if r.returncode != 0:
            raise RuntimeError(f"judge failed on {mm}: {r.stderr[-2000:]}")
    return json.loads(out_json.read_text())


def run_batch(mesh: Path, out: Path, overrides: list[str], extra: list[str]) -> tuple[dict, float]:
    """batch.py on one mesh; (metrics of the run, wall seconds)."""
    cmd = [sys.executable, str(ROOT / "batch.py"), "--input", str(mesh), "--output", str(out),
           "--ply", "--force"] + extra + [a for o in overrides for a in ("--set", o)]
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    wall = time.perf_counter() - t0
    (out / f"{mesh.stem}.log").write_text(r.stdout + r.stderr)
    if r.returncode != 0:
        raise RuntimeError(f"batch.py failed on {mesh.name}: {r.stderr[-2000:]}")
    return json.loads((out / f"{mesh.stem}.metrics.json").read_text())["metrics"], wall


def run_meshreduce(exe: Path, mesh: Path, out: Path) -> dict:
    """micromesh-tools' ``meshreduce`` on ``mesh`` in ``out`` (its ``out_NAME.*`` written
    there): the mesh as OBJ with float32-exact vertices and the faces as they are, the shared
    baselines' commands; {"wall_s", "peak_rss_mb"} of the process (loading, every command,
    its statistics and writing, as ``run.json`` of the shared baselines measured them)."""
    name = mesh.stem
    v, f = read_ply(mesh)
    with open(out / f"{name}.obj", "w") as fh:   # its reader stops at a blank line: none
        fh.writelines(f"v {a:.9g} {b:.9g} {c:.9g}\n" for a, b, c in v.astype(np.float32))
        fh.writelines(f"f {a} {b} {c}\n" for a, b, c in f + 1)
    shutil.copyfile(BASELINES / "cmds.txt", out / "cmds.txt")
    t0 = time.perf_counter()
    proc = subprocess.Popen([str(exe), f"{name}.obj", "cmds.txt", "out_"], cwd=out,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    log = proc.stdout.read()
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    (out / "meshreduce.log").write_bytes(log)
    if os.waitstatus_to_exitcode(status) != 0 or not (out / f"out_{name}.gltf").exists():
        raise RuntimeError(f"meshreduce failed on {mesh.name}: {log[-2000:].decode(errors='replace')}")
    return {"wall_s": round(wall, 2), "peak_rss_mb": round(usage.ru_maxrss / 1024, 1)}


def theirs(name: str, mesh: Path, python: str, cache: Path, baselines: list[Path]) -> dict | None:
    """The judge's figures for micromesh-tools' file (the first of ``baselines`` that has
    ``NAME/out_NAME.gltf``), or None where none has it; with its wall time where that folder
    records one (``run.json``)."""
    path = next((p for p in (b / name / f"out_{name}.gltf" for b in baselines) if p.exists()),
                None)
    if path is None:
        return None
    tag = zlib.crc32(str(path.resolve()).encode())          # one cache per baselines folder
    j = judge(python, mesh, path, cache / f"theirs_{name}_{tag:08x}.json")
    run = path.parent / "run.json"
    return {"wall_s": json.loads(run.read_text()).get("wall_s") if run.exists() else None,
            "psnr": j["render"]["psnr_full"], "geom_err": j["geom_error"]["ref_to_mm"]["avg"],
            "shell": j["shell"]["shell_volume_tight"], "bytes": j["storage"]["mmt_formula_bytes"],
            "disk": j["storage"]["disk_bytes_bin_bary"],
            "iso_base": j["isotropy"]["iso_base"], "cracks": j["watertightness"]["crack_edges"],
            "base_faces": j["counts"]["base_faces"], "micro_faces": j["counts"]["micro_faces_full"]}


def theirs_now(args, mesh: Path) -> dict | None:
    """micromesh-tools' figures for ``mesh``: its ``meshreduce`` run now where
    ``--meshreduce`` is given (its wall time of this run), else :func:`theirs` of the
    baseline folders (the wall time they recorded)."""
    name, cache = mesh.stem, Path(args.out)
    if args.meshreduce is None:
        t = theirs(name, mesh, args.judge_python, cache,
                   [b for b in (args.baselines, BASELINES) if b is not None])
        return None if t is None else {**t, "time_src": "recorded"}
    mout = cache / "meshreduce" / name
    shutil.rmtree(mout, ignore_errors=True)
    mout.mkdir(parents=True)
    timing = run_meshreduce(args.meshreduce, mesh, mout)
    for stale in cache.glob(f"theirs_{name}_*.json"):
        stale.unlink()
    t = theirs(name, mesh, args.judge_python, cache, [mout.parent])
    return {**t, **timing, "time_src": "same run"}


def ours(mesh: Path, label: str, python: str, out: Path, overrides: list[str],
         extra: list[str]) -> dict:
    name = mesh.stem
    m, wall = run_batch(mesh, out, overrides, extra)
    for stale in out.glob("judge_*.json"):     # scores of an earlier run's files
        stale.unlink()
    j = judge(python, mesh, out / f"{name}.gltf", out / f"judge_{name}.json")
    jp = judge(python, mesh, out / f"{name}_micromesh.ply", out / f"judge_{name}_ply.json")
    base = m.get("base", {})
    topo_ok = base.get("topology_input") == base.get("topology_base") if base else None
    return {"psnr": j["render"]["psnr_full"], "psnr_ply": jp["render"]["psnr_full"],
            "geom_err": j["geom_error"]["ref_to_mm"]["avg"],
            "shell": j["shell"]["shell_volume_tight"], "bytes": j["storage"]["mmt_formula_bytes"],
            "disk": j["storage"]["disk_bytes_bin_bary"],
            "iso_base": j["isotropy"]["iso_base"], "cracks": j["watertightness"]["crack_edges"],
            "base_faces": j["counts"]["base_faces"], "micro_faces": j["counts"]["micro_faces_full"],
            "micro_faces_ours": m["micro_triangles"], "time_s": round(wall, 1),
            "topology_kept": topo_ok, "warnings": m.get("warnings", []), "label": label}


def main() -> None:
    p = parser(__doc__.splitlines()[0])
    p.add_argument("--meshes", nargs="+", default=None, help="default: every mesh in ../shared/meshes")
    p.add_argument("--set", nargs="+", action="extend", default=[], metavar="KEY=VALUE",
                   help="settings overrides for our row (a non-default row, labelled so)")
    p.add_argument("--staged", action="store_true", help="add our staged baseline row")
    p.add_argument("--generated", nargs="*", default=None, metavar="NAME",
                   help="the meshes of bench/generated_meshes.py (all, or those named): "
                        "instead of the shared ones, or besides those --meshes names")
    p.add_argument("--baselines", type=Path, default=None, metavar="DIR",
                   help="micromesh-tools' outputs (DIR/NAME/out_NAME.gltf) besides those of "
                        "../shared/baselines, looked up first")
    p.add_argument("--meshreduce", type=Path,
                   default=os.environ.get("MICROMESH_MESHREDUCE") or None, metavar="PATH",
                   help="micromesh-tools' meshreduce: run it beside ours, in the same run "
                        "(docs/micromesh-tools.md builds it)")
    p.add_argument("--judge-python", default=os.environ.get("MICROMESH_JUDGE_PYTHON",
                                                            str(SHARED / "judge" / "venv" / "bin" / "python")))
    p.add_argument("--out", default="/tmp/micromesh_construct_bench")
    args = p.parse_args()
    shared = args.meshes is not None or args.generated is None
    if shared and (not MESHES.exists() or not BASELINES.exists()):
        sys.exit(f"skip: {MESHES} or {BASELINES} not found")
    names = (args.meshes or sorted(f.stem for f in MESHES.glob("*.ply"))) if shared else []
    if args.meshreduce is not None and not (args.meshreduce.is_file()
                                            and (BASELINES / "cmds.txt").exists()):
        sys.exit(f"--meshreduce: {args.meshreduce} or {BASELINES / 'cmds.txt'} not found")
    if not Path(args.judge_python).exists():
        sys.exit(f"the judge's interpreter {args.judge_python} was not found (see --help)")
    meshes = [MESHES / f"{n}.ply" for n in names]
    if args.generated is not None:
        meshes += [write_generated(n, Path(args.out) / "generated")
                   for n in args.generated or GENERATED]
    label = "default" if not args.set else "default+" + ",".join(args.set)
    rows, records = [], []
    for mesh in meshes:
        name = mesh.stem
        out = Path(args.out) / label.replace("/", "_") / name
        out.mkdir(parents=True, exist_ok=True)
        rows_here = [("ours", ours(mesh, label, args.judge_python, out, args.set, []))]
        t = theirs_now(args, mesh)           # right after ours: the same machine, same load
        if args.staged:
            sout = out / "staged"
            sout.mkdir(exist_ok=True)
            rows_here.append(("staged", ours(mesh, "staged", args.judge_python, sout, [],
                                             ["--method", "projection", "--level", "3"])))
        for kind, o in rows_here:
            rec = {"mesh": name, "row": o["label"], "psnr": round(o["psnr"], 2),
                   "file_vs_ply": round(o["psnr"] - o["psnr_ply"], 2),
                   "iso_base": round(o["iso_base"], 3), "cracks": o["cracks"],
                   "topology": o["topology_kept"], "base_f": o["base_faces"],
                   "time_s": o["time_s"], **_against(o, t)}
            rows.append(rec)
            records.append({**rec, "ours": o, "theirs": t})
            print(rec, flush=True)
            write_json(args.json, records)
    cols = ["mesh", "row", "dpsnr", "psnr", "psnr_mmt", "file_vs_ply", "storage", "disk", "shell",
            "iso_base", "iso_mmt",
            "geom_err", "cracks", "topology", "base_f", "base_f_mmt", "time_s", "time_mmt",
            "time_x", "time_src"]
    print_table(rows, cols, title="ours vs micromesh-tools (judge PSNR; storage (formula), disk "
                                  "(.bin + .bary), shell and geometric error as ours / theirs)")
    for lab in dict.fromkeys(r["row"] for r in rows):
        d = np.array([r["dpsnr"] for r in rows if r["row"] == lab and r["dpsnr"] is not None])
        if len(d):
            print(f"{lab}: mean ΔPSNR {d.mean():+.2f} dB, worst {d.min():+.2f} dB over {len(d)} "
                  f"meshes")
        x = np.array([r["time_x"] for r in rows if r["row"] == lab and r["time_x"] is not None])
        if len(x):
            print(f"{lab}: time over micromesh-tools' median {np.median(x):.1f}x, worst "
                  f"{x.max():.1f}x over {len(x)} meshes")
        alone = [r["mesh"] for r in rows if r["row"] == lab and r["dpsnr"] is None]
        if alone:
            print(f"{lab}: no micromesh-tools output to compare with for {', '.join(alone)} "
                  f"(put it in {BASELINES}/NAME/out_NAME.gltf or give --baselines)")


def _against(o: dict, t: dict | None) -> dict:
    """The columns that compare ours with micromesh-tools' (None without its output)."""
    if t is None:
        return dict.fromkeys(("dpsnr", "psnr_mmt", "storage", "disk", "shell", "iso_mmt",
                              "geom_err", "base_f_mmt", "time_mmt", "time_x", "time_src"))
    wall = t.get("wall_s")
    return {"dpsnr": round(o["psnr"] - t["psnr"], 2), "psnr_mmt": round(t["psnr"], 2),
            "storage": round(o["bytes"] / t["bytes"], 3), "disk": round(o["disk"] / t["disk"], 3),
            "shell": round(o["shell"] / t["shell"], 3), "iso_mmt": round(t["iso_base"], 3),
            "geom_err": round(o["geom_err"] / t["geom_err"], 3), "base_f_mmt": t["base_faces"],
            "time_mmt": wall, "time_x": round(o["time_s"] / wall, 1) if wall else None,
            "time_src": t.get("time_src")}


if __name__ == "__main__":
    main()
