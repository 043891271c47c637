"""Closed triangle meshes as rigid body shapes: signed distance, normal derivative, mass.

Same interface as the primitives of :mod:`rodnet.contact.geometry`; equations (G9), (G10) and
(G12) of ``elements/contact/FORMULATION.md``. The closest points come from the compiled hierarchy
of :mod:`rodnet.contact.mesh_distance`; trimesh is imported only to read files and for mass
properties.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rodnet.contact.geometry import MassProperties, SurfaceQuery, as_points, check_mass
from rodnet.contact.mesh_distance import FloatArray, Hierarchy, IntArray, pseudonormals
from rodnet.errors import SceneError

_EYE = np.eye(3)


def _outer(a: FloatArray, b: FloatArray) -> FloatArray:
    return a[:, :, None] * b[:, None, :]


@dataclass(frozen=True, eq=False)
class TriangleMesh:
    """Closed, consistently oriented triangle mesh, (G9)-(G10).

    The sign comes from the angle-weighted pseudonormal of the closest feature, exact for a
    closed mesh; the normal is ``(x - c)/|x - c|`` with that sign, continuous across edges and
    vertices outside. Inside, the normal jumps on the medial surfaces as for the box. The mesh
    is checked on construction: every edge shared by exactly two triangles with opposite
    directions (watertight and consistently oriented); inward-facing triangles are flipped.

    Parameters
    ----------
    vertices : (V, 3) float
        [m], in the body frame.
    faces : (F, 3) int
    name : str
        Where the mesh came from (its file), for messages.
    """

    vertices: FloatArray
    faces: IntArray
    name: str = "<mesh>"
    hierarchy: Hierarchy = field(init=False, repr=False)
    """Bounding boxes of the triangles (:mod:`rodnet.contact.mesh_distance`)."""
    normals: tuple[FloatArray, FloatArray, FloatArray] = field(init=False, repr=False)
    """Face normals, edge and vertex pseudonormals, (G10)."""
    on_surface: float = field(init=False, repr=False)
    """Closer than this [m] a point is on the surface and takes the pseudonormal as normal."""

    def __post_init__(self) -> None:
        vertices = np.array(self.vertices, dtype=np.float64).reshape(-1, 3)
        faces = np.array(self.faces, dtype=np.int64).reshape(-1, 3)
        if faces.size == 0 or not np.isfinite(vertices).all() or faces.min() < 0 \
                or faces.max() >= len(vertices):
            raise SceneError("file", self.name, "must hold a triangle mesh with finite vertices")
        _check_closed(faces, len(vertices), self.name)
        tri = vertices[faces]
        area2 = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
        size = float(np.ptp(vertices, axis=0).max())
        if (area2 <= 1e-14 * size**2).any():
            raise SceneError("file", self.name, f"has {int((area2 <= 1e-14 * size**2).sum())} "
                             "degenerate (zero-area) triangles")
        if np.einsum("fi,fi->", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])) < 0.0:
            faces = faces[:, ::-1].copy()
        vertices.flags.writeable = faces.flags.writeable = False
        object.__setattr__(self, "vertices", vertices)
        object.__setattr__(self, "faces", faces)
        object.__setattr__(self, "hierarchy", Hierarchy(vertices[faces]))
        object.__setattr__(self, "normals", pseudonormals(vertices, faces))
        # closer than this a point is on the surface and takes the pseudonormal as its normal
        object.__setattr__(self, "on_surface", 1e-12 * size)

    @property
    def bounds(self) -> FloatArray:
        return np.stack([self.vertices.min(axis=0), self.vertices.max(axis=0)])

    def thinnest_extent(self) -> float:
        """The smallest edge of the mesh's oriented bounding box [m] (trimesh's minimum-volume
        box): a plate's thickness however the file turns it."""
        import trimesh

        mesh = trimesh.Trimesh(self.vertices, self.faces, process=False)
        return float(np.min(mesh.bounding_box_oriented.primitive.extents))

    def query(self, points: FloatArray, max_distance: float = np.inf) -> SurfaceQuery:
        """(G9)-(G10) for ``points`` (P, 3) in the body frame.

        Points farther than ``max_distance`` [m] from the surface are not resolved: they get
        distance ``+inf``, normal and ``dn/dx`` zero and themselves as closest point, whether
        inside or outside. Use it only where deeper penetration cannot occur.
        """
        x = as_points(points)
        d2, face, bary = self.hierarchy.closest(x, max_distance)
        distance, normal = np.full(x.shape[0], np.inf), np.zeros_like(x)
        closest, gradient = x.copy(), np.zeros((x.shape[0], 3, 3))
        hit = face >= 0
        if hit.any():
            distance[hit], normal[hit], closest[hit], gradient[hit] = self._resolve(
                x[hit], np.sqrt(d2[hit]), face[hit], bary[hit])
        return SurfaceQuery(distance, normal, closest, gradient)

    def _resolve(self, x: FloatArray, unsigned: FloatArray, face: IntArray, bary: FloatArray,
                 ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        face_normal, edge_normal, vertex_normal = self.normals
        corners = self.vertices[self.faces[face]]
        closest = np.einsum("pk,pki->pi", bary, corners)
        zero = bary == 0.0
        on_edge, on_vertex = zero.sum(axis=1) == 1, zero.sum(axis=1) == 2
        pseudo = face_normal[face].copy()
        rows = np.arange(x.shape[0])
        # the edge opposite the zero coordinate i runs from local vertex i+1 to i+2
        edge = (np.argmax(zero, axis=1) + 1) % 3
        pseudo[on_edge] = edge_normal[face, edge][on_edge]
        corner = np.argmax(~zero, axis=1)
        pseudo[on_vertex] = vertex_normal[self.faces[face, corner]][on_vertex]
        diff = x - closest
        sign = np.where(np.einsum("pi,pi->p", diff, pseudo) < 0.0, -1.0, 1.0)
        distance = sign * unsigned
        resolved = unsigned > self.on_surface
        safe = np.where(resolved, unsigned, 1.0)
        normal = np.where(resolved[:, None], sign[:, None] * diff / safe[:, None], pseudo)
        # (G3): dn/dx = (I - n n - T) / d, T the tangent projector of the closest feature
        tangent = np.zeros((x.shape[0], 3, 3))
        e = corners[rows, (edge + 1) % 3] - corners[rows, edge]
        e /= np.linalg.norm(e, axis=1, keepdims=True)
        tangent[on_edge] = _outer(e, e)[on_edge]
        safe_distance = np.where(resolved, distance, 1.0)
        gradient = (_EYE - _outer(normal, normal) - tangent) / safe_distance[:, None, None]
        gradient[~(on_edge | on_vertex) | ~resolved] = 0.0
        return distance, normal, closest, gradient

    def mass_properties(self, mass: float) -> MassProperties:
        """(G12): trimesh's polyhedral integrals with density ``mass / volume``."""
        import trimesh

        m = check_mass(mass)
        mesh = trimesh.Trimesh(self.vertices, self.faces, process=False)
        mesh.density = m / mesh.volume
        return MassProperties(m, float(mesh.volume), np.array(mesh.center_mass),
                              np.array(mesh.moment_inertia))


def _check_closed(faces: IntArray, n_vertices: int, name: str) -> None:
    """Every directed edge once, and its reverse present: closed and consistently oriented."""
    directed = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    key = directed[:, 0] * n_vertices + directed[:, 1]
    if np.unique(key).size != key.size:
        raise SceneError("file", name, "must be a consistently oriented, edge-manifold mesh "
                         "(an edge is used twice in the same direction)")
    open_edges = int((~np.isin(directed[:, 1] * n_vertices + directed[:, 0], key)).sum())
    if open_edges:
        raise SceneError("file", name, f"must be a watertight mesh: it has {open_edges} open "
                         "edges; inside/outside and mass properties need a closed surface")


MESH_FORMATS = ".stl, .obj, .ply, .off, .glb, .gltf and other formats of trimesh and meshio"
"""The mesh files a body may name, as error messages list them."""


def load_mesh(path: str | Path, centre: bool = True) -> tuple[TriangleMesh, FloatArray]:
    """Read a triangle mesh with trimesh (STL, OBJ, PLY, GLB/GLTF, OFF ...).

    Parameters
    ----------
    path : str or Path
    centre : bool
        Translate the mesh so that its centre of volume (the centre of mass of a homogeneous
        body) is the origin of the body frame.

    Returns
    -------
    mesh : TriangleMesh
    offset : (3,) float
        Where the body-frame origin lies in the file's coordinates [m] (zero if not centred).
    """
    import trimesh

    path = Path(path)
    if path.is_dir():
        raise SceneError("file", str(path), "is a directory, not a mesh file")
    if not path.is_file():
        raise SceneError("file", str(path), f"no such file (looked for {path.resolve()})")
    suffix = "".join(path.suffixes[-2:]).lower().lstrip(".")
    if not ({suffix, path.suffix.lower().lstrip(".")} & trimesh.available_formats()):
        told = (f"has the extension {path.suffix!r}, which is no mesh format trimesh reads"
                if path.suffix else "has no extension to tell its format by")
        raise SceneError("file", str(path), f"{told} (allowed: {MESH_FORMATS})")
    try:
        loaded = trimesh.load(path, force="mesh", process=True)
    except Exception as exc:  # trimesh raises many kinds for unreadable files
        raise SceneError("file", str(path), f"could not be read as a triangle mesh "
                         f"({type(exc).__name__}: {exc})") from exc
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise SceneError("file", str(path), "holds no triangles")
    loaded.update_faces(loaded.nondegenerate_faces())
    loaded.remove_unreferenced_vertices()
    mesh = TriangleMesh(np.array(loaded.vertices), np.array(loaded.faces), str(path))
    offset = np.zeros(3)
    if centre:
        offset = mesh.mass_properties(1.0).center_of_mass
        mesh = TriangleMesh(mesh.vertices - offset, mesh.faces, str(path))
    return mesh, offset
