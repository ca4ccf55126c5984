"""The platforms Blender 4.2–5.0 runs on, which of them the dependencies have wheels for, and
why the others are not supported (no ``bpy``).

Measured by resolving the pinned set with ``pip install --dry-run --only-binary=:all:
--platform TAG --python-version 3.11`` (``tests/core/test_platforms.py`` does it again, so a pin
that loses its wheels fails CI instead of a user). Per-platform pins are environment markers in
``deps.REQUIREMENTS``; ``requirements_for`` evaluates them for a platform other than this one.
"""
from __future__ import annotations

import platform as _platform
import sys
from dataclasses import dataclass, field


@dataclass(frozen=True)
class Platform:
    """``tags``: pip's platform tags of its wheels; ``env``: the marker environment (what
    ``sys.platform``, ``platform.machine()`` and the Darwin release say there);
    ``blocker``: why it is not supported ("" where it is), and ``blocked_by``: a requirement
    that has no wheel there (the test checks that it still has none); ``download_mb``: what
    Install Dependencies downloads there with the CPU torch, ``cuda_download_mb`` with the CUDA
    build where it differs (``bench/install_sizes.py``; the README's table)."""

    name: str
    tags: tuple[str, ...]
    env: dict = field(default_factory=dict)
    blocker: str = ""
    blocked_by: str = ""
    download_mb: int = 0
    cuda_download_mb: int = 0

    @property
    def supported(self) -> bool:
        return not self.blocker


def _env(sys_platform: str, machine: str, release: str) -> dict:
    system = {"linux": "Linux", "win32": "Windows", "darwin": "Darwin"}[sys_platform]
    return {"sys_platform": sys_platform, "platform_machine": machine,
            "platform_release": release, "platform_system": system, "os_name":
            "nt" if sys_platform == "win32" else "posix", "python_version": "3.11",
            "python_full_version": "3.11.9", "implementation_name": "cpython",
            "platform_python_implementation": "CPython"}


_LINUX_X64 = ("manylinux_2_28_x86_64", "manylinux_2_17_x86_64", "manylinux2014_x86_64")
_LINUX_ARM = ("manylinux_2_28_aarch64", "manylinux_2_17_aarch64", "manylinux2014_aarch64")

PLATFORMS = (
    Platform("Linux x86-64", _LINUX_X64, _env("linux", "x86_64", "6.8.0"), download_mb=360,
             cuda_download_mb=2900),
    Platform("Windows x64", ("win_amd64",), _env("win32", "AMD64", "10"), download_mb=260),
    Platform("macOS 14+ Apple silicon", ("macosx_14_0_arm64",), _env("darwin", "arm64", "23.0.0"),
             download_mb=230),
    Platform("macOS 13 Apple silicon", ("macosx_13_0_arm64",), _env("darwin", "arm64", "22.0.0"),
             download_mb=200),
    Platform("macOS 11-12 Apple silicon", ("macosx_12_0_arm64",), _env("darwin", "arm64", "21.0.0"),
             blocker="Embree's Python binding (embreex) has no wheel before macOS 13",
             blocked_by="embreex==4.4.0.post1"),
    Platform("macOS Intel", ("macosx_13_0_x86_64",), _env("darwin", "x86_64", "22.0.0"),
             blocker="PyTorch stopped at 2.2 and numba at 0.62 on Intel Macs",
             blocked_by="numba==0.68.1"),
    Platform("Linux arm64", _LINUX_ARM, _env("linux", "aarch64", "6.8.0"),
             blocker="Embree's Python binding (embreex) and xatlas have no Linux arm64 wheels",
             blocked_by="embreex==4.4.0.post1"),
    Platform("Windows arm64", ("win_arm64",), _env("win32", "ARM64", "10"),
             blocker="numba, llvmlite and PyTorch have no Windows arm64 wheels",
             blocked_by="numba==0.68.1"),
)


def current() -> Platform | None:
    """This machine's entry (None: a platform Blender does not run on, or unknown)."""
    machine = _platform.machine().lower()
    arm = machine in ("arm64", "aarch64")
    if sys.platform == "darwin":
        major = int((_platform.mac_ver()[0] or "0").split(".")[0])
        if not arm:
            name = "macOS Intel"
        else:
            name = ("macOS 14+ Apple silicon" if major >= 14 else "macOS 13 Apple silicon"
                    if major == 13 else "macOS 11-12 Apple silicon")
    elif sys.platform == "win32":
        name = "Windows arm64" if arm else "Windows x64"
    elif sys.platform.startswith("linux"):
        name = "Linux arm64" if arm else "Linux x86-64"
    else:
        return None
    return next(p for p in PLATFORMS if p.name == name)


def requirements_for(requirements: list[str], env: dict) -> list[str]:
    """The requirement strings whose markers hold in ``env``, markers dropped."""
    from packaging.markers import Marker

    out = []
    for req in requirements:
        spec, _, marker = req.partition(";")
        if not marker.strip() or Marker(marker.strip()).evaluate(env):
            out.append(spec.strip())
    return out
