"""The lumped-parameter reference net: point masses joined by tension-only Kelvin-Voigt segments.

Equations: ``elements/spring/FORMULATION.md``. Each segment of the :class:`~rodnet.topology.Structure`
is one spring-damper (k = EA / l0, c = tau EA / l0 with tau = viscosity / E); half of each segment's mass goes to
each end, concentrated masses are added, supported nodes do not move.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from rodnet.config import Scene
from rodnet.errors import SceneError
from rodnet.formulations.kirchhoff import Hinges
from rodnet.assembly import SparsityPattern
from rodnet.kernels.cable import cable_tangents, element_blocks
from rodnet.kernels.hinge import hinge_energy, hinge_force, hinge_frequency
from rodnet.kernels.tension import axial_energy, axial_force
from rodnet.topology import Structure

FloatArray = NDArray[np.float64]


def damped_limit(omega: FloatArray, tau: FloatArray) -> FloatArray:
    """Stability limit ``2 (sqrt(1 + zeta^2) - zeta) / omega`` [s] of symplectic Euler for modes
    of frequency ``omega`` [rad/s] with Kelvin-Voigt damping ``zeta = tau omega / 2`` (``tau``:
    retardation time [s]) (S10); infinite for a mode that does not move (``omega = 0``)."""
    zeta = 0.5 * tau * omega
    with np.errstate(divide="ignore"):
        return np.where(omega > 0.0, 2.0 * (np.sqrt(1.0 + zeta**2) - zeta) / omega, np.inf)


@dataclass(frozen=True)
class LumpedModel:
    """Read-only arrays of the lumped model.

    Attributes
    ----------
    structure : Structure
    mass : (N,) float
        Nodal mass [kg], (S1).
    inv_mass : (N,) float
        1 / mass, zero for supported nodes (they never accelerate).
    EA, etaA : (E,) float
        Axial stiffness [N] and viscous coefficient tau EA [N s] (tau = viscosity / E) of each
        segment.
    kink_strain : float
    tension_only : bool
    gravity_force : (N, 3) float
        mass * g [N].
    load_nodes : (L,) int, load_force : (L, 3) float, load_ramp : (L,) float
        Dead point loads [N] and their ramp times [s] (0: applied at once).
    hinges : Hinges
        Bending hinges of Kirchhoff threads, ``elements/kirchhoff/FORMULATION.md`` (K1)
        (:class:`rodnet.formulations.kirchhoff.Hinges`); none for the lumped model and cables.
    """

    structure: Structure
    mass: FloatArray
    inv_mass: FloatArray
    EA: FloatArray
    etaA: FloatArray
    kink_strain: float
    tension_only: bool
    gravity_force: FloatArray
    load_nodes: NDArray[np.int64]
    load_force: FloatArray
    load_ramp: FloatArray
    hinges: Hinges = field(default_factory=Hinges.none, kw_only=True)

    @property
    def segments(self) -> NDArray[np.int64]:
        return self.structure.segments

    @property
    def rest_length(self) -> FloatArray:
        return self.structure.rest_length

    def segment_kinematics(self, x: FloatArray, v: FloatArray) -> tuple[FloatArray, ...]:
        """Length l (E,), unit direction t (E, 3), strain e = l/l0 - 1 and its rate (E,), (S2)."""
        a, b = self.segments[:, 0], self.segments[:, 1]
        d = x[b] - x[a]
        length = np.sqrt(np.einsum("ij,ij->i", d, d))
        t = d / np.where(length > 0.0, length, 1.0)[:, None]
        rate = np.einsum("ij,ij->i", v[b] - v[a], t) / self.rest_length
        return length, t, length / self.rest_length - 1.0, rate

    def tension(self, x: FloatArray, v: FloatArray) -> FloatArray:
        """Axial force of every segment [N], (E,)."""
        _, _, e, rate = self.segment_kinematics(x, v)
        return axial_force(e, rate, self.EA, self.etaA, self.kink_strain, self.tension_only)

    def frame_arrays(self, x: FloatArray, v: FloatArray) -> dict[str, FloatArray]:
        """What a saved frame holds: positions, velocities (N, 3) and segment ``tension`` (E,)."""
        vv = np.asarray(v).reshape(-1, 3)
        return {"positions": np.array(x), "velocities": np.array(vv), "tension": self.tension(x, vv)}

    def external_force(self, t: float) -> FloatArray:
        """Gravity plus ramped dead loads at time ``t`` [N], (N, 3)."""
        f = self.gravity_force.copy()
        scale = np.where(self.load_ramp > 0.0, np.minimum(1.0, t / np.where(
            self.load_ramp > 0.0, self.load_ramp, 1.0)), 1.0)
        np.add.at(f, self.load_nodes, scale[:, None] * self.load_force)
        return f

    def segment_force(self, x: FloatArray, v: FloatArray) -> FloatArray:
        """Force the segments (S7) and the bending hinges (K3), (K4) exert on every node [N],
        (N, 3)."""
        _, direction, e, rate = self.segment_kinematics(x, v)
        n = axial_force(e, rate, self.EA, self.etaA, self.kink_strain, self.tension_only)
        f = self._incidence @ (n[:, None] * direction)
        if len(self.hinges.nodes):
            h = self.hinges
            f += hinge_force(x, v, h.nodes, h.stiffness, h.tau, h.rest)
        return f

    def force(self, x: FloatArray, v: FloatArray, t: float) -> FloatArray:
        """Total force on every node [N], (N, 3): segment forces (S7) plus external forces."""
        return self.segment_force(x, v) + self.external_force(t)

    def acceleration(self, x: FloatArray, v: FloatArray, t: float) -> FloatArray:
        """Nodal acceleration [m/s^2], (N, 3); zero at supported nodes.

        Uses the compiled force loop (:mod:`rodnet.kernels.lumped_explicit`), which tests check
        against the NumPy :meth:`force`.
        """
        from rodnet.kernels.lumped_explicit import accumulate_forces

        f = np.empty_like(x)
        accumulate_forces(x, v, t, f, *self.kernel_arguments())
        return f * self.inv_mass[:, None]

    def kernel_arguments(self) -> tuple:
        """The model's arrays in the order the compiled kernels take them (after the state)."""
        return (self.segments, self.rest_length, self.EA, self.etaA, self.kink_strain,
                self.tension_only, self.gravity_force, self.load_nodes, self.load_force,
                self.load_ramp, *self.hinges)

    def energy(self, x: FloatArray, v: FloatArray, t: float) -> dict[str, float]:
        """Kinetic, elastic and external-load potential energy [J], (S8); elastic includes the
        hinges' bending energy (K2)."""
        _, _, e, _ = self.segment_kinematics(x, v)
        elastic = axial_energy(e, self.EA, self.rest_length, self.kink_strain, self.tension_only)
        if len(self.hinges.nodes):
            h = self.hinges
            elastic = np.append(elastic, hinge_energy(x, h.nodes, h.stiffness, h.rest))
        kinetic = 0.5 * np.sum(self.mass * np.einsum("ij,ij->i", v, v))
        potential = -float(np.sum(self.external_force(t) * x))
        return {"kinetic": float(kinetic), "elastic": float(elastic.sum()), "potential": potential}

    def stable_step(self) -> float:
        """Largest stable step [s] of the explicit (symplectic Euler) scheme, (S10).

        Each segment is taken as the stiffest mode it can drive: omega^2 = 2 k (1/m_a + 1/m_b)
        (the highest mode of a uniform chain, 4 k / m), with its Kelvin-Voigt damping ratio;
        bending hinges raise every segment's omega^2 by 4 times the largest hinge's (K5), which
        holds in every configuration (their stiffness is constant).
        """
        a, b = self.segments[:, 0], self.segments[:, 1]
        k = self.EA / self.rest_length
        omega2 = 2.0 * k * (self.inv_mass[a] + self.inv_mass[b])
        if len(self.hinges.nodes):
            h = self.hinges
            omega2 = omega2 + 4.0 * np.max(hinge_frequency(h.nodes, h.stiffness, h.rest,
                                                           self.inv_mass)) ** 2
        omega = np.sqrt(omega2)
        return float(np.min(damped_limit(omega, self.etaA / self.EA), initial=np.inf))

    # --- the System protocol of rodnet.integrate.system (configuration q = positions (N, 3)) ---

    @property
    def n_dof(self) -> int:
        return 3 * self.structure.n_nodes

    @property
    def length_scale(self) -> float:
        """Size of the structure [m]: the diagonal of its stress-free bounding box."""
        return self.structure.size

    @property
    def force_scale(self) -> float:
        return float(self.EA.max())

    @property
    def free(self) -> NDArray[np.bool_]:
        return np.repeat(self.inv_mass > 0.0, 3)

    @property
    def dof_mass(self) -> FloatArray:
        return np.repeat(self.mass, 3)

    def generalized_force(self, x: FloatArray, v: FloatArray, t: float, load_factor: float = 1.0) -> FloatArray:
        """g = f_int - f_ext (n_dof,) for flat velocities ``v`` (n_dof,)."""
        f = self.segment_force(x, v.reshape(-1, 3)) + load_factor * self.external_force(t)
        return -f.ravel()

    def tangents(self, x: FloatArray, v: FloatArray, t: float, load_factor: float = 1.0):
        """g (n_dof,) and K = dg/dx, C = dg/dv on the free DOFs (cable tangents, no load stiffness)."""
        g, K_blocks, C_blocks = self.tangent_blocks(x, v, t, load_factor)
        pattern = self._pattern
        return g.ravel(), pattern.matrix([K_blocks]), pattern.matrix([C_blocks])

    def tangent_blocks(self, x: FloatArray, v: FloatArray, t: float, load_factor: float = 1.0,
                       ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """g (N, 3) and the segment blocks (E, 6, 6) of K and C over the nodes ``[a, b]``."""
        if len(self.hinges.nodes):  # run.prepare refuses implicit and static Kirchhoff runs
            raise NotImplementedError("bending hinges have no tangent: Kirchhoff threads are "
                                      "integrated explicitly")
        vv = v.reshape(-1, 3)
        a, b = self.segments[:, 0], self.segments[:, 1]
        n, g_b, K_bb, C_bb = cable_tangents(x[a], x[b], vv[a], vv[b], self.rest_length, self.EA,
                                            self.etaA, self.kink_strain, self.tension_only)
        g = np.zeros((self.structure.n_nodes, 3))
        np.add.at(g, b, g_b)
        np.add.at(g, a, -g_b)
        g -= load_factor * self.external_force(t)
        return g, element_blocks(K_bb), element_blocks(C_bb)

    def retract(self, x: FloatArray, dq: FloatArray) -> FloatArray:
        return x + dq.reshape(-1, 3)

    def tangent_operator(self, dq: FloatArray) -> sp.csr_matrix:
        return sp.identity(int(self.free.sum()), format="csr")

    def active_set(self, x: FloatArray, v: FloatArray) -> int:
        return hash(np.packbits(self.tension(x, v.reshape(-1, 3)) > 0.0).tobytes())

    def rotation_dofs(self) -> NDArray[np.int64]:
        return np.zeros(0, np.int64)

    @property
    def _pattern(self) -> SparsityPattern:
        cached = self.__dict__.get("_pattern_cache")
        if cached is None:
            dofs = (3 * self.segments[:, :, None] + np.arange(3)).reshape(-1, 6)
            cached = SparsityPattern([dofs], self.n_dof, self.free)
            object.__setattr__(self, "_pattern_cache", cached)
        return cached

    @property
    def _incidence(self) -> sp.csr_matrix:
        """Signed node-segment incidence (N, E): +1 at the segment's start node, -1 at its end, so
        that ``incidence @ (N t)`` is the force the segments exert on the nodes."""
        cached = self.__dict__.get("_incidence_cache")
        if cached is None:
            n_seg = len(self.segments)
            rows = self.segments.T.ravel()
            cols = np.tile(np.arange(n_seg), 2)
            vals = np.concatenate([np.ones(n_seg), -np.ones(n_seg)])
            cached = sp.csr_matrix((vals, (rows, cols)), shape=(self.structure.n_nodes, n_seg))
            object.__setattr__(self, "_incidence_cache", cached)
        return cached


def build_lumped(scene: Scene, structure: Structure, hinges: Hinges | None = None) -> LumpedModel:
    """The lumped model of a scene (masses (S1), springs (S3), supports, gravity, loads), with the
    bending ``hinges`` of Kirchhoff threads (:func:`rodnet.formulations.kirchhoff.hinges_of`)
    when given."""
    materials = scene.materials
    rho_a = np.array([m.rhoA for m in materials])[structure.material]
    seg_mass = rho_a * structure.rest_length
    mass = structure.point_mass.copy()
    np.add.at(mass, structure.segments[:, 0], 0.5 * seg_mass)
    np.add.at(mass, structure.segments[:, 1], 0.5 * seg_mass)
    inv_mass = 1.0 / mass
    for i, s in enumerate(scene.supports):
        if s.dofs is not None and set(s.dofs) != {"x", "y", "z"}:
            raise SceneError(f"supports[{i}].dofs", list(s.dofs), "the lumped model and cable threads "
                             "support whole nodes only: use fix = 'pin' or dofs = ['x', 'y', 'z']")
        inv_mass[structure.node(s.node, f"supports[{i}].node")] = 0.0
    for i, load in enumerate(scene.loads):
        if any(load.moment):
            raise SceneError(f"loads[{i}].moment", load.moment,
                             "a lumped model has no rotations; moments need model.type = 'cosserat'")
    load_nodes = np.array([structure.node(l.node, f"loads[{i}].node")
                           for i, l in enumerate(scene.loads)], dtype=np.int64)
    model = LumpedModel(
        structure=structure, mass=mass, inv_mass=inv_mass,
        EA=np.array([m.EA for m in materials])[structure.material],
        etaA=np.array([m.damping_coefficient for m in materials])[structure.material],
        kink_strain=scene.model.kink_strain, tension_only=scene.model.axial == "tension-only",
        gravity_force=mass[:, None] * np.asarray(scene.simulation.gravity)[None, :],
        load_nodes=load_nodes,
        load_force=np.array([l.force for l in scene.loads], float).reshape(-1, 3),
        load_ramp=np.array([l.ramp for l in scene.loads], float),
        hinges=Hinges.none() if hinges is None else hinges)
    for array in (*(getattr(model, name) for name in ("mass", "inv_mass", "EA", "etaA",
                                                      "gravity_force", "load_nodes", "load_force",
                                                      "load_ramp")), *model.hinges):
        array.setflags(write=False)
    if not math.isfinite(model.stable_step()):
        raise SceneError("supports", [s.node for s in scene.supports],
                         "every node is supported: nothing can move")
    if scene.bodies:
        from rodnet.contact.lumped import with_bodies

        return with_bodies(model, scene)
    return model
