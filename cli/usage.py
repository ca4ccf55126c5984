"""Everything ``batch.py`` checks before any work: inputs, settings, options, the output
folder and results that exist."""
from __future__ import annotations

import argparse
from pathlib import Path

from ..core.io.output_set import OutputError, OutputSet, check_output_folder, output_names
from ..core.maps.atlas import AtlasError, checked_resolution
from ..core.settings.overrides import apply_overrides
from ..core.settings.fields import SettingsError, preset
from .args import (DEMO_NAME, BatchError, base_overrides, budget_overrides, check_base_method,
                   find_inputs, result_suffixes)



def check_usage(args: argparse.Namespace):
    """Everything that can be checked before any work: inputs, settings, options, the output
    folder and existing results. Returns (settings, inputs or [None] for the demo, one
    OutputSet per input); raises :class:`BatchError`."""
    inputs = find_inputs(args.input)
    extra = base_overrides(args) + (budget_overrides(args.budget) if args.budget else [])
    try:
        settings = apply_overrides(preset(args.preset), extra + args.overrides)
    except SettingsError as e:
        raise BatchError(str(e)) from None
    check_base_method(args, settings)
    if args.level is not None and not 0 <= args.level <= 5:
        raise BatchError("--level must be within 0..5")
    if args.level is not None and args.method != "projection":
        raise BatchError("--level sets the projection method's level: use it with "
                         "--method projection (the optimiser's levels come from the budget "
                         "and --set max_level=N)")
    if args.threads < 0:
        raise BatchError("--threads must be >= 0 (0: all usable cores)")
    if args.maps:
        try:
            checked_resolution(args.maps)
        except AtlasError as e:
            raise BatchError(f"--maps: {e} (0: no maps)") from None
    if args.ray is not None and not inputs:
        raise BatchError("--ray needs --input (a file or a folder of them): the demo runs here")
    out_dir = Path(args.output)
    names = output_names(inputs) if inputs else [DEMO_NAME]
    if args.result_name is not None:
        if len(names) != 1:
            raise BatchError("--result-name names the result of one input file")
        names = [args.result_name]
    report = [".report.png", ".report.json"] if settings.compute_metrics else []
    files, optional = result_suffixes(args)
    suffixes = [".blend"] + files + report + (["_micromesh.ply"] if args.ply else []) \
        + [".metrics.json"]
    sets = [OutputSet(out_dir, n, suffixes, optional) for n in names]
    try:
        check_output_folder(out_dir)
    except OutputError as e:
        raise BatchError(str(e)) from None
    existing = [p for o in sets for p in o.existing()]
    if existing and not (args.force or args.resume or args.ray is not None):
        raise BatchError(f"{len(existing)} result file(s) exist in {out_dir} ("
                         f"{', '.join(p.name for p in existing[:3])}"
                         f"{', ...' if len(existing) > 3 else ''}); --force replaces them, "
                         "--resume skips the complete ones")
    return settings, inputs or [None], sets


def pending(jobs: list, sets: list) -> tuple[list, list, list[tuple]]:
    """``--resume``: the inputs whose result sets are not complete (every file there, the
    marker written last among them) and their sets, and (input, result name) of those
    skipped."""
    keep = [not all(o.final(s).exists() for s in o.suffixes) for o in sets]
    return ([j for j, k in zip(jobs, keep) if k], [o for o, k in zip(sets, keep) if k],
            [(j, o.name) for j, o, k in zip(jobs, sets, keep) if not k])
