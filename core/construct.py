"""The one entry point of a micro-mesh construction (method §2–§5): optimise base offsets and
micro-displacements against rendered images of the reference, progressively subdividing with
adaptive level of detail; plus :func:`staged_baseline` (uniform level, projection baking, no
optimisation) for comparison.

Everything inside runs in the unit-sphere frame of the reference; inputs and the result are in
the caller's frame. Geometry per iteration::

    O = (I + λ1 L)^-1 Ō            (base offsets, Large Steps)
    D = (I + λ2 Lℓ)^-1 D̄           (micro displacements; Lℓ rebuilt at each subdivision)
    P = V + O;  N = normals(P) (detached)
    X = interp @ P + (interp @ N) * D
    loss = Φ(X) + w_sv L_sv(D) + w_range L_range(D) + w_iso L_iso(P)
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import torch

from .bake import SOURCE_NEAREST, bake_displacements
from .bounds import DirectionBounds, shell_volume, tight_bounds
from .cameras import Cameras, fibonacci_cameras
from .laplacian import ScreenedSolver, uniform_laplacian
from .lod import (chamfer_face_errors, exchange_to_budget, face_error_sums, in_optimization_lod,
                  micro_triangle_count, post_process_lod, relative_gain, roll_back_to_budget,
                  trim_to_budget)
from .losses import (isotropy_loss, laplacian_smoothing_loss, mean_edge_length,
                     scipy_to_torch_sparse, shell_range_loss, shell_volume_loss,
                     vertex_groups)
from .mesh import Normalization, TriMesh, unit_sphere_normalization
from .metrics import PhaseTimer, crack_edges, geometric_error, isotropy, psnr, storage_bytes
from .micromesh import MicroMesh
from .microtopology import balance_levels
from .optim import Reparameterized, UniformAdam, clip_gradients
from .render import pixel_error, rasterize, reference_images, render, warm_up
from .settings import ConstructSettings, preset, to_dict
from .memory import keep_large_allocations, release_memory
from .threads import set_threads


class ConstructError(ValueError):
    """The inputs of a construction cannot be used."""


class ConstructCancelled(RuntimeError):
    """Raised when ``should_stop()`` returned True; no partial result exists."""


@dataclass
class Progress:
    """Reported to the progress callback once per iteration (and at phase changes)."""

    phase: str
    iteration: int
    total_iterations: int
    loss: float
    psnr: float
    eta_s: float


@dataclass
class ConstructResult:
    """A finished construction, in the caller's frame.

    ``bounds`` are the tight per-vertex direction bounds (caller's units); ``gains`` the per-face
    subdivision gains per level they were measured at; ``metrics`` see :func:`evaluate`;
    ``timings`` seconds per phase; ``history`` per-iteration lists (iteration, loss, render,
    psnr, level events).
    """

    micromesh: MicroMesh
    bounds: DirectionBounds
    gains: dict[int, np.ndarray]
    metrics: dict
    timings: dict[str, float]
    history: dict[str, list]
    settings: ConstructSettings
    normalization: Normalization
    micromesh_unit: MicroMesh = field(repr=False, default=None)  # same result, unit-sphere frame


# ------------------------------------------------------------------------------- helpers
def _device(name: str) -> torch.device:
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name == "cuda" and not torch.cuda.is_available():
        raise ConstructError("device 'cuda' requested but no CUDA device is available")
    return torch.device(name)


def _check_inputs(reference: TriMesh, base: TriMesh) -> None:
    if not isinstance(reference, TriMesh) or not isinstance(base, TriMesh):
        raise ConstructError("reference and base must be core.mesh.TriMesh")
    if base.n_faces > reference.n_faces * 4:
        raise ConstructError("the base mesh has more faces than the reference; is it swapped?")


def _fixed_levels(base: TriMesh, levels) -> np.ndarray:
    """The artist's per-face levels, checked (one per base face, integers 0..5) and balanced."""
    lv = np.asarray(levels)
    if lv.shape != (base.n_faces,):
        raise ConstructError(f"levels must hold one value per base face ({base.n_faces}), "
                             f"got shape {lv.shape}")
    if lv.size and (not np.all(np.isfinite(lv)) or np.any(lv != np.round(lv))):
        raise ConstructError("levels must be whole numbers")
    lv = lv.astype(np.int64)
    if lv.size and (lv.min() < 0 or lv.max() > 5):
        raise ConstructError("levels must be within 0..5 (the hardware limit is 5)")
    return balance_levels(base, lv)


def _similarity_matrix(norm: Normalization) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] *= norm.scale
    m[:3, 3] = -norm.center * norm.scale
    return m


def _unit_cameras(cameras: Cameras | None, norm: Normalization, s: ConstructSettings,
                  resolution: int) -> Cameras:
    if cameras is None:
        return fibonacci_cameras(s.n_views, s.camera_radius, s.fov_y_deg, resolution)
    cams = cameras.transformed(_similarity_matrix(norm))
    k = resolution / max(cams.width, cams.height)
    return cams.with_resolution(max(8, round(cams.width * k)), max(8, round(cams.height * k)))


def torch_vertex_normals(P: torch.Tensor, F: torch.Tensor) -> torch.Tensor:
    """Area-weighted unit vertex normals (zero where undefined)."""
    fn = torch.cross(P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]], dim=1)
    n = torch.zeros_like(P)
    for k in range(3):
        n.index_add_(0, F[:, k], fn)
    return n / n.norm(dim=1, keepdim=True).clamp_min(1e-20)


def _interp_gather(interp, device) -> tuple[torch.Tensor, torch.Tensor]:
    """The (n_micro, n_base) interpolation matrix as (n, 3) indices and weights (zero-padded)."""
    m = interp.tocsr()
    n = m.shape[0]
    cnt = np.diff(m.indptr)
    if cnt.max(initial=0) > 3:
        raise ConstructError("interpolation rows with more than 3 entries")
    idx = np.zeros((n, 3), np.int64)
    w = np.zeros((n, 3))
    pos = np.arange(len(m.indices)) - np.repeat(m.indptr[:-1], cnt)
    rows = np.repeat(np.arange(n), cnt)
    idx[rows, pos] = m.indices
    w[rows, pos] = m.data
    return (torch.as_tensor(idx, device=device),
            torch.as_tensor(w, dtype=torch.float32, device=device))


def _bake(mm: MicroMesh, reference: TriMesh, max_distance: float) -> np.ndarray:
    """Displacements of every micro-vertex of ``mm`` by projection onto the reference."""
    o = mm.micro_vertex_base_positions()
    d = mm.micro_vertex_directions()
    return bake_displacements(o, d, reference, max_distance=max_distance).displacement


def _to_caller_frame(mm: MicroMesh, bounds: DirectionBounds, norm: Normalization
                     ) -> tuple[MicroMesh, DirectionBounds]:
    """Positions back through the normalisation; displacements and bounds scale by 1/s."""
    base = mm.base.with_vertices(norm.invert(mm.base.vertices))
    inv = 1.0 / norm.scale
    out = MicroMesh(base, mm.directions, mm.levels, mm.displacements * inv, mm._topology)
    return out, DirectionBounds(bounds.bias * inv, bounds.scale * inv)


class _Scene:
    """Reference and cameras in the unit-sphere frame, with cached reference images."""

    def __init__(self, reference_unit: TriMesh, cams: Cameras, device, antialias: bool):
        self.ref = reference_unit
        self.cams = cams
        self.device = device
        self.antialias = antialias
        self.rv = torch.as_tensor(reference_unit.vertices, dtype=torch.float32, device=device)
        self.rf = torch.as_tensor(reference_unit.faces, dtype=torch.int64, device=device)
        self._images: dict[tuple, torch.Tensor] = {}

    def images(self, cams: Cameras, key) -> torch.Tensor:
        if key not in self._images:
            self._images[key] = reference_images(self.rv, self.rf, cams, antialias=self.antialias)
        return self._images[key]


def _face_errors(mm: MicroMesh, scene: _Scene, cams: Cameras, key, s: ConstructSettings,
                 ref_tree=None) -> np.ndarray:
    """Per base face error for the LOD criterion (visual: image L1 over the face's pixels)."""
    nf = mm.base.n_faces
    if s.lod_criterion == "chamfer":
        t = mm.topology
        return chamfer_face_errors(mm.micro_vertex_positions(), np.maximum(t.vertex_face, 0),
                                   scene.ref.vertices, nf, ref_tree)
    target = scene.images(cams, key)
    X = torch.as_tensor(mm.micro_vertex_positions(), dtype=torch.float32, device=scene.device)
    T = torch.as_tensor(mm.topology.triangles, dtype=torch.int64, device=scene.device)
    sums = np.zeros(nf)
    for b in range(0, len(cams), 8):  # chunks of views bound the memory
        sub = cams.subset(np.arange(b, min(b + 8, len(cams))))
        ras = rasterize(X, T, sub)
        err = pixel_error(X, T, sub, target[b:b + 8], raster=ras, antialias=s.antialias)
        sums += face_error_sums(err.cpu().numpy(), ras.tri_id.cpu().numpy(),
                                mm.topology.triangle_face, nf)
    return sums


def _cost_fn(s: ConstructSettings, n_base_vertices: int):
    """(cost(levels), budget) of the LOD budget, or (None, 0)."""
    if s.budget_bytes > 0:
        return (lambda lv: storage_bytes(lv, n_base_vertices)["total"]), float(s.budget_bytes)
    if s.budget_micro_triangles > 0:
        return micro_triangle_count, float(s.budget_micro_triangles)
    return None, 0.0


# -------------------------------------------------------------------------------- metrics
def evaluate(mm_unit: MicroMesh, reference_unit: TriMesh, s: ConstructSettings,
             bounds_unit: DirectionBounds | None = None, device=None,
             ref_images: torch.Tensor | None = None) -> dict:
    """Metrics of a micro-mesh in the unit-sphere frame (method §7)."""
    device = device or _device(s.device)
    bounds_unit = bounds_unit if bounds_unit is not None else tight_bounds(mm_unit)
    tess = mm_unit.tessellate()
    base = mm_unit.base
    out: dict = {}
    cams = fibonacci_cameras(s.eval_views, s.camera_radius, s.fov_y_deg, s.eval_resolution)
    X = torch.as_tensor(tess.vertices, dtype=torch.float32, device=device)
    T = torch.as_tensor(tess.triangles, dtype=torch.int64, device=device)
    if ref_images is None:
        rv = torch.as_tensor(reference_unit.vertices, dtype=torch.float32, device=device)
        rf = torch.as_tensor(reference_unit.faces, dtype=torch.int64, device=device)
    se, n = 0.0, 0
    with torch.no_grad():
        for b in range(0, len(cams), 4):
            sub = cams.subset(np.arange(b, min(b + 4, len(cams))))
            img = render(X, T, sub, antialias=s.antialias)
            ref = (ref_images[b:b + 4] if ref_images is not None
                   else reference_images(rv, rf, sub, antialias=s.antialias))
            se += float(((img - ref) ** 2).double().sum())
            n += img.numel()
    mse = se / max(n, 1)
    out["psnr"] = float(10 * np.log10(1.0 / mse)) if mse > 0 else float("inf")
    out["shell_volume"] = shell_volume(base.vertices, base.faces, mm_unit.directions, bounds_unit)
    if s.geom_error:
        out["geom_err"] = geometric_error(reference_unit.vertices, reference_unit.vertex_areas,
                                          tess.vertices, tess.triangles,
                                          reference_unit.bbox_diagonal)
    out["iso_base"] = isotropy(base.vertices, base.faces)
    out["iso_micro"] = isotropy(tess.vertices, tess.triangles)
    st = storage_bytes(mm_unit.levels, base.n_vertices)
    out["bytes"] = st["total"]
    out["bytes_values"] = st["values"]
    out["micro_triangles"] = micro_triangle_count(mm_unit.levels)
    out["base_faces"] = int(base.n_faces)
    out["levels_hist"] = np.bincount(mm_unit.levels, minlength=6).tolist()
    eb = base.boundary_edges
    expected = int(np.sum(2 ** mm_unit.levels[base.edge_faces[eb, 0]])) if len(eb) else 0
    out["cracks"] = crack_edges(tess.triangles, tess.vertices, expected)
    return out


# ---------------------------------------------------------------------------- baseline
def staged_baseline(reference: TriMesh, base: TriMesh, level: int,
                    settings: ConstructSettings | None = None,
                    evaluate_metrics: bool = True) -> ConstructResult:
    """The staged pipeline (Maggiordomo et al. 2023 style): the given base at one uniform
    ``level``, area-weighted normals as directions, projection baking (nearest of the two ray
    hits within two mean base edge lengths, nearest-point fallback), tight bounds, no
    optimisation."""
    s = (settings or preset("default")).validate()
    _check_inputs(reference, base)
    set_threads(s.threads)
    timer = PhaseTimer()
    with timer.phase("setup"):
        norm = unit_sphere_normalization(reference.vertices)
        ref_u = TriMesh(norm.apply(reference.vertices), reference.faces)
        base_u = TriMesh(norm.apply(base.vertices), base.faces)
        h = mean_edge_length(base_u.vertices, base_u.faces)
    with timer.phase("bake"):
        mm = MicroMesh.flat(base_u, np.full(base_u.n_faces, int(level)))
        mm = mm.with_displacements(_bake(mm, ref_u, 2.0 * h))
        bounds = tight_bounds(mm)
    metrics = {}
    if evaluate_metrics:
        with timer.phase("metrics"):
            metrics = evaluate(mm, ref_u, s, bounds)
    metrics["time_s"] = timer.times.get("setup", 0) + timer.times["bake"]
    out, b = _to_caller_frame(mm, bounds, norm)
    return ConstructResult(out, b, {}, metrics, dict(timer.times), {}, s, norm, mm)


# -------------------------------------------------------------------------- construction
def construct(reference: TriMesh, base: TriMesh, cameras: Cameras | None,
              settings: ConstructSettings,
              progress: Callable[[Progress], None] | None = None,
              should_stop: Callable[[], bool] | None = None,
              levels: np.ndarray | None = None) -> ConstructResult:
    """Build a micro-mesh of ``reference`` on ``base`` (both in the caller's frame).

    ``cameras`` (caller's frame) or None for ``settings.n_views`` Fibonacci cameras. Raises
    :class:`ConstructCancelled` within one iteration of ``should_stop()`` returning True.

    ``levels`` (one per base face, 0..5; the artist's per-face override): balanced, then kept
    fixed. No subdivision schedule and no LOD; the base is frozen (the result's base vertices
    are the input's); displacements start from projection baking at those levels and are
    optimised as usual (reparameterisation, L_sv, rendering loss) within the settings' budget.

    Large freed buffers stay in the heap while it runs (``core.memory``; the policy stays set
    for the process) and the free heap goes back to the OS when it returns.
    """
    keep_large_allocations()
    try:
        return _construct(reference, base, cameras, settings, progress, should_stop, levels)
    finally:
        release_memory()


def _construct(reference: TriMesh, base: TriMesh, cameras: Cameras | None, settings: ConstructSettings,
               progress: Callable[[Progress], None] | None, should_stop: Callable[[], bool] | None,
               levels: np.ndarray | None) -> ConstructResult:
    s = settings.validate()
    _check_inputs(reference, base)
    fixed = _fixed_levels(base, levels) if levels is not None else None
    set_threads(s.threads)
    device = _device(s.device)
    torch.manual_seed(s.seed)
    rng = np.random.default_rng(s.seed)
    timer = PhaseTimer()
    stop = should_stop or (lambda: False)
    history: dict[str, list] = {"iteration": [], "loss": [], "render": [], "psnr": [],
                                "events": []}
    gains_log: dict[int, np.ndarray] = {}
    # Compile the renderer's kernels first: a fresh checkout's JIT (about a minute) must not
    # eat the time limit or distort the ETA.
    warm_up(device, antialias=s.antialias)
    t_start = time.perf_counter()

    def check_stop():
        if stop():
            raise ConstructCancelled("construction cancelled")

    # ---------------------------------------------------------------- setup
    with timer.phase("setup"):
        norm = unit_sphere_normalization(reference.vertices)
        ref_u = TriMesh(norm.apply(reference.vertices), reference.faces)
        base_u = TriMesh(norm.apply(base.vertices), base.faces)
        h = mean_edge_length(base_u.vertices, base_u.faces)
        cams = _unit_cameras(cameras, norm, s, s.train_resolution)
        lod_cams = cams.with_resolution(
            max(8, round(cams.width * s.lod_resolution / max(cams.width, cams.height))),
            max(8, round(cams.height * s.lod_resolution / max(cams.width, cams.height))))
        scene = _Scene(ref_u, cams, device, s.antialias)
        nb, nf = base_u.n_vertices, base_u.n_faces
        V0 = torch.as_tensor(base_u.vertices, dtype=torch.float32, device=device)
        F = torch.as_tensor(base_u.faces, dtype=torch.int64, device=device)
        cost, budget = _cost_fn(s, nb)
        ref_tree = None
        if s.lod_criterion == "chamfer":
            from scipy.spatial import cKDTree
            ref_tree = cKDTree(ref_u.vertices)
        bake_dist = 2.0 * h
    check_stop()
    with timer.phase("reference_images"):
        target_all = scene.images(cams, "train")

    # ------------------------------------------------------- parameters
    base_solver = ScreenedSolver(uniform_laplacian(nb, base_u.faces), s.lambda_base) \
        if s.reparameterize else None
    base_L_t = None if s.reparameterize else \
        scipy_to_torch_sparse(uniform_laplacian(nb, base_u.faces), device=device)
    offsets = Reparameterized(np.zeros((nb, 3)), base_solver, device=device)
    start_level = 0 if s.progressive else s.max_level
    while cost is not None and start_level > 0 and cost(np.full(nf, start_level)) > budget:
        start_level -= 1             # no progressive schedule: the finest uniform level in budget
    with timer.phase("init"):
        if fixed is not None:
            # Fixed levels: always start from projection baking (the "re-bake" the artist
            # asked for), then refine the displacements only.
            mm = MicroMesh.flat(base_u, fixed)
            mm = mm.with_displacements(_bake(mm, ref_u, bake_dist))
            start_level = int(fixed.max())
        else:
            mm = MicroMesh.flat(base_u, np.full(nf, start_level))
            d0 = _bake(mm, ref_u, bake_dist) if s.init_bake else np.zeros(mm.n_vertices)
            mm = mm.with_displacements(d0)

    state: dict = {}

    def build_level(mm_new: MicroMesh) -> None:
        """(Re)create the displacement parameter, micro Laplacian and L_sv groups."""
        t = mm_new.topology
        Lm = uniform_laplacian(t.n_vertices, t.triangles)
        solver = ScreenedSolver(Lm, s.lambda_micro) \
            if s.reparameterize else None
        state["disp"] = Reparameterized(mm_new.displacements, solver, device=device)
        state["micro_L"] = None if s.reparameterize else scipy_to_torch_sparse(Lm, device=device)
        state["interp"] = _interp_gather(t.interp, device)
        state["tris"] = torch.as_tensor(t.triangles, dtype=torch.int64, device=device)
        state["groups"] = vertex_groups(base_u.faces, nb, t.face_vertex_ptr, t.face_vertex_idx,
                                        t.n_vertices, device=device)
        state["mm"] = mm_new

    with timer.phase("init"):
        build_level(mm)
    opt = UniformAdam([{"params": [offsets.param], "lr": s.lr_base},
                       {"params": [state["disp"].param], "lr": s.lr_disp}], betas=s.betas)

    def geometry(detach_base: bool = False):
        O = offsets.value()
        if detach_base:
            O = O.detach()
        P = V0 + O
        N = torch_vertex_normals(P.detach(), F)
        D = state["disp"].value()
        idx, w = state["interp"]
        # interp has at most 3 entries per row: a gather is far cheaper than a sparse matmul.
        # (index_select per column: ~15x faster than fancy indexing or sparse.mm on CPU)
        X = 0
        for k in range(3):
            i = idx[:, k]
            X = X + w[:, k:k + 1] * (P.index_select(0, i) + N.index_select(0, i) * D[:, None])
        return P, N, D, X

    def current_micromesh() -> MicroMesh:
        with torch.no_grad():
            P, N, D, _ = geometry()
        mm_old = state["mm"]
        if fixed is not None:        # frozen base: exactly the input, not its float32 copy
            return MicroMesh(base_u, N.detach().double().cpu().numpy(), mm_old.levels,
                             D.detach().double().cpu().numpy(), mm_old.topology)
        return MicroMesh(base_u.with_vertices(P.detach().double().cpu().numpy()),
                         N.detach().double().cpu().numpy(), mm_old.levels,
                         D.detach().double().cpu().numpy(), mm_old.topology)

    # ------------------------------------------------------------ events
    events = sorted(set(int(i) for i in s.subdivide_at)) if s.progressive else []
    last_errors: dict[str, np.ndarray] = {}
    freeze_at = s.base_freeze_iteration
    if fixed is not None:
        events, freeze_at = [], 0    # no schedule; displacements only from the first iteration
        history["events"].append({"iteration": 0, "fixed_levels": True,
                                  "micro_triangles": micro_triangle_count(fixed)})
    level = start_level

    def subdivide(it: int) -> None:
        nonlocal level
        cur = current_micromesh()
        old = cur.levels.copy()
        errs = _face_errors(cur, scene, lod_cams, "lod", s, ref_tree) \
            if (s.lod == "in_optim" or budget > 0) else None
        gains = None
        if errs is not None and "prev" in last_errors:
            gains = relative_gain(last_errors["prev"], errs)
            gains_log[level] = gains
        if s.lod == "in_optim":
            # With a budget, the budget decides (ours): Algorithm 1 runs with τ = -inf (the
            # one-ring rule still holds) and a binding budget is then spent by gain order.
            tau = -np.inf if cost is not None else s.tau_in
            new = in_optimization_lod(old, level, s.min_level, gains, base_u.face_neighbors_csr,
                                      tau)
        else:
            new = np.where(old == level, level + 1, old)
        if cost is not None and cost(new) > budget:
            if s.lod == "in_optim" and gains is not None and level >= 1:
                new = exchange_to_budget(old, level, last_errors["prev"], errs,
                                         base_u.face_adjacency, cost, budget, s.min_level)
            else:
                prio = gains if gains is not None else errs
                new = trim_to_budget(old, new, prio, cost, budget)
        new = balance_levels(base_u, np.minimum(new, s.max_level))
        if errs is not None:
            last_errors["prev"] = errs
        if np.array_equal(new, old):
            history["events"].append({"iteration": it, "level": level + 1, "subdivided": 0})
            level += 1
            return
        nxt = cur.with_levels(new)
        o = nxt.micro_vertex_base_positions()
        dd = nxt.micro_vertex_directions()
        if s.init_new_levels == "bake":
            # Our addition: project the new micro-vertices onto the reference.
            br = bake_displacements(o, dd, ref_u, max_distance=bake_dist)
        else:
            # The paper's interpolation, made exact: intersect each new vertex's line with the
            # current displaced surface, so every new micro-vertex lies on it.
            br = bake_displacements(o, dd, cur.tessellate().to_trimesh(), max_distance=bake_dist)
        # Keep the resampled value where the projection fell back to the nearest point
        # (no ray hit within reach): those are the spikes of plain baking.
        nxt = nxt.with_displacements(np.where(br.source == SOURCE_NEAREST,
                                              nxt.displacements, br.displacement))
        opt.reset_state(state["disp"].param)
        build_level(nxt)
        opt.param_groups[1]["params"] = [state["disp"].param]
        history["events"].append({"iteration": it, "level": level + 1,
                                  "subdivided": int((new > old).sum()),
                                  "micro_triangles": micro_triangle_count(new)})
        level += 1

    # -------------------------------------------------------------- loop
    n_it = s.iterations
    views = min(s.views_per_iter, len(cams))
    t_loop = time.perf_counter()
    it_done = 0
    limit = s.time_limit_s
    stopped_early = False
    last_event = -10
    for it in range(n_it):
        check_stop()
        if limit > 0:
            # Time limit (ours): pull the next subdivision forward once 60% of the time is
            # spent, end the optimisation at 90% (leaving time for LOD, bounds, output).
            el = time.perf_counter() - t_start
            if el > 0.9 * limit and not events:
                stopped_early = True
                break
            if el > 0.6 * limit and events and events[0] > it and it - last_event >= 10:
                events[0] = it
        while events and it >= events[0]:
            events.pop(0)
            last_event = it
            if level < s.max_level:
                with timer.phase("subdivide"):
                    subdivide(it)
                check_stop()
        with timer.phase("optimize"):
            frozen = it >= freeze_at
            idx = np.sort(rng.choice(len(cams), views, replace=False))
            sub = cams.subset(idx)
            opt.zero_grad(set_to_none=True)
            P, N, D, X = geometry(detach_base=frozen)
            img = render(X, state["tris"], sub, antialias=s.antialias)
            tgt = target_all[idx]
            diff = img - tgt
            l_render = diff.abs().mean()
            loss = s.w_render * l_render
            if s.w_sv > 0:
                loss = loss + s.w_sv * shell_volume_loss(D, state["groups"])
            if s.w_range > 0:
                loss = loss + s.w_range * shell_range_loss(D, state["groups"])
            if s.w_iso > 0 and not frozen:
                loss = loss + s.w_iso * isotropy_loss(P, F)
            if not s.reparameterize and s.laplacian_weight > 0:
                reg = laplacian_smoothing_loss(X, state["micro_L"])
                if not frozen:
                    reg = reg + laplacian_smoothing_loss(P, base_L_t)
                loss = loss + s.laplacian_weight * reg
            loss.backward()
            params = [state["disp"].param] + ([] if frozen else [offsets.param])
            if frozen:
                offsets.param.grad = None
            clip_gradients(params, s.grad_clip)
            opt.step()
        mse = float((diff.detach() ** 2).mean())
        p = 10 * np.log10(1.0 / mse) if mse > 0 else float("inf")
        it_done += 1
        history["iteration"].append(it)
        history["loss"].append(float(loss.detach()))
        history["render"].append(float(l_render.detach()))
        history["psnr"].append(float(p))
        if progress is not None:
            el = time.perf_counter() - t_loop
            progress(Progress("optimize", it + 1, n_it, float(loss.detach()), float(p),
                              el / it_done * (n_it - it_done)))

    # ---------------------------------------------------------- finish
    check_stop()
    with timer.phase("finalize"):
        # Schedules shorter than the events, or a non-progressive run: reach ℓmax-bounded levels.
        mm = current_micromesh()
    if fixed is not None:
        pass                          # the artist's levels are kept: no LOD, no budget
    elif s.lod == "post" and mm.levels.max() > s.min_level:
        with timer.phase("post_lod"):
            mm = _post_process(mm, scene, lod_cams, s, ref_tree, gains_log, cost, budget, check_stop)
    elif cost is not None and cost(mm.levels) > budget:
        with timer.phase("post_lod"):
            mm = mm.with_levels(roll_back_to_budget(mm.levels, gains_log, base_u.face_adjacency,
                                                    cost, budget, s.min_level))
    with timer.phase("finalize"):
        mm = mm.with_levels(balance_levels(base_u, mm.levels))
        bounds = tight_bounds(mm)
    check_stop()
    construct_time = time.perf_counter() - t_start
    metrics: dict = {}
    if s.compute_metrics:
        with timer.phase("metrics"):
            metrics = evaluate(mm, ref_u, s, bounds, device)
    metrics["time_s"] = construct_time
    metrics["iterations"] = it_done
    metrics["stopped_early"] = stopped_early
    metrics["fixed_levels"] = fixed is not None
    out, b = _to_caller_frame(mm, bounds, norm)
    if fixed is not None:             # the base was frozen: hand back the caller's vertices
        out = out.with_base_positions(np.asarray(base.vertices, dtype=np.float64))
    if progress is not None:
        progress(Progress("done", n_it, n_it, history["loss"][-1] if history["loss"] else 0.0,
                          metrics.get("psnr", history["psnr"][-1] if history["psnr"] else 0.0), 0.0))
    return ConstructResult(out, b, gains_log, metrics, dict(timer.times), history, s, norm, mm)


def _post_process(mm: MicroMesh, scene: _Scene, cams: Cameras, s: ConstructSettings, ref_tree,
                  gains_log: dict, cost, budget: float, check_stop) -> MicroMesh:
    """Algorithm 2 on the optimised mesh: per-face errors at every level from ℓmin to the top
    (the finished surface resampled at uniform levels), roll back, then fit the budget."""
    top = int(mm.levels.max())
    nf = mm.base.n_faces
    errs = {}
    for lv in range(max(0, s.min_level - 1), top + 1):
        check_stop()
        m = mm if (mm.levels == lv).all() else mm.with_levels(np.full(nf, lv))
        errs[lv] = _face_errors(m, scene, cams, "lod", s, ref_tree)
    gains = {lv: relative_gain(errs[lv - 1], errs[lv]) for lv in errs if lv - 1 in errs}
    gains_log.update(gains)
    new = post_process_lod(gains, top, s.min_level, mm.base.face_neighbors_csr, s.tau_post)
    new = np.minimum(new, mm.levels)
    new = balance_levels(mm.base, new)
    if cost is not None and cost(new) > budget:
        new = roll_back_to_budget(new, gains, mm.base.face_adjacency, cost, budget, s.min_level)
    return mm.with_levels(new)


__all__ = ["ConstructCancelled", "ConstructError", "ConstructResult", "ConstructSettings",
           "Progress", "construct", "evaluate", "preset", "staged_baseline", "to_dict"]
