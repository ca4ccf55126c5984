"""The caller's cameras checked against the reference before a construction: blind cameras
and cameras inside the surface are said; none seeing the object is refused."""
import numpy as np
import pytest

from core.mesh import primitives
from core.render.cameras import Cameras, fibonacci_cameras
from core.construct.types import ConstructError
from core.construct.views import check_views, view_coverage
from core.mesh.trimesh import TriMesh

DEV = "cpu"


@pytest.fixture(scope="module")
def sphere():
    v, f = primitives.icosphere(3)
    return TriMesh(v, f)


def _turned_away(cams: Cameras) -> Cameras:
    """The same cameras looking the other way (a half turn about their up axis)."""
    flip = np.diag([-1.0, 1.0, -1.0, 1.0])
    return Cameras(flip @ cams.view, cams.proj, cams.width, cams.height)


def test_cameras_around_the_object_see_its_front(sphere):
    cams = fibonacci_cameras(8, 3.5, 35.0, 64)
    covered, back = view_coverage(sphere, cams, DEV)
    assert (covered > 0.3 * 96 * 96).all() and (back == 0).all()
    assert check_views(sphere, cams, DEV) == []


def test_cameras_inside_see_the_back_and_are_said(sphere):
    cams = fibonacci_cameras(6, 0.3, 60.0, 64)
    covered, back = view_coverage(sphere, cams, DEV)
    assert (covered > 0).all() and (back == covered).all()
    (w,) = check_views(sphere, cams, DEV)
    assert "every camera that sees the object (6 of 6)" in w and "inside" in w
    mixed = fibonacci_cameras(4, 3.5, 35.0, 64).concat(cams.subset([0, 1]))
    (w,) = check_views(sphere, mixed, DEV)
    assert w.startswith("2 of 6 cameras see only the back") and "cameras 4, 5" in w


def test_blind_cameras_are_said_and_none_seeing_is_refused(sphere):
    good = fibonacci_cameras(4, 3.5, 35.0, 64)
    away = _turned_away(fibonacci_cameras(3, 3.5, 35.0, 64))
    assert (view_coverage(sphere, away, DEV)[0] == 0).all()
    (w,) = check_views(sphere, good.concat(away), DEV)
    assert w.startswith("3 of 7 cameras see nothing") and "cameras 4, 5, 6" in w
    with pytest.raises(ConstructError, match="none of the 3 cameras sees the object"):
        check_views(sphere, away, DEV)
