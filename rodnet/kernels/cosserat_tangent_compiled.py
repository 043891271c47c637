"""Compiled assembly of the Cosserat element tangents from given kinematics and stresses.

The same equations as :func:`rodnet.kernels.cosserat_tangent.tangents` (``elements/cosserat/
FORMULATION.md`` §Linearisation, §Tangent), written per element: the NumPy path spends most of its
time on many small (n, 3, 3) operations, which a loop keeps in cache. The loop itself is
:func:`rodnet.kernels.cosserat_compiled.tangents_kernel`, which
:func:`rodnet.kernels.cosserat_compiled.internal_force_and_tangents` runs right after the force
loop; both live in that module.
"""

from __future__ import annotations

import numpy as np

from rodnet.kernels.cosserat_compiled import tangents_kernel
from rodnet.kernels.cosserat_strain import midpoint_coefficient
from rodnet.kernels.so3 import FloatArray, dexp_inv_coefficient


def tangents(
    # Kinematics in:
    psi: FloatArray, R_m: FloatArray, g: FloatArray,
    # Constitutive state in:
    stress: FloatArray, modulus: FloatArray, viscous_modulus: FloatArray,
    # State and model in:
    velocity9: FloatArray, rest_length: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """Stiffness and damping tangents (n, 12, 12); arguments as in the NumPy path."""
    n = psi.shape[0]
    phi = np.linalg.norm(psi, axis=1)
    coefficients = np.stack([*midpoint_coefficient(phi), *dexp_inv_coefficient(phi)], axis=1)
    stiffness_out, damping_out = np.empty((n, 12, 12)), np.empty((n, 12, 12))
    constitutive = np.concatenate([stress, modulus, viscous_modulus], axis=1)
    # contiguous inputs keep to one compiled specialisation
    tangents_kernel(np.ascontiguousarray(psi), np.ascontiguousarray(R_m), np.ascontiguousarray(g),
                     coefficients, constitutive, np.ascontiguousarray(velocity9), 1.0 / rest_length,
                     0.0, stiffness_out, damping_out)
    return stiffness_out, damping_out
