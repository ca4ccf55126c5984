"""A command line that runs one function of this package in a Python process of its own.

The kernels' on-disk cache is keyed by the package's import name (``jit``): a child process
must import the package under the name the caller has (``core`` in tests and benchmarks,
``micromesh`` through the scripts' alias, ``bl_ext.<repo>.micromesh`` in Blender) for its
cache entries to serve the caller. :func:`command` sets that up without Blender: the package's
parents become empty modules, the package's own ``__init__.py`` runs (it imports nothing
heavy), and the caller's ``sys.path`` extras go first.
"""
from __future__ import annotations

import sys
from pathlib import Path

_CODE = """\
import importlib, importlib.util, os, sys
root, name, module, function, n_paths = sys.argv[1:6]
sys.path[:0] = sys.argv[6:6 + int(n_paths)]
args = sys.argv[6 + int(n_paths):]
if name:
    parts = name.split('.')
    for i in range(1, len(parts)):   # empty parents (Blender's bl_ext.<repo>)
        p = sys.modules.setdefault('.'.join(parts[:i]), type(sys)('.'.join(parts[:i])))
        p.__path__ = getattr(p, '__path__', [])
    spec = importlib.util.spec_from_file_location(
        name, os.path.join(root, '__init__.py'), submodule_search_locations=[root])
    m = importlib.util.module_from_spec(spec); sys.modules[name] = m
    spec.loader.exec_module(m)
    module = name + '.' + module
else:
    sys.path.insert(0, root)
getattr(importlib.import_module(module), function)(*args)
"""


def here() -> tuple[str, str]:
    """(package root folder, package import name) of this ``core``: the name is "" where
    ``core`` itself is the top-level package."""
    core = __name__.rsplit(".", 2)[0]                       # <...>.core
    root = str(Path(__file__).resolve().parents[2])
    return root, core.rsplit(".", 1)[0] if "." in core else ""


def command(package_root: str, package_name: str, extra_paths: list[str], module: str,
            function: str, *args: str) -> list[str]:
    """``[python, -c, code, ...]`` that imports the package at ``package_root`` as
    ``package_name`` ("" where ``module``'s first part is itself top-level, as ``core`` is in
    tests) with ``extra_paths`` first on ``sys.path``, then calls ``module.function(*args)``
    (``module`` relative to the package, e.g. "core.construct.warm")."""
    return [sys.executable, "-c", _CODE, package_root, package_name, module, function,
            str(len(extra_paths)), *extra_paths, *map(str, args)]
