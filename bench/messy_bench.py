"""Messy inputs: what a user gets from ``batch.py`` (default preset, no overrides) on the
meshes users have, against the same mesh clean, scored by the independent judge.

For each shared mesh given it builds the corpus of ``tests/corpus.py`` (a triangle soup, one
with its coincident vertices 1e-8 of the diagonal apart, binary and ASCII STL, USD from
Blender's exporter, the mesh moved to (2e5, -3e5, 1e4) and (1e6, -1e6, 1e6) in a
double-precision PLY, mixed degenerate faces, T-junctions, holes; generated: a sphere with
non-manifold fins and holes, 300 parts; NaN/inf in PLY, OBJ, STL and glTF, broken glTF files)
and runs ``python batch.py --input CASE --output DIR --force`` on each, as a user would.

- ``same`` cases hold the clean mesh's surface: their judge PSNR (against the clean mesh, in
  the case's own frame) must be within 0.2 dB of the clean mesh's (``ok``), with no cracks;
- ``changed`` cases must construct, crack-free (their PSNR is against themselves);
- ``refuse`` cases must exit 1 with one line naming the cause and no traceback.

    python bench/messy_bench.py [--meshes rocker_arm_20k ...] [--judge-python PATH]
        [--out DIR] [--json FILE]
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from _common import MESHES, ROOT, parser, print_table, write_json

sys.path.insert(0, str(ROOT / "tests"))
import corpus  # noqa: E402

from core.io.mesh_files import read_mesh, write_ply  # noqa: E402

JUDGE = MESHES.parent / "judge" / "judge.py"
TOLERANCE_DB = 0.2


def run_case(case: corpus.Case, out: Path) -> dict:
    cmd = [sys.executable, str(ROOT / "batch.py"), "--input", str(case.path), "--output",
           str(out), "--force"]
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    wall = time.perf_counter() - t0
    (out / "batch.log").write_text(r.stdout + r.stderr)
    errors = [ln for ln in r.stderr.splitlines() if ln.startswith("batch.py: error:")]
    return {"exit": r.returncode, "time_s": round(wall, 1),
            "traceback": "Traceback" in r.stdout + r.stderr, "errors": errors}


def judge(python: str, ref: Path, mm: Path) -> dict:
    out = mm.with_suffix(".judge.json")
    r = subprocess.run([python, str(JUDGE), "--ref", str(ref), "--mm", str(mm), "--json",
                        str(out), "--quiet"], capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"judge failed on {mm}: {r.stderr[-2000:]}")
    return json.loads(out.read_text())


def y_up(reference: Path, folder: Path) -> Path:
    """The reference in glTF's Y-up frame: a USD source (Blender's export, Z-up) stays Z-up
    in Blender, and what is in Blender's frame is exported Y-up."""
    m = read_mesh(reference)
    path = folder / f"{reference.stem}_yup.ply"
    write_ply(path, m.vertices @ np.array([[1, 0, 0], [0, 0, 1], [0, -1, 0]]).T, m.faces,
              double=True)
    return path


def score(case: corpus.Case, out: Path, python: str) -> dict:
    stem = case.path.stem
    gltf = out / f"{stem}.gltf"
    ref = y_up(case.reference, out) if case.path.suffix.startswith(".usd") else case.reference
    j = judge(python, ref, gltf)
    m = json.loads((out / f"{stem}.metrics.json").read_text())["metrics"]
    return {"psnr": round(j["render"]["psnr_full"], 2), "cracks": j["watertightness"]["crack_edges"],
            "base_f": j["counts"]["base_faces"], "bytes": j["storage"]["mmt_formula_bytes"],
            "warnings": m.get("warnings", [])}


def main() -> None:
    p = parser(__doc__.splitlines()[0])
    p.add_argument("--meshes", nargs="+", default=["rocker_arm_20k"])
    p.add_argument("--judge-python", default=os.environ.get("MICROMESH_JUDGE_PYTHON",
                                                            str(JUDGE.parent / "venv" / "bin" / "python")))
    p.add_argument("--out", default="/tmp/micromesh_messy_bench")
    p.add_argument("--cases", nargs="+", default=None, help="only these cases (and clean)")
    args = p.parse_args()
    if not MESHES.exists():
        sys.exit(f"skip: {MESHES} not found")
    if not Path(args.judge_python).exists():
        sys.exit(f"the judge's interpreter {args.judge_python} was not found (see --help)")
    rows = []
    for i, name in enumerate(args.meshes):
        folder = Path(args.out) / name
        cases = corpus.build(read_mesh(MESHES / f"{name}.ply"), folder / "inputs",
                             generated=i == 0)
        if args.cases:
            cases = [c for c in cases if c.name in args.cases or c.name == "clean"]
        clean_psnr = None
        for case in cases:
            out = folder / case.name
            out.mkdir(parents=True, exist_ok=True)
            row = {"mesh": name, "case": case.name, "expect": case.expect, **run_case(case, out)}
            errors = row.pop("errors")
            if case.expect == "refuse":
                row["ok"] = (row["exit"] == 1 and not row["traceback"] and len(errors) == 1
                             and case.cause.lower() in errors[0].lower())
                row["message"] = errors[0] if errors else ""
            elif row["exit"] != 0:
                row["ok"] = False
            else:
                row.update(score(case, out, args.judge_python))
                if case.name == "clean":
                    clean_psnr = row["psnr"]
                if case.expect == "same" and clean_psnr is not None:
                    row["dpsnr"] = round(row["psnr"] - clean_psnr, 2)
                row["ok"] = row["cracks"] == 0 and (case.expect != "same"
                                                    or abs(row.get("dpsnr", 0)) <= TOLERANCE_DB)
            rows.append(row)
            print(json.dumps({k: v for k, v in row.items() if k != "warnings"}), flush=True)
            write_json(args.json, rows)
    print_table(rows, ["mesh", "case", "expect", "exit", "psnr", "dpsnr", "cracks", "base_f",
                       "time_s", "ok"],
                title=f"messy inputs: batch.py's default, judged (same: within {TOLERANCE_DB} dB "
                      "of the clean mesh)")
    for r in rows:
        if r["expect"] == "refuse":
            print(f"{r['mesh']} {r['case']}: {r['message']}")
    bad = [r["case"] for r in rows if not r["ok"]]
    print(f"{len(rows) - len(bad)} of {len(rows)} cases as expected" + (f"; not: {bad}" if bad else ""))


if __name__ == "__main__":
    main()
