"""The run report (core.report): the picture's size and panels, and the JSON's numbers."""
from __future__ import annotations

import io

import numpy as np
import pytest

from core.construct import construct, staged_baseline
from core.report.level_colors import LEVEL_COLORS
from core.report.make import make_report
from core.report.figure import ERROR_SCALE, SIZE
from test_construct import scene, small  # noqa: F401  (the fixture)

pytestmark = pytest.mark.slow     # constructions (test_construct's fixture)


def _png(data: bytes) -> np.ndarray:
    from matplotlib.image import imread

    return imread(io.BytesIO(data), format="png")[..., :3]


def _has_colour(img: np.ndarray, rgb, tol: float = 0.02) -> bool:
    return bool((np.abs(img - np.asarray(rgb)).max(-1) < tol).any())


@pytest.fixture(scope="module")
def optimised(scene):  # noqa: F811
    ref, base = scene
    return ref, construct(ref, base, None, small(max_level=2))


def test_report_picture_and_numbers(optimised):
    ref, res = optimised
    png, data = make_report(res, ref, res.metrics, "fast")
    img = _png(png)
    assert img.shape[:2] == (SIZE[1], SIZE[0])
    # the level histogram's bars, one per level in use, in the levels' colours
    for level in np.unique(res.micromesh.levels):
        assert _has_colour(img, LEVEL_COLORS[level]), level
    # the heat map's colour bar runs to its white-hot end
    from matplotlib import colormaps

    assert _has_colour(img, colormaps["inferno"](1.0)[:3], tol=0.03)
    m = res.metrics
    for k in ("psnr", "shell_volume", "micro_triangles", "base_faces", "bytes", "cracks"):
        assert data["metrics"][k] == m[k], k
    assert data["levels_hist"] == np.bincount(res.micromesh.levels, minlength=6).tolist()
    assert data["history"]["iteration"] == res.history["iteration"]
    assert [e["iteration"] for e in data["events"]] == [5, 15]
    assert data["settings_changed"]["max_level"] == 2 and "threads" not in data["settings_changed"]
    assert data["metrics"]["compression"] == pytest.approx(
        12 * (ref.n_vertices + ref.n_faces) / m["bytes"])
    assert len(data["images_psnr"]) == 4 and min(data["images_psnr"]) > 20
    assert data["device"] == "cpu" and data["threads"] >= 1
    assert ERROR_SCALE == 0.25


def test_report_of_a_baseline_has_no_curves_and_says_its_warnings(scene):  # noqa: F811
    ref, base = scene
    mask = np.random.default_rng(1).random(ref.n_faces) < 0.3
    from core.mesh.trimesh import TriMesh

    flipped = TriMesh(ref.vertices, np.where(mask[:, None], ref.faces[:, ::-1], ref.faces))
    res = staged_baseline(flipped, base, 1, small())
    png, data = make_report(res, flipped, res.metrics)
    assert data["history"]["iteration"] == [] and data["warnings"]
    assert _png(png).shape[:2] == (SIZE[1], SIZE[0])


def test_the_residual_lod_decision_is_reported(optimised):
    """fitting.fitted's decision on the levels moved after the fit reaches the JSON and the
    table (here: a decision made up for the test, kept and refused)."""
    ref, res = optimised
    for kept in (True, False):
        decision = {"faces_up": 7, "faces_down": 12, "kept": kept, "shading_error_before": 2.0,
                    "shading_error_after": 1.5 if kept else 2.5}
        _, data = make_report(res, ref, {**res.metrics, "residual_lod": decision}, "fast")
        assert data["metrics"]["residual_lod"] == decision
    cut = {"kept": False, "cut_by_time_limit": True}        # left out for the time limit
    _, data = make_report(res, ref, {**res.metrics, "residual_lod": cut}, "fast")
    assert data["metrics"]["residual_lod"] == cut
    _, data = make_report(res, ref, {k: v for k, v in res.metrics.items()
                                     if k != "residual_lod"}, "fast")
    assert "residual_lod" not in data["metrics"]


def test_fit_passes_cut_by_the_time_limit_are_reported(optimised):
    """Where the time limit cut the fit's passes, the JSON says after how many."""
    ref, res = optimised
    cut = {"done": 1, "cut_by_time_limit": True}
    png, data = make_report(res, ref, {**res.metrics, "fit_passes": cut}, "fast")
    assert data["metrics"]["fit_passes"] == cut and _png(png).shape[:2] == (SIZE[1], SIZE[0])
    _, data = make_report(res, ref, res.metrics, "fast")
    assert "fit_passes" not in data["metrics"]
