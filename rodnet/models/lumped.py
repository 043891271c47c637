"""The lumped-parameter net: point masses joined by tension-only Kelvin-Voigt segments.

Equations: ``elements/spring/FORMULATION.md``. Each segment of the :class:`~rodnet.topology.Structure`
is one spring-damper (k = EA / l0, c = tau EA / l0 with tau = viscosity / E); half of each
segment's mass goes to each end, concentrated masses are added, supported nodes do not move. The
same model runs cable threads (Cosserat threads without bending and torsion: the lumped model's
equations) and, with bending hinges, Kirchhoff threads (:mod:`rodnet.models.kirchhoff`). Its
configuration is a :class:`~rodnet.state.Configuration` without rotations.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from rodnet.config import Scene
from rodnet.errors import SceneError, at_most
from rodnet.kernels import explicit as kx
from rodnet.kernels.cable import cable_secant_tangents, cable_tangents, element_blocks
from rodnet.kernels.cosserat_compiled import RodElements, no_rod_elements
from rodnet.kernels.hinge import Hinges, hinge_energy, hinge_force, hinge_frequency, no_hinges
from rodnet.kernels.schedule import LoadSchedule, factors
from rodnet.kernels.segments import Segments, segment_states
from rodnet.kernels.tension import axial_force, step_potential, step_strain_rate
from rodnet.models.loads import constant_gravity, dead_loads
from rodnet.state import Configuration, Linearization, StepRate
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
    load_nodes : (L,) int, load_force : (L, 3) float, load_schedule : LoadSchedule
        Dead point loads [N] and their factors over time.
    hinges : rodnet.kernels.explicit.Hinges
        Bending hinges of Kirchhoff threads, ``elements/kirchhoff/FORMULATION.md`` (K1); none for
        the lumped model and cables.
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
    load_schedule: LoadSchedule
    hinges: Hinges = field(default_factory=no_hinges, kw_only=True)

    @property
    def segments(self) -> NDArray[np.int64]:
        return self.structure.segments

    @property
    def rest_length(self) -> FloatArray:
        return self.structure.rest_length

    @property
    def node_mass(self) -> FloatArray:
        """(N,) translational node masses [kg]."""
        return self.mass

    @property
    def n_nodes(self) -> int:
        return self.structure.n_nodes

    n_rot = 0
    """No rotation nodes."""
    potential_exact = True
    """``g`` with a step rate is the gradient of :meth:`potential` (no hinges: they run
    explicitly)."""
    secant_forces = True
    """The midpoint rule's forces are the secant form (S15) (a :class:`StepRate` with a
    ``start``): the midpoint rule then conserves energy."""

    # --- segment kinematics and forces ---------------------------------------------------

    def segment_kinematics(self, x: FloatArray, v: FloatArray) -> tuple[FloatArray, ...]:
        """Length l (E,), unit direction t (E, 3), strain e = l/l0 - 1 and its rate (E,), (S2)."""
        a, b = self.segments[:, 0], self.segments[:, 1]
        d = x[b] - x[a]
        length = np.sqrt(np.einsum("ij,ij->i", d, d))
        t = d / np.where(length > 0.0, length, 1.0)[:, None]
        rate = np.einsum("ij,ij->i", v[b] - v[a], t) / self.rest_length
        return length, t, length / self.rest_length - 1.0, rate

    def tension(self, x: FloatArray, v: FloatArray, rate: StepRate | None = None) -> FloatArray:
        """Axial force of every segment [N], (E,); with ``rate``, at the step's strain rate (S11)."""
        return self._tension_and_direction(x, v, rate)[0]

    def _tension_and_direction(self, x: FloatArray, v: FloatArray,
                               rate: StepRate | None) -> tuple[FloatArray, FloatArray]:
        _, t, e, e_rate = self.segment_kinematics(x, v)
        if rate is not None:
            e_rate = step_strain_rate(e, rate.reference, rate.inv_h,  # type: ignore[arg-type]
                                      self.tension_only)
        return axial_force(e, e_rate, self.EA, self.etaA, self.kink_strain, self.tension_only), t

    def external_force(self, t: float) -> FloatArray:
        """Gravity plus the dead loads at time ``t`` [N], (N, 3)."""
        f = self.gravity_force.copy()
        np.add.at(f, self.load_nodes, factors(self.load_schedule, t)[:, None] * self.load_force)
        return f

    def segment_force(self, x: FloatArray, v: FloatArray,
                      rate: StepRate | None = None) -> FloatArray:
        """Force the segments (S7) and the bending hinges (K3), (K4) exert on every node [N],
        (N, 3); with ``rate``, the segments' at the step's strain rate (S11)."""
        n, direction = self._tension_and_direction(x, v, rate)
        f = self._incidence @ (n[:, None] * direction)
        if len(self.hinges.nodes):
            h = self.hinges
            f += hinge_force(x, v, h.nodes, h.stiffness, h.tau, h.rest)
        return f

    def force(self, x: FloatArray, v: FloatArray, t: float) -> FloatArray:
        """Total force on every node [N], (N, 3): segment forces (S7) plus external forces (the
        NumPy oracle of the compiled :func:`rodnet.kernels.explicit.forces`)."""
        return self.segment_force(x, v) + self.external_force(t)

    def stable_step(self, damped: bool = True) -> float:
        """Largest stable step [s] of the explicit (symplectic Euler) scheme, (S10).

        Each segment is taken as the stiffest mode it can drive: omega^2 = 2 k (1/m_a + 1/m_b)
        (the highest mode of a uniform chain, 4 k / m), with its Kelvin-Voigt damping ratio
        (``damped`` false: without it); bending hinges raise every segment's omega^2 by 4 times
        the largest hinge's (K5), which holds in every configuration (their stiffness is
        constant).
        """
        a, b = self.segments[:, 0], self.segments[:, 1]
        k = self.EA / self.rest_length
        omega2 = 2.0 * k * (self.inv_mass[a] + self.inv_mass[b])
        if len(self.hinges.nodes):
            h = self.hinges
            omega2 = omega2 + 4.0 * np.max(hinge_frequency(h.nodes, h.stiffness, h.rest,
                                                           self.inv_mass)) ** 2
        omega = np.sqrt(omega2)
        tau = self.etaA / self.EA if damped else np.zeros_like(omega)
        return float(np.min(damped_limit(omega, tau), initial=np.inf))

    # --- what the system composes (rodnet.models.system) ---------------------------------

    @property
    def n_dof(self) -> int:
        return 3 * self.structure.n_nodes

    @property
    def length_scale(self) -> float:
        """Size of the structure [m]: the largest distance between two nodes at rest."""
        return self.structure.size

    @property
    def force_scale(self) -> float:
        return float(self.EA.max())

    @cached_property
    def free(self) -> NDArray[np.bool_]:
        return np.repeat(self.inv_mass > 0.0, 3)

    @cached_property
    def dof_mass(self) -> FloatArray:
        return np.repeat(self.mass, 3)

    @cached_property
    def groups(self) -> list[NDArray[np.int64]]:
        """DOFs of the blocks of :meth:`forces`: one (E, 6) group, the segments' ``[x_a, x_b]``."""
        return [(3 * self.segments[:, :, None] + np.arange(3)).reshape(-1, 6)]

    def forces(self, q: Configuration, v: FloatArray, t: float, load_factor: float,
               need_matrices: bool, rate: StepRate | None = None,
               linearization: Linearization | None = None,
               ) -> tuple[FloatArray, list[FloatArray], list[FloatArray]]:
        """``g = f_int - f_ext`` (n_dof,) for flat velocities ``v`` (n_dof,) and, when
        ``need_matrices``, the blocks (E, 6, 6) of ``K = dg/dx`` and ``C = dg/dv`` over the
        segments (cable tangents, no load stiffness). With ``rate`` the strain rates are the
        step's (S11): ``g`` does not depend on ``v`` and is the gradient of :meth:`potential`.
        ``linearization``: its strain shift moves the geometric stiffness; convex leaves
        compression (the linear law) out of it."""
        x, vv = q.x, v.reshape(-1, 3)
        secant = rate is not None and rate.start is not None
        if not need_matrices and not secant:
            f = self.segment_force(x, vv, rate) + load_factor * self.external_force(t)
            return -f.ravel(), [], []
        if len(self.hinges.nodes):  # the model table refuses implicit and static Kirchhoff runs
            raise NotImplementedError("bending hinges have no tangent: Kirchhoff threads are "
                                      "integrated explicitly")
        a, b = self.segments[:, 0], self.segments[:, 1]
        if secant:   # the midpoint rule's secant form (S15); the exact tangent
            x0 = rate.start.x  # type: ignore[union-attr]
            n, g_b, K_bb, C_bb = cable_secant_tangents(
                x[a], x[b], x0[a], x0[b], self.rest_length, self.EA, self.etaA,
                self.kink_strain, self.tension_only, 0.5 * rate.inv_h)  # type: ignore[union-attr]
        else:
            step = None if rate is None else (rate.reference, rate.inv_h)
            lin = Linearization() if linearization is None else linearization
            n, g_b, K_bb, C_bb = cable_tangents(x[a], x[b], vv[a], vv[b], self.rest_length,
                                                self.EA, self.etaA, self.kink_strain,
                                                self.tension_only, step, lin.strain_shift,
                                                lin.convex)
        g = np.zeros((self.structure.n_nodes, 3))
        np.add.at(g, b, g_b)
        np.add.at(g, a, -g_b)
        g -= load_factor * self.external_force(t)
        if not need_matrices:
            return g.ravel(), [], []
        return g.ravel(), [element_blocks(K_bb)], [element_blocks(C_bb)]

    def strains(self, q: Configuration, v: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Segment strains ``e`` and their rates (E,), (S2): what a :class:`StepRate` refers to."""
        _, _, e, e_rate = self.segment_kinematics(q.x, v.reshape(-1, 3))
        return e, e_rate

    def potential(self, q: Configuration, t: float, load_factor: float,
                  rate: StepRate | None) -> float:
        """The segments' incremental potential (S12) (without ``rate``: the stored energy (S6))
        plus the potential of the dead loads and gravity [J]: ``g`` of :meth:`forces` with the
        same ``rate`` is its gradient."""
        if len(self.hinges.nodes):
            raise NotImplementedError("bending hinges have no step potential")
        d = q.x[self.segments[:, 1]] - q.x[self.segments[:, 0]]
        e = np.sqrt(np.einsum("ij,ij->i", d, d)) / self.rest_length - 1.0
        reference, inv_h = (e, 0.0) if rate is None else (rate.reference, rate.inv_h)
        stored = step_potential(e, reference, inv_h, self.EA, self.etaA,  # type: ignore[arg-type]
                                self.rest_length, self.kink_strain, self.tension_only)
        return float(stored.sum()) - load_factor * float(np.sum(self.external_force(t) * q.x))

    def retract(self, q: Configuration, dq: FloatArray) -> Configuration:
        return Configuration(q.x + dq.reshape(-1, 3), q.quat)

    def active_set(self, q: Configuration, v: FloatArray) -> bytes:
        return np.packbits(self.tension(q.x, v.reshape(-1, 3)) > 0.0).tobytes()

    def rotation_dofs(self) -> NDArray[np.int64]:
        return np.zeros(0, np.int64)

    def explicit_terms(self) -> tuple[kx.Nodes, kx.Rotations, kx.Loads, Segments, Hinges,
                                      RodElements]:
        """The model's arrays for the compiled explicit loop."""
        f = np.ascontiguousarray
        n = len(self.load_nodes)
        return (kx.Nodes(f(np.repeat(self.inv_mass[:, None], 3, axis=1)), f(self.gravity_force)),
                kx.Rotations(np.zeros((0, 3)), np.zeros((0, 3))),
                kx.Loads(f(self.load_nodes), np.zeros(n, np.int64), f(self.load_force),
                         np.zeros((n, 3)), self.load_schedule),
                Segments(f(self.segments), f(self.rest_length), f(self.EA), f(self.etaA),
                            float(self.kink_strain), bool(self.tension_only)),
                Hinges(*(f(a) for a in self.hinges)), no_rod_elements())

    # --- output --------------------------------------------------------------------------

    def frame_arrays(self, q: Configuration, v: FloatArray) -> dict[str, FloatArray]:
        """What a saved frame holds: positions, velocities (N, 3) and segment ``tension`` (E,)."""
        return {"positions": np.array(q.x), "velocities": np.array(v).reshape(-1, 3),
                "tension": self.axial_force(q, v)}

    def axial_force(self, q: Configuration, v: FloatArray) -> FloatArray:
        """Axial force of every segment [N], (E,): the frames' ``tension``."""
        return self.segment_states(q.x, np.asarray(v).reshape(-1, 3))[0]

    def segment_states(self, x: FloatArray, v: FloatArray) -> tuple[FloatArray, float]:
        """Axial force of every segment [N] (E,), as :meth:`tension`, and the elastic energy
        they store [J], (S6), in one compiled pass (what every saved frame needs)."""
        tension = np.empty(len(self.segments))
        elastic = segment_states(np.ascontiguousarray(x), np.ascontiguousarray(v),
                                 self.segments, self.rest_length, self.EA, self.etaA,
                                 float(self.kink_strain), bool(self.tension_only), tension)
        return tension, float(elastic)

    def energy(self, q: Configuration, v: FloatArray, t: float) -> dict[str, float]:
        """Kinetic, elastic and external-load potential energy [J], (S8); elastic includes the
        hinges' bending energy (K2)."""
        x, vv = q.x, np.asarray(v).reshape(-1, 3)
        elastic = self.segment_states(x, vv)[1]
        if len(self.hinges.nodes):
            h = self.hinges
            elastic += float(hinge_energy(x, h.nodes, h.stiffness, h.rest).sum())
        kinetic = 0.5 * np.sum(self.mass * np.einsum("ij,ij->i", vv, vv))
        potential = -float(np.sum(self.external_force(t) * x))
        return {"kinetic": float(kinetic), "elastic": elastic, "potential": potential}

    def check_frame(self, t: float, frame: dict[str, FloatArray]) -> None:
        """Nothing to check beyond the run's own checks."""

    @cached_property
    def _incidence(self) -> sp.csr_matrix:
        """Signed node-segment incidence (N, E): +1 at the segment's start node, -1 at its end, so
        that ``incidence @ (N t)`` is the force the segments exert on the nodes."""
        n_seg = len(self.segments)
        rows = self.segments.T.ravel()
        cols = np.tile(np.arange(n_seg), 2)
        vals = np.concatenate([np.ones(n_seg), -np.ones(n_seg)])
        return sp.csr_matrix((vals, (rows, cols)), shape=(self.structure.n_nodes, n_seg))


def build_lumped(scene: Scene, structure: Structure,
                 hinges: Hinges | None = None) -> tuple[LumpedModel, Configuration, FloatArray]:
    """The lumped model of a scene (masses (S1), springs (S3), supports, gravity, loads), with the
    bending ``hinges`` of Kirchhoff threads (:func:`rodnet.models.kirchhoff.hinges_of`) when
    given; its initial configuration and velocities (n_dof,)."""
    materials = scene.materials
    rho_a = np.array([m.rhoA for m in materials])[structure.material]
    seg_mass = rho_a * structure.rest_length
    mass = structure.point_mass.copy()
    np.add.at(mass, structure.segments[:, 0], 0.5 * seg_mass)
    np.add.at(mass, structure.segments[:, 1], 0.5 * seg_mass)
    inv_mass = 1.0 / mass
    label = "the lumped model and cable threads" if hinges is None else "Kirchhoff threads"
    for i, s in enumerate(scene.supports):
        if s.dofs is not None and set(s.dofs) != {"x", "y", "z"}:
            raise SceneError(f"supports[{i}].dofs", list(s.dofs), f"{label} support whole nodes "
                             "only: use fix = 'pin' or dofs = ['x', 'y', 'z']")
        inv_mass[structure.node(s.node, f"supports[{i}].node")] = 0.0
    for i, load in enumerate(scene.loads):
        if any(load.moment):
            raise SceneError(f"loads[{i}].moment", load.moment,
                             f"{label} have no rotations (" + ("their hinges bend through the "
                             "node positions" if hinges is not None else "nodes are points")
                             + "); moments need model.type = 'cosserat' with model.bending or "
                             "model.torsion on")
    loads = dead_loads(scene, structure, mass)
    model = LumpedModel(
        structure=structure, mass=mass, inv_mass=inv_mass,
        EA=np.array([m.EA for m in materials])[structure.material],
        etaA=np.array([m.damping_coefficient for m in materials])[structure.material],
        kink_strain=scene.model.kink_strain, tension_only=scene.model.axial == "tension-only",
        gravity_force=mass[:, None] * constant_gravity(scene)[None, :],
        load_nodes=loads.nodes, load_force=loads.force, load_schedule=loads.schedule,
        hinges=no_hinges() if hinges is None else hinges)
    for array in (*(getattr(model, name) for name in ("mass", "inv_mass", "EA", "etaA",
                                                      "gravity_force", "load_nodes", "load_force")),
                  *model.load_schedule, *model.hinges):
        array.setflags(write=False)
    if not math.isfinite(model.stable_step()) and not scene.bodies:
        raise SceneError("supports", [s.node for s in scene.supports],
                         "every node is supported and there is no body: nothing can move")
    v0 = structure.velocities.copy()
    v0[model.inv_mass == 0.0] = 0.0
    return model, Configuration(structure.positions.copy()), v0.ravel()


def lumped_explicit_plan(model: LumpedModel, v0: FloatArray, dt: float, adaptive: bool,
                         safety: float, scale_rotary_inertia: bool = False,
                         ) -> tuple[LumpedModel, FloatArray, kx.StepControl]:
    """The model the explicit loop runs (this one), its start velocities and the step control:
    fixed steps of ``safety`` times the stability limit (S10), or of ``dt`` (the model has no
    rotary inertia to scale).

    Raises
    ------
    SceneError
        A fixed ``dt`` above the stability limit.
    """
    limit = model.stable_step()
    if not adaptive and dt > limit:
        raise SceneError("simulation.dt", dt, f"exceeds the explicit stability limit "
                         f"{limit:.3g} s of this scene; use dt <= {at_most(limit)} "
                         f"(about half of it for accurate snap loads) or adaptive = true")
    step = safety * limit if adaptive else dt
    return model, v0, kx.StepControl(step, step, 0.0, False, np.zeros(1), np.ones(1), limit,
                                     undamped_step=model.stable_step(damped=False))
