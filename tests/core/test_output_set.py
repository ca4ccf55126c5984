"""Result files written as a set: unique names, the folder checked first, nothing that looks
finished after a failure or an interruption."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

from core.io import output_set
from core.io.output_set import OutputError, OutputSet, check_output_folder, output_names

SUFFIXES = [".blend", "_micromesh.ply", ".metrics.json"]


def test_names_are_unique_within_a_run():
    names = output_names([Path("x/a.obj"), Path("x/a.ply"), Path("x/b.ply"), Path("y/A.PLY"),
                          Path("x/a_obj.ply")])
    assert len({n.lower() for n in names}) == 5
    assert names[:3] == ["a_obj", "a_ply", "b"]
    assert output_names([Path("rock.ply")]) == ["rock"]


def test_unusable_folders_are_refused_before_work(tmp_path):
    check_output_folder(tmp_path / "new" / "deeper")           # created
    assert (tmp_path / "new" / "deeper").is_dir() and not list((tmp_path / "new" / "deeper").iterdir())
    (tmp_path / "file").write_text("x")
    with pytest.raises(OutputError, match="cannot write to the output folder"):
        check_output_folder(tmp_path / "file" / "out")


def _write_all(out: OutputSet, text="new") -> None:
    for s in out.suffixes:
        out.temp(s).write_text(text)


def test_commit_puts_the_set_in_place(tmp_path):
    out = OutputSet(tmp_path, "rock", SUFFIXES)
    _write_all(out)
    assert out.existing() == []
    out.commit()
    assert [p.name for p in out.existing()] == ["rock.blend", "rock_micromesh.ply", "rock.metrics.json"]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in out.existing())


def test_a_failure_leaves_nothing_behind(tmp_path):
    with pytest.raises(KeyboardInterrupt):
        with OutputSet(tmp_path, "rock", SUFFIXES) as out:
            out.temp(".blend").write_text("half")
            raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []
    out = OutputSet(tmp_path, "rock", SUFFIXES)
    out.temp(".blend").write_text("only one file")
    with pytest.raises(OutputError, match="was not written"):
        out.commit()


def test_interrupted_commit_never_looks_finished(tmp_path, monkeypatch):
    """Replacing an older result: if the renames stop half way, the marker (metrics) is gone,
    so the set does not pass for a finished one."""
    out = OutputSet(tmp_path, "rock", SUFFIXES)
    _write_all(out, "old")
    out.commit()
    _write_all(out, "new")
    calls = []
    real = os.replace

    def flaky(a, b):
        calls.append(b)
        if len(calls) == 2:
            raise KeyboardInterrupt
        real(a, b)

    monkeypatch.setattr(output_set.os, "replace", flaky)
    with pytest.raises(KeyboardInterrupt):
        out.commit()
    assert not out.final(".metrics.json").exists()
    assert out.final(".blend").read_text() == "new"
