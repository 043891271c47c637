"""Rigid body shapes: signed distance, outward normal and its derivative, mass properties.

Every shape answers :meth:`query` for points given in its body frame (origin at the centre of
mass, body axes): the signed distance ``d`` (negative inside), the outward unit normal
``n = grad d``, the closest surface point ``c = x - d n`` and ``H = dn/dx``, the Hessian of ``d``,
which the consistent contact tangent needs. Equations (G1)-(G12) of
``elements/contact/FORMULATION.md``; what happens on the medial surfaces (points with two closest
features) is described there in section 1.4 and summarised in each class.

Triangle meshes are in :mod:`rodnet.contact.mesh`. Shapes are frozen dataclasses validated on
construction; a bad value raises :class:`~rodnet.errors.SceneError` naming the key, the value
and what is allowed. Mass properties take the mass; for a scene that gives a density, the mass
is ``density * shape.mass_properties(1.0).volume``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple, Protocol

import numpy as np
from numpy.typing import NDArray

from rodnet.errors import SceneError

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

_EYE = np.eye(3)


class SurfaceQuery(NamedTuple):
    """Closest-point data of ``P`` query points, all in one frame."""

    distance: FloatArray
    """(P,) signed distance [m], negative inside."""
    normal: FloatArray
    """(P, 3) outward unit normal at the closest point (the gradient of ``distance``)."""
    closest: FloatArray
    """(P, 3) closest surface point [m]."""
    normal_gradient: FloatArray
    """(P, 3, 3) ``dn/dx`` [1/m], symmetric: ``normal_gradient[p] @ dx`` is the change of the normal."""


@dataclass(frozen=True, slots=True)
class MassProperties:
    """A homogeneous rigid body: ``inertia`` is about the centre of mass, in body axes."""

    mass: float
    """kg"""
    volume: float
    """m^3"""
    center_of_mass: FloatArray
    """(3,) m, in the shape's frame (zero for the primitives and for a centred mesh)"""
    inertia: FloatArray
    """(3, 3) kg m^2"""


class Shape(Protocol):
    """What contact needs from a rigid body's geometry."""

    @property
    def bounds(self) -> FloatArray:
        """(2, 3) lower and upper corner of the body-frame bounding box [m]."""
        ...

    def query(self, points: FloatArray) -> SurfaceQuery:
        """Closest-point data of body-frame ``points`` (P, 3)."""
        ...

    def mass_properties(self, mass: float) -> MassProperties:
        """Volume, centre of mass and inertia of the shape filled homogeneously with ``mass``."""
        ...


def _positive(key: str, value: float, unit: str) -> None:
    if not (np.isfinite(value) and value > 0.0):
        raise SceneError(key, value, f"must be a finite number > 0 [{unit}]")


def positive_length(key: str, value: float) -> None:
    """Raise :class:`SceneError` for ``key`` unless ``value`` is a finite length > 0 [m]."""
    _positive(key, value, "m")


def as_points(points: FloatArray) -> FloatArray:
    """Query points as a (P, 3) float64 array."""
    return np.asarray(points, dtype=np.float64).reshape(-1, 3)


def _outer(a: FloatArray, b: FloatArray) -> FloatArray:
    return a[:, :, None] * b[:, None, :]


def _exterior(diff: FloatArray, diff_gradient: FloatArray,
              ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Distance, normal and ``dn/dx`` from ``x - c`` (nonzero) and ``d(x - c)/dx``, (G3)."""
    distance = np.linalg.norm(diff, axis=1)
    normal = diff / distance[:, None]
    gradient = (_EYE - _outer(normal, normal)) @ diff_gradient / distance[:, None, None]
    return distance, normal, gradient


def check_mass(mass: float) -> float:
    """``mass`` as a float, or :class:`SceneError` unless finite and > 0."""
    _positive("mass", mass, "kg")
    return float(mass)


@dataclass(frozen=True, slots=True)
class Box:
    """Rectangular box centred at the origin, edges along the body axes.

    Outside, the closest feature is a face, an edge or a corner and the normal turns continuously
    around edges and corners (G4). Inside, the nearest face wins (G5): on the medial surfaces
    (``|x_i| - h_i = |x_j| - h_j``) the distance is continuous but the normal jumps from one face
    normal to the other; ties go to the lower axis index.

    Parameters
    ----------
    half_extents : (3,) float
        Half edge lengths [m].
    """

    half_extents: tuple[float, float, float]

    def __post_init__(self) -> None:
        h = tuple(float(v) for v in self.half_extents)
        if len(h) != 3:
            raise SceneError("half_extents", self.half_extents, "must be three lengths [m]")
        for v in h:
            _positive("half_extents", v, "m")
        object.__setattr__(self, "half_extents", h)

    @property
    def bounds(self) -> FloatArray:
        h = np.array(self.half_extents)
        return np.stack([-h, h])

    def query(self, points: FloatArray) -> SurfaceQuery:
        """(G4)-(G5) for ``points`` (P, 3) in the body frame."""
        x, h = as_points(points), np.array(self.half_extents)
        rows = np.arange(x.shape[0])
        excess = np.abs(x) - h
        axis = np.argmax(excess, axis=1)
        distance = excess[rows, axis]
        normal = np.zeros_like(x)
        normal[rows, axis] = np.where(x[rows, axis] < 0.0, -1.0, 1.0)
        gradient = np.zeros((x.shape[0], 3, 3))
        out = distance > 0.0
        if out.any():
            clamped_axes = excess[out] > 0.0
            diff = x[out] - np.clip(x[out], -h, h)
            distance[out], normal[out], gradient[out] = _exterior(
                diff, clamped_axes[:, :, None] * _EYE)
        closest = x - distance[:, None] * normal
        return SurfaceQuery(distance, normal, closest, gradient)

    def mass_properties(self, mass: float) -> MassProperties:
        """(G11): ``I_xx = m (h_y^2 + h_z^2) / 3`` and cyclic."""
        m, h2 = check_mass(mass), np.array(self.half_extents) ** 2
        inertia = m / 3.0 * np.diag([h2[1] + h2[2], h2[0] + h2[2], h2[0] + h2[1]])
        return MassProperties(m, 8.0 * float(np.prod(self.half_extents)), np.zeros(3), inertia)


@dataclass(frozen=True, slots=True)
class Cylinder:
    """Solid circular cylinder centred at the origin, its axis along body axis ``axis``.

    Outside, the closest feature is the side, a cap or a rim circle (G6). Inside, the nearer of
    side and cap wins (G7): on the medial cone ``R - rho = L/2 - |z|`` the normal jumps (ties go
    to the side); on the axis (``rho = 0``, reached only where the side is nearer than the caps)
    the radial direction is undefined and the side normal is taken along the next body axis.

    Parameters
    ----------
    radius, length : float
        [m]; ``length`` is the full length along the axis.
    axis : int
        0, 1 or 2 (x, y, z).
    """

    radius: float
    length: float
    axis: int = 2

    def __post_init__(self) -> None:
        _positive("radius", self.radius, "m")
        _positive("length", self.length, "m")
        if self.axis not in (0, 1, 2):
            raise SceneError("axis", self.axis, "must be 0, 1 or 2 (x, y, z)")

    @property
    def bounds(self) -> FloatArray:
        h = np.full(3, float(self.radius))
        h[self.axis] = 0.5 * self.length
        return np.stack([-h, h])

    def query(self, points: FloatArray) -> SurfaceQuery:
        """(G6)-(G7) for ``points`` (P, 3) in the body frame."""
        x = as_points(points)
        e_z = _EYE[self.axis]
        z = x[:, self.axis]
        radial = x - z[:, None] * e_z
        rho = np.linalg.norm(radial, axis=1)
        on_axis = rho <= 1e-12 * self.radius
        rho_safe = np.where(on_axis, 1.0, rho)
        e_r = np.where(on_axis[:, None], _EYE[(self.axis + 1) % 3], radial / rho_safe[:, None])
        e_t = np.cross(e_z, e_r)
        side, cap = rho - self.radius, np.abs(z) - 0.5 * self.length
        s = np.where(z < 0.0, -1.0, 1.0)
        side_wins = side >= cap
        distance = np.where(side_wins, side, cap)
        normal = np.where(side_wins[:, None], e_r, s[:, None] * e_z)
        # inside the side's normal turns with the angle around the axis; a cap's does not
        gradient = np.where(side_wins[:, None, None], _outer(e_t, e_t) / rho_safe[:, None, None], 0.0)
        out = (side > 0.0) | (cap > 0.0)
        if out.any():
            a, b = np.maximum(side[out], 0.0), np.maximum(cap[out], 0.0)
            diff = a[:, None] * e_r[out] + (b * s[out])[:, None] * e_z
            diff_gradient = ((side[out] > 0.0)[:, None, None] * _outer(e_r[out], e_r[out])
                             + (cap[out] > 0.0)[:, None, None] * np.outer(e_z, e_z)
                             + (a / rho_safe[out])[:, None, None] * _outer(e_t[out], e_t[out]))
            distance[out], normal[out], gradient[out] = _exterior(diff, diff_gradient)
        closest = x - distance[:, None] * normal
        return SurfaceQuery(distance, normal, closest, gradient)

    def mass_properties(self, mass: float) -> MassProperties:
        """(G11): ``m R^2 / 2`` about the axis, ``m (3 R^2 + L^2) / 12`` across it."""
        m, r2, l2 = check_mass(mass), self.radius**2, self.length**2
        inertia = np.full(3, m * (3.0 * r2 + l2) / 12.0)
        inertia[self.axis] = 0.5 * m * r2
        return MassProperties(m, np.pi * r2 * self.length, np.zeros(3), np.diag(inertia))


@dataclass(frozen=True, slots=True)
class Sphere:
    """Solid sphere centred at the origin, (G8); at the centre itself the normal is taken as +z.

    Parameters
    ----------
    radius : float
        [m]
    """

    radius: float

    def __post_init__(self) -> None:
        _positive("radius", self.radius, "m")

    @property
    def bounds(self) -> FloatArray:
        return np.stack([np.full(3, -self.radius), np.full(3, float(self.radius))])

    def query(self, points: FloatArray) -> SurfaceQuery:
        """(G8) for ``points`` (P, 3) in the body frame."""
        x = as_points(points)
        rho = np.linalg.norm(x, axis=1)
        centre = rho <= 1e-12 * self.radius
        rho_safe = np.where(centre, 1.0, rho)
        normal = np.where(centre[:, None], _EYE[2], x / rho_safe[:, None])
        gradient = (_EYE - _outer(normal, normal)) / rho_safe[:, None, None]
        return SurfaceQuery(rho - self.radius, normal, self.radius * normal, gradient)

    def mass_properties(self, mass: float) -> MassProperties:
        """(G11): ``2 m R^2 / 5``."""
        m = check_mass(mass)
        return MassProperties(m, 4.0 / 3.0 * np.pi * self.radius**3, np.zeros(3),
                              0.4 * m * self.radius**2 * _EYE)


def query_world(shape: Shape, points: FloatArray, position: FloatArray, rotation: FloatArray,
                ) -> SurfaceQuery:
    """:meth:`Shape.query` for world-frame ``points`` (P, 3), with every result in world frame.

    Parameters
    ----------
    position : (3,) float
        World position of the body-frame origin (the centre of mass) [m].
    rotation : (3, 3) float
        Body-to-world rotation: ``x_world = position + rotation @ x_body``.
    """
    rotation = np.asarray(rotation, dtype=np.float64)
    # einsum rather than ``@``: a threaded BLAS call for a (P, 3) x (3, 3) product can cost more
    # than the whole query
    local = np.einsum("pi,ij->pj", as_points(points) - position, rotation)
    q = shape.query(local)
    gradient = np.einsum("ij,pjk->pik", rotation, q.normal_gradient)
    return SurfaceQuery(q.distance, np.einsum("ij,pj->pi", rotation, q.normal),
                        np.einsum("ij,pj->pi", rotation, q.closest) + position,
                        np.einsum("pij,kj->pik", gradient, rotation))
