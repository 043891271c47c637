"""Rods of two-node Simo-Reissner elements: the model a :class:`~rodnet.models.system.ThreadSystem`
integrates.

Configuration (:class:`~rodnet.state.Configuration`): positions ``x`` (N, 3) and unit quaternions
``quat`` (R, 4) of the rotation nodes.
DOFs: ``3 N`` translations (global) then ``3 R`` rotations (body frame). Every element joins a
position node and a rotation node at each end (``pos_nodes``, ``rot_nodes``), so knots that share a
position but not a rotation (pinned knots) fit the same layout. Element physics:
``elements/cosserat/FORMULATION.md``; kernels :mod:`rodnet.kernels.cosserat`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from rodnet.assembly import assemble_vector
from rodnet.errors import SimulationFailed
from rodnet.kernels import explicit as kx
from rodnet.kernels import so3, so3_compiled
from rodnet.kernels.convex import convex_blocks
from rodnet.kernels.cosserat import (internal_force, internal_force_and_tangents, section_state,
                                     step_potential, strain_energy)
from rodnet.kernels.cosserat_compiled import (SERIES_ARGUMENTS, RodElements, element_pose,
                                              element_rotation, element_velocities,
                                              strains_and_rates, to_node_frames)
from rodnet.kernels.hinge import Hinges, no_hinges
from rodnet.kernels.schedule import LoadSchedule, factors
from rodnet.kernels.segments import Segments
from rodnet.kernels.tension import secant_strain
from rodnet.state import Configuration, Linearization, StepRate

FloatArray = NDArray[np.float64]

INVERTED_STRETCH = 1.5
"""Chord over rest length above which a rod element counts as inverted (a frame check)."""


@dataclass(frozen=True)
class CosseratModel:
    """Read-only arrays of a rod structure.

    Attributes
    ----------
    pos_nodes, rot_nodes : (E, 2) int
        Position and rotation node of each element end.
    rest_length : (E,) float
    reference_strain : (E, 6) float
        ``[Gamma0, K0]`` of the stress-free state.
    stiffness : (E, 6) float
        ``[EA, GA, GA, GJ, EI, EI]`` [N, N m^2].
    tau : (E,) float
        Kelvin-Voigt retardation time viscosity / E [s].
    node_mass : (N,) float, rotary_inertia : (R, 3) float
        Lumped mass [kg] and body-frame principal rotary inertia [kg m^2].
    free : (n_dof,) bool
    gravity : (3,) float
    load_nodes (L,) int, load_force (L, 3), load_moment (L, 3), load_schedule (their time factors)
        Dead loads: global force [N] at a position node, global-axis moment [N m] at the
        rotation node ``load_rot_nodes`` (L,).
    end_offset : (E, 2, 4) float or None
        Constant rotation from a rotation node's triad to the element end's material triad
        (``R_end = R_node Q``), for knots whose one rotation serves threads of several
        directions; None: every element end uses its rotation node's triad.
    """

    pos_nodes: NDArray[np.int64]
    rot_nodes: NDArray[np.int64]
    rest_length: FloatArray
    reference_strain: FloatArray
    stiffness: FloatArray
    tau: FloatArray
    node_mass: FloatArray
    rotary_inertia: FloatArray
    free: NDArray[np.bool_]
    gravity: FloatArray
    load_nodes: NDArray[np.int64]
    load_force: FloatArray
    load_moment: FloatArray
    load_schedule: LoadSchedule
    tension_only: bool
    kink_strain: float
    load_rot_nodes: NDArray[np.int64] | None = None
    end_offset: FloatArray | None = None
    size: float = 1.0

    # sizes are read many times per Newton iteration: computed once (the arrays never change)
    @cached_property
    def n_nodes(self) -> int:
        return len(self.node_mass)

    @cached_property
    def n_rot(self) -> int:
        return len(self.rotary_inertia)

    @cached_property
    def n_dof(self) -> int:
        return 3 * (self.n_nodes + self.n_rot)

    @property
    def dof_mass(self) -> FloatArray:
        """(n_dof,) diagonal of the mass matrix [kg, kg m^2] (read-only)."""
        cached = self.__dict__.get("_dof_mass_cache")
        if cached is None:
            cached = np.concatenate([np.repeat(self.node_mass, 3), self.rotary_inertia.ravel()])
            cached.setflags(write=False)
            object.__setattr__(self, "_dof_mass_cache", cached)
        return cached

    @property
    def length_scale(self) -> float:
        """Size of the structure [m]: the largest distance between two nodes at rest."""
        return self.size

    @property
    def force_scale(self) -> float:
        """The largest axial stiffness EA [N]."""
        cached = self.__dict__.get("_force_scale_cache")
        if cached is None:
            cached = float(self.stiffness[:, 0].max())
            object.__setattr__(self, "_force_scale_cache", cached)
        return cached

    @property
    def element_dofs(self) -> NDArray[np.int64]:
        """(E, 12) global DOFs ``[x_a, theta_a, x_b, theta_b]`` of every element."""
        cached = self.__dict__.get("_element_dofs_cache")
        if cached is None:
            t = 3 * self.pos_nodes[:, :, None] + np.arange(3)
            r = 3 * (self.n_nodes + self.rot_nodes[:, :, None]) + np.arange(3)
            cached = np.concatenate([t[:, 0], r[:, 0], t[:, 1], r[:, 1]], axis=1)
            cached.setflags(write=False)
            object.__setattr__(self, "_element_dofs_cache", cached)
        return cached

    def rotation_dofs(self) -> NDArray[np.int64]:
        return np.arange(3 * self.n_nodes, self.n_dof)

    # --- element state -------------------------------------------------------------------

    def _element_pose(self, q: Configuration) -> tuple[FloatArray, FloatArray]:
        """Element end positions (E, 2, 3) and material quaternions (E, 2, 4)."""
        return element_pose(q.x, q.quat, self.pos_nodes, self.rot_nodes, self._offsets[0])

    def _element_state(self, q: Configuration, v: FloatArray) -> tuple[FloatArray, ...]:
        """Element end positions (E, 2, 3), material quaternions (E, 2, 4), velocities (E, 12)
        with angular velocities in the end's material frame."""
        x, quat = self._element_pose(q)
        return x, quat, element_velocities(v, self.element_dofs, self._offsets[1])

    @property
    def _offsets(self) -> tuple[FloatArray, FloatArray]:
        """The ends' offsets as quaternions (E, 2, 4) and rotation matrices (E, 2, 3, 3)
        (both with no elements when there are none)."""
        cached = self.__dict__.get("_offsets_cache")
        if cached is None:
            if self.end_offset is None:
                cached = (np.zeros((0, 2, 4)), np.zeros((0, 2, 3, 3)))
            else:
                offset_q = np.ascontiguousarray(self.end_offset, dtype=float)
                cached = (offset_q, np.ascontiguousarray(so3.quat_to_matrix(offset_q)))
            object.__setattr__(self, "_offsets_cache", cached)
        return cached

    def _load_scale(self, t: float) -> FloatArray:
        return factors(self.load_schedule, t)

    @property
    def _weight(self) -> FloatArray:
        """(n_dof,) gravity on the lumped node masses [N] (zero on the rotations)."""
        cached = self.__dict__.get("_weight_cache")
        if cached is None:
            cached = np.zeros(self.n_dof)
            cached[:3 * self.n_nodes] = (self.node_mass[:, None] * self.gravity).ravel()
            cached.setflags(write=False)
            object.__setattr__(self, "_weight_cache", cached)
        return cached

    def _external(self, q: Configuration, t: float, load_factor: float) -> tuple[FloatArray, FloatArray]:
        """External force vector (n_dof,) and the body-frame load moments (L, 3)."""
        # gravity is raised with the loads in a static run, like the lumped model
        f = load_factor * self._weight
        if len(self.load_nodes) == 0:
            return f, np.zeros((0, 3))
        s = load_factor * self._load_scale(t)
        body_moment = np.einsum("lji,lj->li", so3.quat_to_matrix(q.quat[self._load_rot]),
                                s[:, None] * self.load_moment)
        for k in range(3):
            np.add.at(f, 3 * self.load_nodes + k, s * self.load_force[:, k])
            np.add.at(f, 3 * (self.n_nodes + self._load_rot) + k, body_moment[:, k])
        return f, body_moment

    def load_moments(self, quat: FloatArray) -> FloatArray:
        """The dead loads' moments (L, 3) [N m], without their time factors, in the body frames
        of their rotation nodes at the quaternions ``quat`` (R, 4): the rotations ``r1, r2,
        r3`` they turn."""
        return np.einsum("lji,lj->li", so3.quat_to_matrix(quat[self._load_rot]),
                         self.load_moment)

    @property
    def _load_rot(self) -> NDArray[np.int64]:
        return self.load_nodes if self.load_rot_nodes is None else self.load_rot_nodes

    def _gyroscopic(self, v: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``W x (J W)`` (R, 3) and its derivative ``hat(W) J - hat(J W)`` (R, 3, 3)."""
        W = np.ascontiguousarray(v[3 * self.n_nodes:].reshape(-1, 3))
        return so3_compiled.gyroscopic(W, self.rotary_inertia)

    # --- what the system composes (rodnet.models.system) ---------------------------------

    @property
    def groups(self) -> list[NDArray[np.int64]]:
        """DOFs of the blocks of :meth:`forces`: elements (E, 12), rotation nodes (R, 3)."""
        return [self.element_dofs, 3 * (self.n_nodes + np.arange(self.n_rot))[:, None] + np.arange(3)]

    secant_forces = True
    """The midpoint rule's forces (a :class:`StepRate` with a ``start``) take the stresses of
    the mean of the step's start and end strains and damping at their change over the step,
    with the strain operator of the midpoint configuration (C56): the stresses of the
    midpoint's own strains read a rod turning by ``theta`` in a step as shortened by
    ``theta^2 / 8``, and damping that as a strain rate of first order in the step."""

    @property
    def potential_exact(self) -> bool:
        """Whether :meth:`potential` accounts for every force but the gyroscopic ones (small
        velocity terms): not with dead moments, which have no potential on the rotations."""
        return not np.any(self.load_moment)

    def forces(self, q: Configuration, v: FloatArray, t: float, load_factor: float,
               need_matrices: bool, rate: StepRate | None = None,
               linearization: Linearization | None = None,
               ) -> tuple[FloatArray, list[FloatArray], list[FloatArray]]:
        """``g`` (n_dof,) and, when ``need_matrices``, the blocks of K and of C in the order of
        :attr:`groups`: ``[element (E, 12, 12), rotation node (R, 3, 3)]`` (else empty); with
        ``rate``, the elements' damping at the step's strain rates (C53)."""
        x, quat, ve = self._element_state(q, v)
        step = None if rate is None else (rate.reference, rate.inv_h)
        reference = self.reference_strain
        if rate is not None and rate.start is not None:   # the midpoint rule (C56)
            # the kernels' strains are then those of the mean: the stresses take it, and the
            # damping its change from the start, (e_0 + e_1) / 2 - e_0 over h / 2
            reference = reference - self._secant_shift(q, rate)
        args = (self.rest_length, reference, self.stiffness, self.tau, x, quat, ve,
                self.tension_only, self.kink_strain, step)
        if need_matrices:
            shift = None if linearization is None else linearization.strain_shift
            f_el, K_el, C_el = internal_force_and_tangents(*args, shift)
            if linearization is not None and linearization.convex:
                K_el = convex_blocks(K_el, self._inertia_share(linearization.inertia))
        else:
            f_el, K_el, C_el = internal_force(*args), None, None
        if self.end_offset is not None:  # back to the rotation nodes' frames
            empty = np.zeros((0, 12, 12))
            to_node_frames(f_el, K_el if need_matrices else empty,
                           C_el if need_matrices else empty, self._offsets[1])
        g = assemble_vector(self.element_dofs, f_el, self.n_dof)
        gyro, d_gyro = self._gyroscopic(v)
        g[3 * self.n_nodes:] += gyro.ravel()
        f_ext, body_moment = self._external(q, t, load_factor)
        g -= f_ext
        if not need_matrices:
            return g, [], []
        load_block = np.zeros((self.n_rot, 3, 3))
        if len(body_moment):
            np.add.at(load_block, self._load_rot, -so3.hat(body_moment))
        return g, [K_el, load_block], [C_el, d_gyro]

    INERTIA_SHARE = 0.5
    """The part of the iteration matrix's masses' term that the element blocks count on before
    they are projected (:func:`~rodnet.kernels.convex.convex_blocks`): below 1, so the rest
    keeps the matrix positive definite."""

    def _inertia_share(self, inertia: FloatArray | None) -> FloatArray | None:
        """(E, 12) each element's share of ``inertia`` (n_dof,) (:attr:`Linearization.inertia`):
        :attr:`INERTIA_SHARE` of it, split evenly among the elements at each DOF; None
        without ``inertia``."""
        if inertia is None:
            return None
        dofs = self.element_dofs
        count = np.bincount(dofs.ravel(), minlength=self.n_dof)
        return self.INERTIA_SHARE * inertia[dofs] / count[dofs]

    def _secant_shift(self, q: Configuration, rate: StepRate) -> FloatArray:
        """(E, 6) ``(e_0 + e_1) / 2 - e(q)`` for the midpoint ``q = q_0 o exp(dq / 2)`` of a
        step from ``rate.start`` (strains ``rate.reference``) to ``q_1 = q o exp(dq / 2)``, the
        axial part of the tension-only law at its secant strain
        (:func:`~rodnet.kernels.tension.secant_strain`) (C56)."""
        start = rate.start
        assert start is not None
        half = so3.quat_multiply(so3.quat_conjugate(start.quat), q.quat)
        end = Configuration(2.0 * q.x - start.x, so3.quat_multiply(q.quat, half))
        still = np.zeros(self.n_dof)
        start_strain, end_strain = rate.reference, self.strains(end, still)[0]
        mean = 0.5 * (start_strain + end_strain)
        if self.tension_only:   # the axial secant of the kinked law
            mean[:, 0] = secant_strain(start_strain[:, 0], end_strain[:, 0], self.kink_strain)
        return mean - self.strains(q, still)[0]

    def strains(self, q: Configuration, v: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Element strains ``[Gamma, K]`` and their rates (E, 6): what a
        :class:`~rodnet.state.StepRate` refers to."""
        x, quat, ve = self._element_state(q, v)
        return strains_and_rates(self.rest_length, self.reference_strain, x, quat, ve)

    def potential(self, q: Configuration, t: float, load_factor: float,
                  rate: StepRate | None) -> float:
        """The elements' incremental potential (C53) (without ``rate``: their strain energy)
        minus the work of gravity and the dead forces [J]; the dead moments and gyroscopic
        forces are left out."""
        x, quat = self._element_pose(q)
        step = None if rate is None else (rate.reference, rate.inv_h)
        stored = step_potential(self.rest_length, self.reference_strain, self.stiffness, self.tau,
                                x, quat, self.tension_only, self.kink_strain, step)
        return float(stored.sum()) + self._force_potential(q, t, load_factor)

    def _force_potential(self, q: Configuration, t: float, load_factor: float) -> float:
        """``-sum f . x`` of gravity and the dead forces [J] (their moments left out)."""
        f, _ = self._external(q, t, load_factor)
        return -float(np.dot(f[:3 * self.n_nodes], q.x.ravel()))

    def retract(self, q: Configuration, dq: FloatArray) -> Configuration:
        n3 = 3 * self.n_nodes
        return Configuration(q.x + dq[:n3].reshape(-1, 3),
                                so3_compiled.retract(q.quat, np.ascontiguousarray(dq[n3:].reshape(-1, 3))))

    def active_set(self, q: Configuration, v: FloatArray) -> bytes:
        if not self.tension_only:
            return b""
        return np.packbits(self.axial_force(q, v) > 0.0).tobytes()

    def explicit_terms(self) -> tuple[kx.Nodes, kx.Rotations, kx.Loads, Segments, Hinges,
                                      RodElements]:
        """The model's arrays for the compiled explicit loop (FORMULATION.md §9b)."""
        f = np.ascontiguousarray
        offset_q, offset_R = self._offsets
        rods = RodElements(f(self.pos_nodes, dtype=np.int64), f(self.rot_nodes, dtype=np.int64),
                           offset_q, offset_R, f(self.rest_length, dtype=float),
                           f(self.reference_strain, dtype=float), f(self.stiffness, dtype=float),
                           f(self.tau, dtype=float), bool(self.tension_only),
                           float(self.kink_strain), *SERIES_ARGUMENTS)
        free = self.free.reshape(-1, 3)
        n = self.n_nodes
        inv_mass = np.where(free[:n], 1.0 / np.maximum(self.node_mass, 1e-300)[:, None], 0.0)
        inertia = f(self.rotary_inertia, dtype=float)
        inv_inertia = np.where(free[n:], 1.0 / np.maximum(inertia, 1e-300), 0.0)
        weight = self.node_mass[:, None] * np.asarray(self.gravity, float)
        loads = kx.Loads(f(self.load_nodes, dtype=np.int64), f(self._load_rot, dtype=np.int64),
                         f(self.load_force, dtype=float).reshape(-1, 3),
                         f(self.load_moment, dtype=float).reshape(-1, 3),
                         self.load_schedule)
        no_segments = Segments(np.zeros((0, 2), np.int64), np.zeros(0), np.zeros(0), np.zeros(0),
                               0.0, True)
        return (kx.Nodes(f(inv_mass), f(weight)), kx.Rotations(inertia, f(inv_inertia)), loads,
                no_segments, no_hinges(), rods)

    def check_frame(self, t: float, frame: dict[str, FloatArray]) -> None:
        """Raise :class:`SimulationFailed` when a rod element's chord is longer than
        :data:`INVERTED_STRETCH` times its rest length: its material axis has turned against the
        chord (FORMULATION.md §10), and with the tension-only law it carries no axial force at
        any length, so the thread is in effect cut (the frame is kept: it shows the element)."""
        x, ends = frame["positions"], self.pos_nodes
        stretch = np.linalg.norm(x[ends[:, 1]] - x[ends[:, 0]], axis=1) / self.rest_length
        e = int(np.argmax(stretch)) if len(stretch) else 0
        if len(stretch) and stretch[e] > INVERTED_STRETCH:
            raise SimulationFailed(
                f"rod element {e} (nodes {ends[e, 0]}-{ends[e, 1]}) is {stretch[e]:.3g} times its "
                f"rest length at t = {t:.6g} s with an axial force of {frame['tension'][e]:.3g} N: "
                "its material axis has turned against its chord (an inverted element), so it "
                "resists no stretching")

    # --- output and checks ---------------------------------------------------------------

    def section_state(self, q: Configuration, v: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Strains ``[Gamma, K]`` (E, 6) and stress resultants ``[N, M]`` (E, 6) incl. damping."""
        x, quat, ve = self._element_state(q, v)
        return section_state(self.rest_length, self.reference_strain, self.stiffness, self.tau,
                             x, quat, ve, self.tension_only, self.kink_strain)

    def element_rotation(self, q: Configuration) -> FloatArray:
        """Relative rotation angle ``|psi|`` [rad] of every element's end triads, (E,): what the
        rotation stop (FORMULATION.md C52) acts on beyond ``ROTATION_STOP``."""
        return element_rotation(*self._element_pose(q))

    def frame_arrays(self, q: Configuration, v: FloatArray) -> dict[str, FloatArray]:
        """What a saved frame holds: positions, velocities, rotations, and per element the axial
        force ``tension`` [N], ``curvature`` |(K_1, K_2)| [1/m], ``twist`` K_0 [1/m] and the stress
        resultants in the element's material frame at its middle, ``section_forces`` (E, 3)
        ``(N_1, N_2, N_3)`` [N] and ``section_moments`` (E, 3) ``(M_1, M_2, M_3)`` [N m]
        (damping and the rotation stop included; single precision: they would have made the
        reference deployment's result.npz 28 % larger in double); and,
        not saved, the largest element rotation ``max_element_rotation`` [rad], the number of
        elements turned inside out, ``inside_out_elements`` (axial strain below -1, C51), and of
        those whose chord is also shorter than a tenth of the rest length, ``folded_elements``
        (pushed through themselves, not turned)."""
        eps, stress = self.section_state(q, v)
        ends = self._element_pose(q)[0]
        inside_out = eps[:, 0] < -1.0
        short = np.linalg.norm(ends[:, 1] - ends[:, 0], axis=1) < 0.1 * self.rest_length
        return {"positions": q.x.copy(), "velocities": v[:3 * self.n_nodes].reshape(-1, 3).copy(),
                "rotations": q.quat[self._rotation_of_node], "tension": self._tension(stress[:, 0]),
                "curvature": np.hypot(eps[:, 4], eps[:, 5]), "twist": eps[:, 3],
                "section_forces": stress[:, :3].astype(np.float32),
                "section_moments": stress[:, 3:].astype(np.float32),
                "max_element_rotation": float(self.element_rotation(q).max(initial=0.0)),
                "inside_out_elements": float(np.count_nonzero(inside_out)),
                "folded_elements": float(np.count_nonzero(inside_out & short))}

    @property
    def _rotation_of_node(self) -> NDArray[np.int64]:
        """(N,) the rotation node reported for each position node: its own, or for a node
        whose thread ends rotate independently (pinned knot, corner mass) the first end's."""
        cached = self.__dict__.get("_rotation_of_node_cache")
        if cached is None:
            cached = np.zeros(self.n_nodes, np.int64)
            cached[self.pos_nodes[::-1].ravel()] = self.rot_nodes[::-1].ravel()
            object.__setattr__(self, "_rotation_of_node_cache", cached)
        return cached

    def axial_force(self, q: Configuration, v: FloatArray) -> FloatArray:
        """Axial force N [N] of every element (the ``tension`` output), (E,)."""
        return self._tension(self.section_state(q, v)[1][:, 0])

    def _tension(self, N: FloatArray) -> FloatArray:
        """The ``tension`` output from the axial resultants ``N`` (E,) [N]: ``N`` itself, except
        that with the tension-only law an element whose material axis is against its chord (C51)
        reports the magnitude of its pushing force: along the chord it pulls the ends together,
        so every element of a tension-only thread reports a tension >= 0."""
        return np.abs(N) if self.tension_only else N

    def energy(self, q: Configuration, v: FloatArray, t: float = 0.0) -> dict[str, float]:
        """Kinetic (translational + rotational) and elastic energy [J], and the ``potential``
        ``-sum f(t) . x`` of gravity and the dead forces at time ``t`` (nan where a load has a
        moment: a dead moment has no potential on finite rotations)."""
        x, quat, _ = self._element_state(q, v)
        elastic = strain_energy(self.rest_length, self.reference_strain, self.stiffness, x, quat,
                                self.tension_only, self.kink_strain)
        kinetic = 0.5 * float(np.sum(self.dof_mass * v * v))
        moments = len(self.load_nodes) and np.any(self.load_moment)
        potential = float("nan") if moments else self._force_potential(q, t, 1.0)
        return {"kinetic": kinetic, "elastic": float(elastic.sum()), "potential": potential}

