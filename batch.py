"""Headless micro-mesh construction: ``python batch.py ARGS`` or ``blender -b --python batch.py -- ARGS``.

With no ``--input`` it builds the built-in demo: a procedurally generated detailed mesh (an
icosphere displaced by Blender's procedural textures, made at run time), decimated into a base
(``core.base``: topology kept, error and triangle shape bounded) and turned into a micro-mesh
within a storage budget. With ``--input`` (one file or a folder of .ply / .obj / .stl / .glb /
.gltf / .fbx / .usd / .usda / .usdc / .usdz / .blend; a micro-mesh glTF is read as its
tessellation) it does the same per input: the same workflow as the add-on's panel
(``core.workflow``). Per input NAME it writes ``NAME.blend`` (holding ``NAME_micromesh``
and ``NAME_base``), the micro-mesh for other tools (``NAME.gltf`` + ``.bin`` + ``.bary``; or
``--export glb``), with ``--maps RES`` height and normal maps (``NAME_maps`` in the .blend,
``NAME_height.png`` (16-bit), ``NAME_height.exr``, ``NAME_normal.png``, ``NAME_base.gltf``
(``KHR_materials_displacement``), ``NAME.usda``), the run report
(``NAME.report.png``, ``NAME.report.json``), ``NAME.metrics.json`` and with ``--ply``
``NAME_micromesh.ply``: NAME is the input's stem (``stem_ext`` where two inputs share one),
the files appear together when the input is done (the metrics file last), and existing
results are kept unless ``--force`` (``--resume`` skips the complete ones and redoes the
rest). What Blender's importers print is shown with ``--verbose`` only. ``--ray auto|HOST:PORT``
runs each input as a task on a Ray cluster (``cli.ray_run``), the same files byte for byte.
"""
from __future__ import annotations

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
from micromesh.cli.usage import check_usage, pending  # noqa: E402
from micromesh.core.runtime import compiling  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    t_start = time.perf_counter()
    try:
        settings, jobs, sets = check_usage(args)
    except BatchError as e:
        print(f"batch.py: error: {e}", file=sys.stderr, flush=True)
        return 2
    skipped: list = []
    if (args.resume or args.ray is not None) and not args.force:
        jobs, sets, skipped = pending(jobs, sets)
        if skipped and args.ray is None:
            print(f"skipping {len(skipped)} input(s) whose results are complete", flush=True)
    if args.ray is not None:      # the inputs as tasks on a Ray cluster (cli.ray_run)
        from micromesh.cli.ray_run import run_on_ray

        return run_on_ray(args, settings, jobs, sets, skipped, t_start)
    rows: list = []
    # A fresh checkout's kernels compile in processes of their own while bpy and torch are
    # imported and the first input is read (the first construction takes them over).
    compiling.start_early()
    try:
        run_all(args, settings, jobs, sets, rows)
    except KeyboardInterrupt:
        _print_table(rows, jobs, "interrupted")
        print("batch.py: interrupted", file=sys.stderr, flush=True)
        return 130
    finally:
        compiling.close_early()
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
    from micromesh.cli.args import headless_options
    from micromesh.cli.progress import PhaseProgress
    from micromesh.cli.summary import Row
    from micromesh.operators import headless

    headless.start(args.threads or settings.threads)
    options = headless_options(args, settings)
    interrupt = Interrupt()
    interrupt.install()
    for path, out in zip(jobs, sets):
        label = path.name if path else "demo"
        try:
            with out:
                rows.append(Row(label, "done",
                                headless.process(path, out, options, PhaseProgress, interrupt)))
        except (BatchError, ValueError) as e:
            rows.append(Row(label, "failed"))
            print(f"batch.py: error: {label}: {e}", file=sys.stderr, flush=True)
        except OSError as e:      # a full disk, a file or folder gone: nothing of it is left
            rows.append(Row(label, "failed"))
            where = f" ({e.filename})" if e.filename else ""
            print(f"batch.py: error: {label}: {e.strerror or e}{where}; nothing of this "
                  "input was kept", file=sys.stderr, flush=True)
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
