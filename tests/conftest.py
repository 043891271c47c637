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


@pytest.fixture
def small_net() -> str:
    return small_net_toml()
