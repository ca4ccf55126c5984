"""The base vertices held where the builder put them (core.construct.held), and held in the
optimiser (core.construct.params)."""
from __future__ import annotations

import numpy as np
import torch

from core.construct.held import held_vertices
from core.construct.params import Parameters
from core.mesh.trimesh import TriMesh
from core.micro.micromesh import MicroMesh
from core.settings.fields import preset


def cube(n: int) -> TriMesh:
    """The surface of the cube [-1, 1]³, each side an n × n grid of quads (two triangles
    each), vertices shared along the cube's edges."""
    t = np.linspace(-1.0, 1.0, n + 1)
    verts, faces = [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            u, v = np.meshgrid(t, t, indexing="ij")
            p = np.zeros((n + 1, n + 1, 3))
            p[..., axis] = sign
            p[..., (axis + 1) % 3], p[..., (axis + 2) % 3] = u, v
            i = np.arange((n + 1) ** 2).reshape(n + 1, n + 1) + sum(len(x) for x in verts)
            a, b, c, d = i[:-1, :-1], i[1:, :-1], i[1:, 1:], i[:-1, 1:]
            quads = np.stack([a, b, c, a, c, d], -1).reshape(-1, 3)
            faces.append(quads if sign > 0 else quads[:, ::-1])
            verts.append(p.reshape(-1, 3))
    v, inv = np.unique(np.round(np.concatenate(verts), 12), axis=0, return_inverse=True)
    return TriMesh(v, inv.reshape(-1)[np.concatenate(faces)])


def test_a_base_on_the_reference_is_held_where_it_or_its_whole_star_lies_on_it():
    reference, base = cube(16), cube(4)
    star, vertex = held_vertices(base, reference)
    assert star.all() and vertex.all()
    # one vertex in the middle of a side, moved off it: it and its one-ring no longer have
    # their whole star on the reference; the one-ring still lies on it, the vertex does not
    moved = int(np.argmin(np.linalg.norm(base.vertices - [0.0, 0.0, 1.0], axis=1)))
    v = base.vertices.copy()
    v[moved, 2] += 0.05
    star, vertex = held_vertices(TriMesh(v, base.faces), reference)
    ring = np.unique(base.faces[(base.faces == moved).any(axis=1)])
    others = np.setdiff1d(np.arange(base.n_vertices), ring)
    assert not star[ring].any() and star[others].all()
    assert not vertex[moved] and vertex[np.setdiff1d(np.arange(base.n_vertices), [moved])].all()
    # a base inside the reference holds nothing (as a chord of a rounder shape would)
    star, vertex = held_vertices(TriMesh(base.vertices * 0.9, base.faces), reference)
    assert not star.any() and not vertex.any()


def test_held_vertices_do_not_move_in_the_optimiser():
    base = cube(3)
    mm = MicroMesh.flat(base, np.full(base.n_faces, 1))
    held = np.zeros(base.n_vertices, bool)
    held[::3] = True
    params = Parameters(base, mm, preset("default"), torch.device("cpu"), held=held)
    for _ in range(5):
        params.optimizer.zero_grad()
        P = params.geometry()[0]
        (P ** 2).sum().backward()            # pulls every vertex towards the centre
        params.optimizer.step()
    moved = np.linalg.norm(params.micromesh().base.vertices - base.vertices, axis=1)
    assert (moved[held] == 0.0).all()
    assert (moved[~held] > 1e-4).all()
