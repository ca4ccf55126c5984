"""Python dependencies inside a real Blender: where they live and how they get there.

Blender bundles numpy but not torch, scipy, numba or Embree. The extension does not bundle
them as wheels (torch alone is hundreds of MB per platform); instead the preferences offer
"Install Dependencies", which runs Blender's own Python with pip into the extension's user
folder (``<extension user folder>/site-packages``, kept across extension upgrades:
``operators.prefs.site_dir``), and :func:`ensure_on_path` adds that folder to ``sys.path`` at register time. With the ``bpy``
wheel (tests, batch.py) the virtual environment already has them.
"""
from __future__ import annotations

import importlib.util
import os
import sys

# What the core imports, with the pins of requirements.txt (CPU torch from PyTorch's index);
# per-platform pins as environment markers (``platforms.py``: which platforms, and why not).
_MAC_14 = 'platform_release >= "23"'         # Darwin 23: macOS 14
REQUIREMENTS = {
    "scipy": ("scipy==1.17.1",),
    "torch": (f'torch==2.13.0; sys_platform != "darwin" or {_MAC_14}',
              'torch==2.11.0; sys_platform == "darwin" and platform_release < "23"'),
    # (torch 2.13 needs macOS 14 on Apple silicon; 2.11 is the last with macOS 13 wheels)
    "numba": ("numba==0.68.1",),
    "embreex": ("embreex==4.4.0.post1",),
    "xatlas": ("xatlas==0.0.11",),
    "OpenEXR": ("openexr==3.5.3",),     # the height map's half-float EXR (core.io.images)
    "matplotlib": ("matplotlib==3.10.8",),
    "tqdm": ("tqdm==4.70.1",),          # batch.py's progress bars (plain lines without it)
    "threadpoolctl": ("threadpoolctl==3.8.0",),   # BLAS on one thread (runtime.threads)
}
TORCH_CPU_INDEX = "https://download.pytorch.org/whl/cpu"
# What the operators and panels need to import at all (the rest is checked when they run).
GLUE_MODULES = ("numpy", "scipy")


# Where the add-on is not loaded as an extension (scripts, tests): the dependency folder.
FALLBACK_SITE = os.path.join(os.path.dirname(os.path.dirname(__file__)), ".deps")


def log_path(site: str) -> str:
    """pip's whole output of the last install into the dependency folder ``site``:
    ``install.log`` beside it."""
    return os.path.join(os.path.dirname(site.rstrip(os.sep)), "install.log")


def ensure_on_path(site: str) -> None:
    """Put the dependency folder ``site`` on ``sys.path`` (after Blender's own paths)."""
    path = site
    if os.path.isdir(path) and path not in sys.path:
        sys.path.append(path)


def missing_modules(names=None) -> list[str]:
    """The modules of ``names`` (default: all dependencies) that cannot be imported."""
    out = []
    for name in (REQUIREMENTS if names is None else names):
        try:
            found = importlib.util.find_spec(name) is not None
        except (ImportError, ValueError):  # e.g. sys.modules[name] is None
            found = False
        if not found:
            out.append(name)
    return out


def pins(modules=None) -> list[str]:
    """The requirement strings (markers kept) for ``modules`` (default: all of them), with
    Blender's numpy held below 2."""
    mods = REQUIREMENTS if modules is None else modules
    return ["numpy<2"] + [r for m in mods for r in REQUIREMENTS[m]]


def pip_command(target: str, modules: list[str] | None = None, cuda: bool = False) -> list[str]:
    """The pip command that installs the missing (or given) modules into ``target``."""
    mods = [m for m in (modules if modules is not None else missing_modules()) if m in REQUIREMENTS]
    cmd = [sys.executable, "-m", "pip", "install", "--disable-pip-version-check",
           "--target", target] + pins(mods)
    if "torch" in mods and not cuda:
        cmd += ["--extra-index-url", TORCH_CPU_INDEX]
    return cmd
