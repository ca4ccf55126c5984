"""Adaptive level of detail: per-base-face subdivision criteria, the supplement's Algorithm 1
(in-optimisation, τ = 0.1) and Algorithm 2 (post-process, τ = 0.03), ±1 balancing and a
budget of micro-triangles or bytes.

The one-ring of a base face is the faces sharing a vertex with it (``TriMesh.face_neighbors_csr``);
the ±1 rule is across shared edges, among all the faces on an edge (three or more on a
non-manifold one: ``core.micro.levels``, the one definition), which is what the micro-mesh
format's edge flags can stitch.
"""
from __future__ import annotations

from ..micro.levels import balance_levels, is_balanced
from .algorithms import in_optimization_lod, post_process_lod
from .budget import exchange_to_budget, roll_back_to_budget, trim_to_budget
from .counts import effective_micro_triangles, micro_triangle_count, ring_min_max
from .criteria import LodError, chamfer_face_errors, face_error_sums, relative_gain

__all__ = ["LodError", "balance_levels", "chamfer_face_errors",
           "effective_micro_triangles", "exchange_to_budget", "face_error_sums",
           "in_optimization_lod", "is_balanced", "micro_triangle_count", "post_process_lod",
           "relative_gain", "ring_min_max", "roll_back_to_budget", "trim_to_budget"]
