"""The eigen-decomposition of a symmetric 3 x 3 matrix inside a compiled loop (the collapse's
vertex placement, :mod:`core.base.collapse`)."""
from __future__ import annotations

import numpy as np

from ..runtime.jit import kernel


@kernel(cache=True)
def eigh3(a, vec):  # pragma: no cover - compiled
    """Eigen-decomposition of the symmetric 3 x 3 ``a`` in place (cyclic Jacobi rotations):
    on return its diagonal holds the eigenvalues (unsorted) and the columns of ``vec`` the
    unit eigenvectors. ``np.linalg.eigh`` does the same through LAPACK with allocations, which
    took most of a collapse's time (every candidate places its vertex)."""
    for i in range(3):
        for j in range(3):
            vec[i, j] = 1.0 if i == j else 0.0
    for _ in range(32):
        off = a[0, 1] * a[0, 1] + a[0, 2] * a[0, 2] + a[1, 2] * a[1, 2]
        diag = a[0, 0] * a[0, 0] + a[1, 1] * a[1, 1] + a[2, 2] * a[2, 2]
        if off <= 1e-32 * diag or off == 0.0:
            return
        for p, r in ((0, 1), (0, 2), (1, 2)):
            apr = a[p, r]
            if apr == 0.0:
                continue
            theta = (a[r, r] - a[p, p]) / (2.0 * apr)
            t = 1.0 / (abs(theta) + np.sqrt(theta * theta + 1.0))
            if theta < 0.0:
                t = -t
            c = 1.0 / np.sqrt(t * t + 1.0)
            s = t * c
            for k in range(3):            # A <- A J (columns p, r)
                akp, akr = a[k, p], a[k, r]
                a[k, p] = c * akp - s * akr
                a[k, r] = s * akp + c * akr
            for k in range(3):            # A <- J^T A (rows p, r)
                apk, ark = a[p, k], a[r, k]
                a[p, k] = c * apk - s * ark
                a[r, k] = s * apk + c * ark
            for k in range(3):            # V <- V J
                vkp, vkr = vec[k, p], vec[k, r]
                vec[k, p] = c * vkp - s * vkr
                vec[k, r] = s * vkp + c * vkr
