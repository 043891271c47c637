"""A thread model and its contact term as one system: what the integrators advance.

:class:`ThreadSystem` implements :class:`rodnet.integrate.system.System` for any thread model
(lumped segments, Kirchhoff threads, Cosserat rods, or a new one) that has the
:class:`ThreadModel` methods, and adds the contact term of a scene with bodies
(:class:`rodnet.contact.term.ContactTerm`) as one more force: forces add, tangent blocks are one
more group of the sparsity pattern, fingerprints of the non-smooth state combine. The
integrators see only this class; the registry (:mod:`rodnet.models.registry`) composes it.

Newton's iteration matrix ``diag(m) + a C + b K T(dq)`` is assembled in one pass over every
group's blocks (:meth:`rodnet.assembly.SparsityPattern.iteration_matrix`); ``T(dq)`` is the
identity on translations and ``dexp`` of the increment on rotation nodes whose three rotations
are free.

In an implicit run with free rigid bodies (``moving_bodies``) every free body adds six unknowns
after the model's: its centre and velocity, then its rotation and angular velocity about its
principal axes (so that its inertia is diagonal, like a rotation node's); the contact term
couples them to the threads (``elements/contact/FORMULATION.md`` section 9).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Any, Protocol

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from rodnet.assembly import IterationMatrix, SparsityPattern
from rodnet.contact.forces import contact_state
from rodnet.contact.term import ContactTerm
from rodnet.kernels import so3, so3_compiled
from rodnet.kernels.contact_compiled import no_contact
from rodnet.kernels.cosserat_compiled import RodElements
from rodnet.kernels.explicit import BodyMass, ExplicitProblem, Loads, Nodes, Rotations, StepControl
from rodnet.kernels.hinge import Hinges
from rodnet.kernels.schedule import factor_energy
from rodnet.kernels.segments import Segments
from rodnet.state import AcceptedStep, BodyMotion, Configuration, Linearization, State, StepRate
from rodnet.topology import Structure

FloatArray = NDArray[np.float64]

SMALL_ROTATION = 1e-4
"""Below this increment [rad] ``K T(dq)`` is taken as ``K``: ``T = I - hat(dq) / 2 + O(dq^2)``
changes Newton's matrix by less than 5e-5 relative (its convergence rate, never its solution)."""


class ThreadModel(Protocol):
    """What a thread model gives its system (see :mod:`rodnet.models.lumped` and
    :mod:`rodnet.models.cosserat.model` for two of them)."""

    structure: Structure
    n_nodes: int
    n_rot: int
    n_dof: int
    dof_mass: FloatArray
    node_mass: FloatArray
    free: NDArray[np.bool_]
    force_scale: float
    length_scale: float
    groups: list[NDArray[np.int64]]
    """DOF indices of the blocks of :meth:`forces`, one (E_g, k_g) array per group."""

    def forces(self, q: Configuration, v: FloatArray, t: float, load_factor: float,
               need_matrices: bool, rate: StepRate | None = None,
               linearization: Linearization | None = None,
               ) -> tuple[FloatArray, list[FloatArray], list[FloatArray]]:
        """``g`` (n_dof,) and, when asked, the blocks of ``K`` and ``C``, one per group; with
        ``rate``, damping acts at the step's strain rates (:class:`~rodnet.state.StepRate`);
        ``linearization`` says how the blocks depart from the exact tangent."""
        ...

    def strains(self, q: Configuration, v: FloatArray) -> tuple[Any, Any]:
        """The strains the damping acts on and their rates at ``q``, ``v``."""
        ...

    def potential(self, q: Configuration, t: float, load_factor: float,
                  rate: StepRate | None) -> float:
        """The function whose gradient is ``g`` with ``rate`` (up to the terms
        :attr:`potential_exact` says are left out) [J]."""
        ...

    potential_exact: bool
    """Whether the gradient of :meth:`potential` is exactly ``g`` with a rate (no term that
    depends on the velocities otherwise, such as gyroscopic forces)."""

    def retract(self, q: Configuration, dq: FloatArray) -> Configuration: ...

    def active_set(self, q: Configuration, v: FloatArray) -> bytes: ...

    def rotation_dofs(self) -> NDArray[np.int64]: ...

    def explicit_terms(self) -> tuple[Nodes, Rotations, Loads, Segments, Hinges, RodElements]: ...

    def frame_arrays(self, q: Configuration, v: FloatArray) -> dict[str, Any]: ...

    def axial_force(self, q: Configuration, v: FloatArray) -> FloatArray:
        """The frames' ``tension`` [N] of every element or segment (E,)."""
        ...

    def energy(self, q: Configuration, v: FloatArray, t: float) -> dict[str, float]: ...

    def check_frame(self, t: float, frame: dict[str, Any]) -> None: ...


@dataclass(frozen=True, eq=False)
class ThreadSystem:
    """A thread model with its contact term (None without bodies) and, for explicit runs, the
    step control of the compiled loop.

    Attributes
    ----------
    model : ThreadModel
    contact : ContactTerm or None
    control : StepControl or None
        Set by the registry for an explicit run.
    moving_bodies : bool
        The free bodies are unknowns of the system (implicit runs); otherwise they are held at
        their start pose here and the explicit loop moves them.
    """

    model: Any
    contact: ContactTerm | None = None
    control: StepControl | None = field(default=None)
    moving_bodies: bool = False

    # --- sizes and scales ----------------------------------------------------------------

    @cached_property
    def n_moving(self) -> int:
        """F, the free bodies that are unknowns of the system."""
        return len(self.contact.moving) if self.moving_bodies and self.contact else 0

    @property
    def n_dof(self) -> int:
        return self.model.n_dof + 6 * self.n_moving

    @cached_property
    def dof_mass(self) -> FloatArray:
        if not self.n_moving:
            return self.model.dof_mass
        _, J = self.contact.principal
        return np.concatenate([self.model.dof_mass, np.repeat(self.contact.moving_mass, 3),
                               J.ravel()])

    @cached_property
    def _body_dofs(self) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """(F, 3) translational and (F, 3) rotational DOFs of the free bodies."""
        n, f = self.model.n_dof, self.n_moving
        return (n + np.arange(3 * f).reshape(-1, 3), n + 3 * f + np.arange(3 * f).reshape(-1, 3))

    def _split(self, v: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """The model's velocities and the free bodies' ``V`` (F, 3) and ``W`` (F, 3)."""
        trans, rot = self._body_dofs
        return v[:self.model.n_dof], v[trans], v[rot]

    def _motion(self, q: Configuration, v: FloatArray) -> BodyMotion:
        """The bodies' motion at ``q``, ``v`` (their start motion where they are not unknowns)."""
        if not self.n_moving:
            return self._start  # type: ignore[return-value]
        _, V, W = self._split(v)
        return self.contact.motion(q.body_x, q.body_quat, V, W)  # type: ignore[union-attr]

    @property
    def n_nodes(self) -> int:
        """Position nodes N."""
        return self.model.n_nodes

    @property
    def n_rot(self) -> int:
        """Rotation nodes R (0 without rotations)."""
        return self.model.n_rot

    @cached_property
    def free(self) -> NDArray[np.bool_]:
        return np.concatenate([self.model.free, np.ones(6 * self.n_moving, bool)])

    @property
    def force_scale(self) -> float:
        return self.model.force_scale

    @property
    def length_scale(self) -> float:
        return self.model.length_scale

    @property
    def structure(self) -> Structure:
        return self.model.structure

    @property
    def node_mass(self) -> FloatArray:
        """(N,) translational node masses [kg]."""
        return self.model.node_mass

    def parallel_work(self) -> int:
        """Work items of the compiled parallel loops (rod elements): what the thread count is
        chosen by (:func:`rodnet.kernels.threads.use_threads`)."""
        return int(self.model.explicit_terms()[5].rest_length.shape[0]) if self.model.n_rot else 0

    @cached_property
    def _start(self) -> BodyMotion | None:
        """The bodies' pose in the implicit system: held fixed."""
        return None if self.contact is None else self.contact.start_motion()

    def initial_state(self, q0: Configuration, v0: FloatArray) -> State:
        """The state at t = 0: ``q0``, ``v0`` and the bodies' start motion (with moving bodies
        also as unknowns in the configuration and velocities)."""
        v0 = np.array(v0, dtype=float)
        if self.n_moving:
            body_x, body_quat, V, W = self.contact.moving_unknowns(self._start)  # type: ignore
            q0 = Configuration(q0.x, q0.quat, body_x, body_quat)
            v0 = np.concatenate([v0, V.ravel(), W.ravel()])
        return State(q0, v0, self._start.copy() if self._start else None)

    # --- the System protocol: implicit integrators and statics ---------------------------

    @cached_property
    def _pattern(self) -> SparsityPattern:
        groups = list(self.model.groups) + ([self.contact.dofs] if self.contact else [])
        if self.n_moving:
            trans, rot = self._body_dofs
            n_seg = len(self.contact.dofs)  # type: ignore[union-attr]
            groups += [np.hstack([self.contact.dofs, np.tile(np.r_[trans[k], rot[k]],  # type: ignore
                                                             (n_seg, 1))])
                       for k in range(self.n_moving)]
            groups.append(np.hstack([trans, rot]))
        return SparsityPattern(groups, self.n_dof, self.free)

    def _forces(self, q: Configuration, v: FloatArray, t: float, load_factor: float,
                need_matrices: bool, rate: StepRate | None = None,
                linearization: Linearization | None = None,
                ) -> tuple[FloatArray, list[FloatArray], list[FloatArray]]:
        v_model = v[:self.model.n_dof]
        if self.model_has_strains:
            g, K_blocks, C_blocks = self.model.forces(q, v_model, t, load_factor, need_matrices,
                                                      rate, linearization)
        else:  # a model without strains: no step rates, exact tangents only
            g, K_blocks, C_blocks = self.model.forces(q, v_model, t, load_factor, need_matrices)
        if self.contact is None:
            return g, K_blocks, C_blocks
        if self.n_moving:
            return self._coupled_forces(q, v, load_factor, g, K_blocks, C_blocks, need_matrices)
        n3 = 3 * self.model.n_nodes
        velocities = v[:n3].reshape(-1, 3)
        if not need_matrices:
            g[:n3] -= self.contact.force(q.x, velocities, self._start).ravel()
            return g, K_blocks, C_blocks
        f, d_x, d_v = self.contact.tangents(q.x, velocities, self._start)
        g[:n3] -= f.ravel()
        return g, [*K_blocks, -d_x], [*C_blocks, -d_v]

    def _coupled_forces(self, q: Configuration, v: FloatArray, load_factor: float,
                        g_model: FloatArray, K_blocks: list[FloatArray],
                        C_blocks: list[FloatArray], need_matrices: bool,
                        ) -> tuple[FloatArray, list[FloatArray], list[FloatArray]]:
        """The model's forces with contact and the free bodies' own equations added: gravity,
        the reactions of contact and the gyroscopic moment ``W x J W`` (C block
        ``hat(W) J - hat(J W)``), (B7)-(B9)."""
        contact = self.contact
        assert contact is not None
        n3, f = 3 * self.model.n_nodes, self.n_moving
        motion = self._motion(q, v)
        frames = contact.frames(q.body_quat)
        ct = contact.coupled(q.x, v[:n3].reshape(-1, 3), motion, frames, need_matrices)
        g = np.concatenate([g_model, np.zeros(6 * f)])
        g[:n3] -= ct.force.ravel()
        trans, rot = self._body_dofs
        moving = contact.moving
        _, J = contact.principal
        _, _, W = self._split(v)
        JW = J * W
        gravity = np.asarray(contact.bodies.gravity, dtype=float)
        g[trans] = ct.body_force[moving] - load_factor * contact.moving_mass[:, None] * gravity
        g[rot] = np.einsum("fji,fj->fi", frames[moving], ct.body_moment[moving]) \
            + np.cross(W, JW)
        if not need_matrices:
            return g, K_blocks, C_blocks
        own_C = np.zeros((f, 6, 6))
        own_C[:, 3:, 3:] = so3.hat(W) * J[:, None, :] - so3.hat(JW)
        K_blocks = [*K_blocks, -ct.d_position, *(ct.coupled_position[b] for b in moving),
                    np.zeros((f, 6, 6))]
        C_blocks = [*C_blocks, -ct.d_velocity, *(ct.coupled_velocity[b] for b in moving), own_C]
        return g, K_blocks, C_blocks

    def generalized_force(self, q: Configuration, v: FloatArray, t: float,
                          load_factor: float = 1.0, rate: StepRate | None = None) -> FloatArray:
        return self._forces(q, v, t, load_factor, False, rate)[0]

    def tangents(self, q: Configuration, v: FloatArray, t: float, load_factor: float = 1.0,
                 rate: StepRate | None = None, linearization: Linearization | None = None,
                 ) -> tuple[FloatArray, sp.csr_matrix, sp.csr_matrix]:
        g, K_blocks, C_blocks = self._forces(q, v, t, load_factor, True, rate, linearization)
        return g, self._pattern.matrix(K_blocks), self._pattern.matrix(C_blocks)

    def iteration_matrix(self, q: Configuration, v: FloatArray, t: float, dq: FloatArray,
                         diagonal: FloatArray, a: float, b: float, load_factor: float = 1.0,
                         rate: StepRate | None = None,
                         linearization: Linearization | None = None,
                         ) -> tuple[FloatArray, IterationMatrix]:
        """``g`` (n_dof,) and ``diag(diagonal) + a C + b K T(dq)`` on the free DOFs, in the
        storage its LU takes (band, dense or CSR: :meth:`SparsityPattern.iteration_matrix`)."""
        if linearization is not None and linearization.convex and b > 0.0:
            per_dof = np.zeros(len(self.free))   # the masses' term, in the blocks' units
            per_dof[self.free] = diagonal / b
            linearization = replace(linearization, inertia=per_dof[:self.model.n_dof])
        g, K_blocks, C_blocks = self._forces(q, v, t, load_factor, True, rate, linearization)
        return g, self._pattern.iteration_matrix(diagonal, a, C_blocks, b, K_blocks,
                                                 self._triple_transforms(dq))

    def retract(self, q: Configuration, dq: FloatArray) -> Configuration:
        moved = self.model.retract(q, dq[:self.model.n_dof])
        if not self.n_moving:
            return moved
        _, dc, dphi = self._split(dq)
        return Configuration(moved.x, moved.quat, q.body_x + dc,
                             so3.retract(q.body_quat, dphi))

    @cached_property
    def model_has_strains(self) -> bool:
        """Whether the model reports strains (:meth:`ThreadModel.strains`) and so takes step
        rates and linearizations in :meth:`ThreadModel.forces`; a model without them (such as
        a plain spring chain) gets exact tangents and damping at the velocities' rates."""
        return hasattr(self.model, "strains")

    def strains(self, q: Configuration, v: FloatArray) -> tuple[Any, Any]:
        """The model's strains and their rates (:meth:`ThreadModel.strains`); ``(None, None)``
        for a model without them."""
        if not self.model_has_strains:
            return None, None
        return self.model.strains(q, v[:self.model.n_dof])

    def step_rate(self, q: Configuration, v: FloatArray, h_bar: float) -> StepRate | None:
        """The :class:`~rodnet.state.StepRate` of a step that moves the configuration as
        ``q* o exp(h_bar (v1 - v*))`` from ``q* = q``, ``v* = v``: reference strains
        ``e(q) - h_bar de/dt(q, v)``, ``inv_h = 1 / h_bar``; None without step rates."""
        strain, rate = self.strains(q, v)
        return None if strain is None else StepRate(strain - h_bar * rate, 1.0 / h_bar)

    def potential(self, q: Configuration, t: float, load_factor: float = 1.0,
                  rate: StepRate | None = None) -> float | None:
        """The model's potential (:meth:`ThreadModel.potential`) [J]; None for a model without
        one. Contact adds no term (:attr:`potential_exact` is then False)."""
        if not hasattr(self.model, "potential"):
            return None
        return self.model.potential(q, t, load_factor, rate)

    def mechanical_energy(self, q: Configuration, v: FloatArray, t: float) -> float | None:
        """Kinetic energy plus the potential of the internal and external forces at time ``t``
        and the energy in the contact springs [J]; None where the forces have no potential
        (dead moments, a model without one)."""
        if not bool(getattr(self.model, "potential_exact", False)):
            return None
        stored = self.potential(q, t)
        if stored is None:
            return None
        energy = 0.5 * float(np.einsum("i,i,i", self.dof_mass, v, v)) + stored
        if self.contact is not None:  # the penalty springs and, when they move, the bodies' weight
            bodies = self.contact.energy(q.x, self._motion(q, v))
            energy += bodies["contact"] + (bodies["potential"] if self.n_moving else 0.0)
        return energy

    @property
    def potential_exact(self) -> bool:
        """Whether ``g`` with a step rate is exactly the gradient of :meth:`potential`."""
        return self.contact is None and bool(getattr(self.model, "potential_exact", False))

    def static_potential(self, q: Configuration, t: float, load_factor: float) -> float | None:
        """The potential whose gradient is a static run's ``g`` (no velocities, so no damping
        and no friction): the model's (:meth:`potential`) plus the energy in the contact's
        penalty springs against fixed bodies (N4) [J]; None where there is none (dead moments,
        a model without one, bodies that move)."""
        if not bool(getattr(self.model, "potential_exact", False)) or self.n_moving:
            return None
        stored = self.potential(q, t, load_factor)
        if stored is None or self.contact is None:
            return stored
        return stored + self.contact.energy(q.x, self._start)["contact"]  # type: ignore[arg-type]

    @property
    def secant_forces(self) -> bool:
        """Whether the model takes the midpoint rule's secant form (the contact term does not:
        its penalty forces act at the midpoint)."""
        return bool(getattr(self.model, "secant_forces", False))

    def times_tangent_operator(self, K: sp.csr_matrix, dq: FloatArray) -> sp.csr_matrix:
        """``K T(dq)`` without forming ``T`` (the same pattern as ``K``)."""
        if not len(self._free_rotation_nodes):
            return K
        rot = dq[self._free_rotation_dofs]
        if np.abs(rot).max() < SMALL_ROTATION:
            return K
        return self._pattern.right_multiply_blocks(K, self._free_rotation_triples,
                                                   so3_compiled.dexp(rot))

    def _triple_transforms(self, dq: FloatArray) -> FloatArray:
        """(n_dof / 3, 3, 3) blocks of ``T(dq)`` per DOF triple: ``dexp`` of the increment on
        rotation nodes whose three rotations are free, the identity elsewhere."""
        transforms = self._identity_triples.copy()
        if len(self._free_rotation_nodes):
            transforms[self._free_rotation_dofs[:, 0] // 3] = so3_compiled.dexp(
                np.ascontiguousarray(dq[self._free_rotation_dofs]))
        return transforms

    @cached_property
    def _identity_triples(self) -> FloatArray:
        """(n_dof / 3, 3, 3) identity blocks: :meth:`_triple_transforms` without rotations."""
        return np.tile(np.eye(3), (self.n_dof // 3, 1, 1))

    @cached_property
    def _free_rotation_nodes(self) -> NDArray[np.int64]:
        """Rotation nodes (R,) whose three rotations are all free."""
        return np.flatnonzero(self.free[self.rotation_dofs()].reshape(-1, 3).all(axis=1))

    @cached_property
    def _free_rotation_dofs(self) -> NDArray[np.int64]:
        """(F, 3) DOFs of the rotation nodes whose three rotations are free."""
        return self.rotation_dofs().reshape(-1, 3)[self._free_rotation_nodes]

    @cached_property
    def _free_rotation_triples(self) -> NDArray[np.int64]:
        return self._pattern.reduced_index[self._free_rotation_dofs]

    def active_set(self, q: Configuration, v: FloatArray) -> int:
        threads = self.model.active_set(q, v[:self.model.n_dof])
        if self.contact is None:
            return hash(threads)
        n3 = 3 * self.model.n_nodes
        return hash((threads, self.contact.active_set(q.x, v[:n3].reshape(-1, 3),
                                                      self._motion(q, v))))

    @cached_property
    def _thread_translations(self) -> NDArray[np.int64]:
        """The model's free translational DOFs."""
        translation = self.model.free.copy()
        translation[self.model.rotation_dofs()] = False
        return np.flatnonzero(translation)

    def error_norm(self, change: FloatArray) -> float:
        c = change[self._thread_translations]
        threads = float(np.sqrt(3.0 * np.mean(c * c))) if c.size else 0.0
        if not self.n_moving:
            return threads
        trans, rot = self._body_dofs
        radius = self.contact.bodies.bound_radius[self.contact.moving]  # type: ignore[union-attr]
        bodies = np.sqrt(np.sum(change[trans] ** 2, axis=1)
                         + radius**2 * np.sum(change[rot] ** 2, axis=1))
        return max(threads, float(bodies.max()))

    def step_limit(self, v: FloatArray) -> float:
        """A free body turning at ``W`` nutates, seen from its own axes, at up to ``f |W|``
        (``f`` from its principal moments, :func:`nutation_factor`): a motion the dissipative
        schemes damp (turning its angular momentum) where their error estimate, measured on the
        damped solution, does not see it. The step is held to :data:`NUTATION_TURN` of it."""
        if not self.n_moving:
            return math.inf
        _, rot = self._body_dofs
        rate = self._nutation_factors * np.linalg.norm(v[rot], axis=1)
        fastest = float(rate.max(initial=0.0))
        return NUTATION_TURN / fastest if fastest > 0.0 else math.inf

    @cached_property
    def _nutation_factors(self) -> FloatArray:
        moments = self.contact.principal[1]  # type: ignore[union-attr]
        return np.array([nutation_factor(J) for J in moments])

    def rotation_dofs(self) -> NDArray[np.int64]:
        if not self.n_moving:
            return self.model.rotation_dofs()
        return np.concatenate([self.model.rotation_dofs(), self._body_dofs[1].ravel()])

    def body_dof_groups(self) -> NDArray[np.int64]:
        if not self.n_moving:
            return np.zeros((0, 3), np.int64)
        return np.vstack(self._body_dofs)

    def step_travel(self, q_old: Configuration, q_new: Configuration) -> float:
        """Travel of thread points near a body relative to it (E3)."""
        if self.contact is None:
            return 0.0
        if not self.n_moving:
            return self.contact.step_travel(q_old.x, q_new.x, self._start)
        zero = np.zeros((self.n_moving, 3))
        old = self.contact.motion(q_old.body_x, q_old.body_quat, zero, zero)
        new = self.contact.motion(q_new.body_x, q_new.body_quat, zero, zero)
        return self.contact.step_travel(q_old.x, q_new.x, new, old)

    def accepted_step(self, q_start: Configuration, v_start: FloatArray, q: Configuration,
                      v: FloatArray, t_start: float, t_end: float) -> AcceptedStep:
        n3 = 3 * self.model.n_nodes
        velocities = v[:n3].reshape(-1, 3)
        tension = float(self.model.axial_force(q, v[:self.model.n_dof]).max(initial=0.0))
        loads = self._loads
        drift = 0.0 if not len(loads.nodes) else factor_energy(
            loads.schedule, loads.force, t_start, t_end, q_start.x[loads.nodes],
            v_start[:n3].reshape(-1, 3)[loads.nodes], q.x[loads.nodes], velocities[loads.nodes])
        if self.contact is None:
            return AcceptedStep(0.0, tension, 0.0, 0, 0.0, drift)
        state = contact_state(self.contact.bodies, self._motion(q, v), q.x, velocities)
        return AcceptedStep((t_end - t_start) * state.friction_power, tension, state.total_force,
                            state.count, state.sunk, drift)

    @cached_property
    def _loads(self) -> Loads:
        """The model's dead loads as the explicit loop takes them."""
        return self.model.explicit_terms()[2]

    # --- the System protocol: the explicit loop ------------------------------------------

    def explicit_problem(self) -> tuple[ExplicitProblem, StepControl | None]:
        """The compiled loop's arrays: the model's terms, the contact term's (none without
        bodies), and the step control the registry chose for an explicit run (else None)."""
        return self._explicit_problem, self.control

    @cached_property
    def _explicit_problem(self) -> ExplicitProblem:
        nodes, rotations, loads, segments, hinges, rods = self.model.explicit_terms()
        if self.contact is None:
            z = np.zeros
            contact, mass = no_contact(), BodyMass(z(0), z((0, 3, 3)), z((0, 3, 3)), z(3))
        else:
            contact, mass = self.contact.kernel_data, self.contact.body_mass()
        return ExplicitProblem(nodes, rotations, loads, segments, hinges, rods, contact, mass)

    # --- output --------------------------------------------------------------------------

    def frame(self, t: float, state: State) -> dict[str, Any]:
        """What a saved frame holds: the model's arrays, every rotation node's quaternion and
        body-frame angular velocity (models with rotations), the kinetic, elastic and potential
        energy [J] and, with bodies, the energy in the penalty springs and the contact and body
        arrays of :meth:`ContactTerm.frame_arrays`."""
        if self.n_moving:  # the bodies' motion from the unknowns, for the frame and the state
            state.bodies = self._motion(state.q, state.v)
        frame = self.model.frame_arrays(state.q, state.v[:self.model.n_dof])
        if len(state.q.quat):   # the whole rotational state, for a later run to start from
            frame["rotation_node_quaternions"] = state.q.quat.copy()
            frame["rotation_node_spins"] = state.spin.copy()
        energy = self.energy(t, state)
        frame["kinetic_energy"], frame["elastic_energy"] = energy["kinetic"], energy["elastic"]
        frame["potential_energy"] = energy.get("potential", float("nan"))
        frame["load_factor_energy"] = state.load_factor_energy
        if "contact" in energy:
            frame["contact_energy"] = energy["contact"]
        if self.contact is not None and state.bodies is not None:
            frame.update(self.contact.frame_arrays(state.q.x, state.velocities, state.bodies,
                                                   state.friction_work, state.applied_to_bodies))
        return frame

    def support_reactions(self, q: Configuration, v: FloatArray, t: float, load_factor: float,
                          nodes: NDArray[np.int64]) -> FloatArray:
        """(S, 3) force [N] that the supports exert on each of the position ``nodes`` (S,):
        ``g`` (internal, damping and contact forces less the loads) at their fixed
        translations, where the node does not accelerate; zero along a free direction."""
        dofs = 3 * np.asarray(nodes)[:, None] + np.arange(3)
        reaction = self.generalized_force(q, v, t, load_factor)[dofs]
        reaction[self.free[dofs]] = 0.0
        return reaction

    def energy(self, t: float, state: State) -> dict[str, float]:
        """Kinetic, elastic (and, where the model reports it, external-load potential) energy
        [J]; with bodies also theirs and ``contact``, the energy in the penalty springs."""
        energy = self.model.energy(state.q, state.v[:self.model.n_dof], t)
        motion = self._motion(state.q, state.v) if self.n_moving else state.bodies
        if self.contact is not None and motion is not None:
            for key, value in self.contact.energy(state.q.x, motion).items():
                if key in energy or key == "contact":
                    energy[key] = energy.get(key, 0.0) + value
        return energy

    def check_frame(self, t: float, frame: dict[str, Any]) -> None:
        """The model's checks of a saved frame (raise :class:`rodnet.errors.SimulationFailed`)."""
        self.model.check_frame(t, frame)

    def surfaces(self) -> list[tuple[str, FloatArray, NDArray[np.int64]]]:
        """Body surfaces in their body frames, for the VTK series (none without bodies)."""
        return [] if self.contact is None else self.contact.surfaces()

    def summary(self, arrays: dict[str, Any]) -> dict[str, Any]:
        """What the system adds to ``summary.json`` (with bodies: the contact series)."""
        return {} if self.contact is None else self.contact.summary(arrays)


NUTATION_TURN = 0.05
"""The largest turn [rad] of a free body's nutation per step in adaptive implicit runs
(:meth:`ThreadSystem.step_limit`)."""


def nutation_factor(moments: FloatArray) -> float:
    """``f`` (at most 1) such that a torque-free body with the principal moments (3,) turning at
    ``W`` nutates, seen from its own axes, at no more than ``f |W|``: the largest
    ``sqrt(|(I_i - I_j)(I_i - I_k)| / (I_j I_k))`` over its principal moments, the frequency
    (or growth rate) of a small wobble about a spin about axis ``i`` per unit of spin (Euler's
    equations); 0 for a body whose moments are all equal. The moments obey ``I_i <= I_j +
    I_k``, so ``|I_i - I_j| <= I_k`` and ``f <= 1``."""
    out = 0.0
    for i in range(3):
        j, k = (i + 1) % 3, (i + 2) % 3
        out = max(out, float(np.sqrt(abs((moments[i] - moments[j]) * (moments[i] - moments[k]))
                                     / (moments[j] * moments[k]))))
    return out
