"""The CUDA path's Triton kernels (rasteriser, shading and its backward, vertex normals,
facing, antialiasing walk) checked on the CPU under Triton's interpreter, against the plain
torch path: CI has no GPU, so this is where their logic is tested on every change. (On a GPU
``test_render_grad``'s GPU tests compile and run them.)"""
from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parents[1]    # tests/, where the script is


@pytest.mark.skipif(importlib.util.find_spec("triton") is None,
                    reason="Triton is not installed (requirements.txt pins it)")
@pytest.mark.slow
def test_the_triton_kernels_match_the_plain_torch_path_under_the_interpreter():
    env = dict(os.environ, TRITON_INTERPRET="1")
    r = subprocess.run([sys.executable, str(HERE / "triton_interpreted.py")], env=env,
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    assert r.stdout.strip().endswith("ok"), r.stdout
