"""Penalty contact laws of a thread point against a rigid body, vectorised over contact points.

Normal: a penalty force on the penetration ``delta = r - d`` (thread radius minus signed distance
of the centreline point), smoothed C1 around ``delta = 0`` so that its linear branch passes
through the origin, with damping that fades in with the contact and a total that never pulls,
(N1)-(N5). Friction: regularised Coulomb, either velocity-regularised (no history; the
"stick" is a creep at a velocity of order ``slip_velocity``), (F1)-(F4), or an elastic stick
spring with a return mapping onto the Coulomb cone (true stick; needs an anchor point carried
from step to step), (F5)-(F8). :func:`contact_force` combines them with the geometry into the
force on each point and its derivatives with respect to the point's position and velocity,
(K1)-(K4). Equations: ``elements/contact/FORMULATION.md``.

Sign convention: every force is the force *on the thread point*, exerted by the body; the body
receives the opposite force at the same point.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from rodnet.contact.geometry import FloatArray, SurfaceQuery
from rodnet.errors import SceneError

_EYE = np.eye(3)


@dataclass(frozen=True, slots=True, kw_only=True)
class ContactLaw:
    """Parameters of the penalty contact of a thread with a body (``[contact]``).

    Parameters
    ----------
    stiffness : float
        Penalty stiffness k [N/m] per contact point.
    damping : float
        c [N s/m], acting only in contact, (N3).
    friction : float
        Coulomb coefficient mu >= 0.
    smoothing : float
        s [m]: the normal law is quadratic for ``|delta| < s`` and starts at a gap of ``s``, (N1).
        0 gives the sharp ``max(k delta, 0)``. About a tenth of the admissible penetration.
    slip_velocity : float
        eps_v [m/s] of the velocity-regularised friction law, (F2): the velocity at which
        friction reaches 71 % of mu N. Well below the sliding speeds of interest.
    tangential_stiffness : float or None
        k_T [N/m] of the elastic stick law, (F5); ``None`` means equal to ``stiffness``.
    """

    stiffness: float
    damping: float = 0.0
    friction: float = 0.0
    smoothing: float = 0.0
    slip_velocity: float = 1.0e-3
    tangential_stiffness: float | None = None

    def __post_init__(self) -> None:
        for key in ("stiffness", "slip_velocity", "tangential_stiffness"):
            value = getattr(self, key)
            if value is not None and not (math.isfinite(value) and value > 0.0):
                raise SceneError(key, value, "must be a finite number > 0")
        for key in ("damping", "friction", "smoothing"):
            value = getattr(self, key)
            if not (math.isfinite(value) and value >= 0.0):
                raise SceneError(key, value, "must be a finite number >= 0")

    @property
    def spring_stiffness(self) -> float:
        """k_T [N/m] of the elastic stick law."""
        return self.stiffness if self.tangential_stiffness is None else self.tangential_stiffness


class NormalForce(NamedTuple):
    """(N3) and (N5) for P points."""

    force: FloatArray
    """(P,) N >= 0 [N]."""
    d_penetration: FloatArray
    """(P,) dN/d delta [N/m]."""
    d_rate: FloatArray
    """(P,) dN/d delta_dot [N s/m]."""


class FrictionForce(NamedTuple):
    """(F2)-(F3) or (F6)-(F8) for P points."""

    force: FloatArray
    """(P, 3) tangential force on the thread point [N]."""
    d_tangential: FloatArray
    """(P, 3, 3) derivative with respect to the tangential slip velocity (F3) or slip (F7)."""
    d_normal: FloatArray
    """(P, 3) derivative with respect to the normal force N [1]."""
    sticking: FloatArray
    """(P,) bool: within the Coulomb cone (elastic law), or slower than eps_v (regularised)."""
    anchor: FloatArray | None
    """(P, 3) anchor after return mapping (elastic law only), (F8)."""


class PointForces(NamedTuple):
    """(K1)-(K4): force on each contact point and its derivatives, world frame."""

    force: FloatArray
    """(P, 3) [N]."""
    d_position: FloatArray
    """(P, 3, 3) df/dx [N/m] with the body held fixed."""
    d_velocity: FloatArray
    """(P, 3, 3) df/dv [N s/m]."""
    normal_force: FloatArray
    """(P,) N [N]; a point is in contact where it is > 0."""
    sticking: FloatArray
    """(P,) bool, see :class:`FrictionForce`."""
    anchor: FloatArray | None
    """(P, 3) updated anchors of the elastic friction law, else None."""


def smoothed_ramp(penetration: FloatArray, smoothing: float,
                  ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The C1 ramp rho(delta) standing in for ``max(delta, 0)``, and its two derivatives, (N1)-(N2).

    Parameters
    ----------
    penetration : (P,) float
        delta [m]; any value, including -inf.
    smoothing : float
        s [m] >= 0.

    Returns
    -------
    rho [m], rho' [1], rho'' [1/m] : (P,) float
    """
    delta = np.asarray(penetration, dtype=np.float64)
    if smoothing == 0.0:
        inside = delta > 0.0
        return np.where(inside, delta, 0.0), inside.astype(float), np.zeros_like(delta)
    s = smoothing
    t = np.clip(delta, -s, s) + s  # 0 .. 2s across the blend
    blend = delta < s
    rho = np.where(blend, t * t / (4.0 * s), delta)
    slope = np.where(blend, t / (2.0 * s), 1.0)
    curvature = np.where(blend & (delta > -s), 1.0 / (2.0 * s), 0.0)
    return rho, slope, curvature


def normal_energy(penetration: FloatArray, stiffness: float, smoothing: float) -> FloatArray:
    """Stored penalty energy U(delta) [J] of the elastic part of (N3), (N4)."""
    delta = np.asarray(penetration, dtype=np.float64)
    s = smoothing
    if s == 0.0:
        return 0.5 * stiffness * np.maximum(delta, 0.0) ** 2
    t = np.clip(delta, -s, s) + s
    return stiffness * np.where(delta < s, t**3 / (12.0 * s), 0.5 * delta**2 + s * s / 6.0)


def normal_force(penetration: FloatArray, penetration_rate: FloatArray, stiffness: float,
                 damping: float, smoothing: float) -> NormalForce:
    """Penalty normal force with contact damping, never pulling, (N3) and its partials (N5).

    ``N = max(0, k rho(delta) + c rho'(delta) delta_dot)``.

    Parameters
    ----------
    penetration : (P,) float
        delta = r - d [m].
    penetration_rate : (P,) float
        d delta/dt = -n . v_rel [m/s].
    stiffness, damping, smoothing : float
        k [N/m], c [N s/m], s [m].
    """
    rate = np.asarray(penetration_rate, dtype=np.float64)
    rho, slope, curvature = smoothed_ramp(penetration, smoothing)
    total = stiffness * rho + damping * slope * rate
    pushing = total > 0.0
    return NormalForce(np.where(pushing, total, 0.0),
                       np.where(pushing, stiffness * slope + damping * curvature * rate, 0.0),
                       np.where(pushing, damping * slope, 0.0))


def regularized_friction(slip_velocity: FloatArray, normal: FloatArray, friction: float,
                         regularization: float) -> FrictionForce:
    """Velocity-regularised Coulomb friction, (F2), with its derivatives (F3).

    ``f_T = -mu N v_T / sqrt(|v_T|^2 + eps_v^2)``: at most mu N, opposing the slip.

    Parameters
    ----------
    slip_velocity : (P, 3) float
        Tangential relative velocity v_T [m/s] of the thread point, (F1).
    normal : (P,) float
        Normal force N [N].
    friction, regularization : float
        mu [1] and eps_v [m/s].
    """
    v = np.asarray(slip_velocity, dtype=np.float64).reshape(-1, 3)
    scale = np.sqrt(np.einsum("pi,pi->p", v, v) + regularization**2)
    phi = v / scale[:, None]
    d_phi = (_EYE - phi[:, :, None] * phi[:, None, :]) / scale[:, None, None]
    mu_n = friction * np.asarray(normal, dtype=np.float64)
    return FrictionForce(-mu_n[:, None] * phi, -mu_n[:, None, None] * d_phi, -friction * phi,
                         scale < math.sqrt(2.0) * regularization, None)


def elastic_friction(slip: FloatArray, normal: FloatArray, friction: float,
                     tangential_stiffness: float, position: FloatArray) -> FrictionForce:
    """Elastic stick spring with return mapping onto the Coulomb cone, (F5)-(F8).

    Trial ``t = -k_T g_T``; stick if ``|t| <= mu N``, else slip with ``f_T = mu N t/|t|``.

    Parameters
    ----------
    slip : (P, 3) float
        g_T = (I - n n)(x - a) [m], the tangential distance of the point from its anchor, (F5).
    normal : (P,) float
        N [N].
    friction, tangential_stiffness : float
        mu [1], k_T [N/m].
    position : (P, 3) float
        x [m], for the updated anchor (F8).
    """
    g = np.asarray(slip, dtype=np.float64).reshape(-1, 3)
    n_force = np.asarray(normal, dtype=np.float64)
    length = np.linalg.norm(g, axis=1)
    limit = friction * n_force
    stick = tangential_stiffness * length <= limit
    safe = np.where(length > 0.0, length, 1.0)
    direction = g / safe[:, None]
    slide = -limit[:, None] * direction
    force = np.where(stick[:, None], -tangential_stiffness * g, slide)
    d_slide = -(limit / safe)[:, None, None] * (_EYE - direction[:, :, None] * direction[:, None, :])
    d_slip = np.where(stick[:, None, None], -tangential_stiffness * _EYE, d_slide)
    d_normal = np.where(stick[:, None], 0.0, -friction * direction)
    anchor = np.where(stick[:, None], np.asarray(position) - g,
                      np.asarray(position) + slide / tangential_stiffness)
    return FrictionForce(force, d_slip, d_normal, stick, anchor)


def _projected_derivative(normal: FloatArray, gradient: FloatArray, w: FloatArray) -> FloatArray:
    """d[(I - n n) w]/dx at fixed w: ``-(n (H w)^T + (n . w) H)``, (K3)."""
    hw = np.einsum("pij,pj->pi", gradient, w)
    nw = np.einsum("pi,pi->p", normal, w)
    return -(normal[:, :, None] * hw[:, None, :] + nw[:, None, None] * gradient)


def contact_force(query: SurfaceQuery, velocity: FloatArray, radius: FloatArray | float,
                  law: ContactLaw, anchor: FloatArray | None = None,
                  lagged_normal_force: FloatArray | None = None) -> PointForces:
    """Force of a body on thread points and its derivatives, (K1)-(K4).

    Parameters
    ----------
    query : SurfaceQuery
        Signed distance, normal, closest point and ``dn/dx`` of the points (world frame, see
        :func:`~rodnet.contact.geometry.query_world`).
    velocity : (P, 3) float
        Velocity of each thread point relative to the body's material point at the same place
        [m/s] (for a fixed body, the point's velocity).
    radius : float or (P,) float
        Thread radius r [m]: the point touches the body when ``d = r``.
    law : ContactLaw
    anchor : (P, 3) float or None
        None: velocity-regularised friction (F2). Else the world position of each point's stick
        anchor, and the elastic law (F5)-(F8) is used; the returned ``anchor`` is the updated
        one, to be kept when the step is accepted (at a new contact, pass the point itself).
    lagged_normal_force : (P,) float or None
        If given, friction uses this N (e.g. from the previous iteration or step) and its
        dependence on N is left out of the derivatives (K4).
    """
    d, n, H = query.distance, query.normal, query.normal_gradient
    v = np.asarray(velocity, dtype=np.float64).reshape(-1, 3)
    delta = radius - d
    rate = -np.einsum("pi,pi->p", n, v)
    normal = normal_force(delta, rate, law.stiffness, law.damping, law.smoothing)
    # (K1): dN/dx, dN/dv from d delta/dx = -n, d delta_dot/dx = -H v, d delta_dot/dv = -n
    dN_dx = -normal.d_penetration[:, None] * n - normal.d_rate[:, None] * np.einsum("pij,pj->pi", H, v)
    dN_dv = -normal.d_rate[:, None] * n
    N = normal.force
    projector = _EYE - n[:, :, None] * n[:, None, :]
    if anchor is None:
        w = v
        dw_dx, dw_dv = _projected_derivative(n, H, v), projector
    else:
        # unresolved far points (d = inf, n = 0) carry their own position as closest point
        x = query.closest + np.where(np.isfinite(d), d, 0.0)[:, None] * n
        w = x - np.asarray(anchor, dtype=np.float64)
        dw_dx, dw_dv = projector + _projected_derivative(n, H, w), np.zeros_like(projector)
    tangential = np.einsum("pij,pj->pi", projector, w)
    friction_n = N if lagged_normal_force is None else np.asarray(lagged_normal_force, dtype=np.float64)
    if anchor is None:
        fr = regularized_friction(tangential, friction_n, law.friction, law.slip_velocity)
    else:
        fr = elastic_friction(tangential, friction_n, law.friction, law.spring_stiffness, x)
    # (K2): f = N n + f_T
    force = N[:, None] * n + fr.force
    d_x = n[:, :, None] * dN_dx[:, None, :] + N[:, None, None] * H + fr.d_tangential @ dw_dx
    d_v = n[:, :, None] * dN_dv[:, None, :] + fr.d_tangential @ dw_dv
    if lagged_normal_force is None:
        d_x += fr.d_normal[:, :, None] * dN_dx[:, None, :]
        d_v += fr.d_normal[:, :, None] * dN_dv[:, None, :]
    return PointForces(force, d_x, d_v, N, fr.sticking, fr.anchor)
