"""The base builder's edge flips: a flip turns a quad's long diagonal into its short one and
leaves the vertex → face lists consistent; creases, locked vertices, quads whose diagonals lie
far apart and quads without a triangle below the quality floor are not flipped; the final
pass shapes bases better at the same vertices."""
import numpy as np
from scipy.spatial import Delaunay

from core.base import decimate, topology
from core.base.collapse import RING
from core.base.flip import flip_all, try_flip
from core.base.links import build_lists
from core.mesh.trimesh import TriMesh
from core.micro.metrics import isotropy, triangle_isotropy


def fan_with_a_long_diagonal(lift=0.0):
    """A planar patch around a thin rhombus u-a-o-b whose long diagonal (u, o) is an edge;
    ``lift`` raises a and b (a crease across the short diagonal)."""
    ring = [(np.cos(t) * 2.5, np.sin(t) * 1.6) for t in np.linspace(0, 2 * np.pi, 10, endpoint=False)]
    pts = np.array([(-1.0, 0.0), (1.0, 0.0), (0.0, 0.3), (0.0, -0.3)] + ring)
    faces = Delaunay(pts).simplices.copy()
    v = np.c_[pts, np.zeros(len(pts))]
    # orient every face counter-clockwise (normal +z)
    d = np.cross(v[faces[:, 1]] - v[faces[:, 0]], v[faces[:, 2]] - v[faces[:, 0]])[:, 2]
    faces[d < 0] = faces[d < 0][:, ::-1]
    u, o, a, b = 0, 1, 2, 3
    has = lambda f, x, y: x in f and y in f                     # noqa: E731
    pair = [i for i, f in enumerate(faces) if has(f, a, b)]
    assert len(pair) == 2                                      # Delaunay took the short diagonal
    faces[pair[0]], faces[pair[1]] = (u, o, a), (o, u, b)      # the long one instead, CCW
    v[[a, b], 2] += lift
    return v, faces.astype(np.int64), (u, o, a, b)


def state(v, f):
    head, tail, nxt = build_lists(f, len(v))
    return dict(V=v.copy(), F=f.copy(), head=head, tail=tail, nxt=nxt,
                falive=np.ones(len(f), bool), locked=np.zeros(len(v), bool),
                mark=np.zeros(len(v), np.int64), tag=np.zeros(1, np.int64),
                buf=np.empty(RING, np.int64))


def flip(s, u, o, min_cos=np.cos(np.radians(20)), max_gap=1e300, below=2.0):
    return try_flip(u, o, s["V"], s["F"], s["head"], s["tail"], s["nxt"], s["falive"],
                    s["locked"], s["mark"], s["tag"], s["buf"], min_cos, max_gap, below)


def assert_lists_consistent(s, n_vertices):
    """Every live corner sits in the list of its vertex, exactly once, and nothing else does."""
    seen = []
    for x in range(n_vertices):
        k, last = s["head"][x], -1
        while k >= 0:
            assert s["F"][k // 3, k % 3] == x
            seen.append(k)
            last, k = k, s["nxt"][k]
        assert s["tail"][x] == last
    assert sorted(seen) == list(range(3 * len(s["F"])))


def test_a_flat_thin_quad_flips_to_its_short_diagonal():
    v, f, (u, o, a, b) = fan_with_a_long_diagonal()
    s = state(v, f)
    q_before = triangle_isotropy(v, f)[0].min()
    assert flip(s, u, o)
    F = s["F"]
    assert not any(u in t and o in t for t in F) and sum(a in t and b in t for t in F) == 2
    q, area = triangle_isotropy(v, F)
    assert q.min() > q_before + 0.2
    normals = np.cross(v[F[:, 1]] - v[F[:, 0]], v[F[:, 2]] - v[F[:, 0]])
    assert (normals[:, 2] > 0).all()                           # orientation kept
    assert np.isclose(area.sum(), triangle_isotropy(v, f)[1].sum())
    assert_lists_consistent(s, len(v))
    assert not flip(s, a, b)                                   # and never back


def test_only_quads_with_a_triangle_below_the_floor_flip():
    v, f, (u, o, a, b) = fan_with_a_long_diagonal()
    worse = min(triangle_isotropy(v, f[[i for i, t in enumerate(f) if u in t and o in t]])[0])
    assert not flip(state(v, f), u, o, below=worse)
    assert flip(state(v, f), u, o, below=worse + 1e-6)


def test_creases_locked_vertices_and_the_gap_bound_stop_a_flip():
    v, f, (u, o, a, b) = fan_with_a_long_diagonal(lift=0.5)    # a ridge across (a, b)
    assert not flip(state(v, f), u, o)
    v, f, (u, o, a, b) = fan_with_a_long_diagonal(lift=0.05)   # nearly flat: 0.05 apart
    s = state(v, f)
    s["locked"][a] = True
    assert not flip(s, u, o)
    assert not flip(state(v, f), u, o, max_gap=0.01)
    assert flip(state(v, f), u, o, max_gap=0.1)


def test_flip_all_flips_until_nothing_improves():
    v, f, (u, o, a, b) = fan_with_a_long_diagonal()
    s = state(v, f)
    args = (s["V"], s["F"], s["head"], s["tail"], s["nxt"], s["falive"], s["locked"], s["mark"],
            s["tag"], np.cos(np.radians(20)), 1e300, 2.0, 20)
    assert flip_all(*args) >= 1 and not any(u in t and o in t for t in s["F"])
    assert_lists_consistent(s, len(v))
    assert flip_all(*args) == 0                                # a second call finds nothing


def sheared_grid(n=20, shear=0.8, seed=0):
    """A gently curved sheet of parallelograms, each split along a random diagonal: about half
    along the long one."""
    x, y = np.meshgrid(np.arange(n + 1.0), np.arange(n + 1.0), indexing="ij")
    x = x + shear * y
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = (q.ravel() for q in (idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]))
    long = np.random.default_rng(seed).random(len(a)) < 0.5
    faces = np.concatenate([np.where(long[:, None], np.c_[a, b, c], np.c_[a, b, d]),
                            np.where(long[:, None], np.c_[a, c, d], np.c_[b, c, d])])
    z = 0.02 * ((x - n / 2) ** 2 + (y - n / 2) ** 2) / n
    return TriMesh(np.c_[x.ravel(), y.ravel(), z.ravel()], faces)


def test_the_final_flips_shape_a_sheet_better_at_the_same_vertices():
    ref = sheared_grid()
    plain = decimate(ref, ref.n_faces, flip_angle_deg=None)     # the target: no collapse
    ours = decimate(ref, ref.n_faces)
    assert plain.collapses == ours.collapses == 0 and plain.flips == 0 and ours.flips > 50
    np.testing.assert_array_equal(ours.vertices, plain.vertices)
    assert len(ours.faces) == len(plain.faces)
    q0, q1 = (triangle_isotropy(d.vertices, d.faces)[0] for d in (plain, ours))
    # all but a few quads at the border (a vertex there would keep too few neighbours)
    assert (q1 < 0.5).sum() < 0.1 * (q0 < 0.5).sum() and q1.mean() > q0.mean() + 0.1
    assert q1.min() >= q0.min()
    assert topology(TriMesh(ours.vertices, ours.faces)) == topology(ref)
    assert decimate(ref, ref.n_faces, flip_angle_deg=1.0).flips == ours.flips   # a gentle curve
    # every triangle above a lower floor: nothing flips
    assert q0.min() > 0.3 and decimate(ref, ref.n_faces, min_quality=0.3).flips == 0


def test_the_cad_parts_base_is_better_shaped():
    """The CAD part's base (long thin triangles along its creases): the flips raise its
    isotropy at the same vertices, and keep its topology."""
    from core.base.build import welded
    from core.io.mesh_files import read_mesh
    from core.mesh.normalization import unit_sphere_normalization
    from tests.conftest import mesh_path

    ref = read_mesh(mesh_path("counter_cad_84k.ply"))
    unit = welded(TriMesh(unit_sphere_normalization(ref.vertices).apply(ref.vertices), ref.faces))
    bound = 1e-3 * unit.bbox_diagonal
    plain = decimate(unit, 1, max_error=bound, flip_angle_deg=None)
    ours = decimate(unit, 1, max_error=bound)
    assert len(ours.faces) == len(plain.faces)
    assert isotropy(ours.vertices, ours.faces) > isotropy(plain.vertices, plain.faces) + 0.01
    assert topology(TriMesh(ours.vertices, ours.faces)) == topology(unit)
