"""``key=value`` overrides of construction settings (``--set`` in batch.py, the panel's
fields): each string parsed to its field's type, the result validated."""
from __future__ import annotations

from dataclasses import fields, replace
from typing import Iterable

from .fields import ConstructSettings, SettingsError


def _parse(value: str, current):
    """Parse ``value`` to the type of the field's current value."""
    v = value.strip()
    if isinstance(current, bool):
        if v.lower() in ("1", "true", "yes", "on"):
            return True
        if v.lower() in ("0", "false", "no", "off"):
            return False
        raise SettingsError(f"expected a boolean, got {value!r}")
    if isinstance(current, int):
        return _integer(v)
    if isinstance(current, float):
        return float(v)
    if isinstance(current, tuple):
        items = [s for s in v.strip("()[] ").replace(";", ",").split(",") if s.strip()]
        kind = type(current[0]) if current else int
        return tuple(_integer(s) if kind is int else kind(s) for s in items)
    return v


def _integer(text: str) -> int:
    """``text`` as an integer: "12" or "1e3", never a rounded "1.7" or "inf"."""
    try:
        return int(text)
    except ValueError:
        x = float(text)
        if not x.is_integer():
            raise SettingsError(f"expected an integer, got {text!r}") from None
        return int(x)


def apply_overrides(settings: ConstructSettings, overrides: Iterable[str] | dict) -> ConstructSettings:
    """Apply ``["key=value", ...]`` or ``{key: value}`` overrides (strings parsed by field type)."""
    names = {f.name for f in fields(ConstructSettings)}
    items = overrides.items() if isinstance(overrides, dict) else (
        (s.split("=", 1) if "=" in s else (s, None)) for s in overrides)
    changes = {}
    for key, value in items:
        key = key.strip()
        if key not in names:
            raise SettingsError(f"unknown setting {key!r}")
        if value is None:
            raise SettingsError(f"override {key!r} needs a value (key=value)")
        cur = getattr(settings, key)
        try:
            changes[key] = _parse(value, cur) if isinstance(value, str) and not isinstance(cur, str) else value
        except (TypeError, ValueError) as e:
            if isinstance(e, SettingsError):
                raise SettingsError(f"setting '{key}': {e}") from None
            raise SettingsError(f"bad value {value!r} for {key}: {e}") from None
    return replace(settings, **changes).validate()
