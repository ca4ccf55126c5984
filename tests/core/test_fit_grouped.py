"""The fit's matches group by group (core.fit.grouped) and its blocks applied without a matrix
(core.fit.system.displacement_blocks): the same as one tree and the assembled system."""
from __future__ import annotations

import numpy as np
import pytest

from core.fit.grouped import GroupedMatches, triangle_groups
from core.fit.samples import reference_samples
from core.fit.system import displacement_blocks, normal_equations, sample_matches
from core.mesh.trimesh import TriMesh
from core.micro.micromesh import MicroMesh
from core.mesh.primitives import icosphere, noisy_sphere


@pytest.fixture(scope="module")
def case():
    v, f = noisy_sphere(6000, amplitude=0.04, seed=5)
    ref = TriMesh(v, f)
    bv, bf = icosphere(1)
    mm = MicroMesh.flat(TriMesh(bv, bf), np.full(len(bf), 3))
    d = np.random.default_rng(0).normal(0.0, 0.01, mm.n_vertices)
    samples = reference_samples(ref, 0.5 * 4 * np.pi / mm.topology.n_triangles)
    return ref, mm.with_displacements(d), samples


def _groups(mm: MicroMesh, size: int) -> list:
    base = mm.base
    return triangle_groups(base.vertices[base.faces].mean(1), mm.topology.face_triangle_ptr,
                           size)


def test_matches_over_groups_are_one_trees(case):
    _, mm, samples = case
    X, T = mm.micro_vertex_positions(), mm.topology.triangles
    groups = _groups(mm, 300)
    assert len(groups) > 4
    assert np.array_equal(np.sort(np.concatenate(groups)), np.arange(len(T)))
    bound = np.full(len(samples), 10.0, np.float32)
    one = list(sample_matches(X, mm.topology, samples, 1 << 12))
    grouped = GroupedMatches(X, T, groups, samples, bound, chunk=1 << 12)
    many = list(grouped)
    pts = np.concatenate([m[0] for m in one])
    assert np.array_equal(pts, np.concatenate([m[0] for m in many]))

    def closest(matches):
        return np.concatenate([np.einsum("sk,skc->sc", B, X[c])
                               for _, _, _, _, c, B in matches])
    near_one, near_many = closest(one), closest(many)
    other = np.abs(near_one - near_many).max(1) > 1e-12
    assert other.sum() <= 1e-3 * len(pts)               # the same points, but for ties:
    dist = np.linalg.norm(pts - near_many, axis=1)      # equally near at float32's precision
    assert np.allclose(dist[other], np.linalg.norm(pts - near_one, axis=1)[other], rtol=1e-7)
    assert np.allclose(grouped.distance, dist, rtol=1e-6, atol=1e-9)
    # a bound below a sample's distance leaves it out, rather than matching it far off
    tight = GroupedMatches(X, T, groups, samples, np.float32(0.5) * grouped.distance)
    assert sum(len(m[0]) for m in tight) < len(samples)


def test_the_blocks_apply_the_assembled_system(case):
    _, mm, samples = case
    d = mm.displacements
    M, b = normal_equations(mm, d, samples, smoothness=0.0, slopes=0.1)
    t = mm.topology
    X, P, D = mm.micro_vertex_positions(), mm.micro_vertex_base_positions(), \
        mm.micro_vertex_directions()
    # one group: one tree, as normal_equations' (over several, a sample on an edge may match
    # the triangle on its other side: the same point, other slope rows)
    matches = GroupedMatches(X, t.triangles, [np.arange(t.n_triangles)], samples,
                             np.full(len(samples), 10.0, np.float32))
    op, b2 = displacement_blocks(matches, t.triangles, P, D, d, 0.1)
    v = np.random.default_rng(1).normal(size=len(d))
    scale = np.abs(M @ v).max()
    assert np.allclose(op @ v, M @ v, atol=1e-6 * scale)        # float32 blocks
    assert np.allclose(op.diagonal(), M.diagonal(), rtol=1e-5)
    assert np.allclose(b2, b, atol=1e-9 * np.abs(b).max())
