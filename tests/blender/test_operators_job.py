"""The modal path's worker/queue logic (operators/job.py), exercised without a window."""
from __future__ import annotations

import threading
import time

import pytest

import micromesh_path

micromesh_path.ensure_package()
from micromesh.operators import job  # noqa: E402  (job.py imports no bpy)


class Cancelled(Exception):
    pass


Cancelled.__name__ = "ConstructCancelled"


def _wait(j: job.Job, timeout=10.0) -> job.JobState:
    t = time.monotonic()
    while time.monotonic() - t < timeout:
        s = j.poll()
        if s.done:
            return s
        time.sleep(0.01)
    raise AssertionError("job did not finish")


def test_progress_then_result_through_the_queue():
    gate = threading.Event()

    def work(progress, should_stop):
        progress({"phase": "warmup", "iteration": 1, "total": 4, "psnr": 20.0})
        gate.wait(5)
        progress(type("P", (), dict(phase="optimize", iteration=3, total_iterations=4, loss=0.5,
                                    psnr=31.5, eta_s=2.0))())
        return "the result"

    j = job.Job(work).start()
    assert job.active_job() is j
    with pytest.raises(job.JobBusy):
        job.Job(work).start()  # only one construction at a time
    time.sleep(0.1)
    s = j.poll()  # the timer tick: drains what is there, does not block
    assert (s.phase, s.iteration, s.total, s.psnr) == ("warmup", 1, 4, 20.0)
    assert s.fraction == pytest.approx(0.25) and not s.done
    gate.set()
    s = _wait(j)
    assert s.result == "the result" and not s.cancelled and not s.error
    assert s.fraction == 1.0 and s.psnr == 31.5 and s.total == 4
    assert "PSNR 31.50 dB" in s.status_text()
    j.join(1)
    assert job.active_job() is None


def test_cancel_stops_the_worker_and_reports_cancelled():
    started = threading.Event()
    iterations = []

    def work(progress, should_stop):
        started.set()
        for i in range(10_000):
            if should_stop():
                raise Cancelled("stopped")
            iterations.append(i)
            time.sleep(0.001)
        return "finished"

    j = job.Job(work).start()
    started.wait(5)
    j.cancel()
    s = _wait(j)
    assert s.cancelled and s.result is None and not s.error
    assert len(iterations) < 10_000
    assert job.active_job() is None


def test_a_result_after_cancel_counts_as_cancelled():
    gate = threading.Event()

    def work(progress, should_stop):
        gate.wait(5)
        return "too late"

    j = job.Job(work).start()
    j.cancel()
    gate.set()
    s = _wait(j)
    assert s.cancelled and s.result is None


def test_error_is_one_line_and_frees_the_slot():
    def work(progress, should_stop):
        raise ValueError("reference has no faces")

    s = _wait(job.Job(work).start())
    assert s.error == "ValueError: reference has no faces" and s.phase == "failed"
    assert job.active_job() is None


def test_stop_active_joins_the_worker():
    def work(progress, should_stop):
        while not should_stop():
            time.sleep(0.001)
        raise Cancelled()

    j = job.Job(work).start()
    assert job.stop_active(timeout=5)
    assert not j.alive
    assert not job.stop_active()


@pytest.mark.slow
def test_construct_waits_for_the_warm_up_process():
    """operators/warmup.wait: while the kernel warm-up process runs, a construction reports
    "compiling kernels" and waits; a stop request ends the wait; no process: no wait."""
    import subprocess
    import sys

    from micromesh.operators import warmup

    seen = []
    warmup._PROC = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(1.5)"])
    try:
        t = time.monotonic()
        warmup.wait(seen.append, lambda: False)
        assert time.monotonic() - t > 1.0 and not warmup.running()
        assert seen and seen[0]["phase"] == "compiling kernels"
        warmup._PROC = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
        t = time.monotonic()
        warmup.wait(seen.append, lambda: time.monotonic() - t > 0.5)
        assert time.monotonic() - t < 5 and warmup.running()
    finally:
        warmup.stop()
    assert not warmup.running()
    seen.clear()
    warmup.wait(seen.append, lambda: False)
    assert seen == []
