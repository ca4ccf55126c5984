"""Every platform Blender 4.2-5.0 runs on (install/platforms.py): each pinned dependency
has a wheel for each supported one, and each unsupported one still lacks the wheel its reason
names. pip resolves each pin for the platform's tags (``--dry-run --only-binary=:all:
--no-deps``: pip would judge the markers of their own dependencies by this machine, not by
the platform asked for); skipped where the package index cannot be reached."""
from __future__ import annotations

import subprocess
import sys

import pytest

import micromesh_path

micromesh_path.ensure_package()
from micromesh.install import deps, platforms  # noqa: E402  (neither imports bpy)


def _resolve(p: platforms.Platform, reqs: list[str], target):
    tags = [a for t in p.tags for a in ("--platform", t)]
    return subprocess.run([sys.executable, "-m", "pip", "install", "--dry-run", "--no-deps",
                           "--ignore-installed", "--only-binary=:all:", "--python-version",
                           "3.11", "--target", str(target), *tags, *reqs],
                          capture_output=True, text=True, timeout=600)


@pytest.mark.parametrize("p", [p for p in platforms.PLATFORMS if p.supported],
                         ids=lambda p: p.name)
@pytest.mark.slow
def test_the_pinned_set_has_wheels(p, package_index):
    reqs = platforms.requirements_for(deps.pins(), p.env)
    assert sum(r.startswith("torch==") for r in reqs) == 1
    r = _resolve(p, reqs, package_index)
    assert r.returncode == 0, r.stdout[-1500:] + r.stderr[-1500:]
    installs = r.stdout.strip().splitlines()[-1].split()
    assert len(installs) == 2 + len(reqs) and any(w.startswith("torch-2.") for w in installs)


@pytest.mark.parametrize("p", [p for p in platforms.PLATFORMS if not p.supported],
                         ids=lambda p: p.name)
@pytest.mark.slow
def test_an_unsupported_platform_still_lacks_what_its_reason_names(p, package_index):
    r = _resolve(p, [p.blocked_by], package_index)
    assert r.returncode != 0 and "No matching distribution found for " + p.blocked_by in \
        r.stderr, r.stdout[-500:] + r.stderr[-500:]


def test_this_machine_and_the_markers():
    here = platforms.current()
    assert here is not None and here.supported        # CI runs on a supported platform
    mac13 = next(p for p in platforms.PLATFORMS if p.name == "macOS 13 Apple silicon")
    torch = list(deps.REQUIREMENTS["torch"])
    assert platforms.requirements_for(torch, mac13.env) == ["torch==2.11.0"]
    assert platforms.requirements_for(torch, platforms.PLATFORMS[0].env) == ["torch==2.13.0"]


def test_each_supported_platform_states_its_download_as_the_readme_does():
    import re

    readme = (micromesh_path.ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    for p in platforms.PLATFORMS:
        assert (p.download_mb > 0) == p.supported, p.name
        if not p.supported:
            continue
        row = next(line for line in readme if line.startswith(f"| {p.name}"))
        stated = float(re.search(r"(\d+) MB", row.split("|")[3]).group(1))
        assert abs(stated - p.download_mb) <= 0.05 * p.download_mb, (p.name, row)

