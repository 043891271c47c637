"""Rigid body shapes: distances against brute force, normals and their derivatives against
finite differences, mesh loading and mass properties (elements/contact/FORMULATION.md §1)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from rodnet.contact.geometry import Box, Cylinder, Sphere, query_world
from rodnet.contact.shapes import shape_from_scene
from rodnet.contact.mesh import TriangleMesh, load_mesh
from rodnet.errors import SceneError

RNG = np.random.default_rng(20261122)


# ---------- independent oracles ----------

def brute_force_triangles(points: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Unsigned distance of every point to the nearest of all triangles (F, 3, 3), vectorised
    over all pairs: the closest point of a triangle is the nearest of its interior projection
    (when inside) and the closest points on its three edges."""
    p = points[:, None, :]
    a, b, c = tri[None, :, 0], tri[None, :, 1], tri[None, :, 2]

    def edge(u, v):
        t = np.clip(np.einsum("pfi,pfi->pf", p - u, v - u) / np.einsum("pfi,pfi->pf", v - u, v - u), 0, 1)
        return np.linalg.norm(p - (u + t[..., None] * (v - u)), axis=2)

    best = np.minimum(np.minimum(edge(a, b), edge(b, c)), edge(c, a))
    n = np.cross(b - a, c - a)
    n = n / np.linalg.norm(n, axis=2, keepdims=True)
    h = np.einsum("pfi,pfi->pf", p - a, n)
    q = p - h[..., None] * n
    inside = np.ones(best.shape, bool)
    for u, v in ((a, b), (b, c), (c, a)):
        inside &= np.einsum("pfi,pfi->pf", np.cross(v - u, q - u), n) >= 0
    return np.where(inside, np.minimum(best, np.abs(h)), best).min(axis=1)


def winding_number(points: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Generalised winding number (van Oosterom-Strackee solid angles): 1 inside, 0 outside."""
    a, b, c = (tri[None, :, k] - points[:, None, :] for k in range(3))
    la, lb, lc = (np.linalg.norm(v, axis=2) for v in (a, b, c))
    num = np.einsum("pfi,pfi->pf", a, np.cross(b, c))
    den = la * lb * lc + np.einsum("pfi,pfi->pf", a, b) * lc + np.einsum("pfi,pfi->pf", b, c) * la \
        + np.einsum("pfi,pfi->pf", c, a) * lb
    return (2 * np.arctan2(num, den)).sum(axis=1) / (4 * np.pi)


def rectangle_distance_2d(rho: np.ndarray, z: np.ndarray, radius: float, half: float) -> np.ndarray:
    """Signed distance in the meridian half-plane to the rectangle [0, R] x [-H, H] (its three
    boundary segments that are not on the axis), by brute force over the segments."""
    p = np.stack([rho, z], axis=1)
    segments = [((radius, -half), (radius, half)), ((0, half), (radius, half)), ((0, -half), (radius, -half))]
    dist = []
    for u, v in segments:
        u, v = np.array(u, float), np.array(v, float)
        t = np.clip((p - u) @ (v - u) / ((v - u) @ (v - u)), 0, 1)
        dist.append(np.linalg.norm(p - (u + t[:, None] * (v - u)), axis=1))
    unsigned = np.min(dist, axis=0)
    inside = (rho < radius) & (np.abs(z) < half)
    return np.where(inside, -unsigned, unsigned)


def box_rectangles_distance(x: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Signed distance to a box as the nearest of its six face rectangles."""
    best = np.full(x.shape[0], np.inf)
    for axis in range(3):
        for side in (-1.0, 1.0):
            c = np.clip(x, -h, h)
            c[:, axis] = side * h[axis]
            best = np.minimum(best, np.linalg.norm(x - c, axis=1))
    inside = np.all(np.abs(x) < h, axis=1)
    return np.where(inside, -best, best)


def near_features(h: np.ndarray, n: int) -> np.ndarray:
    """Points close to the corners and edge midpoints of a box, inside and outside."""
    corners = np.array(np.meshgrid(*[[-1, 1]] * 3)).reshape(3, -1).T * h
    edges = []
    for axis in range(3):
        for s1 in (-1, 1):
            for s2 in (-1, 1):
                e = np.zeros(3)
                e[(axis + 1) % 3], e[(axis + 2) % 3] = s1 * h[(axis + 1) % 3], s2 * h[(axis + 2) % 3]
                edges.append(e)
    anchors = np.concatenate([corners, np.array(edges)])
    return anchors[RNG.integers(len(anchors), size=n)] + RNG.normal(scale=0.05 * h.min(), size=(n, 3))


def finite_difference(func, points: np.ndarray, step: float = 1e-6) -> np.ndarray:
    """Central differences of func (P, 3) -> (P, ...) w.r.t. the points: (P, ..., 3)."""
    cols = [(func(points + step * e) - func(points - step * e)) / (2 * step) for e in np.eye(3)]
    return np.stack(cols, axis=-1)


# ---------- primitives ----------

def test_box_distance_matches_brute_force_inside_outside_edges_corners() -> None:
    h = np.array([1.0, 0.5, 0.3])
    box = Box(tuple(h))
    x = np.concatenate([RNG.uniform(-2 * h, 2 * h, (2000, 3)), near_features(h, 2000)])
    q = box.query(x)
    np.testing.assert_allclose(q.distance, box_rectangles_distance(x, h), atol=1e-14)
    np.testing.assert_allclose(np.linalg.norm(q.normal, axis=1), 1.0, atol=1e-14)
    # the closest point is on the surface and at |d| from x
    assert np.all(np.abs(box.query(q.closest).distance) < 1e-14)
    np.testing.assert_allclose(np.linalg.norm(x - q.closest, axis=1), np.abs(q.distance), atol=1e-14)


def test_box_known_values() -> None:
    box = Box((1.0, 2.0, 3.0))
    x = np.array([[0.0, 0.0, 4.0], [2.0, 3.0, 0.0], [2.0, 3.0, 5.0], [0.5, 0.0, 0.0], [1.0, 0.0, 0.0]])
    q = box.query(x)
    np.testing.assert_allclose(q.distance, [1.0, np.sqrt(2), np.sqrt(6), -0.5, 0.0])
    np.testing.assert_allclose(q.normal[2], np.array([1, 1, 2]) / np.sqrt(6))
    np.testing.assert_allclose(q.normal[3], [1, 0, 0])


def test_cylinder_distance_matches_meridian_brute_force() -> None:
    radius, length = 0.7, 2.0
    for axis in (0, 1, 2):
        cyl = Cylinder(radius, length, axis=axis)
        x = RNG.uniform(-1.5, 1.5, (3000, 3))
        # add points near the rim circles
        theta = RNG.uniform(0, 2 * np.pi, 1000)
        rim = np.stack([radius * np.cos(theta), radius * np.sin(theta), np.sign(theta - np.pi) * 1.0], 1)
        rim = rim + RNG.normal(scale=0.02, size=rim.shape)
        rim = rim[:, [(k - axis - 1) % 3 for k in range(3)]] if axis != 2 else rim
        x = np.concatenate([x, rim])
        z = x[:, axis]
        rho = np.linalg.norm(np.delete(x, axis, axis=1), axis=1)
        q = cyl.query(x)
        np.testing.assert_allclose(q.distance, rectangle_distance_2d(rho, z, radius, length / 2), atol=1e-14)
        np.testing.assert_allclose(np.abs(cyl.query(q.closest).distance), 0.0, atol=1e-14)


def test_sphere_known_values() -> None:
    q = Sphere(2.0).query(np.array([[3.0, 0, 0], [0, 0, 1.0], [0, 0, 0]]))
    np.testing.assert_allclose(q.distance, [1.0, -1.0, -2.0])
    np.testing.assert_allclose(q.closest[:2], [[2.0, 0, 0], [0, 0, 2.0]])
    assert np.isfinite(q.normal_gradient).all()


def away_from_medial(shape, x: np.ndarray, gap: float = 1e-3) -> np.ndarray:
    """Mask of points farther than ``gap`` from medial surfaces and region borders."""
    if isinstance(shape, Box):
        ex = np.sort(np.abs(x) - np.array(shape.half_extents), axis=1)
        inside = ex[:, 2] < 0
        return np.where(inside, ex[:, 2] - ex[:, 1] > gap, np.all(np.abs(ex) > gap, axis=1))
    if isinstance(shape, Cylinder):
        z = np.abs(x[:, shape.axis]) - shape.length / 2
        r = np.linalg.norm(np.delete(x, shape.axis, axis=1), axis=1)
        side = r - shape.radius
        return (np.abs(side - z) > gap) & (np.abs(side) > gap) & (np.abs(z) > gap) & (r > gap)
    return np.linalg.norm(x, axis=1) > gap


@pytest.mark.parametrize("shape", [Box((1.0, 0.5, 0.3)), Cylinder(0.7, 1.5, axis=1), Sphere(0.9)],
                         ids=["box", "cylinder", "sphere"])
def test_normal_and_its_derivative_match_finite_differences(shape) -> None:
    x = RNG.uniform(-2, 2, (3000, 3))
    x = x[away_from_medial(shape, x)]
    q = shape.query(x)
    np.testing.assert_allclose(q.normal, finite_difference(lambda p: shape.query(p).distance, x), atol=1e-8)
    fd = finite_difference(lambda p: shape.query(p).normal, x)
    np.testing.assert_allclose(q.normal_gradient, fd, atol=1e-6)
    np.testing.assert_allclose(q.normal_gradient, q.normal_gradient.transpose(0, 2, 1), atol=1e-12)


def test_query_world_rotates_every_output() -> None:
    box = Box((1.0, 0.5, 0.3))
    angle = 0.7
    rotation = np.array([[np.cos(angle), -np.sin(angle), 0], [np.sin(angle), np.cos(angle), 0], [0, 0, 1]])
    position = np.array([1.0, -2.0, 0.5])
    x = position + RNG.uniform(-2, 2, (500, 3))
    local = (x - position) @ rotation
    x, local = x[away_from_medial(box, local)], local[away_from_medial(box, local)]
    q = query_world(box, x, position, rotation)
    np.testing.assert_allclose(q.distance, box.query(local).distance, atol=1e-14)
    np.testing.assert_allclose(q.normal, finite_difference(
        lambda p: query_world(box, p, position, rotation).distance, x), atol=1e-8)
    np.testing.assert_allclose(q.normal_gradient, finite_difference(
        lambda p: query_world(box, p, position, rotation).normal, x), atol=1e-6)
    np.testing.assert_allclose(q.closest, x - q.distance[:, None] * q.normal, atol=1e-14)


# ---------- meshes ----------

@pytest.fixture(scope="module")
def torus() -> TriangleMesh:
    m = trimesh.creation.torus(major_radius=1.0, minor_radius=0.35, major_sections=48, minor_sections=16)
    return TriangleMesh(m.vertices, m.faces, "torus")


def test_mesh_signed_distance_matches_brute_force_on_a_nonconvex_mesh(torus: TriangleMesh) -> None:
    x = np.concatenate([RNG.uniform(-1.6, 1.6, (400, 3)),
                        trimesh.Trimesh(torus.vertices, torus.faces).sample(200, seed=1)
                        + RNG.normal(scale=0.01, size=(200, 3))])
    tri = torus.vertices[torus.faces]
    q = torus.query(x)
    np.testing.assert_allclose(np.abs(q.distance), brute_force_triangles(x, tri), atol=1e-13)
    inside = winding_number(x, tri) > 0.5
    np.testing.assert_array_equal(q.distance < 0, inside)
    np.testing.assert_allclose(np.linalg.norm(x - q.closest, axis=1), np.abs(q.distance), atol=1e-13)


def test_mesh_normal_and_derivative_match_finite_differences(torus: TriangleMesh) -> None:
    x = RNG.uniform(-1.6, 1.6, (1500, 3))
    q = torus.query(x)
    np.testing.assert_allclose(q.normal, finite_difference(lambda p: torus.query(p).distance, x), atol=1e-7)
    fd = finite_difference(lambda p: torus.query(p).normal, x)
    # points within a step of a region border (face/edge/vertex) see a kink of n: a few may miss
    err = np.abs(fd - q.normal_gradient).max(axis=(1, 2))
    assert np.mean(err < 1e-5) > 0.99
    assert np.any(np.abs(q.normal_gradient).max(axis=(1, 2)) > 0.1), "edge/vertex regions were visited"


def test_mesh_and_primitive_cylinder_agree_within_faceting_error() -> None:
    radius, length, sections = 0.7, 1.5, 96
    mesh = TriangleMesh(*(lambda m: (m.vertices, m.faces))(
        trimesh.creation.cylinder(radius=radius, height=length, sections=sections)))
    x = RNG.uniform(-1.2, 1.2, (3000, 3))
    faceting = radius * (1 - np.cos(np.pi / sections))
    diff = mesh.query(x).distance - Cylinder(radius, length).query(x).distance
    assert np.abs(diff).max() <= faceting * (1 + 1e-9)
    assert np.abs(diff).max() > 0.5 * faceting  # the bound is tight, the test sees faceting


def test_mesh_inward_orientation_is_flipped_and_max_distance_stops_far_points() -> None:
    m = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    mesh = TriangleMesh(m.vertices, m.faces[:, ::-1])
    q = mesh.query(np.array([[0, 0, 2.0], [0, 0, 0.0], [0, 0, 1.05]]), max_distance=0.5)
    assert q.distance[0] == np.inf and not q.normal[0].any()
    assert q.distance[2] == pytest.approx(0.05, abs=0.01)
    assert mesh.query(np.zeros((1, 3))).distance[0] < -0.9


@pytest.mark.parametrize("suffix", ["stl", "obj", "ply", "glb"])
def test_load_mesh_formats_and_mass_properties(tmp_path, suffix: str) -> None:
    half = np.array([1.0, 0.5, 0.25])
    shifted = trimesh.creation.box(extents=2 * half)
    shifted.apply_translation([3.0, 0.0, 1.0])
    path = tmp_path / f"box.{suffix}"
    shifted.export(path)
    mesh, offset = load_mesh(path)
    np.testing.assert_allclose(offset, [3.0, 0.0, 1.0], atol=1e-12)
    props, exact = mesh.mass_properties(12.0), Box(tuple(half)).mass_properties(12.0)
    assert props.volume == pytest.approx(exact.volume, rel=1e-12)
    np.testing.assert_allclose(props.center_of_mass, 0.0, atol=1e-12)
    np.testing.assert_allclose(props.inertia, exact.inertia, atol=1e-12)
    np.testing.assert_allclose(mesh.query(np.array([[0, 0, 1.0]])).distance, [0.75])


def test_primitive_mass_properties_match_fine_meshes() -> None:
    for shape, mesh in [(Cylinder(0.5, 2.0), trimesh.creation.cylinder(radius=0.5, height=2.0, sections=512)),
                        (Sphere(0.8), trimesh.creation.icosphere(subdivisions=5, radius=0.8))]:
        exact = shape.mass_properties(3.0)
        approx = TriangleMesh(mesh.vertices, mesh.faces).mass_properties(3.0)
        np.testing.assert_allclose(approx.inertia, exact.inertia, rtol=2e-3, atol=1e-12)
        assert approx.volume == pytest.approx(exact.volume, rel=2e-3)
    sphere = Sphere(0.8).mass_properties(3.0)
    assert sphere.inertia[0, 0] == pytest.approx(0.4 * 3.0 * 0.64)


def test_bad_meshes_and_files_are_refused_with_the_file_named(tmp_path) -> None:
    with pytest.raises(SceneError, match="no such file") as err:
        load_mesh(tmp_path / "missing.stl")
    assert err.value.key == "file"
    garbage = tmp_path / "garbage.stl"
    garbage.write_bytes(b"\x00\x01 not a mesh")
    with pytest.raises(SceneError, match="garbage.stl"):
        load_mesh(garbage)
    open_box = trimesh.creation.box()
    open_box = trimesh.Trimesh(open_box.vertices, open_box.faces[:-1], process=False)
    path = tmp_path / "open.stl"
    open_box.export(path)
    with pytest.raises(SceneError, match="watertight") as err:
        load_mesh(path)
    assert "open.stl" in str(err.value)


def test_bad_dimensions_and_masses_are_refused() -> None:
    for make in (lambda: Box((1.0, 0.0, 1.0)), lambda: Cylinder(-1.0, 1.0), lambda: Sphere(float("nan")),
                 lambda: Cylinder(1.0, 1.0, axis=3)):
        with pytest.raises(SceneError):
            make()
    for mass in (0.0, -1.0, float("inf")):
        with pytest.raises(SceneError, match="mass"):
            Box((1.0, 1.0, 1.0)).mass_properties(mass)
    with pytest.raises(SceneError, match="size"):
        shape_from_scene("cylinder", (1.0, 2.0, 3.0))
    with pytest.raises(SceneError, match="shape"):
        shape_from_scene("cone", (1.0, 1.0, 1.0))
    with pytest.raises(SceneError, match="size"):
        shape_from_scene("box", (1.0, -1.0, 1.0))
    assert shape_from_scene("cylinder", (2.4, 2.4, 6.0)) == Cylinder(1.2, 6.0, axis=2)
    assert shape_from_scene("box", (2.0, 4.0, 6.0)) == Box((1.0, 2.0, 3.0))
