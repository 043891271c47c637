"""Slow, readable NumPy oracle of the 2-node Cosserat (Simo-Reissner) rod element.

One element at a time, plain NumPy, no vectorisation. Every formula cites its equation in
``FORMULATION.md`` next to this file. ``elements/`` is not a package: load this file by path
(``importlib.util.spec_from_file_location``).

Shapes: positions ``x1, x2: (3,)``; unit quaternions ``q1, q2: (4,)`` ordered (w, x, y, z);
element DOF and velocity vectors ``(12,)`` ordered [node 1 translation, node 1 rotation,
node 2 translation, node 2 rotation]; rotations and angular velocities in the BODY frame.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Literal

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

SMALL_ANGLE = 1e-2  # below this angle the Taylor series of (C5) replace the closed forms
NEAR_PI = 1e-3  # within this of pi, (C6) takes the axis from the symmetric part of R
PSI_MARGIN = 1e-6  # the element requires |psi| < pi - PSI_MARGIN, see (C11)


@dataclass(frozen=True, slots=True, kw_only=True)
class Section:
    """Section parameters of the element, see (C22)-(C27).

    Parameters
    ----------
    EA, GA2, GA3 : float
        Axial and shear stiffnesses [N] (shear factor included), ``C_N = diag(EA, GA2, GA3)``.
    GJ, EI2, EI3 : float
        Torsional and bending stiffnesses [N m^2], ``C_M = diag(GJ, EI2, EI3)``.
    tau : float
        Kelvin-Voigt retardation time ``viscosity / E`` [s].
    axial : {"tension-only", "linear"}
        Axial law.
    delta : float
        Kink strain of the C¹ ramp of the tension-only law.
    """

    EA: float
    GA2: float
    GA3: float
    GJ: float
    EI2: float
    EI3: float
    tau: float = 0.0
    axial: Literal["tension-only", "linear"] = "tension-only"
    delta: float = 1e-6

    def __post_init__(self) -> None:
        for name in ("EA", "GA2", "GA3", "GJ", "EI2", "EI3", "tau"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0.0):
                raise ValueError(f"section.{name} = {value!r}: must be a finite number >= 0")
        if self.axial not in ("tension-only", "linear"):
            raise ValueError(f"section.axial = {self.axial!r}: allowed 'tension-only', 'linear'")
        if not (np.isfinite(self.delta) and self.delta > 0.0):
            raise ValueError(f"section.delta = {self.delta!r}: must be a finite number > 0")

    @property
    def C_N(self) -> Array:
        """Force stiffness ``diag(EA, GA2, GA3)``, shape (3, 3)."""
        return np.diag([self.EA, self.GA2, self.GA3])

    @property
    def C_M(self) -> Array:
        """Moment stiffness ``diag(GJ, EI2, EI3)``, shape (3, 3)."""
        return np.diag([self.GJ, self.EI2, self.EI3])


# ----------------------------------------------------------------------------- SO(3) tools


def hat(w: Array) -> Array:
    """Skew matrix of ``w: (3,)`` with ``hat(w) @ u == cross(w, u)``, shape (3, 3). (C3)"""
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def vee(W: Array) -> Array:
    """Inverse of :func:`hat` applied to the skew part of ``W: (3, 3)``, shape (3,). (C3)"""
    return 0.5 * np.array([W[2, 1] - W[1, 2], W[0, 2] - W[2, 0], W[1, 0] - W[0, 1]])


def _coefficients(theta: float) -> tuple[float, float, float, float]:
    """Scalar functions a, b, c, d of the rotation angle, (C5)."""
    if theta < SMALL_ANGLE:
        t2 = theta * theta
        a = 1.0 - t2 / 6.0 + t2 * t2 / 120.0
        b = 0.5 - t2 / 24.0 + t2 * t2 / 720.0
        c = 1.0 / 6.0 - t2 / 120.0 + t2 * t2 / 5040.0
        d = 1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0
        return a, b, c, d
    s, co = np.sin(theta), np.cos(theta)
    half = np.sin(0.5 * theta) / (0.5 * theta)
    a = s / theta
    b = 0.5 * half * half  # (1 - cos)/theta^2 without cancellation
    c = (theta - s) / theta**3
    d = 1.0 / theta**2 - (1.0 + co) / (2.0 * theta * s)
    return a, b, c, d


def so3_exp(phi: Array) -> Array:
    """Rotation matrix ``exp(hat(phi))`` by Rodrigues' formula, shape (3, 3). (C4)"""
    a, b, _, _ = _coefficients(float(np.linalg.norm(phi)))
    P = hat(phi)
    return np.eye(3) + a * P + b * (P @ P)


def so3_log(R: Array) -> Array:
    """Rotation vector ``psi`` with ``exp(hat(psi)) = R`` and ``|psi| <= pi``, shape (3,). (C6)"""
    axis_sin = vee(R)  # sin(theta) * n
    cos_theta = 0.5 * (np.trace(R) - 1.0)
    theta = float(np.arctan2(np.linalg.norm(axis_sin), cos_theta))
    if theta < SMALL_ANGLE:
        return axis_sin / _coefficients(theta)[0]
    if theta < np.pi - NEAR_PI:
        return theta * axis_sin / np.linalg.norm(axis_sin)
    # near pi sin(theta) carries no axis information; R + R^T = 2 cos I + 2 (1 - cos) n n^T
    S = (0.5 * (R + R.T) - cos_theta * np.eye(3)) / (1.0 - cos_theta)
    k = int(np.argmax(np.diag(S)))
    n = S[:, k] / np.sqrt(S[k, k])
    return theta * (n if n @ axis_sin >= 0.0 else -n)


def tangent_operator(phi: Array) -> Array:
    """``T(phi)`` with ``d exp(hat(phi)) = exp(hat(phi)) hat(T(phi) dphi)``, shape (3, 3). (C7)"""
    _, b, c, _ = _coefficients(float(np.linalg.norm(phi)))
    P = hat(phi)
    return np.eye(3) - b * P + c * (P @ P)


def tangent_operator_inv(phi: Array) -> Array:
    """``T(phi)^-1`` in closed form, shape (3, 3); singular at ``|phi| = 2 pi``. (C8)"""
    _, _, _, d = _coefficients(float(np.linalg.norm(phi)))
    P = hat(phi)
    return np.eye(3) + 0.5 * P + d * (P @ P)


def quat_to_matrix(q: Array) -> Array:
    """Rotation matrix (columns = directors d1, d2, d3) of quaternion ``q: (4,)``. (C2)

    ``q`` is normalised first, so a round-off drift of its norm does not leak into R.
    """
    w, x, y, z = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def quat_multiply(p: Array, q: Array) -> Array:
    """Hamilton product ``p ⊗ q``, shape (4,); ``R(p ⊗ q) = R(p) R(q)``. (C2)"""
    pw, pv, qw, qv = p[0], p[1:], q[0], q[1:]
    return np.concatenate([[pw * qw - pv @ qv], pw * qv + qw * pv + np.cross(pv, qv)])


def retract_node(x: Array, q: Array, dx: Array, dtheta: Array) -> tuple[Array, Array]:
    """Move a node by a Lie-algebra increment: ``x + dx``, ``q ⊗ exp_q(dtheta/2)``. (C1)"""
    angle = float(np.linalg.norm(dtheta))
    half_sinc = 0.5 if angle == 0.0 else np.sin(0.5 * angle) / angle  # no cancellation
    dq = np.concatenate([[np.cos(0.5 * angle)], half_sinc * np.asarray(dtheta, dtype=float)])
    q_new = quat_multiply(q, dq)
    return x + dx, q_new / np.linalg.norm(q_new)


# ----------------------------------------------------------------------------- kinematics


def _kinematics(x1: Array, q1: Array, x2: Array, q2: Array) -> tuple[Array, Array]:
    """Relative rotation vector ``psi`` (C11) and midpoint triad ``R_m`` (C12)."""
    R1, R2 = quat_to_matrix(q1), quat_to_matrix(q2)
    psi = so3_log(R1.T @ R2)  # (C11)
    if np.linalg.norm(psi) >= np.pi - PSI_MARGIN:
        raise ValueError(f"|psi| = {np.linalg.norm(psi):.6g}: the element needs |psi| < pi")
    R_m = R1 @ so3_exp(0.5 * psi)  # (C12)
    return psi, R_m


def strains(
    x1: Array, q1: Array, x2: Array, q2: Array, Le: float, Gamma0: Array, K0: Array
) -> tuple[Array, Array]:
    """Material strains of the element at its midpoint.

    Returns
    -------
    Gamma : (3,)
        Axial strain and two shear strains, (C14).
    K : (3,)
        Twist and two bending curvatures [1/m], (C13).
    """
    psi, R_m = _kinematics(x1, q1, x2, q2)
    K = psi / Le - K0  # (C13)
    Gamma = R_m.T @ (x2 - x1) / Le - Gamma0  # (C14)
    return Gamma, K


def stress_free_strains(
    x1: Array, q1: Array, x2: Array, q2: Array, Le: float
) -> tuple[Array, Array]:
    """``(Gamma0, K0)``, each (3,), that make this configuration stress-free. (C15)"""
    return strains(x1, q1, x2, q2, Le, np.zeros(3), np.zeros(3))


def b_matrix(x1: Array, q1: Array, x2: Array, q2: Array, Le: float) -> Array:
    """``B = d(Gamma, K) / d(DOF)`` under ``R <- R exp(hat(dtheta))``, shape (6, 12). (C20)"""
    psi, R_m = _kinematics(x1, q1, x2, q2)
    E_half = so3_exp(-0.5 * psi)  # = R_m^T R1
    A2 = np.linalg.inv(np.eye(3) + E_half)  # (C17)
    A1 = A2 @ E_half  # (C17)
    T_inv = tangent_operator_inv(psi)
    G = hat(R_m.T @ (x2 - x1)) / Le  # (C18)
    B = np.zeros((6, 12))
    B[0:3, 0:3] = -R_m.T / Le  # (C18)
    B[0:3, 3:6] = G @ A1
    B[0:3, 6:9] = R_m.T / Le
    B[0:3, 9:12] = G @ A2
    B[3:6, 3:6] = -T_inv.T / Le  # (C16), (C19)
    B[3:6, 9:12] = T_inv / Le
    return B


# ----------------------------------------------------------------------------- constitutive law


def ramp(e: float, delta: float) -> tuple[float, float, float]:
    """C¹ tension ramp ``r(e)``, its slope ``r'(e)`` and its integral ``Rint(e)``. (C22), (C23)"""
    if e <= 0.0:
        return 0.0, 0.0, 0.0
    if e < delta:
        return e * e / (2.0 * delta), e / delta, e**3 / (6.0 * delta)
    return e - 0.5 * delta, 1.0, 0.5 * e * e - 0.5 * delta * e + delta * delta / 6.0


def stress_resultants(
    Gamma: Array, K: Array, Gamma_rate: Array, K_rate: Array, section: Section
) -> tuple[Array, Array]:
    """Material force ``N: (3,)`` and moment ``M: (3,)`` incl. Kelvin-Voigt damping. (C24)-(C27)"""
    tau = section.tau
    N = section.C_N @ (Gamma + tau * Gamma_rate)  # shear rows of (C27); axial row replaced below
    if section.axial == "linear":
        N[0] = section.EA * (Gamma[0] + tau * Gamma_rate[0])  # (C24), (C25)
    else:
        r, dr, _ = ramp(Gamma[0], section.delta)
        N[0] = max(0.0, section.EA * (r + tau * dr * Gamma_rate[0]))  # (C24)-(C26)
    M = section.C_M @ (K + tau * K_rate)  # (C27)
    return N, M


def energy(
    x1: Array, q1: Array, x2: Array, q2: Array, Le: float, Gamma0: Array, K0: Array,
    section: Section,
) -> float:
    """Elastic strain energy of the element [J]. (C28)"""
    Gamma, K = strains(x1, q1, x2, q2, Le, Gamma0, K0)
    if section.axial == "linear":
        axial = 0.5 * section.EA * Gamma[0] ** 2
    else:
        axial = section.EA * ramp(Gamma[0], section.delta)[2]
    shear = 0.5 * (section.GA2 * Gamma[1] ** 2 + section.GA3 * Gamma[2] ** 2)
    return float(Le * (axial + shear + 0.5 * K @ section.C_M @ K))


def internal_force(
    x1: Array, q1: Array, x2: Array, q2: Array, Le: float, Gamma0: Array, K0: Array,
    section: Section, velocities: Array | None = None,
) -> Array:
    """Internal force vector ``f_int = Le B^T [N; M]``, shape (12,). (C30)

    ``velocities: (12,)`` = [v1 (global), W1 (body), v2, W2]; ``None`` means at rest.
    Rotational entries are moments in the body frame of their node.
    """
    Gamma, K = strains(x1, q1, x2, q2, Le, Gamma0, K0)
    B = b_matrix(x1, q1, x2, q2, Le)
    rates = np.zeros(6) if velocities is None else B @ velocities  # (C21)
    N, M = stress_resultants(Gamma, K, rates[:3], rates[3:], section)
    return Le * B.T @ np.concatenate([N, M])  # (C30)


def damping_matrix(
    x1: Array, q1: Array, x2: Array, q2: Array, Le: float, Gamma0: Array, K0: Array,
    section: Section, velocities: Array | None = None,
) -> Array:
    """Analytic ``C_T = d f_int / d velocities = Le B^T D_v B``, shape (12, 12). (C35)"""
    Gamma, K = strains(x1, q1, x2, q2, Le, Gamma0, K0)
    B = b_matrix(x1, q1, x2, q2, Le)
    rates = np.zeros(6) if velocities is None else B @ velocities
    d_v = section.tau * np.array(
        [section.EA, section.GA2, section.GA3, section.GJ, section.EI2, section.EI3]
    )
    if section.axial == "tension-only":
        r, dr, _ = ramp(Gamma[0], section.delta)
        clamped = r + section.tau * dr * rates[0] < 0.0  # (C26) active: N0 = 0 whatever the rate
        d_v[0] = 0.0 if clamped else d_v[0] * dr
    return Le * B.T @ np.diag(d_v) @ B


# ----------------------------------------------------------------------------- finite differences


def _central_difference(fun: Callable[[Array], Array], steps: Array) -> Array:
    """Columns ``d fun / d u_j`` at u = 0, Richardson-extrapolated central differences."""
    columns = []
    for j, h in enumerate(steps):
        e = np.zeros(len(steps))
        e[j] = 1.0
        d_h = (fun(h * e) - fun(-h * e)) / (2.0 * h)
        d_h2 = (fun(0.5 * h * e) - fun(-0.5 * h * e)) / h
        columns.append((4.0 * d_h2 - d_h) / 3.0)
    return np.column_stack(columns)


def tangent_fd(
    x1: Array, q1: Array, x2: Array, q2: Array, Le: float, Gamma0: Array, K0: Array,
    section: Section, velocities: Array | None = None, h: float = 1e-4,
) -> Array:
    """Stiffness tangent ``K_T = d f_int / d DOF`` by central differences on the Lie algebra.

    Column j perturbs DOF j by (C1) at fixed velocities; translations step ``h * Le``,
    rotations ``h`` rad. Shape (12, 12). (C32)
    """

    def perturbed_force(u: Array) -> Array:
        y1, p1 = retract_node(x1, q1, u[0:3], u[3:6])
        y2, p2 = retract_node(x2, q2, u[6:9], u[9:12])
        return internal_force(y1, p1, y2, p2, Le, Gamma0, K0, section, velocities)

    steps = np.array([h * Le] * 3 + [h] * 3 + [h * Le] * 3 + [h] * 3)
    return _central_difference(perturbed_force, steps)


def damping_fd(
    x1: Array, q1: Array, x2: Array, q2: Array, Le: float, Gamma0: Array, K0: Array,
    section: Section, velocities: Array | None = None, h: float = 1e-6,
) -> Array:
    """``C_T = d f_int / d velocities`` by central differences, shape (12, 12). (C35)"""
    v0 = np.zeros(12) if velocities is None else np.asarray(velocities, dtype=float)

    def force(u: Array) -> Array:
        return internal_force(x1, q1, x2, q2, Le, Gamma0, K0, section, v0 + u)

    scale = max(1.0, float(np.linalg.norm(v0)))
    return _central_difference(force, np.full(12, h * scale))


# ----------------------------------------------------------------------------- inertia


def lumped_node_inertia(
    Le: float, mass_per_length: float, rotary_inertia_per_length: Array
) -> tuple[float, Array]:
    """Mass and body-frame rotary inertia one element gives each of its nodes. (C36)

    ``rotary_inertia_per_length: (3,)`` = rho * (J, I2, I3) [kg m]. Returns ``(m, J_diag (3,))``.
    """
    return 0.5 * Le * mass_per_length, 0.5 * Le * np.asarray(rotary_inertia_per_length, dtype=float)


def node_inertial_force(m: float, J: Array, a: Array, W: Array, W_dot: Array) -> Array:
    """Inertial force ``m a`` (global), moment ``J W_dot + W x (J W)`` (body); shape (6,). (C37)"""
    return np.concatenate([m * a, J * W_dot + np.cross(W, J * W)])


def gyroscopic_matrix(J: Array, W: Array) -> Array:
    """``d (W x J W) / d W = hat(W) J - hat(J W)``, shape (3, 3). (C38)"""
    return hat(W) @ np.diag(J) - hat(J * W)
