"""What the picture and movie tests share: whether this machine renders off screen, and a
target for the small net."""

from __future__ import annotations

import functools
import subprocess
import sys

import pytest

SPHERE_TARGET = """
[[bodies]]
name = "target"
shape = "sphere"
size = [1.0, 1.0, 1.0]
position = [1.0, -2.0, 4.0]
fixed = true
[contact]
stiffness = 1.0e5
damping = 10.0
friction = 0.3
"""
"""A fixed 1 m sphere on the path of conftest's small net (``small_net_toml``), which reaches it
near its largest mouth area."""


@functools.cache
def rendering_works() -> bool:
    """True when pyvista draws off screen here (in a child process: a broken OpenGL stack may
    crash rather than raise)."""
    probe = "import pyvista as pv; pv.Plotter(off_screen=True).screenshot()"
    try:
        done = subprocess.run([sys.executable, "-c", probe], capture_output=True, timeout=120)
        return done.returncode == 0
    except (subprocess.TimeoutExpired, OSError):
        return False


def require_offscreen() -> None:
    """Skip the calling test where pyvista or off-screen rendering is missing."""
    pytest.importorskip("pyvista")
    if not rendering_works():
        pytest.skip("off-screen rendering is not available on this machine "
                    "(needs libegl1, libgl1-mesa-dri)")
