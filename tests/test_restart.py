"""Starting from a saved frame of an earlier run: the rest of the run is reproduced, a static
equilibrium stays put in a dynamic run, and an incompatible folder is refused by key."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rodnet.errors import SceneError
from rodnet.run import run
from rodnet.scene import scene_from_toml
from tests.conftest import small_net_toml

THREAD = """
[simulation]
type = "{kind}"
duration = {duration}
gravity = [0.0, 0.0, -9.81]
integrator = "{integrator}"
[model]
type = "{model}"
axial = "{axial}"
[[materials]]
name = "kevlar"
density = 1440.0
youngs_modulus = 7.0e10
poisson_ratio = 0.36
diameter = 1.0e-3
viscosity = 2.0e6
[[rods]]
name = "thread"
material = "kevlar"
points = [[0.0, 0.0, 0.0], [0.6, 0.0, 0.0], [1.0, 0.0, 0.3]]
elements = 10
[[supports]]
node = "thread:start"
fix = "{fix}"
{extra}
[output]
vtk = false
frame_interval = 0.02
"""


def _thread(**kw: object) -> str:
    values = dict(kind="dynamic", duration=0.2, integrator="explicit", model="cosserat",
                  fix="clamp", extra="", axial="tension-only")
    values.update(kw)
    return THREAD.format(**values)


PULLED = _thread(model="lumped", fix="pin", extra=(
    '[[loads]]\nnode = "thread:end"\nforce = [0.0, 0.0, 0.5]\n'
    "table = [[0.0, 0.0], [0.05, 1.0], [0.1, 1.0], [0.1, 0.5], [0.16, -0.2]]\n"
    '[[loads]]\nnode = "thread:5"\nforce = [0.0, 0.2, 0.0]\nstart = 0.03\nstop = 0.09\nramp = 0.02'))
"""The thread pulled by loads that change in time, before and after the restart's frame (an
outside check found a restart after a load's first change integrate again from that change:
its first frame 3.15 m off)."""


@pytest.mark.parametrize("text", [small_net_toml(duration=0.3), _thread(), PULLED],
                         ids=["lumped net", "cosserat thread", "loads over time"])
def test_a_restart_from_frame_k_reproduces_the_rest_of_the_run(tmp_path: Path,
                                                               text: str) -> None:
    whole = run(scene_from_toml(text), tmp_path / "whole", progress=False)
    assert whole.status == "ok", whole.message
    k = 6
    again = text.replace("[output]", f'[initial]\nfrom = "{tmp_path / "whole"}"\nframe = {k}\n'
                         "[output]")
    rest = run(scene_from_toml(again), tmp_path / "rest", progress=False)
    assert rest.status == "ok", rest.message
    a, b = whole.arrays, rest.arrays
    np.testing.assert_array_equal(b["time"], a["time"][k:])
    scale = np.abs(a["positions"]).max()
    assert np.abs(b["positions"] - a["positions"][k:]).max() <= 1e-12 * scale
    if "rotation_node_quaternions" in a:
        assert np.abs(b["rotation_node_quaternions"] - a["rotation_node_quaternions"][k:]).max() < 1e-12


def test_a_static_equilibrium_starts_a_dynamic_run_at_rest(tmp_path: Path) -> None:
    """A clamped thread sagging under its weight: the dynamic run from the static solution
    (same gravity) stays where it is. The axial law is linear: a tension-only thread's part
    that its weight compresses has no axial stiffness, and the static solve of that
    near-mechanism depends on round-off (docs/rod_model.md, Limits). Newton's tolerance is
    tightened: a residual ``r`` left on the thread's softest bending mode (about
    ``EI / L^3`` = 3e-3 N/m) moves it by ``r L^3 / EI``, 3e-8 m at the default tolerance."""
    tight = ["simulation.rtol=1e-10"]
    static = run(scene_from_toml(_thread(kind="static", integrator="bdf2", axial="linear"),
                                 tight), tmp_path / "static", progress=False)
    assert static.status == "ok", static.message
    text = _thread(duration=1.0, integrator="bdf2", axial="linear",
                   extra=f'[initial]\nfrom = "{tmp_path / "static"}"')
    dynamic = run(scene_from_toml(text, tight), tmp_path / "dynamic", progress=False)
    assert dynamic.status == "ok", dynamic.message
    x = dynamic.arrays["positions"]
    assert dynamic.arrays["time"][0] == 0.0 and dynamic.arrays["time"][-1] == 1.0
    np.testing.assert_array_equal(x[0], static.arrays["positions"][-1])
    drift = np.abs(x - x[0]).max()
    assert drift < 1e-9 * 1.0, drift   # 1.0 m: the thread's length scale


def test_incompatible_or_missing_runs_are_refused_by_key(tmp_path: Path) -> None:
    whole = run(scene_from_toml(_thread(duration=0.04)), tmp_path / "rod", progress=False)
    assert whole.status == "ok"
    cases = [(_thread(extra=f'[initial]\nfrom = "{tmp_path / "nothing"}"'), "initial.from"),
             (_thread(extra=f'[initial]\nfrom = "{tmp_path / "rod"}"\nframe = 9'), "initial.frame"),
             (_thread(extra=f'[initial]\nfrom = "{tmp_path / "rod"}"\ntime = 0.5'), "initial.time"),
             (_thread(model="lumped", extra=f'[initial]\nfrom = "{tmp_path / "rod"}"'),
              "initial.from"),
             (_thread(duration=0.04, extra=f'[initial]\nfrom = "{tmp_path / "rod"}"'),
              "simulation.duration"),
             (_thread(extra="[initial]\nframe = 2"), "initial.frame"),
             # given velocities were silently replaced by the saved frame's
             (_thread(extra=f'[initial]\nfrom = "{tmp_path / "rod"}"\n'
                      'velocities = [["thread:end", 0.0, 0.0, 1.0]]'), "initial.velocities")]
    for text, key in cases:
        with pytest.raises(SceneError) as err:
            run(scene_from_toml(text), tmp_path / "out", progress=False)
        assert key in str(err.value), (key, str(err.value))
        assert not (tmp_path / "out").exists()



def _arch(q0: float, steps: int, extra: str = "", elements: int = 20) -> str:
    """A shallow sinusoidal arch (span 1 m, rise 4 mm, EI 1 N m^2, EA 1e6 N) between pins, held
    in its plane, under the downward load q0 sin(pi x) [N/m] on its nodes; its limit load is
    about q0 = 0.78 N/m."""
    x = np.linspace(0.0, 1.0, elements + 1)
    points = [[float(a), float(0.004 * np.sin(np.pi * a)), 0.0] for a in x]
    supports = ('[[supports]]\nnode = "arch:start"\ndofs = ["x", "y", "z", "r1"]\n'
                '[[supports]]\nnode = "arch:end"\ndofs = ["x", "y", "z"]\n'
                + "".join(f'[[supports]]\nnode = "arch:{k}"\ndofs = ["z"]\n'
                          for k in range(1, elements)))
    loads = "".join(f'[[loads]]\nnode = "arch:{k}"\n'
                    f"force = [0.0, {-q0 * np.sin(np.pi * x[k]) / elements}, 0.0]\n"
                    for k in range(1, elements))
    return f"""
[simulation]
type = "static"
load_steps = {steps}
[model]
type = "cosserat"
axial = "linear"
[[materials]]
name = "m"
density = 7800.0
youngs_modulus = 2.0e11
diameter = 0.01
axial_stiffness = 1.0e6
shear_stiffness = 1.0e7
bending_stiffness = 1.0
torsional_stiffness = 1.0
[[rods]]
name = "arch"
material = "m"
points = {points}
elements = {elements}
{supports}{loads}{extra}
[output]
vtk = false
"""


def test_a_static_run_starts_its_solve_from_a_saved_frame(tmp_path: Path) -> None:
    """Below its limit load a shallow arch has two stable equilibria: a static run started from
    a saved frame of the snapped arch finds the inverted one, a run from the scene's own shape
    the upright one (both in equilibrium: the supports carry the load)."""
    snapped = run(scene_from_toml(_arch(1.5 * 0.78, 20)), tmp_path / "snapped", progress=False)
    assert snapped.status == "ok" and snapped.arrays["positions"][-1, 10, 1] < -0.004
    middle = {}
    for label, extra in (("own", ""), ("saved", f'[initial]\nfrom = "{tmp_path / "snapped"}"')):
        r = run(scene_from_toml(_arch(0.95 * 0.78, 10, extra)), tmp_path / label, progress=False)
        assert r.status == "ok"
        middle[label] = r.arrays["positions"][-1, 10, 1]
        load = 0.95 * 0.78 * np.sin(np.pi * np.linspace(0.0, 1.0, 21)[1:-1]).sum() / 20
        assert r.arrays["support_reactions"][-1][:, 1].sum() == pytest.approx(load, rel=1e-6)
    assert middle["saved"] < -0.003 and middle["own"] > 0.0
