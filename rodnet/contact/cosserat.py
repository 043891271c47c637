"""Cosserat rods with bending and torsion touching rigid bodies: contact as one more force term.

:class:`CosseratContactModel` is a :class:`~rodnet.formulations.cosserat.CosseratModel` whose
generalized force and tangents include the contact forces of :mod:`rodnet.contact.forces`. The
thread is the same capsule as for the lumped model and cable threads: contact points on the
straight chord between an element's two position nodes (B1)-(B3), so the contact force acts on
the translational DOFs only (B5), and its consistent tangent (K4) is a 6 x 6 block per element on
``[x_a, x_b]``. That block is placed in the element's 12 x 12 block ``[x_a, theta_a, x_b,
theta_b]`` before assembly. The translational part of the rotation-aware tangent operator
``T(dq)`` is the identity, so Newton's iteration matrix ``diag + a C + b K T(dq)`` receives the
contact tangent unchanged, and Newton converges quadratically through contact as for cables.

The rotations do not enter the contact: friction acts at the centreline point, and its moment
``r n x f_T`` about the thread axis is neglected (FORMULATION section 6). Free bodies are not part
of the implicit system (FORMULATION section 8): they move with the explicit integrator
(:func:`rodnet.integrate.explicit_rods.integrate_explicit_rods`), implicit runs need fixed bodies.
Equations: ``elements/contact/FORMULATION.md``; user guide: ``docs/contact.md``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from rodnet.config import Scene
from rodnet.contact.bodies import BodyContact, build_body_contact
from rodnet.contact.forces import (add_body_energy, add_friction_work, nodal_force, nodal_tangents,
                                   pressed_nodes, step_travel)
from rodnet.contact.geometry import FloatArray
from rodnet.formulations.cosserat import CosseratModel, RodConfiguration
from rodnet.integrate.frames import StepStats
from rodnet.topology import Structure

TRANSLATIONS = np.r_[0:3, 6:9]
"""Rows and columns of an element's 12 x 12 block that hold ``[x_a, x_b]``."""


@dataclass(frozen=True)
class CosseratContactModel(CosseratModel):
    """A Cosserat rod model with rigid bodies (see the module docstring).

    Attributes
    ----------
    contact : BodyContact
        Its ``segments`` are the elements' position nodes ``pos_nodes``, in the same order.
    """

    contact: BodyContact = field(kw_only=True)

    def __post_init__(self) -> None:
        if not np.array_equal(self.contact.segments, self.pos_nodes):
            raise ValueError("the contact segments must be the elements' position nodes")

    def _node_state(self, q: RodConfiguration, v: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Positions and translational velocities (N, 3) of ``q``, ``v`` (n_dof,)."""
        return np.asarray(q.x), np.asarray(v[:3 * self.n_nodes]).reshape(-1, 3)

    def _forces(self, q: RodConfiguration, v: FloatArray, t: float, load_factor: float,
                need_matrices: bool) -> tuple[FloatArray, list[FloatArray], list[FloatArray]]:
        """The rod's ``g`` and blocks with the contact force and its tangent (K4), (B5) on the
        translational DOFs: ``g -= f``, ``K -= df/dx``, ``C -= df/dv`` per element."""
        g, K_blocks, C_blocks = super()._forces(q, v, t, load_factor, need_matrices)
        x, u = self._node_state(q, v)
        n3 = 3 * self.n_nodes
        if not need_matrices:
            g[:n3] -= nodal_force(self.contact, x, u).ravel()
            return g, K_blocks, C_blocks
        c = nodal_tangents(self.contact, x, u)
        g[:n3] -= c.force.ravel()
        touched = np.flatnonzero(np.any(c.d_position != 0.0, axis=(1, 2))
                                 | np.any(c.d_velocity != 0.0, axis=(1, 2)))
        if len(touched):
            K_el, C_el = K_blocks[0].copy(), C_blocks[0].copy()
            rows = np.ix_(touched, TRANSLATIONS, TRANSLATIONS)
            K_el[rows] -= c.d_position[touched]
            C_el[rows] -= c.d_velocity[touched]
            K_blocks, C_blocks = [K_el, *K_blocks[1:]], [C_el, *C_blocks[1:]]
        return g, K_blocks, C_blocks

    def energy(self, q: RodConfiguration, v: FloatArray, t: float = 0.0) -> dict[str, float]:
        """The rod's kinetic and elastic energy [J] with the free bodies' kinetic energy in
        ``kinetic``, and ``contact``, the energy stored in the penalty springs (N4)."""
        return add_body_energy(super().energy(q, v, t), self.contact, np.asarray(q.x))

    def active_set(self, q: RodConfiguration, v: FloatArray) -> int:
        return hash((super().active_set(q, v), pressed_nodes(self.contact, *self._node_state(q, v))))

    def step_travel(self, q_old: RodConfiguration, q_new: RodConfiguration) -> float:
        """Travel of the points near a body over a step as a multiple of the travel limit (E3)."""
        return step_travel(self.contact, np.asarray(q_old.x), np.asarray(q_new.x))

    def after_step(self, q: RodConfiguration, v: FloatArray, dt: float, stats: StepStats) -> None:
        """Add the friction work of an accepted step ending in ``q``, ``v`` to
        ``stats.extra["friction_work"]`` [J] (friction power at the end of the step times dt)."""
        add_friction_work(self.contact, *self._node_state(q, v), dt, stats)


def cosserat_with_bodies(model: CosseratModel, scene: Scene,
                         structure: Structure) -> CosseratContactModel:
    """``model`` with the bodies and contact law of ``scene``."""
    contact = build_body_contact(scene, structure)
    assert contact is not None
    fields = {f.name: getattr(model, f.name) for f in dataclasses.fields(model)}
    return CosseratContactModel(**fields, contact=contact)
