"""Flat arrays of a :class:`~rodnet.contact.bodies.BodyContact` for the compiled contact kernels.

The compiled kernels (:mod:`rodnet.kernels.contact_compiled`) take plain arrays: one row per body
for the primitives and every mesh's bounding-volume hierarchy and pseudonormals concatenated, with
each mesh body pointing at the root of its own tree. Built once per model; the bodies' poses and
velocities are not among them (they change during a run: the state's bodies).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from rodnet.contact.bodies import BodyContact
from rodnet.contact.geometry import Box, Cylinder, Sphere
from rodnet.kernels.contact_compiled import ContactData


def _primitive_row(shape: object) -> tuple[int, list[float]]:
    """Shape code and the three numbers the kernel needs: box half extents; cylinder radius,
    length and axis; sphere radius; mesh the distance below which a point is on its surface."""
    if isinstance(shape, Box):
        return 0, list(shape.half_extents)
    if isinstance(shape, Cylinder):
        return 1, [shape.radius, shape.length, float(shape.axis)]
    if isinstance(shape, Sphere):
        return 2, [shape.radius, 0.0, 0.0]
    return 3, [shape.on_surface, 0.0, 0.0]  # type: ignore[attr-defined]


def _mesh_arrays(meshes: list) -> tuple[list[int], tuple[np.ndarray, ...]]:
    """Roots and the concatenated hierarchies and pseudonormals of ``meshes``."""
    parts: dict[str, list[np.ndarray]] = {k: [] for k in (
        "tri", "lower", "upper", "left", "right", "start", "count", "order",
        "face_normal", "edge_normal", "corner_normal")}
    roots, n_nodes, n_tri = [], 0, 0
    for mesh in meshes:
        h = mesh.hierarchy
        face_normal, edge_normal, vertex_normal = mesh.normals
        roots.append(n_nodes)
        parts["tri"].append(h.triangles)
        parts["lower"].append(h.lower)
        parts["upper"].append(h.upper)
        parts["left"].append(np.where(h.left >= 0, h.left + n_nodes, -1))
        parts["right"].append(np.where(h.right >= 0, h.right + n_nodes, -1))
        parts["start"].append(h.start + n_tri)   # order has one entry per triangle
        parts["count"].append(h.count)
        parts["order"].append(h.order + n_tri)
        parts["face_normal"].append(face_normal)
        parts["edge_normal"].append(edge_normal)
        parts["corner_normal"].append(vertex_normal[mesh.faces])
        n_nodes += len(h.lower)
        n_tri += len(h.triangles)
    empty = {"tri": (0, 3, 3), "lower": (0, 3), "upper": (0, 3), "face_normal": (0, 3),
             "edge_normal": (0, 3, 3), "corner_normal": (0, 3, 3)}
    arrays = []
    for key, chunks in parts.items():
        if chunks:
            out = np.concatenate(chunks)
        else:
            out = np.zeros(empty.get(key, (0,)))
        dtype = np.float64 if key in empty else np.int64
        arrays.append(np.ascontiguousarray(out, dtype=dtype))
    return roots, tuple(arrays)


def kernel_data(contact: BodyContact, inv_mass: NDArray[np.float64]) -> ContactData:
    """The :class:`~rodnet.kernels.contact_compiled.ContactData` of ``contact`` for nodes of
    inverse masses ``inv_mass`` (N,) [1/kg] (for the friction cap, (E2))."""
    codes, sizes = zip(*(_primitive_row(s) for s in contact.shapes))
    meshes = [s for s, code in zip(contact.shapes, codes) if code == 3]
    roots, mesh = _mesh_arrays(meshes)
    mesh_root = np.full(contact.n_bodies, -1, np.int64)
    mesh_root[[i for i, code in enumerate(codes) if code == 3]] = roots
    bounds = np.array([s.bounds for s in contact.shapes], dtype=np.float64)
    bound_radius = np.linalg.norm(np.abs(bounds).max(axis=1), axis=1)
    law = contact.law
    f = np.ascontiguousarray
    return ContactData(
        f(inv_mass, dtype=np.float64), f(contact.segments, dtype=np.int64),
        f(contact.radius, dtype=np.float64),
        np.array(codes, np.int64), np.array(sizes, np.float64), bounds, bound_radius,
        f(contact.travel_limit, dtype=np.float64), f(contact.compliance(), dtype=np.float64),
        mesh_root, *mesh, float(law.stiffness), float(law.damping), float(law.friction),
        float(law.smoothing), float(law.slip_velocity), int(contact.points_per_segment))
