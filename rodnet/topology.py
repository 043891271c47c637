"""Discrete geometry shared by every model: nodes, segments, threads and node selectors.

The square net follows Eq. (1) of the seed paper in 0-based form: knot ``i`` is joined to ``i+1``
when both are on the same row and to ``i+Ns``; threads are numbered in order of their first knot,
the row thread before the column thread, and the four corner threads come last. Nodes are
numbered knots first (``0 .. Ns^2-1``), then the four corner masses, then the interior nodes of
each thread in thread order, then the nodes of each ``[[rods]]`` entry.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from rodnet.config import NetSpec, RodSpec, Scene
from rodnet.errors import SceneError


def square_net_threads(nodes_per_side: int) -> NDArray[np.int64]:
    """Knot pairs of the mesh threads of a square net, in the seed paper's order.

    Parameters
    ----------
    nodes_per_side : int
        Ns, the number of knots on a side.

    Returns
    -------
    pairs : (2 Ns (Ns - 1), 2) int array
        Mesh thread ``t`` joins knots ``pairs[t, 0] < pairs[t, 1]``.
    """
    ns = nodes_per_side
    pairs = []
    for i in range(ns * ns):
        if (i + 1) % ns != 0:
            pairs.append((i, i + 1))
        if i + ns < ns * ns:
            pairs.append((i, i + ns))
    return np.array(pairs, dtype=np.int64).reshape(-1, 2)


def corner_knots(nodes_per_side: int) -> NDArray[np.int64]:
    """The four corner knots ``0, Ns-1, Ns^2-Ns, Ns^2-1`` (order of the corner masses)."""
    ns = nodes_per_side
    return np.array([0, ns - 1, ns * ns - ns, ns * ns - 1], dtype=np.int64)


def in_plane_axes(direction: tuple[float, float, float]) -> NDArray[np.float64]:
    """Unit vectors ``(u, w, d)`` with ``d`` along ``direction`` and ``u, w`` spanning the net plane.

    ``u`` is the projection of the global x axis on the plane (y when x is nearly along ``d``).
    """
    d = np.asarray(direction, float) / np.linalg.norm(direction)
    ref = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = ref - (ref @ d) * d
    u /= np.linalg.norm(u)
    return np.array([u, np.cross(d, u), d])


@dataclass(frozen=True)
class NetLayout:
    """Where the net's parts are in the node and segment arrays."""

    nodes_per_side: int
    knots: NDArray[np.int64]          # (Ns^2,) node index of every knot
    corners: NDArray[np.int64]        # (4,) node index of the corner masses
    net_nodes: NDArray[np.int64]      # knots and thread nodes, without the corner masses
    direction: NDArray[np.float64]    # (3,) unit shooting direction
    n_threads: int                    # mesh threads + 4 corner threads


def diameter(points: NDArray[np.float64]) -> float:
    """The largest distance between two of ``points`` (P, 3) [m]: over the vertices of their
    convex hull (joggled where the points are flat or on a line), or over all pairs of a few."""
    points = np.asarray(points, dtype=float)
    if len(points) > 256:
        from scipy.spatial import ConvexHull
        points = points[ConvexHull(points, qhull_options="QJ").vertices]
    gaps = points[:, None, :] - points[None, :, :]
    return float(np.sqrt(np.max(np.einsum("ijk,ijk->ij", gaps, gaps), initial=0.0)))


@dataclass(frozen=True)
class Structure:
    """Nodes and two-node segments of a scene, independent of the mechanical model.

    Attributes
    ----------
    rest_positions : (N, 3) float
        Stress-free (deployed) node positions [m].
    positions : (N, 3) float
        Initial node positions [m] (the packed net).
    velocities : (N, 3) float
        Initial node velocities [m/s].
    segments : (E, 2) int
        Node pairs of the segments, thread by thread along each thread.
    rest_length : (E,) float
        Stress-free segment length [m].
    material : (E,) int
        Index into ``scene.materials`` of each segment.
    thread : (E,) int
        Thread index of each segment (net threads first, then one per rod).
    point_mass : (N,) float
        Concentrated masses (knots, corner masses, ``[[masses]]``) [kg].
    selectors : dict
        Every named node selector mapped to its node index.
    net : NetLayout or None
    """

    rest_positions: NDArray[np.float64]
    positions: NDArray[np.float64]
    velocities: NDArray[np.float64]
    segments: NDArray[np.int64]
    rest_length: NDArray[np.float64]
    material: NDArray[np.int64]
    thread: NDArray[np.int64]
    point_mass: NDArray[np.float64]
    selectors: dict[str, int]
    net: NetLayout | None

    @property
    def n_nodes(self) -> int:
        return len(self.positions)

    @cached_property
    def size(self) -> float:
        """The largest distance between two nodes of the stress-free structure [m] (for a
        straight rod its length, for a flat square net the distance between opposite corners:
        the diagonal of the bounding box there, but unchanged when the scene is turned)."""
        return diameter(self.rest_positions)

    def node(self, selector: str, key: str) -> int:
        """Node index of ``selector``; ``key`` names the scene key for the error message."""
        if selector in self.selectors:
            return self.selectors[selector]
        raise SceneError(key, selector, "names no node of this scene; use 'ROD:start', 'ROD:end', "
                         "'ROD:i', 'net:knot:i' or 'net:corner:0..3' "
                         f"(this scene has {self._selector_ranges()})")

    def _selector_ranges(self) -> str:
        parts = []
        if self.net is not None:
            parts.append(f"net:knot:0..{len(self.net.knots) - 1}, net:corner:0..3")
        rods = sorted({s.split(":")[0] for s in self.selectors if not s.startswith("net:")})
        for rod in rods:
            last = max(int(s.split(":")[1]) for s in self.selectors
                       if s.startswith(rod + ":") and s.split(":")[1].isdigit())
            parts.append(f"{rod}:0..{last}")
        return ", ".join(parts)


class _Builder:
    """Accumulates nodes and segments; turned into a :class:`Structure` at the end."""

    def __init__(self) -> None:
        self.rest: list[NDArray[np.float64]] = []
        self.pos: list[NDArray[np.float64]] = []
        self.vel: list[NDArray[np.float64]] = []
        self.mass: list[NDArray[np.float64]] = []
        self.segs: list[NDArray[np.int64]] = []
        self.mat: list[int] = []
        self.thread: list[int] = []
        self.starts: list[int] = []
        """The index of the first node of each block of ``rest``."""
        self.n = 0
        self.n_threads = 0

    def add_nodes(self, rest: NDArray, pos: NDArray, vel: NDArray, mass: NDArray) -> NDArray[np.int64]:
        idx = np.arange(self.n, self.n + len(rest))
        self.rest.append(rest), self.pos.append(pos), self.vel.append(vel), self.mass.append(mass)
        self.starts.append(self.n)
        self.n += len(rest)
        return idx

    def add_chain(self, nodes: NDArray[np.int64], material: int) -> None:
        """Segments joining consecutive ``nodes``, all in one new thread."""
        self.segs.append(np.column_stack([nodes[:-1], nodes[1:]]))
        self.mat += [material] * (len(nodes) - 1)
        self.thread += [self.n_threads] * (len(nodes) - 1)
        self.n_threads += 1

    def rest_position(self, i: int) -> NDArray[np.float64]:
        """The stress-free position (3,) of node ``i`` (without stacking every block: a net adds
        a block per thread, and stacking them all for each made building the 21 x 21 net take
        0.3 s)."""
        k = bisect.bisect_right(self.starts, i) - 1
        return self.rest[k][i - self.starts[k]]

    def interior(self, a: int, b: int, n: int, scale: float, center: NDArray) -> NDArray[np.int64]:
        """Add the ``n - 1`` interior nodes of a thread from node ``a`` to ``b``, evenly spaced."""
        s = np.arange(1, n)[:, None] / n
        ra, rb = self.rest_position(a), self.rest_position(b)
        r = ra + s * (rb - ra)
        zeros = np.zeros_like(r)
        return self.add_nodes(r, center + scale * (r - center), zeros, np.zeros(len(r)))


def build_structure(scene: Scene) -> Structure:
    """Discretise the scene's net and rods into nodes and segments."""
    b = _Builder()
    selectors: dict[str, int] = {}
    net = _add_net(b, scene, selectors) if scene.net is not None else None
    for rod in scene.rods:
        _add_rod(b, scene, rod, selectors)
    velocities = np.vstack(b.vel)
    point_mass = np.concatenate(b.mass)
    structure = Structure(
        rest_positions=np.vstack(b.rest), positions=np.vstack(b.pos), velocities=velocities,
        segments=np.vstack(b.segs), rest_length=np.empty(0), material=np.array(b.mat),
        thread=np.array(b.thread), point_mass=point_mass, selectors=selectors, net=net)
    for i, m in enumerate(scene.masses):
        node = structure.node(m.node, f"masses[{i}].node")
        point_mass[node] += m.mass
        if m.velocity is not None:
            velocities[node] = m.velocity
    for i, (selector, *v) in enumerate(scene.initial.velocities if scene.initial else ()):
        velocities[structure.node(selector, f"initial.velocities[{i}]")] = v
    rest_length = np.linalg.norm(structure.rest_positions[structure.segments[:, 1]]
                                 - structure.rest_positions[structure.segments[:, 0]], axis=1)
    object.__setattr__(structure, "rest_length", rest_length)
    return structure


def _add_net(b: _Builder, scene: Scene, selectors: dict[str, int]) -> NetLayout:
    spec: NetSpec = scene.net  # type: ignore[assignment]
    ns, n = spec.nodes_per_side, scene.model.elements_per_thread
    material = [m.name for m in scene.materials].index(spec.material)
    u, w, d = in_plane_axes(spec.direction)
    center = np.asarray(spec.center, float)
    col, row = np.meshgrid(np.arange(ns), np.arange(ns))
    offset = (ns - 1) / 2.0
    knots_rest = center + spec.mesh_length * ((col.ravel() - offset)[:, None] * u
                                              + (row.ravel() - offset)[:, None] * w)
    corner_k = corner_knots(ns)
    diag = knots_rest[corner_k] - center
    diag /= np.linalg.norm(diag, axis=1)[:, None]
    corners_rest = knots_rest[corner_k] + spec.corner_thread_length * diag
    angle = math.radians(spec.launch_angle_deg)
    corner_vel = spec.launch_speed * (math.cos(angle) * d + math.sin(angle) * diag)
    p = spec.packing
    knots = b.add_nodes(knots_rest, center + p * (knots_rest - center), np.zeros_like(knots_rest),
                        np.full(ns * ns, spec.knot_mass))
    corners = b.add_nodes(corners_rest, center + p * (corners_rest - center), corner_vel,
                          np.full(4, spec.corner_mass))
    ends = np.vstack([square_net_threads(ns), np.column_stack([corner_k, corners])])
    first_thread_node = b.n
    for a, c in ends:
        chain = np.concatenate([[a], b.interior(a, c, n, p, center), [c]])
        b.add_chain(chain, material)
    for i, k in enumerate(knots):
        selectors[f"net:knot:{i}"] = int(k)
    for i, k in enumerate(corners):
        selectors[f"net:corner:{i}"] = int(k)
    net_nodes = np.concatenate([knots, np.arange(first_thread_node, b.n)])
    return NetLayout(nodes_per_side=ns, knots=knots, corners=corners, net_nodes=net_nodes,
                     direction=d, n_threads=len(ends))


def _add_rod(b: _Builder, scene: Scene, rod: RodSpec, selectors: dict[str, int]) -> None:
    points = np.asarray(rod.points, float)
    rest = _spread_by_arc_length(points, rod.elements)
    omega = np.asarray(rod.angular_velocity, float)
    center = rest.mean(axis=0) if rod.rotation_center is None else np.asarray(rod.rotation_center)
    vel = np.asarray(rod.velocity, float) + np.cross(omega, rest - center)
    nodes = b.add_nodes(rest, rest.copy(), vel, np.zeros(len(rest)))
    b.add_chain(nodes, [m.name for m in scene.materials].index(rod.material))
    for i, k in enumerate(nodes):
        selectors[f"{rod.name}:{i}"] = int(k)
    selectors[f"{rod.name}:start"], selectors[f"{rod.name}:end"] = int(nodes[0]), int(nodes[-1])


def _spread_by_arc_length(points: NDArray[np.float64], elements: int) -> NDArray[np.float64]:
    """``elements + 1`` nodes on the polyline ``points``, evenly spaced in arc length.

    Every polyline vertex is kept as a node (corners stay sharp); each polyline segment receives
    a number of elements proportional to its length, at least one.
    """
    lengths = np.linalg.norm(np.diff(points, axis=0), axis=1)
    share = lengths / lengths.sum() * elements
    counts = np.maximum(1, np.floor(share).astype(int))
    while counts.sum() < elements:  # hand out the remaining elements by largest shortfall
        counts[np.argmax(share - counts)] += 1
    while counts.sum() > elements:  # short polyline segments took more than their share
        counts[np.argmax(np.where(counts > 1, counts - share, -np.inf))] -= 1
    nodes = [points[:1]]
    for p, q, c in zip(points[:-1], points[1:], counts):
        s = np.arange(1, c + 1)[:, None] / c
        nodes.append(p + s * (q - p))
    return np.vstack(nodes)
