"""Polishing the folded values against the images (``core.construct.polish``): it lowers the
metrics' image error, keeps every value within the folded bounds (the shell cannot grow),
hands back the micro-mesh unchanged where it does not help, and stops at the deadline."""
import math
from types import SimpleNamespace

import numpy as np
import pytest

from core.spatial.bake import bake_displacements
from core.micro.bounds import baked, micromesh_shell_volume, tight_bounds, unit_bounds
from core.render.cameras import fibonacci_cameras
from core.construct.polish import polished
from core.construct.scene import Scene, image_error
from core.mesh.trimesh import TriMesh
from core.micro.micromesh import MicroMesh
from core.settings.fields import preset
from tests.core.test_construct import icosphere


def _run(**kw):
    """A folded micro-mesh of a bumpy sphere with noisy values, and a stand-in run."""
    s = preset("default", n_views=8, eval_views=8, train_resolution=64, eval_resolution=96,
               views_per_iter=4, **kw)
    rv, rf = icosphere(4)
    rv = rv * (1 + 0.06 * np.sin(6 * rv[:, :1]) * np.sin(5 * rv[:, 1:2]))
    v, f = icosphere(2)
    mm = MicroMesh.flat(TriMesh(v * 0.97, f), np.full(len(f), 2))
    d = bake_displacements(mm.micro_vertex_base_positions(), mm.micro_vertex_directions(),
                           TriMesh(rv, rf), max_distance=0.3).displacement
    noise = 0.01 * np.random.default_rng(0).standard_normal(len(d))
    mm = mm.with_displacements(d + noise)
    mm = baked(mm, tight_bounds(mm))
    scene = Scene(TriMesh(rv, rf), fibonacci_cameras(8, width=64), "cpu", True, s.shading)
    run = SimpleNamespace(s=s, scene=scene, notes={}, deadline=math.inf,
                          check_stop=lambda: None)
    return run, mm


def _shell(mm):
    return micromesh_shell_volume(mm, unit_bounds(mm.base.n_vertices))


def test_polishing_lowers_the_image_error_within_the_bounds():
    run, mm = _run(polish_steps=30)
    out = polished(run, mm)
    note = run.notes["polish"]
    assert note["kept"] and note["steps"] == 30
    before, after = image_error(mm, run.scene, run.s), image_error(out, run.scene, run.s)
    assert after == pytest.approx(note["image_error_after"]) and after < 0.99 * before
    t = out.displacements
    assert t.min() >= 0.0 and t.max() <= 1.0 and not np.array_equal(t, mm.displacements)
    assert _shell(out) <= _shell(mm) * (1 + 1e-9)
    # Only the values move: base, directions and levels are the folded ones.
    np.testing.assert_array_equal(out.base.vertices, mm.base.vertices)
    np.testing.assert_array_equal(out.directions, mm.directions)
    np.testing.assert_array_equal(out.levels, mm.levels)


def test_polishing_that_does_not_help_is_not_kept(monkeypatch):
    import core.construct.polish as polish

    run, mm = _run(polish_steps=3)
    errors = iter([1.0, 2.0])                 # before, after: worse
    monkeypatch.setattr(polish, "image_error", lambda *a: next(errors))
    assert polished(run, mm) is mm and run.notes["polish"]["kept"] is False


def test_polishing_stops_at_the_deadline(monkeypatch):
    """Past the deadline no step is taken; before it, a step that would end past it is left
    out (a clock that moves one second per step, the deadline 1.5 s on)."""
    import time

    import core.construct.polish as polish

    run, mm = _run(polish_steps=30)
    run.deadline = time.perf_counter()
    assert polished(run, mm) is mm
    assert run.notes["polish"] == {"steps": 0, "kept": False, "cut_by_time_limit": True}
    clock = [0.0]
    monkeypatch.setattr(polish, "time", SimpleNamespace(perf_counter=lambda: clock[0]))
    step = polish._Move.step

    def one_second(self, loss):
        step(self, loss)
        clock[0] += 1.0

    monkeypatch.setattr(polish._Move, "step", one_second)
    run.deadline = 1.5
    polished(run, mm)
    assert run.notes["polish"]["steps"] == 1 and run.notes["polish"]["cut_by_time_limit"]


def test_polishing_views_share_the_metrics_images_by_default():
    """With the default Fibonacci views, the training cameras at the metrics' resolution are
    the metrics' views: the scene renders one set of reference images for both (cached by
    the cameras themselves), while other cameras get their own."""
    from core.construct.evaluate import eval_cameras

    s = preset("default", eval_resolution=48, eval_views=24)
    v, f = icosphere(2)
    scene = Scene(TriMesh(v, f), fibonacci_cameras(24, width=32), "cpu", True, s.shading)
    polish_views = scene.images(scene.cams.at_resolution(s.eval_resolution))
    assert scene.images(eval_cameras(s)) is polish_views
    assert scene.images(scene.cams) is not polish_views and len(scene._images) == 2


@pytest.mark.slow
def test_polishing_uses_the_callers_cameras_at_the_metrics_resolution(monkeypatch):
    """A construction with the caller's cameras (not square, in the caller's frame) polishes
    against their images at the metrics' resolution (the longer side)."""
    from core.construct import construct
    from tests.core.test_construct import scene, small

    ref, base = scene.__wrapped__()
    cams = fibonacci_cameras(6, radius=7.0, width=80, height=48, center=np.ones(3))
    sizes, images = [], Scene.images

    def recorded(self, c):
        sizes.append((c.width, c.height))
        return images(self, c)

    monkeypatch.setattr(Scene, "images", recorded)
    r = construct(ref, base, cams, small(eval_resolution=128, polish_steps=5))
    assert (128, 77) in sizes and r.metrics["polish"]["steps"] == 5
    assert r.metrics["polish"]["image_error_after"] > 0
    # Its starting error is the one the bounds' tries measured for the micro-mesh they kept.
    lp = r.metrics["lp_bounds"]
    kept = lp["image_error_after"] if lp["kept"] else lp["image_error_before"]
    assert r.metrics["polish"]["image_error_before"] == kept
