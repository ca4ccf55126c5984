"""The test meshes ``bench/generated_meshes.py`` makes like issue 59's: what each is said to be
(closed or not, genus, holes, non-manifold edges, size), the same arrays on every call."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))

from generated_meshes import GENERATED  # noqa: E402


def _edges(f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    return np.unique(e, axis=0, return_counts=True)


def _directed_repeats(f: np.ndarray) -> int:
    d = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    return int((np.unique(d, axis=0, return_counts=True)[1] > 1).sum())


def _volume(v: np.ndarray, f: np.ndarray) -> float:
    a = v[f]
    return float(np.einsum("ij,ij->i", a[:, 0], np.cross(a[:, 1], a[:, 2])).sum() / 6)


@pytest.mark.parametrize("name, genus, faces", [("gen_cad_plate11_18k", 11, 18_000),
                                                ("gen_cad_plate133_18k", 133, 18_000),
                                                ("gen_bracket_10k", 4, 10_000)])
def test_cad_parts_are_closed_outward_solids_of_their_genus(name, genus, faces):
    v, f = GENERATED[name]()
    _, count = _edges(f)
    assert (count == 2).all()                                   # closed, 2-manifold
    assert _directed_repeats(f) == 0                            # consistently oriented
    assert _volume(v, f) > 0                                    # outward
    chi = len(np.unique(f)) - len(count) + len(f)
    assert (2 - chi) // 2 == genus
    assert abs(len(f) - faces) < 0.05 * faces
    assert len(np.unique(v, axis=0)) == len(v)                  # one vertex per position
    a = v[f]
    sides = np.linalg.norm(a - np.roll(a, 1, axis=1), axis=2)
    assert np.percentile(sides.max(1) / sides.min(1), 95) > 5   # CAD's long, thin triangles


def test_the_statue_is_closed_but_for_two_tiny_holes():
    v, f = GENERATED["gen_statue_20k"]()
    _, count = _edges(f)
    assert set(np.unique(count)) == {1, 2}
    assert (count == 1).sum() == 10                  # two holes of three faces: 5 edges each
    assert _directed_repeats(f) == 0 and _volume(v, f) > 0
    assert abs(len(f) - 20_000) < 500


def test_the_bust_has_non_manifold_edges():
    v, f = GENERATED["gen_bust_109k"]()
    _, count = _edges(f)
    assert (count == 3).sum() == 40                  # the fins' edges
    assert (count == 1).sum() == 80                  # each fin's two free sides
    assert abs(len(f) - 109_000) < 500


def test_the_meshes_are_the_same_on_every_call():
    for name in ("gen_cad_plate11_18k", "gen_statue_20k"):
        (v1, f1), (v2, f2) = GENERATED[name](), GENERATED[name]()
        assert np.array_equal(v1, v2) and np.array_equal(f1, f2)
