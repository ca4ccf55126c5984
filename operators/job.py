"""A construction job in a worker thread, talking to Blender only through a queue.

No ``bpy`` here: the worker runs a plain callable (the core), reports progress by putting
messages on a queue and checks a stop flag; the modal operator drains the queue on a timer
(:meth:`Job.poll`) in Blender's main thread. That split keeps the worker away from bpy (which
is not thread-safe) and makes the logic testable without a window.
"""
from __future__ import annotations

import queue
import threading
import time
import traceback
from dataclasses import dataclass, field
from typing import Any, Callable


class JobBusy(RuntimeError):
    """Another construction is already running (only one at a time)."""


@dataclass
class JobState:
    """What the UI shows: the last progress report, and the outcome once finished."""

    phase: str = "starting"
    iteration: int = 0
    total: int = 0
    psnr: float = float("nan")
    loss: float = float("nan")
    eta_s: float = float("nan")
    fraction: float = 0.0
    started: float = field(default_factory=time.monotonic)
    done: bool = False
    cancelled: bool = False
    error: str = ""
    result: Any = None

    @property
    def elapsed_s(self) -> float:
        return time.monotonic() - self.started

    def status_text(self) -> str:
        parts = [f"Micro-Mesh: {self.phase}"]
        if self.total:
            parts.append(f"{self.iteration}/{self.total}")
        if self.psnr == self.psnr:
            parts.append(f"PSNR {self.psnr:.2f} dB")
        if self.eta_s == self.eta_s:
            parts.append(f"{self.eta_s:.0f} s left")
        return "  ".join(parts)


_ACTIVE: "Job | None" = None
_ACTIVE_LOCK = threading.Lock()


def active_job() -> "Job | None":
    """The running job, if any."""
    return _ACTIVE


_REPORT_KEYS = ("phase", "iteration", "total", "total_iterations", "psnr", "loss", "eta_s",
                "fraction")


def report_items(report: Any) -> dict:
    """A progress report (a mapping, or an object such as ``core.construct.Progress``) as a
    new dict of the keys it has."""
    if isinstance(report, dict):
        return dict(report)
    return {k: getattr(report, k) for k in _REPORT_KEYS if hasattr(report, k)}


class Job:
    """Run ``work(progress, should_stop)`` in a daemon thread; one job at a time per process.

    ``progress`` accepts a mapping or an object with attributes among phase, iteration, total,
    psnr, loss, eta_s, fraction. ``work`` signals a cancel by raising any exception whose class
    is named ``*Cancelled`` (the core's ``ConstructCancelled``) once ``should_stop()`` is true.
    """

    def __init__(self, work: Callable[[Callable, Callable], Any]):
        self._work = work
        self._queue: queue.Queue = queue.Queue()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.state = JobState()

    # ------------------------------------------------------------ worker side
    def _progress(self, report: Any) -> None:
        self._queue.put(("progress", report_items(report)))

    def _run(self) -> None:
        try:
            result = self._work(self._progress, self._stop.is_set)
        except BaseException as e:  # noqa: BLE001 - everything is reported to the main thread
            if type(e).__name__.endswith("Cancelled") or (self._stop.is_set() and isinstance(e, KeyboardInterrupt)):
                self._queue.put(("cancelled", None))
            else:
                self._queue.put(("error", f"{type(e).__name__}: {e}", traceback.format_exc()))
        else:
            if self._stop.is_set():
                self._queue.put(("cancelled", None))
            else:
                self._queue.put(("done", result))
        finally:
            global _ACTIVE
            with _ACTIVE_LOCK:
                if _ACTIVE is self:
                    _ACTIVE = None

    # -------------------------------------------------------------- main side
    def start(self) -> "Job":
        global _ACTIVE
        with _ACTIVE_LOCK:
            if _ACTIVE is not None:
                raise JobBusy("a micro-mesh construction is already running")
            _ACTIVE = self
        self.state = JobState()
        self._thread = threading.Thread(target=self._run, name="micromesh-construct", daemon=True)
        self._thread.start()
        return self

    def cancel(self) -> None:
        """Ask the worker to stop (it stops at its next should_stop check)."""
        self._stop.set()

    def join(self, timeout: float | None = None) -> None:
        if self._thread is not None:
            self._thread.join(timeout)

    @property
    def alive(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    @staticmethod
    def _progress_into(state: JobState, report) -> None:
        """Apply one progress report (mapping or object) to ``state``."""
        items = report_items(report)
        if "total_iterations" in items:  # core.construct.Progress
            items["total"] = items.pop("total_iterations")
        for k, v in items.items():
            if hasattr(state, k) and v is not None:
                setattr(state, k, v)
        if state.total and "fraction" not in items:
            state.fraction = min(1.0, state.iteration / state.total)

    def poll(self) -> JobState:
        """Drain the queue into :attr:`state` (main thread); returns it."""
        s = self.state
        while True:
            try:
                msg = self._queue.get_nowait()
            except queue.Empty:
                break
            kind = msg[0]
            if kind == "progress":
                self._progress_into(s, msg[1])
            elif kind == "done":
                s.done, s.result, s.fraction = True, msg[1], 1.0
            elif kind == "cancelled":
                s.done, s.cancelled = True, True
            elif kind == "error":
                s.done, s.error = True, msg[1]
                s.phase = "failed"
        return s


def start_modal(op, context, work: Callable[[Callable, Callable], Any]) -> bool:
    """Start ``work`` in the worker and make the operator ``op`` modal, woken every 0.2 s to
    poll it (``op._job``, ``op._timer``); False (reported on ``op``) when a job already runs.
    The window objects come in through ``context``: nothing here imports bpy."""
    try:
        op._job = Job(work).start()
    except JobBusy as e:
        op.report({"ERROR"}, str(e))
        return False
    op._timer = context.window_manager.event_timer_add(0.2, window=context.window)
    context.window_manager.modal_handler_add(op)
    return True


def end_modal(op, context) -> None:
    """Undo :func:`start_modal`'s timer and clear the status bar."""
    context.window_manager.event_timer_remove(op._timer)
    context.workspace.status_text_set(None)


def stop_active(timeout: float = 10.0) -> bool:
    """Cancel the running job (file closed, Blender quitting); True if one was stopped."""
    job = _ACTIVE
    if job is None:
        return False
    job.cancel()
    job.join(timeout)
    return True
