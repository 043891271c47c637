"""A point mass against fixed boxes, integrated in the test: rest depth under the normal law and
stick/slip on an inclined plane (elements/contact/FORMULATION.md (N3), (F2)-(F8))."""

from __future__ import annotations

import numpy as np
import pytest

from rodnet.contact.geometry import Box, query_world
from rodnet.contact.laws import ContactLaw, contact_force

G = 9.81
MASS = 1.0
RADIUS = 0.01


def test_dropped_point_mass_comes_to_rest_at_depth_mg_over_k_backward_euler() -> None:
    """Backward Euler with Newton on the analytic tangents (K4): few iterations per step."""
    law = ContactLaw(stiffness=1.0e4, damping=60.0, smoothing=1e-5)
    box, position, rotation = Box((1.0, 1.0, 0.5)), np.zeros(3), np.eye(3)
    gravity = np.array([0.0, 0.0, -G])
    x, v = np.array([[0.1, -0.2, 0.5 + RADIUS + 0.05]]), np.zeros((1, 3))
    dt, most_iterations = 1e-3, 0
    for _ in range(1500):
        v_new = v.copy()
        for iteration in range(1, 20):
            x_new = x + dt * v_new
            pf = contact_force(query_world(box, x_new, position, rotation), v_new, RADIUS, law)
            residual = MASS * (v_new - v) - dt * (pf.force + MASS * gravity)
            if np.abs(residual).max() < 1e-10 * MASS * G * dt:
                break
            jacobian = MASS * np.eye(3) - dt * (dt * pf.d_position[0] + pf.d_velocity[0])
            v_new = v_new - np.linalg.solve(jacobian, residual[0])
        most_iterations = max(most_iterations, iteration)
        x, v = x + dt * v_new, v_new
    depth = RADIUS - box.query(x).distance[0]
    assert depth == pytest.approx(MASS * G / law.stiffness, rel=0.01)
    assert np.abs(v).max() < 1e-6
    assert most_iterations <= 6


def test_dropped_point_mass_rest_depth_explicit() -> None:
    law = ContactLaw(stiffness=1.0e4, damping=60.0, smoothing=1e-5)
    box = Box((1.0, 1.0, 0.5))
    x, v = np.array([[0.0, 0.0, 0.5 + RADIUS + 0.02]]), np.zeros((1, 3))
    dt = 2e-4
    for _ in range(5000):
        pf = contact_force(box.query(x), v, RADIUS, law)
        v = v + dt * (pf.force / MASS + np.array([0.0, 0.0, -G]))
        x = x + dt * v
    assert RADIUS - box.query(x).distance[0] == pytest.approx(MASS * G / law.stiffness, rel=0.01)


class Incline:
    """A point mass on the top face of a box tilted by ``angle`` about the body y axis."""

    def __init__(self, angle: float, law: ContactLaw) -> None:
        c, s = np.cos(angle), np.sin(angle)
        self.rotation = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
        self.position = np.array([0.0, 0.0, -1.0])
        self.box, self.law, self.angle = Box((20.0, 5.0, 1.0)), law, angle
        self.normal = self.rotation[:, 2]
        gravity_t = np.array([0.0, 0.0, -G]) - (-G * self.normal[2]) * self.normal
        self.downhill = gravity_t / np.linalg.norm(gravity_t)
        depth = MASS * G * np.cos(angle) / law.stiffness
        self.start = self.position + self.normal * (1.0 + RADIUS - depth)

    def run(self, duration: float, velocity: float = 0.0, elastic: bool = False, dt: float = 2e-4):
        """Semi-implicit Euler; returns times, downhill positions and velocities, sticking flags."""
        x = self.start[None, :].copy()
        v = velocity * self.downhill[None, :]
        anchor = None
        if elastic:
            # a block already sliding has its stick spring at the Coulomb limit (F8)
            stretch = self.law.friction * MASS * G * np.cos(self.angle) / self.law.spring_stiffness
            anchor = x - (stretch if velocity else 0.0) * self.downhill
        n = int(round(duration / dt))
        s, u, stick = np.empty(n), np.empty(n), np.empty(n, bool)
        for i in range(n):
            q = query_world(self.box, x, self.position, self.rotation)
            pf = contact_force(q, v, RADIUS, self.law, anchor=anchor)
            anchor = pf.anchor
            v = v + dt * (pf.force / MASS + np.array([0.0, 0.0, -G]))
            x = x + dt * v
            s[i], u[i], stick[i] = (x[0] - self.start) @ self.downhill, v[0] @ self.downhill, pf.sticking[0]
        return dt * np.arange(1, n + 1), s, u, stick


MU = 0.3


@pytest.mark.parametrize("elastic", [False, True], ids=["regularized", "elastic"])
def test_block_slides_with_acceleration_g_sin_minus_mu_cos_above_the_friction_angle(elastic: bool) -> None:
    angle = np.arctan(1.5 * MU)
    law = ContactLaw(stiffness=1e5, damping=300.0, friction=MU, smoothing=1e-6,
                     slip_velocity=1e-3, tangential_stiffness=1e4)
    t, s, u, stick = Incline(angle, law).run(0.5, elastic=elastic)
    i1, i2 = np.searchsorted(t, 0.2), np.searchsorted(t, 0.5) - 1
    measured = (u[i2] - u[i1]) / (t[i2] - t[i1])
    assert measured == pytest.approx(G * (np.sin(angle) - MU * np.cos(angle)), rel=0.01)
    assert not stick[i1:].any()


def test_block_below_the_friction_angle_stops_and_sticks_elastic_law() -> None:
    angle, v0 = np.arctan(0.8 * MU), 0.3
    law = ContactLaw(stiffness=1e5, damping=300.0, friction=MU, smoothing=1e-6, tangential_stiffness=1e4)
    t, s, u, stick = Incline(angle, law).run(0.8, velocity=v0, elastic=True)
    deceleration = G * (MU * np.cos(angle) - np.sin(angle))
    stop = v0**2 / (2 * deceleration)
    # the stick spring stretches by at most mu N / k_T beyond the stopping point
    spring = MU * MASS * G * np.cos(angle) / law.spring_stiffness
    assert s[-1] == pytest.approx(stop, abs=0.01 * stop + spring)
    stopped = t > 0.65
    # the undamped stick spring swings between 0.6 and 1.0 mu N: its peaks just touch the cone
    assert stick[stopped].mean() > 0.99
    assert np.ptp(s[stopped]) <= 2 * spring


def test_block_below_the_friction_angle_creeps_at_the_regularisation_velocity() -> None:
    """(F4): with velocity-regularised friction, 'stick' is a creep of order eps_v."""
    angle, eps = np.arctan(0.8 * MU), 1e-3
    law = ContactLaw(stiffness=1e5, damping=300.0, friction=MU, smoothing=1e-6, slip_velocity=eps)
    t, s, u, stick = Incline(angle, law).run(0.8, velocity=0.3)
    ratio = np.tan(angle) / MU
    assert u[-1] == pytest.approx(eps * ratio / np.sqrt(1 - ratio**2), rel=0.01)
    stop = 0.3**2 / (2 * G * (MU * np.cos(angle) - np.sin(angle)))
    assert s[-1] == pytest.approx(stop, rel=0.03)
