"""The run report: ``NAME.report.png`` a user reads in a minute and ``NAME.report.json`` with
every number the picture shows. Drawn with matplotlib (Agg, no window).

Panels: reference | micro-mesh | per-pixel error from four of the evaluation views (one colour
scale, with its bar); the micro-mesh coloured by subdivision level and the level histogram (the
level colours of the N-panel); loss and PSNR over the iterations with the subdivision events
marked; the metrics table; the run's warnings in words.
"""
from __future__ import annotations

import io
import textwrap

import numpy as np
import torch

from .cameras import fibonacci_cameras
from .construct.frame import device as torch_device
from .mesh import TriMesh
from .metrics import psnr
from .micromesh import MicroMesh
from .orient import orient
from .render import rasterize, reference_images, render
from .settings import preset, to_dict
from .runtime.threads import default_threads

# One colour per level 0..7, blue -> red (the N-panel's and the result object's colours).
LEVEL_COLORS = np.array([[0.05, 0.10, 0.60], [0.05, 0.45, 0.80], [0.10, 0.70, 0.30],
                         [0.85, 0.80, 0.10], [0.90, 0.40, 0.05], [0.80, 0.05, 0.05],
                         [0.55, 0.0, 0.35], [0.3, 0.0, 0.2]])
ERROR_SCALE = 0.25          # the heat map's white, as the independent judge draws it
ROWS = [("psnr", "PSNR (dB)", "{:.2f}"), ("shell_volume", "shell volume (unit sphere)", "{:.4g}"),
        ("geom_err", "geometric error (/ diagonal)", "{:.3g}"),
        ("iso_base", "isotropy, base", "{:.3f}"), ("iso_micro", "isotropy, micro", "{:.3f}"),
        ("base_faces", "base triangles", "{:,}"), ("micro_triangles", "micro-triangles", "{:,}"),
        ("bytes", "bytes (.bary + glTF)", "{:,}"), ("compression", "input mesh / bytes", "{:.1f}x"),
        ("quantization_max", "11-bit error, max (/ diag.)", "{:.2g}"),
        ("quantization_rms", "11-bit error, RMS (/ diag.)", "{:.2g}"), ("cracks", "cracks", "{}"),
        ("time_s", "time (s)", "{:.1f}")]
# The picture's size in pixels (a test checks it).
SIZE = (1600, 1500)


def make_report(result, reference: TriMesh, metrics: dict, preset_name: str = "default"
                ) -> tuple[bytes, dict]:
    """(PNG bytes, JSON-ready dict) of a :class:`core.construct.ConstructResult` of
    ``reference`` (caller's frame) with the run's ``metrics``, its settings compared with
    ``preset_name``'s. The reference is wound as the construction saw it (``core.orient``)."""
    s = result.settings
    oriented = orient(reference).mesh
    ref_unit = TriMesh(result.normalization.apply(oriented.vertices), oriented.faces)
    images = report_images(result.micromesh_unit, ref_unit, s.eval_views, 256, s.shading,
                           s.camera_radius, s.fov_y_deg)
    try:
        base_settings = to_dict(preset(preset_name))
    except ValueError:
        base_settings = {}
    changed = {k: v for k, v in to_dict(s).items() if base_settings.get(k, v) != v}
    warnings = list(metrics.get("warnings", []))
    data = report_data(metrics, result.history or {}, result.micromesh.levels, changed,
                       preset_name, 12 * (reference.n_vertices + reference.n_faces),
                       result.timings or {}, warnings)
    data["device"] = str(torch_device(s.device))
    data["threads"] = int(s.threads or default_threads())
    data["images_psnr"] = [psnr(a, b) for a, b in zip(images["micromesh"], images["reference"])]
    title = (f"{result.micromesh.base.n_faces:,} base triangles, "
             f"{metrics.get('micro_triangles', 0):,} micro-triangles, "
             f"PSNR {metrics.get('psnr', float('nan')):.2f} dB")
    return draw_report(data, images, title), data


def report_images(mm_unit: MicroMesh, reference_unit: TriMesh, views: int = 24,
                  resolution: int = 256, shading: str = "flat", camera_radius: float = 3.0,
                  fov_y_deg: float = 40.0) -> dict[str, np.ndarray]:
    """Four of ``views`` Fibonacci views (0, N/4, N/2, 3N/4), in the unit frame: ``reference``
    and ``micromesh`` (4, H, W, 3), ``error`` (4, H, W) mean absolute difference, ``levels``
    (4, H, W, 3) the micro-mesh coloured by level and shaded."""
    cams = fibonacci_cameras(views, camera_radius, fov_y_deg, resolution).subset(
        np.array([0, views // 4, views // 2, 3 * views // 4]))
    tess = mm_unit.tessellate()
    X = torch.as_tensor(tess.vertices, dtype=torch.float32)
    T = torch.as_tensor(tess.triangles, dtype=torch.int64)
    with torch.no_grad():
        ours = render(X, T, cams, kind=shading).numpy()
        ref = reference_images(torch.as_tensor(reference_unit.vertices, dtype=torch.float32),
                               torch.as_tensor(reference_unit.faces, dtype=torch.int64), cams,
                               kind=shading).numpy()
        tri = rasterize(X, T, cams).tri_id.numpy()
    level = np.where(tri >= 0, mm_unit.levels[tess.triangle_face[np.maximum(tri, 0)]], -1)
    gray = ours.mean(-1, keepdims=True)
    colours = np.where((level >= 0)[..., None],
                       LEVEL_COLORS[np.clip(level, 0, 7)] * (0.35 + 0.65 * gray), 0.0)
    return {"reference": ref, "micromesh": ours, "error": np.abs(ours - ref).mean(-1),
            "levels": colours}


def report_data(metrics: dict, history: dict, levels: np.ndarray, settings_changed: dict,
                preset: str, input_bytes: int, timings: dict, warnings: list[str]) -> dict:
    """Every number of the picture, JSON-ready."""
    m = {k: metrics.get(k) for k, _, _ in ROWS if k in metrics}
    if metrics.get("bytes"):
        m["compression"] = input_bytes / metrics["bytes"]
    for key in ("residual_lod", "base_fit", "direction_fit", "fit_passes", "lp_bounds"):
        if isinstance(metrics.get(key), dict):
            m[key] = dict(metrics[key])
    return {"metrics": m, "levels_hist": np.bincount(levels, minlength=6).tolist(),
            "history": {k: list(history.get(k, [])) for k in ("iteration", "loss", "psnr")},
            "events": [e for e in history.get("events", []) if "level" in e],
            "timings": {k: float(v) for k, v in timings.items()}, "preset": preset,
            "settings_changed": settings_changed, "warnings": list(warnings),
            "input_bytes": int(input_bytes)}


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
    if r:
        rows.append(["levels moved after the fit", "kept" if r["kept"] else "refused"])
        rows.append(["faces moved up / down", f"{r['faces_up']} / {r['faces_down']}"])
    for key, label in (("base_fit", "base moved by the fit"),
                       ("direction_fit", "directions turned by the fit"),
                       ("lp_bounds", "least-volume bounds")):
        note = data["metrics"].get(key)
        if note:
            passes = note.get("passes_kept", 0)
            rows.append([label, ("kept" if note["kept"] else "refused") +
                         (f" ({passes} passes)" if passes > 1 else "")])
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
