"""Settings of a construction: :class:`ConstructSettings` (``fields``), the named presets
(``presets``), every field's allowed values (``rules``) and ``key=value`` overrides
(``overrides``)."""
from .fields import ConstructSettings, SettingsError, preset, to_dict
from .overrides import apply_overrides

__all__ = ["ConstructSettings", "SettingsError", "apply_overrides", "preset", "to_dict"]
