"""The residual-bending shear correction (``model.shear_correction``, FORMULATION.md C44, C45).

- The effective shear stiffness ``1/GA_eff = 1/GA + Le^2/(12 EI)``, per bending plane, and its
  limit ``GA`` as the element shrinks.
- One element reproduces the Timoshenko cantilever exactly in the small-load limit: tip
  deflection ``P L^3/(3 EI) + P L/GA`` (the Euler-Bernoulli ``P L^3/(3 EI)`` for a slender
  rod) and tip rotation ``P L^2/(2 EI)``; without the correction one element gives
  ``P L^3/(4 EI) + P L/GA``. With the correction every mesh is exact at the nodes.
- The price in geometrically exact kinematics: a straight element under tension ``N`` keeps
  its triad on its chord only while ``N < GA_eff lambda`` (C45), checked on the tangent.
- A bad value is refused with the key, the value and the allowed values.
"""

from __future__ import annotations

import numpy as np
import pytest

from rodnet.config import ModelSpec
from rodnet.errors import SceneError
from rodnet.models.cosserat.geometry import residual_bending_shear
from rodnet.kernels import so3
from rodnet.run import prepare, run
from rodnet.scene import scene_from_toml
from rodnet.state import Configuration as RodConfiguration

E, NU, RHO, D, L = 2.0e11, 0.3, 7800.0, 0.01, 1.0     # steel rod, L / d = 100
AREA, INERTIA, G = np.pi * D**2 / 4, np.pi * D**4 / 64, E / (2 * (1 + NU))
EI, EA = E * INERTIA, E * AREA
GA = 6 * (1 + NU) / (7 + 6 * NU) * G * AREA

ROD = """
[simulation]
type = "{type}"
load_steps = 1
[model]
axial = "linear"
shear_correction = "{correction}"
[[materials]]
name = "steel"
density = {rho}
youngs_modulus = {E}
poisson_ratio = {nu}
diameter = {d}
[[rods]]
name = "beam"
material = "steel"
points = [[0, 0, 0], [{L}, 0, 0]]
elements = {elements}
{supports}
[[loads]]
node = "beam:end"
force = [0.0, {P}, 0.0]
[output]
vtk = false
"""


def rod(elements: int, correction: str, P: float = 1.0, kind: str = "static",
        clamped: bool = True):
    supports = '[[supports]]\nnode = "beam:start"\nfix = "clamp"' if clamped else ""
    return scene_from_toml(ROD.format(type=kind, correction=correction, rho=RHO, E=E, nu=NU, d=D,
                                      L=L, elements=elements, supports=supports, P=P))


def linear_tip(elements: int, correction: str, P: float = 1.0) -> tuple[float, float]:
    """Tip deflection [m] along the load and tip rotation [rad] of the clamped rod linearised
    at the stress-free state: ``K u = -g(q0)``."""
    p = prepare(rod(elements, correction, P))
    model = p.system
    g, K, _ = model.tangents(p.q0, np.zeros(model.n_dof), 0.0, 1.0)
    u = np.zeros(model.n_dof)
    u[model.free] = np.linalg.solve(K.toarray(), -g[model.free])
    tip = model.n_nodes - 1
    body = u[3 * (model.n_nodes + tip):3 * (model.n_nodes + tip) + 3]
    rotation = so3.quat_to_matrix(p.q0.quat[tip]) @ body        # global components
    assert np.allclose(rotation[:2], 0.0, atol=1e-12 * abs(rotation[2]))   # about z only
    return float(u[3 * tip + 1]), float(rotation[2])


def test_effective_shear_stiffness_pairs_planes_and_tends_to_ga() -> None:
    stiffness = np.array([[EA, 2.0, 3.0, 1.0, 5.0, 7.0]] * 3)
    le = np.array([1.0, 1e-2, 1e-4])
    out = residual_bending_shear(stiffness, le)
    np.testing.assert_allclose(out[:, 1], 1.0 / (1.0 / 2.0 + le**2 / (12 * 7.0)), rtol=1e-15)
    np.testing.assert_allclose(out[:, 2], 1.0 / (1.0 / 3.0 + le**2 / (12 * 5.0)), rtol=1e-15)
    np.testing.assert_array_equal(out[:, [0, 3, 4, 5]], stiffness[:, [0, 3, 4, 5]])
    assert abs(out[-1, 1] / 2.0 - 1.0) < 1e-9      # a short element keeps its shear stiffness
    no_bending = stiffness.copy()
    no_bending[:, 4:] = 0.0
    assert not residual_bending_shear(no_bending, le)[:, 1:3].any()


def test_one_element_gives_the_exact_cantilever() -> None:
    """Small-load limit: one corrected element against the Timoshenko (and, for this slender rod,
    the Euler-Bernoulli) cantilever; the plain element is 25 % too stiff in bending."""
    P = 1.0
    deflection, rotation = linear_tip(1, "residual-bending", P)
    exact = P * L**3 / (3 * EI) + P * L / GA
    assert deflection == pytest.approx(exact, rel=1e-10)
    assert deflection == pytest.approx(P * L**3 / (3 * EI), rel=2e-4)   # shear part: 6e-5
    assert rotation == pytest.approx(P * L**2 / (2 * EI), rel=1e-10)
    plain, _ = linear_tip(1, "none", P)
    assert plain == pytest.approx(P * L**3 / (4 * EI) + P * L / GA, rel=1e-10)


@pytest.mark.parametrize("elements", [2, 5, 20])
def test_corrected_meshes_are_exact_at_the_tip(elements: int) -> None:
    deflection, rotation = linear_tip(elements, "residual-bending")
    assert deflection == pytest.approx(L**3 / (3 * EI) + L / GA, rel=1e-9)
    assert rotation == pytest.approx(L**2 / (2 * EI), rel=1e-9)


def test_static_run_with_one_corrected_element(tmp_path) -> None:
    """The scene key end to end: a static run at P L^2 / EI = 1e-4 (nonlinearity ~1e-5)."""
    P = 1e-4 * EI / L**2
    result = run(rod(1, "residual-bending", P), tmp_path, progress=False)
    assert result.status == "ok", result.message
    tip = result.arrays["positions"][-1, -1]
    assert tip[1] == pytest.approx(P * L**3 / (3 * EI) + P * L / GA, rel=1e-4)


@pytest.mark.parametrize("correction", ["none", "residual-bending"])
def test_tension_limit_of_the_triad_on_its_chord(correction: str) -> None:
    """A straight element stretched to ``lambda`` with axial force ``N``: turning both end triads
    by the same angle about a bending axis, positions held, has the stiffness
    ``Le lambda (GA_eff lambda - N)`` (C45). It turns negative above ``N = GA_eff lambda``."""
    p = prepare(rod(1, correction, kind="dynamic", clamped=False))
    model = p.model
    ga_eff = model.stiffness[0, 1]
    assert ga_eff == pytest.approx(GA if correction == "none" else
                                   1.0 / (1.0 / GA + L**2 / (12 * EI)), rel=1e-12)
    mode = np.zeros(model.n_dof)
    for node in (0, 1):
        mode[3 * (model.n_nodes + node) + 2] = 1.0      # about d3 (-y) of both nodes
    for ratio in (0.5, 2.0):                            # N / (GA_eff lambda)
        stretch = 1.0 + ratio * ga_eff / (EA - ratio * ga_eff)   # N = EA (lambda - 1)
        N = EA * (stretch - 1.0)
        q = RodConfiguration(p.q0.x * np.array([stretch, 1.0, 1.0]), p.q0.quat)
        _, K, _ = p.system.tangents(q, np.zeros(model.n_dof), 0.0, 0.0)
        stiffness = mode @ (K.toarray() @ mode)
        assert stiffness == pytest.approx(L * stretch * (ga_eff * stretch - N), rel=1e-6)
        assert (stiffness > 0.0) == (ratio < 1.0)


def test_bad_value_names_key_value_and_allowed() -> None:
    text = ROD.format(type="static", correction="macneal", rho=RHO, E=E, nu=NU, d=D, L=L,
                      elements=1, supports="", P=1.0)
    with pytest.raises(SceneError) as err:
        scene_from_toml(text)
    message = str(err.value)
    assert "model.shear_correction" in message and "macneal" in message
    assert "'none'" in message and "'residual-bending'" in message
    with pytest.raises(SceneError, match="shear_correction"):
        ModelSpec(shear_correction="shear")  # type: ignore[arg-type]
