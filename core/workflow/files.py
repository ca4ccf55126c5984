"""A result's files, bpy-free: the formats of ``core.io.formats`` a job's outputs name (the
micro-mesh for micro-map tools, the maps for renderers), the run report, the tessellation as
PLY and the metrics, each under its temporary name in the result's output set
(``core.io.output_set``); the caller commits the set."""
from __future__ import annotations

import json
from dataclasses import dataclass, field

from ..mesh.float32_origin import float32_origin
from ..io import formats
from ..io.mesh_files import write_ply
from .outcome import Outcome, jsonable


@dataclass
class Outputs:
    """What a job writes: ``formats`` (rows of ``core.io.formats``), ``export`` (the key of
    the micro-mesh's one among them, whose record goes to the metrics' "export"; "none"), how the micro-mesh's values are stored
    (``values``, ``layout``), the maps' resolution (``maps``, 0: none) and ``ply`` (the
    tessellation as PLY)."""

    formats: list = field(default_factory=list)
    export: str = "none"
    values: str = "r11"
    layout: str = "bird"
    maps: int = 0
    ply: bool = False


def write_formats(chosen: list, product: formats.Product, out) -> dict:
    """The ``chosen`` formats' files of ``product`` into ``out``; {format key: what its
    writer records, with its files' bytes}."""
    records = {}
    for fmt in chosen:
        files, record = formats.write(fmt, product, out.name)
        for suffix, data in files.items():
            out.temp(suffix).write_bytes(data)
        records[fmt.key] = {**record, "bytes_by_file": {s: len(d) for s, d in files.items()}}
    return records


def write_report(outcome: Outcome, out) -> None:
    """``NAME.report.png`` and ``NAME.report.json`` (when the run made a report)."""
    if outcome.report_png:
        out.temp(".report.png").write_bytes(outcome.report_png)
        out.temp(".report.json").write_text(json.dumps(jsonable(outcome.report), indent=1))


def write_files(outcome: Outcome, product: formats.Product, outputs: Outputs, out,
                identity: dict) -> dict:
    """``outputs``' files of ``outcome`` into the output set ``out``, the metrics last.

    Args:
        outcome: the finished construction (:func:`core.workflow.run`).
        product: what the formats draw from (the micro-mesh, its bounds, the maps if any,
            in the files' frame).
        outputs: which formats, and the PLY.
        out: the result's :class:`~core.io.output_set.OutputSet` (the caller commits it).
        identity: the first keys of ``NAME.metrics.json`` (e.g. the name and the object).

    Returns:
        The metrics as written, with what each format recorded (``export``; ``maps`` and
        their files' bytes).
    """
    m = outcome.metrics
    records = write_formats(outputs.formats, product, out)
    if outputs.export != "none":
        m["export"] = records.pop(outputs.export)
    if product.maps is not None:
        m.setdefault("maps", {})
        for record in records.values():
            m["maps"].update({k: v for k, v in record.items() if k != "bytes_by_file"})
        m["maps"]["bytes"] = {s: n for r in records.values() for s, n in r["bytes_by_file"].items()}
    write_report(outcome, out)
    if outputs.ply:
        tess = outcome.micromesh.tessellate()     # doubles where float32 would blur it
        write_ply(out.temp("_micromesh.ply"), tess.vertices, tess.triangles,
                  double=float32_origin(tess.vertices) is not None)
    out.temp(".metrics.json").write_text(json.dumps(
        {**identity, "method": outcome.method, "metrics": jsonable(m),
         "settings": outcome.settings}, indent=1))
    return m
