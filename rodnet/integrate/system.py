"""What an integrator needs to know about a mechanical system, and nothing more.

The equations of motion are ``M dv/dt + g(q, v, t) = 0`` on the configuration space of the
system: ``q`` is a :class:`rodnet.state.Configuration` (node positions and rotation-node
quaternions), ``v`` a vector of ``n_dof`` generalized velocities (translational velocities, then
body-frame angular velocities), ``M`` is constant and diagonal (lumped masses and body-frame
rotary inertias), and the configuration moves by ``retract(q, dq)`` (the exponential map on
rotations). Integrators see a system only through this protocol: they import no model, contact
term or scene configuration, so every thread model and every integrator combine.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from rodnet.kernels.explicit import ExplicitProblem, StepControl
from rodnet.state import AcceptedStep, Configuration, Linearization, State, StepRate

FloatArray = NDArray[np.float64]
IterationMatrix = object
"""Newton's iteration matrix in the storage its LU takes (:mod:`rodnet.assembly`)."""


class System(Protocol):
    """A model (with its contact terms) as the integrators see it."""

    n_dof: int
    dof_mass: FloatArray
    """(n_dof,) diagonal of M [kg, kg m^2]."""
    force_scale: float
    """A characteristic internal force [N] (e.g. the largest axial stiffness EA): Newton's
    tolerance is relative to the larger of the step's forces and 1 % of this."""
    length_scale: float
    """A characteristic size of the system [m] (Newton's position tolerance is relative to it)."""
    free: NDArray[np.bool_]
    """(n_dof,) DOFs that move; the others are supported and keep zero velocity."""

    # --- implicit integrators and statics ------------------------------------------------

    def generalized_force(self, q: Configuration, v: FloatArray, t: float,
                          load_factor: float = 1.0, rate: StepRate | None = None) -> FloatArray:
        """``g(q, v, t)`` (n_dof,): internal, gyroscopic, damping and contact forces minus
        external ones (``load_factor`` scales gravity and loads, for static load stepping).
        With ``rate`` (from :meth:`step_rate`) the internal damping acts at the step's strain
        rates instead of those of ``v``."""
        ...

    def tangents(self, q: Configuration, v: FloatArray, t: float, load_factor: float = 1.0,
                 rate: StepRate | None = None, linearization: Linearization | None = None,
                 ) -> tuple[FloatArray, sp.csr_matrix, sp.csr_matrix]:
        """``g`` (n_dof,) and, on the free DOFs, ``K = dg/dq`` and ``C = dg/dv``
        (n_free, n_free)."""
        ...

    def iteration_matrix(self, q: Configuration, v: FloatArray, t: float, dq: FloatArray,
                         diagonal: FloatArray, a: float, b: float, load_factor: float = 1.0,
                         rate: StepRate | None = None,
                         linearization: Linearization | None = None,
                         ) -> tuple[FloatArray, IterationMatrix]:
        """``g`` and Newton's matrix ``diag(diagonal) + a C + b K T(dq)`` on the free DOFs
        (``K`` and ``C`` as ``linearization`` says)."""
        ...

    def strains(self, q: Configuration, v: FloatArray) -> tuple[object, object]:
        """The strains the internal damping acts on and their rates (a model's own arrays,
        combined linearly by multistep schemes into a :class:`~rodnet.state.StepRate`)."""
        ...

    def step_rate(self, q: Configuration, v: FloatArray, h_bar: float) -> StepRate:
        """The strain rates of a step whose end configuration is ``q o exp(h_bar (v1 - v))``:
        damping then has a potential over the step."""
        ...

    def potential(self, q: Configuration, t: float, load_factor: float = 1.0,
                  rate: StepRate | None = None) -> float | None:
        """A function whose gradient is ``g`` with ``rate`` (exactly when
        :attr:`potential_exact`, else up to velocity terms such as gyroscopic forces, contact
        and friction) [J]; None when the system has none."""
        ...

    potential_exact: bool
    """Whether ``g`` with a step rate is exactly the gradient of :meth:`potential` (so the
    system has one)."""

    secant_forces: bool
    """Whether ``g`` takes the midpoint rule's secant form when its :class:`StepRate` has a
    ``start`` (then ``g`` is not the gradient of :meth:`potential`)."""

    def mechanical_energy(self, q: Configuration, v: FloatArray, t: float) -> float | None:
        """Kinetic plus potential energy (internal, external at time ``t``, contact springs)
        [J]; None where the forces have no potential."""
        ...

    def retract(self, q: Configuration, dq: FloatArray) -> Configuration:
        """The configuration ``q`` moved by the increment ``dq`` (n_dof,)."""
        ...

    def times_tangent_operator(self, K: sp.csr_matrix, dq: FloatArray) -> sp.csr_matrix:
        """``K T(dq)``, ``T`` the tangent operator on the free DOFs:
        ``retract(q, dq + e) ~ retract(retract(q, dq), T(dq) e)``."""
        ...

    def active_set(self, q: Configuration, v: FloatArray) -> int:
        """A fingerprint of the non-smooth state (taut segments, contacts): when it changes,
        a reused factorisation is refreshed."""
        ...

    def error_norm(self, change: FloatArray) -> float:
        """The size of a change of the velocities (n_dof,) as a speed [m/s], the norm of the
        local error estimate: for threads the root-mean-square over the nodes of their
        translations (a net's accuracy is that of its whole shape, and a norm of the largest
        would let every thread snapping taut somewhere shrink the step of all); for rigid
        bodies the largest speed change of a point on their bounding sphere. The larger of
        the two."""
        ...

    def step_limit(self, v: FloatArray) -> float:
        """The longest step [s] an adaptive run may take at the velocities ``v`` (n_dof,)
        besides its error control: what the free bodies' nutation allows (inf without one)."""
        ...

    def rotation_dofs(self) -> NDArray[np.int64]:
        """Indices of the rotational DOFs (their Newton increments are capped)."""
        ...

    def body_dof_groups(self) -> NDArray[np.int64]:
        """(G, 3) DOF indices of the free bodies' unknowns, one row per body's translation and
        per body's rotation; (0, 3) without free bodies."""
        ...

    def step_travel(self, q_old: Configuration, q_new: Configuration) -> float:
        """How far points near a rigid body moved over a step, as a multiple of their travel
        limit (above 1 the step is retried shorter); 0 without bodies."""
        ...

    def accepted_step(self, q_start: Configuration, v_start: FloatArray, q: Configuration,
                      v: FloatArray, t_start: float, t_end: float) -> AcceptedStep:
        """What an accepted step from ``t_start`` to ``t_end`` [s], from ``q_start``,
        ``v_start`` to ``q``, ``v``, adds to the run's records: the work friction dissipated
        over it [J] (0 without bodies), the largest tension and the contact totals at its end,
        and what the dead forces' time factors changed of their potential over it [J]
        (:func:`rodnet.kernels.schedule.factor_energy`)."""
        ...

    # --- explicit integrator and RK45 --------------------------------------------------------

    def explicit_problem(self) -> tuple[ExplicitProblem, StepControl | None]:
        """The arrays of the compiled explicit loop (RK45 evaluates its forces), and the step
        control of an explicit run (None when the system was not prepared for one)."""
        ...


class FrameSink(Protocol):
    """Receives every saved frame: time [s] and the state."""

    def __call__(self, time: float, state: State) -> None: ...
