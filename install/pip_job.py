"""Installing the Python dependencies in the background (no ``bpy``: the preferences' modal
operator drives it, tests run it as it is).

pip runs in a subprocess into a temporary folder beside the dependency folder; every line it
prints goes to a log file and, read as it comes, becomes the progress (which package is being
fetched, and how large it is, or installed). When pip has finished, the torch that arrived is
checked (version, CPU or CUDA build) and only then is the temporary folder moved into the
dependency folder. A cancel or a failure removes the temporary folder: the dependency folder
stays as it was. A failure is summed up in words from pip's output (no network, no wheel for
this platform, disk full, no permission), with the log's path for the rest.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field

from .pip_output import failure_cause, line_progress


class InstallError(RuntimeError):
    """An install that cannot go on; the message says why, in words."""


@dataclass
class InstallState:
    """What the panel shows. ``phase``: starting, downloading, installing, checking, moving,
    finished, failed, cancelled; ``downloaded_mb``: the sizes pip announced so far."""

    phase: str = "starting"
    package: str = ""
    downloaded_mb: float = 0.0
    packages_done: int = 0
    message: str = ""
    torch: str = ""
    started: float = field(default_factory=time.monotonic)

    @property
    def done(self) -> bool:
        return self.phase in ("finished", "failed", "cancelled")

    def status_text(self) -> str:
        parts = [f"Installing: {self.phase}"]
        if self.package and not self.done:
            parts.append(self.package)
        if self.downloaded_mb:
            parts.append(f"{self.downloaded_mb:.0f} MB fetched")
        parts.append(f"{time.monotonic() - self.started:.0f} s")
        return "  ".join(parts)


def torch_build(folder: str, python: str = sys.executable) -> tuple[str, str] | None:
    """(version, "CPU" or "CUDA x.y") of the torch in ``folder``, None where it has none."""
    if not os.path.isdir(os.path.join(folder, "torch")):
        return None
    code = ("import sys; sys.path.insert(0, sys.argv[1]); import torch; "
            "print(torch.__version__); print(torch.version.cuda or '')")
    r = subprocess.run([python, "-c", code, folder], capture_output=True, text=True,
                       timeout=600)
    if r.returncode != 0:
        raise InstallError("the installed torch does not import: "
                           + (r.stderr.strip().splitlines() or ["?"])[-1])
    version, cuda = (r.stdout.strip().splitlines() + ["", ""])[:2]
    return version, (f"CUDA {cuda}" if cuda else "CPU")


def move_in(temp: str, target: str) -> None:
    """Everything of ``temp`` into ``target`` (entries of the same name replaced); ``temp``
    goes. An entry in use (a loaded library on Windows) stops it with a clear message."""
    os.makedirs(target, exist_ok=True)
    for name in sorted(os.listdir(temp)):
        src, dst = os.path.join(temp, name), os.path.join(target, name)
        if os.path.lexists(dst):
            try:
                shutil.rmtree(dst) if os.path.isdir(dst) and not os.path.islink(dst) \
                    else os.unlink(dst)
            except OSError as e:
                raise InstallError(f"{name} in {target} is in use ({e.strerror}): restart "
                                   "Blender and install again") from e
        os.replace(src, dst)
    shutil.rmtree(temp, ignore_errors=True)


class Install:
    """One background install: ``start``, ``poll`` from a timer, ``cancel`` at any time.

    ``command(folder)``: the pip command line that installs into ``folder``; ``target``: the
    dependency folder; ``log_path``: pip's whole output; ``cuda``: whether a CUDA torch was
    chosen (a CUDA build that arrives otherwise is refused)."""

    def __init__(self, command, target: str, log_path: str, cuda: bool = False,
                 python: str = sys.executable) -> None:
        self.command, self.target, self.log_path = command, target, log_path
        self.cuda, self.python = cuda, python
        self.temp = f"{target.rstrip(os.sep)}.partial-{os.getpid()}"
        self.state = InstallState()
        self._lock = threading.Lock()
        self._proc: subprocess.Popen | None = None
        self._cancel = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True, name="micromesh-pip")

    def start(self) -> "Install":
        self._thread.start()
        return self

    def poll(self) -> InstallState:
        with self._lock:
            return InstallState(**vars(self.state))

    def cancel(self) -> None:
        """Stop pip; the dependency folder stays as it was (once files move in, it finishes)."""
        self._cancel.set()
        proc = self._proc
        if proc is not None and proc.poll() is None:
            proc.terminate()

    def wait(self, timeout: float | None = None) -> InstallState:
        self._thread.join(timeout)
        return self.poll()

    def _set(self, **kw) -> None:
        with self._lock:
            for k, v in kw.items():
                setattr(self.state, k, v)

    def _run(self) -> None:
        try:
            os.makedirs(os.path.dirname(self.log_path) or ".", exist_ok=True)
            shutil.rmtree(self.temp, ignore_errors=True)
            with open(self.log_path, "w", encoding="utf-8") as log:
                lines = self._pip(log)
                if self._cancel.is_set():
                    raise _Cancelled
                if self._proc.returncode != 0:
                    raise InstallError(failure_cause(lines))
                self._set(phase="checking", package="torch")
                build = torch_build(self.temp, self.python)
                if build is not None:
                    self._check_torch(*build)
                if self._cancel.is_set():
                    raise _Cancelled
                self._set(phase="moving", package="")
                move_in(self.temp, self.target)
                log.write(f"\nmoved into {self.target}\n")
            self._set(phase="finished", message="dependencies installed in " + self.target
                      + (f" (torch {self.state.torch})" if self.state.torch else ""))
        except _Cancelled:
            self._set(phase="cancelled", message="cancelled: nothing was changed")
        except (InstallError, OSError, subprocess.SubprocessError) as e:
            self._set(phase="failed", message=f"{e} (pip's output: {self.log_path})")
        finally:
            if self.state.phase != "finished":
                shutil.rmtree(self.temp, ignore_errors=True)

    def _pip(self, log) -> list[str]:
        lines: list[str] = []
        cmd = list(self.command(self.temp)) + ["--progress-bar", "off"]
        log.write(" ".join(cmd) + "\n")
        self._proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                      text=True, bufsize=1, env={**os.environ,
                                                                 "PYTHONUNBUFFERED": "1"})
        if self._cancel.is_set():
            self._proc.terminate()
        for line in self._proc.stdout:
            log.write(line)
            lines.append(line.rstrip("\n"))
            self._progress(line)
        self._proc.wait()
        log.write(f"pip exit status {self._proc.returncode}\n")
        return lines

    def _progress(self, line: str) -> None:
        said = line_progress(line)
        if said is None:
            return
        with self._lock:
            self.state.phase, self.state.package = said["phase"], said["package"]
            if said.get("fetched"):
                self.state.downloaded_mb += said["mb"]
                self.state.packages_done += 1

    def _check_torch(self, version: str, build: str) -> None:
        self._set(torch=f"{version}, {build} build")
        if build.startswith("CUDA") and not self.cuda:
            raise InstallError(
                f"pip brought the {build} build of torch {version} (about 2.9 GB), not the CPU "
                "build: PyTorch's CPU index (download.pytorch.org) could not be reached, so pip "
                "took the default one. Nothing was installed; allow that address, or choose "
                "the CUDA build in the preferences")


class _Cancelled(Exception):
    pass
