"""The construction settings a scene asks for: its preset, the panel's base targets and
budget, the text overrides and the preferences (device), read from the scene's ``micromesh``
property group."""
from __future__ import annotations

from ..core.settings.overrides import apply_overrides
from ..core.settings.fields import preset


def panel_overrides(s) -> dict:
    """The panel's base-mesh targets and storage budget as settings."""
    out = {"base_max_error": s.base_max_error, "base_max_distance": s.base_max_distance,
           "base_min_quality": s.base_min_quality,
           "base_ratio": s.ratio if s.decimate_mode == "RATIO" else 0.0,
           "base_faces": s.target_faces if s.decimate_mode == "TARGET" else 0,
           "budget_ratio": 0.0, "budget_micro_triangles": 0, "budget_bytes": 0}
    if s.budget_mode == "RATIO":
        out["budget_ratio"] = s.budget_value
    elif s.budget_mode == "TRIANGLES":
        out["budget_micro_triangles"] = int(round(s.budget_value))
    elif s.budget_mode == "BYTES":
        out["budget_bytes"] = int(round(s.budget_value))
    return out


def panel_settings(scene):
    """The scene's preset with the panel's base targets and budget (what Make Base uses)."""
    s = scene.micromesh
    return apply_overrides(preset(s.preset), panel_overrides(s))


def scene_settings(scene):
    """The construction settings of the scene: :func:`panel_settings`, then the text
    overrides and the preferences (device, threads)."""
    from . import prefs

    s = scene.micromesh
    return apply_overrides(panel_settings(scene),
                           s.overrides.split() + [f"device={prefs.device()}"])
