"""Closest points on a closed triangle mesh: a bounding-volume hierarchy (its compiled queries
are :mod:`rodnet.kernels.mesh_distance`).

The unsigned part of the mesh signed distance (``elements/contact/FORMULATION.md`` (G9)): for each
query point, the nearest triangle, the barycentric coordinates of the closest point on it and the
squared distance. The sign and the normal come from the angle-weighted pseudonormals of
:func:`pseudonormals`, (G10). The hierarchy is a binary tree of axis-aligned boxes, split at the
median centroid along the longest extent, with at most ``LEAF_SIZE`` triangles per leaf; a query
visits the nearer child first and skips any box farther than the best distance found so far, so
its cost grows with the logarithm of the number of triangles. Points farther than an optional
``max_distance`` stop early, which is where most of the time goes for points away from the body.

The closest point on one triangle is Ericson's region test (Real-Time Collision Detection, 2005,
section 5.1.5). In a vertex region it returns exact barycentric coordinates 1, 0, 0 and on an edge
an exact 0 for the opposite vertex, so the closest feature (face, edge, vertex) is read off the
zeros without a tolerance.

Measured against libigl's ``signed_distance`` and trimesh's proximity queries in
``validation/benchmarks/contact_mesh_distance.py``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from rodnet.kernels.mesh_distance import closest

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

LEAF_SIZE = 4


class Hierarchy:
    """Bounding boxes of a triangle mesh, built once per mesh in its body frame.

    Parameters
    ----------
    triangles : (F, 3, 3) float
        Corner coordinates of every triangle [m].
    """

    def __init__(self, triangles: FloatArray) -> None:
        self.triangles = np.ascontiguousarray(triangles, dtype=np.float64)
        if self.triangles.shape[0] == 0:
            raise ValueError("a mesh hierarchy needs at least one triangle")
        (self.lower, self.upper, self.left, self.right, self.start, self.count,
         self.order, n_nodes) = _build(self.triangles, LEAF_SIZE)
        for name in ("lower", "upper", "left", "right", "start", "count"):
            setattr(self, name, np.ascontiguousarray(getattr(self, name)[:n_nodes]))

    def closest(self, points: FloatArray, max_distance: float = np.inf,
                ) -> tuple[FloatArray, IntArray, FloatArray]:
        """Nearest triangle of every point.

        Parameters
        ----------
        points : (P, 3) float
            Query points in the mesh frame [m].
        max_distance : float
            Points farther than this from the mesh get face ``-1`` and squared distance
            ``max_distance**2`` (``inf`` by default: every point gets its nearest triangle).

        Returns
        -------
        squared_distance : (P,) float [m^2]
        face : (P,) int
            Index of the nearest triangle, or -1.
        barycentric : (P, 3) float
            Coordinates of the closest point in that triangle (zeros for face -1).
        """
        points = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
        return closest(points, self.triangles, self.lower, self.upper, self.left, self.right,
                        self.start, self.count, self.order, float(max_distance))


def pseudonormals(vertices: FloatArray, faces: IntArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Face normals, edge and angle-weighted vertex pseudonormals of a closed mesh, (G10).

    Parameters
    ----------
    vertices : (V, 3) float
    faces : (F, 3) int
        Counter-clockwise seen from outside.

    Returns
    -------
    face_normal : (F, 3) float
        Outward unit normals.
    edge_normal : (F, 3, 3) float
        ``edge_normal[f, i]``: unit sum of the normals of the two faces sharing the edge from
        local vertex ``i`` to ``i + 1``.
    vertex_normal : (V, 3) float
        Unit sum of the incident face normals weighted by the face angle at the vertex
        (Baerentzen and Aanaes 2005).
    """
    tri = vertices[faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    face_normal = cross / np.linalg.norm(cross, axis=1, keepdims=True)
    vertex_normal = np.zeros_like(vertices)
    for i in range(3):
        e1 = tri[:, (i + 1) % 3] - tri[:, i]
        e2 = tri[:, (i + 2) % 3] - tri[:, i]
        cos = np.einsum("fi,fi->f", e1, e2) / (np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1))
        np.add.at(vertex_normal, faces[:, i], np.arccos(np.clip(cos, -1.0, 1.0))[:, None] * face_normal)
    vertex_normal /= np.linalg.norm(vertex_normal, axis=1, keepdims=True)
    edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    _, edge_id = np.unique(edges[:, 0] * len(vertices) + edges[:, 1], return_inverse=True)
    edge_sum = np.zeros((edge_id.max() + 1, 3))
    np.add.at(edge_sum, edge_id, np.repeat(face_normal, 3, axis=0))
    edge_sum /= np.linalg.norm(edge_sum, axis=1, keepdims=True)
    return face_normal, edge_sum[edge_id].reshape(-1, 3, 3), vertex_normal


def _build(tri: FloatArray, leaf_size: int) -> tuple[FloatArray, ...]:
    """Median-split hierarchy built one level at a time, all nodes of a level at once.

    Every node owns a contiguous range of ``order``; a level sorts each range along its longest
    centroid extent (one lexsort for the whole level) and halves it.
    """
    n = tri.shape[0]
    centroid = tri.mean(axis=1)
    tri_lower, tri_upper = tri.min(axis=1), tri.max(axis=1)
    order = np.arange(n)
    begin, end = np.array([0]), np.array([n])
    ids = np.array([0])
    lower, upper = np.empty((2 * n, 3)), np.empty((2 * n, 3))
    left, right = np.full(2 * n, -1), np.full(2 * n, -1)
    start, count = np.zeros(2 * n, np.int64), np.zeros(2 * n, np.int64)
    n_nodes = 1
    while ids.size:
        lower[ids] = np.minimum.reduceat(tri_lower[order], begin)[: ids.size]
        upper[ids] = np.maximum.reduceat(tri_upper[order], begin)[: ids.size]
        leaf = end - begin <= leaf_size
        start[ids[leaf]], count[ids[leaf]] = begin[leaf], (end - begin)[leaf]
        ids, begin, end = ids[~leaf], begin[~leaf], end[~leaf]
        if not ids.size:
            break
        size = end - begin
        offset = np.r_[0, np.cumsum(size)[:-1]]
        owner = np.repeat(np.arange(ids.size), size)
        positions = np.arange(size.sum()) + np.repeat(begin - offset, size)
        c = centroid[order[positions]]
        extent = np.maximum.reduceat(c, offset) - np.minimum.reduceat(c, offset)
        axis = np.argmax(extent, axis=1)[owner]
        order[positions] = order[positions][np.lexsort((c[np.arange(c.shape[0]), axis], owner))]
        mid = begin + size // 2
        left[ids] = n_nodes + 2 * np.arange(ids.size)
        right[ids] = left[ids] + 1
        n_nodes += 2 * ids.size
        ids = np.stack([left[ids], right[ids]], axis=1).ravel()
        begin, end = np.stack([begin, mid], axis=1).ravel(), np.stack([mid, end], axis=1).ravel()
    return lower, upper, left, right, start, count, order, n_nodes
