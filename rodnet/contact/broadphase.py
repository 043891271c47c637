"""Which thread points may touch a body, and how their contact forces reach the nodes.

A thread is a chain of capsules of radius r around straight segments between nodes. Contact is
checked at points on the centreline: every node once, plus ``points_per_segment - 1`` equally
spaced interior points on each segment, (B2). Selection is two vectorised box tests in the
body frame: segments whose bounding box, grown by ``r + margin``, overlaps the body's bounding
box (B1), then points inside that grown box. A point at parameter ``xi`` on the segment from node
a to node b passes its force to the two nodes with the linear shape functions ``1 - xi`` and
``xi``, (B3)-(B5); the body gets the opposite forces at the same points, (B6). Equations:
``elements/contact/FORMULATION.md`` section 5.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from rodnet.contact.geometry import FloatArray, IntArray


class ContactPoints(NamedTuple):
    """C candidate contact points on thread centrelines."""

    segment: IntArray
    """(C,) index of the segment the point lies on."""
    parameter: FloatArray
    """(C,) xi in [0, 1] from the segment's first to its second node."""
    position: FloatArray
    """(C, 3) world position [m]."""
    local: FloatArray
    """(C, 3) position in the body frame [m], ready for ``shape.query``."""
    weight: FloatArray
    """(C,) length of thread the point stands for [m] (trapezoidal rule along the thread)."""


def _to_body(points: FloatArray, position: FloatArray, rotation: FloatArray) -> FloatArray:
    """``R^T (x - p)`` for points (..., 3): world to body frame."""
    # einsum rather than ``@``: a threaded BLAS call for a (P, 3) x (3, 3) product is slow
    return np.einsum("...i,ij->...j", np.asarray(points, dtype=np.float64) - position,
                     np.asarray(rotation, dtype=np.float64))


def _reach(radius: FloatArray | float, n_segments: int, margin: float) -> FloatArray:
    return np.broadcast_to(np.asarray(radius, dtype=np.float64), (n_segments,)) + margin


def candidate_segments(endpoints: FloatArray, radius: FloatArray | float, position: FloatArray,
                       rotation: FloatArray, bounds: FloatArray, margin: float = 0.0) -> IntArray:
    """Segments whose capsule may come within ``margin`` of the body's bounding box, (B1).

    Parameters
    ----------
    endpoints : (S, 2, 3) float
        World positions of the two nodes of every segment [m].
    radius : float or (S,) float
        Thread radius r [m].
    position : (3,) float
        World position of the body frame's origin [m].
    rotation : (3, 3) float
        Body-to-world rotation.
    bounds : (2, 3) float
        Lower and upper corner of the body's bounding box in its own frame [m] (``shape.bounds``).
    margin : float
        Extra distance [m] (e.g. how far a point can move in one step).

    Returns
    -------
    (K,) int, ascending
    """
    local = _to_body(endpoints, position, rotation)
    bounds = np.asarray(bounds, dtype=np.float64)
    reach = _reach(radius, local.shape[0], margin)[:, None]
    lower = np.minimum(local[:, 0], local[:, 1]) - reach
    upper = np.maximum(local[:, 0], local[:, 1]) + reach
    overlap = np.all((lower <= bounds[1]) & (upper >= bounds[0]), axis=1)
    return np.flatnonzero(overlap)


def contact_points(endpoints: FloatArray, radius: FloatArray | float, position: FloatArray,
                   rotation: FloatArray, bounds: FloatArray, margin: float = 0.0,
                   points_per_segment: int = 2, segment_nodes: IntArray | None = None,
                   ) -> ContactPoints:
    """Points on the candidate segments inside the body's bounding box grown by ``r + margin``, (B2).

    Parameters
    ----------
    endpoints, radius, position, rotation, bounds, margin
        As in :func:`candidate_segments`.
    points_per_segment : int
        n >= 1: the points of a segment sit at ``xi = j / n``; its nodes (``j = 0, n``) are
        taken once per node, the ``n - 1`` interior points once per segment.
    segment_nodes : (S, 2) int or None
        Node index of each segment end, so that a node shared by several segments is one
        point; without it every segment end is its own node.

    Returns
    -------
    ContactPoints
        Nodes first, in ascending node order, then interior points by segment.
    """
    if points_per_segment < 1:
        raise ValueError(f"points_per_segment = {points_per_segment}: must be >= 1")
    endpoints = np.asarray(endpoints, dtype=np.float64)
    bounds = np.asarray(bounds, dtype=np.float64)
    n_segments = endpoints.shape[0]
    nodes = (np.arange(2 * n_segments).reshape(-1, 2) if segment_nodes is None
             else np.asarray(segment_nodes))
    reach = _reach(radius, n_segments, margin)
    # bounding spheres first: far from the body, nothing more is computed
    half = 0.5 * np.linalg.norm(endpoints[:, 1] - endpoints[:, 0], axis=1)
    centre = np.linalg.norm(0.5 * (endpoints[:, 0] + endpoints[:, 1]) - position, axis=1)
    body_radius = float(np.linalg.norm(np.abs(bounds).max(axis=0)))
    if n_segments == 0 or not (centre - half - reach <= body_radius).any():
        empty = np.zeros(0)
        return ContactPoints(np.zeros(0, np.int64), empty, np.zeros((0, 3)), np.zeros((0, 3)),
                             empty)
    cand = candidate_segments(endpoints, radius, position, rotation, bounds, margin)
    n = points_per_segment
    length = np.linalg.norm(endpoints[cand, 1] - endpoints[cand, 0], axis=1)
    # nodes: each once, on the first candidate segment that has it; weight (B4)
    unique, first, inverse = np.unique(nodes[cand].ravel(), return_index=True, return_inverse=True)
    node_segment = np.repeat(cand, 2)[first]
    node_xi = np.tile([0.0, 1.0], cand.size)[first]
    node_weight = np.bincount(inverse, weights=np.repeat(length / (2 * n), 2), minlength=unique.size)
    # interior points
    inner_segment = np.repeat(cand, n - 1)
    inner_xi = np.tile(np.arange(1, n) / n, cand.size)
    inner_weight = np.repeat(length / n, n - 1)
    segment = np.concatenate([node_segment, inner_segment]).astype(np.int64)
    xi = np.concatenate([node_xi, inner_xi])
    weight = np.concatenate([node_weight, inner_weight])
    world = (1.0 - xi)[:, None] * endpoints[segment, 0] + xi[:, None] * endpoints[segment, 1]
    local = _to_body(world, position, rotation)
    grow = reach[segment][:, None]
    inside = np.all((local >= bounds[0] - grow) & (local <= bounds[1] + grow), axis=1)
    return ContactPoints(segment[inside], xi[inside], world[inside], local[inside], weight[inside])


def shape_functions(parameter: FloatArray) -> FloatArray:
    """Linear shape functions ``[1 - xi, xi]`` of the two segment nodes, (B3): (C,) -> (C, 2)."""
    xi = np.asarray(parameter, dtype=np.float64)
    return np.stack([1.0 - xi, xi], axis=1)


def distribute_force(force: FloatArray, points: ContactPoints, segment_nodes: IntArray,
                     n_nodes: int) -> FloatArray:
    """Nodal forces ``F_a = sum_c N_a(xi_c) f_c`` of point forces, (B5).

    Parameters
    ----------
    force : (C, 3) float
        Force on each contact point [N].
    points : ContactPoints
    segment_nodes : (S, 2) int
        Node index of each segment end.
    n_nodes : int

    Returns
    -------
    (n_nodes, 3) float [N]
    """
    weights = shape_functions(points.parameter)
    nodal = np.zeros((n_nodes, 3))
    np.add.at(nodal, np.asarray(segment_nodes)[points.segment].ravel(),
              (weights[:, :, None] * np.asarray(force)[:, None, :]).reshape(-1, 3))
    return nodal


def segment_blocks(d_force: FloatArray, parameter: FloatArray) -> FloatArray:
    """Derivative of the two nodal forces with respect to the two nodes' positions (or
    velocities) for each point, ``N_a N_b df/dx``, (B5).

    Parameters
    ----------
    d_force : (C, 3, 3) float
        df/dx or df/dv of each contact point.
    parameter : (C,) float
        xi of each point.

    Returns
    -------
    (C, 6, 6) float
        Rows and columns ordered ``[node a (3), node b (3)]`` of the point's segment.
    """
    weights = shape_functions(parameter)
    blocks = weights[:, :, None, None, None] * weights[:, None, :, None, None] \
        * np.asarray(d_force)[:, None, None, :, :]
    return blocks.transpose(0, 1, 3, 2, 4).reshape(-1, 6, 6)


def body_point_velocity(points: FloatArray, body_position: FloatArray, body_velocity: FloatArray,
                        angular_velocity: FloatArray) -> FloatArray:
    """Velocity of the body's material points at world ``points`` (C, 3), (B6).

    ``v_B + omega x (x - p)``, with the angular velocity ``omega`` (3,) in world components
    (``R @ omega_body``). The relative velocity passed to the contact law is the thread point's
    velocity minus this.
    """
    arm = np.asarray(points, dtype=np.float64) - body_position
    return np.asarray(body_velocity, dtype=np.float64) + np.cross(angular_velocity, arm)


def body_reaction(force: FloatArray, points: FloatArray, body_position: FloatArray,
                  ) -> tuple[FloatArray, FloatArray]:
    """Force (3,) [N] and moment about the centre of mass (3,) [N m], world components, that
    point forces ``force`` (C, 3) on the thread at ``points`` (C, 3) exert back on the body, (B6)."""
    f = np.asarray(force, dtype=np.float64)
    arm = np.asarray(points, dtype=np.float64) - body_position
    return -f.sum(axis=0), -np.cross(arm, f).sum(axis=0)
