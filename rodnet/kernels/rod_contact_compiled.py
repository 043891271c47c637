"""Compiled explicit step loop of Cosserat rods with rigid bodies: contact and free bodies.

The rod part of every step is that of :func:`rodnet.kernels.cosserat_compiled._advance_explicit`
(``elements/cosserat/FORMULATION.md`` (C46)-(C50)); the contact part is that of the lumped
model's loop, :func:`rodnet.kernels.contact_compiled.advance_contact`
(``elements/contact/FORMULATION.md`` (E1)-(E5), (R1)-(R4)). The thread is the capsule around the
chord between an element's two position nodes (B1)-(B3), so contact acts on the positions only
(B5), as in the implicit rod model :mod:`rodnet.contact.cosserat`.

The step control of the two parts is merged in one time-driven loop, landing on ``t_end``: the
step is the base step times the bent-element factor (C50); the base step starts at ``h0`` and,
for the rest of the call (one frame interval), drops to ``near_h`` once a body is within reach
(E5), and to 0.9 times the travel-limited step when a point near a body would move more than its
travel limit (E3). A step is then redone from the same state; nothing is returned to Python.
"""

from __future__ import annotations

import numba
import numpy as np

from rodnet.contact.rigid_body import advance_bodies
from rodnet.kernels.contact_compiled import (accumulate_contact, body_speed, forget_clearance,
                                             largest_speed, select_bodies)
from rodnet.kernels.cosserat_compiled import (_element_forces, _nodal_forces, _step_length,
                                              _update_explicit)


@numba.njit(cache=True, parallel=True)
def advance_rods_contact(x, quat, v, W, t0, t_end, h0, near_h, min_h,
                         pos_nodes, rot_nodes, offset_q, offset_R, rest_length, reference_strain,
                         stiffness, tau, tension_only, kink, series, beta_angle, gamma_angle,
                         angles, step_factor,
                         inv_mass, inertia, inv_inertia, weight, load_nodes, load_rot, load_force,
                         load_moment, load_ramp,
                         xe, qe, ve, force, monitor, f_node, m_node,
                         contact_inv_mass, segments, radius, node_share, kind, body_size,
                         body_bounds, bound_radius, travel_limit, body_compliance, mesh_root, tri,
                         lower, upper, left, right, start, count, order, face_normal, edge_normal,
                         corner_normal, contact_stiffness, damping, friction, smoothing,
                         slip_velocity, points_per_segment,
                         body_position, body_rotation, body_velocity, body_omega,
                         body_quaternion, body_momentum, body_inv_mass, body_inertia,
                         body_inv_inertia, body_gravity,
                         taken, body_force, body_moment, clearance, travelled):  # pragma: no cover
    """Advance the rods (``x`` (N, 3), ``quat`` (R, 4), ``v`` (N, 3), ``W`` (R, 3)) and the free
    bodies in place from ``t0`` to ``t_end`` [s] (see the module docstring).

    The arguments up to ``m_node`` are those of
    :func:`rodnet.kernels.cosserat_compiled._advance_explicit` (``h0`` the base step [s]);
    ``near_h`` [s] is the step limit with the contact springs (E1) and ``min_h`` [s] the shortest
    travel-limited base step accepted. From ``contact_inv_mass`` (N,) [1/kg] to
    ``points_per_segment`` the arguments are those of
    :func:`rodnet.kernels.contact_compiled.accumulate_contact` (with ``segments`` the elements'
    position nodes), then the bodies' state and mass properties and the scratch of
    :func:`rodnet.kernels.contact_compiled.advance_contact` (``clearance`` and ``travelled`` (B,)
    carry over from call to call: start with ``-inf`` and 0).

    Returns
    -------
    status : int
        0 done; 1 the state became non-finite; 2 the travel-limited step fell below ``min_h``.
    t : float
        The time reached [s].
    steps : int
    h_min : float
        The shortest step taken [s] before the cut of the last one to land on ``t_end``.
    peak, phi_max : float
        The largest axial force [N] and element rotation [rad] met on the way.
    friction_work : float
        Work dissipated by friction [J].
    """
    active = np.zeros(kind.shape[0], np.bool_)
    scratch = np.empty((9, 3))  # for the free bodies' update
    peak, phi_max, h_min, work = 0.0, 0.0, h0, 0.0
    t, steps, base = t0, 0, h0
    node_speed = largest_speed(v)
    while t < t_end:
        step_peak, phi = _element_forces(x, quat, v, W, pos_nodes, rot_nodes, offset_q, offset_R,
                                         rest_length, reference_strain, stiffness, tau,
                                         tension_only, kink, series, beta_angle, gamma_angle, xe,
                                         qe, ve, force, monitor)
        h_full, h, last = _step_length(base, phi, angles, step_factor, t, t_end)
        _nodal_forces(t, quat, pos_nodes, rot_nodes, offset_R, force, weight, load_nodes,
                      load_rot, load_force, load_moment, load_ramp, f_node, m_node)
        any_active = select_bodies(h, node_speed, body_velocity, body_omega, bound_radius,
                                   travelled, clearance, active, body_force, body_moment)
        power = 0.0
        if any_active:
            if h > near_h * (1.0 + 1e-12):  # (E5): contact needs the shorter step; redo
                forget_clearance(active, clearance)
                base = near_h
                continue
            power, _, _, allowed = accumulate_contact(
                x, v, f_node, h, contact_inv_mass, segments, radius, node_share, kind, body_size,
                body_bounds, bound_radius, travel_limit, body_compliance, mesh_root, tri, lower,
                upper, left, right, start, count, order, face_normal, edge_normal, corner_normal,
                contact_stiffness, damping, friction, smoothing, slip_velocity,
                points_per_segment, body_position, body_rotation, body_velocity, body_omega,
                active, taken, body_force, body_moment, clearance)
            if allowed < h:  # (E3): a point near a body would jump too far; redo shorter
                forget_clearance(active, clearance)
                base = min(base, 0.9 * allowed)
                if base < min_h:
                    return 2, t, steps, h_min, peak, phi_max, work
                continue
        peak = max(peak, step_peak)
        phi_max = max(phi_max, phi)
        h_min = min(h_min, h_full)
        work += h * power
        finite = _update_explicit(x, quat, v, W, f_node, m_node, inv_mass, inertia, inv_inertia, h)
        node_speed = largest_speed(v)
        advance_bodies(h, body_force, body_moment, body_inv_mass, body_inertia, body_inv_inertia,
                       body_gravity, body_position, body_velocity, body_quaternion, body_rotation,
                       body_momentum, body_omega, scratch)
        for b in range(active.shape[0]):
            travelled[b] += h * (2.0 * node_speed + body_speed(body_velocity, body_omega,
                                                               bound_radius, b))
        steps += 1
        t = t_end if last else t + h
        if not finite:
            return 1, t, steps, h_min, peak, phi_max, work
    return 0, t, steps, h_min, peak, phi_max, work
