"""Fixed second-order spherical-harmonic lighting of unit normals (the rendering loss's shading).

The light is three coloured directional lobes plus a grey ambient term, all in the unit-sphere
world frame (+Z up, as the cameras' up rule):

| lobe | direction (normalised) | RGB radiance |
|---|---|---|
| warm key, from above | (1, -1, 2) | (1.60, 1.20, 0.90) |
| cool fill, from the side | (-1, 0.5, 0.3) | (0.40, 0.60, 1.20) |
| green rim, from below/behind | (0.3, 1, -1) | (0.40, 0.90, 0.40) |
| ambient | - | (0.10, 0.10, 0.10) |

Each lobe is projected onto the 9 real SH basis functions Y_lm (l <= 2) and convolved with the
clamped cosine (Ramamoorthi & Hanrahan: A_0 = pi, A_1 = 2 pi / 3, A_2 = pi / 4), divided by pi,
giving per channel c the irradiance  rgb_c(n) = sum_lm C[lm, c] Y_lm(n)  (``SH_COEFFS``, (9, 3),
basis order Y00, Y1-1, Y10, Y11, Y2-2, Y2-1, Y20, Y21, Y22). For unit n this is the quadratic
rgb_c(n) = k_c + b_c . n + n^T A_c n (``SH_QUADRATIC``), the form the fused kernels use.
The lobes differ in colour so that different normal directions give different RGB.
"""
from __future__ import annotations

import numpy as np
import torch

_LOBES = (
    ((1.0, -1.0, 2.0), (1.60, 1.20, 0.90)),
    ((-1.0, 0.5, 0.3), (0.40, 0.60, 1.20)),
    ((0.3, 1.0, -1.0), (0.40, 0.90, 0.40)),
)
_AMBIENT = np.array([0.10, 0.10, 0.10])

_C0, _C1, _C2, _C3, _C4 = 0.28209479177387814, 0.4886025119029199, 1.0925484305920792, \
    0.31539156525252005, 0.5462742152960396


def sh_basis(n: np.ndarray) -> np.ndarray:
    """Real SH basis Y_lm, l <= 2, of directions (..., 3) -> (..., 9)."""
    x, y, z = n[..., 0], n[..., 1], n[..., 2]
    return np.stack([np.full_like(x, _C0), _C1 * y, _C1 * z, _C1 * x, _C2 * x * y, _C2 * y * z,
                     _C3 * (3 * z * z - 1), _C2 * x * z, _C4 * (x * x - y * y)], axis=-1)


def _coefficients() -> np.ndarray:
    band = np.array([np.pi] + [2 * np.pi / 3] * 3 + [np.pi / 4] * 5) / np.pi
    c = np.zeros((9, 3))
    for d, rgb in _LOBES:
        d = np.asarray(d) / np.linalg.norm(d)
        c += (band * sh_basis(d))[:, None] * np.asarray(rgb)[None, :]
    c[0] += _AMBIENT / _C0
    return c


SH_COEFFS: np.ndarray = _coefficients()


def _quadratic(c: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A (3, 3, 3) symmetric per channel, b (3, 3), k (3,)) with rgb_c = k_c + b_c.n + n^T A_c n."""
    k = _C0 * c[0] - _C3 * c[6]
    b = np.stack([_C1 * c[3], _C1 * c[1], _C1 * c[2]], axis=1)  # (3 channels, xyz)
    a = np.zeros((3, 3, 3))
    a[:, 0, 1] = a[:, 1, 0] = 0.5 * _C2 * c[4]
    a[:, 1, 2] = a[:, 2, 1] = 0.5 * _C2 * c[5]
    a[:, 0, 2] = a[:, 2, 0] = 0.5 * _C2 * c[7]
    a[:, 2, 2] = 3 * _C3 * c[6]
    a[:, 0, 0] = _C4 * c[8]
    a[:, 1, 1] = -_C4 * c[8]
    return a, b, k


SH_QUADRATIC = _quadratic(SH_COEFFS)


def shade_normals(n: torch.Tensor) -> torch.Tensor:
    """RGB (..., 3) of unit normals (..., 3) under the fixed lighting (differentiable)."""
    a, b, k = (torch.as_tensor(t, dtype=n.dtype, device=n.device) for t in SH_QUADRATIC)
    quad = torch.einsum("...i,cij,...j->...c", n, a, n)
    return quad + n @ b.T + k
