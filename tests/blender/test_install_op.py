"""The install panel's note (operators/install_op.py): the download each platform states
(install/platforms.py) said before installing."""
from __future__ import annotations

import pytest

bpy = pytest.importorskip("bpy")

import micromesh_path  # noqa: E402

micromesh_path.ensure_package()
from micromesh.install import platforms  # noqa: E402


def test_the_panel_says_the_download_before_installing():
    from micromesh.operators.install_op import download_note

    linux = platforms.PLATFORMS[0]
    assert download_note(linux) == "About 360 MB to download for Linux x86-64"
    assert download_note(linux, "CUDA").startswith("About 2.9 GB to download")
    win = next(p for p in platforms.PLATFORMS if p.name == "Windows x64")
    assert download_note(win, "CUDA") == download_note(win)    # PyPI's Windows torch: CPU
