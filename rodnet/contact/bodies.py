"""The rigid bodies of a scene as contact sees them: shapes, poses, the contact law, thread radii.

:func:`build_body_contact` turns ``[[bodies]]`` and ``[contact]`` into a read-only
:class:`BodyContact`: one shape per body (:mod:`rodnet.contact.geometry`, :mod:`rodnet.contact.mesh`),
its pose, the penalty law, the radius of every thread segment and the per-step travel limit that
keeps thread points from jumping over a body. It refuses a body that overlaps a thread at the
start, naming the body and the first node inside it. Every body of this version is fixed: its
pose is constant and its material points do not move. The arrays the compiled explicit loop takes
are built once by :meth:`BodyContact.kernel_arguments`. Equations:
``elements/contact/FORMULATION.md``; user documentation: ``docs/contact.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from rodnet.config import BodySpec, ContactSpec, Scene
from rodnet.contact.geometry import Box, Cylinder, Shape, Sphere, shape_from_scene
from rodnet.contact.laws import ContactLaw
from rodnet.errors import SceneError
from rodnet.kernels import so3
from rodnet.topology import Structure

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

TRAVEL_FRACTION = 0.5
"""Largest travel of a thread point near a body in one step, as a fraction of the smaller of the
thinnest thread radius and the body's half thickness, (E3)."""

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
    """Fixed rigid bodies and the penalty contact of the threads with them (read-only arrays).

    Attributes
    ----------
    names : tuple of str
        ``[[bodies]]`` names, in scene order (the body index B of the result arrays).
    kinds : tuple of str
        ``"box"``, ``"cylinder"``, ``"sphere"`` or ``"mesh"``.
    shapes : tuple of Shape
        Geometry in the body frame (origin at the centre of mass).
    position : (B, 3) float
        World position of each body frame's origin [m].
    rotation : (B, 3, 3) float
        Body-to-world rotations.
    quaternion : (B, 4) float
        The same rotations as unit quaternions (w, x, y, z).
    mass : (B,) float
        Body mass [kg] from ``mass`` or ``density``; nan when neither is given.
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
    _kernel: tuple = field(default=(), repr=False)

    @property
    def n_bodies(self) -> int:
        return len(self.names)

    def kernel_arguments(self, inv_mass: FloatArray) -> tuple:
        """The arrays of :func:`rodnet.kernels.contact_compiled.accumulate_contact` after the
        state, the force and the step, in its order (built once, then reused)."""
        if not self._kernel:
            from rodnet.contact.kernel_data import kernel_arrays

            object.__setattr__(self, "_kernel", kernel_arrays(self))
        node_share = _node_share(self.segments, len(inv_mass), self.points_per_segment)
        return (inv_mass, self.segments, self.radius, node_share, *self._kernel)

    def stable_step(self, inv_mass: FloatArray) -> float:
        """Stability limit [s] of symplectic Euler under the contact springs alone (inf when no
        node can move), (E1).

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
        if omega2 <= 0.0:
            return math.inf
        omega = math.sqrt(omega2)
        zeta = c * omega / (2.0 * k)
        return 2.0 / omega * (math.sqrt(1.0 + zeta**2) - zeta)


def _node_share(segments: IntArray, n_nodes: int, points_per_segment: int) -> IntArray:
    """Number of contact points that can act on each node: the node itself plus the interior
    points of its segments, (N,)."""
    degree = np.bincount(segments.ravel(), minlength=n_nodes)
    return (1 + degree * (points_per_segment - 1)).astype(np.int64)


def _base_dir(scene: Scene) -> Path:
    source = Path(scene.source)
    return source.parent if source.is_file() else Path.cwd()


def _shape(spec: BodySpec, key: str, base_dir: Path) -> Shape:
    try:
        return shape_from_scene(spec.shape, spec.size, spec.file, base_dir)
    except SceneError as exc:
        raise exc.within(key) from None


def _half_thickness(shape: Shape) -> float:
    """Half the smallest extent of the body [m] (of its bounding box for a mesh)."""
    if isinstance(shape, Box):
        return min(shape.half_extents)
    if isinstance(shape, Cylinder):
        return min(shape.radius, 0.5 * shape.length)
    if isinstance(shape, Sphere):
        return shape.radius
    return 0.5 * float(np.ptp(shape.bounds, axis=0).min())


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
    law = ContactLaw(stiffness=spec.stiffness, damping=spec.damping, friction=spec.friction,
                     smoothing=spec.smoothing, slip_velocity=spec.slip_velocity)
    radius = 0.5 * np.array([m.diameter for m in scene.materials])[structure.material]
    travel = TRAVEL_FRACTION * np.minimum(float(radius.min()),
                                          np.array([_half_thickness(s) for s in shapes]))
    contact = BodyContact(
        names=tuple(b.name for b in scene.bodies), kinds=tuple(b.shape for b in scene.bodies),
        shapes=shapes, position=np.array([b.position for b in scene.bodies], dtype=np.float64),
        rotation=np.array([p[0] for p in poses]), quaternion=np.array([p[1] for p in poses]),
        mass=np.array([_mass(b, s) for b, s in zip(scene.bodies, shapes)]), law=law,
        points_per_segment=spec.points_per_segment, segments=structure.segments,
        radius=radius, travel_limit=travel)
    for name in ("position", "rotation", "quaternion", "mass", "radius", "travel_limit"):
        getattr(contact, name).setflags(write=False)
    check_start_clear(contact, structure)
    return contact


def check_start_clear(contact: BodyContact, structure: Structure) -> None:
    """Refuse bodies that touch a thread at the start: a node or a segment point closer to the
    body surface than the thread radius (or inside it).

    Raises
    ------
    SceneError
        Naming the body, and the first node inside it (or the first node of the first segment
        that touches it).
    """
    from rodnet.contact.broadphase import contact_points

    x = structure.positions
    names = {index: selector for selector, index in sorted(structure.selectors.items(),
                                                            key=lambda item: item[0])}
    for b, shape in enumerate(contact.shapes):
        points = contact_points(x[contact.segments], contact.radius, contact.position[b],
                                contact.rotation[b], shape.bounds, 0.0,
                                contact.points_per_segment, contact.segments)
        if not len(points.segment):
            continue
        gap = shape.query(points.local).distance - contact.radius[points.segment]
        touching = np.flatnonzero(gap < 0.0)
        if not len(touching):
            continue
        ends = contact.segments[points.segment[touching]]
        xi = points.parameter[touching]
        node_points = np.flatnonzero((xi == 0.0) | (xi == 1.0))
        if len(node_points):
            p = touching[node_points]
            nodes = np.where(points.parameter[p] == 0.0, contact.segments[points.segment[p], 0],
                             contact.segments[points.segment[p], 1])
            node, what = int(nodes.min()), "node"
        else:
            node, what = int(ends.min()), "a segment from node"
        label = f" ({names[node]})" if node in names else ""
        raise SceneError(f"bodies[{b}]", contact.names[b],
                         f"starts in contact with the threads: {what} {node}{label} at "
                         f"{np.array2string(x[node], precision=4)} m is inside the body or "
                         "closer to its surface than the thread radius; move the body or the "
                         "threads apart")


def check_contact_supported(scene: Scene) -> None:
    """Refuse scenes with bodies that this version cannot run: Cosserat rods with bending or
    torsion (contact is modelled for the lumped model and cable threads) and ``rk45``.

    Raises
    ------
    SceneError
    """
    if not scene.bodies:
        return
    model = scene.model
    if model.type == "cosserat" and (model.bending or model.torsion):
        raise SceneError("bodies", [b.name for b in scene.bodies],
                         "contact with rigid bodies is modelled for model.type = 'lumped' and "
                         "for cable threads (model.type = 'cosserat' with bending = false and "
                         "torsion = false) only, not yet for rods with bending or torsion")
    if scene.simulation.type == "dynamic" and scene.integrator == "rk45":
        raise SceneError("simulation.integrator", "rk45", "rk45 does not model contact; scenes "
                         "with [[bodies]] need 'explicit' or an implicit integrator "
                         "('generalized-alpha', 'backward-euler', 'midpoint')")
