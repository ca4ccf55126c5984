"""What Blender's importers print, kept off the terminal: they write to the process's own
standard output and error (the C code's printf, the Python importers' prints, logging and
tracebacks), so both are redirected at the file-descriptor level around the call (and
Python's ``sys.stdout``/``sys.stderr`` with them); and an importer's failure said in one
line."""
from __future__ import annotations

import ctypes
import os
import re
import sys
import tempfile
from contextlib import contextmanager

_EXCEPTION = re.compile(r"^[\w.]*(Error|Exception)(: .*)?$")    # "IndexError: ..."


def flush() -> None:
    """Python's and the C library's buffered output written out (C's buffers would else
    reach the terminal after the descriptors are restored)."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (AttributeError, OSError, ValueError):
            pass
    try:
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError, TypeError):   # no C library by that name (Windows)
        pass


@contextmanager
def quiet(show: bool = False):
    """Descriptors 1 and 2 into a temporary file while the block runs (unless ``show``);
    yields a list that holds that output as text once the block has ended."""
    captured: list[str] = []
    if show:
        yield captured
        return
    flush()
    saved = [os.dup(1), os.dup(2)]
    streams = sys.stdout, sys.stderr    # where these are not descriptors 1 and 2 (pytest)
    try:
        with tempfile.TemporaryFile() as tmp:
            text = open(tmp.fileno(), "w", encoding="utf-8", errors="replace", closefd=False)
            os.dup2(tmp.fileno(), 1)
            os.dup2(tmp.fileno(), 2)
            sys.stdout = sys.stderr = text
            try:
                yield captured
            finally:
                flush()
                sys.stdout, sys.stderr = streams
                text.close()
                os.dup2(saved[0], 1)
                os.dup2(saved[1], 2)
                tmp.seek(0)
                captured.append(tmp.read().decode("utf-8", errors="replace"))
    finally:
        for fd in saved:
            os.close(fd)


def failure(error: BaseException) -> str:
    """An importer's error (``RuntimeError`` from ``bpy.ops``, whose text holds the
    importer's traceback and Blender's "Location:" line) in one line: its last exception
    line, else its first line."""
    lines = [ln.strip() for ln in str(error).strip().splitlines() if ln.strip()]
    lines = [ln.removeprefix("Error:").strip() for ln in lines
             if not ln.startswith("Location:")]
    exceptions = [ln for ln in lines if _EXCEPTION.match(ln)]
    if exceptions:
        return exceptions[-1]
    return lines[0].removeprefix("Python:").strip() if lines else type(error).__name__
