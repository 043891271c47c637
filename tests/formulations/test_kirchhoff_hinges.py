"""Kirchhoff threads' bending hinges (elements/kirchhoff/FORMULATION.md): force against the
energy's gradient, the compiled loop against the NumPy forces, momentum and dissipation, the
hinges found in a net, and the scenes the model refuses."""

from __future__ import annotations

import numpy as np
import pytest

from rodnet.errors import SceneError
from rodnet.kernels.hinge import hinge_energy, hinge_force
from rodnet.run import prepare
from rodnet.scene import scene_from_toml
from tests.conftest import small_net_toml
from tests.systems import compiled_forces
from tests.validation.test_kirchhoff import BEAM

KIRCHHOFF = ["model.type=kirchhoff", "model.knots=pinned"]


def _chain(rng: np.random.Generator, n: int = 6) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A random bent chain of ``n`` nodes, its hinges (H, 3) and their rest lengths (H, 2)."""
    steps = rng.normal(size=(n - 1, 3)) + [1.0, 0.0, 0.0]
    x = np.vstack([np.zeros(3), np.cumsum(steps, axis=0)])
    hinges = np.array([[i, i + 1, i + 2] for i in range(n - 2)])
    rest = rng.uniform(0.5, 1.5, (len(hinges), 2))
    return x, hinges, rest


def test_hinge_force_is_minus_the_energy_gradient() -> None:
    """At rest (no damping) (K3) is -dW/dx of (K2), by central differences."""
    rng = np.random.default_rng(3)
    x, hinges, rest = _chain(rng)
    k = rng.uniform(0.5, 2.0, len(hinges))
    f = hinge_force(x, np.zeros_like(x), hinges, k, np.zeros(len(hinges)), rest)
    h, grad = 1e-6, np.zeros_like(x)
    for i in range(x.shape[0]):
        for j in range(3):
            xp, xm = x.copy(), x.copy()
            xp[i, j] += h
            xm[i, j] -= h
            grad[i, j] = (hinge_energy(xp, hinges, k, rest).sum()
                          - hinge_energy(xm, hinges, k, rest).sum()) / (2 * h)
    np.testing.assert_allclose(f, -grad, atol=1e-8 * np.abs(f).max())


def test_hinge_at_rest_lengths_stores_the_beam_curvature_energy() -> None:
    """Segments at their rest lengths turned by phi: (K2) is k_h (1 - cos phi), which is
    (EI / 2) (phi / lbar)^2 lbar for small phi; a slack segment (half its length) carries less."""
    lbar, EI = 0.5, 3.0
    hinge, rest = np.array([[0, 1, 2]]), np.array([[lbar, lbar]])
    for phi in (1e-3, 0.7, 2.5):
        x = np.array([[0.0, 0.0, 0.0], [lbar, 0.0, 0.0],
                      [lbar + lbar * np.cos(phi), lbar * np.sin(phi), 0.0]])
        W = hinge_energy(x, hinge, np.array([EI / lbar]), rest)[0]
        assert W == pytest.approx(EI / lbar * (1.0 - np.cos(phi)), rel=1e-12)
    x[0] = [0.5 * lbar, 0.0, 0.0]   # the first segment slack at half its rest length
    assert hinge_energy(x, hinge, np.array([EI / lbar]), rest)[0] < W
    assert 0.5 * EI * (1e-3 / lbar) ** 2 * lbar == pytest.approx(EI / lbar * (1.0 - np.cos(1e-3)), rel=1e-6)


def test_hinges_carry_no_net_force_or_moment_and_damping_dissipates() -> None:
    rng = np.random.default_rng(4)
    x, hinges, rest = _chain(rng, 8)
    v = rng.normal(size=x.shape)
    k, tau = rng.uniform(0.5, 2.0, len(hinges)), np.full(len(hinges), 0.3)
    f = hinge_force(x, v, hinges, k, tau, rest)
    elastic = hinge_force(x, np.zeros_like(v), hinges, k, np.zeros_like(tau), rest)
    scale = np.abs(f).max()
    np.testing.assert_allclose(f.sum(axis=0), 0.0, atol=1e-12 * scale)
    np.testing.assert_allclose(np.cross(x, f).sum(axis=0), 0.0, atol=1e-11 * scale * np.abs(x).max())
    assert np.sum((f - elastic) * v) < 0.0            # the damping takes energy out
    # a rigid rotation is not damped: objective
    omega = np.array([0.3, -1.2, 0.7])
    spin = np.cross(omega, x)
    np.testing.assert_allclose(hinge_force(x, spin, hinges, k, tau, rest), elastic, atol=1e-12 * scale)


@pytest.mark.parametrize("axial", ["tension-only", "linear"])
def test_compiled_forces_equal_numpy_forces(axial: str) -> None:
    rng = np.random.default_rng(5)
    p = prepare(scene_from_toml(small_net_toml(n=3), [*KIRCHHOFF, f"model.axial={axial}",
                                                      "simulation.gravity=[0, 0, -9.81]"]))
    x = p.structure.rest_positions + rng.normal(scale=0.05, size=p.q0.x.shape)
    v = rng.normal(size=x.shape)
    f = compiled_forces(p.system, x, v, 0.3)
    np.testing.assert_allclose(f, p.model.force(x, v, 0.3), rtol=1e-10, atol=1e-9)


def test_a_hinge_at_every_node_inside_a_thread() -> None:
    """n elements per thread: n - 1 hinges per thread, none at a knot, each joining two segments
    of one thread end to start, with their rest lengths."""
    for n in (1, 2, 4):
        p = prepare(scene_from_toml(small_net_toml(n=n), KIRCHHOFF))
        s = p.structure
        hinges = p.model.hinges.nodes
        n_threads = len(np.unique(s.thread))
        assert len(hinges) == n_threads * (n - 1)
        pairs = {tuple(seg): i for i, seg in enumerate(s.segments.tolist())}
        first = np.array([pairs[(a, b)] for a, b, _ in hinges.tolist()], dtype=int)
        second = np.array([pairs[(b, c)] for _, b, c in hinges.tolist()], dtype=int)
        assert np.all(s.thread[first] == s.thread[second])
        np.testing.assert_array_equal(p.model.hinges.rest, s.rest_length[np.c_[first, second]])
        knots = set(s.selectors[k] for k in s.selectors if k.startswith("net:knot:"))
        assert not knots & set(hinges[:, 1].tolist())


@pytest.mark.parametrize(("override", "key"), [
    ("model.knots=rigid", "model.knots"),
    ("simulation.integrator=generalized-alpha", "simulation.integrator"),
    ("simulation.type=static", "simulation.type"),
])
def test_refused_scenes_name_the_key(override: str, key: str) -> None:
    with pytest.raises(SceneError, match=key.replace(".", r"\.")):
        prepare(scene_from_toml(small_net_toml(), [*KIRCHHOFF, override]))


def test_clamps_and_bent_rods_are_refused() -> None:
    beam = BEAM.format(duration=0.01, elements=4, frame_interval=0.01)
    with pytest.raises(SceneError, match=r"supports\[0\]\.fix"):
        prepare(scene_from_toml(beam, ['supports[0].fix="clamp"']))
    with pytest.raises(SceneError, match=r"rods\[0\]\.points"):
        prepare(scene_from_toml(beam, ["rods[0].points=[[0.0, 0.0, 0.0], [0.5, 0.0, 0.0], [1.0, 0.5, 0.0]]"]))
    prepare(scene_from_toml(beam))
