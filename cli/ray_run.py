"""``batch.py --ray auto|HOST:PORT``: the inputs as tasks on a Ray cluster.

Each input is one task (``cli.ray_task``: ``batch.py`` on that input alone, in a child process
on the node: the serial run's code path and result set) asking for ``--threads`` CPUs, its
estimated memory and a GPU where the cluster has any (``cli.ray_submit``). A task whose
worker, node or process dies runs again elsewhere (``ray_submit.RETRIES``); an input that
fails fails alone, named on one line; no set looks finished before its marker is written
(``core.io.output_set``). Inputs whose results are complete were skipped before (``--ray``
implies ``--resume``). One bar over the inputs, then the table and ``batch-summary.json`` /
``.csv``. Every node needs the checkout and its environment at the driver's path, and the
input and output folders at the same paths (a shared file system).
"""
from __future__ import annotations

import logging
import socket
import sys
import time
from pathlib import Path

from .args import BatchError
from .interrupt import Interrupt

BATCH_PY = Path(__file__).resolve().parents[1] / "batch.py"
CANCEL_WAIT_S = 20      # Ctrl-C: how long the cancelled tasks' workers may take to end
WAIT_S = 0.5            # the longest a wait for the next result holds off Ctrl-C


def run_on_ray(args, settings, jobs: list, sets: list, skipped: list, t_start: float) -> int:
    """Runs ``jobs`` (their result sets ``sets``) on the cluster at ``args.ray``; returns
    ``batch.py``'s exit status."""
    try:
        ray = _connect(args.ray)
    except BatchError as e:
        print(f"batch.py: error: {e}", file=sys.stderr, flush=True)
        return 2
    try:
        return _run(ray, args, settings, jobs, sets, skipped, t_start)
    except BatchError as e:
        print(f"batch.py: error: {e}", file=sys.stderr, flush=True)
        return 2
    finally:
        ray.shutdown()


def _connect(address: str):
    try:
        import ray
    except ImportError:
        raise BatchError("--ray needs the ray package: pip install -r "
                         "requirements-ray.txt") from None
    if address != "auto":         # an address nobody listens at: said now, not retried
        host, _, port = address.rpartition(":")
        try:
            socket.create_connection((host, int(port)), timeout=5).close()
        except (OSError, ValueError) as e:
            raise BatchError(f"--ray {address}: no Ray cluster answers there "
                             f"({getattr(e, 'strerror', None) or e})") from None
    try:
        ray.init(address=address, log_to_driver=False, logging_level=logging.WARNING)
    except (ConnectionError, RuntimeError, ValueError) as e:
        raise BatchError(f"--ray {address}: {str(e).splitlines()[0]}") from None
    return ray


def _run(ray, args, settings, jobs, sets, skipped, t_start) -> int:
    from . import ray_task
    from .inputs_progress import InputsProgress
    from .ray_submit import one_input_argv, task_options, task_threads
    from .summary_files import record

    nodes = [n["Resources"] for n in ray.nodes() if n["Alive"] and n["Resources"].get("CPU")]
    gpu = any(r.get("GPU", 0) > 0 for r in nodes)
    most_cpus = max((r.get("CPU", 0) for r in nodes), default=0)
    most_memory = max((r.get("memory", 0) for r in nodes), default=0)
    threads = task_threads(args)
    if threads > most_cpus:
        raise BatchError(f"--threads {threads}: no node of the cluster has {threads} CPUs "
                         f"(the most: {most_cpus:g})")
    ray.cloudpickle.register_pickle_by_value(ray_task)   # the workers lack our package name
    remote = ray.remote(ray_task.run_input)
    print(f"[ray] {len(jobs)} input(s) on {len(nodes)} node(s) "
          f"({sum(r.get('CPU', 0) for r in nodes):g} CPUs"
          f"{', a GPU per task' if gpu else ''}), {threads} thread(s) per input"
          + (f"; {len(skipped)} complete before, skipped" if skipped else ""), flush=True)
    records: list = [None] * len(jobs)
    refs = {}
    for i, (path, out) in enumerate(zip(jobs, sets)):
        opts = task_options(path, settings, args, gpu)
        if opts["memory"] > most_memory:
            records[i] = record(path, out.name, "failed", error=(
                f"batch.py: error: {path.name}: needs about {opts['memory'] / 2 ** 30:.1f} GB "
                f"of memory, the cluster's largest node offers {most_memory / 2 ** 30:.1f} GB"))
            continue
        refs[remote.options(**opts).remote(
            str(BATCH_PY), one_input_argv(args, path, out), str(out.folder.resolve()),
            out.name, out.suffixes[-1], gpu)] = i
    progress = InputsProgress(len(jobs))
    pending = list(refs)
    # Ctrl-C raises KeyboardInterrupt (no construction runs here), by the serial run's handler,
    # also where SIGINT came ignored from the parent (a shell's background job)
    Interrupt().install()
    try:
        for r in records:
            if r is not None:
                _report(progress, r)
        while pending:
            # (a timeout: Ctrl-C is raised between waits, not held until a task ends)
            ready, pending = ray.wait(pending, num_returns=1, timeout=WAIT_S)
            for ref in ready:
                i = refs[ref]
                records[i] = _outcome(ray, ref, jobs[i], sets[i])
                _report(progress, records[i])
    except KeyboardInterrupt:
        for ref in pending:      # the worker killed, and its batch.py with it
            ray.cancel(ref, force=True)
        ray.wait(pending, num_returns=len(pending), timeout=CANCEL_WAIT_S)
        for i in {refs[ref] for ref in pending}:      # what those runs had begun to write
            ray_task.remove_partials(sets[i].folder, sets[i].name)
        progress.close()
        _finish(args, jobs, sets, records, skipped, len(nodes), t_start, "interrupted")
        print("batch.py: interrupted", file=sys.stderr, flush=True)
        return 130
    progress.close()
    statuses = _finish(args, jobs, sets, records, skipped, len(nodes), t_start, "")
    return 3 if "crashed" in statuses else 1 if "failed" in statuses else 0


def _outcome(ray, ref, path: Path, out) -> dict:
    """One finished task's record: done, failed (batch.py's exit 1: a bad input) or crashed
    (its retries spent, or batch.py's internal error)."""
    from .summary_files import record

    try:
        result = ray.get(ref)
    except ray.exceptions.RayError as e:
        why = str(e).strip().splitlines()
        return record(path, out.name, "crashed", error=(
            f"batch.py: internal error on {path.name}: {type(e).__name__}: "
            f"{why[-1] if why else ''}"))
    status = {0: "done", 1: "failed", 2: "failed"}.get(result["rc"], "crashed")
    lines = result["errors"] if status != "crashed" else (
        [f"batch.py: internal error on {path.name}:"] + result["tail"])
    return record(path, out.name, status, result, "\n".join(lines))


def _report(progress, r: dict) -> None:
    progress.finished(Path(r["input"]).name, r["status"], r["seconds"], r["host"])
    if r["error"]:
        progress.write(r["error"], file=sys.stderr)


def _finish(args, jobs, sets, records, skipped, n_nodes, t_start, rest: str) -> set:
    """The table, the summary files and the last line; the statuses of the inputs."""
    from .summary import Row, table
    from .summary_files import record, write_summary

    records = [r if r is not None else record(p, o.name, rest or "crashed")
               for r, p, o in zip(records, jobs, sets)]
    rows = [Row(Path(r["input"]).name, r["status"], _metrics(r)) for r in records]
    if rows:
        print(table(rows), flush=True)
    seconds = time.perf_counter() - t_start
    done = sum(r["status"] == "done" for r in records)
    figures = {"ray": args.ray, "nodes": n_nodes, "inputs": len(jobs), "done": done,
               "failed": sum(r["status"] == "failed" for r in records),
               "crashed": sum(r["status"] == "crashed" for r in records),
               "skipped": len(skipped), "seconds": round(seconds, 2),
               "inputs_per_minute": round(60 * done / seconds, 3)}
    everything = records + [record(p, name, "skipped") for p, name in skipped]
    paths = write_summary(Path(args.output), everything, figures)
    print(f"summary: {paths[0]} and {paths[1].name}", flush=True)
    print(f"done: {done}/{len(jobs)} in {seconds:.1f} s ({figures['inputs_per_minute']:.2f} "
          f"inputs/min on {n_nodes} node(s))", flush=True)
    return {r["status"] for r in records}


def _metrics(r: dict) -> dict:
    """The table's figures from a record (``cli.summary.Row`` reads metrics' names)."""
    return {"base_faces": r["base_faces"], "micro_triangles": r["micro_triangles"],
            "psnr": r["psnr"], "shell_volume": r["shell_volume"],
            "export": {"bytes": r["bytes"]}, "total_time_s": r["seconds"]}
