"""Ctrl-C in ``batch.py``."""
from __future__ import annotations

import threading


class Interrupt:
    """Ctrl-C: during a construction it asks the construction to stop at its next iteration
    (``should_stop``), so the stop never lands inside a compiled kernel or a thread pool;
    elsewhere, or at a second Ctrl-C, it interrupts at once (KeyboardInterrupt)."""

    def __init__(self) -> None:
        self.requested = False
        self.constructing = False

    def __call__(self, signum, frame) -> None:
        again, self.requested = self.requested, True
        if again or not self.constructing:
            raise KeyboardInterrupt

    def should_stop(self) -> bool:
        return self.requested

    def install(self) -> None:
        import signal

        if threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGINT, self)
