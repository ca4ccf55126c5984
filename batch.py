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

import json
import os
import sys
import time
import traceback
from pathlib import Path

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

import micromesh_path  # noqa: E402  (the checkout as the package ``micromesh``)

micromesh_path.ensure_package()
from micromesh.cli.args import BatchError, parse_args  # noqa: E402
from micromesh.cli.interrupt import Interrupt  # noqa: E402
from micromesh.cli.usage import DEMO_NAME, check_usage  # noqa: E402


# ------------------------------------------------------------------ one input
def process(bpy, source, args, settings, out, interrupt: Interrupt) -> dict:
    """Base mesh, cameras, construction, write-back, save: the add-on's steps, headless.
    ``out``: the result's :class:`OutputSet` (committed here, when every file is written)."""
    from micromesh.operators import (bl_decimate, bl_mesh, cameras_io, construct_scene, pipeline,
                                     result_files, writeback)

    from micromesh.cli.progress import PhaseProgress
    from micromesh.core.base import target_faces

    name = source.name
    t0 = time.perf_counter()
    notes: list[str] = []
    reference = bl_mesh.mesh_to_arrays(source, notes=notes)
    base_tm = base_uv = None
    if args.base_method == "blender":      # as Make Base: the source's UVs carried along
        target = min(target_faces(reference.n_faces, settings.base_ratio, settings.base_faces),
                     reference.n_faces)
        base_tm, base_uv = bl_decimate.decimate_object_uvs(source, target_faces=max(4, target),
                                                       symmetry=args.symmetry)
        print(f"[{name}] reference {reference.n_faces} triangles -> base {base_tm.n_faces} "
              f"(Blender's Decimate, {time.perf_counter() - t0:.1f} s)", flush=True)
    cams = None
    if args.cameras:
        coll = cameras_io.place_cameras(bpy.context.scene, reference, args.cameras,
                                        settings.camera_radius, settings.fov_y_deg)
        cams = cameras_io.collection_cameras(coll, settings.train_resolution)
    if args.method != "projection":
        from micromesh.core.construct.estimate import estimate
        print(f"[{name}] estimate: {estimate(reference.n_faces, settings).text()}", flush=True)
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
    obj = construct_scene.finish(bpy.context, source, None, outcome, base_uv)   # as the panel does
    if args.maps:
        m["maps"] = result_files.write_maps(bpy.context, outcome, source, args.maps, out,
                                            progress, base_obj=obj.micromesh_base)
        if m["maps"].get("atlas_note"):
            print(f"[{name}] note: {m['maps']['atlas_note']}", flush=True)
        progress.close(complete=True)
    m["total_time_s"] = time.perf_counter() - t0
    bpy.ops.wm.save_as_mainfile(filepath=str(out.temp(".blend")), compress=True)
    if args.export != "none":
        m["export"] = result_files.write_export(outcome, source, args.export, args.values,
                                                args.layout, out)
    result_files.write_report(outcome, out)
    if args.ply:
        from micromesh.core.io.mesh_files import write_ply

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


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    t_start = time.perf_counter()
    try:
        settings, jobs, sets = check_usage(args)
    except BatchError as e:
        print(f"batch.py: error: {e}", file=sys.stderr, flush=True)
        return 2
    rows: list = []
    try:
        run_all(args, settings, jobs, sets, rows)
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


def run_all(args, settings, jobs: list, sets: list, rows: list) -> None:
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
                    t_read = time.perf_counter()
                    mb = path.stat().st_size / 2 ** 20
                    print(f"[{out.name}] reading {path.name} ({mb:.{0 if mb >= 10 else 1}f} MB)",
                          flush=True)
                    source = sources.import_source(path)
                    source.name = out.name
                    print(f"[{out.name}] read in {time.perf_counter() - t_read:.1f} s",
                          flush=True)
                rows.append(Row(label, "done",
                                process(bpy, source, args, settings, out, interrupt)))
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
