"""A new thread model added in one file and one registry entry: a chain of linear springs.

The whole model is :class:`SpringChain` and :func:`build_spring_chain` below, registered as
``model.type = "springchain"``; nothing else in rodnet is touched. It runs through the public
scene format and ``rodnet.run`` with the explicit and the implicit integrators, with a fixed and
a free rigid body, because integrators, contact and output see only the system."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np
import pytest

from rodnet.kernels import explicit as kx
from rodnet.kernels.cosserat_compiled import no_rod_elements
from rodnet.kernels.schedule import schedule_of
from rodnet.kernels.hinge import no_hinges
from rodnet.kernels.segments import Segments
from rodnet.models import registry
from rodnet.run import prepare, run
from rodnet.scene import scene_from_toml
from rodnet.state import Configuration


@dataclass(frozen=True)
class SpringChain:
    """Point masses joined by linear springs ``k = EA / l0`` (no damping), pins held."""

    structure: object
    node_mass: np.ndarray
    k: np.ndarray
    pinned: np.ndarray
    gravity: np.ndarray
    n_rot = 0

    @property
    def n_nodes(self) -> int:
        return len(self.node_mass)

    @property
    def n_dof(self) -> int:
        return 3 * self.n_nodes

    @cached_property
    def free(self) -> np.ndarray:
        return np.repeat(~self.pinned, 3)

    @cached_property
    def dof_mass(self) -> np.ndarray:
        return np.repeat(self.node_mass, 3)

    @property
    def force_scale(self) -> float:
        return float((self.k * self.structure.rest_length).max())

    @property
    def length_scale(self) -> float:
        return self.structure.size

    @cached_property
    def groups(self) -> list[np.ndarray]:
        return [(3 * self.structure.segments[:, :, None] + np.arange(3)).reshape(-1, 6)]

    def forces(self, q, v, t, load_factor, need_matrices):
        a, b = self.structure.segments.T
        d = q.x[b] - q.x[a]
        length = np.linalg.norm(d, axis=1)
        u = d / length[:, None]
        n = self.k * (length - self.structure.rest_length)
        f = np.zeros_like(q.x)
        np.add.at(f, a, n[:, None] * u)
        np.add.at(f, b, -n[:, None] * u)
        g = -(f + load_factor * self.node_mass[:, None] * self.gravity).ravel()
        if not need_matrices:
            return g, [], []
        uu = np.einsum("si,sj->sij", u, u)
        Kab = self.k[:, None, None] * uu + (n / length)[:, None, None] * (np.eye(3) - uu)
        K = np.zeros((len(n), 6, 6))
        K[:, :3, :3] = K[:, 3:, 3:] = Kab
        K[:, :3, 3:] = K[:, 3:, :3] = -Kab
        return g, [K], [np.zeros_like(K)]

    def retract(self, q, dq):
        return Configuration(q.x + dq.reshape(-1, 3), q.quat)

    def active_set(self, q, v) -> bytes:
        return b""

    def rotation_dofs(self) -> np.ndarray:
        return np.zeros(0, np.int64)

    def explicit_terms(self):
        s, n = self.structure, self.n_nodes
        inv_mass = np.where(self.pinned[:, None], 0.0, 1.0 / self.node_mass[:, None]) * np.ones(3)
        springs = Segments(s.segments, s.rest_length, self.k * s.rest_length,
                           np.zeros(len(self.k)), 0.0, False)
        return (kx.Nodes(inv_mass, self.node_mass[:, None] * self.gravity),
                kx.Rotations(np.zeros((0, 3)), np.zeros((0, 3))),
                kx.Loads(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3)),
                         np.zeros((0, 3)), schedule_of([])),
                springs, no_hinges(), no_rod_elements())

    def frame_arrays(self, q, v):
        a, b = self.structure.segments.T
        length = np.linalg.norm(q.x[b] - q.x[a], axis=1)
        return {"positions": q.x.copy(), "velocities": v.reshape(-1, 3).copy(),
                "tension": self.k * (length - self.structure.rest_length)}

    def axial_force(self, q, v):
        return self.frame_arrays(q, v)["tension"]

    def energy(self, q, v, t):
        a, b = self.structure.segments.T
        stretch = np.linalg.norm(q.x[b] - q.x[a], axis=1) - self.structure.rest_length
        kinetic = 0.5 * float(self.dof_mass @ (v * v))
        return {"kinetic": kinetic, "elastic": 0.5 * float(self.k @ stretch**2),
                "potential": -float((self.node_mass[:, None] * self.gravity * q.x).sum())}

    def check_frame(self, t, frame) -> None:
        pass


def build_spring_chain(scene, structure):
    """The chain of a scene's ``[[rods]]``: half of each segment's mass at each end."""
    material = scene.materials[0]
    mass = structure.point_mass.copy()
    for end in (0, 1):
        np.add.at(mass, structure.segments[:, end], 0.5 * material.rhoA * structure.rest_length)
    pinned = np.zeros(structure.n_nodes, bool)
    for i, s in enumerate(scene.supports):
        pinned[structure.node(s.node, f"supports[{i}].node")] = True
    model = SpringChain(structure, mass, material.EA / structure.rest_length, pinned,
                        np.asarray(scene.simulation.gravity, float))
    v0 = structure.velocities.copy()
    v0[pinned] = 0.0
    return model, Configuration(structure.positions.copy()), v0.ravel()


def spring_chain_plan(model, v0, dt, adaptive, safety, scale_rotary_inertia=False):
    """Fixed explicit steps below the chain's limit ``2 / sqrt(4 k / m)``."""
    limit = float(np.min(2.0 / np.sqrt(4.0 * model.k / model.node_mass[1:-1].min())))
    step = safety * limit if adaptive else dt
    return model, v0, kx.StepControl(step, step, 0.0, False, np.zeros(1), np.ones(1), limit)


ENTRY = registry.ModelType(
    "spring chains", build_spring_chain, spring_chain_plan,
    registry.Supports(("explicit", "backward-euler", "generalized-alpha"), True,
                      ("explicit", "backward-euler", "generalized-alpha"), ("explicit",)))


@pytest.fixture
def spring_chain():
    registry.register("springchain", ENTRY)
    yield
    from rodnet import config

    registry.MODELS.pop("springchain")
    registry.TYPES.pop("springchain")
    config.MODEL_TYPES.pop("springchain")


PINS = """
[[supports]]
node = "r:start"
fix = "pin"
[[supports]]
node = "r:end"
fix = "pin"
"""
CHAIN = """
[simulation]
duration = 0.3
integrator = "{integrator}"
dt = 1.0e-4
adaptive = false
gravity = [0.0, 0.0, -9.81]
[model]
type = "springchain"
[[materials]]
name = "cord"
density = 1000.0
youngs_modulus = 1.0e9
diameter = 2.0e-3
mass_per_length = 0.01
axial_stiffness = 200.0
[[rods]]
name = "r"
material = "cord"
points = [[-0.5, 0.0, 1.0], [0.5, 0.0, 1.0]]
elements = 10
{supports}
[output]
frame_interval = 0.01
vtk = false
"""

BALL = """
[[bodies]]
name = "ball"
shape = "sphere"
size = [0.3, 0.3, 0.3]
position = [0.0, 0.0, {z}]
{kind}
[contact]
stiffness = 1.0e4
damping = 0.0
friction = 0.0
"""


def test_the_chain_runs_explicit_and_implicit_and_both_agree(spring_chain, tmp_path: Path) -> None:
    """Released straight, the chain falls and rings; backward Euler at the explicit step damps
    little over 0.3 s, so the middle node's paths agree; the explicit energy is conserved."""
    paths = {}
    for integrator in ("explicit", "backward-euler"):
        r = run(scene_from_toml(CHAIN.format(integrator=integrator, supports=PINS)), tmp_path / integrator,
                progress=False)
        assert r.status == "ok", r.message
        paths[integrator] = r.arrays["positions"][:, 5, 2]
        if integrator == "explicit":
            p = prepare(scene_from_toml(CHAIN.format(integrator=integrator, supports=PINS)))
            energy = np.array([sum(p.system.energy(t, _state(x, v)).values()) for t, x, v in zip(
                r.arrays["time"], r.arrays["positions"], r.arrays["velocities"])])
            assert np.ptp(energy) < 1e-2 * r.arrays["kinetic_energy"].max()
    fall = paths["explicit"][0] - paths["explicit"].min()
    assert fall > 0.03
    assert np.abs(paths["explicit"] - paths["backward-euler"]).max() < 0.05 * fall


def _state(x, v):
    from rodnet.state import State

    return State(Configuration(x), v.ravel())


@pytest.mark.slow
def test_the_chain_drapes_over_a_fixed_ball_implicitly(spring_chain, tmp_path: Path) -> None:
    text = CHAIN.format(integrator="backward-euler", supports=PINS) + BALL.format(kind="fixed = true", z=0.84)
    r = run(scene_from_toml(text, ["simulation.duration=0.5"]), tmp_path, progress=False)
    assert r.status == "ok", r.message
    assert r.arrays["contact_count"].max() > 0
    mid = r.arrays["positions"][:, 5]
    assert mid[:, 2].min() > 0.84 + 0.15 - 0.005   # held on the ball's top, 0.99 m


def test_the_chain_moves_a_free_ball_and_keeps_the_momentum_balance(spring_chain,
                                                                   tmp_path: Path) -> None:
    """The pins are lifted: chain and ball fly free under gravity, and the chain, shot at the
    ball, pushes it; total momentum changes by exactly the weight times the time."""
    text = (CHAIN.format(integrator="explicit", supports="")
            + BALL.format(kind="mass = 0.05\nvelocity = [0.0, 0.0, 1.0]", z=0.7))
    r = run(scene_from_toml(text), tmp_path, progress=False)
    assert r.status == "ok", r.message
    a = r.arrays
    m = prepare(scene_from_toml(text)).mass
    momentum = np.einsum("n,fni->fi", m, a["velocities"]) + 0.05 * a["body_velocities"][:, 0]
    expected = momentum[0] + np.outer(a["time"], [0.0, 0.0, -9.81]) * (m.sum() + 0.05)
    free_fall = 1.0 - 9.81 * a["time"]
    assert np.abs(a["body_velocities"][:, 0, 2] - free_fall).max() > 0.02   # the chain hit it
    assert np.abs(momentum - expected).max() < 1e-9 * np.abs(expected).max()
