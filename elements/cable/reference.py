"""Slow, readable NumPy oracle of the 2-node cable (tension-only truss) element.

One element at a time, plain NumPy. Every formula cites its equation in ``FORMULATION.md`` next
to this file. ``elements/`` is not a package: load this file by path
(``importlib.util.spec_from_file_location``).

Shapes: positions and velocities ``x1, x2, v1, v2: (3,)`` in global axes; element vectors
``(6,)`` ordered [node 1, node 2]; element matrices ``(6, 6)``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Literal

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


@dataclass(frozen=True, slots=True, kw_only=True)
class CableSection:
    """Axial law of the cable, (CB5)-(CB7).

    Parameters
    ----------
    EA : float
        Axial stiffness [N].
    tau : float
        Kelvin-Voigt retardation time ``viscosity / E`` [s].
    axial : {"tension-only", "linear"}
        Axial law.
    delta : float
        Kink strain of the C¹ ramp of the tension-only law.
    """

    EA: float
    tau: float = 0.0
    axial: Literal["tension-only", "linear"] = "tension-only"
    delta: float = 1e-6

    def __post_init__(self) -> None:
        for name in ("EA", "tau"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0.0):
                raise ValueError(f"section.{name} = {value!r}: must be a finite number >= 0")
        if self.axial not in ("tension-only", "linear"):
            raise ValueError(f"section.axial = {self.axial!r}: allowed 'tension-only', 'linear'")
        if not (np.isfinite(self.delta) and self.delta > 0.0):
            raise ValueError(f"section.delta = {self.delta!r}: must be a finite number > 0")


def ramp(e: float, delta: float) -> tuple[float, float, float, float]:
    """C¹ tension ramp ``r(e)``, ``r'(e)``, ``r''(e)`` and its integral ``Rint(e)``. (CB5)"""
    if e <= 0.0:
        return 0.0, 0.0, 0.0, 0.0
    if e < delta:
        return e * e / (2.0 * delta), e / delta, 1.0 / delta, e**3 / (6.0 * delta)
    return e - 0.5 * delta, 1.0, 0.0, 0.5 * e * e - 0.5 * delta * e + delta * delta / 6.0


def _law(e: float, section: CableSection) -> tuple[float, float, float, float]:
    """``(r, r', r'', Rint)`` of the chosen axial law: the ramp (CB5) or the identity (CB6)."""
    if section.axial == "linear":
        return e, 1.0, 0.0, 0.5 * e * e
    return ramp(e, section.delta)


def kinematics(
    x1: Array, x2: Array, Le: float, v1: Array | None = None, v2: Array | None = None
) -> tuple[float, float, Array, float]:
    """Chord length ``l``, strain ``e`` (CB1), unit tangent ``t: (3,)`` (CB2), strain rate (CB3)."""
    chord = x2 - x1
    length = float(np.linalg.norm(chord))
    if not length > 0.0:
        raise ValueError("cable element of zero length: its direction is undefined")
    t = chord / length
    e_rate = 0.0 if v1 is None or v2 is None else float(t @ (v2 - v1)) / Le
    return length, length / Le - 1.0, t, e_rate


def axial_force(e: float, e_rate: float, section: CableSection) -> float:
    """Axial force ``N`` [N] incl. Kelvin-Voigt damping and the >= 0 clamp. (CB7)"""
    r, dr, _, _ = _law(e, section)
    total = section.EA * (r + section.tau * dr * e_rate)
    if section.axial == "linear":
        return total
    return max(0.0, total)


def energy(x1: Array, x2: Array, Le: float, section: CableSection) -> float:
    """Elastic strain energy [J]. (CB9)"""
    _, e, _, _ = kinematics(x1, x2, Le)
    return float(Le * section.EA * _law(e, section)[3])


def internal_force(
    x1: Array, x2: Array, Le: float, section: CableSection,
    v1: Array | None = None, v2: Array | None = None,
) -> Array:
    """Internal force ``N [-t, t]``, shape (6,). (CB8)"""
    _, e, t, e_rate = kinematics(x1, x2, Le, v1, v2)
    N = axial_force(e, e_rate, section)
    return np.concatenate([-N * t, N * t])


def _clamped(e: float, e_rate: float, section: CableSection) -> bool:
    """True where the tension-only clamp (CB7) holds N at 0 against a negative sum."""
    r, dr, _, _ = _law(e, section)
    return section.axial == "tension-only" and r + section.tau * dr * e_rate < 0.0


def _expand(A: Array) -> Array:
    """The (6, 6) matrix [[A, -A], [-A, A]] of a force that depends on x2 - x1 only."""
    return np.block([[A, -A], [-A, A]])


def tangent_stiffness(
    x1: Array, x2: Array, Le: float, section: CableSection,
    v1: Array | None = None, v2: Array | None = None,
) -> Array:
    """Analytic ``K_T = d f_int / d (x1, x2)`` at fixed velocities, shape (6, 6). (CB10)"""
    length, e, t, e_rate = kinematics(x1, x2, Le, v1, v2)
    if _clamped(e, e_rate, section):
        return np.zeros((6, 6))
    r, dr, ddr, _ = _law(e, section)
    EA, tau = section.EA, section.tau
    P = np.eye(3) - np.outer(t, t)  # d t / d x2 = P / l
    dv = np.zeros(3) if v1 is None or v2 is None else v2 - v1
    dN_dx2 = EA * (dr + tau * ddr * e_rate) * t / Le + EA * tau * dr * (P @ dv) / (length * Le)
    N = axial_force(e, e_rate, section)
    return _expand(np.outer(t, dN_dx2) + N * P / length)


def damping_matrix(
    x1: Array, x2: Array, Le: float, section: CableSection,
    v1: Array | None = None, v2: Array | None = None,
) -> Array:
    """Analytic ``C_T = d f_int / d (v1, v2)``, shape (6, 6). (CB11)"""
    _, e, t, e_rate = kinematics(x1, x2, Le, v1, v2)
    if _clamped(e, e_rate, section):
        return np.zeros((6, 6))
    dr = _law(e, section)[1]
    return _expand(section.tau * section.EA * dr / Le * np.outer(t, t))


def _central_difference(fun: Callable[[Array], Array], h: float) -> Array:
    """Columns ``d fun / d u_j`` at u = 0 (6 inputs), Richardson-extrapolated central
    differences."""
    columns = []
    for j in range(6):
        e = np.zeros(6)
        e[j] = h
        d_h = (fun(e) - fun(-e)) / (2.0 * h)
        d_h2 = (fun(0.5 * e) - fun(-0.5 * e)) / h
        columns.append((4.0 * d_h2 - d_h) / 3.0)
    return np.column_stack(columns)


def tangent_fd(
    x1: Array, x2: Array, Le: float, section: CableSection,
    v1: Array | None = None, v2: Array | None = None, h: float = 1e-5,
) -> Array:
    """``K_T`` by central differences, position steps ``h * Le``, shape (6, 6). (CB10)"""
    return _central_difference(
        lambda u: internal_force(x1 + u[:3], x2 + u[3:], Le, section, v1, v2), h * Le
    )


def damping_fd(
    x1: Array, x2: Array, Le: float, section: CableSection,
    v1: Array | None = None, v2: Array | None = None, h: float = 1e-6,
) -> Array:
    """``C_T`` by central differences in the velocities, shape (6, 6). (CB11)"""
    w1 = np.zeros(3) if v1 is None else np.asarray(v1, dtype=float)
    w2 = np.zeros(3) if v2 is None else np.asarray(v2, dtype=float)
    scale = max(1.0, float(np.linalg.norm(w1)), float(np.linalg.norm(w2)))
    return _central_difference(
        lambda u: internal_force(x1, x2, Le, section, w1 + u[:3], w2 + u[3:]), h * scale
    )


def lumped_node_mass(Le: float, mass_per_length: float) -> float:
    """Mass [kg] one element gives each of its two nodes. (CB12)"""
    return 0.5 * Le * mass_per_length


def node_inertial_force(m: float, a: Array) -> Array:
    """Inertial force ``m a`` of a node, shape (3,). (CB12)"""
    return m * np.asarray(a, dtype=float)
