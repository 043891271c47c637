"""The lumped model (and cable threads) with rigid bodies: contact as one more force term.

:class:`LumpedContactModel` is a :class:`~rodnet.reference.lumped.LumpedModel` whose generalized
force and tangents include the contact forces of :mod:`rodnet.contact.forces` (so backward Euler,
generalized-alpha, midpoint and static runs see contact with its consistent tangent, (K4)), and
whose explicit stability limit includes the contact springs (E1). Saved frames report contact
through :class:`rodnet.contact.output.ContactLog`. The plain :class:`LumpedModel` of a scene
without bodies has none of this. Two optional hooks tell the implicit integrator about contact: :meth:`LumpedContactModel.step_travel` (a step that moves a
point near a body more than its travel limit is retried shorter) and
:meth:`LumpedContactModel.after_step` (friction work of every accepted step).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from rodnet.config import Scene
from rodnet.contact.bodies import BodyContact, build_body_contact
from rodnet.contact.forces import (add_body_energy, add_friction_work, nodal_force, nodal_tangents,
                                   pressed_nodes, step_travel)
from rodnet.integrate.frames import StepStats
from rodnet.reference.lumped import FloatArray, LumpedModel


@dataclass(frozen=True)
class LumpedContactModel(LumpedModel):
    """A lumped model with rigid bodies (see the module docstring).

    Attributes
    ----------
    contact : BodyContact
    """

    contact: BodyContact

    def energy(self, x: FloatArray, v: FloatArray, t: float) -> dict[str, float]:
        """Kinetic, elastic and external-load energy [J] as the lumped model, with the free
        bodies' kinetic energy (at ``contact.motion``) in ``kinetic`` and their gravity
        potential in ``potential``, plus ``contact``: the energy stored in the penalty springs
        (N4)."""
        return add_body_energy(super().energy(x, v, t), self.contact, np.asarray(x))

    def generalized_force(self, x: FloatArray, v: FloatArray, t: float,
                          load_factor: float = 1.0) -> FloatArray:
        g = super().generalized_force(x, v, t, load_factor)
        return g - nodal_force(self.contact, x, v.reshape(-1, 3)).ravel()

    def tangents(self, x: FloatArray, v: FloatArray, t: float, load_factor: float = 1.0):
        """g (n_dof,), K and C on the free DOFs, with the contact tangent (K4) added to each
        segment's block."""
        g, K_blocks, C_blocks = self.tangent_blocks(x, v, t, load_factor)
        c = nodal_tangents(self.contact, x, v.reshape(-1, 3))
        g -= c.force
        pattern = self._pattern
        return g.ravel(), pattern.matrix([K_blocks - c.d_position]), \
            pattern.matrix([C_blocks - c.d_velocity])

    def stable_step(self) -> float:
        """(S10) combined with the contact springs (E1), :meth:`BodyContact.combined_step`."""
        return self.contact.combined_step(super().stable_step(), self.inv_mass)

    def far_stable_step(self) -> float:
        """(S10) of the threads alone [s]: the explicit loop's step limit while no body is within
        reach of a thread (E5)."""
        return super().stable_step()

    def active_set(self, x: FloatArray, v: FloatArray) -> int:
        return hash((super().active_set(x, v), pressed_nodes(self.contact, x, v.reshape(-1, 3))))

    def step_travel(self, x_old: FloatArray, x_new: FloatArray) -> float:
        """Travel of the points near a body over a step as a multiple of the travel limit."""
        return step_travel(self.contact, np.asarray(x_old), np.asarray(x_new))

    def after_step(self, x: FloatArray, v: FloatArray, dt: float, stats: StepStats) -> None:
        """Add the friction work of an accepted step ending in ``x``, ``v`` to
        ``stats.extra["friction_work"]`` [J] (friction power at the end of the step times dt)."""
        add_friction_work(self.contact, np.asarray(x), np.asarray(v).reshape(-1, 3), dt, stats)


def with_bodies(model: LumpedModel, scene: Scene) -> LumpedContactModel:
    """``model`` with the bodies and contact law of ``scene``."""
    contact = build_body_contact(scene, model.structure)
    assert contact is not None
    fields = {f.name: getattr(model, f.name) for f in dataclasses.fields(model)}
    return LumpedContactModel(**fields, contact=contact)
