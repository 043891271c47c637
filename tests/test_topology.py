"""The square net against the seed paper's Eq. (1) and Fig. 1 (Ns = 6), and the packed state."""

from __future__ import annotations

import numpy as np
import pytest

from rodnet.scene import scene_from_toml
from rodnet.topology import build_structure, corner_knots, diameter, square_net_threads
from tests.conftest import small_net_toml


def seed_eq1_threads(ns: int) -> list[tuple[int, int]]:
    """Eq. (1) of the seed paper, literally, in its 1-based numbering."""
    return [(i, j) for i in range(1, ns * ns + 1) for j in range(i + 1, ns * ns + 1)
            if (j == i + 1 and i % ns != 0) or j == i + ns]


def test_ns6_matches_seed_figure() -> None:
    pairs = square_net_threads(6)
    assert len(pairs) == 60
    assert [(a + 1, b + 1) for a, b in pairs] == seed_eq1_threads(6)
    scene = scene_from_toml(small_net_toml().replace("nodes_per_side = 5", "nodes_per_side = 6"))
    s = build_structure(scene)
    # 36 knots, corner masses are nodes 37..40 (1-based), corner threads are 61..64 (1-based)
    assert [s.selectors[f"net:corner:{k}"] + 1 for k in range(4)] == [37, 38, 39, 40]
    assert s.net.n_threads == 64
    corner_threads = s.segments[s.thread >= 60]
    assert corner_threads.tolist() == [[0, 36], [5, 37], [30, 38], [35, 39]]
    assert corner_knots(6).tolist() == [0, 5, 30, 35]


@pytest.mark.parametrize("n", [1, 3])
def test_subdivision_and_packed_state(n: int) -> None:
    scene = scene_from_toml(small_net_toml(n=n, direction="[1.0, 2.0, -0.5]"))
    s = build_structure(scene)
    ns, n_threads = 5, 2 * 5 * 4 + 4
    assert s.n_nodes == ns * ns + 4 + n_threads * (n - 1)
    assert len(s.segments) == n_threads * n
    lengths = np.linalg.norm(s.positions[s.segments[:, 1]] - s.positions[s.segments[:, 0]], axis=1)
    np.testing.assert_allclose(lengths, 0.2 * s.rest_length, rtol=1e-12)  # slack, stress-free
    np.testing.assert_allclose(s.rest_length[s.thread < 40], 1.0 / n, rtol=1e-12)
    d = np.array([1.0, 2.0, -0.5]) / np.linalg.norm([1.0, 2.0, -0.5])
    plane = (s.rest_positions - np.array([1.0, -2.0, 0.5])) @ d
    np.testing.assert_allclose(plane, 0.0, atol=1e-12)  # deployed layout is flat, normal to d
    v = s.velocities[s.net.corners]
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), 10.0, rtol=1e-12)
    np.testing.assert_allclose(v @ d, 10.0 * np.cos(np.radians(40.0)), rtol=1e-12)
    outward = s.rest_positions[s.net.corners] - s.rest_positions[s.net.knots[corner_knots(5)]]
    assert np.all(np.einsum("ij,ij->i", v, outward) > 0)
    assert np.all(s.velocities[s.net.net_nodes] == 0.0)


def test_rod_nodes_spread_by_arc_length() -> None:
    scene = scene_from_toml("""
[model]
type = "lumped"
[[materials]]
name = "steel"
density = 7800.0
youngs_modulus = 2.1e11
diameter = 0.01
[[rods]]
name = "frame"
material = "steel"
points = [[0, 0, 0], [3, 0, 0], [3, 1, 0]]
elements = 8
""")
    s = build_structure(scene)
    assert s.n_nodes == 9 and len(s.segments) == 8
    np.testing.assert_allclose(s.rest_length, 0.5, rtol=1e-12)
    assert s.selectors["frame:start"] == 0 and s.selectors["frame:end"] == 8
    np.testing.assert_allclose(s.positions[s.selectors["frame:6"]], [3.0, 0.0, 0.0])


def test_the_size_of_a_point_set_is_its_largest_distance_whatever_its_orientation() -> None:
    """:func:`rodnet.topology.diameter` over the convex hull (more than 256 points, flat and on
    a line: joggled) equals the largest distance over all pairs, and turning the points does not
    change it (the bounding box's diagonal did)."""
    from rodnet.kernels import so3

    rng = np.random.default_rng(3)
    line = np.outer(np.linspace(0.0, 2.0, 400), [1.0, 0.5, 0.0])
    grid = np.stack(np.meshgrid(np.linspace(0.0, 3.0, 30), np.linspace(0.0, 4.0, 30)), -1)
    flat = np.c_[grid.reshape(-1, 2), np.zeros(900)]
    cloud = rng.normal(size=(500, 3)) * [3.0, 1.0, 0.2]
    turn = so3.so3_exp(np.array([[0.3, -1.1, 0.7]]))[0]
    for points in (line, flat, cloud):
        pairs = np.sqrt(((points[:, None] - points[None]) ** 2).sum(-1)).max()
        assert diameter(points) == pytest.approx(pairs, rel=1e-14)
        assert diameter(points @ turn.T) == pytest.approx(pairs, rel=1e-12)
