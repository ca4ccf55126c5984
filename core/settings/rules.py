"""The allowed values of every construction setting, checked when settings are made or read,
before any work starts; each message names the setting, its allowed range and the value."""
from __future__ import annotations

import math
from dataclasses import fields

INF = math.inf

# name: (low, high, low inclusive, high inclusive); numbers must also be finite.
RANGES: dict[str, tuple[float, float, bool, bool]] = {
    "seed": (0, 2 ** 32 - 1, True, True),
    "threads": (0, 4096, True, True),
    "iterations": (0, 10 ** 7, True, True),
    "max_level": (0, 5, True, True),
    "min_level": (0, 5, True, True),
    "freeze_base_at": (-1, 10 ** 7, True, True),
    "time_limit_s": (0, INF, True, False),
    "base_ratio": (0, 1, True, True),
    "base_faces": (0, INF, True, False),
    "base_max_error": (0, 1, True, False),
    "base_max_distance": (0, 1, True, False),
    "base_min_quality": (0, 1, True, False),
    "base_refine": (0, 1e6, True, False),
    "tau_in": (0, 1e3, True, False),
    "tau_post": (0, 1e3, True, False),
    "budget_bytes": (0, INF, True, False),
    "budget_micro_triangles": (0, INF, True, False),
    "budget_ratio": (0, 4 ** 5, True, True),
    "laplacian_weight": (0, INF, True, False),
    "lambda_base": (0, INF, True, False),
    "lambda_micro": (0, INF, True, False),
    "lr_base": (0, 1, True, False),
    "lr_disp": (0, 1, True, False),
    "grad_clip": (0, INF, True, False),
    "fit_smoothness": (0, 1e3, True, False),
    "fit_slopes": (0, 1e3, True, False),
    "fit_base_stiffness": (0, 1e6, True, False),
    "fit_passes": (0, 100, True, True),
    "polish_steps": (0, 10 ** 5, True, True),
    "residual_lod": (0, 1, True, True),
    "w_render": (0, INF, True, False),
    "w_sv": (0, INF, True, False),
    "w_range": (0, INF, True, False),
    "w_iso": (0, INF, True, False),
    "n_views": (1, 10 ** 4, True, True),
    "views_per_iter": (1, 10 ** 4, True, True),
    "train_resolution": (8, 8192, True, True),
    "camera_radius": (1, INF, False, False),      # outside the unit sphere around the object
    "fov_y_deg": (0, 180, False, False),
    "lod_resolution": (8, 8192, True, True),
    "eval_views": (1, 10 ** 4, True, True),
    "eval_resolution": (8, 8192, True, True),
}

CHOICES: dict[str, tuple[str, ...]] = {
    "device": ("cpu", "cuda", "auto"),
    "lod": ("in_optim", "post", "uniform"),
    "lod_criterion": ("visual", "chamfer"),
    "init_new_levels": ("bake", "interpolate", "rebake"),
    "shading": ("flat", "shaded"),
}


def _range_text(lo, hi, lo_in, hi_in) -> str:
    if hi == INF:
        return f"{'>=' if lo_in else '>'} {lo:g}"
    return f"within {'[' if lo_in else '('}{lo:g}, {hi:g}{']' if hi_in else ')'}"


def _check_number(name: str, value, integer: bool) -> str | None:
    kind = "an integer" if integer else "a finite number"
    ok_type = isinstance(value, int) if integer else isinstance(value, (int, float))
    if isinstance(value, bool) or not ok_type or (not integer and not math.isfinite(value)):
        return f"setting '{name}' must be {kind}, not {value!r}"
    if name in RANGES:
        lo, hi, lo_in, hi_in = RANGES[name]
        if (value < lo or (value == lo and not lo_in)) or (value > hi or (value == hi and not hi_in)):
            return f"setting '{name}' must be {kind} {_range_text(lo, hi, lo_in, hi_in)}, not {value!r}"
    return None


def problems(settings, presets) -> list[str]:
    """Every rule ``settings`` breaks, in words (empty: all good)."""
    out = []
    for f in fields(settings):
        name, value = f.name, getattr(settings, f.name)
        default = f.default
        if name == "preset":
            if value not in presets:
                out.append(f"setting 'preset' must be one of {', '.join(presets)}, not {value!r}")
        elif name in CHOICES:
            if value not in CHOICES[name]:
                out.append(f"setting '{name}' must be one of {', '.join(CHOICES[name])}, "
                           f"not {value!r}")
        elif name == "base_method":          # a key of core.base.builders, checked there
            if not isinstance(value, str) or not value:
                out.append(f"setting 'base_method' must be a base builder's name, not {value!r}")
        elif isinstance(default, bool):
            if not isinstance(value, bool):
                out.append(f"setting '{name}' must be true or false, not {value!r}")
        elif isinstance(default, (int, float)):
            msg = _check_number(name, value, isinstance(default, int))
            if msg:
                out.append(msg)
    out += _tuples(settings)
    return out


def _tuples(s) -> list[str]:
    out = []
    sub = s.subdivide_at
    if not isinstance(sub, tuple) or any(isinstance(b, bool) or not isinstance(b, int) or b < 0
                                         for b in sub) or list(sub) != sorted(sub):
        out.append(f"setting 'subdivide_at' must be ascending, non-negative iterations, not {sub!r}")
    b = s.betas
    if (not isinstance(b, tuple) or len(b) != 2
            or any(isinstance(x, bool) or not isinstance(x, (int, float)) or not 0 <= x < 1
                   for x in b)):
        out.append(f"setting 'betas' must be two numbers within [0, 1), not {b!r}")
    return out
