"""Scene cameras: a Fibonacci set of real camera objects, and cameras of a collection to core.

Placement follows the supplement (Fibonacci sphere around the source's bounding sphere,
up = the tangent direction with the largest +Z); artists may move, add or delete cameras
afterwards, and construction reads whatever cameras the collection holds.
"""
from __future__ import annotations

import math

import bpy
import numpy as np

from ..core.render.cameras import (Cameras, cameras_from_poses, fibonacci_sphere, look_at,
                                   supplement_up)
from ..core.mesh.trimesh import TriMesh
from ..core.mesh.normalization import unit_sphere_normalization

COLLECTION = "MicroMesh Cameras"


def bounding_sphere(mesh: TriMesh) -> tuple[np.ndarray, float]:
    n = unit_sphere_normalization(mesh.vertices)
    return n.center, 1.0 / n.scale


def place_cameras(scene, source_mesh: TriMesh, count: int = 24, radius_factor: float = 3.5,
                  fov_y_deg: float = 35.0, collection: bpy.types.Collection | None = None
                  ) -> bpy.types.Collection:
    """Fill ``collection`` (created under the scene if None) with ``count`` Fibonacci cameras,
    removing the cameras it held before. Returns the collection."""
    if count < 1:
        raise ValueError("need at least one camera")
    if collection is None:
        collection = bpy.data.collections.get(COLLECTION) or bpy.data.collections.new(COLLECTION)
        if collection.name not in scene.collection.children:
            scene.collection.children.link(collection)
    for obj in list(collection.objects):
        if obj.type == "CAMERA":
            data = obj.data
            bpy.data.objects.remove(obj)
            if data.users == 0:
                bpy.data.cameras.remove(data)
    center, radius = bounding_sphere(source_mesh)
    dist = radius_factor * radius
    dirs = fibonacci_sphere(count)
    ups = supplement_up(dirs)
    for i, (d, u) in enumerate(zip(dirs, ups)):
        cam = bpy.data.cameras.new(f"mm_cam_{i:03d}")
        cam.sensor_fit = "VERTICAL"
        cam.angle_y = math.radians(fov_y_deg)
        cam.clip_start = max(1e-6, 0.01 * dist)        # Blender's least clip distance
        cam.clip_end = 4.0 * dist
        obj = bpy.data.objects.new(f"mm_cam_{i:03d}", cam)
        m = np.linalg.inv(look_at(center + dist * d, center, u))
        obj.matrix_world = m.T.tolist()  # mathutils takes rows
        collection.objects.link(obj)
    return collection


def camera_objects(collection: bpy.types.Collection | None) -> list[bpy.types.Object]:
    if collection is None:
        return []
    return sorted((o for o in collection.all_objects if o.type == "CAMERA"), key=lambda o: o.name)


def fov_y_deg(cam: bpy.types.Camera) -> float:
    """Vertical field of view (square images: AUTO fit means the same angle both ways)."""
    return math.degrees(cam.angle_y if cam.sensor_fit == "VERTICAL" else cam.angle)


def collection_cameras(collection: bpy.types.Collection | None, resolution: int = 256
                       ) -> Cameras | None:
    """Core cameras (square images) from the camera objects of a collection; None if empty."""
    objs = camera_objects(collection)
    if not objs:
        return None
    poses = np.array([np.array(o.matrix_world, dtype=np.float64) for o in objs])
    fovs = np.array([fov_y_deg(o.data) for o in objs])
    near = min(o.data.clip_start for o in objs)
    far = max(o.data.clip_end for o in objs)
    return cameras_from_poses(poses, fovs, resolution, resolution, near=near, far=far)
