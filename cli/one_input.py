"""One input of ``batch.py``: the add-on's steps, headless (base mesh, cameras, construction,
write-back), then the files (the .blend, the export, maps, the report, the metrics), written
as one set."""
from __future__ import annotations

import json
import time

from .interrupt import Interrupt
from .progress import PhaseProgress


def process(bpy, source, args, settings, out, interrupt: Interrupt) -> dict:
    """The result of ``source`` into the scene and ``out``'s files; its metrics. ``out``: the
    result's :class:`OutputSet` (committed here, when every file is written)."""
    from ..operators import construct_scene

    t0 = time.perf_counter()
    outcome, base_uv, progress = _constructed(bpy, source, args, settings, interrupt)
    m = outcome.metrics
    obj = construct_scene.finish(bpy.context, source, None, outcome, base_uv)   # as the panel does
    _write_files(bpy, obj, source, outcome, args, out, progress, t0)
    print(f"[{source.name}] {obj.name}: reference {m['reference_faces']} triangles, base "
          f"{m['base_faces']} triangles, {m['micro_vertices']} micro-vertices, "
          f"{m['micro_triangles']} micro-triangles, shell volume {m['shell_volume']:.5f} "
          f"(unit sphere), {outcome.method}, {m['total_time_s']:.1f} s -> "
          f"{out.final('.blend')}", flush=True)
    return m


def _constructed(bpy, source, args, settings, interrupt: Interrupt):
    """(outcome, the base's UVs where Blender's Decimate made it, the input's progress):
    the base (when ``--base-method blender``), the cameras (``--cameras``), the estimate, the
    construction, and what it said."""
    from ..core.base import target_faces
    from ..operators import bl_decimate, bl_mesh, cameras_io, pipeline

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
        from ..core.construct.estimate import estimate
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
    return outcome, base_uv, progress


def _save_blend(bpy, path) -> None:
    """Save the .blend; Blender 4.2 reports a failed write (a full disk) as a RuntimeError of
    the operator, later versions as an OSError: both leave here as an OSError."""
    try:
        bpy.ops.wm.save_as_mainfile(filepath=str(path), compress=True)
    except RuntimeError as e:
        raise OSError(None, str(e).removeprefix("Error: ").strip(), str(path)) from e


def _write_files(bpy, obj, source, outcome, args, out, progress, t0: float) -> None:
    """The maps (``--maps``), the .blend, the formats (``--export``, the maps'), the report,
    ``--ply``'s tessellation and the metrics (last), then the set committed."""
    from ..operators import result_files, writeback
    from .args import result_formats

    m = outcome.metrics
    maps = None
    if args.maps:
        maps = result_files.scene_maps(bpy.context, outcome, source, args.maps, progress,
                                       base_obj=obj.micromesh_base)
        m["maps"] = maps.record
        if maps.record.get("atlas_note"):
            print(f"[{source.name}] note: {maps.record['atlas_note']}", flush=True)
        progress.close(complete=True)
    m["total_time_s"] = time.perf_counter() - t0
    _save_blend(bpy, out.temp(".blend"))
    product = result_files.product(outcome, source, args.values, args.layout, maps)
    records = result_files.write_formats(result_formats(args), product, out)
    if args.export != "none":
        m["export"] = records.pop(args.export)
    if maps is not None:
        for record in records.values():
            m["maps"].update({k: v for k, v in record.items() if k != "bytes_by_file"})
        m["maps"]["bytes"] = {s: n for r in records.values() for s, n in r["bytes_by_file"].items()}
    result_files.write_report(outcome, out)
    if args.ply:
        from ..core.float32_origin import float32_origin
        from ..core.io.mesh_files import write_ply

        tess = outcome.micromesh.tessellate()     # doubles where float32 would blur it
        write_ply(out.temp("_micromesh.ply"), tess.vertices, tess.triangles,
                  double=float32_origin(tess.vertices) is not None)
    out.temp(".metrics.json").write_text(json.dumps(
        {"name": source.name, "object": obj.name, "method": outcome.method,
         "metrics": writeback._jsonable(m), "settings": outcome.settings}, indent=1))
    out.commit()
