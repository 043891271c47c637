"""Broad phase and force distribution (elements/contact/FORMULATION.md §5)."""

from __future__ import annotations

import numpy as np

from rodnet.contact.broadphase import (body_point_velocity, body_reaction, candidate_segments,
                                       contact_points, distribute_force, segment_blocks,
                                       shape_functions)
from rodnet.contact.geometry import Box

RNG = np.random.default_rng(11)


def rotation(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]) @ np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


POSITION, ROTATION = np.array([0.5, -1.0, 2.0]), rotation(0.8)
BOUNDS = np.array([[-1.0, -0.5, -0.3], [1.0, 0.5, 0.3]])


def random_segments(n: int) -> np.ndarray:
    start = POSITION + RNG.uniform(-3, 3, (n, 3))
    return np.stack([start, start + RNG.normal(scale=0.3, size=(n, 3))], axis=1)


def test_candidates_are_exactly_the_brute_force_box_overlaps() -> None:
    endpoints = random_segments(5000)
    radius = RNG.uniform(1e-3, 0.05, 5000)
    margin = 0.1
    expected = []
    for s, (a, b) in enumerate(endpoints):
        la, lb = ROTATION.T @ (a - POSITION), ROTATION.T @ (b - POSITION)
        lo, hi = np.minimum(la, lb) - radius[s] - margin, np.maximum(la, lb) + radius[s] + margin
        if np.all(lo <= BOUNDS[1]) and np.all(hi >= BOUNDS[0]):
            expected.append(s)
    got = candidate_segments(endpoints, radius, POSITION, ROTATION, BOUNDS, margin)
    np.testing.assert_array_equal(got, expected)
    assert 50 < len(got) < 4950


def test_no_segment_within_reach_of_the_body_is_missed() -> None:
    endpoints = random_segments(3000)
    radius, margin = 0.02, 0.05
    got = set(candidate_segments(endpoints, radius, POSITION, ROTATION, BOUNDS, margin).tolist())
    box = Box(tuple(BOUNDS[1]))
    xi = np.linspace(0, 1, 101)
    dense = (1 - xi)[None, :, None] * endpoints[:, None, 0] + xi[None, :, None] * endpoints[:, None, 1]
    d = box.query(((dense - POSITION) @ ROTATION).reshape(-1, 3)).distance.reshape(len(endpoints), -1)
    touching = np.flatnonzero(d.min(axis=1) <= radius + margin)
    assert len(touching) > 10 and set(touching.tolist()) <= got


def test_points_take_each_node_once_and_weights_add_up_to_the_thread_length() -> None:
    # a polyline threading through the box along its body x axis
    n_nodes = 21
    local = np.stack([np.linspace(-0.9, 0.9, n_nodes), np.zeros(n_nodes), np.full(n_nodes, 0.305)], 1)
    nodes = POSITION + local @ ROTATION.T
    segment_nodes = np.stack([np.arange(n_nodes - 1), np.arange(1, n_nodes)], 1)
    endpoints = nodes[segment_nodes]
    points = contact_points(endpoints, 0.01, POSITION, ROTATION, BOUNDS, margin=0.0,
                            points_per_segment=3, segment_nodes=segment_nodes)
    assert len(points.segment) == n_nodes + 2 * (n_nodes - 1)
    assert np.isclose(points.weight.sum(), 1.8, rtol=1e-12)
    expected = (1 - points.parameter)[:, None] * endpoints[points.segment, 0] \
        + points.parameter[:, None] * endpoints[points.segment, 1]
    np.testing.assert_allclose(points.position, expected)
    np.testing.assert_allclose(points.local, (points.position - POSITION) @ ROTATION, atol=1e-14)
    node_of_point = np.where(points.parameter == 0.0, segment_nodes[points.segment, 0],
                             np.where(points.parameter == 1.0, segment_nodes[points.segment, 1], -1))
    assert sorted(node_of_point[node_of_point >= 0].tolist()) == list(range(n_nodes))
    # without node indices each segment end is its own point
    loose = contact_points(endpoints, 0.01, POSITION, ROTATION, BOUNDS, points_per_segment=3)
    assert len(loose.segment) == 2 * (n_nodes - 1) + 2 * (n_nodes - 1)
    assert np.isclose(loose.weight.sum(), 1.8)
    # points outside the grown box are dropped
    far = contact_points(endpoints + ROTATION[:, 2] * 0.05, 0.01, POSITION, ROTATION, BOUNDS)
    assert len(far.segment) == 0


def test_distribution_keeps_force_and_moment_and_blocks_match_differences() -> None:
    n_nodes = 6
    nodes = POSITION + RNG.uniform(-0.4, 0.4, (n_nodes, 3))
    segment_nodes = np.array([[0, 1], [1, 2], [2, 3], [3, 4], [4, 5], [5, 0]])
    points = contact_points(nodes[segment_nodes], 0.01, POSITION, ROTATION, BOUNDS, 1.0, 4, segment_nodes)
    force = RNG.normal(size=(len(points.segment), 3))
    nodal = distribute_force(force, points, segment_nodes, n_nodes)
    np.testing.assert_allclose(nodal.sum(axis=0), force.sum(axis=0), atol=1e-12)
    np.testing.assert_allclose(np.cross(nodes, nodal).sum(axis=0),
                               np.cross(points.position, force).sum(axis=0), atol=1e-12)
    np.testing.assert_allclose(shape_functions(points.parameter).sum(axis=1), 1.0)
    # a linear point-force field f = K x: the nodal Jacobian assembled from the 6x6 blocks
    K = RNG.normal(size=(3, 3))
    blocks = segment_blocks(np.broadcast_to(K, (len(points.segment), 3, 3)), points.parameter)
    jac = np.zeros((3 * n_nodes, 3 * n_nodes))
    for c, s in enumerate(points.segment):
        dofs = (3 * segment_nodes[s][:, None] + np.arange(3)).ravel()
        jac[np.ix_(dofs, dofs)] += blocks[c]

    def nodal_force(flat: np.ndarray) -> np.ndarray:
        x = flat.reshape(-1, 3)
        at = (1 - points.parameter)[:, None] * x[segment_nodes[points.segment, 0]] \
            + points.parameter[:, None] * x[segment_nodes[points.segment, 1]]
        return distribute_force(at @ K.T, points, segment_nodes, n_nodes).ravel()

    fd = np.stack([(nodal_force(nodes.ravel() + 1e-6 * e) - nodal_force(nodes.ravel() - 1e-6 * e)) / 2e-6
                   for e in np.eye(3 * n_nodes)], axis=1)
    np.testing.assert_allclose(jac, fd, atol=1e-8)


def test_thread_and_body_forces_balance_in_force_and_moment() -> None:
    n_nodes = 8
    nodes = POSITION + RNG.uniform(-0.5, 0.5, (n_nodes, 3))
    segment_nodes = np.stack([np.arange(n_nodes - 1), np.arange(1, n_nodes)], 1)
    points = contact_points(nodes[segment_nodes], 0.01, POSITION, ROTATION, BOUNDS, 0.5, 3, segment_nodes)
    force = RNG.normal(size=(len(points.segment), 3))
    nodal = distribute_force(force, points, segment_nodes, n_nodes)
    body_force, body_moment = body_reaction(force, points.position, POSITION)
    np.testing.assert_allclose(nodal.sum(axis=0) + body_force, 0.0, atol=1e-12)
    np.testing.assert_allclose(np.cross(nodes - POSITION, nodal).sum(axis=0) + body_moment, 0.0, atol=1e-12)
    # rigid motion x(t) = p + v t + exp(t hat(omega)) (x0 - p): its velocity at t = 0
    omega, velocity = np.array([0.3, -1.0, 2.0]), np.array([1.0, 0.0, -0.5])

    def moved(t: float) -> np.ndarray:
        angle, axis = np.linalg.norm(omega) * t, omega / np.linalg.norm(omega)
        k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        turn = np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k
        return POSITION + velocity * t + (points.position - POSITION) @ turn.T

    at = body_point_velocity(points.position, POSITION, velocity, omega)
    np.testing.assert_allclose(at, (moved(1e-6) - moved(-1e-6)) / 2e-6, atol=1e-8)
