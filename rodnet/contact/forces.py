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
from rodnet.kernels import so3
from rodnet.state import BodyMotion


class BodyPoints(NamedTuple):
    """The contact points near one body and the forces on them."""

    points: ContactPoints
    forces: PointForces
    slip_velocity: FloatArray
    """(C, 3) tangential velocity of each point relative to the body [m/s]."""
    depth: FloatArray
    """(C,) how far each point's thread surface lies inside the body [m] (radius minus the
    signed distance of its centreline; negative: a gap)."""


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
    radius = contact.radius[points.segment]
    forces = contact_force(query, velocity, radius, contact.law)
    normal_speed = np.einsum("pi,pi->p", query.normal, velocity)
    return BodyPoints(points, forces, velocity - normal_speed[:, None] * query.normal,
                      radius - query.distance)


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


class CoupledTangents(NamedTuple):
    """Contact forces and their derivatives with the free bodies' motion as unknowns too."""

    force: FloatArray
    """(N, 3) force on every node [N]."""
    body_force: FloatArray
    """(B, 3) sum of the point forces on the threads near each body, ``sum f`` [N] (the body
    feels its negative)."""
    body_moment: FloatArray
    """(B, 3) ``sum (p - c) x f`` about each body's centre, world axes [N m] (the body feels its
    negative)."""
    d_position: FloatArray
    """(S, 6, 6) as :class:`ContactTangents`, for the fixed bodies."""
    d_velocity: FloatArray
    """(S, 6, 6)."""
    coupled_position: dict[int, FloatArray]
    """Free body b -> (S, 12, 12) derivatives of ``[g_a, g_b, g_c, g_phi]`` with respect to
    ``[x_a, x_b, c, phi]`` (B7)."""
    coupled_velocity: dict[int, FloatArray]
    """Free body b -> (S, 12, 12) the same with respect to ``[v_a, v_b, V, W]``."""


def coupled_tangents(contact: BodyContact, motion: BodyMotion, frames: FloatArray,
                     x: FloatArray, v: FloatArray, need_matrices: bool = True) -> CoupledTangents:
    """Contact forces on the nodes and, per body, their sum and moment, with the derivatives
    that couple every segment to the motion of each free body (B7)-(B9).

    A free body's unknowns are its centre ``c``, a rotation ``phi`` in the body frame
    ``frames[b]`` (``R_b -> R_b exp(hat(phi))``), its velocity ``V`` and angular velocity ``W``
    in that frame. The generalized forces of the threads are ``g_a = -N_a f`` (per point force
    ``f`` at ``p = N_a x_a + N_b x_b``), those of the body ``g_c = f`` and
    ``g_phi = R_b^T (p - c) x f``: the body takes the reaction at the thread's point, so that
    forces and moments of contact cancel exactly.

    Parameters
    ----------
    frames : (B, 3, 3) float
        World rotation of the frame each free body's rotation unknown lives in (its principal
        axes); ignored for fixed bodies.
    x, v : (N, 3) float
        Node positions [m] and velocities [m/s].
    """
    n_seg = len(contact.segments)
    force = np.zeros_like(x)
    body_force = np.zeros((contact.n_bodies, 3))
    body_moment = np.zeros((contact.n_bodies, 3))
    d_x, d_v = np.zeros((n_seg, 6, 6)), np.zeros((n_seg, 6, 6))
    coupled_x: dict[int, FloatArray] = {}
    coupled_v: dict[int, FloatArray] = {}
    eye = np.eye(3)
    for b, bp in enumerate(body_points(contact, motion, x, v)):
        f_all = bp.forces.force
        force += distribute_force(f_all, bp.points, contact.segments, len(x))
        arm_all = bp.points.position - motion.position[b]
        body_force[b] = f_all.sum(axis=0)
        body_moment[b] = np.cross(arm_all, f_all).sum(axis=0)
        if contact.free[b] and need_matrices:
            coupled_x[b], coupled_v[b] = np.zeros((n_seg, 12, 12)), np.zeros((n_seg, 12, 12))
        active = bp.forces.normal_force > 0.0
        if not need_matrices or not active.any():
            continue
        seg, xi = bp.points.segment[active], bp.points.parameter[active]
        D_p, D_u = bp.forces.d_position[active], bp.forces.d_velocity[active]
        if not contact.free[b]:
            np.add.at(d_x, seg, segment_blocks(D_p, xi))
            np.add.at(d_v, seg, segment_blocks(D_u, xi))
            continue
        f, arm = f_all[active], arm_all[active]
        R = frames[b]
        omega = motion.omega[b]
        w = shape_functions(xi)                                    # (C, 2)
        ends = contact.segments[seg]
        u_trans = w[:, 0, None] * v[ends[:, 0]] + w[:, 1, None] * v[ends[:, 1]] \
            - motion.velocity[b]
        hat_r, hat_f, hat_w = so3.hat(arm), so3.hat(f), so3.hat(omega)
        D_x = D_p - D_u @ hat_w                                    # df/dp, body still
        F_psi = -hat_f + D_p @ hat_r + D_u @ (so3.hat(u_trans) - hat_w @ hat_r)
        A = np.concatenate([w[:, 0, None, None] * D_x, w[:, 1, None, None] * D_x, -D_x,
                            F_psi @ R], axis=2)                    # (C, 3, 12)
        Cv = np.concatenate([w[:, 0, None, None] * D_u, w[:, 1, None, None] * D_u, -D_u,
                             D_u @ hat_r @ R], axis=2)
        rows = np.concatenate([-w[:, 0, None, None] * eye, -w[:, 1, None, None] * eye,
                               np.broadcast_to(eye, (len(f), 3, 3)),
                               R.T @ hat_r], axis=1)               # (C, 12, 3)
        K = rows @ A
        m_body = np.einsum("ji,cj->ci", R, np.cross(arm, f))       # R^T (p - c) x f
        K[:, 9:, 0:3] -= w[:, 0, None, None] * (R.T @ hat_f)
        K[:, 9:, 3:6] -= w[:, 1, None, None] * (R.T @ hat_f)
        K[:, 9:, 6:9] += R.T @ hat_f
        K[:, 9:, 9:] += so3.hat(m_body)
        np.add.at(coupled_x[b], seg, K)
        np.add.at(coupled_v[b], seg, rows @ Cv)
    return CoupledTangents(force, body_force, body_moment, d_x, d_v, coupled_x, coupled_v)


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
    sunk: float
    """The largest depth of a thread's surface in a body as a fraction of its radius (1: the
    centreline on the surface); 0 without contact."""


def contact_state(contact: BodyContact, motion: BodyMotion, x: FloatArray,
                  v: FloatArray) -> ContactState:
    """Contact totals at positions ``x`` and velocities ``v`` (N, 3)."""
    total, count, power, sunk = 0.0, 0, 0.0, 0.0
    body_force = np.zeros((contact.n_bodies, 3))
    body_moment = np.zeros((contact.n_bodies, 3))
    if not bodies_in_reach(contact, motion, x).any():  # the common case while the target is far
        return ContactState(total, count, body_force, body_moment, power, sunk)
    for b, bp in enumerate(body_points(contact, motion, x, v)):
        if len(bp.depth):
            sunk = max(sunk, float((bp.depth / contact.radius[bp.points.segment]).max()))
        f = bp.forces.force
        total += float(np.linalg.norm(f, axis=1).sum())
        count += int((bp.forces.normal_force > 0.0).sum())
        body_force[b], body_moment[b] = body_reaction(f, bp.points.position,
                                                      motion.position[b])
        # n is normal to the slip velocity, so f . v_T = f_T . v_T
        power -= float(np.einsum("pi,pi->", f, bp.slip_velocity))
    return ContactState(total, count, body_force, body_moment, power, sunk)


def step_travel(contact: BodyContact, motion: BodyMotion, x_old: FloatArray,
                x_new: FloatArray, old_motion: BodyMotion | None = None) -> float:
    """Largest travel over a step of the nodes of segments that pass near a body, as a multiple
    of the body's travel limit (above 1: the step is too long), (E3).

    A segment counts when the box of its old and new end positions, grown by the thread radius
    and the law's smoothing, overlaps the body's box: only then can a point on it reach the body
    during the step. With ``old_motion`` (bodies that moved over the step to ``motion``) the
    old positions are carried along with each body, so that the travel is relative to it.
    """
    a, b = contact.segments[:, 0], contact.segments[:, 1]
    reach = contact.radius + contact.law.smoothing
    worst = 0.0
    x_before = x_old
    for k, shape in enumerate(contact.shapes):
        R, p = motion.rotation[k], motion.position[k]
        if old_motion is not None:  # old positions in the body's frame, placed at its new pose
            x_old = p + (x_before - old_motion.position[k]) @ old_motion.rotation[k] @ R.T
        move = np.linalg.norm(x_new - x_old, axis=1)
        seg_move = np.maximum(move[a], move[b])
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
