"""Make this checkout importable as the package ``micromesh``, whatever its folder is called.

Blender loads the extension as ``bl_ext.<repo>.micromesh``; scripts (``batch.py``, ``bench/``,
tests of the Blender glue) need the same relative imports to work, so they import it through
this alias. ``core`` itself is importable directly as ``core`` from the repository root.
"""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent


def ensure_package(name: str = "micromesh"):
    """Import the repository root as package ``name`` (once) and return it."""
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(
        name, ROOT / "__init__.py", submodule_search_locations=[str(ROOT)])
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module
