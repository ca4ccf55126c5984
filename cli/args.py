"""``batch.py``'s command line: its options, the options as settings overrides, the inputs
it accepts, what its exit status means."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..core.base import builders
from ..core.io import formats, inputs

DESCRIPTION = "Headless micro-mesh construction: the add-on's workflow on files or the demo."
EXIT_CODES = """exit status:
  0    every input done
  1    some inputs failed (each named on one line; the others were done)
  2    bad usage: options, input paths, output folder, results that exist (nothing was done)
  3    internal error (a traceback follows: please report it)
  130  interrupted (Ctrl-C); files of the input in progress are not left behind"""
DEMO_NAME = "demo_rock"          # the demo's source and result


class BatchError(ValueError):
    """Bad input: reported as one line, exit status 2."""


def in_blender() -> bool:
    """True inside the Blender executable (not the ``bpy`` module)."""
    bpy = sys.modules.get("bpy")
    return bool(bpy is not None and bpy.app.binary_path)


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    if argv is None:
        if "--" in sys.argv:  # blender -b --python batch.py -- ARGS
            argv = sys.argv[sys.argv.index("--") + 1:]
        elif in_blender():   # blender -b --python batch.py: Blender's own arguments only
            argv = []
        else:                 # python batch.py ARGS
            argv = sys.argv[1:]
    return parser().parse_args(argv)


def parser() -> argparse.ArgumentParser:
    """``batch.py``'s options (``cli.ray_argv`` hands them on to one input's run)."""
    p = argparse.ArgumentParser(prog="batch.py", description=DESCRIPTION,
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
    p.add_argument("--base-method", choices=list(builders.BUILDERS), default=None,
                   help="; ".join(f"{b.key}: {b.description}" for b in builders.BUILDERS.values())
                   + " (default: the preset's, collapse)")
    p.add_argument("--symmetry", choices=("X", "Y", "Z"), default=None,
                   help="symmetric decimation (with --base-method blender)")
    p.add_argument("--budget", default=None, metavar="AMOUNT",
                   help="storage budget: '2x' (micro-triangles per input face, the default; "
                        "counted on the base as micromesh-tools' microexpansion counts them), "
                        "'150000' (micro-triangles) or '300kB' / '2MB' / '500000B' (bytes); "
                        "'0': none")
    p.add_argument("--cameras", type=int, default=0,
                   help="place this many Fibonacci camera objects and construct with them")
    exports = formats.group(formats.MICROMESH)
    p.add_argument("--export", choices=[f.key for f in exports] + ["none"], default="gltf",
                   help="the micro-mesh for other tools: " + "; ".join(
                       f"{f.key}: {f.label}" for f in exports) + "; none (default: gltf)")
    p.add_argument("--values", choices=("r11", "float"), default="r11",
                   help="stored values: 11-bit packed (default) or 32-bit float")
    p.add_argument("--layout", choices=("bird", "umajor"), default="bird",
                   help="micro-vertex order: bird curve (default, the hardware's) or u-major")
    p.add_argument("--maps", type=int, default=0, metavar="RES",
                   help="also a RES x RES height map fitted to the input and a normal map on "
                        "the base (RES a power of two): NAME_maps in the .blend and " + ", ".join(
                            f"NAME{f.suffixes[0]}" for f in formats.group(formats.MAPS)))
    p.add_argument("--ply", action="store_true", help="also write NAME_micromesh.ply")
    p.add_argument("--force", action="store_true", help="replace results that already exist")
    p.add_argument("--threads", type=int, default=0, help="CPU threads (0: all usable cores)")
    p.add_argument("--verbose", action="store_true",
                   help="show what Blender's importers print (glTF, FBX, USD, .blend): hidden "
                        "otherwise, a failure said in one line")
    p.add_argument("--resume", action="store_true",
                   help="skip the inputs whose results are complete (their metrics file is "
                        "there) and redo the others; without it existing results are refused")
    p.add_argument("--ray", default=None, metavar="ADDRESS",
                   help="each input a task on a Ray cluster: 'auto' (the cluster 'ray start' "
                        "began on this machine) or HOST:PORT; implies --resume")
    p.add_argument("--demo-subdivisions", type=int, default=7, help=argparse.SUPPRESS)
    # one input's result name where it differs from its stem (the runs --ray starts)
    p.add_argument("--result-name", default=None, help=argparse.SUPPRESS)
    return p


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
    """``--target-faces`` / ``--ratio`` / ``--base-error`` / ``--base-method`` as settings
    overrides."""
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
    if args.base_method is not None:
        out.append(f"base_method={args.base_method}")
    return out


def check_base_method(args: argparse.Namespace, settings) -> None:
    """The settings' ``base_method`` (``--base-method`` or ``--set``) is a builder of the table,
    and ``--symmetry`` is given only to a builder of the source object."""
    try:
        builder = builders.get(settings.base_method)
    except ValueError as e:
        raise BatchError(str(e)) from None
    if args.symmetry and builder.takes != builders.OBJECT:
        objects = [b.key for b in builders.BUILDERS.values() if b.takes == builders.OBJECT]
        raise BatchError(f"--symmetry needs --base-method {' or '.join(objects)}")


def find_inputs(path: str | None) -> list[Path]:
    """The input file at ``path``, or a folder's files of the input formats (none: the demo)."""
    if path is None:
        return []
    p = Path(path)
    if not p.exists():
        raise BatchError(f"input not found: {p}")
    suffixes = inputs.suffixes()             # the table of input formats
    if p.is_dir():
        files = sorted(f for f in p.iterdir() if f.suffix.lower() in suffixes)
        if not files:
            raise BatchError(f"no {'/'.join(suffixes)} files in {p}")
        return files
    if p.suffix.lower() not in suffixes:
        raise BatchError(f"unsupported file type '{p.suffix}' ({', '.join(suffixes)})")
    return [p]


def result_formats(args: argparse.Namespace) -> list:
    """The output formats of one result (``core.io.formats``): ``--export``'s and, with
    ``--maps``, all of the maps'."""
    chosen = [] if args.export == "none" else [formats.FORMATS[args.export]]
    return chosen + (formats.group(formats.MAPS) if args.maps else [])


def result_suffixes(args: argparse.Namespace) -> tuple[list[str], list[str]]:
    """(the files of one result's formats, the files they may write or not)."""
    chosen = result_formats(args)
    return ([s for f in chosen for s in f.suffixes], [s for f in chosen for s in f.optional])


def headless_options(args: argparse.Namespace, settings):
    """What the command line chose, as ``operators.headless`` runs each input."""
    from ..core.workflow import Outputs
    from ..operators.headless import Options

    outputs = Outputs(result_formats(args), args.export, args.values, args.layout,
                      args.maps or 0, args.ply)
    return Options(settings, outputs, args.method, args.level, args.preset, args.symmetry,
                   args.cameras or 0, args.verbose, DEMO_NAME, args.demo_subdivisions)
