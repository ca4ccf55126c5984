"""The named presets of :class:`core.settings.ConstructSettings`: plain dicts of field
overrides (``fast``, ``default``, ``quality``, ``paper``); :func:`core.settings.preset`
builds and validates one."""
from __future__ import annotations

PRESETS: dict[str, dict] = {
    # Every preset spends the storage micromesh-tools' microexpansion 2 would take on the
    # base (budget_ratio; "paper" too, which the paper ran without a
    # budget: at equal storage the rows compare); every one but
    # "paper" ends with the least-squares fit and trains on flat-shaded renders;
    # docs/results.md has the measurements behind lr_disp 1e-4 and w_iso 0.1 (larger steps
    # or isotropy weights over-fit the training views: the judge's PSNR and the geometric
    # error get worse) and behind
    # lod="uniform": every face goes up together and only the last, partial level is given
    # by image error within the budget; Algorithm 1's exchange spent the budget worse
    # (horse_97k −0.26 → +0.81 dB, fertility_60k +0.21 → +0.44 dB against micromesh-tools).
    # About a minute on a 2-core CPU for ~100k-face inputs.
    "fast": dict(iterations=120, subdivide_at=(15, 40, 70), views_per_iter=3,
                 train_resolution=160, lod_resolution=128, lr_base=3e-4, lr_disp=1e-4,
                 w_iso=0.1, lod="uniform", time_limit_s=55.0, min_level=0),
    # Under five minutes on a 2-core CPU: what batch.py and the panel run unless told otherwise
    # (the time limit holds from the start of the base building to the metrics; the loop gets
    # what the estimated fit and metrics leave of it, but always its subdivisions: millions of
    # faces take longer; the file writing comes after it). 100 iterations: the fit at the end
    # redoes what 400 bought (docs/results.md, seventh table).
    # min_level 0 (every preset but "paper"): after the fit a face the base already matches
    # may give its micro-triangles to one that needs them (the flight helmet's many small
    # parts: +0.31 dB).
    "default": dict(iterations=100, subdivide_at=(6, 18, 37, 62), max_level=4, min_level=0,
                    views_per_iter=12, train_resolution=256, lod_resolution=192,
                    lr_base=3e-4, lr_disp=1e-4, w_iso=0.1, w_range=0.03, lod="uniform",
                    time_limit_s=270.0),
    # Slower: more iterations, finer LOD renders, and the values polished against the images
    # (40 steps at the metrics' resolution: 0.02-0.12 dB for 18-31 s on 20k-face inputs, which
    # the default leaves out; docs/performance.md).
    "quality": dict(iterations=900, subdivide_at=(50, 150, 300, 500), views_per_iter=12,
                    train_resolution=256, lod_resolution=256, max_level=4, lr_disp=1e-4,
                    w_iso=0.1, w_range=0.03, lod="uniform", min_level=0, polish_steps=40),
    # The paper's method as published: 1600 iterations, all 24 views each iteration, ℓmax 4,
    # smooth shading, interpolated new levels, no least-squares fit, L_iso weight 1.
    "paper": dict(iterations=1600, subdivide_at=(50, 150, 400, 800), views_per_iter=24,
                  train_resolution=512, lod_resolution=512, max_level=4, freeze_base_at=1200,
                  lr_base=1e-3, lr_disp=1e-3, shading="shaded", init_new_levels="interpolate",
                  final_fit=False, lod="in_optim", paper_losses=True,
                  hold_exact_base=False),
}
