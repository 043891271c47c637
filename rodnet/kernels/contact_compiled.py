"""Compiled contact forces of thread points against rigid bodies.

One call of :func:`accumulate_contact` does, for every body, the broad phase (B1)-(B2) over all
segments, the signed distance and normal of each candidate point ((G4)-(G10): box, cylinder,
sphere, triangle mesh through its bounding-volume hierarchy), the penalty normal force (N1)-(N3),
velocity-regularised friction (F1)-(F2) on the velocity relative to the body, and the distribution
to the segment's nodes (B5) with the body's reaction force and moment (B6). Equations:
``elements/contact/FORMULATION.md``. The NumPy building blocks of :mod:`rodnet.contact` are the
oracle: ``tests/contact/test_contact_model.py`` checks this kernel against them point by point.

Two things are specific to the explicit scheme, (E2)-(E3). Friction acts on the slip the step
would end with under the forces added so far, this point's friction left out, and its viscous
slope ``mu N / S`` is capped at ``m_eff / dt`` (``m_eff`` the point's effective mass
``1 / (N_a^2/m_a + N_b^2/m_b)``): each point's friction stops at most that slip, a step of
coordinate descent on the step's kinetic energy, so it holds a sticking point and never adds
energy; sliding friction ``mu N`` is unchanged. And every
segment whose nodes could reach a body within the step reports the step that keeps its travel
within the body's travel limit, so the explicit loop (:mod:`rodnet.kernels.explicit`) can shorten
the step before a point jumps over a thin body; the loop visits a body only when a thread can
have come within its reach since the last visit (E4, :func:`select_bodies`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np

from rodnet.kernels.mesh_distance import STACK_DEPTH, nearest_triangle


class ContactData(NamedTuple):
    """The read-only arrays of the contact of thread segments with rigid bodies.

    ``inv_mass`` (N,): 1 / mass of the nodes [1/kg] for the friction cap (E2); ``segments``
    (S, 2) node pairs and ``radius`` (S,) [m]; per body (B): ``kind`` (0 box, 1 cylinder, 2
    sphere, 3 mesh), ``body_size`` (B, 3), ``body_bounds`` (B, 2, 3) [m], ``bound_radius``, ``travel_limit`` [m], ``body_compliance``
    [1/kg] and ``mesh_root`` (-1 for primitives); the meshes' hierarchies and pseudonormals
    concatenated (``tri`` ... ``corner_normal``); the law's ``stiffness`` [N/m], ``damping``
    [N s/m], ``friction``, ``smoothing`` [m], ``slip_velocity`` [m/s]; ``points_per_segment``.
    A scene without bodies has B = 0.
    """

    inv_mass: np.ndarray
    segments: np.ndarray
    radius: np.ndarray
    kind: np.ndarray
    body_size: np.ndarray
    body_bounds: np.ndarray
    bound_radius: np.ndarray
    travel_limit: np.ndarray
    body_compliance: np.ndarray
    mesh_root: np.ndarray
    tri: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    left: np.ndarray
    right: np.ndarray
    start: np.ndarray
    count: np.ndarray
    order: np.ndarray
    face_normal: np.ndarray
    edge_normal: np.ndarray
    corner_normal: np.ndarray
    stiffness: float
    damping: float
    friction: float
    smoothing: float
    slip_velocity: float
    points_per_segment: int


class ContactScratch(NamedTuple):
    """Work arrays of :func:`accumulate_contact` and the explicit loop's body selection:
    ``active`` (B,) bool, ``taken`` (N,) bool (all False between calls), ``body_force`` and
    ``body_moment`` (B, 3) [N, N m]; ``clearance`` (B,) [m] and ``travelled`` (B,) [m] carry over
    from step to step (start with ``-inf`` and 0)."""

    active: np.ndarray
    taken: np.ndarray
    body_force: np.ndarray
    body_moment: np.ndarray
    clearance: np.ndarray
    travelled: np.ndarray


def no_contact() -> ContactData:
    """:class:`ContactData` without bodies (a scene without ``[[bodies]]``)."""
    z, i = np.zeros, np.int64
    return ContactData(z(0), z((0, 2), i), z(0), z(0, i), z((0, 3)), z((0, 2, 3)), z(0),
                       z(0), z(0), z(0, i), z((0, 3, 3)), z((0, 3)), z((0, 3)), z(0, i), z(0, i),
                       z(0, i), z(0, i), z(0, i), z((0, 3)), z((0, 3, 3)), z((0, 3, 3)), 0.0, 0.0,
                       0.0, 0.0, 1.0, 1)


def contact_scratch(n_nodes: int, n_bodies: int) -> ContactScratch:
    """Fresh :class:`ContactScratch` for ``n_nodes`` nodes and ``n_bodies`` bodies."""
    return ContactScratch(np.zeros(n_bodies, np.bool_), np.zeros(n_nodes, np.bool_),
                          np.zeros((n_bodies, 3)), np.zeros((n_bodies, 3)),
                          np.full(n_bodies, -np.inf), np.zeros(n_bodies))


@numba.njit(cache=True)
def _box(h, p, n):  # pragma: no cover - compiled
    """(G4)-(G5): signed distance of body-frame point ``p`` to the box of half extents ``h``;
    the outward normal is written to ``n``."""
    e0, e1, e2 = abs(p[0]) - h[0], abs(p[1]) - h[1], abs(p[2]) - h[2]
    if e0 > 0.0 or e1 > 0.0 or e2 > 0.0:
        d2 = 0.0
        for k in range(3):
            diff = p[k] - min(max(p[k], -h[k]), h[k])
            n[k] = diff
            d2 += diff * diff
        d = math.sqrt(d2)
        for k in range(3):
            n[k] /= d
        return d
    a = 0 if (e0 >= e1 and e0 >= e2) else (1 if e1 >= e2 else 2)
    n[0] = n[1] = n[2] = 0.0
    n[a] = -1.0 if p[a] < 0.0 else 1.0
    return abs(p[a]) - h[a]


@numba.njit(cache=True)
def _cylinder(radius, length, axis, p, n):  # pragma: no cover - compiled
    """(G6)-(G7) for a cylinder along body axis ``axis``."""
    z = p[axis]
    e_r = np.zeros(3)
    rho2 = 0.0
    for k in range(3):
        if k != axis:
            e_r[k] = p[k]
            rho2 += p[k] * p[k]
    rho = math.sqrt(rho2)
    if rho <= 1e-12 * radius:
        e_r[:] = 0.0
        e_r[(axis + 1) % 3] = 1.0
    else:
        for k in range(3):
            e_r[k] /= rho
    side, cap = rho - radius, abs(z) - 0.5 * length
    s = -1.0 if z < 0.0 else 1.0
    if side > 0.0 or cap > 0.0:
        a, b = max(side, 0.0), max(cap, 0.0)
        for k in range(3):
            n[k] = a * e_r[k]
        n[axis] += b * s
        d = math.sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2])
        for k in range(3):
            n[k] /= d
        return d
    if side >= cap:
        for k in range(3):
            n[k] = e_r[k]
        return side
    n[0] = n[1] = n[2] = 0.0
    n[axis] = s
    return cap


@numba.njit(cache=True)
def _sphere(radius, p, n):  # pragma: no cover - compiled
    """(G8)."""
    rho = math.sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2])
    if rho <= 1e-12 * radius:
        n[0], n[1], n[2] = 0.0, 0.0, 1.0
    else:
        for k in range(3):
            n[k] = p[k] / rho
    return rho - radius


@numba.njit(cache=True)
def _mesh(p, root, on_surface, tri, lower, upper, left, right, start, count, order,
          face_normal, edge_normal, corner_normal, stack, w, n):  # pragma: no cover - compiled
    """(G9)-(G10): nearest triangle through the hierarchy below ``root``, sign and normal from
    the pseudonormal of the closest feature."""
    best, face, b0, b1, b2 = nearest_triangle(p, root, np.inf, tri, lower, upper, left, right,
                                              start, count, order, stack, w)
    zeros = int(b0 == 0.0) + int(b1 == 0.0) + int(b2 == 0.0)
    if zeros == 1:
        i = 0 if b0 == 0.0 else (1 if b1 == 0.0 else 2)
        pseudo = edge_normal[face, (i + 1) % 3]
    elif zeros == 2:
        pseudo = corner_normal[face, 0 if b0 != 0.0 else (1 if b1 != 0.0 else 2)]
    else:
        pseudo = face_normal[face]
    diff = np.empty(3)
    dot = 0.0
    for k in range(3):
        diff[k] = p[k] - (b0 * tri[face, 0, k] + b1 * tri[face, 1, k] + b2 * tri[face, 2, k])
        dot += diff[k] * pseudo[k]
    sign = -1.0 if dot < 0.0 else 1.0
    unsigned = math.sqrt(best)
    for k in range(3):
        n[k] = sign * diff[k] / unsigned if unsigned > on_surface else pseudo[k]
    return sign * unsigned


@numba.njit(cache=True)
def _segment_near(la, lb, reach, bounds):  # pragma: no cover - compiled
    """Does the box of segment ``la``-``lb`` grown by ``reach`` overlap ``bounds`` (2, 3)?"""
    for k in range(3):
        if min(la[k], lb[k]) - reach > bounds[1, k] or max(la[k], lb[k]) + reach < bounds[0, k]:
            return False
    return True


@numba.njit(cache=True)
def _distance(code, size, root, p, n, tri, lower, upper, left, right, start, count, order,
              face_normal, edge_normal, corner_normal, stack, w):  # pragma: no cover - compiled
    """Signed distance of body-frame point ``p`` to a body of shape ``code`` (0 box, 1 cylinder,
    2 sphere, 3 mesh) with parameters ``size`` (3,); the outward normal goes to ``n``."""
    if code == 0:
        return _box(size, p, n)
    if code == 1:
        return _cylinder(size[0], size[1], int(size[2]), p, n)
    if code == 2:
        return _sphere(size[0], p, n)
    return _mesh(p, root, size[0], tri, lower, upper, left, right, start, count, order,
                 face_normal, edge_normal, corner_normal, stack, w, n)


@numba.njit(cache=True)
def _point_force(delta, nl, R, xi, a, b, v, dt, inv_mass, body_compliance, arm,
                 body_velocity, body_omega, stiffness, damping, friction, smoothing, slip_velocity,
                 force, body_force, body_moment, nw, vp):  # pragma: no cover - compiled
    """Force on the point at ``xi`` of segment a-b with penetration ``delta`` and body-frame
    normal ``nl``, (N1)-(N3), (F1)-(F2) with the explicit cap (E2); added to the nodes' ``force``
    (B5) and, opposite, to the body's ``body_force`` (3,) with its moment about the body's
    centre of mass, ``arm`` (3,) being the point's offset from it, to ``body_moment`` (B6).
    The relative velocity is the point's minus that of the body's material point there,
    ``body_velocity + body_omega x arm``.

    Returns the magnitude of the point force [N] and the friction power [W], or (-1, 0) when
    the point does not press on the body."""
    if delta <= -smoothing or (smoothing == 0.0 and delta <= 0.0):
        return -1.0, 0.0
    if delta < smoothing:
        t = delta + smoothing
        rho, slope = t * t / (4.0 * smoothing), t / (2.0 * smoothing)
    else:
        rho, slope = delta, 1.0
    vn = 0.0
    for k in range(3):
        nw[k] = R[k, 0] * nl[0] + R[k, 1] * nl[1] + R[k, 2] * nl[2]
        k1, k2 = (k + 1) % 3, (k + 2) % 3
        vp[k] = ((1.0 - xi) * v[a, k] + xi * v[b, k] - body_velocity[k]
                 - (body_omega[k1] * arm[k2] - body_omega[k2] * arm[k1]))
    for k in range(3):
        vn += nw[k] * vp[k]
    normal = stiffness * rho - damping * slope * vn
    if normal <= 0.0:
        return -1.0, 0.0
    slip2 = 0.0
    for k in range(3):
        vp[k] -= vn * nw[k]
        slip2 += vp[k] * vp[k]
    slip_now2, cap = slip2, math.inf
    if dt > 0.0:
        # (E2) the slip the step ends with under the forces so far, this friction left out,
        # and the slope that stops it in the step
        wa, wb = 1.0 - xi, xi
        d0 = dt * (wa * force[a, 0] * inv_mass[a] + wb * force[b, 0] * inv_mass[b])
        d1 = dt * (wa * force[a, 1] * inv_mass[a] + wb * force[b, 1] * inv_mass[b])
        d2 = dt * (wa * force[a, 2] * inv_mass[a] + wb * force[b, 2] * inv_mass[b])
        dn = d0 * nw[0] + d1 * nw[1] + d2 * nw[2]
        slip_now2, slip2 = 0.0, 0.0
        for k, dk in enumerate((d0, d1, d2)):
            ends = vp[k] + (dk - dn * nw[k])
            slip_now2 += vp[k] * ends
            vp[k] = ends
            slip2 += ends * ends
        compliance = wa * wa * inv_mass[a] + wb * wb * inv_mass[b] + body_compliance
        if compliance > 0.0:
            cap = 1.0 / (compliance * dt)
    viscous = min(friction * normal / math.sqrt(slip2 + slip_velocity * slip_velocity), cap)
    f2 = 0.0
    for k in range(3):
        fk = normal * nw[k] - viscous * vp[k]
        force[a, k] += (1.0 - xi) * fk
        force[b, k] += xi * fk
        body_force[k] -= fk
        f2 += fk * fk
        vp[k] = fk  # vp now holds the point force
    body_moment[0] -= arm[1] * vp[2] - arm[2] * vp[1]
    body_moment[1] -= arm[2] * vp[0] - arm[0] * vp[2]
    body_moment[2] -= arm[0] * vp[1] - arm[1] * vp[0]
    return math.sqrt(f2), viscous * slip_now2


@numba.njit(cache=True)
def body_speed(body_velocity, body_omega, bound_radius, b):  # pragma: no cover - compiled
    """Largest speed of a material point of body ``b`` within its bounding sphere [m/s]."""
    return (math.sqrt(body_velocity[b, 0] ** 2 + body_velocity[b, 1] ** 2 + body_velocity[b, 2] ** 2)
            + bound_radius[b] * math.sqrt(body_omega[b, 0] ** 2 + body_omega[b, 1] ** 2
                                          + body_omega[b, 2] ** 2))


@numba.njit(cache=True)
def segment_clearance(x, segments, radius, smoothing, body_position, bound_radius):  # pragma: no cover
    """Smallest gap [m] between the bounding sphere of a segment (midpoint, half its length),
    grown by its radius and the law's smoothing, and each body's bounding sphere (centre
    ``body_position`` (B, 3), radius ``bound_radius`` (B,)): (B,) float, the clearance of (E4).
    A body with a positive clearance has no contact point."""
    out = np.full(body_position.shape[0], np.inf)
    for s in range(segments.shape[0]):
        a, b = segments[s, 0], segments[s, 1]
        half = 0.5 * math.sqrt((x[b, 0] - x[a, 0]) ** 2 + (x[b, 1] - x[a, 1]) ** 2
                               + (x[b, 2] - x[a, 2]) ** 2)
        for bi in range(body_position.shape[0]):
            far = 0.0
            for k in range(3):
                far += (0.5 * (x[a, k] + x[b, k]) - body_position[bi, k]) ** 2
            gap = math.sqrt(far) - bound_radius[bi] - half - radius[s] - smoothing
            if gap < out[bi]:
                out[bi] = gap
    return out


@numba.njit(cache=True)
def accumulate_contact(x, v, force, dt, data, body_position, body_rotation, body_velocity,
                       body_omega, scratch):  # pragma: no cover - compiled
    """Add the contact forces on the nodes to ``force`` (N, 3) [N] at positions ``x`` and
    velocities ``v`` (N, 3), the bodies at ``body_position`` (B, 3), ``body_rotation`` (B, 3, 3)
    moving with ``body_velocity``, ``body_omega`` (B, 3, world axes); ``data`` is a
    :class:`ContactData`, ``scratch`` a :class:`ContactScratch`.

    ``dt`` > 0 caps friction's viscous slope for a symplectic Euler step of that size and checks
    the travel of segments near bodies; ``dt`` <= 0 evaluates the plain law. Only bodies with
    ``scratch.active`` True are visited. For every visited body, ``body_force`` and ``body_moment`` (B, 3) receive the
    force of the threads on it [N] and its moment about the centre of mass [N m], and
    ``clearance`` (B,) the smallest gap [m] between the bounding sphere of a segment, grown by
    its radius and the law's smoothing, and the body's bounding sphere (negative when some
    segment is that close).

    Returns
    -------
    friction_power : float
        Rate of work dissipated by friction [W], >= 0.
    total_force : float
        Sum of the magnitudes of the point forces [N].
    contacts : int
        Points with a positive normal force.
    deepest : float
        The largest depth of a thread's surface in a body, in thread radii (0 when none is in
        one).
    allowed_step : float
        The largest step [s] that keeps every segment near a body within its travel limit
        (inf when none is limiting, or ``dt`` <= 0).
    """
    (inv_mass, segments, radius, kind, body_size, body_bounds, bound_radius,
     travel_limit, body_compliance, mesh_root, tri, lower, upper, left, right, start, count,
     order, face_normal, edge_normal, corner_normal, stiffness, damping, friction, smoothing,
     slip_velocity, points_per_segment) = data
    active, taken, body_force, body_moment, clearance, _ = scratch
    n_seg, n_pts = segments.shape[0], points_per_segment
    power, total, contacts, deepest, allowed = 0.0, 0.0, 0, 0.0, np.inf
    stack = np.empty(STACK_DEPTH, np.int64)
    w, nl, nw, pl = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    la, lb, vp, arm = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    marked = np.empty(x.shape[0], np.int64)
    for bi in range(kind.shape[0]):
        if not active[bi]:
            continue
        R, bounds, p = body_rotation[bi], body_bounds[bi], body_position[bi]
        for k in range(3):
            body_force[bi, k] = body_moment[bi, k] = 0.0
        moving = body_speed(body_velocity, body_omega, bound_radius, bi)
        gap_min = np.inf
        n_marked = 0
        for s in range(n_seg):
            a, b = segments[s, 0], segments[s, 1]
            speed = moving + math.sqrt(max(v[a, 0] ** 2 + v[a, 1] ** 2 + v[a, 2] ** 2,
                                           v[b, 0] ** 2 + v[b, 1] ** 2 + v[b, 2] ** 2))
            reach_points = radius[s] + smoothing
            reach = reach_points + (speed * dt if dt > 0.0 else 0.0)
            far = 0.0
            half = 0.0
            for k in range(3):
                far += (0.5 * (x[a, k] + x[b, k]) - p[k]) ** 2
                half += (x[b, k] - x[a, k]) ** 2
            gap = math.sqrt(far) - bound_radius[bi] - 0.5 * math.sqrt(half) - reach_points
            gap_min = min(gap_min, gap)
            if gap > reach - reach_points:
                continue
            for k in range(3):
                la[k] = R[0, k] * (x[a, 0] - p[0]) + R[1, k] * (x[a, 1] - p[1]) + R[2, k] * (x[a, 2] - p[2])
                lb[k] = R[0, k] * (x[b, 0] - p[0]) + R[1, k] * (x[b, 1] - p[1]) + R[2, k] * (x[b, 2] - p[2])
            if not _segment_near(la, lb, reach, bounds):
                continue
            if dt > 0.0 and speed * dt > travel_limit[bi]:  # (E3)
                allowed = min(allowed, travel_limit[bi] / speed)
            if not _segment_near(la, lb, reach_points, bounds):
                continue
            for j in range(n_pts + 1):
                xi = j / n_pts
                if j == 0 or j == n_pts:
                    node = a if j == 0 else b
                    if taken[node]:
                        continue
                    taken[node] = True
                    marked[n_marked] = node
                    n_marked += 1
                inside = True
                for k in range(3):
                    pl[k] = (1.0 - xi) * la[k] + xi * lb[k]
                    if pl[k] < bounds[0, k] - reach_points or pl[k] > bounds[1, k] + reach_points:
                        inside = False
                if not inside:
                    continue
                d = _distance(kind[bi], body_size[bi], mesh_root[bi], pl, nl, tri, lower, upper,
                              left, right, start, count, order, face_normal, edge_normal,
                              corner_normal, stack, w)
                deepest = max(deepest, (radius[s] - d) / radius[s])
                for k in range(3):
                    arm[k] = (1.0 - xi) * x[a, k] + xi * x[b, k] - p[k]
                magnitude, dissipation = _point_force(
                    radius[s] - d, nl, R, xi, a, b, v, dt, inv_mass,
                    body_compliance[bi], arm, body_velocity[bi], body_omega[bi], stiffness,
                    damping, friction, smoothing, slip_velocity, force, body_force[bi],
                    body_moment[bi], nw, vp)
                if magnitude >= 0.0:
                    total += magnitude
                    contacts += 1
                    power += dissipation
        clearance[bi] = gap_min
        for i in range(n_marked):
            taken[marked[i]] = False
    return power, total, contacts, deepest, allowed


@numba.njit(cache=True)
def largest_speed(v):  # pragma: no cover - compiled
    """Largest node speed [m/s] of velocities ``v`` (N, 3)."""
    top = 0.0
    for i in range(v.shape[0]):
        top = max(top, v[i, 0] ** 2 + v[i, 1] ** 2 + v[i, 2] ** 2)
    return math.sqrt(top)


@numba.njit(cache=True)
def centre_speed(body_velocity, b):  # pragma: no cover - compiled
    """Speed of body ``b``'s centre [m/s]: how fast its bounding sphere, centred there, moves
    (a turn about the centre leaves the sphere where it is)."""
    return math.sqrt(body_velocity[b, 0] ** 2 + body_velocity[b, 1] ** 2
                     + body_velocity[b, 2] ** 2)


@numba.njit(cache=True)
def _in_reach(dt, node_speed, body_velocity, travelled, clearance, b):  # pragma: no cover
    """(E4): whether a thread point can have come within reach of body ``b`` since its last
    evaluation, by the end of a coming step of ``dt`` [s]: ``travelled + 2 dt (2 node_speed +
    centre speed) >= clearance``."""
    return travelled[b] + 2.0 * dt * (2.0 * node_speed + centre_speed(body_velocity, b)) \
        >= clearance[b]


@numba.njit(cache=True)
def bodies_clear(dt, node_speed, body_velocity, travelled, clearance):  # pragma: no cover
    """(E5): whether no thread point can come within reach of any body in a step of ``dt`` [s]
    (the test of :func:`select_bodies`, which marks nothing)."""
    for b in range(clearance.shape[0]):
        if _in_reach(dt, node_speed, body_velocity, travelled, clearance, b):
            return False
    return True


@numba.njit(cache=True)
def select_bodies(dt, node_speed, body_velocity, travelled, clearance, active, body_force,
                  body_moment):  # pragma: no cover - compiled
    """(E4): mark in ``active`` (B,) the bodies that a thread point can have come within reach of
    since their last evaluation (:func:`_in_reach`), restart their ``travelled`` and zero the
    force and moment of the others; True when any is active. ``node_speed`` [m/s] is the
    largest node speed, ``dt`` [s] the coming step."""
    any_active = False
    for b in range(active.shape[0]):
        active[b] = _in_reach(dt, node_speed, body_velocity, travelled, clearance, b)
        if active[b]:
            any_active = True
            travelled[b] = 0.0
        else:
            for k in range(3):
                body_force[b, k] = body_moment[b, k] = 0.0
    return any_active


@numba.njit(cache=True)
def forget_clearance(active, clearance):  # pragma: no cover - compiled
    """Make every ``active`` body's ``clearance`` (B,) -inf: evaluated again in the next step."""
    for b in range(active.shape[0]):
        if active[b]:
            clearance[b] = -np.inf
