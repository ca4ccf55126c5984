"""Fibonacci cameras, the supplement's up rule and pose conversion."""
from __future__ import annotations

import numpy as np
import pytest

from core.render.cameras import (cameras_from_poses, fibonacci_cameras, fibonacci_sphere, look_at,
                                 supplement_up)


def project(cams, points):
    p = np.concatenate([points, np.ones((len(points), 1))], 1)
    clip = np.einsum("bij,nj->bni", cams.mvp, p)
    return clip[..., :3] / clip[..., 3:]


@pytest.mark.parametrize("count", [16, 24, 40])
def test_fibonacci_points_evenly_spread(count):
    p = fibonacci_sphere(count)
    assert np.allclose(np.linalg.norm(p, axis=1), 1)
    d = np.linalg.norm(p[:, None] - p[None], axis=2) + np.eye(count) * 9
    nearest = d.min(1)
    # Even spread: nearest-neighbour distances vary little and match the area per point.
    assert nearest.max() / nearest.min() < 1.6
    expected = np.sqrt(4 * np.pi / count)
    assert 0.6 * expected < nearest.mean() < 1.3 * expected
    # Balanced: the centroid is near the origin.
    assert np.linalg.norm(p.mean(0)) < 1.0 / count


def test_cameras_look_at_origin_on_radius():
    cams = fibonacci_cameras(24, radius=3.5, fov_y_deg=35, width=64)
    assert len(cams) == 24
    assert np.allclose(np.linalg.norm(cams.eye, axis=1), 3.5)
    ndc = project(cams, np.zeros((1, 3)))[:, 0]
    assert np.allclose(ndc[:, :2], 0, atol=1e-12)
    assert ((ndc[:, 2] > -1) & (ndc[:, 2] < 1)).all()
    # The whole unit sphere is inside every view (fov 35 deg at radius 3.5).
    s = fibonacci_sphere(500)
    ndc = project(cams, s)
    assert np.abs(ndc[..., :2]).max() < 1.0


def test_up_rule_largest_z_in_tangent_plane():
    cams = fibonacci_cameras(24)
    cam_to_world = np.linalg.inv(cams.view)
    for k in range(24):
        n = cams.eye[k] / np.linalg.norm(cams.eye[k])
        up = cam_to_world[k, :3, 1]
        assert abs(up @ n) < 1e-9                      # in the tangent plane
        # No other tangent direction has a larger z: compare with sampled tangent directions.
        t1 = np.cross(n, [0.3, 0.1, 0.9]); t1 /= np.linalg.norm(t1)
        t2 = np.cross(n, t1)
        ang = np.linspace(0, 2 * np.pi, 360)
        dirs = np.cos(ang)[:, None] * t1 + np.sin(ang)[:, None] * t2
        assert up[2] >= dirs[:, 2].max() - 1e-6
    # Poles fall back to +Y.
    assert np.allclose(supplement_up(np.array([0, 0, 1.0])), [0, 1, 0])


def test_poses_round_trip_and_blender_convention():
    view = look_at(np.array([0, -5.0, 0]), np.zeros(3), np.array([0, 0, 1.0]))
    cam_to_world = np.linalg.inv(view)
    # A Blender camera looks down its local -Z: here that is +Y in the world.
    assert np.allclose(cam_to_world[:3, 2], [0, -1, 0])
    cams = cameras_from_poses(cam_to_world[None] @ np.diag([2.0, 2, 2, 1]), 40.0, 80, 60)
    assert np.allclose(cams.view[0], view)
    ndc = project(cams, np.array([[0, 0, 0.5]]))[0, 0]
    assert abs(ndc[0]) < 1e-12 and ndc[1] > 0          # up in the world is up in the image


def test_transformed_keeps_projection_of_points():
    cams = fibonacci_cameras(4, width=32)
    scale, shift = 0.25, np.array([1.0, -2.0, 0.5])
    m = np.eye(4); m[:3, :3] *= scale; m[:3, 3] = shift
    moved = cams.transformed(m)
    pts = np.random.default_rng(1).normal(size=(10, 3)) * 0.5
    a = project(cams, pts)
    b = project(moved, pts * scale + shift)
    assert np.allclose(a, b, atol=1e-9)       # depth too: near and far scale with the frame


@pytest.mark.parametrize("radius", [1e-3, 1.0, 1e5])
def test_scene_cameras_see_the_whole_object_at_any_scale(radius):
    """Cameras placed as the add-on places them (clip planes in world units around an object
    of that size), brought into the unit frame as a construction does: the object is seen
    whole in every view, the same as at radius 1."""
    import torch

    from core.mesh import primitives
    from core.construct.frame import unit_cameras
    from core.mesh.normalization import unit_sphere_normalization
    from core.render import render
    from core.settings.fields import preset

    v, f = primitives.icosphere(8)
    center = np.array([5.0, -3.0, 2.0]) * radius
    world = v * radius + center
    dist = 3.5 * radius
    dirs = fibonacci_cameras(6).eye / 3.5
    poses = np.linalg.inv(np.stack([look_at(center + dist * d, center, supplement_up(d))
                                    for d in dirs]))
    cams = cameras_from_poses(poses, 35.0, 64, 64, near=0.01 * dist, far=4.0 * dist)
    norm = unit_sphere_normalization(world)
    unit = unit_cameras(cams, norm, preset("fast"), 64)
    mask = render(torch.as_tensor(norm.apply(world), dtype=torch.float32), torch.as_tensor(f),
                  unit, kind="mask", antialias=False)
    ref = render(torch.as_tensor(v, dtype=torch.float32), torch.as_tensor(f),
                 fibonacci_cameras(6, fov_y_deg=35.0, width=64), kind="mask", antialias=False)
    assert ref.sum() > 0
    assert torch.equal(mask.sum(dim=(1, 2, 3)), ref.sum(dim=(1, 2, 3)))


def test_bad_cameras():
    with pytest.raises(ValueError):
        fibonacci_cameras(0)
    with pytest.raises(ValueError):
        cameras_from_poses(np.eye(4), 0.0, 10, 10)
