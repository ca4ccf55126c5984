"""One input of ``batch.py --ray`` as a Ray task: the command line of its own ``batch.py``
run (the driver's options handed on; the input, the output folder, its result name, the
threads and ``--force`` for the files a killed attempt left) and what it asks the cluster for
(``--threads`` CPUs, its estimated memory, one GPU where the cluster has any)."""
from __future__ import annotations

import argparse
from pathlib import Path

RETRIES = 3          # a task whose worker, node or process dies runs again, this many times
# the driver's own options; every other one is handed on to each input's run
NOT_HANDED_ON = {"help", "input", "output", "ray", "resume", "force", "threads", "result_name"}


def task_threads(args: argparse.Namespace) -> int:
    """The CPUs each task asks for and the threads its run uses (``--threads``; 0: one)."""
    return max(1, args.threads)


def one_input_argv(args: argparse.Namespace, path: Path, out) -> list[str]:
    """``batch.py``'s arguments for input ``path`` alone, its result set ``out`` (an
    ``OutputSet``): the same result as the serial run of the whole folder."""
    from .args import parser

    argv = ["--input", str(path.resolve()), "--output", str(out.folder.resolve()),
            "--result-name", out.name, "--threads", str(task_threads(args)), "--force"]
    for action in parser()._actions:
        if action.dest in NOT_HANDED_ON or not action.option_strings:
            continue
        value = getattr(args, action.dest, action.default)
        if value == action.default:
            continue
        flag = action.option_strings[-1]
        if action.nargs == 0:                    # a flag such as --ply
            argv.append(flag)
        elif isinstance(value, list):            # --set, repeated
            for v in value:
                argv += [flag, str(v)]
        else:
            argv += [flag, str(value)]
    return argv


def task_options(path: Path, settings, args: argparse.Namespace, gpu: bool) -> dict:
    """The task's Ray options: resources, retries, its name in Ray's tools. Its memory: the
    construction's estimate (``core.construct.estimate``, the figure ``batch.py`` prints per
    input) from the input's triangles, counted without reading the mesh where its format's
    row says how (``core.io.inputs``), else from the file's size, so that the task asks for
    too much rather than too little."""
    from ..core.construct.estimate import estimate
    from ..core.io.inputs import count_triangles

    memory = int(estimate(count_triangles(path), settings, speed=1.0).peak_bytes)
    return dict(num_cpus=task_threads(args), num_gpus=1 if gpu else 0,
                memory=memory, max_retries=RETRIES,
                retry_exceptions=True, name=f"batch.py {path.name}")
