"""Adding a file format is one module plus one row: a tiny output format and a tiny input
format, each registered here the way a new module would, reach every place that reads the
tables (``batch.py``'s options and inputs, a result's output set, the workflow's writer,
the Ray memory estimate), and leave again."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import micromesh_path

micromesh_path.ensure_package()
from micromesh.cli import args as cli_args  # noqa: E402
from micromesh.cli.usage import check_usage  # noqa: E402
from micromesh.core.io import formats, inputs  # noqa: E402
from micromesh.core.io.inputs import InputFormat, count_triangles, read_mesh  # noqa: E402
from micromesh.core.io.output_set import OutputSet  # noqa: E402
from micromesh.core.mesh.trimesh import TriMesh  # noqa: E402
from micromesh.core.micro.micromesh import MicroMesh  # noqa: E402
from micromesh.core.workflow import write_formats  # noqa: E402


def _write_tiny(product: formats.Product, name: str):
    """The tiny format's module: one text file, the micro-vertex count."""
    n = product.micromesh.n_vertices
    return {".tiny.txt": f"{n}\n".encode()}, {"micro_vertices": n}


def _read_tri(path: Path) -> TriMesh:
    """The tiny input format's module: 'x y z' lines, then 'f a b c' lines."""
    rows = [line.split() for line in path.read_text().splitlines() if line.strip()]
    v = np.array([[float(x) for x in r] for r in rows if r[0] != "f"])
    f = np.array([[int(x) for x in r[1:]] for r in rows if r[0] == "f"])
    return TriMesh(v, f)


@pytest.fixture
def tiny():
    out = formats.register(formats.OutputFormat("tiny", formats.MICROMESH, "Tiny (.tiny.txt)",
                                                (".tiny.txt",), _write_tiny))
    inp = inputs.register(InputFormat("tri", (".tri",), _read_tri,
                                      lambda p: p.read_text().count("\nf ")))
    try:
        yield out, inp
    finally:
        del formats.FORMATS["tiny"], inputs.INPUTS["tri"]


def _tri_file(folder: Path) -> Path:
    p = folder / "quad.tri"
    p.write_text("0 0 0\n1 0 0\n1 1 0\n0 1 0\nf 0 1 2\nf 0 2 3\n")
    return p


def test_a_registered_output_format_reaches_the_options_the_set_and_the_writer(tiny, tmp_path):
    src = _tri_file(tmp_path)
    args = cli_args.parse_args(["--input", str(src), "--output", str(tmp_path / "out"),
                                "--export", "tiny"])
    assert cli_args.result_formats(args) == [tiny[0]]
    settings, jobs, sets = check_usage(args)
    assert jobs == [src] and ".tiny.txt" in sets[0].suffixes
    base = read_mesh(src)
    mm = MicroMesh(base, np.tile([0.0, 0.0, 1.0], (4, 1)), np.ones(2, np.int64),
                   np.zeros(9))
    out = OutputSet(tmp_path / "out", "quad", [".tiny.txt"])
    with out:
        records = write_formats(cli_args.result_formats(args), formats.Product(mm), out)
        out.commit()
    assert (tmp_path / "out" / "quad.tiny.txt").read_text() == f"{mm.n_vertices}\n"
    assert records["tiny"]["micro_vertices"] == mm.n_vertices == 9


def test_a_registered_input_format_is_found_read_and_counted(tiny, tmp_path):
    src = _tri_file(tmp_path)
    assert cli_args.find_inputs(str(tmp_path)) == [src]
    assert read_mesh(src).n_faces == 2 == count_triangles(src)


def test_without_the_rows_neither_format_is_known(tmp_path):
    src = _tri_file(tmp_path)
    with pytest.raises(cli_args.BatchError, match="unsupported file type"):
        cli_args.find_inputs(str(src))
    with pytest.raises(SystemExit):
        cli_args.parse_args(["--export", "tiny"])


def test_a_registered_base_builder_is_an_option_and_builds_the_base(tmp_path):
    """A base builder is one row too: ``batch.py --base-method`` offers it, the setting takes
    it, and a construction without a base builds with it; a builder of Blender objects is
    refused there with what to do instead."""
    from dataclasses import replace

    from micromesh.core.base import BaseMesh, base_for, builders
    from micromesh.core.construct import ConstructError
    from micromesh.core.construct.frame import prepare_base
    from micromesh.core.mesh.primitives import noisy_sphere
    from micromesh.core.settings import apply_overrides, preset

    calls = []

    def coarse(reference, settings, progress=None, should_stop=None) -> BaseMesh:
        calls.append(base_for(reference, replace(settings, base_ratio=1 / 8, base_faces=0),
                              progress, should_stop))
        return calls[-1]

    builders.register(builders.BaseBuilder("coarse", "Coarse", "an eighth of the faces",
                                           builders.ARRAYS, coarse))
    try:
        args = cli_args.parse_args(["--base-method", "coarse"])
        overrides = cli_args.base_overrides(args)
        assert overrides == ["base_method=coarse"]
        s = apply_overrides(preset("fast"), overrides)
        ref = TriMesh(*noisy_sphere(1280))
        base, report, _ = prepare_base(ref, None, s)
        assert len(calls) == 1 and base is calls[0].mesh and report is calls[0].report
        blender = apply_overrides(preset("fast"), ["base_method=blender"])
        with pytest.raises(ConstructError, match="Make Base"):
            prepare_base(ref, None, blender)
    finally:
        del builders.BUILDERS["coarse"]
    with pytest.raises(SystemExit):
        cli_args.parse_args(["--base-method", "coarse"])


def test_the_base_method_is_checked_before_work(tmp_path):
    """``--set base_method=…`` is checked against the table before any work, and
    ``--symmetry`` follows the resulting setting, however it was given."""
    out = ["--output", str(tmp_path / "out")]
    with pytest.raises(cli_args.BatchError, match="unknown base method 'Blender'"):
        check_usage(cli_args.parse_args(["--set", "base_method=Blender", *out]))
    settings, _, _ = check_usage(cli_args.parse_args(
        ["--set", "base_method=blender", "--symmetry", "X", *out]))
    assert settings.base_method == "blender"
    with pytest.raises(cli_args.BatchError, match="--symmetry needs --base-method blender"):
        check_usage(cli_args.parse_args(["--base-method", "blender", "--set",
                                         "base_method=collapse", "--symmetry", "X", *out]))
    with pytest.raises(ValueError, match="a reader or Blender's importer"):
        inputs.register(InputFormat("nothing", (".nothing",)))
    with pytest.raises(ValueError, match="'ply'"):
        inputs.register(InputFormat("ply2", (".ply",), _read_tri))
    assert "nothing" not in inputs.INPUTS and "ply2" not in inputs.INPUTS
