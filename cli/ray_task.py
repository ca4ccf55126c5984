"""One input of ``batch.py --ray`` on a Ray worker: ``batch.py`` itself on that one input, in
a child process (a fresh Blender state and the serial run's own code path and files), which
dies with the worker; what became of it goes back to the driver as a dict.

Standard library only (and ``ray`` on the worker): Ray ships this module by value to workers
that never imported the checkout as the ``micromesh`` package.
"""
from __future__ import annotations

import ctypes
import glob
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

TAIL = 30          # lines of a failed input's output kept for the driver
_PR_SET_PDEATHSIG = 1


class ChildKilled(RuntimeError):
    """The input's process died by a signal (the out-of-memory killer, a cancel): the task
    raises it so that Ray runs the input again (``retry_exceptions``)."""


def run_input(batch_py: str, argv: list[str], out_dir: str, name: str, marker: str,
              cuda: bool) -> dict:
    """``python batch.py ARGV`` for one input whose result set is ``out_dir/name*`` with the
    marker suffix ``marker``; returns rc (batch.py's exit status), its error lines, the last
    lines of its output when it failed, the result's metrics, the node and the seconds."""
    host = socket.gethostname()
    record = {"host": host, "node": _node_id(), "errors": [], "tail": [], "metrics": {}}
    if not Path(batch_py).is_file():
        record.update(rc=2, seconds=0.0, errors=[
            f"batch.py: error: {batch_py} not found on {host}: every node needs the checkout "
            "at the same path"])
        return record
    remove_partials(Path(out_dir), name)     # an attempt killed earlier left its temporaries
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    if not cuda:           # a CPU task on a GPU node stays on the CPU (the same bytes)
        env["CUDA_VISIBLE_DEVICES"] = ""
    t0 = time.monotonic()
    proc = subprocess.run([sys.executable, batch_py, *argv], stdin=subprocess.DEVNULL,
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env=env,
                          text=True, errors="replace", preexec_fn=_die_with_parent)
    record["seconds"] = time.monotonic() - t0
    if proc.returncode < 0:
        raise ChildKilled(f"{name}: its process on {host} was killed "
                          f"({signal.Signals(-proc.returncode).name})")
    lines = proc.stdout.splitlines()
    record["rc"] = proc.returncode
    record["errors"] = [line for line in lines if line.startswith(("batch.py: error:",
                                                                   "batch.py: internal error"))]
    if proc.returncode == 0:
        record["metrics"] = json.loads((Path(out_dir) / f"{name}{marker}").read_text()
                                       ).get("metrics", {})
    else:
        record["tail"] = lines[-TAIL:]
    return record


def _die_with_parent() -> None:
    """In the child before it runs: killed when the worker that started it dies (Linux), so a
    lost worker leaves no process writing the input's files while Ray runs it elsewhere."""
    if sys.platform.startswith("linux"):
        ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)


def remove_partials(folder: Path, name: str) -> None:
    """The temporary files of an earlier attempt at ``name`` (``core.io.output_set``'s
    ``.NAME.partial-PID*``): only one attempt at an input runs at a time (and none once the
    driver cancelled it)."""
    for p in folder.glob(f".{glob.escape(name)}.partial-*"):
        p.unlink(missing_ok=True)


def _node_id() -> str:
    """The Ray node's id ("" outside a Ray worker: the tests call the function directly;
    asking Ray there would start a local instance)."""
    ray = sys.modules.get("ray")
    if ray is None or not ray.is_initialized():
        return ""
    return ray.get_runtime_context().get_node_id()
