"""Pieces the contact tests share: the cord their rods are made of, and running a scene."""

from __future__ import annotations

import tempfile
from collections.abc import Sequence

from rodnet.run import RunResult, run
from rodnet.scene import scene_from_toml


def cord(diameter: float = 2.0e-3, axial_stiffness: float = 1.0e3) -> str:
    """The ``[[materials]]`` table of a light cord named "cord", as TOML.

    Parameters
    ----------
    diameter : float
        Contact diameter of the cord [m].
    axial_stiffness : float
        EA [N].

    Returns
    -------
    str
        The table: density 1000 kg/m^3, E = 1 GPa, 10 g/m.
    """
    return f"""
[[materials]]
name = "cord"
density = 1000.0
youngs_modulus = 1.0e9
diameter = {diameter}
mass_per_length = 0.01
axial_stiffness = {axial_stiffness}
"""


def run_ok(text: str, overrides: Sequence[str] = (), directory: str | None = None) -> RunResult:
    """Run a scene written as TOML and check that it ran to its end.

    Parameters
    ----------
    text : str
        The scene.
    overrides : sequence of str
        ``key=value`` overrides, as on the command line.
    directory : str, optional
        Where the results go; a new temporary folder by default.

    Returns
    -------
    RunResult
        The run, with status "ok".
    """
    r = run(scene_from_toml(text, overrides), directory or tempfile.mkdtemp(), progress=False)
    assert r.status == "ok", r.message
    return r
