"""batch.py over the messy-input corpus (tests/corpus.py) of a small mesh: every case either
constructs or is refused in one line naming the cause; never a traceback, never exit 0 with a
refused input. (Quality against the clean mesh, under the judge: bench/messy_bench.py.)"""
from __future__ import annotations

import json

import pytest

bpy = pytest.importorskip("bpy")

import corpus  # noqa: E402
from core.mesh.trimesh import TriMesh  # noqa: E402
from core.mesh.primitives import noisy_sphere  # noqa: E402
from test_batch import QUICK, _error_lines, run_batch  # noqa: E402

pytestmark = pytest.mark.slow     # batch.py in a process of its own


@pytest.fixture(scope="module")
def batch_run(tmp_path_factory):
    """(cases, batch.py's result, output folder) for one run over the whole corpus."""
    folder = tmp_path_factory.mktemp("corpus")
    cases = corpus.build(TriMesh(*noisy_sphere(2000)), folder, generated=False)
    out = folder / "out"
    r = run_batch("--input", folder, "--output", out, *QUICK, timeout=600)
    return cases, r, out


def test_every_case_constructs_or_is_refused_in_one_line(batch_run):
    cases, r, out = batch_run
    assert r.returncode == 1, r.stdout + r.stderr           # some refused, none crashed
    assert "Traceback" not in r.stdout + r.stderr
    errors = _error_lines(r.stderr)
    for case in cases:
        mine = [ln for ln in errors if f" {case.path.name}:" in ln]
        if case.expect == "refuse":
            assert len(mine) == 1 and case.cause.lower() in mine[0].lower(), (case.name, errors)
            assert not list(out.glob(f"{case.path.stem}.*"))
        else:
            assert not mine, mine
            assert (out / f"{case.path.stem}.metrics.json").exists(), case.name
    assert len(errors) == sum(c.expect == "refuse" for c in cases)


def _metrics(out, case) -> dict:
    return json.loads((out / f"{case.path.stem}.metrics.json").read_text())["metrics"]


def test_a_soup_an_stl_and_a_usd_build_on_the_clean_mesh(batch_run):
    """Welded, the soup, both STLs and the USD are the clean mesh, and so is the mesh with
    degenerate faces once they are left out: the same reference and the same base."""
    cases, _, out = batch_run
    by = {c.name: _metrics(out, c) for c in cases if c.expect != "refuse"}
    clean = by["clean"]
    for name in ("soup", "soup_jitter", "stl_binary", "stl_ascii", "usd", "degenerate"):
        m = by[name]
        assert m["base_faces"] == clean["base_faces"], name
        if name != "degenerate":          # (which counts the faces it leaves out)
            assert m["reference_faces"] == clean["reference_faces"], name
    welded = [w for w in by["soup"]["warnings"] if "were welded" in w]
    sphere = TriMesh(*noisy_sphere(2000))
    assert len(welded) == 1 and welded[0].startswith(
        f"{3 * sphere.n_faces - sphere.n_vertices} coincident vertices")
    assert any("of no area" in w for w in by["degenerate"]["warnings"])
