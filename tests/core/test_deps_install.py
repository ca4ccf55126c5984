"""The background install (install/pip_job.py) with the real pip: a package installed
into a temporary folder and moved in, failures summed up in words, cancel leaving the
dependency folder as it was, the torch build read from what arrived."""
from __future__ import annotations

import sys
import time
from pathlib import Path

import pytest

import micromesh_path

micromesh_path.ensure_package()
from micromesh.install import pip_job as di  # noqa: E402  (imports no bpy)
from micromesh.install import pip_output  # noqa: E402

# pip without this machine's configuration (mirrors, local wheels), aimed at a closed port
UNREACHABLE = ["--isolated", "--index-url", "http://127.0.0.1:9/simple", "--retries", "1",
               "--timeout", "1"]


def _pip(*args):
    return lambda folder: [sys.executable, "-m", "pip", "install", "--disable-pip-version-check",
                           "--no-deps", "--target", folder, *args]


def _folder_with_a_file(tmp_path: Path) -> Path:
    target = tmp_path / "site-packages"
    target.mkdir()
    (target / "keep.txt").write_text("there before")
    return target


@pytest.mark.slow
def test_install_moves_the_package_in_and_logs_pip(tmp_path, package_index):
    target = _folder_with_a_file(tmp_path)
    log = tmp_path / "install.log"
    job = di.Install(_pip("tqdm==4.70.1"), str(target), str(log)).start()
    s = job.wait(300)
    assert s.phase == "finished", s.message
    assert (target / "tqdm" / "__init__.py").exists() and (target / "keep.txt").exists()
    assert not Path(job.temp).exists()
    assert "Successfully installed tqdm-4.70.1" in log.read_text()
    assert s.packages_done == 1 and s.torch == ""     # a download, a cached or a local wheel


@pytest.mark.slow
def test_no_wheel_is_named_and_nothing_changes(tmp_path, package_index):
    target = _folder_with_a_file(tmp_path)
    s = di.Install(_pip("tqdm==0.0.1"), str(target), str(tmp_path / "l.log")).start().wait(300)
    assert s.phase == "failed"
    assert "no package for this platform: tqdm==0.0.1 has no wheel for" in s.message
    assert pip_output.platform_text() in s.message and str(tmp_path / "l.log") in s.message
    assert sorted(p.name for p in target.iterdir()) == ["keep.txt"]


@pytest.mark.slow
def test_no_network_is_named(tmp_path):
    target = _folder_with_a_file(tmp_path)
    s = di.Install(_pip("tqdm==4.70.1", *UNREACHABLE), str(target),
                   str(tmp_path / "l.log")).start().wait(300)
    assert s.phase == "failed" and s.message.startswith("no network"), s.message
    s = di.Install(_pip("tqdm==4.70.1", *UNREACHABLE[:-4], "--retries", "0"), str(target),
                   str(tmp_path / "l.log")).start().wait(300)    # no retries: pip says less
    assert s.message.startswith("pip found no version of tqdm==4.70.1 at all: the package "
                                "index cannot be reached"), s.message
    assert sorted(p.name for p in target.iterdir()) == ["keep.txt"]


@pytest.mark.slow
def test_cancel_stops_pip_and_leaves_the_folder_as_it_was(tmp_path):
    """pip waits on an index that accepts the connection and never answers; Cancel stops it."""
    import socket

    target = _folder_with_a_file(tmp_path)
    with socket.socket() as silent:
        silent.bind(("127.0.0.1", 0))
        silent.listen(8)
        slow = ["--isolated", "--index-url", f"http://127.0.0.1:{silent.getsockname()[1]}/simple",
                "--retries", "5", "--timeout", "60"]
        job = di.Install(_pip("tqdm==4.70.1", *slow), str(target),
                         str(tmp_path / "l.log")).start()
        time.sleep(2.0)
        assert not job.poll().done            # still waiting for the index
        t = time.monotonic()
        job.cancel()
        s = job.wait(30)
    assert s.phase == "cancelled" and time.monotonic() - t < 10, s.message
    assert sorted(p.name for p in target.iterdir()) == ["keep.txt"]
    assert not Path(job.temp).exists()


@pytest.mark.parametrize("line, cause", [
    ("ERROR: Could not install packages due to an OSError: [Errno 28] No space left on device",
     "the disk is full"),
    ("ERROR: Could not install packages due to an OSError: [Errno 13] Permission denied: '/x'",
     "no permission"),
    ("WARNING: Retrying (Retry(total=4, connect=None, read=None, redirect=None, status=None)) "
     "after connection broken by 'NewConnectionError(...: Failed to establish a new connection:"
     " [Errno -3] Temporary failure in name resolution')'\nERROR: No matching distribution "
     "found for numpy<2", "no network"),
    ("ERROR: Could not find a version that satisfies the requirement torch==2.13.0 (from "
     "versions: 2.2.0)\nERROR: No matching distribution found for torch==2.13.0",
     "no package for this platform: torch==2.13.0"),
    ("ERROR: something else", "ERROR: something else"),
])
def test_failure_cause_in_words(line, cause):
    assert pip_output.failure_cause(line.splitlines()).startswith(cause)


@pytest.mark.slow
def test_torch_build_of_the_test_environment():
    import torch

    site = str(Path(torch.__file__).resolve().parents[1])
    version, build = di.torch_build(site)
    assert version == torch.__version__
    assert build == (f"CUDA {torch.version.cuda}" if torch.version.cuda else "CPU")


def test_a_cuda_torch_nobody_chose_is_refused():
    job = di.Install(_pip(), "/nonexistent", "/nonexistent.log", cuda=False)
    with pytest.raises(di.InstallError, match="CUDA 12.8 build of torch 2.13.0"):
        job._check_torch("2.13.0", "CUDA 12.8")
    di.Install(_pip(), "/x", "/x.log", cuda=True)._check_torch("2.13.0", "CUDA 12.8")


def test_move_in_replaces_entries_of_the_same_name(tmp_path):
    temp, target = tmp_path / "t", _folder_with_a_file(tmp_path)
    (temp / "pkg").mkdir(parents=True)
    (temp / "pkg" / "new.py").write_text("new")
    (target / "pkg").mkdir()
    (target / "pkg" / "old.py").write_text("old")
    di.move_in(str(temp), str(target))
    assert sorted(p.name for p in (target / "pkg").iterdir()) == ["new.py"]
    assert (target / "keep.txt").exists() and not temp.exists()
