"""The surfaces of rigid bodies as triangles, for the VTK series and the pictures of a run."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from rodnet.contact.geometry import Box, Cylinder, Shape, Sphere

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

CYLINDER_SIDES = 64
SPHERE_RINGS = 24


def _box_surface(h: tuple[float, float, float]) -> tuple[FloatArray, IntArray]:
    corners = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    faces = [(a, b, c) for a, b, c, d in quads] + [(a, c, d) for a, b, c, d in quads]
    return corners * np.asarray(h), np.array(faces, dtype=np.int64)


def _cylinder_surface(c: Cylinder) -> tuple[FloatArray, IntArray]:
    n = CYLINDER_SIDES
    angle = 2.0 * np.pi * np.arange(n) / n
    ring = np.stack([c.radius * np.cos(angle), c.radius * np.sin(angle)], axis=1)
    z = 0.5 * c.length
    local = np.vstack([np.column_stack([ring, np.full(n, -z)]), np.column_stack([ring, np.full(n, z)]),
                       [[0.0, 0.0, -z], [0.0, 0.0, z]]])
    i, j = np.arange(n), (np.arange(n) + 1) % n
    faces = np.vstack([np.column_stack([i, j, n + j]), np.column_stack([i, n + j, n + i]),
                       np.column_stack([np.full(n, 2 * n), j, i]),
                       np.column_stack([np.full(n, 2 * n + 1), n + i, n + j])])
    # the cylinder's axis is body axis ``c.axis``: rotate z onto it
    order = {0: [2, 0, 1], 1: [1, 2, 0], 2: [0, 1, 2]}[c.axis]
    return local[:, order], faces.astype(np.int64)


def _sphere_surface(s: Sphere) -> tuple[FloatArray, IntArray]:
    rings, sides = SPHERE_RINGS, 2 * SPHERE_RINGS
    polar = np.pi * np.arange(1, rings) / rings
    azimuth = 2.0 * np.pi * np.arange(sides) / sides
    p, a = np.meshgrid(polar, azimuth, indexing="ij")
    body = np.stack([np.sin(p) * np.cos(a), np.sin(p) * np.sin(a), np.cos(p)], axis=-1).reshape(-1, 3)
    local = s.radius * np.vstack([[[0.0, 0.0, 1.0]], body, [[0.0, 0.0, -1.0]]])
    top, bottom = 0, len(local) - 1

    def vid(r: IntArray, k: IntArray) -> IntArray:
        return 1 + r * sides + k % sides

    k = np.arange(sides)
    faces = [np.column_stack([np.full(sides, top), vid(np.zeros_like(k), k), vid(np.zeros_like(k), k + 1)]),
             np.column_stack([np.full(sides, bottom), vid(np.full_like(k, rings - 2), k + 1),
                              vid(np.full_like(k, rings - 2), k)])]
    for r in range(rings - 2):
        rr = np.full_like(k, r)
        faces.append(np.column_stack([vid(rr, k), vid(rr + 1, k), vid(rr + 1, k + 1)]))
        faces.append(np.column_stack([vid(rr, k), vid(rr + 1, k + 1), vid(rr, k + 1)]))
    return local, np.vstack(faces).astype(np.int64)


def surface_triangles(shape: Shape) -> tuple[FloatArray, IntArray]:
    """Triangulated surface of ``shape`` in its body frame: vertices (V, 3) [m], faces (F, 3)."""
    if isinstance(shape, Box):
        return _box_surface(shape.half_extents)
    if isinstance(shape, Cylinder):
        return _cylinder_surface(shape)
    if isinstance(shape, Sphere):
        return _sphere_surface(shape)
    return np.asarray(shape.vertices), np.asarray(shape.faces)  # type: ignore[attr-defined]
