"""What Blender's importers print kept off the terminal (operators.importer_output): the
process's own descriptors 1 and 2 redirected, C's printf included; a failure in one line."""
from __future__ import annotations

import ctypes
import os
import sys

import pytest

from operators.importer_output import failure, flush, quiet


def _c_printf(text: bytes) -> None:
    try:
        libc = ctypes.CDLL(None)
    except OSError:
        pytest.skip("no C library to print with")
    libc.printf(text)             # buffered by C's stdio: flushed inside quiet()


def test_everything_written_to_1_and_2_is_captured(capfd):
    flush()                       # what earlier tests (bpy's "Read blend: ...") left in C's
    capfd.readouterr()            # buffer belongs before the block, not in it
    with quiet() as out:
        print("from python")
        print("python stderr", file=sys.stderr)
        os.write(1, b"fd one\n")
        os.write(2, b"fd two\n")
        _c_printf(b"from C\n")
    seen = capfd.readouterr()
    assert seen.out == "" and seen.err == ""
    for text in ("from python", "python stderr", "fd one", "fd two", "from C"):
        assert text in out[0]
    print("after")                                   # the descriptors are back
    assert capfd.readouterr().out == "after\n"


def test_show_leaves_the_output_alone_and_an_exception_restores(capfd):
    with quiet(show=True) as out:
        print("shown")
    assert capfd.readouterr().out == "shown\n" and out == []
    with pytest.raises(KeyError):
        with quiet():
            print("hidden")
            raise KeyError("x")
    print("back")
    assert capfd.readouterr().out == "back\n"


@pytest.mark.parametrize("text, line", [
    ('Error: Python: Traceback (most recent call last):\n  File "x.py", line 3, in f\n'
     "    vs[unique]\nIndexError: index 1000000 is out of bounds for axis 0 with size 42\n"
     "Location: /bpy/ops.py:109\n", "IndexError: index 1000000 is out of bounds for axis 0 "
                                    "with size 42"),
    ("Error: Python: Traceback (most recent call last):\n  File \"m.py\", line 650\n"
     "Exception: primitive mode unimplemented: 99\nLocation: /bpy/ops.py:109\n",
     "Exception: primitive mode unimplemented: 99"),
    ("Error: USD Import: unable to open stage to read /tmp/a.usdc\n",
     "USD Import: unable to open stage to read /tmp/a.usdc"),
    ("", "RuntimeError"),
])
def test_a_failure_in_one_line(text, line):
    assert failure(RuntimeError(text)) == line
