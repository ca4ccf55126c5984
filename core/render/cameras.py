"""Pinhole cameras as batched OpenGL-style view and projection matrices.

Conventions (shared by the renderer and Blender): a camera looks down its local -Z axis with
+Y up, exactly like Blender's camera object, so ``view = inverse(camera.matrix_world)``.
``proj`` is the OpenGL perspective matrix; clip = proj @ view @ [x, y, z, 1]. NDC x runs left
to right and NDC y bottom to top; image row 0 is the *top* of the picture, and pixel (row r,
column c) has its centre at NDC ((c + 0.5) / W * 2 - 1, 1 - (r + 0.5) / H * 2).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Cameras:
    """A batch of B cameras sharing one image size.

    view: (B, 4, 4) world -> camera; proj: (B, 4, 4) camera -> clip; both float64.
    """

    view: np.ndarray
    proj: np.ndarray
    width: int
    height: int

    def __post_init__(self) -> None:
        if self.view.ndim != 3 or self.view.shape[1:] != (4, 4):
            raise ValueError(f"view must be (B, 4, 4), got {self.view.shape}")
        if self.proj.shape != self.view.shape:
            raise ValueError("view and proj must have the same shape")
        if self.width < 1 or self.height < 1:
            raise ValueError("image size must be positive")

    def __len__(self) -> int:
        return len(self.view)

    @property
    def mvp(self) -> np.ndarray:
        """(B, 4, 4) world -> clip."""
        return self.proj @ self.view

    @property
    def eye(self) -> np.ndarray:
        """(B, 3) camera centres in world space."""
        return np.linalg.inv(self.view)[:, :3, 3]

    def with_resolution(self, width: int, height: int | None = None) -> "Cameras":
        """Same poses and fields of view, another image size (aspect must match to keep fov)."""
        return Cameras(self.view, self.proj, int(width), int(height if height else width))

    def at_resolution(self, resolution: int) -> "Cameras":
        """The same cameras with their longer side ``resolution`` pixels (8 at least)."""
        k = resolution / max(self.width, self.height)
        return self.with_resolution(max(8, round(self.width * k)), max(8, round(self.height * k)))

    def subset(self, index) -> "Cameras":
        idx = np.atleast_1d(np.asarray(index))
        return Cameras(self.view[idx], self.proj[idx], self.width, self.height)

    def concat(self, other: "Cameras") -> "Cameras":
        if (other.width, other.height) != (self.width, self.height):
            raise ValueError("cameras to concatenate must share the image size")
        return Cameras(np.concatenate([self.view, other.view]),
                       np.concatenate([self.proj, other.proj]), self.width, self.height)

    def transformed(self, world_to_new: np.ndarray) -> "Cameras":
        """The same cameras expressed in a new world frame (x_new = world_to_new @ x).

        For a similarity (e.g. unit-sphere normalisation) the view matrix keeps a uniform scale;
        it is removed so that view stays rigid and depths are in the new frame's units, and the
        perspective's near and far planes are scaled with it (they are depths too), so the
        cameras clip exactly what they clipped before, at any scale.
        """
        m = np.asarray(world_to_new, dtype=np.float64)
        cam_to_world = np.linalg.inv(self.view)
        new = m[None] @ cam_to_world
        s = np.cbrt(np.abs(np.linalg.det(new[:, :3, :3])))
        new[:, :3, :3] /= s[:, None, None]
        proj = self.proj.copy()
        # OpenGL perspective: P[2,2] = (f+n)/(n-f) keeps its value when n and f scale together,
        # P[2,3] = 2fn/(n-f) scales with them.
        proj[:, 2, 3] *= s
        return Cameras(np.linalg.inv(new), proj, self.width, self.height)


def perspective(fov_y_deg: float, aspect: float, near: float, far: float) -> np.ndarray:
    """OpenGL perspective projection (4, 4); aspect = width / height."""
    if not (0 < fov_y_deg < 180) or near <= 0 or far <= near:
        raise ValueError("bad perspective parameters")
    f = 1.0 / np.tan(np.radians(fov_y_deg) / 2.0)
    p = np.zeros((4, 4))
    p[0, 0] = f / aspect
    p[1, 1] = f
    p[2, 2] = (far + near) / (near - far)
    p[2, 3] = 2.0 * far * near / (near - far)
    p[3, 2] = -1.0
    return p


def look_at(eye: np.ndarray, target: np.ndarray, up: np.ndarray) -> np.ndarray:
    """World -> camera matrix of a camera at ``eye`` looking at ``target`` (OpenGL convention)."""
    eye, target, up = (np.asarray(a, dtype=np.float64) for a in (eye, target, up))
    fwd = target - eye
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, up)
    right /= np.linalg.norm(right)
    true_up = np.cross(right, fwd)
    cam_to_world = np.eye(4)
    cam_to_world[:3, 0], cam_to_world[:3, 1], cam_to_world[:3, 2] = right, true_up, -fwd
    cam_to_world[:3, 3] = eye
    return np.linalg.inv(cam_to_world)


def fibonacci_sphere(count: int) -> np.ndarray:
    """``count`` unit vectors spread evenly on the sphere (golden-angle spiral), (count, 3)."""
    if count < 1:
        raise ValueError("need at least one camera")
    i = np.arange(count, dtype=np.float64)
    z = 1.0 - 2.0 * (i + 0.5) / count
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = i * np.pi * (3.0 - np.sqrt(5.0))
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def supplement_up(direction: np.ndarray) -> np.ndarray:
    """The supplement's up rule: in the sphere's tangent plane at ``direction``, the unit
    direction with the largest +z component (the projection of +Z); +Y at the poles."""
    n = np.asarray(direction, dtype=np.float64)
    n = n / np.linalg.norm(n, axis=-1, keepdims=True)
    z = np.array([0.0, 0.0, 1.0])
    up = z - (n @ z)[..., None] * n
    norm = np.linalg.norm(up, axis=-1, keepdims=True)
    pole = norm[..., 0] < 1e-9
    up = np.where(pole[..., None], np.array([0.0, 1.0, 0.0]), up / np.maximum(norm, 1e-30))
    return up


def fibonacci_cameras(count: int = 24, radius: float = 3.5, fov_y_deg: float = 35.0,
                      width: int = 512, height: int | None = None,
                      center: np.ndarray | None = None) -> Cameras:
    """Cameras on a Fibonacci sphere looking at ``center`` (the origin by default)."""
    height = int(height or width)
    c = np.zeros(3) if center is None else np.asarray(center, dtype=np.float64)
    dirs = fibonacci_sphere(count)
    ups = supplement_up(dirs)
    views = np.stack([look_at(c + radius * d, c, u) for d, u in zip(dirs, ups)])
    near, far = max(radius - 2.0, radius * 0.05), radius + 2.0
    proj = perspective(fov_y_deg, width / height, near, far)
    return Cameras(views, np.repeat(proj[None], count, axis=0), int(width), height)


def cameras_from_poses(cam_to_world: np.ndarray, fov_y_deg: float | np.ndarray, width: int,
                       height: int, near: float = 0.01, far: float = 100.0) -> Cameras:
    """Cameras from arbitrary poses (e.g. Blender cameras' ``matrix_world``).

    ``cam_to_world`` is (B, 4, 4) rigid (scale is removed); ``fov_y_deg`` one value or (B,).
    """
    m = np.array(cam_to_world, dtype=np.float64).reshape(-1, 4, 4)
    s = np.linalg.norm(m[:, :3, :3], axis=1, keepdims=True)
    m[:, :3, :3] /= s
    fov = np.broadcast_to(np.asarray(fov_y_deg, dtype=np.float64), (len(m),))
    proj = np.stack([perspective(f, width / height, near, far) for f in fov])
    return Cameras(np.linalg.inv(m), proj, int(width), int(height))
