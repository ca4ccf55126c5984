"""The run report's picture (``core.report``): its panels drawn with matplotlib (Agg, no
window, no pyplot) from the report's data and images."""
from __future__ import annotations

import io
import textwrap

import numpy as np

from .level_colors import LEVEL_COLORS

ERROR_SCALE = 0.25          # the heat map's white, as the independent judge draws it
ROWS = [("psnr", "PSNR (dB)", "{:.2f}"), ("shell_volume", "shell volume (unit sphere)", "{:.4g}"),
        ("geom_err", "geometric error (/ diag.)", "{:.3g}"),
        ("iso_base", "isotropy, base", "{:.3f}"), ("iso_micro", "isotropy, micro", "{:.3f}"),
        ("base_faces", "base triangles", "{:,}"), ("micro_triangles", "micro-triangles", "{:,}"),
        ("bytes", "bytes (.bin + .bary)", "{:,}"), ("compression", "input mesh / bytes", "{:.1f}x"),
        ("quantization_max", "11-bit error, max (/ diag.)", "{:.2g}"),
        ("quantization_rms", "11-bit error, RMS (/ diag.)", "{:.2g}"), ("cracks", "cracks", "{}"),
        ("time_s", "time (s)", "{:.1f}")]
# The picture's size in pixels (a test checks it).
SIZE = (1600, 1500)


def draw_report(data: dict, images: dict[str, np.ndarray], title: str) -> bytes:
    """The PNG (1600 × 1500 pixels): the panels below on one grid."""
    from matplotlib.figure import Figure     # no pyplot: no global state, any thread

    fig = Figure(figsize=(SIZE[0] / 100, SIZE[1] / 100), dpi=100)
    fig.suptitle(title, fontsize=16)
    grid = fig.add_gridspec(6, 5, height_ratios=[1, 1, 1, 1, 1.2, 0.8], hspace=0.3,
                            wspace=0.08, left=0.06, right=0.97, top=0.94, bottom=0.03)
    _views(fig, grid, images)
    _histogram(fig.add_subplot(grid[0, 4]), data["levels_hist"])
    _curves(fig.add_subplot(grid[4, 0:4]), data["history"], data["events"])
    _table(fig.add_subplot(grid[1:6, 4]), data)
    notes = fig.add_subplot(grid[5, 0:4])
    notes.set_axis_off()
    text = "\n".join(textwrap.fill("• " + w, 120) for w in data["warnings"]) or "no warnings"
    notes.text(0, 1, "warnings\n" + text, va="top", fontsize=10, family="monospace")
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


def _views(fig, grid, images: dict[str, np.ndarray]) -> None:
    """Rows 0-3: reference | micro-mesh | |error| (one scale, with its bar) | levels."""
    heat, error_axes = None, []
    for i in range(4):
        for j, (key, name) in enumerate((("reference", "reference"), ("micromesh", "micro-mesh"),
                                          ("error", "|error|"), ("levels", "levels"))):
            ax = fig.add_subplot(grid[i, j])
            img = np.clip(images[key][i], 0, 1)
            if key == "error":
                heat = ax.imshow(img, cmap="inferno", vmin=0, vmax=ERROR_SCALE)
                error_axes.append(ax)
            else:
                ax.imshow(img)
            ax.set_axis_off()
            if i == 0:
                ax.set_title(name)
    fig.colorbar(heat, ax=error_axes, shrink=0.5, pad=0.01, label="mean |error| per pixel")


def _histogram(ax, counts: list[int]) -> None:
    ax.bar(range(len(counts)), counts, color=LEVEL_COLORS[:len(counts)])
    ax.set_title("base faces per level (the levels' colours)", fontsize=10)
    ax.set_xticks(range(len(counts)))


def _curves(ax, h: dict, events: list[dict]) -> None:
    """Loss (log, left) and training PSNR (right) over the iterations, subdivisions dashed."""
    ax.set_title("loss and PSNR over the iterations (dashed: subdivisions)")
    if not h["iteration"]:
        ax.text(0.5, 0.5, "no optimisation (projection baking)", ha="center")
        ax.set_axis_off()
        return
    ax.plot(h["iteration"], h["loss"], color="tab:orange", label="loss (left)")
    ax.set_yscale("log")
    ax.set_xlabel("iteration")
    ax.set_ylabel("loss")
    ps = ax.twinx()
    ps.plot(h["iteration"], [np.nan if p is None else p for p in h["psnr"]],
            color="tab:blue", label="PSNR, training views (right)")
    ps.set_ylabel("PSNR (dB)")
    ax.legend(handles=ax.lines + ps.lines, loc="lower right", fontsize=9)
    for e in events:
        ax.axvline(e["iteration"], color="gray", ls="--", lw=0.8)
        ax.text(e["iteration"], ax.get_ylim()[1], f" level {e['level']}", fontsize=8,
                va="top", color="gray")


def _table(ax, data: dict) -> None:
    """Metrics, time per phase, device, threads, the preset and what differs from it."""
    ax.set_axis_off()
    rows = [[label, fmt.format(data["metrics"][k])] for k, label, fmt in ROWS
            if data["metrics"].get(k) is not None]
    r = data["metrics"].get("residual_lod")
    if r and r.get("cut_by_time_limit"):
        rows.append(["levels moved after the fit", "time limit"])
    elif r:
        rows.append(["levels moved after the fit", "kept" if r["kept"] else "refused"])
        rows.append(["faces moved up / down", f"{r['faces_up']} / {r['faces_down']}"])
    for key, label in (("base_fit", "base moved by the fit"),
                       ("direction_fit", "directions turned by the fit"),
                       ("lp_bounds", "least-volume bounds")):
        note = data["metrics"].get(key)
        if note:
            passes = note.get("passes_kept", 0)   # short: the values' column is narrow
            rows.append([label, f"{passes} passes" if note["kept"] and passes > 1
                         else "kept" if note["kept"] else "refused"])
    cut = data["metrics"].get("fit_passes")
    if cut:
        rows.append(["fit passes (then the time limit)", str(cut["done"])])
    rows += [[f"time: {k}", f"{v:.1f} s"] for k, v in sorted(data["timings"].items())
             if v >= 0.5]
    rows += [["device", data.get("device", "")], ["threads", str(data.get("threads", ""))]]
    rows += [["preset", data["preset"]]] + [[f"setting {k}", str(v)]
                                            for k, v in data["settings_changed"].items()]
    t = ax.table(cellText=rows, colWidths=[0.7, 0.3], loc="upper center")
    t.auto_set_font_size(False)
    t.set_fontsize(9)
