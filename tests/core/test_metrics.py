"""Metrics against hand-computed values on known shapes."""
import numpy as np
import pytest

from core.micro.metrics import (PhaseTimer, crack_edges, distance_to_mesh, geometric_error,
                                isotropy, packed11_block_bytes, psnr, triangle_isotropy)


def test_psnr():
    a = np.zeros((2, 4, 4, 3))
    b = np.full((2, 4, 4, 3), 0.1)
    assert psnr(b, a) == pytest.approx(20.0)           # mse 0.01
    assert psnr(a, a) == float("inf")
    with pytest.raises(ValueError):
        psnr(a, a[:1])


def test_isotropy_known_triangles():
    eq = np.array([[0, 0, 0], [1, 0, 0], [0.5, np.sqrt(3) / 2, 0]])
    rt = np.array([[0, 0, 0], [3, 0, 0], [0, 4, 0.0]])
    q, a = triangle_isotropy(np.vstack([eq, rt]), np.array([[0, 1, 2], [3, 4, 5]]))
    assert q[0] == pytest.approx(1.0)
    # 3-4-5: r = 1, R = 2.5 → 2r/R = 0.8
    assert q[1] == pytest.approx(0.8)
    expect = (1.0 * a[0] + 0.8 * a[1]) / (a[0] + a[1])
    assert isotropy(np.vstack([eq, rt]), np.array([[0, 1, 2], [3, 4, 5]])) == pytest.approx(expect)


def test_distance_to_a_triangle_in_each_region():
    a, b, c = np.array([0.0, 0, 0]), np.array([1.0, 0, 0]), np.array([0.0, 1, 0])
    pts = np.array([[0.2, 0.2, 2.0],      # above the interior
                    [-1.0, -1.0, 0.0],    # vertex a region
                    [0.5, -2.0, 0.0],     # edge ab
                    [1.0, 1.0, 0.0],      # edge bc
                    [3.0, -1.0, 0.0]])    # vertex b region
    d = distance_to_mesh(pts, np.stack([a, b, c]), np.array([[0, 1, 2]]))
    assert d == pytest.approx([2.0, np.sqrt(2), 2.0, np.sqrt(0.5), np.sqrt(5)])


def test_geometric_error_unit_square_offset():
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.0]])
    t = np.array([[0, 1, 2], [0, 2, 3]])
    pts = np.array([[0.5, 0.5, 0.1], [0.2, 0.7, -0.1], [0.9, 0.1, 0.1], [2.0, 0.5, 0.0]])
    d = distance_to_mesh(pts, v, t)
    assert d == pytest.approx([0.1, 0.1, 0.1, 1.0])
    w = np.ones(4)
    # The 99th percentile drops the 1.0 outlier: mean 0.1 over diagonal 2.
    assert geometric_error(pts, w, v, t, diagonal=2.0) == pytest.approx(0.05)


def test_packed11_block_bytes():
    # level 0: 3 values → 33 bits → 8 bytes; level 1: 6 → 66 bits → 12; level 3: 45 → 495 → 64.
    assert packed11_block_bytes(np.array([0, 1, 3])).tolist() == [8, 12, 64]


def test_crack_edges():
    # Two triangles sharing an edge through shared indices: closed along it, the square's
    # outline (4 edges) is the expected boundary.
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.0]])
    t = np.array([[0, 1, 2], [0, 2, 3]])
    assert crack_edges(t, v, base_boundary_micro_edges=4) == 0
    # Split vertex 2 at a different position: a gap of two extra open edges.
    v2 = np.vstack([v, [[1.0, 1.0, 0.01]]])
    t2 = np.array([[0, 1, 2], [0, 4, 3]])
    assert crack_edges(t2, v2, base_boundary_micro_edges=4) == 2
    # Same position split: merged, no crack.
    v3 = np.vstack([v, [[1.0, 1.0, 0.0]]])
    assert crack_edges(t2, v3, base_boundary_micro_edges=4) == 0


def test_phase_timer():
    t = PhaseTimer()
    with t.phase("a"):
        pass
    with t.phase("a"):
        pass
    assert set(t.times) == {"a"} and t.total >= 0
