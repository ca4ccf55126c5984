"""Progress of one input in ``batch.py``: on a terminal one tqdm bar per phase (elapsed time,
time left, PSNR while optimising); elsewhere (a log, a pipe) plain lines, one at each phase
change and one every ``interval`` seconds, so logs stay readable.

The time left is the construction's own estimate (``Progress.eta_s``: mean time per iteration
so far × iterations left), the one the N-panel shows; tqdm's is the same figure, since the
bar averages over the whole phase (``smoothing=0``).
"""
from __future__ import annotations

import shutil
import sys
import time
from typing import IO


def _get(p, key, default=None):
    return p.get(key, default) if isinstance(p, dict) else getattr(p, key, default)


def _number(x) -> float | None:
    return float(x) if isinstance(x, (int, float)) and x == x and abs(x) != float("inf") else None


class PhaseProgress:
    """Callable given to the workflow as its progress callback; :meth:`close` at the end.

    ``bars``: draw tqdm bars (default: when standard error is a terminal and tqdm imports);
    bars go to standard error, lines to standard output (unless ``stream`` is given)."""

    def __init__(self, name: str, stream: IO | None = None, interval: float = 2.0,
                 bars: bool | None = None) -> None:
        self.name, self.interval = name, interval
        if bars is None:
            bars = _is_terminal(sys.stderr)
        self._tqdm = _tqdm_class() if bars else None
        self.stream = stream or (sys.stderr if self._tqdm is not None else sys.stdout)
        self.t0 = time.perf_counter()
        self._bar = None
        self._phase, self._last = "", 0.0

    def __call__(self, p) -> None:
        phase = str(_get(p, "phase", ""))
        it = int(_get(p, "iteration", 0) or 0)
        total = int(_get(p, "total_iterations", None) or _get(p, "total", 0) or 0)
        psnr, eta = _number(_get(p, "psnr")), _number(_get(p, "eta_s"))
        if self._tqdm is not None:
            self._draw(phase, it, total, psnr)
        else:
            self._line(phase, it, total, psnr, eta)

    def _draw(self, phase: str, it: int, total: int, psnr: float | None) -> None:
        if phase == "done":                 # the construction's last word: its phase ended
            self.close(complete=True)
            return
        if phase != self._phase or self._bar is None:
            self.close(complete=True)       # a phase ends where the next begins
            self._phase = phase
            size = shutil.get_terminal_size()   # a terminal of unknown size: 80 x 24
            self._bar = self._tqdm(total=total or None, desc=f"[{self.name}] {phase}",
                                   file=self.stream, smoothing=0, leave=True, unit="it",
                                   ncols=size.columns, nrows=size.lines)
        if total and self._bar.total != total:
            self._bar.total = total
        self._bar.n = it
        if psnr is not None:
            self._bar.set_postfix_str(f"PSNR {psnr:.2f}", refresh=False)
        self._bar.refresh()

    def _line(self, phase: str, it: int, total: int, psnr: float | None,
              eta: float | None) -> None:
        now = time.perf_counter()
        if phase == self._phase and now - self._last < self.interval:
            return
        self._phase, self._last = phase, now
        parts = [f"[{self.name}] {phase}", f"{it}/{total}" if total else str(it)]
        if psnr is not None:
            parts.append(f"PSNR {psnr:.2f}")
        parts.append(f"{now - self.t0:.1f} s")
        if eta is not None and phase != "done":
            parts.append(f"{eta:.0f} s left")
        print("  ".join(parts), file=self.stream, flush=True)

    def write(self, line: str) -> None:
        """A message line that does not break the bar."""
        if self._bar is not None:
            self._bar.write(line, file=self.stream)
        else:
            print(line, file=self.stream, flush=True)

    def close(self, complete: bool = False) -> None:
        """End the current bar; ``complete``: its phase finished (the bar shows it full)."""
        if self._bar is not None:
            if complete and self._bar.total:
                self._bar.n = self._bar.total
                self._bar.refresh()
            self._bar.close()
            self._bar = None


def _is_terminal(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False


def _tqdm_class():
    """tqdm's bar, or None where tqdm is not installed (then plain lines)."""
    try:
        from tqdm import tqdm
    except ImportError:
        return None
    return tqdm
