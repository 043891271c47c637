"""Compiled versions of the per-node rotation updates used every Newton iteration.

Same formulas as :mod:`rodnet.kernels.so3` (``retract``) and the gyroscopic term of
:class:`~rodnet.formulations.cosserat.CosseratModel`; ``tests/kernels/test_so3.py`` checks them
against the NumPy versions.
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True)
def retract(q, dtheta):  # pragma: no cover - compiled
    """``q ⊗ exp_q(dtheta / 2)``, renormalised: (n, 4), (n, 3) -> (n, 4)."""
    out = np.empty_like(q)
    for i in range(q.shape[0]):
        x, y, z = dtheta[i, 0], dtheta[i, 1], dtheta[i, 2]
        angle = math.sqrt(x * x + y * y + z * z)
        half = 0.5 * angle
        c = math.cos(half)
        s = 0.5 - angle * angle / 48.0 if angle < 1e-4 else math.sin(half) / angle
        bw, bx, by, bz = c, s * x, s * y, s * z
        aw, ax, ay, az = q[i, 0], q[i, 1], q[i, 2], q[i, 3]
        w = aw * bw - ax * bx - ay * by - az * bz
        xx = aw * bx + ax * bw + ay * bz - az * by
        yy = aw * by - ax * bz + ay * bw + az * bx
        zz = aw * bz + ax * by - ay * bx + az * bw
        norm = math.sqrt(w * w + xx * xx + yy * yy + zz * zz)
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = w / norm, xx / norm, yy / norm, zz / norm
    return out


@numba.njit(cache=True)
def gyroscopic(W, J):  # pragma: no cover - compiled
    """``W x (J W)`` (n, 3) and its derivative ``hat(W) J - hat(J W)`` (n, 3, 3), J diagonal (n, 3)."""
    n = W.shape[0]
    f = np.empty((n, 3))
    d = np.zeros((n, 3, 3))
    for i in range(n):
        w0, w1, w2 = W[i, 0], W[i, 1], W[i, 2]
        j0, j1, j2 = J[i, 0] * w0, J[i, 1] * w1, J[i, 2] * w2
        f[i, 0] = w1 * j2 - w2 * j1
        f[i, 1] = w2 * j0 - w0 * j2
        f[i, 2] = w0 * j1 - w1 * j0
        # hat(W) diag(J): column k of hat(W) scaled by J_k; minus hat(J W)
        d[i, 0, 1] = -w2 * J[i, 1] + j2
        d[i, 0, 2] = w1 * J[i, 2] - j1
        d[i, 1, 0] = w2 * J[i, 0] - j2
        d[i, 1, 2] = -w0 * J[i, 2] + j0
        d[i, 2, 0] = -w1 * J[i, 0] + j1
        d[i, 2, 1] = w0 * J[i, 1] - j0
    return f, d
