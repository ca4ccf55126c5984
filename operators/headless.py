"""One input of ``batch.py`` in Blender: a fresh scene, the source (the demo, or a file:
Blender's own formats through its importers), the job built as the panel builds it (the base
by Blender's Decimate where asked, placed cameras where asked), run by ``core.workflow``,
the result into the scene as the panel puts it (``construct_scene.finish``), the maps made
there, then the ``.blend`` and the workflow's files, written as one set."""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import bpy

from ..core import workflow
from ..core.settings.fields import ConstructSettings


@dataclass
class Options:
    """What ``batch.py``'s command line chose: the job's ``settings`` (``base_method`` among
    them), ``method``, uniform ``level`` and ``preset_name``; its ``outputs``; Blender's part:
    ``symmetry`` (a base builder of the source object's, Blender's Decimate), ``cameras``
    (objects placed and read back; 0: the settings' sphere), ``verbose`` (what importers
    print) and the demo's name and ``demo_subdivisions``."""

    settings: ConstructSettings
    outputs: workflow.Outputs = field(default_factory=workflow.Outputs)
    method: str = "auto"
    level: int | None = None
    preset_name: str = "default"
    symmetry: str | None = None
    cameras: int = 0
    verbose: bool = False
    demo_name: str = "demo_rock"
    demo_subdivisions: int = 7


def start(threads: int) -> None:
    """Once before the inputs: the thread pools pinned, the add-on's properties registered."""
    from ..core.runtime.threads import set_threads

    set_threads(threads)
    if not hasattr(bpy.types.Object, "micromesh_source"):
        from . import props

        props.register()


def process(path, out, options: Options, make_progress, interrupt) -> dict:
    """The result of the input at ``path`` (None: the demo) into a fresh scene and ``out``'s
    files (the result's :class:`OutputSet`, committed here when every file is written); its
    metrics. ``make_progress(name)``: the input's progress (``cli.progress.PhaseProgress``);
    ``interrupt``: Ctrl-C as a stop request (``should_stop``, ``constructing``,
    ``requested``)."""
    from . import bl_mesh, construct_scene

    bpy.ops.wm.read_factory_settings(use_empty=True)
    source, reference = _source(path, out, options)
    progress = make_progress(source.name)
    t0 = time.perf_counter()
    notes: list[str] = []           # what reading the source found
    if reference is None:                     # Blender read it: its arrays, read back
        reference = bl_mesh.mesh_to_arrays(source, notes=notes)
    outcome, base_uv = _constructed(source, reference, notes, options, progress, interrupt)
    m = outcome.metrics
    obj = construct_scene.finish(bpy.context, source, None, outcome, base_uv)   # as the panel does
    _write_files(obj, source, reference, outcome, options.outputs, out, progress, t0)
    print(f"[{source.name}] {obj.name}: reference {m['reference_faces']} triangles, base "
          f"{m['base_faces']} triangles, {m['micro_vertices']} micro-vertices, "
          f"{m['micro_triangles']} micro-triangles, shell volume {m['shell_volume']:.5f} "
          f"(unit sphere), {outcome.method}, {m['total_time_s']:.1f} s -> "
          f"{out.final('.blend')}", flush=True)
    return m


def _source(path, out, options: Options):
    """(the source object, its mesh where we read the file ourselves, else None)."""
    from . import sources

    if path is None:
        source = sources.demo_source(options.demo_name, subdivisions=options.demo_subdivisions)
        print(f"[demo] procedural source '{source.name}': "
              f"{sum(len(p.vertices) - 2 for p in source.data.polygons)} triangles", flush=True)
        return source, None
    t_read = time.perf_counter()
    mb = path.stat().st_size / 2 ** 20
    print(f"[{out.name}] reading {path.name} ({mb:.{0 if mb >= 10 else 1}f} MB)", flush=True)
    source, mesh = sources.import_source(path, verbose=options.verbose)
    source.name = out.name
    print(f"[{out.name}] read in {time.perf_counter() - t_read:.1f} s", flush=True)
    return source, mesh


def _constructed(source, reference, notes: list[str], options: Options, progress, interrupt):
    """(outcome, the base's UVs where a builder of the source object made it) of
    ``reference`` (the source's arrays; ``notes``: what reading it found): the base (when the
    settings' ``base_method`` is a builder of the source object, ``core.base.builders``), the
    cameras, the estimate, the construction, and what it said."""
    from ..core.base import builders
    from . import bl_decimate, cameras_io  # noqa: F401  (bl_decimate: its builder)

    name, settings = source.name, options.settings
    t0 = time.perf_counter()
    base_tm = base_uv = None
    builder = builders.get(settings.base_method)
    if builder.takes == builders.OBJECT:      # as Make Base: the source's UVs carried along
        base_tm, base_uv = builder.build(source, settings, reference_faces=reference.n_faces,
                                         symmetry=options.symmetry)
        print(f"[{name}] reference {reference.n_faces} triangles -> base {base_tm.n_faces} "
              f"({builder.label}, {time.perf_counter() - t0:.1f} s)", flush=True)
    cams = None
    if options.cameras:
        coll = cameras_io.place_cameras(bpy.context.scene, reference, options.cameras,
                                        settings.camera_radius, settings.fov_y_deg)
        cams = cameras_io.collection_cameras(coll, settings.train_resolution)
    if options.method != "projection":
        from ..core.construct.estimate import estimate
        print(f"[{name}] estimate: {estimate(reference.n_faces, settings).text()}", flush=True)
    job = workflow.Job(reference, settings, base_tm, cams, options.method, level=options.level,
                       preset_name=options.preset_name, input_warnings=notes)
    interrupt.constructing = True
    try:
        outcome = workflow.run(job, progress, interrupt.should_stop)
        progress.close(complete=True)
    except workflow.Cancelled:
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
    return outcome, base_uv


def _save_blend(path) -> None:
    """Save the .blend; Blender 4.2 reports a failed write (a full disk) as a RuntimeError of
    the operator, later versions as an OSError: both leave here as an OSError."""
    try:
        bpy.ops.wm.save_as_mainfile(filepath=str(path), compress=True)
    except RuntimeError as e:
        raise OSError(None, str(e).removeprefix("Error: ").strip(), str(path)) from e


def _write_files(obj, source, reference, outcome, outputs: workflow.Outputs, out, progress,
                 t0: float) -> None:
    """The maps (``outputs.maps``) in the scene, the .blend, then the workflow's files (the
    formats, the report, the PLY, the metrics last), then the set committed."""
    from . import result_files

    m = outcome.metrics
    maps = None
    if outputs.maps:
        maps = result_files.scene_maps(bpy.context, outcome, source, outputs.maps, progress,
                                       base_obj=obj.micromesh_base, reference=reference)
        m["maps"] = maps.record
        if maps.record.get("atlas_note"):
            print(f"[{source.name}] note: {maps.record['atlas_note']}", flush=True)
        progress.close(complete=True)
    m["total_time_s"] = time.perf_counter() - t0
    _save_blend(out.temp(".blend"))
    product = result_files.product(outcome, source, outputs.values, outputs.layout, maps)
    workflow.write_files(outcome, product, outputs, out,
                         {"name": source.name, "object": obj.name})
    out.commit()
