"""The final table of ``batch.py``: one row per input, what became of it and its main figures."""
from __future__ import annotations

from dataclasses import dataclass, field

COLUMNS = ("input", "result", "base", "micro-tris", "PSNR dB", "shell", "MB", "time s")


@dataclass
class Row:
    """One input: ``status`` is ``done``, ``failed``, ``crashed`` or ``interrupted``; the
    metrics are those of the run (``NAME.metrics.json``), empty where it did not finish."""

    name: str
    status: str
    metrics: dict = field(default_factory=dict)

    def cells(self) -> list[str]:
        m = self.metrics
        if self.status != "done":
            return [self.name, self.status] + [""] * (len(COLUMNS) - 2)
        psnr = m.get("psnr")
        size = m.get("export", {}).get("bytes") if isinstance(m.get("export"), dict) else None
        return [self.name, "done", _int(m.get("base_faces")), _int(m.get("micro_triangles")),
                f"{psnr:.2f}" if isinstance(psnr, (int, float)) else "",
                _float(m.get("shell_volume"), "{:.4f}"),
                f"{size / 1e6:.2f}" if isinstance(size, (int, float)) else "",
                _float(m.get("total_time_s"), "{:.0f}")]


def _int(x) -> str:
    return str(int(x)) if isinstance(x, (int, float)) else ""


def _float(x, fmt: str) -> str:
    return fmt.format(x) if isinstance(x, (int, float)) else ""


def table(rows: list[Row]) -> str:
    """The rows as a text table with a header line, columns aligned (numbers to the right)."""
    cells = [list(COLUMNS)] + [r.cells() for r in rows]
    widths = [max(len(c[i]) for c in cells) for i in range(len(COLUMNS))]
    lines = []
    for c in cells:
        lines.append("  ".join(v.ljust(w) if i < 2 else v.rjust(w)
                               for i, (v, w) in enumerate(zip(c, widths))).rstrip())
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)
