"""Triads, quaternion signs, support DOFs and section corrections of rod structures: what the
builders of rods (:mod:`rodnet.models.cosserat.build`) and nets (:mod:`rodnet.models.cosserat.net`)
share.

Rod triads (:func:`corner_triads`): ``d1`` along each element's chord, ``d2``, ``d3`` carried
along each rod by parallel transport from a first triad whose ``d2`` is the global z axis
projected normal to ``d1`` (y when ``d1`` is along z); a polyline's corner joins its two elements
rigidly through an end offset. The stress-free strains are measured from these triads, so any
choice is stress-free; parallel transport keeps the reference twist zero. A corner node's own
triad is set by the corner alone (the incoming chord and the corner's plane), so that its lumped
rotary inertia, kept diagonal in that triad, does not depend on how the scene is oriented.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy.sparse.csgraph import breadth_first_order

from rodnet.kernels import so3

FloatArray = NDArray[np.float64]


def corner_triads(points: FloatArray, segments: NDArray[np.int64], thread: NDArray[np.int64]
                  ) -> tuple[FloatArray, FloatArray]:
    """Triads of a polyline taken literally: each element straight with ``d1`` along its chord,
    the triad carried from element to element by the smallest rotation between their chords
    (parallel transport, so no reference twist), and a node's triad that of the element
    ending there (the first element's at a chain's first node), except at a corner of the
    polyline: there ``d1`` is along the incoming chord ``a``, ``d3`` along ``a x b`` (``b`` the
    outgoing chord) and ``d2 = d3 x d1``, a triad the corner's geometry alone fixes (the
    element's own ``d2`` comes from the global z axis: the rotary inertia kept diagonal in it
    turned with the scene's orientation, 4.8 % at a 37 degree rotation).

    Returns
    -------
    R_nodes : (N, 3, 3) float
        The nodes' triads (columns d1, d2, d3).
    offset_R : (E, 2, 3, 3) float
        Each element end's triad in its node's frame, ``R_node^T R_element``: the identity
        except at a corner of the polyline, where the node joins its two elements rigidly.
    """
    d = points[segments[:, 1]] - points[segments[:, 0]]
    d /= np.linalg.norm(d, axis=1)[:, None]
    R_el = np.empty((len(segments), 3, 3))
    R = np.tile(np.eye(3), (len(points), 1, 1))
    for th in np.unique(thread):
        chain = np.flatnonzero(thread == th)
        R_el[chain[0]] = _first_triad(d[chain[0]])
        R[segments[chain[0], 0]] = R_el[chain[0]]
        for prev, e in zip(chain[:-1], chain[1:]):
            R_el[e] = _transport(d[prev], d[e]) @ R_el[prev]
        R[segments[chain, 1]] = R_el[chain]
        for prev, e in zip(chain[:-1], chain[1:]):
            normal = np.cross(d[prev], d[e])
            size = np.linalg.norm(normal)
            if size > 1e-12:   # a corner
                normal /= size
                R[segments[prev, 1]] = np.column_stack([d[prev], np.cross(normal, d[prev]), normal])
    offset_R = np.einsum("enji,ejk->enik", R[segments], R_el)
    return R, offset_R


def oriented_ends(R_nodes: FloatArray, rot_nodes: NDArray[np.int64], offset_R: FloatArray,
                  rest_length: FloatArray, rho_i: FloatArray
                  ) -> tuple[FloatArray, FloatArray | None, FloatArray, FloatArray]:
    """What rods and nets build alike from their rotation nodes' triads ``R_nodes`` (R, 3, 3)
    and each element end's offset ``offset_R`` (E, 2, 3, 3) in its node's frame.

    Returns
    -------
    quat_nodes : (R, 4) float
        The nodes' quaternions, signed by :func:`align_quaternion_signs`.
    end_offset : (E, 2, 4) float or None
        The ends' offsets as quaternions; None where every one is the identity.
    quat_ends : (E, 2, 4) float
        The element ends' quaternions ``q_node o offset``.
    rotary : (R, 3) float
        The nodes' lumped rotary inertia (C36)-(C38): each end's ``Le/2 diag(2 rho I, rho I,
        rho I)`` turned by its offset into its node's triad, the diagonal kept.
    """
    end_offset = None if np.allclose(offset_R, np.eye(3), atol=1e-14) else \
        so3.quat_from_matrix(offset_R)
    rotary = np.zeros((len(R_nodes), 3))
    inertia_end = 0.5 * rest_length[:, None] * rho_i[:, None] * np.array([2.0, 1.0, 1.0])
    for end in (0, 1):
        in_node = np.einsum("eij,ej,ekj->eik", offset_R[:, end], inertia_end, offset_R[:, end])
        np.add.at(rotary, rot_nodes[:, end], np.diagonal(in_node, axis1=1, axis2=2))
    quat_nodes, end_offset = align_quaternion_signs(so3.quat_from_matrix(R_nodes), rot_nodes,
                                                    end_offset)
    quat_ends = quat_nodes[rot_nodes]
    if end_offset is not None:
        quat_ends = so3.quat_multiply(quat_ends, end_offset)
    return quat_nodes, end_offset, quat_ends, rotary


def _first_triad(t: FloatArray) -> FloatArray:
    ref = np.array([0.0, 0.0, 1.0]) if abs(t[2]) < 0.9 else np.array([0.0, 1.0, 0.0])
    d2 = ref - (ref @ t) * t
    d2 /= np.linalg.norm(d2)
    return np.column_stack([t, d2, np.cross(t, d2)])


def _transport(a: FloatArray, b: FloatArray) -> FloatArray:
    """The smallest rotation taking unit vector ``a`` to ``b``."""
    axis = np.cross(a, b)
    s, c = np.linalg.norm(axis), float(a @ b)
    if s < 1e-14:
        return np.eye(3)
    return so3.so3_exp((axis / s * np.arctan2(s, c))[None])[0]


def support_dofs(names: tuple[str, ...], node: int, rotation: int, n_nodes: int) -> list[int]:
    """Global DOF indices of the support DOF ``names`` at a position node and its rotation node
    (``rotation < 0``: the node has no rotation of its own; rotation names are then ignored)."""
    dofs = [3 * node + "xyz".index(d) for d in names if d in ("x", "y", "z")]
    if rotation >= 0:
        dofs += [3 * (n_nodes + rotation) + int(d[1]) - 1 for d in names if d.startswith("r")]
    return dofs


def align_quaternion_signs(quat_nodes: FloatArray, rot_nodes: NDArray[np.int64],
                           end_offset: FloatArray | None) -> tuple[FloatArray, FloatArray | None]:
    """Signs of the node quaternions (and of the end offsets) that start every element's
    relative rotation on its short branch.

    The relative rotation vector is the logarithm of ``conj(q1) q2`` on the quaternion double
    cover (C11): it follows the rotations continuously past pi, so it starts where the sign of
    each quaternion puts it, and ``q`` and ``-q`` differ by a full turn. The elements must start
    with ``w >= 0``. Node signs are propagated along a spanning tree of the elements; an element
    closing a loop with the wrong sign (a ring whose triads turn once around) gets an end
    offset of ``-1`` (the identity rotation with the other sign).

    Parameters
    ----------
    quat_nodes : (R, 4) float
    rot_nodes : (E, 2) int
    end_offset : (E, 2, 4) float or None

    Returns
    -------
    quat_nodes : (R, 4) float
    end_offset : (E, 2, 4) float or None
    """
    def relative_w(q: FloatArray, offset: FloatArray | None) -> FloatArray:
        ends = q[rot_nodes]
        if offset is not None:
            ends = so3.quat_multiply(ends, offset)
        return np.einsum("ei,ei->e", ends[:, 0], ends[:, 1])

    q = quat_nodes.copy()
    if np.all(relative_w(q, end_offset) >= 0.0):
        return q, end_offset
    if end_offset is None:
        n = len(q)
        a, b = rot_nodes[:, 0], rot_nodes[:, 1]
        graph = sp.csr_matrix((np.ones(2 * len(a)), (np.r_[a, b], np.r_[b, a])), shape=(n, n))
        sign = np.zeros(n)
        for root in range(n):
            if sign[root]:
                continue
            order, parent = breadth_first_order(graph, root, directed=False)
            sign[root] = 1.0
            for node in order[1:]:
                p = parent[node]
                sign[node] = sign[p] * (1.0 if q[p] @ q[node] >= 0.0 else -1.0)
        q *= sign[:, None]
        wrong = relative_w(q, None) < 0.0
        if not wrong.any():
            return q, None
        end_offset = np.zeros((len(rot_nodes), 2, 4))
        end_offset[:, :, 0] = 1.0
    else:
        end_offset = end_offset.copy()
        wrong = relative_w(q, end_offset) < 0.0
    end_offset[wrong, 1] *= -1.0
    return q, end_offset


def residual_bending_shear(stiffness: FloatArray, rest_length: FloatArray) -> FloatArray:
    """Section stiffnesses with the shear stiffness lowered by the residual bending flexibility
    of each element (FORMULATION.md, C44): ``1/GA_eff = 1/GA + Le^2 / (12 EI)``.

    Parameters
    ----------
    stiffness : (E, 6) float
        ``[EA, GA2, GA3, GJ, EI2, EI3]`` [N, N m^2]; shear along ``d2`` bends about ``d3``, so
        ``GA2`` pairs with ``EI3`` and ``GA3`` with ``EI2``.
    rest_length : (E,) float
        Element length ``Le`` [m].

    Returns
    -------
    (E, 6) float
        A copy with ``GA2``, ``GA3`` replaced; 0 where the paired ``EI`` is 0 (no bending
        stiffness: nothing resists the element's rotation relative to its chord).
    """
    out = np.array(stiffness, dtype=float)
    for shear, bend in ((1, 5), (2, 4)):
        ga, ei = out[:, shear], out[:, bend]
        flexible = (ei > 0.0) & (ga > 0.0)
        ei, ga = np.where(flexible, ei, 1.0), np.where(flexible, ga, 1.0)
        out[:, shear] = np.where(flexible, 1.0 / (1.0 / ga + rest_length**2 / (12.0 * ei)), 0.0)
    return out
