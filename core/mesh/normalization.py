"""The unit-sphere frame: the similarity that maps a mesh into the unit sphere, and back."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .trimesh import MeshError


@dataclass(frozen=True)
class Normalization:
    """Similarity that maps a mesh into the unit sphere: ``x' = (x - center) * scale``."""

    center: np.ndarray
    scale: float

    def apply(self, points: np.ndarray) -> np.ndarray:
        return (np.asarray(points, dtype=np.float64) - self.center) * self.scale

    def invert(self, points: np.ndarray) -> np.ndarray:
        return np.asarray(points, dtype=np.float64) / self.scale + self.center

    def invert_lengths(self, lengths: np.ndarray | float) -> np.ndarray | float:
        return np.asarray(lengths) / self.scale

    def invert_volume(self, volume: float) -> float:
        return volume / self.scale ** 3


def unit_sphere_normalization(vertices: np.ndarray) -> Normalization:
    """Centre of the bounding box, scaled so the farthest vertex lies on the unit sphere."""
    v = np.asarray(vertices, dtype=np.float64)
    center = 0.5 * (v.min(0) + v.max(0))
    radius = float(np.linalg.norm(v - center, axis=1).max())
    if not np.isfinite(radius) or radius <= 0:
        raise MeshError("mesh has zero extent")
    return Normalization(center=center, scale=1.0 / radius)
