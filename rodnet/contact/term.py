"""Contact with rigid bodies as one force term any thread model carries.

The thread is a capsule around the chord of every segment (a lumped segment, a cable element or
a rod element's two position nodes, (B1)-(B3)); contact acts on the positions only (B5). The
term gives what a system composes (:class:`rodnet.models.system.ThreadSystem`): the nodal
contact force and its consistent tangent (K4) as one 6 x 6 block per segment over its nodes'
positions ``[x_a, x_b]``, a fingerprint of the pressed nodes, the travel of points near a body
over a step (E3), the friction work of a step, the energy stored in the penalty springs (N4) and
the bodies' energy, the arrays of the compiled explicit loop and its stability limit with the
contact springs (E1), and what a saved frame and the summary report. Rotations do not enter:
friction acts at the centreline, and its moment about the thread axis is neglected
(FORMULATION section 6).

The bodies' pose and velocity come with every call, from the run's state: the term holds no
state. In an implicit run the free bodies are unknowns of the global system beside the threads
(FORMULATION section 9): :meth:`ContactTerm.moving_unknowns` gives their start values,
:meth:`ContactTerm.motion` the bodies' motion from them, and :meth:`ContactTerm.coupled` the
forces and the tangent blocks that couple every segment to every free body. Equations:
``elements/contact/FORMULATION.md``; user guide: ``docs/contact.md``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rodnet.contact.bodies import BodyContact
from rodnet.contact.forces import (CoupledTangents, body_energy, contact_state,
                                   coupled_tangents, nodal_force, nodal_tangents, pressed_nodes,
                                   step_travel)
from rodnet.contact.kernel_data import kernel_data
from rodnet.contact.surfaces import surface_triangles
from rodnet.kernels.contact_compiled import ContactData
from rodnet.kernels import so3
from rodnet.kernels.explicit import BodyMass
from rodnet.state import BodyMotion

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class ContactTerm:
    """The contact of a model's segments with the bodies of a scene.

    Attributes
    ----------
    bodies : BodyContact
        The bodies, the law and the thread radii; ``bodies.segments`` are the model's segments
        (position nodes of each element).
    inv_mass : (N,) float
        1 / mass of every node with a free axis, 0 for a fully supported one [1/kg]: the masses
        contact sees (its stability limit (E1) and friction cap (E2)).
    """

    bodies: BodyContact
    inv_mass: FloatArray

    @property
    def n_bodies(self) -> int:
        return self.bodies.n_bodies

    @cached_property
    def dofs(self) -> NDArray[np.int64]:
        """(S, 6) the translational DOFs ``[x_a, x_b]`` of every segment: the DOFs of the
        tangent blocks of :meth:`tangents`."""
        return (3 * self.bodies.segments[:, :, None] + np.arange(3)).reshape(-1, 6)

    def start_motion(self) -> BodyMotion:
        return self.bodies.start_motion()

    # --- forces and tangents (the bodies at ``motion``) ----------------------------------

    def force(self, x: FloatArray, v: FloatArray, motion: BodyMotion) -> FloatArray:
        """Force of all bodies on every node [N], (N, 3), at positions and velocities (N, 3)."""
        return nodal_force(self.bodies, motion, x, v)

    def tangents(self, x: FloatArray, v: FloatArray,
                 motion: BodyMotion) -> tuple[FloatArray, FloatArray, FloatArray]:
        """The force (N, 3) and its derivatives with respect to the positions and velocities of
        every segment's nodes, (S, 6, 6) each (K4), (B5)."""
        c = nodal_tangents(self.bodies, motion, x, v)
        return c.force, c.d_position, c.d_velocity

    def active_set(self, x: FloatArray, v: FloatArray, motion: BodyMotion) -> bytes:
        return pressed_nodes(self.bodies, motion, x, v)

    def step_travel(self, x_old: FloatArray, x_new: FloatArray, motion: BodyMotion,
                    old_motion: BodyMotion | None = None) -> float:
        """Travel of the points near a body over a step as a multiple of the travel limit (E3);
        relative to the body when it moved from ``old_motion``."""
        return step_travel(self.bodies, motion, x_old, x_new, old_motion)

    def energy(self, x: FloatArray, motion: BodyMotion) -> dict[str, float]:
        """The bodies' ``kinetic`` and gravity ``potential`` energy and the ``contact`` energy
        in the penalty springs (N4) [J], to add to the threads'."""
        return body_energy(self.bodies, motion, x)

    # --- free bodies as unknowns of an implicit system (FORMULATION section 9) -------------

    @cached_property
    def moving(self) -> NDArray[np.int64]:
        """(F,) indices of the free bodies."""
        return np.flatnonzero(self.bodies.free)

    @cached_property
    def principal(self) -> tuple[FloatArray, FloatArray]:
        """Principal axes ``P`` (F, 3, 3) (columns, det +1) of every free body's inertia in body
        axes, and its principal moments ``J`` (F, 3) [kg m^2]: ``inertia = P diag(J) P^T``."""
        J, P = np.linalg.eigh(self.bodies.inertia[self.moving].reshape(-1, 3, 3))
        P[:, :, 2] *= np.sign(np.linalg.det(P))[:, None]
        return P, J

    @property
    def moving_mass(self) -> FloatArray:
        """(F,) mass of every free body [kg]."""
        return self.bodies.mass[self.moving]

    def moving_unknowns(self, motion: BodyMotion
                        ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """The free bodies' unknowns at ``motion``: centres (F, 3), principal-axes quaternions
        (F, 4), velocities (F, 3) and angular velocities in principal axes (F, 3)."""
        P, _ = self.principal
        f = self.moving
        frames = np.einsum("fij,fjk->fik", motion.rotation[f], P)
        quat = np.array([so3.quat_from_matrix(R) for R in frames]).reshape(-1, 4)
        W = np.einsum("fji,fj->fi", frames, motion.omega[f])
        return motion.position[f].copy(), quat, motion.velocity[f].copy(), W

    def motion(self, body_x: FloatArray, body_quat: FloatArray, V: FloatArray,
               W: FloatArray) -> BodyMotion:
        """Every body's motion with the free ones at the unknowns ``body_x`` (F, 3),
        ``body_quat`` (F, 4), ``V`` (F, 3), ``W`` (F, 3) (as :meth:`moving_unknowns`)."""
        motion = self.bodies.start_motion()
        if not len(self.moving):
            return motion
        P, J = self.principal
        f = self.moving
        frames = self.frames(body_quat)[f]
        rotation = np.einsum("fij,fkj->fik", frames, P)
        motion.position[f], motion.velocity[f] = body_x, V
        motion.rotation[f] = rotation
        motion.quaternion[f] = [so3.quat_from_matrix(R) for R in rotation]
        motion.omega[f] = np.einsum("fij,fj->fi", frames, W)
        motion.momentum[f] = np.einsum("fij,fj->fi", frames, J * W)
        return motion

    def frames(self, body_quat: FloatArray) -> FloatArray:
        """(B, 3, 3) the principal frames of the free bodies (identity for fixed ones)."""
        out = np.tile(np.eye(3), (self.n_bodies, 1, 1))
        if len(self.moving):
            out[self.moving] = [so3.quat_to_matrix(q) for q in body_quat]
        return out

    def coupled(self, x: FloatArray, v: FloatArray, motion: BodyMotion, frames: FloatArray,
                need_matrices: bool) -> CoupledTangents:
        """Forces on the nodes and bodies and, when asked, the tangent blocks coupling the
        segments to the free bodies (B7)-(B9): :func:`rodnet.contact.forces.coupled_tangents`."""
        return coupled_tangents(self.bodies, motion, frames, x, v, need_matrices)

    # --- the explicit loop ---------------------------------------------------------------

    @cached_property
    def kernel_data(self) -> ContactData:
        """The contact arrays of the compiled explicit loop (built once)."""
        return kernel_data(self.bodies, self.inv_mass)

    def body_mass(self) -> BodyMass:
        """The bodies' mass properties for (R1)-(R4): fixed bodies get zeros."""
        b = self.bodies
        inertia = np.ascontiguousarray(np.where(b.free[:, None, None], b.inertia, 0.0))
        return BodyMass(b.inv_mass, inertia, b.inv_inertia, np.asarray(b.gravity, dtype=float))

    def combined_step(self, threads: float) -> float:
        """The explicit limit [s] of threads whose own limit is ``threads`` [s] with the contact
        springs added (E1)."""
        return self.bodies.combined_step(threads, self.inv_mass)

    # --- output --------------------------------------------------------------------------

    def frame_arrays(self, x: FloatArray, v: FloatArray, motion: BodyMotion,
                     friction_work: float,
                     applied: tuple[FloatArray, FloatArray] | None = None) -> dict[str, Any]:
        """What a saved frame holds of contact: ``contact_force`` [N] (sum of the magnitudes of
        the point forces), ``contact_count``, ``contact_depth`` (the deepest thread surface in a
        body, in thread radii), ``friction_work`` [J] so far, and per body (B, 3)
        ``body_force`` [N], ``body_moment`` [N m] (about the centre of mass; ``applied``, the
        explicit loop's last step's, where given), ``body_positions``, ``body_velocities``,
        ``body_angular_velocities`` (world axes) and ``body_rotations`` (B, 4)."""
        state = contact_state(self.bodies, motion, x, v)
        force, moment = (state.body_force, state.body_moment) if applied is None else applied
        return {"contact_force": state.total_force, "contact_count": state.count,
                "contact_depth": state.sunk, "friction_work": friction_work, "body_force": force,
                "body_moment": moment, "body_positions": np.array(motion.position),
                "body_rotations": np.array(motion.quaternion),
                "body_velocities": np.array(motion.velocity),
                "body_angular_velocities": np.array(motion.omega)}

    def surfaces(self) -> list[tuple[str, FloatArray, NDArray[np.int64]]]:
        """``(name, vertices (V, 3) in the body frame [m], faces (F, 3))`` of every body."""
        return [(name, *surface_triangles(shape))
                for name, shape in zip(self.bodies.names, self.bodies.shapes)]

    def summary(self, arrays: dict[str, Any]) -> dict[str, Any]:
        """What a run with bodies adds to ``summary.json``: ``bodies`` (name to index), the
        ``contact`` time series and the metrics ``max_contact_force``, ``max_contact_count``,
        ``max_contact_depth`` (thread radii) and ``friction_work``; and ``body_names`` to the
        arrays."""
        arrays["body_names"] = np.array(self.bodies.names, dtype=str)
        force = arrays.get("contact_force", np.zeros(0))
        count = arrays.get("contact_count", np.zeros(0, np.int64))
        depth = arrays.get("contact_depth", np.zeros(0))
        work = arrays.get("friction_work", np.zeros(0))
        return {"bodies": {name: i for i, name in enumerate(self.bodies.names)},
                "contact": {"time": [float(t) for t in arrays["time"]], "force": force.tolist(),
                            "count": [int(c) for c in count],
                            "friction_work": [float(w) for w in work]},
                "metrics": {"max_contact_force": float(force.max(initial=0.0)),
                            "max_contact_count": int(count.max(initial=0)),
                            "max_contact_depth": float(depth.max(initial=0.0)),
                            "friction_work": float(work[-1]) if len(work) else 0.0}}
