"""A real Ray cluster on this machine for tests and benchmarks: a head that only schedules
(no CPUs) and worker nodes of a few CPUs, each ``ray start --block`` in a process group of
its own, started one after the other (two nodes starting at once time out on a small
machine). ``kill_worker`` kills one node's raylet as a lost machine would; ``stop`` ends
every process the cluster started (its nodes' process trees, never by name).

    with LocalCluster(workers=2, cpus=1) as cluster:
        run(["python", "batch.py", ..., "--ray", cluster.address], env=cluster.env)
"""
from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

START_TIMEOUT_S = 90


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _processes() -> dict[int, tuple[int, int, str]]:
    """pid -> (parent pid, process group, command line) of every process we can read."""
    out = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
            cmd = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2:].split()
        out[int(entry.name)] = (int(fields[1]), int(fields[2]), cmd)
    return out


class LocalCluster:
    def __init__(self, workers: int = 2, cpus: int = 1):
        self.workers, self.cpus = workers, cpus
        self.port = _free_port()
        self.address = f"127.0.0.1:{self.port}"
        # Ray's socket paths must stay short: a folder of its own directly in /tmp
        self.temp = Path(tempfile.mkdtemp(prefix="ray", dir="/tmp"))
        self.nodes: list[subprocess.Popen] = []
        ray = Path(sys.executable).with_name("ray")
        self.ray = str(ray) if ray.exists() else (shutil.which("ray") or "ray")
        # ``env``: the nodes' and the drivers' (Ray's token authentication off on this
        # loopback cluster, whatever a ~/.ray/auth_token would switch on)
        self.env = dict(os.environ, RAY_USAGE_STATS_ENABLED="0", RAY_AUTH_MODE="disabled",
                        PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}")

    def __enter__(self) -> "LocalCluster":
        try:
            self._node(["--head", f"--port={self.port}", "--num-cpus=0",
                        "--include-dashboard=false"])
            for _ in range(self.workers):
                self._node([f"--address={self.address}", f"--num-cpus={self.cpus}"])
        except BaseException:
            self.stop()
            raise
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    def _node(self, args: list[str]) -> None:
        log = self.temp / f"node{len(self.nodes)}.log"
        with open(log, "w") as f:
            p = subprocess.Popen([self.ray, "start", "--block", "--disable-usage-stats",
                                  f"--temp-dir={self.temp}", "--object-store-memory=100000000",
                                  *args], stdout=f, stderr=subprocess.STDOUT, env=self.env,
                                 stdin=subprocess.DEVNULL, start_new_session=True)
        self.nodes.append(p)
        t0 = time.monotonic()
        while "Ray runtime started" not in log.read_text():
            if p.poll() is not None or time.monotonic() - t0 > START_TIMEOUT_S:
                raise RuntimeError(f"ray start {' '.join(args)} failed:\n"
                                   f"{log.read_text()[-3000:]}")
            time.sleep(0.2)

    def raylet(self, worker: int) -> int | None:
        """The pid of worker node ``worker``'s raylet (0: the first worker)."""
        group = self.nodes[1 + worker].pid
        return next((pid for pid, (_, pg, cmd) in _processes().items()
                     if pg == group and "raylet/raylet" in cmd), None)

    def descendants(self, pid: int) -> dict[int, str]:
        """pid -> command line of every process below ``pid`` (a raylet's Ray workers and
        the ``batch.py`` runs they started)."""
        procs = _processes()
        found, frontier = {}, {pid}
        while frontier:
            frontier = {p for p, (ppid, _, _) in procs.items() if ppid in frontier}
            found.update({p: procs[p][2] for p in frontier})
        return found

    def kill_worker(self, worker: int) -> None:
        """SIGKILL that node's raylet: its Ray workers end, and their children with them."""
        pid = self.raylet(worker)
        if pid is not None:
            os.kill(pid, signal.SIGKILL)

    def stop(self) -> None:
        """Every process the nodes started ended (SIGTERM to each node's group, SIGKILL to
        what is left after a few seconds: the groups, their Ray workers, which have groups of
        their own, and those workers' children); the folder removed."""
        started = {pid for p in self.nodes for pid in self.descendants(p.pid)}
        for p in reversed(self.nodes):
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGTERM)
        deadline = time.monotonic() + 5
        for p in self.nodes:
            try:
                p.wait(timeout=max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                pass
        for p in self.nodes:
            try:
                os.killpg(p.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            p.wait()
        for pid in started:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        shutil.rmtree(self.temp, ignore_errors=True)
