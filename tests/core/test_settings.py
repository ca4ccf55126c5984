"""Settings are checked when they are made or read: every bad value is refused before any
work, with the setting's name, its allowed values and the value in the message."""
from __future__ import annotations

import dataclasses
import math

import pytest

from core.settings.overrides import apply_overrides
from core.settings.fields import PRESETS, ConstructSettings, SettingsError, preset
from core.settings.rules import CHOICES, RANGES


@pytest.mark.parametrize("override, words", [
    ("seed=1.7", ["'seed'", "integer"]),
    ("threads=-1", ["'threads'", "[0, 4096]"]),
    ("preset=turbo", ["'preset'", "fast"]),
    ("tau_in=nan", ["'tau_in'", "finite"]),
    ("iterations=inf", ["'iterations'", "integer"]),
    ("lr_base=nan", ["'lr_base'"]),
    ("camera_radius=0", ["'camera_radius'", "> 1"]),
    ("betas=0.9", ["'betas'", "two numbers"]),
    ("eval_views=0", ["'eval_views'", "[1, 10000]"]),
    ("max_level=6", ["'max_level'", "[0, 5]"]),
    ("subdivide_at=30,10", ["'subdivide_at'", "ascending"]),
    ("shading=glossy", ["'shading'", "flat"]),
    ("fov_y_deg=180", ["'fov_y_deg'", "(0, 180)"]),
])
def test_bad_overrides_name_the_setting(override, words):
    with pytest.raises(SettingsError) as e:
        apply_overrides(preset("default"), [override])
    assert all(w in str(e.value) for w in words), str(e.value)


def test_good_overrides_parse_exactly():
    s = apply_overrides(preset("default"), ["seed=3", "iterations=1e3", "betas=0.5,0.99",
                                             "lr_base=1e-4", "final_fit=off"])
    assert (s.seed, s.iterations, s.betas, s.lr_base, s.final_fit) == (3, 1000, (0.5, 0.99), 1e-4, False)


def test_every_preset_and_every_rule_holds_together():
    for name in PRESETS:
        preset(name)
    names = {f.name for f in dataclasses.fields(ConstructSettings)}
    assert set(RANGES) <= names and set(CHOICES) <= names


def test_values_from_python_are_checked_too():
    """The add-on and tests pass Python values, not strings: same rules."""
    for bad in (dict(seed=1.7), dict(iterations=math.inf), dict(w_sv=math.nan), dict(final_fit=2),
                dict(threads=True)):
        with pytest.raises(SettingsError):
            preset("default", **bad)
