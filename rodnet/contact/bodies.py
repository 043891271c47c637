"""The rigid bodies of a scene as contact sees them: shapes, poses, the contact law, thread radii.

:func:`build_body_contact` turns ``[[bodies]]`` and ``[contact]`` into a read-only
:class:`BodyContact`: one shape per body (:mod:`rodnet.contact.geometry`, :mod:`rodnet.contact.mesh`),
its start pose, the penalty law, the radius of every thread segment and the per-step travel limit
that keeps thread points from jumping over a body. It refuses a body that overlaps a thread at
the start, naming the body and the first node inside it. A fixed body keeps its pose; a free body
has mass and inertia (from the shape, (G11)-(G12), or given). The bodies' current state is not
here but in the run's :class:`rodnet.state.State` (:meth:`BodyContact.start_motion` is its start).
Equations: ``elements/contact/FORMULATION.md``; user documentation: ``docs/contact.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from rodnet.config import BodySpec, ContactSpec, Scene
from rodnet.contact.broadphase import contact_points
from rodnet.contact.geometry import Box, Cylinder, Shape, Sphere, query_world
from rodnet.contact.shapes import shape_from_scene
from rodnet.contact.surfaces import surface_triangles
from rodnet.contact.laws import ContactLaw
from rodnet.contact.rigid_body import start_motion
from rodnet.errors import SceneError
from rodnet.kernels import so3
from rodnet.state import BodyMotion
from rodnet.topology import Structure

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

TRAVEL_FRACTION = 0.5
"""Largest travel of a thread point near a body in one step, as a fraction of the body's half
thickness plus the thinnest thread radius, (E3)."""

SHAPE_CODES = {"box": 0, "cylinder": 1, "sphere": 2, "mesh": 3}
"""Shape kind as the compiled kernels number it."""


def euler_xyz_matrix(angles_deg: tuple[float, float, float]) -> tuple[FloatArray, FloatArray]:
    """Body-to-world rotation of ``orientation_deg``: rotations about the fixed world x, y and z
    axes, in that order (``R = R_z R_y R_x``).

    Returns
    -------
    rotation : (3, 3) float
    quaternion : (4,) float
        The same rotation as a unit quaternion (w, x, y, z), w >= 0.
    """
    q = np.array([1.0, 0.0, 0.0, 0.0])
    for axis, angle in enumerate(angles_deg):
        q = so3.quat_multiply(so3.quat_from_rotvec(math.radians(angle) * np.eye(3)[axis]), q)
    q = so3.quat_normalize(q)
    q = -q if q[0] < 0.0 else q
    return so3.quat_to_matrix(q), q


@dataclass(frozen=True, eq=False)
class BodyContact:
    """Rigid bodies and the penalty contact of the threads with them.

    Every array is read-only.

    Attributes
    ----------
    names : tuple of str
        ``[[bodies]]`` names, in scene order (the body index B of the result arrays).
    kinds : tuple of str
        ``"box"``, ``"cylinder"``, ``"sphere"`` or ``"mesh"``.
    shapes : tuple of Shape
        Geometry in the body frame (origin at the centre of mass).
    position : (B, 3) float
        World position of each body frame's origin (its centre of mass) at t = 0 [m].
    rotation : (B, 3, 3) float
        Body-to-world rotations at t = 0.
    quaternion : (B, 4) float
        The same rotations as unit quaternions (w, x, y, z).
    mass : (B,) float
        Body mass [kg] from ``mass`` or ``density``; nan when neither is given (fixed bodies).
    free : (B,) bool
        True for a free body (``fixed = false``).
    inertia : (B, 3, 3) float
        Inertia about the centre of mass in body axes [kg m^2]; nan without a mass.
    velocity : (B, 3) float
        Velocity at t = 0 [m/s].
    omega : (B, 3) float
        Angular velocity at t = 0, world axes [rad/s].
    gravity : (3,) float
        Acceleration of gravity acting on the free bodies [m/s^2].
    law : ContactLaw
        Penalty normal law and velocity-regularised friction (``[contact]``).
    points_per_segment : int
        n: contact points at ``xi = j / n`` of every segment near a body, nodes once.
    segments : (S, 2) int
        Node pairs of the thread segments.
    radius : (S,) float
        Thread radius of every segment [m] (half its material's diameter).
    travel_limit : (B,) float
        Largest distance a thread point near body b may move in one step [m].
    """

    names: tuple[str, ...]
    kinds: tuple[str, ...]
    shapes: tuple[Shape, ...]
    position: FloatArray
    rotation: FloatArray
    quaternion: FloatArray
    mass: FloatArray
    law: ContactLaw
    points_per_segment: int
    segments: IntArray
    radius: FloatArray
    travel_limit: FloatArray
    free: NDArray[np.bool_]
    inertia: FloatArray
    velocity: FloatArray
    omega: FloatArray
    gravity: FloatArray

    def start_motion(self) -> BodyMotion:
        """A new state of every body at t = 0."""
        inertia = np.where(self.free[:, None, None], self.inertia, 0.0)
        return start_motion(self.position, self.quaternion, self.velocity, self.omega, inertia)

    @property
    def inv_mass(self) -> FloatArray:
        """1 / mass of the free bodies, 0 for the fixed ones (B,) [1/kg]."""
        return np.where(self.free, 1.0 / np.where(self.free, self.mass, 1.0), 0.0)

    @property
    def inv_inertia(self) -> FloatArray:
        """Inverse inertia in body axes of the free bodies, 0 for the fixed ones (B, 3, 3)."""
        out = np.zeros((self.n_bodies, 3, 3))
        out[self.free] = np.linalg.inv(self.inertia[self.free])
        return out

    def compliance(self) -> FloatArray:
        """Largest compliance of each body at a point within its bounding sphere,
        ``1/m + r_b^2 / I_min`` (B,) [1/kg]; 0 for fixed bodies, (E1)."""
        out = np.zeros(self.n_bodies)
        for b in np.flatnonzero(self.free):
            r_b = float(np.linalg.norm(np.abs(self.shapes[b].bounds).max(axis=0)))
            out[b] = 1.0 / self.mass[b] + r_b**2 / float(np.linalg.eigvalsh(self.inertia[b])[0])
        return out

    @property
    def n_bodies(self) -> int:
        return len(self.names)

    @cached_property
    def overlaps(self) -> list[tuple[int, int]]:
        """:func:`overlapping_bodies` at the start pose, computed once (a run says it before and
        after it; two meshes of 82,000 triangles take about a second)."""
        return overlapping_bodies(self)

    @cached_property
    def bound_radius(self) -> FloatArray:
        """(B,) radius of each body's bounding sphere about its centre of mass [m]."""
        return np.array([np.linalg.norm(np.abs(s.bounds).max(axis=0)) for s in self.shapes])

    def combined_step(self, threads: float, inv_mass: FloatArray) -> float:
        """The explicit limit [s] of threads whose own limit is ``threads`` [s] with these contact
        springs added (E1): ``1/dt^2 = 1/dt_threads^2 + 1/dt_contact^2``, which is
        ``omega^2 = omega_threads^2 + omega_contact^2`` without damping; ``inv_mass`` (N,) as for
        :meth:`stable_step`."""
        contact = self.stable_step(inv_mass)
        if not math.isfinite(contact):
            return threads
        return 1.0 / math.sqrt(1.0 / threads**2 + 1.0 / contact**2)

    def stable_step(self, inv_mass: FloatArray) -> float:
        """Stability limit [s] of symplectic Euler under the contact springs alone (inf when no
        node can move), (E1).

        A free body adds ``k P c_b`` to the bound, ``P`` the number of contact points of the
        model and ``c_b`` the body's largest compliance (:meth:`compliance`).

        Every candidate point is taken as touching at once with stiffness k and damping c. With
        ``w_p = (N_a / sqrt(m_a), N_b / sqrt(m_b))`` the mass-scaled shape functions of point p,
        node a's Gershgorin row of ``M^-1/2 K M^-1/2`` is ``k sum_p w_pa (w_pa + w_pb)``; its
        largest value bounds ``omega^2``, and the damping ratio follows from
        ``c omega / (2 k)`` as for the segments (S10).
        """
        k, c = self.law.stiffness, self.law.damping
        row = k * inv_mass.copy()  # every node is one point
        n = self.points_per_segment
        a, b = self.segments[:, 0], self.segments[:, 1]
        sa, sb = np.sqrt(inv_mass[a]), np.sqrt(inv_mass[b])
        for j in range(1, n):
            xi = j / n
            wa, wb = (1.0 - xi) * sa, xi * sb
            np.add.at(row, a, k * wa * (wa + wb))
            np.add.at(row, b, k * wb * (wa + wb))
        omega2 = float(row.max(initial=0.0))
        if self.free.any():
            # a free body's own row: every point pressing on it at once, (E1)
            points = len(inv_mass) + len(self.segments) * (n - 1)
            omega2 += k * points * float(self.compliance().max())
        if omega2 <= 0.0:
            return math.inf
        omega = math.sqrt(omega2)
        zeta = c * omega / (2.0 * k)
        return 2.0 / omega * (math.sqrt(1.0 + zeta**2) - zeta)


def _base_dir(scene: Scene) -> Path:
    source = Path(scene.source)
    return source.parent if source.is_file() else Path.cwd()


def _shape(spec: BodySpec, key: str, base_dir: Path) -> Shape:
    try:
        return shape_from_scene(spec.shape, spec.size, spec.file, base_dir)
    except SceneError as exc:
        raise exc.within(key) from None


def _half_thickness(shape: Shape) -> float:
    """Half the smallest extent of the body [m] (of its oriented bounding box for a mesh)."""
    if isinstance(shape, Box):
        return min(shape.half_extents)
    if isinstance(shape, Cylinder):
        return min(shape.radius, 0.5 * shape.length)
    if isinstance(shape, Sphere):
        return shape.radius
    return 0.5 * shape.thinnest_extent()


def _inertia(spec: BodySpec, shape: Shape, mass: float) -> FloatArray:
    """Inertia about the centre of mass in body axes [kg m^2]: ``inertia`` of the scene, else
    that of the homogeneous shape (G11)-(G12); nan without a mass."""
    if spec.inertia is not None:
        xx, yy, zz = spec.inertia[:3]
        xy, xz, yz = spec.inertia[3:] if len(spec.inertia) == 6 else (0.0, 0.0, 0.0)
        return np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]], dtype=np.float64)
    if not math.isfinite(mass):
        return np.full((3, 3), math.nan)
    return np.asarray(shape.mass_properties(mass).inertia, dtype=np.float64)


def _mass(spec: BodySpec, shape: Shape) -> float:
    if spec.mass is not None:
        return spec.mass
    if spec.density is not None:
        return spec.density * shape.mass_properties(1.0).volume
    return math.nan


def build_body_contact(scene: Scene, structure: Structure) -> BodyContact | None:
    """The fixed bodies of ``scene`` and their contact with the threads, or None without bodies.

    Raises
    ------
    SceneError
        For a mesh file that is missing, unreadable or not watertight, or a body that overlaps a
        thread in the initial state.
    """
    if not scene.bodies:
        return None
    base_dir = _base_dir(scene)
    shapes = tuple(_shape(b, f"bodies[{i}]", base_dir) for i, b in enumerate(scene.bodies))
    poses = [euler_xyz_matrix(b.orientation_deg) for b in scene.bodies]
    spec = scene.contact if scene.contact is not None else ContactSpec()
    radius = 0.5 * np.array([m.diameter for m in scene.materials])[structure.material]
    law = ContactLaw(stiffness=spec.stiffness, damping=spec.damping, friction=spec.friction,
                     smoothing=spec.smoothing_for(float(radius.min())),
                     slip_velocity=spec.slip_velocity)
    travel = TRAVEL_FRACTION * (np.array([_half_thickness(s) for s in shapes])
                                + float(radius.min()))
    mass = np.array([_mass(b, s) for b, s in zip(scene.bodies, shapes)])
    rotation = np.array([p[0] for p in poses])
    omega_body = np.radians(np.array([b.angular_velocity_deg for b in scene.bodies], float))
    contact = BodyContact(
        names=tuple(b.name for b in scene.bodies), kinds=tuple(b.shape for b in scene.bodies),
        shapes=shapes, position=np.array([b.position for b in scene.bodies], dtype=np.float64),
        rotation=rotation, quaternion=np.array([p[1] for p in poses]), mass=mass, law=law,
        points_per_segment=spec.points_per_segment, segments=structure.segments,
        radius=radius, travel_limit=travel,
        free=np.array([not b.fixed for b in scene.bodies], dtype=np.bool_),
        inertia=np.array([_inertia(b, s, m) for b, s, m in zip(scene.bodies, shapes, mass)]),
        velocity=np.array([b.velocity for b in scene.bodies], dtype=np.float64),
        omega=np.einsum("bij,bj->bi", rotation, omega_body),
        gravity=np.array(scene.simulation.gravity, dtype=np.float64))
    for name in ("position", "rotation", "quaternion", "mass", "radius", "travel_limit", "free",
                 "inertia", "velocity", "omega", "gravity"):
        getattr(contact, name).setflags(write=False)
    check_start_clear(contact, structure,
                      contact.law.smoothing if scene.simulation.type == "dynamic" else 0.0)
    return contact


def check_start_clear(contact: BodyContact, structure: Structure, band: float = 0.0) -> None:
    """Refuse bodies that touch a thread at the start: a node or a segment point closer to the
    body surface than the thread radius (or inside it), or closer than the radius plus
    ``band`` [m] (a dynamic run's: the contact law's ``smoothing``, where its force already
    acts, N1; a thread at rest 9.5 mm above a sphere with ``smoothing = 0.1`` m started with
    201 J in the contact spring and flew off at 1,000 m/s, outside check; a static run only
    starts its search for the equilibrium there).

    Raises
    ------
    SceneError
        Naming the body, and the first node inside it (or the first node of the first segment
        that touches it); naming ``contact.smoothing`` where the gap is within the blend.
    """
    x = structure.positions
    names = {index: selector for selector, index in sorted(structure.selectors.items(),
                                                            key=lambda item: item[0])}
    for b, shape in enumerate(contact.shapes):
        points = contact_points(x[contact.segments], contact.radius, contact.position[b],
                                contact.rotation[b], shape.bounds, band,
                                contact.points_per_segment, contact.segments)
        if not len(points.segment):
            continue
        gap = shape.query(points.local).distance - contact.radius[points.segment]
        # a gap of the blend's width starts at zero force: the rounding of the positions
        # (a thread placed at exactly the blend's width) is not a touch
        touching = np.flatnonzero(gap < (1.0 - 1e-6) * band if band > 0.0 else gap < 0.0)
        if not len(touching):
            continue
        if float(gap[touching].min()) >= 0.0:
            closest = touching[int(np.argmin(gap[touching]))]
            a, c = (int(n) for n in contact.segments[points.segment[closest]])
            xi = float(points.parameter[closest])
            where = f"at {_node_name(a, names)}" if xi == 0.0 else \
                f"at {_node_name(c, names)}" if xi == 1.0 else \
                (f"on the segment from {_node_name(a, names)} to {_node_name(c, names)}, "
                 f"{xi:.2g} of the way along,")
            raise SceneError("contact.smoothing", band,
                             f"puts body {contact.names[b]!r} in contact with the threads at the "
                             f"start: {where} the thread's surface is "
                             f"{float(gap[closest]):.3g} m from the body's, within the blend "
                             "where the contact force already acts (N1); lower "
                             "contact.smoothing below the starting gaps, or move the body or "
                             "the threads apart")
        ends = contact.segments[points.segment[touching]]
        xi = points.parameter[touching]
        node_points = np.flatnonzero((xi == 0.0) | (xi == 1.0))
        if len(node_points):
            p = touching[node_points]
            nodes = np.where(points.parameter[p] == 0.0, contact.segments[points.segment[p], 0],
                             contact.segments[points.segment[p], 1])
            node, what = int(nodes.min()), ""
        else:
            node, what = int(ends.min()), "a segment from "
        raise SceneError(f"bodies[{b}]", contact.names[b],
                         f"starts in contact with the threads: {what}{_node_name(node, names)} at "
                         f"{np.array2string(x[node], precision=4)} m is inside the body or "
                         "not farther from its surface than the thread radius; move the body or "
                         "the threads apart (a gap above zero between the thread's surface and "
                         "the body's)")


def _node_name(node: int, names: dict[int, str]) -> str:
    """``node N`` with its selector where it has one: ``node 5 (r:5)``."""
    return f"node {node}" + (f" ({names[node]})" if node in names else "")


OVERLAP_ROUNDOFF = 1e-9
"""A vertex deeper than this [m] inside another body makes the two overlap."""


OVERLAP_SAMPLES = 20000
"""About how many points of a body's surface :func:`overlapping_bodies` tests."""


def _surface_samples(shape: Shape) -> FloatArray:
    """Points (P, 3) on ``shape``'s surface in its body frame: on every triangle of
    :func:`~rodnet.contact.surfaces.surface_triangles`, a barycentric grid of up to 8
    divisions per edge (fewer for fine meshes, about :data:`OVERLAP_SAMPLES` points in all;
    a mesh of more triangles than that: its vertices, thinned to about as many)."""
    vertices, faces = surface_triangles(shape)
    if len(faces) > OVERLAP_SAMPLES:   # a fine mesh: its vertices, thinned to about as many
        vertices = np.asarray(vertices, dtype=np.float64)
        return vertices[::max(1, len(vertices) // OVERLAP_SAMPLES)]
    n = max(1, min(8, int(math.sqrt(OVERLAP_SAMPLES / max(len(faces), 1)))))
    weights = np.array([(i, j, n - i - j) for i in range(n + 1) for j in range(n + 1 - i)],
                       dtype=np.float64) / n
    corners = np.asarray(vertices, dtype=np.float64)[np.asarray(faces)]   # (F, 3, 3)
    return np.einsum("wk,fkd->fwd", weights, corners).reshape(-1, 3)


def overlapping_bodies(contact: BodyContact) -> list[tuple[int, int]]:
    """The pairs ``(a, b)``, ``a < b``, of bodies that overlap at the start, at least one of them
    free: a point of one's surface (:func:`_surface_samples`) inside the other. Bodies do not
    touch each other, so a free body moves through the other; fixed bodies may overlap to
    build one obstacle. Surface points, not corners alone: two boxes with faces in one plane
    overlap where no corner of either is inside the other (outside check)."""
    samples = [contact.position[b] + _surface_samples(shape) @ contact.rotation[b].T
               for b, shape in enumerate(contact.shapes)]
    pairs = []
    for a in range(len(contact.shapes)):
        for b in range(a + 1, len(contact.shapes)):
            if not (contact.free[a] or contact.free[b]):
                continue
            # deeper than round-off: bodies resting on each other's faces do not overlap
            inside = [query_world(contact.shapes[j], samples[i], contact.position[j],
                                  contact.rotation[j]).distance < -OVERLAP_ROUNDOFF
                      for i, j in ((a, b), (b, a))]
            if any(bool(np.any(x)) for x in inside):
                pairs.append((a, b))
    return pairs
