"""Shared fixtures: small scenes written as TOML, as a user would write them."""

from __future__ import annotations

import pytest

SMALL_NET = """
[simulation]
duration = {duration}
integrator = "{integrator}"

[model]
type = "lumped"
elements_per_thread = {n}

[[materials]]
name = "kevlar"
density = 1440.0
youngs_modulus = 7.0e10
poisson_ratio = 0.36
diameter = 1.0e-3
viscosity = {viscosity}

[net]
nodes_per_side = 5
mesh_length = 1.0
material = "kevlar"
direction = {direction}
center = [1.0, -2.0, 0.5]
packing = 0.2
corner_mass = 0.2
launch_speed = 10.0
launch_angle_deg = 40.0

[output]
frame_interval = 0.01
vtk = {vtk}
"""


def small_net_toml(duration: float = 0.6, integrator: str = "explicit", n: int = 1,
                   viscosity: float = 2.0e6, direction: str = "[0.0, 0.0, 1.0]",
                   vtk: str = "false") -> str:
    """A 5 x 5 knot net launched by four 0.2 kg corner masses."""
    return SMALL_NET.format(duration=duration, integrator=integrator, n=n, viscosity=viscosity,
                            direction=direction, vtk=vtk)



FALLING_THREAD = """
[simulation]
type = "dynamic"
duration = {duration}
gravity = [0.0, 0.0, -9.81]
{simulation}
[model]
type = "cosserat"
axial = "linear"
[[materials]]
name = "nylon"
density = 1150.0
youngs_modulus = 2.5e9
poisson_ratio = 0.35
diameter = 1.0e-3
[[rods]]
name = "thread"
material = "nylon"
points = [[0, 0, 0], [1.5, 0, 0]]
elements = {elements}
[[supports]]
node = "thread:start"
fix = "clamp"
[output]
frame_interval = {frame_interval}
vtk = false
"""


def falling_thread_toml(duration: float = 1.0, elements: int = 20, frame_interval: float = 0.01,
                        simulation: str = "") -> str:
    """The benchmark thread: 1.5 m of 1 mm nylon (EA L^2 / EI = 3.6e7), clamped at one end and
    released horizontal under gravity; ``simulation`` adds lines to ``[simulation]``."""
    return FALLING_THREAD.format(duration=duration, elements=elements,
                                 frame_interval=frame_interval, simulation=simulation)

@pytest.fixture
def small_net() -> str:
    return small_net_toml()


_IGNORED = {".git", ".venv", "__pycache__", ".pytest_cache", "node_modules"}


def _tree(root) -> dict[str, int]:  # type: ignore[no-untyped-def]
    """Files under ``root`` (paths relative to it) with their modification times [ns], leaving
    out version control, virtual environments and caches (numba's kernels live in __pycache__)."""
    import os

    found: dict[str, int] = {}
    for folder, dirs, files in os.walk(root):
        dirs[:] = [d for d in dirs if d not in _IGNORED and not d.endswith(".egg-info")]
        for name in files:
            path = os.path.join(folder, name)
            try:
                found[os.path.relpath(path, root)] = os.stat(path).st_mtime_ns
            except OSError:
                continue
    return found


@pytest.fixture(autouse=True)
def _no_writes_to_the_working_directory():  # type: ignore[no-untyped-def]
    """Fail a test that creates or changes a file in the working directory (the repository
    when pytest runs from it): tests write into temporary directories only, so they never
    overwrite a user's results (``out/`` of ``rodnet demo``) or tracked files."""
    import os

    cwd = os.getcwd()
    before = _tree(cwd)
    yield
    after = _tree(cwd)
    changed = sorted(p for p, t in after.items() if before.get(p) != t)
    assert not changed, f"the test wrote into the working directory {cwd}: {changed[:10]}"
