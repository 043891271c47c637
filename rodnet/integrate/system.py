"""What an implicit integrator needs to know about a mechanical model, and nothing more.

The equations of motion are ``M dv/dt + g(q, v, t) = 0`` on the configuration space of the model:
``q`` is opaque to the integrator (positions, unit quaternions ...), ``v`` is a vector of
``n_dof`` generalised velocities (translational velocities and body-frame angular velocities),
``M`` is constant and diagonal (lumped masses and body-frame rotary inertias), and the
configuration moves by ``retract(q, dq)`` (the exponential map on rotations).
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


class System(Protocol):
    """A model as the integrators see it."""

    n_dof: int
    dof_mass: FloatArray
    """(n_dof,) diagonal of M [kg, kg m^2]."""
    force_scale: float
    """A characteristic internal force [N] (e.g. the largest axial stiffness EA): Newton's
    tolerance is relative to the larger of the step's forces and 1 % of this."""
    length_scale: float
    """A characteristic size of the model [m] (Newton's position tolerance is relative to it)."""
    free: NDArray[np.bool_]
    """(n_dof,) DOFs that move; the others are supported and keep zero velocity."""

    def generalized_force(self, q: Any, v: FloatArray, t: float, load_factor: float = 1.0) -> FloatArray:
        """``g(q, v, t)`` (n_dof,): internal, gyroscopic and damping forces minus external ones."""
        ...

    def tangents(self, q: Any, v: FloatArray, t: float, load_factor: float = 1.0,
                 ) -> tuple[FloatArray, sp.csr_matrix, sp.csr_matrix]:
        """``g`` (n_dof,) and, on the free DOFs, ``K = dg/dq`` and ``C = dg/dv`` (n_free, n_free)."""
        ...

    def retract(self, q: Any, dq: FloatArray) -> Any:
        """The configuration ``q`` moved by the increment ``dq`` (n_dof,)."""
        ...

    def tangent_operator(self, dq: FloatArray) -> sp.csr_matrix:
        """``T(dq)`` on the free DOFs: ``retract(q, dq + e) ~ retract(retract(q, dq), T(dq) e)``."""
        ...

    def active_set(self, q: Any, v: FloatArray) -> int:
        """A fingerprint of the non-smooth state (taut segments, contacts): when it changes,
        a reused factorisation is refreshed."""
        ...

    def rotation_dofs(self) -> NDArray[np.int64]:
        """Indices of the rotational DOFs (their Newton increments are capped)."""
        ...
