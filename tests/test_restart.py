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
