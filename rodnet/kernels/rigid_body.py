"""Compiled step of the free rigid bodies, (R1)-(R4) of ``elements/contact/FORMULATION.md``.

Symplectic Euler for the translation, exactly as for the thread nodes, a kick of the angular
momentum ``L`` by the contact moment, and the torque-free rotation of the Lie group variational
integrator of Lee, Leok & McClamroch (2007, CMAME 196:2907): it keeps ``L`` exactly under zero
moment and, being symplectic, keeps the kinetic energy bounded. :func:`advance_bodies` runs inside
the explicit step loop (:mod:`rodnet.kernels.explicit`).
"""

from __future__ import annotations

import math

import numba

SERIES_BELOW = 1e-3
"""Below this rotation angle [rad] per step the coefficients of (R3) use their Taylor series."""


@numba.njit(cache=True)
def _coefficients(angle):  # pragma: no cover - compiled
    """a = sin x / x, b = (1 - cos x) / x^2 and their derivatives divided by x, (R3)."""
    x2 = angle * angle
    if angle < SERIES_BELOW:
        return (1.0 - x2 / 6.0 + x2 * x2 / 120.0, 0.5 - x2 / 24.0 + x2 * x2 / 720.0,
                -1.0 / 3.0 + x2 / 30.0 - x2 * x2 / 840.0, -1.0 / 12.0 + x2 / 180.0 - x2 * x2 / 6720.0)
    s, c = math.sin(angle), math.cos(angle)
    return (s / angle, (1.0 - c) / x2, (angle * c - s) / (x2 * angle),
            (angle * s - 2.0 * (1.0 - c)) / (x2 * x2))


@numba.njit(cache=True)
def _solve3(A, r, out):  # pragma: no cover - compiled
    """Solve the 3 x 3 system ``A out = r`` by Cramer's rule (no temporary arrays: this runs in
    every step of every free body)."""
    c00 = A[1, 1] * A[2, 2] - A[1, 2] * A[2, 1]
    c01 = A[1, 2] * A[2, 0] - A[1, 0] * A[2, 2]
    c02 = A[1, 0] * A[2, 1] - A[1, 1] * A[2, 0]
    det = A[0, 0] * c00 + A[0, 1] * c01 + A[0, 2] * c02
    # out = adj(A) r / det, adj(A) the transposed cofactor matrix
    out[0] = (c00 * r[0] + (A[0, 2] * A[2, 1] - A[0, 1] * A[2, 2]) * r[1]
              + (A[0, 1] * A[1, 2] - A[0, 2] * A[1, 1]) * r[2]) / det
    out[1] = (c01 * r[0] + (A[0, 0] * A[2, 2] - A[0, 2] * A[2, 0]) * r[1]
              + (A[0, 2] * A[1, 0] - A[0, 0] * A[1, 2]) * r[2]) / det
    out[2] = (c02 * r[0] + (A[0, 1] * A[2, 0] - A[0, 0] * A[2, 1]) * r[1]
              + (A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]) * r[2]) / det


@numba.njit(cache=True)
def rotation_increment(J, inv_J, pi, h, f, work):  # pragma: no cover - compiled
    """Solve (R3) ``h pi = a(|f|) J f + b(|f|) f x J f`` for the body-frame rotation vector ``f``
    (3,) of one torque-free step of length ``h``, by Newton's method from ``h J^-1 pi``.

    ``pi`` (3,) is the angular momentum in body axes at the start of the step; the step rotates
    the body by ``R <- R exp(hat f)`` and leaves the world angular momentum unchanged. ``work``
    (7, 3) is scratch space. Returns the number of Newton iterations."""
    for k in range(3):
        f[k] = h * (inv_J[k, 0] * pi[0] + inv_J[k, 1] * pi[1] + inv_J[k, 2] * pi[2])
    scale = abs(f[0]) + abs(f[1]) + abs(f[2])
    if scale == 0.0:
        return 0
    Jf, c, G, delta, A = work[0], work[1], work[2], work[3], work[4:7]
    for iteration in range(1, 31):
        angle = math.sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2])
        a, b, da, db = _coefficients(angle)
        for k in range(3):
            Jf[k] = J[k, 0] * f[0] + J[k, 1] * f[1] + J[k, 2] * f[2]
        c[0] = f[1] * Jf[2] - f[2] * Jf[1]
        c[1] = f[2] * Jf[0] - f[0] * Jf[2]
        c[2] = f[0] * Jf[1] - f[1] * Jf[0]
        for k in range(3):
            G[k] = a * Jf[k] + b * c[k] - h * pi[k]
        # dG/df = a J + da Jf f^T + b (hat(f) J - hat(Jf)) + db c f^T
        for i in range(3):
            for j in range(3):
                fJ = 0.0  # (hat(f) J)_ij = sum_k eps_ikl f_k J_lj
                if i == 0:
                    fJ = f[1] * J[2, j] - f[2] * J[1, j]
                elif i == 1:
                    fJ = f[2] * J[0, j] - f[0] * J[2, j]
                else:
                    fJ = f[0] * J[1, j] - f[1] * J[0, j]
                A[i, j] = a * J[i, j] + da * Jf[i] * f[j] + b * fJ + db * c[i] * f[j]
        A[0, 1] += b * Jf[2]
        A[0, 2] -= b * Jf[1]
        A[1, 0] -= b * Jf[2]
        A[1, 2] += b * Jf[0]
        A[2, 0] += b * Jf[1]
        A[2, 1] -= b * Jf[0]
        _solve3(A, G, delta)
        for k in range(3):
            f[k] -= delta[k]
        if abs(delta[0]) + abs(delta[1]) + abs(delta[2]) <= 1e-15 * scale:
            return iteration
    return iteration


@numba.njit(cache=True)
def _quaternion_step(q, f, R):  # pragma: no cover - compiled
    """``q <- q exp(f / 2)`` (right multiplication: a body-frame rotation by ``f``), normalised,
    and ``R`` (3, 3) from it."""
    angle = math.sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2])
    if angle == 0.0:
        dw, dx, dy, dz = 1.0, 0.0, 0.0, 0.0
    else:
        s = math.sin(0.5 * angle) / angle
        dw, dx, dy, dz = math.cos(0.5 * angle), s * f[0], s * f[1], s * f[2]
    w, x, y, z = q[0], q[1], q[2], q[3]
    nw = w * dw - x * dx - y * dy - z * dz
    nx = w * dx + x * dw + y * dz - z * dy
    ny = w * dy - x * dz + y * dw + z * dx
    nz = w * dz + x * dy - y * dx + z * dw
    norm = math.sqrt(nw * nw + nx * nx + ny * ny + nz * nz)
    w, x, y, z = nw / norm, nx / norm, ny / norm, nz / norm
    q[0], q[1], q[2], q[3] = w, x, y, z
    R[0, 0], R[0, 1], R[0, 2] = 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)
    R[1, 0], R[1, 1], R[1, 2] = 2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)
    R[2, 0], R[2, 1], R[2, 2] = 2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)


@numba.njit(cache=True)
def advance_bodies(dt, body_force, body_moment, inv_mass, inertia, inv_inertia, gravity,
                   position, velocity, quaternion, rotation, momentum, omega,
                   work):  # pragma: no cover
    """One step (R1)-(R4) of every free body (``inv_mass`` > 0), in place.

    ``body_force``, ``body_moment`` (B, 3) are the force of the threads on each body [N] and its
    moment about the centre of mass [N m] at the start of the step; ``gravity`` (3,) [m/s^2].
    ``work`` (9, 3) is scratch space (allocated once by the caller: this runs every step)."""
    pi, f = work[0], work[1]
    for b in range(position.shape[0]):
        if inv_mass[b] == 0.0:
            continue
        R = rotation[b]
        for k in range(3):  # (R1), (R2)
            velocity[b, k] += dt * (body_force[b, k] * inv_mass[b] + gravity[k])
            position[b, k] += dt * velocity[b, k]
            momentum[b, k] += dt * body_moment[b, k]
        for k in range(3):
            pi[k] = R[0, k] * momentum[b, 0] + R[1, k] * momentum[b, 1] + R[2, k] * momentum[b, 2]
        rotation_increment(inertia[b], inv_inertia[b], pi, dt, f, work[2:])  # (R3)
        _quaternion_step(quaternion[b], f, R)
        # (R4): omega = R J^-1 R^T L
        for k in range(3):
            pi[k] = R[0, k] * momentum[b, 0] + R[1, k] * momentum[b, 1] + R[2, k] * momentum[b, 2]
        for k in range(3):
            f[k] = inv_inertia[b, k, 0] * pi[0] + inv_inertia[b, k, 1] * pi[1] + inv_inertia[b, k, 2] * pi[2]
        for k in range(3):
            omega[b, k] = R[k, 0] * f[0] + R[k, 1] * f[1] + R[k, 2] * f[2]
