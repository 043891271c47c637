"""Contact forces of rigid bodies on the nodes of a thread model, with their tangents (NumPy).

The implicit integrators, static runs and the saved frames use these; the explicit loop runs the
compiled equivalent (:mod:`rodnet.kernels.contact_compiled`, checked against this module). For
every body, at its pose and velocity (a :class:`~rodnet.state.BodyMotion`): candidate points (B1)-(B2),
geometry in the body frame, the point law (K1)-(K4) with velocity-regularised friction (F2) on
the velocity relative to the body's material point (B6), and distribution to the segment nodes
(B5). The tangents hold the body still (implicit integrators run fixed bodies only). The tangents come
as one 6 x 6 block per segment, the layout of the thread elements' own blocks, so they add to the
element matrices before assembly. Equations: ``elements/contact/FORMULATION.md``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from rodnet.contact.bodies import BodyContact
from rodnet.contact.broadphase import (ContactPoints, body_point_velocity, body_reaction,
                                       contact_points, distribute_force, segment_blocks,
                                       shape_functions)
from rodnet.contact.geometry import FloatArray, SurfaceQuery
from rodnet.contact.laws import PointForces, contact_force, normal_energy
from rodnet.contact.rigid_body import kinetic_energy
from rodnet.state import BodyMotion


class BodyPoints(NamedTuple):
    """The contact points near one body and the forces on them."""

    points: ContactPoints
    forces: PointForces
    slip_velocity: FloatArray
    """(C, 3) tangential velocity of each point relative to the body [m/s]."""


def _world_query(contact: BodyContact, motion: BodyMotion, b: int,
                 local: FloatArray) -> SurfaceQuery:
    """Query body ``b`` at body-frame points ``local`` (C, 3); results in world frame."""
    R, p = motion.rotation[b], motion.position[b]
    q = contact.shapes[b].query(local)
    gradient = np.einsum("ij,pjk,lk->pil", R, q.normal_gradient, R)
    return SurfaceQuery(q.distance, np.einsum("ij,pj->pi", R, q.normal),
                        np.einsum("ij,pj->pi", R, q.closest) + p, gradient)


_NO_POINTS = ContactPoints(np.zeros(0, np.int64), np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)),
                          np.zeros(0))
"""No candidate point (a body out of reach)."""


def bodies_in_reach(contact: BodyContact, motion: BodyMotion, x: FloatArray) -> NDArray[np.bool_]:
    """Which bodies a thread point may touch at positions ``x`` (N, 3), (B,) bool.

    A cheap bounding-sphere test, the clearance of (E4): body b is out of reach when every
    segment's midpoint is farther from the body's centre than the body's bounding radius, the
    segment's half length, its radius and the law's smoothing together. A body out of reach has
    no point that presses on it.
    """
    from rodnet.kernels.contact_compiled import segment_clearance

    gap = segment_clearance(np.ascontiguousarray(x, dtype=np.float64), contact.segments,
                            contact.radius, float(contact.law.smoothing),
                            np.ascontiguousarray(motion.position), contact.bound_radius)
    return gap <= 0.0


def body_points(contact: BodyContact, motion: BodyMotion, x: FloatArray,
                v: FloatArray) -> list[BodyPoints]:
    """Contact points and point forces for every body at positions ``x`` and velocities ``v``
    (N, 3), with the bodies at ``motion``."""
    endpoints = x[contact.segments]
    near = bodies_in_reach(contact, motion, x)
    out = []
    for b, shape in enumerate(contact.shapes):
        if near[b]:
            points = contact_points(endpoints, contact.radius, motion.position[b],
                                    motion.rotation[b], shape.bounds, contact.law.smoothing,
                                    contact.points_per_segment, contact.segments)
        else:
            points = _NO_POINTS
        out.append(_evaluate(contact, motion, b, points, v))
    return out


def _evaluate(contact: BodyContact, motion: BodyMotion, b: int, points: ContactPoints,
              v: FloatArray) -> BodyPoints:
    """Point forces on the contact points ``points`` of body ``b``."""
    weights = shape_functions(points.parameter)
    ends = contact.segments[points.segment]
    velocity = weights[:, 0, None] * v[ends[:, 0]] + weights[:, 1, None] * v[ends[:, 1]]
    if contact.free[b]:
        velocity = velocity - body_point_velocity(points.position, motion.position[b],
                                                  motion.velocity[b], motion.omega[b])
    query = _world_query(contact, motion, b, points.local)
    forces = contact_force(query, velocity, contact.radius[points.segment], contact.law)
    normal_speed = np.einsum("pi,pi->p", query.normal, velocity)
    return BodyPoints(points, forces, velocity - normal_speed[:, None] * query.normal)


def nodal_force(contact: BodyContact, motion: BodyMotion, x: FloatArray,
                v: FloatArray) -> FloatArray:
    """Force of all bodies on every node [N], (N, 3)."""
    total = np.zeros_like(x)
    for bp in body_points(contact, motion, x, v):
        total += distribute_force(bp.forces.force, bp.points, contact.segments, len(x))
    return total


class ContactTangents(NamedTuple):
    """Nodal contact forces and their derivatives, per segment."""

    force: FloatArray
    """(N, 3) force on every node [N]."""
    d_position: FloatArray
    """(S, 6, 6) d(nodal force)/d(node positions) over the segment's nodes ``[a, b]`` [N/m]."""
    d_velocity: FloatArray
    """(S, 6, 6) d(nodal force)/d(node velocities) [N s/m]."""


def nodal_tangents(contact: BodyContact, motion: BodyMotion, x: FloatArray,
                   v: FloatArray) -> ContactTangents:
    """:func:`nodal_force` and its derivatives (K4), (B5), summed per segment."""
    n_seg = len(contact.segments)
    force = np.zeros_like(x)
    d_x, d_v = np.zeros((n_seg, 6, 6)), np.zeros((n_seg, 6, 6))
    for bp in body_points(contact, motion, x, v):
        force += distribute_force(bp.forces.force, bp.points, contact.segments, len(x))
        active = bp.forces.normal_force > 0.0
        if not active.any():
            continue
        seg, xi = bp.points.segment[active], bp.points.parameter[active]
        np.add.at(d_x, seg, segment_blocks(bp.forces.d_position[active], xi))
        np.add.at(d_v, seg, segment_blocks(bp.forces.d_velocity[active], xi))
    return ContactTangents(force, d_x, d_v)


class ContactState(NamedTuple):
    """What a saved frame reports about contact."""

    total_force: float
    """Sum of the magnitudes of the point forces [N]."""
    count: int
    """Points with a positive normal force."""
    body_force: FloatArray
    """(B, 3) force of the threads on each body [N]."""
    body_moment: FloatArray
    """(B, 3) its moment about the body's centre of mass [N m]."""
    friction_power: float
    """Rate of work dissipated by friction [W], >= 0."""


def contact_state(contact: BodyContact, motion: BodyMotion, x: FloatArray,
                  v: FloatArray) -> ContactState:
    """Contact totals at positions ``x`` and velocities ``v`` (N, 3)."""
    total, count, power = 0.0, 0, 0.0
    body_force = np.zeros((contact.n_bodies, 3))
    body_moment = np.zeros((contact.n_bodies, 3))
    if not bodies_in_reach(contact, motion, x).any():  # the common case while the target is far
        return ContactState(total, count, body_force, body_moment, power)
    for b, bp in enumerate(body_points(contact, motion, x, v)):
        f = bp.forces.force
        total += float(np.linalg.norm(f, axis=1).sum())
        count += int((bp.forces.normal_force > 0.0).sum())
        body_force[b], body_moment[b] = body_reaction(f, bp.points.position,
                                                      motion.position[b])
        # n is normal to the slip velocity, so f . v_T = f_T . v_T
        power -= float(np.einsum("pi,pi->", f, bp.slip_velocity))
    return ContactState(total, count, body_force, body_moment, power)


def step_travel(contact: BodyContact, motion: BodyMotion, x_old: FloatArray,
                x_new: FloatArray) -> float:
    """Largest travel over a step of the nodes of segments that pass near a body, as a multiple
    of the body's travel limit (above 1: the step is too long), (E3).

    A segment counts when the box of its old and new end positions, grown by the thread radius
    and the law's smoothing, overlaps the body's box: only then can a point on it reach the body
    during the step.
    """
    a, b = contact.segments[:, 0], contact.segments[:, 1]
    move = np.linalg.norm(x_new - x_old, axis=1)
    seg_move = np.maximum(move[a], move[b])
    reach = contact.radius + contact.law.smoothing
    worst = 0.0
    for k, shape in enumerate(contact.shapes):
        R, p = motion.rotation[k], motion.position[k]
        corners = np.stack([x_old[a], x_old[b], x_new[a], x_new[b]], axis=1)
        local = np.einsum("sci,ij->scj", corners - p, R)
        lower, upper = local.min(axis=1) - reach[:, None], local.max(axis=1) + reach[:, None]
        near = np.all((lower <= shape.bounds[1]) & (upper >= shape.bounds[0]), axis=1)
        if near.any():
            worst = max(worst, float(seg_move[near].max()) / float(contact.travel_limit[k]))
    return worst



def body_energy(contact: BodyContact, motion: BodyMotion, x: FloatArray) -> dict[str, float]:
    """The energy terms [J] of the bodies: the free bodies' ``kinetic`` energy, their gravity
    ``potential``, and ``contact``, the energy stored in the penalty springs (N4) at positions
    ``x`` (N, 3)."""
    free = contact.free
    return {"kinetic": kinetic_energy(contact.mass, contact.inertia, motion, free) if free.any() else 0.0,
            "potential": -float(np.sum(contact.mass[free] * (motion.position[free] @ contact.gravity)))
            if free.any() else 0.0,
            "contact": penalty_energy(contact, motion, x)}


def penalty_energy(contact: BodyContact, motion: BodyMotion, x: FloatArray) -> float:
    """Energy stored in the penalty springs of every body within reach (N4) [J]; x (N, 3)."""
    energy = 0.0
    for b in np.flatnonzero(bodies_in_reach(contact, motion, x)):
        points = contact_points(x[contact.segments], contact.radius, motion.position[b],
                                motion.rotation[b], contact.shapes[b].bounds,
                                contact.law.smoothing, contact.points_per_segment,
                                contact.segments)
        if len(points.segment):
            delta = contact.radius[points.segment] - contact.shapes[b].query(points.local).distance
            energy += float(normal_energy(delta, contact.law.stiffness, contact.law.smoothing).sum())
    return energy


def pressed_nodes(contact: BodyContact, motion: BodyMotion, x: FloatArray, v: FloatArray) -> bytes:
    """Which nodes a body pushes on, packed: the contact part of a model's active set."""
    return np.packbits(np.any(nodal_force(contact, motion, x, v) != 0.0, axis=1)).tobytes()
