"""Bending hinges of Kirchhoff threads: energy and forces, vectorised over hinges.

A hinge ``(a, b, c)`` joins two consecutive segments of a thread at node ``b``; its bending
measure is ``kappa = e1 / l1 - e0 / l0`` (edge vectors over their rest lengths). Equations
``elements/kirchhoff/FORMULATION.md`` (K2)-(K5). The compiled explicit loop uses the same formulas
per hinge (:func:`rodnet.kernels.segments.hinge_forces`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


class Hinges(NamedTuple):
    """Bending hinges (K1): ``nodes`` (H, 3) int ``(a, b, c)``, ``stiffness`` (H,)
    ``k_h = EI / lbar`` [N m], ``tau`` (H,) retardation time [s], ``rest`` (H, 2) rest lengths of
    the segments ``(a, b)`` and ``(b, c)`` [m]."""

    nodes: NDArray[np.int64]
    stiffness: FloatArray
    tau: FloatArray
    rest: FloatArray


def no_hinges() -> Hinges:
    """No hinges: the lumped model and cables."""
    return Hinges(np.zeros((0, 3), np.int64), np.zeros(0), np.zeros(0), np.zeros((0, 2)))

STRAIGHT = 1e-20
"""Below this ``|kappa|^2`` the bending direction is undefined and the damping term is left out
(K4)."""


def _bend(x: FloatArray, hinges: NDArray[np.int64], rest: FloatArray) -> FloatArray:
    """``kappa = (x_c - x_b) / l1 - (x_b - x_a) / l0`` (H, 3) of every hinge, (K2)."""
    a, b, c = hinges.T
    return (x[c] - x[b]) / rest[:, 1:] - (x[b] - x[a]) / rest[:, :1]


def hinge_energy(x: FloatArray, hinges: NDArray[np.int64], stiffness: FloatArray,
                 rest: FloatArray) -> FloatArray:
    """Bending energy ``(k_h / 2) |kappa|^2`` [J] of every hinge, (K2).

    Parameters
    ----------
    x : (N, 3) float
        Node positions [m].
    hinges : (H, 3) int
        Node triples ``(a, b, c)``.
    stiffness : (H,) float
        ``k_h = EI / lbar`` [N m], (K1).
    rest : (H, 2) float
        Rest lengths ``l0, l1`` of the segments ``(a, b)`` and ``(b, c)`` [m].
    """
    kappa = _bend(x, hinges, rest)
    return 0.5 * stiffness * np.einsum("ij,ij->i", kappa, kappa)


def hinge_force(x: FloatArray, v: FloatArray, hinges: NDArray[np.int64], stiffness: FloatArray,
                tau: FloatArray, rest: FloatArray) -> FloatArray:
    """Force of the hinges on every node [N], (N, 3): (K3) with the damping of (K4).

    ``v`` (N, 3): node velocities [m/s]; ``tau`` (H,): retardation time [s]; the other
    arguments as :func:`hinge_energy`.
    """
    kappa, rate = _bend(x, hinges, rest), _bend(v, hinges, rest)
    size2 = np.einsum("ij,ij->i", kappa, kappa)
    damped = np.where(size2 > STRAIGHT, tau * np.einsum("ij,ij->i", kappa, rate)
                      / np.where(size2 > STRAIGHT, size2, 1.0), 0.0)
    g = (stiffness * (1.0 + damped))[:, None] * kappa                     # k_h (1 + ...) kappa
    i0, i1 = 1.0 / rest[:, :1], 1.0 / rest[:, 1:]
    f = np.stack([-i0 * g, (i0 + i1) * g, -i1 * g], axis=1)               # (H, 3 nodes, 3)
    out = np.zeros_like(x)
    np.add.at(out, hinges.ravel(), f.reshape(-1, 3))
    return out


def hinge_frequency(hinges: NDArray[np.int64], stiffness: FloatArray, rest: FloatArray,
                    inv_mass: FloatArray) -> FloatArray:
    """Frequency ``omega_h`` [rad/s] of every hinge with the nodal masses, (K5): the hinge's
    stiffness is constant, so this holds in every configuration.

    ``rest`` (H, 2): rest lengths ``l0, l1`` [m]; ``inv_mass`` (N,): 1 / m [1/kg], 0 when
    supported.
    """
    l0, l1 = rest[:, 0], rest[:, 1]
    a, b, c = hinges.T
    return np.sqrt(stiffness * (inv_mass[a] / l0**2 + inv_mass[b] * (1.0 / l0 + 1.0 / l1) ** 2
                                + inv_mass[c] / l1**2))
