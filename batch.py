"""Headless micro-mesh construction: ``python batch.py ARGS`` or ``blender -b --python batch.py -- ARGS``.

With no ``--input`` it builds the built-in demo: a procedurally generated detailed mesh (an
icosphere displaced by Blender's procedural textures, made at run time), decimated into a base
(``core.base``: topology kept, error and triangle shape bounded) and turned into a micro-mesh
within a storage budget. With ``--input`` (one file or a folder of .ply / .obj / .glb / .gltf /
.fbx / .blend; a micro-mesh glTF is read as its tessellation) it does the same per input: the
same workflow as the add-on's panel (``operators.pipeline``). Per input NAME it writes
``NAME.blend`` (holding ``NAME_micromesh`` and ``NAME_base``), the micro-mesh for other tools
(``NAME.gltf`` + ``.bin`` + ``.bary``; or ``--export glb``), with ``--maps RES`` height and
normal maps (``NAME_maps`` in the .blend, ``NAME_height.exr``, ``NAME_normal.png``,
``NAME_base.gltf``), the run report (``NAME.report.png``, ``NAME.report.json``),
``NAME.metrics.json`` and with ``--ply`` ``NAME_micromesh.ply``: NAME is the
input's stem (``stem_ext`` where two inputs share one), the files appear together when the input
is done (the metrics file last), and existing results are kept unless ``--force``.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import threading
import time
import traceback
from pathlib import Path

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

SUFFIXES = (".ply", ".obj", ".glb", ".gltf", ".fbx", ".blend")
DEMO_NAME = "demo_rock"


EXIT_CODES = """exit status:
  0    every input done
  1    some inputs failed (each named on one line; the others were done)
  2    bad usage: options, input paths, output folder, results that exist (nothing was done)
  3    internal error (a traceback follows: please report it)
  130  interrupted (Ctrl-C); files of the input in progress are not left behind"""


class BatchError(ValueError):
    """Bad input: reported as one line, exit status 2."""


class Interrupt:
    """Ctrl-C: during a construction it asks the construction to stop at its next iteration
    (``should_stop``), so the stop never lands inside a compiled kernel or a thread pool;
    elsewhere, or at a second Ctrl-C, it interrupts at once (KeyboardInterrupt)."""

    def __init__(self) -> None:
        self.requested = False
        self.constructing = False

    def __call__(self, signum, frame) -> None:
        again, self.requested = self.requested, True
        if again or not self.constructing:
            raise KeyboardInterrupt

    def should_stop(self) -> bool:
        return self.requested

    def install(self) -> None:
        import signal

        if threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGINT, self)


def _in_blender() -> bool:
    """True inside the Blender executable (not the ``bpy`` module)."""
    bpy = sys.modules.get("bpy")
    return bool(bpy is not None and bpy.app.binary_path)


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    if argv is None:
        if "--" in sys.argv:  # blender -b --python batch.py -- ARGS
            argv = sys.argv[sys.argv.index("--") + 1:]
        elif _in_blender():   # blender -b --python batch.py: Blender's own arguments only
            argv = []
        else:                 # python batch.py ARGS
            argv = sys.argv[1:]
    p = argparse.ArgumentParser(prog="batch.py", description=__doc__.split("\n")[0],
                                epilog=EXIT_CODES,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--input", help="a mesh file or a folder of mesh files (default: the demo)")
    p.add_argument("--output", default="out", help="output folder (default: out)")
    p.add_argument("--preset", default="default",
                   help="fast, default, quality or paper (default: default)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a construction setting (repeatable)")
    p.add_argument("--method", default="auto", choices=("auto", "optimize", "projection"),
                   help="auto: the optimiser when available; projection: the staged baseline")
    p.add_argument("--level", type=int, default=None,
                   help="uniform level of the projection method (default: the preset's max_level)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--target-faces", type=int, default=None, help="base triangles")
    g.add_argument("--ratio", type=float, default=None,
                   help="base triangles as a fraction of the input's (default 1/32; 0: as far "
                        "as --base-error allows)")
    p.add_argument("--base-error", type=float, default=None,
                   help="bound on the base's distance to the input, relative to its bounding-box "
                        "diagonal (default 1e-3; 0: none)")
    p.add_argument("--base-method", choices=("collapse", "blender"), default="collapse",
                   help="collapse: topology-keeping, error-bounded (default); blender: "
                        "Blender's Decimate modifier")
    p.add_argument("--symmetry", choices=("X", "Y", "Z"), default=None,
                   help="symmetric decimation (with --base-method blender)")
    p.add_argument("--budget", default=None, metavar="AMOUNT",
                   help="storage budget: '2x' (micro-triangles per input face, the default), "
                        "'150000' (micro-triangles) or '300kB' / '2MB' / '500000B' (bytes); "
                        "'0': none")
    p.add_argument("--cameras", type=int, default=0,
                   help="place this many Fibonacci camera objects and construct with them")
    p.add_argument("--export", choices=("gltf", "glb", "none"), default="gltf",
                   help="the micro-mesh for other tools: NAME.gltf + .bin + .bary (default), "
                        "one NAME.glb, or none")
    p.add_argument("--values", choices=("r11", "float"), default="r11",
                   help="stored values: 11-bit packed (default) or 32-bit float")
    p.add_argument("--layout", choices=("bird", "umajor"), default="bird",
                   help="micro-vertex order: bird curve (default, the hardware's) or u-major")
    p.add_argument("--maps", type=int, default=0, metavar="RES",
                   help="also bake RES x RES height and normal maps: NAME_maps in the .blend, "
                        "NAME_height.exr, NAME_normal.png and NAME_base.gltf (UVs, normal map)")
    p.add_argument("--ply", action="store_true", help="also write NAME_micromesh.ply")
    p.add_argument("--force", action="store_true", help="replace results that already exist")
    p.add_argument("--threads", type=int, default=0, help="CPU threads (0: all usable cores)")
    p.add_argument("--demo-subdivisions", type=int, default=7, help=argparse.SUPPRESS)
    return p.parse_args(argv)


def budget_overrides(text: str) -> list[str]:
    """``--budget`` as settings overrides (one budget set, the others cleared)."""
    t = text.strip().lower().replace(" ", "")
    units = {"kb": 1e3, "mb": 1e6, "gb": 1e9, "b": 1.0}
    try:
        if t.endswith("x"):
            values = {"budget_ratio": float(t[:-1])}
        elif t[-1:] == "b":
            unit = next(u for u in units if t.endswith(u))
            values = {"budget_bytes": int(round(float(t[:-len(unit)]) * units[unit]))}
        else:
            values = {"budget_micro_triangles": int(t)}
    except (ValueError, StopIteration):
        raise BatchError(f"--budget {text!r}: give e.g. 2x, 150000 or 300kB") from None
    amount = next(iter(values.values()))
    if not amount >= 0 or amount != amount:
        raise BatchError("--budget must not be negative")
    out = {"budget_ratio": 0.0, "budget_micro_triangles": 0, "budget_bytes": 0}
    out.update(values)
    return [f"{k}={v}" for k, v in out.items()]


def base_overrides(args: argparse.Namespace) -> list[str]:
    """``--target-faces`` / ``--ratio`` / ``--base-error`` as settings overrides."""
    out = []
    if args.target_faces is not None:
        if args.target_faces < 4:
            raise BatchError("--target-faces must be at least 4")
        out.append(f"base_faces={args.target_faces}")
    if args.ratio is not None:
        if not 0 <= args.ratio <= 1:
            raise BatchError("--ratio must be within [0, 1]")
        out += [f"base_ratio={args.ratio}", "base_faces=0"]
    if args.base_error is not None:
        if not 0 <= args.base_error < 1:
            raise BatchError("--base-error must be within [0, 1)")
        out.append(f"base_max_error={args.base_error}")
    if args.symmetry and args.base_method != "blender":
        raise BatchError("--symmetry needs --base-method blender")
    return out


def find_inputs(path: str | None) -> list[Path]:
    if path is None:
        return []
    p = Path(path)
    if not p.exists():
        raise BatchError(f"input not found: {p}")
    if p.is_dir():
        files = sorted(f for f in p.iterdir() if f.suffix.lower() in SUFFIXES)
        if not files:
            raise BatchError(f"no {'/'.join(SUFFIXES)} files in {p}")
        return files
    if p.suffix.lower() not in SUFFIXES:
        raise BatchError(f"unsupported file type '{p.suffix}' ({', '.join(SUFFIXES)})")
    return [p]


# ------------------------------------------------------------------ one input
def process(bpy, pkg, source, args, settings, out, interrupt: Interrupt) -> dict:
    """Base mesh, cameras, construction, write-back, save: the add-on's steps, headless.
    ``out``: the result's :class:`OutputSet` (committed here, when every file is written)."""
    from micromesh.operators import (bl_mesh, cameras_io, construct_op, pipeline, result_files,
                                     writeback)

    from micromesh.cli.progress import PhaseProgress
    from micromesh.core.base import target_faces

    name = source.name
    t0 = time.perf_counter()
    notes: list[str] = []
    reference = bl_mesh.mesh_to_arrays(source, notes=notes)
    base_tm = None
    if args.base_method == "blender":
        target = min(target_faces(reference.n_faces, settings.base_ratio, settings.base_faces),
                     reference.n_faces)
        base_tm = bl_mesh.decimate_object(source, target_faces=max(4, target),
                                          symmetry=args.symmetry)
        print(f"[{name}] reference {reference.n_faces} triangles -> base {base_tm.n_faces} "
              f"(Blender's Decimate, {time.perf_counter() - t0:.1f} s)", flush=True)
    cams = None
    if args.cameras:
        coll = cameras_io.place_cameras(bpy.context.scene, reference, args.cameras,
                                        settings.camera_radius, settings.fov_y_deg)
        cams = cameras_io.collection_cameras(coll, settings.train_resolution)
    progress = PhaseProgress(name)
    interrupt.constructing = True
    try:
        outcome = pipeline.run(reference, base_tm, cams, settings, progress,
                               interrupt.should_stop, level=args.level, method=args.method,
                               preset_name=args.preset, input_warnings=notes)
        progress.close(complete=True)
    except pipeline.PipelineCancelled:
        raise KeyboardInterrupt from None
    finally:
        interrupt.constructing = False
        progress.close()
    if interrupt.requested:
        raise KeyboardInterrupt
    m = outcome.metrics
    if "base" in m:
        b = m["base"]
        print(f"[{name}] reference {reference.n_faces} triangles -> base {b['faces']} "
              f"(error {b['error_mean']:.2e} of the diagonal, isotropy {b['isotropy']:.3f}, "
              f"{b['time_s']:.1f} s)", flush=True)
        for note in b["notes"]:
            print(f"[{name}] note: {note}", flush=True)
    for warning in m.get("warnings", []):
        print(f"[{name}] warning: {warning}", flush=True)
    obj = construct_op.finish(bpy.context, source, None, outcome)   # as the panel does
    if args.maps:
        m["maps"] = result_files.write_maps(bpy.context, outcome, source, args.maps, out,
                                            progress)
        progress.close(complete=True)
    m["total_time_s"] = time.perf_counter() - t0
    bpy.ops.wm.save_as_mainfile(filepath=str(out.temp(".blend")), compress=True)
    if args.export != "none":
        m["export"] = result_files.write_export(outcome, source, args.export, args.values,
                                                args.layout, out)
    result_files.write_report(outcome, out)
    if args.ply:
        from micromesh.core.meshio import write_ply

        tess = outcome.micromesh.tessellate()
        write_ply(out.temp("_micromesh.ply"), tess.vertices, tess.triangles)
    out.temp(".metrics.json").write_text(json.dumps(
        {"name": name, "object": obj.name, "method": outcome.method, "metrics": writeback._jsonable(m),
         "settings": outcome.settings}, indent=1))
    out.commit()
    blend = out.final(".blend")
    print(f"[{name}] {obj.name}: reference {m['reference_faces']} triangles, base "
          f"{m['base_faces']} triangles, {m['micro_vertices']} micro-vertices, "
          f"{m['micro_triangles']} micro-triangles, shell volume {m['shell_volume']:.5f} "
          f"(unit sphere), {outcome.method}, {m['total_time_s']:.1f} s -> {blend}", flush=True)
    return m


def result_suffixes(args: argparse.Namespace) -> list[str]:
    """The export's and the maps' files of one result (``operators.result_files``)."""
    maps = ["_height.exr", "_normal.png", "_base.gltf", "_base.bin"] if args.maps else []
    return {"gltf": [".gltf", ".bin", ".bary"], "glb": [".glb"], "none": []}[args.export] + maps


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    t_start = time.perf_counter()
    try:
        pkg, settings, jobs, sets = check_usage(args)
    except BatchError as e:
        print(f"batch.py: error: {e}", file=sys.stderr, flush=True)
        return 2
    rows: list = []
    try:
        run_all(pkg, args, settings, jobs, sets, rows)
    except KeyboardInterrupt:
        _print_table(rows, jobs, "interrupted")
        print("batch.py: interrupted", file=sys.stderr, flush=True)
        return 130
    _print_table(rows, jobs, "")
    done = sum(r.status == "done" for r in rows)
    print(f"done: {done}/{len(jobs)} in {time.perf_counter() - t_start:.1f} s", flush=True)
    statuses = {r.status for r in rows}
    return 3 if "crashed" in statuses else 1 if "failed" in statuses else 0


def _print_table(rows: list, jobs: list, rest: str) -> None:
    """The final table; inputs not reached are listed as ``rest`` (when given)."""
    from micromesh.cli.summary import Row, table

    if rest:
        rows = rows + [Row(p.name if p else "demo", rest) for p in jobs[len(rows):]]
    if rows:
        print(table(rows), flush=True)


def check_usage(args: argparse.Namespace):
    """Everything that can be checked before any work: inputs, settings, options, the output
    folder and existing results. Returns (package, settings, inputs or [None] for the demo,
    one OutputSet per input); raises :class:`BatchError`."""
    inputs = find_inputs(args.input)
    import micromesh_path

    pkg = micromesh_path.ensure_package()
    from micromesh.core.io.output_set import OutputError, OutputSet, check_output_folder, output_names
    from micromesh.core.settings import SettingsError, apply_overrides, preset

    extra = base_overrides(args) + (budget_overrides(args.budget) if args.budget else [])
    try:
        settings = apply_overrides(preset(args.preset), extra + args.overrides)
    except SettingsError as e:
        raise BatchError(str(e)) from None
    if args.level is not None and not 0 <= args.level <= 5:
        raise BatchError("--level must be within 0..5")
    if args.level is not None and args.method != "projection":
        raise BatchError("--level sets the projection method's level: use it with "
                         "--method projection (the optimiser's levels come from the budget "
                         "and --set max_level=N)")
    if args.threads < 0:
        raise BatchError("--threads must be >= 0 (0: all usable cores)")
    if args.maps and not 64 <= args.maps <= 16384:
        raise BatchError("--maps must be a resolution within 64..16384 (0: no maps)")
    out_dir = Path(args.output)
    names = output_names(inputs) if inputs else [DEMO_NAME]
    report = [".report.png", ".report.json"] if settings.compute_metrics else []
    suffixes = [".blend"] + result_suffixes(args) + report \
        + (["_micromesh.ply"] if args.ply else []) + [".metrics.json"]
    sets = [OutputSet(out_dir, n, suffixes) for n in names]
    try:
        check_output_folder(out_dir)
    except OutputError as e:
        raise BatchError(str(e)) from None
    existing = [p for o in sets for p in o.existing()]
    if existing and not args.force:
        raise BatchError(f"{len(existing)} result file(s) exist in {out_dir} ("
                         f"{', '.join(p.name for p in existing[:3])}"
                         f"{', ...' if len(existing) > 3 else ''}); --force replaces them")
    return pkg, settings, inputs or [None], sets


def run_all(pkg, args, settings, jobs: list, sets: list, rows: list) -> None:
    """Each input in a fresh scene, its files written as a set (removed again when it fails);
    appends a :class:`cli.summary.Row` per input to ``rows``. Ctrl-C raises
    KeyboardInterrupt."""
    import bpy

    from micromesh.cli.summary import Row

    from micromesh.core.runtime.threads import set_threads
    from micromesh.operators import sources

    set_threads(args.threads or settings.threads)
    if not hasattr(bpy.types.Object, "micromesh_source"):
        from micromesh.operators import props

        props.register()
    interrupt = Interrupt()
    interrupt.install()
    for path, out in zip(jobs, sets):
        label = path.name if path else "demo"
        bpy.ops.wm.read_factory_settings(use_empty=True)
        try:
            with out:
                if path is None:
                    source = sources.demo_source(DEMO_NAME, subdivisions=args.demo_subdivisions)
                    print(f"[demo] procedural source '{source.name}': "
                          f"{sum(len(p.vertices) - 2 for p in source.data.polygons)} triangles",
                          flush=True)
                else:
                    source = sources.import_source(path)
                    source.name = out.name
                rows.append(Row(label, "done",
                                process(bpy, pkg, source, args, settings, out, interrupt)))
        except (BatchError, ValueError) as e:
            rows.append(Row(label, "failed"))
            print(f"batch.py: error: {label}: {e}", file=sys.stderr, flush=True)
        except Exception:
            rows.append(Row(label, "crashed"))
            print(f"batch.py: internal error on {label}:", file=sys.stderr, flush=True)
            traceback.print_exc()


def _exit(code: int) -> None:
    """Leave the process. With the ``bpy`` module (not the Blender binary) end it at once:
    bpy 4.5 can deadlock in a static destructor at interpreter exit (a "delayed close" file
    thread); the .blend files are already written and closed."""
    bpy = sys.modules.get("bpy")
    if bpy is not None and not bpy.app.binary_path:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    if code:
        sys.exit(code)


if __name__ == "__main__":
    _exit(main())
