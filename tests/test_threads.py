"""set_threads pins both pools, also on the first call of a fresh process (numba's OpenMP
layer resets the thread count torch shares when it starts)."""
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

SCRIPT = """
import numpy as np, numba, torch
from core.runtime.threads import set_threads
from core.render import warm_up
assert set_threads(1) == 1
warm_up(torch.device("cpu"), antialias=True)      # runs parallel numba kernels
print(torch.get_num_threads(), numba.get_num_threads())
"""


def test_set_threads_first_call_pins_torch_and_numba():
    out = subprocess.run([sys.executable, "-c", SCRIPT], cwd=ROOT, capture_output=True, text=True,
                         timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["1", "1"], out.stdout
