"""Rods of two-node Simo-Reissner elements as a :class:`~rodnet.integrate.system.System`.

Configuration: positions ``x`` (N, 3) and unit quaternions ``quat`` (R, 4) of the rotation nodes.
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

from rodnet.assembly import IterationMatrix, SparsityPattern, assemble_vector
from rodnet.kernels import so3, so3_compiled
from rodnet.kernels.cosserat_strain import kinematics
from rodnet.kernels.cosserat import (internal_force, internal_force_and_tangents, section_state,
                                     strain_energy)

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class RodConfiguration:
    """Positions (N, 3) [m] and unit quaternions (R, 4) (w, x, y, z)."""

    x: FloatArray
    quat: FloatArray


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
    load_nodes (L,) int, load_force (L, 3), load_moment (L, 3), load_ramp (L,)
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
    load_ramp: FloatArray
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
        """Size of the structure [m]: the diagonal of its stress-free bounding box."""
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

    def _element_pose(self, q: RodConfiguration) -> tuple[FloatArray, FloatArray]:
        """Element end positions (E, 2, 3) and material quaternions (E, 2, 4)."""
        quat = q.quat[self.rot_nodes]
        if self.end_offset is not None:
            quat = so3.quat_multiply(quat, self.end_offset)
        return q.x[self.pos_nodes], quat

    def _element_state(self, q: RodConfiguration, v: FloatArray) -> tuple[FloatArray, ...]:
        """Element end positions (E, 2, 3), material quaternions (E, 2, 4), velocities (E, 12)
        with angular velocities in the end's material frame."""
        x, quat = self._element_pose(q)
        ve = v[self.element_dofs]
        if self.end_offset is not None:
            ve = np.einsum("eji,ej->ei", self._offset_transform, ve)
        return x, quat, ve

    @property
    def _offset_transform(self) -> FloatArray:
        """(E, 12, 12) ``blockdiag(I, Q_a, I, Q_b)``: element-end components to node components."""
        cached = self.__dict__.get("_offset_cache")
        if cached is None:
            Q = so3.quat_to_matrix(self.end_offset)
            cached = np.zeros((len(Q), 12, 12))
            for k, (i, j) in enumerate(((0, 3), (6, 9))):
                cached[:, i:i + 3, i:i + 3] = np.eye(3)
                cached[:, j:j + 3, j:j + 3] = Q[:, k]
            object.__setattr__(self, "_offset_cache", cached)
        return cached

    def _load_scale(self, t: float) -> FloatArray:
        ramp = self.load_ramp
        return np.where(ramp > 0.0, np.minimum(1.0, t / np.where(ramp > 0.0, ramp, 1.0)), 1.0)

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

    def _external(self, q: RodConfiguration, t: float, load_factor: float) -> tuple[FloatArray, FloatArray]:
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

    @property
    def _load_rot(self) -> NDArray[np.int64]:
        return self.load_nodes if self.load_rot_nodes is None else self.load_rot_nodes

    def _gyroscopic(self, v: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``W x (J W)`` (R, 3) and its derivative ``hat(W) J - hat(J W)`` (R, 3, 3)."""
        W = np.ascontiguousarray(v[3 * self.n_nodes:].reshape(-1, 3))
        return so3_compiled.gyroscopic(W, self.rotary_inertia)

    # --- the System protocol -------------------------------------------------------------

    def generalized_force(self, q: RodConfiguration, v: FloatArray, t: float,
                          load_factor: float = 1.0) -> FloatArray:
        g, _, _ = self._forces(q, v, t, load_factor, need_matrices=False)
        return g

    def tangents(self, q: RodConfiguration, v: FloatArray, t: float, load_factor: float = 1.0,
                 ) -> tuple[FloatArray, sp.csr_matrix, sp.csr_matrix]:
        g, K_blocks, C_blocks = self._forces(q, v, t, load_factor, need_matrices=True)
        return g, self._pattern.matrix(K_blocks), self._pattern.matrix(C_blocks)

    def iteration_matrix(self, q: RodConfiguration, v: FloatArray, t: float, dq: FloatArray,
                         diagonal: FloatArray, a: float, b: float, load_factor: float = 1.0,
                         ) -> tuple[FloatArray, IterationMatrix]:
        """``g`` (n_dof,) and Newton's iteration matrix ``diag(diagonal) + a C + b K T(dq)`` on the
        free DOFs, assembled in one pass.

        ``K``, ``C`` are those of :meth:`tangents` and ``T(dq)`` is the tangent operator as
        :meth:`times_tangent_operator` applies it (at every angle here). The matrix comes in the
        storage its LU will use: LAPACK band storage for a thread, dense or CSR otherwise
        (:meth:`rodnet.assembly.SparsityPattern.iteration_matrix`).

        Parameters
        ----------
        q, v, t, load_factor
            As :meth:`tangents`.
        dq : (n_dof,) float
            The increment whose tangent operator multiplies K.
        diagonal : (n_free,) float
            Added to the diagonal (the mass term).
        a, b : float
            Weights of C and of K T.
        """
        g, K_blocks, C_blocks = self._forces(q, v, t, load_factor, need_matrices=True)
        S = self._pattern.iteration_matrix(diagonal, a, C_blocks, b, K_blocks,
                                           self._triple_transforms(dq))
        return g, S

    def _forces(self, q: RodConfiguration, v: FloatArray, t: float, load_factor: float,
                need_matrices: bool) -> tuple[FloatArray, list[FloatArray], list[FloatArray]]:
        """``g`` (n_dof,) and, when ``need_matrices``, the blocks of K and of C in the order of
        the pattern's groups: ``[element (E, 12, 12), rotation node (R, 3, 3)]`` (else empty)."""
        x, quat, ve = self._element_state(q, v)
        args = (self.rest_length, self.reference_strain, self.stiffness, self.tau, x, quat, ve,
                self.tension_only, self.kink_strain)
        if need_matrices:
            f_el, K_el, C_el = internal_force_and_tangents(*args)
        else:
            f_el, K_el, C_el = internal_force(*args), None, None
        if self.end_offset is not None:  # back to the rotation nodes' frames
            T = self._offset_transform
            f_el = np.einsum("eij,ej->ei", T, f_el)
            if need_matrices:
                K_el = T @ K_el @ T.transpose(0, 2, 1)
                C_el = T @ C_el @ T.transpose(0, 2, 1)
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

    def retract(self, q: RodConfiguration, dq: FloatArray) -> RodConfiguration:
        n3 = 3 * self.n_nodes
        return RodConfiguration(q.x + dq[:n3].reshape(-1, 3),
                                so3_compiled.retract(q.quat, np.ascontiguousarray(dq[n3:].reshape(-1, 3))))

    def tangent_operator(self, dq: FloatArray) -> sp.csr_matrix:
        blocks = np.concatenate([np.tile(np.eye(3), (self.n_nodes, 1, 1)),
                                 so3.dexp(dq[3 * self.n_nodes:].reshape(-1, 3))])
        n = len(blocks)
        full = sp.bsr_matrix((blocks, np.arange(n), np.arange(n + 1)), shape=(3 * n, 3 * n)).tocsr()
        keep = np.flatnonzero(self.free)
        return full[keep][:, keep]

    def times_tangent_operator(self, K: sp.csr_matrix, dq: FloatArray) -> sp.csr_matrix:
        """``K @ tangent_operator(dq)`` without forming the operator (same pattern as K).

        ``T(dq) = I - hat(dq) / 2 + O(|dq|^2)``: below 1e-4 rad the product is K itself, which
        changes the Newton matrix by less than 5e-5 relative (Newton's convergence rate, never
        its solution)."""
        rot = dq[3 * self.n_nodes:].reshape(-1, 3)[self._free_rot_nodes]
        if not len(rot) or np.abs(rot).max() < 1e-4:
            return K
        return self._pattern.right_multiply_blocks(K, self._free_rot_triples, so3_compiled.dexp(rot))

    def _triple_transforms(self, dq: FloatArray) -> FloatArray:
        """(n_dof / 3, 3, 3) blocks of the tangent operator ``T(dq)`` per DOF triple: ``dexp`` of
        the increment on rotation nodes whose three rotations are free (as in
        :meth:`times_tangent_operator`), the identity elsewhere."""
        identity = self.__dict__.get("_identity_cache")
        if identity is None:
            identity = np.tile(np.eye(3), (self.n_dof // 3, 1, 1))
            identity.setflags(write=False)
            object.__setattr__(self, "_identity_cache", identity)
        transforms = identity.copy()
        nodes = self._free_rot_nodes
        transforms[self.n_nodes + nodes] = so3_compiled.dexp(
            dq[3 * self.n_nodes:].reshape(-1, 3)[nodes])
        return transforms

    @property
    def _free_rot_nodes(self) -> NDArray[np.int64]:
        """Rotation nodes whose three rotations are all free, (F,)."""
        cached = self.__dict__.get("_free_rot_nodes_cache")
        if cached is None:
            cached = np.flatnonzero(self.free[3 * self.n_nodes:].reshape(-1, 3).all(axis=1))
            object.__setattr__(self, "_free_rot_nodes_cache", cached)
        return cached

    @property
    def _free_rot_triples(self) -> NDArray[np.int64]:
        cached = self.__dict__.get("_triples_cache")
        if cached is None:
            dofs = 3 * (self.n_nodes + self._free_rot_nodes)[:, None] + np.arange(3)
            cached = self._pattern.reduced_index[dofs]
            object.__setattr__(self, "_triples_cache", cached)
        return cached

    def active_set(self, q: RodConfiguration, v: FloatArray) -> int:
        return hash(np.packbits(self.axial_force(q, v) > 0.0).tobytes()) if self.tension_only else 0

    # --- output and checks ---------------------------------------------------------------

    def section_state(self, q: RodConfiguration, v: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Strains ``[Gamma, K]`` (E, 6) and stress resultants ``[N, M]`` (E, 6) incl. damping."""
        x, quat, ve = self._element_state(q, v)
        return section_state(self.rest_length, self.reference_strain, self.stiffness, self.tau,
                             x, quat, ve, self.tension_only, self.kink_strain)

    def element_rotation(self, q: RodConfiguration) -> FloatArray:
        """Relative rotation angle ``|psi|`` [rad] of every element's end triads, (E,): what the
        rotation stop (FORMULATION.md C52) acts on beyond ``ROTATION_STOP``."""
        return np.linalg.norm(kinematics(*self._element_pose(q))[0], axis=1)

    def frame_arrays(self, q: RodConfiguration, v: FloatArray) -> dict[str, FloatArray]:
        """What a saved frame holds: positions, velocities, rotations, and per element the axial
        force ``tension`` [N], ``curvature`` |(K_1, K_2)| [1/m] and ``twist`` K_0 [1/m]."""
        eps, stress = self.section_state(q, v)
        return {"positions": q.x.copy(), "velocities": v[:3 * self.n_nodes].reshape(-1, 3).copy(),
                "rotations": q.quat[self._rotation_of_node], "tension": self._tension(stress[:, 0]),
                "curvature": np.hypot(eps[:, 4], eps[:, 5]), "twist": eps[:, 3]}

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

    def axial_force(self, q: RodConfiguration, v: FloatArray) -> FloatArray:
        """Axial force N [N] of every element (the ``tension`` output), (E,)."""
        return self._tension(self.section_state(q, v)[1][:, 0])

    def _tension(self, N: FloatArray) -> FloatArray:
        """The ``tension`` output from the axial resultants ``N`` (E,) [N]: ``N`` itself, except
        that with the tension-only law an element whose material axis is against its chord (C51)
        reports the magnitude of its pushing force: along the chord it pulls the ends together,
        so every element of a tension-only thread reports a tension >= 0."""
        return np.abs(N) if self.tension_only else N

    def energy(self, q: RodConfiguration, v: FloatArray, t: float = 0.0) -> dict[str, float]:
        """Kinetic (translational + rotational) and elastic energy [J]; ``t`` is unused (the
        signature is that of the lumped model's)."""
        x, quat, _ = self._element_state(q, v)
        elastic = strain_energy(self.rest_length, self.reference_strain, self.stiffness, x, quat,
                                self.tension_only, self.kink_strain)
        kinetic = 0.5 * float(np.sum(self.dof_mass * v * v))
        return {"kinetic": kinetic, "elastic": float(elastic.sum())}

    @property
    def _pattern(self) -> SparsityPattern:
        cached = self.__dict__.get("_pattern_cache")
        if cached is None:
            rot_blocks = (3 * (self.n_nodes + np.arange(self.n_rot))[:, None] + np.arange(3))
            cached = SparsityPattern([self.element_dofs, rot_blocks], self.n_dof, self.free)
            object.__setattr__(self, "_pattern_cache", cached)
        return cached
