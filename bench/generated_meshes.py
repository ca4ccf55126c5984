"""Meshes made here, for the shapes ../shared/meshes lacks: parts of high genus, an assembly
of many parts and a large scan-like surface, with that surface without its noise as a control
(issue 48); and meshes like those issue 59 measured on, which the first ones do not resemble:
CAD plates of genus 11 and 133 and a mounting bracket with four holes, triangulated as a CAD
program's STL export is (``cad_meshes``), a scanned statue with two tiny holes and a scanned
bust with non-manifold edges (``scan_meshes``). Deterministic: the same PLY bytes on every
machine (the CAD parts' and scans' triangulations come from scipy's Qhull: with the pinned
scipy), so micromesh-tools' outputs for them can be made once elsewhere and put beside the
shared ones (``../shared/baselines/NAME/out_NAME.gltf``), or made in the same run
(``construct_bench.py --meshreduce``).

    python bench/generated_meshes.py OUT_DIR [NAME ...]     # writes OUT_DIR/NAME.ply
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from core.io.ply import write_ply  # noqa: E402
from core.mesh.primitives import holed_plate, noisy_sphere, torus  # noqa: E402
from cad_meshes import bracket, cad_plate  # noqa: E402
from scan_meshes import nonmanifold_bust, scanned_statue  # noqa: E402


def plate(genus: int, k: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`core.mesh.primitives.holed_plate`, its corners rounded off a little by a smooth
    bulge (a cast part rather than voxels)."""
    v, f = holed_plate(genus, k)
    c = (v.max(0) + v.min(0)) / 2
    v = v + 0.02 * np.sin(3.0 * (v - c))
    return v, f


def assembly(parts: int = 86, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """``parts`` separate closed parts (tori and wavy spheres of many sizes, 300 to 4,000
    faces each) on a jittered grid: an engine's bolts, rings and housings."""
    rng = np.random.default_rng(seed)
    side = int(np.ceil(parts ** (1 / 3)))
    vs, fs, n = [], [], 0
    for i in range(parts):
        cell = np.array([i % side, (i // side) % side, i // side // side], float)
        scale = rng.uniform(0.15, 0.45)
        if i % 2:
            v, f = torus(int(rng.integers(12, 40)), int(rng.integers(8, 24)), 1.0,
                         rng.uniform(0.2, 0.45))
        else:
            v, f = noisy_sphere(int(rng.integers(300, 4000)), amplitude=0.15, seed=i)
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        if np.linalg.det(q) < 0:
            q[:, 0] = -q[:, 0]
        vs.append(v @ q.T * scale + cell + rng.uniform(-0.05, 0.05, 3))
        fs.append(f + n)
        n += len(v)
    return np.concatenate(vs), np.concatenate(fs)


def scan(faces: int = 871_000, seed: int = 0, noisy: bool = True
         ) -> tuple[np.ndarray, np.ndarray]:
    """A scan-like surface of about ``faces`` faces: a wavy sphere with fine ridges, scanner
    noise along the normals and some 900 faces missing (holes where the scanner saw
    nothing). ``noisy=False``: the same surface, tessellation and holes without the noise
    (a control: what the noise alone costs both tools)."""
    v, f = noisy_sphere(faces, amplitude=0.12, seed=seed)
    rng = np.random.default_rng(seed + 1)
    n = v / np.linalg.norm(v, axis=1, keepdims=True)
    ridges = 0.004 * np.sin(60.0 * n[:, 0] + 40.0 * n[:, 1] ** 2) * np.cos(45.0 * n[:, 2])
    noise = rng.normal(0.0, 2e-4, len(v)) * noisy      # drawn either way: the same holes
    v = v + n * (ridges + noise)[:, None]
    holes = rng.choice(len(f), size=12, replace=False)
    centres = v[f[holes]].mean(1)
    gone = np.zeros(len(f), bool)
    fc = v[f].mean(1)
    for c in centres:
        gone |= np.linalg.norm(fc - c, axis=1) < 0.02
    f = f[~gone]
    used = np.unique(f)
    remap = np.full(len(v), -1, np.int64)
    remap[used] = np.arange(len(used))
    return v[used], remap[f]


GENERATED = {
    "gen_genus11_27k": lambda: plate(11, 8),
    "gen_genus133_77k": lambda: plate(133, 4),
    "gen_parts86": assembly,
    "gen_scan_871k": scan,
    "gen_scan_smooth_871k": lambda: scan(noisy=False),
    "gen_cad_plate11_18k": lambda: cad_plate(11, 160),
    "gen_cad_plate133_18k": lambda: cad_plate(133, 13),
    "gen_bracket_10k": lambda: bracket(180),
    "gen_statue_20k": scanned_statue,
    "gen_bust_109k": nonmanifold_bust,
}


def write(name: str, out: Path) -> Path:
    """``out/NAME.ply`` (made once; an existing file is kept)."""
    path = out / f"{name}.ply"
    if not path.exists():
        out.mkdir(parents=True, exist_ok=True)
        v, f = GENERATED[name]()
        write_ply(path, v, f)
    return path


if __name__ == "__main__":
    if len(sys.argv) < 2 or sys.argv[1].startswith("-"):     # -h, --help: the usage
        sys.exit(__doc__)
    for name in sys.argv[2:] or GENERATED:
        p = write(name, Path(sys.argv[1]))
        print(p)
