"""``batch.py --ray``'s progress: on a terminal one tqdm bar over the inputs (inputs done,
failures, elapsed time and the time left at the mean rate so far, which counts every worker);
elsewhere (a log, a pipe) a plain line per finished input with the same figures."""
from __future__ import annotations

import sys
import time
from typing import IO

from .progress import _is_terminal, _tqdm_class


class InputsProgress:
    """Call :meth:`finished` as each input ends (in any order); :meth:`close` at the end."""

    def __init__(self, total: int, stream: IO | None = None, bars: bool | None = None):
        if bars is None:
            bars = _is_terminal(sys.stderr)
        tqdm = _tqdm_class() if bars else None
        self.stream = stream or (sys.stderr if tqdm is not None else sys.stdout)
        self.total, self.n, self.failed = total, 0, 0
        self.t0 = time.perf_counter()
        self._bar = None if tqdm is None else tqdm(
            total=total, desc="inputs", unit="input", file=self.stream, smoothing=0,
            dynamic_ncols=True)

    def finished(self, name: str, status: str, seconds: float | None, where: str) -> None:
        self.n += 1
        self.failed += status != "done"
        took = f" in {seconds:.0f} s" if seconds is not None else ""
        line = f"[{name}] {status}{took}{f' on {where}' if where else ''}"
        if self._bar is not None:
            self._bar.set_postfix_str(f"failed {self.failed}", refresh=False)
            self._bar.update(1)
            if status != "done":
                self._bar.write(line, file=self.stream)
            return
        elapsed = time.perf_counter() - self.t0
        left = elapsed / self.n * (self.total - self.n)
        print(f"{line}  ({self.n}/{self.total} inputs, {self.failed} failed, {elapsed:.0f} s, "
              f"about {left:.0f} s left)", file=self.stream, flush=True)

    def write(self, line: str, file: IO | None = None) -> None:
        """A message (to ``file``, default the progress' stream) that does not break the
        bar."""
        if self._bar is not None:
            self._bar.write(line, file=file or self.stream)
        else:
            print(line, file=file or self.stream, flush=True)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None
