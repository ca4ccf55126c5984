"""Least-squares fitting of a micro-mesh to the reference surface (ours): its displacements,
and its base vertices where they may move.

Projection baking samples the reference at each micro-vertex along its direction: the
piecewise-linear micro-surface interpolates those samples, so between them it cuts corners.
Fitting instead chooses all displacements together so that the micro-surface passes as close
as possible to the whole reference: dense samples on the reference (at least ``density`` per
micro-triangle, area-weighted), each matched to its closest point on the current micro-surface
(micro-triangle and barycentrics), and the point-to-plane residual along the reference normal

    r = n · (Σ_k b_k (P_k + D_k d_k) − s)

minimised in the least-squares sense together with ``slopes`` times the same weights on

    e = n · (X_b − X_a)   for each edge (a, b) of the matched micro-triangle,

which asks that triangle to lie in the sample's tangent plane, so that its normal, which flat
shading shows, is the reference's (distance alone lets a triangle tilt while its points stay
close), and ``smoothness`` · |L (|D| d)|² (the micro Laplacian of the displacement as a length,
which damps noise; as a length, it weighs the same under directions scaled by folded bounds).
In the rounds over the displacements alone, a micro-vertex that no sample holds (a patch off
the reference gets none) is kept, weakly, at the displacement the round started from: the
smoothness alone let such patches drift into spikes that set the shell. The matches are
renewed ``iterations`` times (an ICP on the displacements). With ``base_stiffness`` the base
vertices are unknowns too (``fit_micromesh``): P_k is then their interpolation, and a base vertex
may slide where one displacement per micro-vertex cannot reach (a crease between two of its
faces), held in place by ``base_stiffness``; with ``fit_directions`` (``directions.py``) the
base directions turn instead, so that micro-vertices reach what their own direction misses.
The sparse normal equations are
solved by preconditioned conjugate gradients (:func:`solve_normal_equations`). Lengths are
those of the inputs (the construction calls it in the unit-sphere frame).
"""
from __future__ import annotations

from .directions import fit_directions
from .lsq import fit_displacements, fit_micromesh
from .residuals import surface_errors
from .samples import FitError, Samples, fit_samples, reference_samples
from .solve import solve_normal_equations
from .system import normal_equations

__all__ = ["FitError", "Samples", "fit_directions", "fit_displacements", "fit_micromesh",
           "fit_samples", "normal_equations", "reference_samples", "solve_normal_equations",
           "surface_errors"]
