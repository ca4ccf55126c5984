"""``batch.py --ray``'s summary files in the output folder: ``batch-summary.json`` (the run's
figures and one record per input) and ``batch-summary.csv`` (the records), each written
whole under a temporary name and then renamed."""
from __future__ import annotations

import csv
import io
import json
import os
from pathlib import Path

NAME = "batch-summary"
FIELDS = ("input", "name", "status", "host", "node", "seconds", "base_faces", "micro_triangles",
          "psnr", "shell_volume", "bytes", "error")


def record(path: Path, name: str, status: str, result: dict | None = None,
           error: str = "") -> dict:
    """One input's record: what became of it (``done``, ``failed``, ``crashed``,
    ``skipped``, ``interrupted``), where and how long it ran, its main metrics, its error."""
    result = result or {}
    m = result.get("metrics") or {}
    export = m.get("export") if isinstance(m.get("export"), dict) else {}
    seconds = result.get("seconds")
    return {"input": str(path), "name": name, "status": status,
            "host": result.get("host", ""), "node": result.get("node", ""),
            "seconds": round(seconds, 2) if isinstance(seconds, float) else seconds,
            "base_faces": m.get("base_faces"), "micro_triangles": m.get("micro_triangles"),
            "psnr": m.get("psnr"), "shell_volume": m.get("shell_volume"),
            "bytes": export.get("bytes"), "error": error}


def write_summary(folder: Path, records: list[dict], figures: dict) -> list[Path]:
    """Both files; returns their paths."""
    text = io.StringIO()
    w = csv.DictWriter(text, fieldnames=FIELDS, lineterminator="\n")
    w.writeheader()
    w.writerows({k: "" if r.get(k) is None else r[k] for k in FIELDS} for r in records)
    paths = [folder / f"{NAME}.json", folder / f"{NAME}.csv"]
    for path, body in zip(paths, [json.dumps({"run": figures, "inputs": records}, indent=1),
                                  text.getvalue()]):
        tmp = folder / f".{path.name}.partial-{os.getpid()}"
        tmp.write_text(body)
        os.replace(tmp, path)
    return paths
