"""Compiled closest-triangle queries on a bounding-volume hierarchy of a triangle mesh.

The query half of :mod:`rodnet.contact.mesh_distance` (which builds the hierarchy and the
pseudonormals): the nearest triangle of a point, the barycentric coordinates of the closest
point on it and the squared distance, ``elements/contact/FORMULATION.md`` (G9). A query visits
the nearer child first and skips any box farther than the best distance found so far. The
closest point on one triangle is Ericson's region test (Real-Time Collision Detection, 2005,
section 5.1.5): exact barycentric zeros on edges and vertices.
"""

from __future__ import annotations

import numba
import numpy as np

STACK_DEPTH = 128
"""Length of the scratch stack a :func:`nearest_triangle` query needs."""


@numba.njit(cache=True)
def _dot3(u0, u1, u2, v0, v1, v2):  # pragma: no cover - compiled
    return u0 * v0 + u1 * v1 + u2 * v2


@numba.njit(cache=True)
def _triangle_barycentric(p, a, b, c, out):  # pragma: no cover - compiled
    """Ericson's closest point on triangle abc to p, as barycentric coordinates in ``out``."""
    ab0, ab1, ab2 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    ac0, ac1, ac2 = c[0] - a[0], c[1] - a[1], c[2] - a[2]
    d1 = _dot3(ab0, ab1, ab2, p[0] - a[0], p[1] - a[1], p[2] - a[2])
    d2 = _dot3(ac0, ac1, ac2, p[0] - a[0], p[1] - a[1], p[2] - a[2])
    if d1 <= 0.0 and d2 <= 0.0:
        out[0], out[1], out[2] = 1.0, 0.0, 0.0
        return
    d3 = _dot3(ab0, ab1, ab2, p[0] - b[0], p[1] - b[1], p[2] - b[2])
    d4 = _dot3(ac0, ac1, ac2, p[0] - b[0], p[1] - b[1], p[2] - b[2])
    if d3 >= 0.0 and d4 <= d3:
        out[0], out[1], out[2] = 0.0, 1.0, 0.0
        return
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        v = d1 / (d1 - d3)
        out[0], out[1], out[2] = 1.0 - v, v, 0.0
        return
    d5 = _dot3(ab0, ab1, ab2, p[0] - c[0], p[1] - c[1], p[2] - c[2])
    d6 = _dot3(ac0, ac1, ac2, p[0] - c[0], p[1] - c[1], p[2] - c[2])
    if d6 >= 0.0 and d5 <= d6:
        out[0], out[1], out[2] = 0.0, 0.0, 1.0
        return
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        w = d2 / (d2 - d6)
        out[0], out[1], out[2] = 1.0 - w, 0.0, w
        return
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and d4 - d3 >= 0.0 and d5 - d6 >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        out[0], out[1], out[2] = 0.0, 1.0 - w, w
        return
    den = 1.0 / (va + vb + vc)
    v, w = vb * den, vc * den
    out[0], out[1], out[2] = 1.0 - v - w, v, w


@numba.njit(cache=True)
def _box_distance2(p, lower, upper, node):  # pragma: no cover - compiled
    d = 0.0
    for k in range(3):
        if p[k] < lower[node, k]:
            d += (lower[node, k] - p[k]) ** 2
        elif p[k] > upper[node, k]:
            d += (p[k] - upper[node, k]) ** 2
    return d


@numba.njit(cache=True, inline="always")
def nearest_triangle(p, root, best, tri, lower, upper, left, right, start, count, order, stack,
                     w):  # pragma: no cover - compiled
    """Nearest triangle to one point among those below a node of the hierarchy.

    Visits the nearer child first and skips every box at least as far as the best squared
    distance found so far.

    Parameters
    ----------
    p : (3,) float
        Query point in the mesh frame [m].
    root : int
        Node whose triangles are searched (0: the whole mesh).
    best : float
        Squared distance [m^2] a triangle must beat to be taken (``inf``: no cut-off).
    tri, lower, upper, left, right, start, count, order : arrays
        The triangles and the arrays of a :class:`Hierarchy`.
    stack : (STACK_DEPTH,) int
        Scratch space.
    w : (3,) float
        Scratch space.

    Returns
    -------
    squared_distance : float
        To the nearest triangle [m^2], or ``best`` when none is nearer.
    face : int
        Index of the nearest triangle, or -1.
    b0, b1, b2 : float
        Barycentric coordinates of the closest point in that triangle (zeros for face -1).
    """
    face = -1
    b0 = b1 = b2 = 0.0
    stack[0] = root
    depth = 1
    while depth > 0:
        depth -= 1
        node = stack[depth]
        if _box_distance2(p, lower, upper, node) >= best:
            continue
        if count[node] > 0:
            for j in range(start[node], start[node] + count[node]):
                f = order[j]
                _triangle_barycentric(p, tri[f, 0], tri[f, 1], tri[f, 2], w)
                d = 0.0
                for k in range(3):
                    d += (p[k] - w[0] * tri[f, 0, k] - w[1] * tri[f, 1, k] - w[2] * tri[f, 2, k]) ** 2
                if d < best:
                    best, face = d, f
                    b0, b1, b2 = w[0], w[1], w[2]
            continue
        near, far = left[node], right[node]
        if _box_distance2(p, lower, upper, far) < _box_distance2(p, lower, upper, near):
            near, far = far, near
        stack[depth], stack[depth + 1] = far, near
        depth += 2
    return best, face, b0, b1, b2


@numba.njit(cache=True)
def closest(points, tri, lower, upper, left, right, start, count, order,
             max_distance):  # pragma: no cover - compiled
    n = points.shape[0]
    dist2 = np.empty(n)
    face = np.empty(n, np.int64)
    bary = np.empty((n, 3))
    stack = np.empty(STACK_DEPTH, np.int64)
    w = np.empty(3)
    cut = max_distance * max_distance
    for i in range(n):
        dist2[i], face[i], bary[i, 0], bary[i, 1], bary[i, 2] = nearest_triangle(
            points[i], 0, cut, tri, lower, upper, left, right, start, count, order, stack, w)
    return dist2, face, bary
