"""The compiled explicit step loop of every model: symplectic Euler from one saved frame to the
next, without returning to Python.

A model hands the loop its arrays as an :class:`ExplicitProblem`, a bundle of the terms it has
(each with no rows when absent): lumped segments (``elements/spring/FORMULATION.md`` (S7)),
Kirchhoff hinges (``elements/kirchhoff/FORMULATION.md`` (K3), (K4)), rod elements
(``elements/cosserat/FORMULATION.md`` (C46), (C47)), dead loads and gravity, and contact with rigid
bodies and the bodies' own step (``elements/contact/FORMULATION.md`` (E1)-(E5), (R1)-(R4)). Every
step evaluates the forces at the start of the step, then

    v1 = v0 + h m^-1 f,   x1 = x0 + h v1                                        (S9), (C46)
    P = J W0 + h mu,   (q1, P1) = free rotation of the node for h,   W1 = J^-1 P1     (C47)

(the free rotation split into turns about the three body axes, (C47a))

and moves the free bodies. The step length is decided by :class:`StepControl`:

- fixed steps (``rotation_controlled`` False: models without rod elements): the frame interval is
  divided into a whole number of equal steps, ``t = t_start + k h``;
- rotation-controlled steps (rods): each step is the base step times the factor (C50) at the
  largest element rotation of the structure, the last one cut to land on the frame time.

With bodies, the base step drops to ``near_dt`` for the rest of the interval once a body is within
reach (E5), and to 0.9 times the travel-limited step when a point near a body would move more
than its travel limit (E3); the step is then redone from the same state (fixed steps divide the
rest of the interval anew).

:func:`march` and :func:`march_parallel` are the same loop (:func:`_loop`) compiled without and
with numba's parallel loops over blocks of elements and nodes, :func:`march_free` and
:func:`march_parallel_free` the same without contact, for problems without bodies
(:func:`march_for` picks one); :func:`march_nodes` is the loop of problems
with position nodes only (the lumped model, cable and Kirchhoff threads without bodies), fused
and on one thread (measured on the reference deployment, validation/benchmarks/results/peers.md);
:func:`forces` evaluates the forces alone (RK45, tests).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np

from rodnet.kernels.contact_compiled import (ContactData, ContactScratch, accumulate_contact,
                                             bodies_clear, centre_speed, forget_clearance,
                                             largest_speed, select_bodies)
from rodnet.kernels import threads
from rodnet.kernels.cosserat_compiled import RodElements, rod_forces, scatter_forces
from rodnet.kernels.hinge import Hinges
from rodnet.kernels.rigid_body import advance_bodies
from rodnet.kernels.schedule import LoadSchedule, factor_change, load_factor
from rodnet.kernels.segments import Segments, hinge_forces, segment_forces


class Nodes(NamedTuple):
    """``inv_mass`` (N, 3) [1/kg], 0 on supported DOFs; ``weight`` (N, 3): gravity on the node
    masses [N]."""

    inv_mass: np.ndarray
    weight: np.ndarray


class Rotations(NamedTuple):
    """Body-frame principal rotary inertia of the rotation nodes, ``inertia`` (R, 3)
    [kg m^2], and ``inv_inertia`` (R, 3), 0 on supported DOFs; R = 0 without rotations."""

    inertia: np.ndarray
    inv_inertia: np.ndarray


class Loads(NamedTuple):
    """Dead loads: ``nodes`` (L,) position node and ``rot_nodes`` (L,) rotation node of each,
    ``force`` (L, 3) [N] and ``moment`` (L, 3) [N m] in fixed global directions, times the
    factors of ``schedule`` (:mod:`rodnet.kernels.schedule`)."""

    nodes: np.ndarray
    rot_nodes: np.ndarray
    force: np.ndarray
    moment: np.ndarray
    schedule: LoadSchedule


class BodyMass(NamedTuple):
    """Mass properties of the rigid bodies for (R1)-(R4): ``inv_mass`` (B,) [1/kg] (0 for a
    fixed body), ``inertia`` and ``inv_inertia`` (B, 3, 3) body axes (0 for a fixed body),
    ``gravity`` (3,) [m/s^2]."""

    inv_mass: np.ndarray
    inertia: np.ndarray
    inv_inertia: np.ndarray
    gravity: np.ndarray


class ExplicitProblem(NamedTuple):
    """Everything the loop needs of a model, term by term."""

    nodes: Nodes
    rotations: Rotations
    loads: Loads
    segments: Segments
    hinges: Hinges
    rods: RodElements
    contact: ContactData
    body_mass: BodyMass


class StepControl(NamedTuple):
    """How the loop chooses its steps.

    ``dt``: the base step far from bodies [s]; ``near_dt``: the base step while a body is within
    reach (E5) [s]; ``min_dt``: the shortest travel-limited base step accepted [s];
    ``rotation_controlled``: steps shrink with the element rotation (C50), by ``factor``
    interpolated at ``angles`` [rad] (else fixed steps, ``angles = [0]``, ``factor = [1]``);
    ``stable_step``: the stability limit of the threads [s] (for messages); ``blocks``: how
    many blocks of consecutive elements and nodes the loops over them take, one per thread of
    the parallel loops (:func:`march_parallel`), 1 on one thread (a block costs about half a
    microsecond more in the nodes' update); ``undamped_step``: the stability limit without the
    threads' Kelvin-Voigt damping [s] (for messages).
    """

    dt: float
    near_dt: float
    min_dt: float
    rotation_controlled: bool
    angles: np.ndarray
    factor: np.ndarray
    stable_step: float
    blocks: int = 1
    undamped_step: float = math.inf


class Scratch(NamedTuple):
    """Work arrays, allocated once per run: ``f_node`` (N, 3), ``m_node`` (R, 3) (the moments,
    then in the update the body momenta after the kick), the rod
    elements' ``force`` (E, 12) and ``monitor`` (E, 2),
    the bodies' ``body_work`` (9, 3), the contact's :class:`ContactScratch`, and
    ``load_rate`` (L, 3) [N/s], each dead load's force times its factor's slope over the call
    (:func:`~rodnet.kernels.schedule.factor_change`; (0, 3) while no factor changes)."""

    f_node: np.ndarray
    m_node: np.ndarray
    force: np.ndarray
    monitor: np.ndarray
    body_work: np.ndarray
    contact: ContactScratch
    load_rate: np.ndarray


class Bodies(NamedTuple):
    """The rigid bodies' state arrays (:class:`rodnet.state.BodyMotion`), advanced in place:
    ``position``, ``velocity`` (B, 3), ``quaternion`` (B, 4), ``rotation`` (B, 3, 3),
    ``momentum``, ``omega`` (B, 3)."""

    position: np.ndarray
    velocity: np.ndarray
    quaternion: np.ndarray
    rotation: np.ndarray
    momentum: np.ndarray
    omega: np.ndarray


class Marched(NamedTuple):
    """What one call of the loop did: ``status`` (0 done, 1 the state became non-finite, 2 the
    travel-limited step fell below ``min_dt``), the time reached ``t`` [s], ``steps`` taken,
    force ``evaluations`` (steps redone included), the shortest and longest steps ``h_min``,
    ``h_max`` [s] (a step cut to land on the frame left out), the largest axial force ``peak``
    [N] and element rotation ``phi_max`` [rad], the ``friction_work`` [J], and over the steps'
    start states the largest sum of contact point forces ``contact_force`` [N], number of
    contact points ``contact_count`` and depth of a thread's surface in a body
    ``contact_depth`` [thread radii], and ``load_factor_energy`` [J]
    (:func:`~rodnet.kernels.schedule.factor_change` over the steps; a jump of a factor at ``t``
    is the caller's)."""

    status: int
    t: float
    steps: int
    evaluations: int
    h_min: float
    h_max: float
    peak: float
    phi_max: float
    friction_work: float
    contact_force: float
    contact_count: int
    contact_depth: float
    load_factor_energy: float


@numba.njit(inline="always")
def _rate_products(x, v, nodes, rate):  # pragma: no cover - compiled
    """``sum_j rate_j . x[nodes_j]`` [W] and ``sum_j rate_j . v[nodes_j]`` [W/s] over the
    loads' ``rate`` (L, 3) (:attr:`Scratch.load_rate`) at positions ``x`` and velocities ``v``
    (N, 3)."""
    gx, gv = 0.0, 0.0
    for j in range(rate.shape[0]):
        a = nodes[j]
        for k in range(3):
            gx += rate[j, k] * x[a, k]
            gv += rate[j, k] * v[a, k]
    return gx, gv


@numba.njit(inline="always")
def _apply_loads(t, quat, loads, f_node, m_node):  # pragma: no cover - compiled
    """Add the dead loads at time ``t`` to the node forces and, for models with rotation
    nodes, their moments in the body frame, ``R^T m``, to the node moments."""
    with_rotations = m_node.shape[0] > 0
    sc = loads.schedule
    scale = 0.0
    for j in range(loads.nodes.shape[0]):
        if not sc.repeats[j]:
            scale = load_factor(sc.ptr, sc.times, sc.values, sc.start, sc.stop, j, t)
        a = loads.nodes[j]
        if with_rotations:
            r = loads.rot_nodes[j]
            w, u, v, z = quat[r, 0], quat[r, 1], quat[r, 2], quat[r, 3]
            R = (1.0 - 2.0 * (v * v + z * z), 2.0 * (u * v - w * z), 2.0 * (u * z + w * v),
                 2.0 * (u * v + w * z), 1.0 - 2.0 * (u * u + z * z), 2.0 * (v * z - w * u),
                 2.0 * (u * z - w * v), 2.0 * (v * z + w * u), 1.0 - 2.0 * (u * u + v * v))
            m0, m1, m2 = loads.moment[j, 0], loads.moment[j, 1], loads.moment[j, 2]
            for k in range(3):  # a global-axis moment in the body frame: R^T m
                f_node[a, k] += scale * loads.force[j, k]
                m_node[r, k] += scale * (R[k] * m0 + R[3 + k] * m1 + R[6 + k] * m2)
        else:
            for k in range(3):
                f_node[a, k] += scale * loads.force[j, k]


@numba.njit(inline="always")
def _forces(t, x, quat, v, W, p, s, blocks):  # pragma: no cover - compiled
    """Every force and moment on the nodes at time ``t`` into ``s.f_node``, ``s.m_node``,
    contact aside (the rod elements in ``blocks`` blocks); returns the largest axial force [N]
    and element rotation [rad]."""
    _dead_forces(t, quat, p, s)
    peak = 0.0
    seg = p.segments
    if seg.pairs.shape[0] > 0:
        peak = segment_forces(x, v, s.f_node, seg.pairs, seg.rest_length, seg.EA, seg.etaA,
                              seg.kink_strain, seg.tension_only)
    h = p.hinges
    if h.nodes.shape[0] > 0:
        hinge_forces(x, v, s.f_node, h.nodes, h.stiffness, h.tau, h.rest)
    rod_peak, phi = _rod_element_forces(x, quat, v, W, p, s, blocks)
    return max(peak, rod_peak), phi


@numba.njit(inline="always")
def _rods_forces(t, x, quat, v, W, p, s, blocks):  # pragma: no cover - compiled
    """:func:`_forces` of a problem without segments and hinges (rod models), which the loop
    without bodies runs: the same arithmetic, compiled without the segments' and hinges' code."""
    _dead_forces(t, quat, p, s)
    return _rod_element_forces(x, quat, v, W, p, s, blocks)


@numba.njit(inline="always")
def _dead_forces(t, quat, p, s):  # pragma: no cover - compiled
    """``s.f_node`` the nodes' weights plus the loads at time ``t``, ``s.m_node`` the loads'
    moments."""
    f_node, m_node = s.f_node, s.m_node
    for i in range(f_node.shape[0]):
        for k in range(3):
            f_node[i, k] = p.nodes.weight[i, k]
    m_node[:, :] = 0.0
    _apply_loads(t, quat, p.loads, f_node, m_node)


@numba.njit(inline="always")
def _rod_element_forces(x, quat, v, W, p, s, blocks):  # pragma: no cover - compiled
    """The rod elements' forces added to ``s.f_node``, ``s.m_node``; returns their largest axial
    force [N] and element rotation [rad] (0, 0 without rod elements)."""
    rods = p.rods
    if rods.rest_length.shape[0] == 0:
        return 0.0, 0.0
    peak, phi = rod_forces(x, quat, v, W, rods, s.force, s.monitor, blocks)
    scatter_forces(s.force, rods.pos_nodes, rods.rot_nodes, rods.offset_R, s.f_node, s.m_node)
    return peak, phi


@numba.njit(inline="always")
def _turned(aw, ax, ay, az, bw, bx, by, bz):  # pragma: no cover - compiled
    """``q o exp(h W)`` normalised, from ``q`` and ``exp(h W) = (bw, bx, by, bz)``
    (so3_compiled.retract), and whether its norm was finite and positive."""
    qw = aw * bw - ax * bx - ay * by - az * bz
    qx = aw * bx + ax * bw + ay * bz - az * by
    qy = aw * by - ax * bz + ay * bw + az * bx
    qz = aw * bz + ax * by - ay * bx + az * bw
    norm = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    inv = 1.0 / norm
    return qw * inv, qx * inv, qy * inv, qz * inv, math.isfinite(norm) & (norm > 0.0)


@numba.njit(inline="always")
def _half_series(theta):  # pragma: no cover - compiled
    """``cos(theta / 2)``, ``sin(theta / 2)`` by their series, to round-off for ``|theta| <=
    0.05`` (the next terms are below 1e-20)."""
    f = 0.5 * theta
    p = f * f
    c = 1.0 + p * (-0.5 + p * (1.0 / 24.0 + p * (-1.0 / 720.0 + p / 40320.0)))
    s = f * (1.0 + p * (-1.0 / 6.0 + p * (1.0 / 120.0 + p * (-1.0 / 5040.0 + p / 362880.0))))
    return c, s


@numba.njit(inline="always")
def _half_trig(theta):  # pragma: no cover - compiled
    """``cos(theta / 2)``, ``sin(theta / 2)``."""
    return math.cos(0.5 * theta), math.sin(0.5 * theta)


@numba.njit(inline="always")
def _axis_flow(axis, tau, qw, qx, qy, qz, p0, p1, p2, j0, j1, j2,
               half):  # pragma: no cover - compiled
    """The exact flow over ``tau`` [s] of the free rotation whose kinetic energy is the
    ``axis`` term ``P_a^2 / (2 J_a)`` alone (C47a): the node turns about its body axis ``a`` at
    ``W_a = P_a / J_a``, ``q <- q o exp(tau W_a e_a)``, and its body-frame angular momentum
    ``P`` turns the other way, ``P <- exp(-tau W_a e_a) P`` (spatial momentum unchanged).
    ``j`` are the inverse inertias; ``half`` gives the cosine and sine of half an angle."""
    if axis == 0:
        c, s = half(tau * p0 * j0)
        qw, qx, qy, qz = qw * c - qx * s, qw * s + qx * c, qy * c + qz * s, qz * c - qy * s
        cc, ss = 1.0 - 2.0 * s * s, 2.0 * s * c
        p1, p2 = cc * p1 + ss * p2, cc * p2 - ss * p1
    elif axis == 1:
        c, s = half(tau * p1 * j1)
        qw, qx, qy, qz = qw * c - qy * s, qx * c - qz * s, qw * s + qy * c, qx * s + qz * c
        cc, ss = 1.0 - 2.0 * s * s, 2.0 * s * c
        p2, p0 = cc * p2 + ss * p0, cc * p0 - ss * p2
    else:
        c, s = half(tau * p2 * j2)
        qw, qx, qy, qz = qw * c - qz * s, qx * c + qy * s, qy * c - qx * s, qw * s + qz * c
        cc, ss = 1.0 - 2.0 * s * s, 2.0 * s * c
        p0, p1 = cc * p0 + ss * p1, cc * p1 - ss * p0
    return qw, qx, qy, qz, p0, p1, p2


@numba.njit(inline="always")
def _free_rotation(h, qw, qx, qy, qz, p0, p1, p2, j0, j1, j2,
                   half):  # pragma: no cover - compiled
    """The free rotation of a node over ``h`` [s] from ``q``, body momentum ``P``, by the
    symmetric splitting of its kinetic energy into the three axis terms (C47a): axes 0, 1 for
    ``h / 2``, axis 2 for ``h``, axes 1, 0 for ``h / 2``; ``q`` normalised, and whether it
    is finite."""
    g = 0.5 * h
    qw, qx, qy, qz, p0, p1, p2 = _axis_flow(0, g, qw, qx, qy, qz, p0, p1, p2, j0, j1, j2, half)
    qw, qx, qy, qz, p0, p1, p2 = _axis_flow(1, g, qw, qx, qy, qz, p0, p1, p2, j0, j1, j2, half)
    qw, qx, qy, qz, p0, p1, p2 = _axis_flow(2, h, qw, qx, qy, qz, p0, p1, p2, j0, j1, j2, half)
    qw, qx, qy, qz, p0, p1, p2 = _axis_flow(1, g, qw, qx, qy, qz, p0, p1, p2, j0, j1, j2, half)
    qw, qx, qy, qz, p0, p1, p2 = _axis_flow(0, g, qw, qx, qy, qz, p0, p1, p2, j0, j1, j2, half)
    norm = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    inv = 1.0 / norm
    ok = math.isfinite(norm) & (norm > 0.0)
    return qw * inv, qx * inv, qy * inv, qz * inv, p0, p1, p2, ok


@numba.njit(inline="always")
def _series_rotation(h, p0, p1, p2, j0, j1, j2):  # pragma: no cover - compiled
    """Whether the free rotation of a node with body momentum ``P`` and inverse inertias ``j``
    can take the series of :func:`_half_series` (every axis turns by at most 0.05 rad in
    ``h``: ``h |P| max j`` bounds each axis' angle, and the splitting keeps ``|P|``) and has no
    supported axis (some, not all, ``j`` zero: such a node turns without gyroscopic coupling,
    left to :func:`_turn_far`)."""
    jm = max(j0, max(j1, j2))
    reach = h * h * (p0 * p0 + p1 * p1 + p2 * p2) * jm * jm
    held = (j0 == 0.0) | (j1 == 0.0) | (j2 == 0.0)
    all_held = (j0 == 0.0) & (j1 == 0.0) & (j2 == 0.0)
    return (reach < 2.5e-3) & ((not held) | all_held)


@numba.njit(cache=True, error_model="numpy")
def _turn_far(quat, W, P, inverse, h):  # pragma: no cover - compiled
    """The rotation nodes that :func:`update_range` left (see :func:`_series_rotation`), from
    their body momenta after the kick ``P`` (R, 3): a node with a supported axis by
    ``W1 = J^-1 P``, ``q1 = q0 o exp(h W1)``, the others by the splitting (C47a) with ``cos``
    and ``sin``; returns how many became non-finite."""
    bad = 0
    for r in range(W.shape[0]):
        p0, p1, p2 = P[r, 0], P[r, 1], P[r, 2]
        j0, j1, j2 = inverse[r, 0], inverse[r, 1], inverse[r, 2]
        if _series_rotation(h, p0, p1, p2, j0, j1, j2):
            continue
        held = (j0 == 0.0) | (j1 == 0.0) | (j2 == 0.0)
        aw, ax, ay, az = quat[r, 0], quat[r, 1], quat[r, 2], quat[r, 3]
        if held:
            w0, w1, w2 = p0 * j0, p1 * j1, p2 * j2
            d0, d1, d2 = h * w0, h * w1, h * w2
            angle = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            c = math.cos(0.5 * angle)
            sn = 0.5 if angle == 0.0 else math.sin(0.5 * angle) / angle
            qw, qx, qy, qz, ok = _turned(aw, ax, ay, az, c, sn * d0, sn * d1, sn * d2)
        else:
            qw, qx, qy, qz, p0, p1, p2, ok = _free_rotation(h, aw, ax, ay, az, p0, p1, p2,
                                                            j0, j1, j2, _half_trig)
            w0, w1, w2 = p0 * j0, p1 * j1, p2 * j2
        if ok:
            quat[r, 0], quat[r, 1], quat[r, 2], quat[r, 3] = qw, qx, qy, qz
            W[r, 0], W[r, 1], W[r, 2] = w0, w1, w2
        else:
            bad += 1
    return bad


@numba.njit(cache=True, error_model="numpy")
def update_range(x, quat, v, W, f_node, m_node, inv_mass, inertia, inv_inertia,
                 h):  # pragma: no cover - compiled
    """The symplectic Euler update (S9), (C46), (C47) in place of the position nodes (``x``,
    ``v``, ``f_node``, ``inv_mass``) and rotation nodes (``quat``, ``W``, ``m_node``,
    ``inertia``, ``inv_inertia``) given (a block: these arrays' rows, as views, so that the loops
    start at 0 and the compiler drops the checks for negative indices and vectorises the
    rotations); ``m_node`` is left holding the rotation nodes' body momenta after the kick.
    Returns how many nodes became non-finite and how many rotation nodes were left for
    :func:`_turn_far`. ``inv_mass`` is :class:`Nodes`' field, ``inertia`` and
    ``inv_inertia`` :class:`Rotations`'."""
    bad = 0
    for i in range(x.shape[0]):
        for k in range(3):
            v[i, k] += h * f_node[i, k] * inv_mass[i, k]
            x[i, k] += h * v[i, k]
        if not (math.isfinite(x[i, 0]) and math.isfinite(x[i, 1]) and math.isfinite(x[i, 2])):
            bad += 1
    # the rotations in a loop without branches or calls, which the compiler vectorises (flat
    # arrays, fixed strides): the kick P = J W0 + h mu, then the free rotation (C47a) by the
    # series of cos and sin; a node that turns further, or has a supported axis, keeps its
    # state here and is redone by _turn_far from its kicked momentum (left in m_node)
    Wf, Q, M = W.reshape(-1), quat.reshape(-1), m_node.reshape(-1)
    J, Ji = inertia.reshape(-1), inv_inertia.reshape(-1)
    far = 0
    for r in range(W.shape[0]):
        a, b = 3 * r, 4 * r
        p0 = J[a] * Wf[a] + h * M[a]
        p1 = J[a + 1] * Wf[a + 1] + h * M[a + 1]
        p2 = J[a + 2] * Wf[a + 2] + h * M[a + 2]
        M[a], M[a + 1], M[a + 2] = p0, p1, p2
        j0, j1, j2 = Ji[a], Ji[a + 1], Ji[a + 2]
        aw, ax, ay, az = Q[b], Q[b + 1], Q[b + 2], Q[b + 3]
        qw, qx, qy, qz, n0, n1, n2, ok = _free_rotation(h, aw, ax, ay, az, p0, p1, p2,
                                                        j0, j1, j2, _half_series)
        near = _series_rotation(h, p0, p1, p2, j0, j1, j2)
        keep = near & ok   # selected, not branched on (a load in a branch stops vectorising)
        Q[b] = qw if keep else aw
        Q[b + 1] = qx if keep else ax
        Q[b + 2] = qy if keep else ay
        Q[b + 3] = qz if keep else az
        Wf[a] = n0 * j0 if keep else Wf[a]
        Wf[a + 1] = n1 * j1 if keep else Wf[a + 1]
        Wf[a + 2] = n2 * j2 if keep else Wf[a + 2]
        far += int(not near)
        bad += int(near & (not ok))
    return bad, far


@numba.njit(inline="always")
def _update(x, quat, v, W, f_node, m_node, nodes, rotations, h,
            blocks):  # pragma: no cover - compiled
    """One symplectic Euler update (S9), (C46), (C47) in place (:func:`update_range` in
    ``blocks`` blocks of nodes, over numba's threads in a ``parallel=True`` caller); False
    when the state became non-finite."""
    n, r = x.shape[0], W.shape[0]
    inv_mass, inertia, inv_inertia = nodes.inv_mass, rotations.inertia, rotations.inv_inertia
    if blocks == 1:  # one call (as rod_forces)
        bad, far = update_range(x, quat, v, W, f_node, m_node, inv_mass, inertia, inv_inertia, h)
    else:
        bad, far = 0, 0
        for b in numba.prange(blocks):  # no named tuple in a parallel loop
            i, j = b * n // blocks, (b + 1) * n // blocks
            k, m = b * r // blocks, (b + 1) * r // blocks
            bad_b, far_b = update_range(x[i:j], quat[k:m], v[i:j], W[k:m], f_node[i:j],
                                        m_node[k:m], inv_mass[i:j], inertia[k:m],
                                        inv_inertia[k:m], h)
            bad += bad_b
            far += far_b
    if far:
        bad += _turn_far(quat, W, m_node, inv_inertia, h)
    return bad == 0


@numba.njit(cache=True)
def _whole_steps(t_start, t_end, step):  # pragma: no cover - compiled
    """``rodnet.integrate.frames.whole_steps``: how many steps of at most ``step`` fit from
    ``t_start`` to ``t_end``, and their length."""
    n = max(1, math.ceil((t_end - t_start) / step - 1e-9))
    return n, (t_end - t_start) / n


@numba.njit(inline="always")
def _interp(x, xp, fp):  # pragma: no cover - compiled
    """``np.interp(x, xp, fp)`` for a number ``x`` and increasing ``xp`` (K,) with ``fp``
    (K,), K >= 2: the same arithmetic as numba's, so the same result to the last bit, without
    its array code, which took a tenth of compiling the loop of rods."""
    last = xp.shape[0] - 1
    if np.isnan(x):
        return x
    if x < xp[0]:
        return fp[0]
    if x >= xp[last]:
        return fp[last]
    j = 0
    while xp[j + 1] <= x:
        j += 1
    if xp[j] == x:
        return fp[j]
    slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j])
    y = slope * (x - xp[j]) + fp[j]
    if np.isnan(y):   # numpy's fallback: from the other end, or the flat value
        y = slope * (x - xp[j + 1]) + fp[j + 1]
        if np.isnan(y) and fp[j] == fp[j + 1]:
            y = fp[j]
    return y


def _loop(with_bodies: bool):  # type: ignore[no-untyped-def]
    """The loop of :func:`march` (see the module docstring), compiled inline into each of the
    entry points; ``with_bodies`` False leaves the contact and the bodies' step out (numba drops
    the branches on a constant), which saves a third of compiling the loop of rods
    (validation/benchmarks/results/cold_start.md). The loop without bodies runs rod models
    only (the lumped model without bodies has :func:`march_nodes`), so it is compiled without
    the segments' and hinges' forces (:func:`_rods_forces`).
    """
    forces_of = _forces if with_bodies else _rods_forces

    @numba.njit(inline="always")
    def march_loop(x, quat, v, W, bodies, t0, t_end, n0, h0, p, control,
                   s):  # pragma: no cover - compiled
        c, cs, bm = p.contact, s.contact, p.body_mass
        has_bodies = c.kind.shape[0] > 0
        peak, phi_max, h_min, h_max, work = 0.0, 0.0, np.inf, 0.0, 0.0
        touch, touching, deep = 0.0, 0, 0.0    # contact's largest force, points, depth
        drift = 0.0                            # the loads' potential moved by their factors
        total, points, depth = 0.0, 0, 0.0
        steps, evaluations = 0, 0
        node_speed = largest_speed(v) if with_bodies and has_bodies else 0.0
        fixed = not control.rotation_controlled
        base, t = h0, t0
        t_seg, k, n_seg, h_seg = t0, 0, n0, h0          # fixed steps: t = t_seg + k h_seg
        while True:
            if fixed:
                if k >= n_seg:
                    break
                t = t_seg + k * h_seg
            elif not t < t_end:
                break
            if with_bodies and has_bodies and base < h0 and bodies_clear(
                    h0, node_speed, bodies.velocity, cs.travelled, cs.clearance):
                base = h0    # (E5): no body within reach of the longer step again
                if fixed:
                    t_seg, k = t, 0
                    n_seg, h_seg = _whole_steps(t, t_end, base)
            step_peak, phi = forces_of(t, x, quat, v, W, p, s, control.blocks)
            evaluations += 1
            if fixed:
                h_full, h, last = h_seg, h_seg, False
            else:
                h_full = base * _interp(phi, control.angles, control.factor)
                remaining = t_end - t
                last = h_full >= remaining * (1.0 - 1e-9)
                h = remaining if last else h_full
            power, total, points, depth = 0.0, 0.0, 0, 0.0
            if with_bodies and has_bodies and select_bodies(
                    h, node_speed, bodies.velocity, cs.travelled, cs.clearance, cs.active,
                    cs.body_force, cs.body_moment):
                new_base = base
                if h > control.near_dt * (1.0 + 1e-12):   # (E5): contact needs the shorter step
                    new_base = control.near_dt
                else:
                    power, total, points, depth, allowed = accumulate_contact(
                        x, v, s.f_node, h, c, bodies.position, bodies.rotation, bodies.velocity,
                        bodies.omega, cs)
                    if allowed < h:                       # (E3): a point would jump too far
                        new_base = min(base, 0.9 * allowed)
                        if new_base < control.min_dt:
                            return Marched(2, t, steps, evaluations, h_min, h_max, peak, phi_max,
                                           work, touch, touching, deep, drift)
                if new_base != base:                      # redo the step from the same state
                    forget_clearance(cs.active, cs.clearance)
                    base = new_base
                    if fixed:
                        t_seg, k = t, 0
                        n_seg, h_seg = _whole_steps(t, t_end, base)
                    continue
            peak = max(peak, step_peak)
            phi_max = max(phi_max, phi)
            touch, touching, deep = max(touch, total), max(touching, points), max(deep, depth)
            h_min = min(h_min, h_full)
            h_max = max(h_max, h_full)
            work += h * power
            rated = s.load_rate.shape[0] > 0
            if rated:
                start = _rate_products(x, v, p.loads.nodes, s.load_rate)
            finite = _update(x, quat, v, W, s.f_node, s.m_node, p.nodes, p.rotations, h,
                             control.blocks)
            if rated:
                drift += factor_change(h, start, _rate_products(x, v, p.loads.nodes,
                                                                 s.load_rate))
            if with_bodies and has_bodies:
                node_speed = largest_speed(v)
                advance_bodies(h, cs.body_force, cs.body_moment, bm.inv_mass, bm.inertia,
                               bm.inv_inertia, bm.gravity, bodies.position, bodies.velocity,
                               bodies.quaternion, bodies.rotation, bodies.momentum, bodies.omega,
                               s.body_work)
                for b in range(cs.travelled.shape[0]):
                    cs.travelled[b] += h * (2.0 * node_speed + centre_speed(bodies.velocity, b))
            steps += 1
            if fixed:
                k += 1
            else:
                t = t_end if last else t + h
            if not finite:
                if fixed:
                    t = t_seg + k * h_seg
                return Marched(1, t, steps, evaluations, h_min, h_max, peak, phi_max, work,
                               touch, touching, deep, drift)
        if fixed:
            t = t_end
        return Marched(0, t, steps, evaluations, h_min, h_max, peak, phi_max, work, touch,
                       touching, deep, drift)

    return march_loop


_march, _march_free = _loop(True), _loop(False)


@numba.njit(cache=True, error_model="numpy")
def march(x, quat, v, W, bodies, t0, t_end, n0, h0, problem, control,
          scratch):  # pragma: no cover - compiled
    """Advance positions ``x`` (N, 3), quaternions ``quat`` (R, 4), velocities ``v`` (N, 3),
    body-frame angular velocities ``W`` (R, 3) and the ``bodies`` (:class:`Bodies`) in place
    from ``t0`` to ``t_end`` [s], starting with ``n0`` steps of ``h0`` [s] (the frame interval
    divided into whole steps of at most ``control.dt``); returns a :class:`Marched`."""
    return _march(x, quat, v, W, bodies, t0, t_end, n0, h0, problem, control, scratch)


@numba.njit(cache=True, parallel=threads.PRANGE_ONLY, error_model="numpy")
def march_parallel(x, quat, v, W, bodies, t0, t_end, n0, h0, problem, control,
                   scratch):  # pragma: no cover - compiled
    """:func:`march` with the loops over rod elements and nodes on numba's threads."""
    return _march(x, quat, v, W, bodies, t0, t_end, n0, h0, problem, control, scratch)


@numba.njit(cache=True, error_model="numpy")
def march_free(x, quat, v, W, bodies, t0, t_end, n0, h0, problem, control,
               scratch):  # pragma: no cover - compiled
    """:func:`march` for a problem without rigid bodies (compiled without contact)."""
    return _march_free(x, quat, v, W, bodies, t0, t_end, n0, h0, problem, control, scratch)


@numba.njit(cache=True, parallel=threads.PRANGE_ONLY, error_model="numpy")
def march_parallel_free(x, quat, v, W, bodies, t0, t_end, n0, h0, problem, control,
                        scratch):  # pragma: no cover - compiled
    """:func:`march_parallel` for a problem without rigid bodies (compiled without contact)."""
    return _march_free(x, quat, v, W, bodies, t0, t_end, n0, h0, problem, control, scratch)


def march_for(problem: ExplicitProblem, parallel: bool):  # type: ignore[no-untyped-def]
    """The compiled loop that runs ``problem``: :func:`march` or, ``parallel``,
    :func:`march_parallel`, each without contact, segments and hinges when the problem has
    none of them (the same arithmetic: such a problem never enters the branches left out)."""
    nodes = problem.segments.pairs.shape[0] > 0 or problem.hinges.nodes.shape[0] > 0
    if problem.contact.kind.shape[0] > 0 or nodes:
        return march_parallel if parallel else march
    return march_parallel_free if parallel else march_free


def node_forces_only(problem: ExplicitProblem, control: StepControl) -> bool:
    """Whether :func:`march_nodes` can run ``problem``: fixed steps, forces on position nodes
    only (segments, bending hinges, dead loads, gravity), no rotations, rod elements or bodies."""
    return (not control.rotation_controlled and problem.rotations.inertia.shape[0] == 0
            and problem.rods.rest_length.shape[0] == 0 and problem.contact.kind.shape[0] == 0)


@numba.njit(cache=True, error_model="numpy")
def march_nodes(x, v, t0, t_end, n, h, problem, f_node,
                load_rate):  # pragma: no cover - compiled
    """:func:`march` for a problem of :func:`node_forces_only`: ``n`` fixed steps of ``h`` [s]
    from ``t0`` to ``t_end``, each the forces (S7), (K3), (K4) and the update (S9) with the
    next step's start force (the node weights) written in the same pass over the nodes; the
    same arithmetic in the same order as :func:`march`, so the same result to the last bit.
    ``f_node`` (N, 3) is work space, ``load_rate`` :attr:`Scratch.load_rate`. Returns a
    :class:`Marched`."""
    nodes, loads, seg, hinges = problem.nodes, problem.loads, problem.segments, problem.hinges
    inv_mass, weight = nodes.inv_mass, nodes.weight
    no_quat, no_moment = np.zeros((0, 4)), np.zeros((0, 3))
    peak, drift = 0.0, 0.0
    for i in range(x.shape[0]):
        for c in range(3):
            f_node[i, c] = weight[i, c]
    for k in range(n):
        _apply_loads(t0 + k * h, no_quat, loads, f_node, no_moment)
        if seg.pairs.shape[0] > 0:
            peak = max(peak, segment_forces(x, v, f_node, seg.pairs, seg.rest_length, seg.EA,
                                            seg.etaA, seg.kink_strain, seg.tension_only))
        if hinges.nodes.shape[0] > 0:
            hinge_forces(x, v, f_node, hinges.nodes, hinges.stiffness, hinges.tau, hinges.rest)
        rated = load_rate.shape[0] > 0
        if rated:
            start = _rate_products(x, v, loads.nodes, load_rate)
        bad = 0
        for i in range(x.shape[0]):
            for c in range(3):
                v[i, c] += h * f_node[i, c] * inv_mass[i, c]
                x[i, c] += h * v[i, c]
                f_node[i, c] = weight[i, c]
            if not (math.isfinite(x[i, 0]) and math.isfinite(x[i, 1]) and math.isfinite(x[i, 2])):
                bad += 1
        if rated:
            drift += factor_change(h, start, _rate_products(x, v, loads.nodes, load_rate))
        if bad:
            return Marched(1, t0 + (k + 1) * h, k + 1, k + 1, h, h, peak, 0.0, 0.0, 0.0, 0,
                           0.0, drift)
    return Marched(0, t_end, n, n, h if n else np.inf, h if n else 0.0, peak, 0.0, 0.0, 0.0,
                   0, 0.0, drift)


@numba.njit(cache=True)
def forces(t, x, quat, v, W, problem, scratch):  # pragma: no cover - compiled
    """The force (N, 3) [N] and body-frame moment (R, 3) [N m] on every node at time ``t``,
    contact aside, into ``scratch.f_node`` and ``scratch.m_node``; returns the largest axial
    force [N] and element rotation [rad]."""
    return _forces(t, x, quat, v, W, problem, scratch, 1)
