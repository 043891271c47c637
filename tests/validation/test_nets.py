"""Nets of threads: the cable/lumped bridge, the Cosserat-to-cable limit, invariants on the net."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rodnet.run import prepare, run
from rodnet.scene import scene_from_toml
from tests.conftest import small_net_toml

IMPLICIT = ["simulation.integrator=backward-euler", "simulation.dt=1e-4", "simulation.adaptive=true"]


def _net(overrides: list[str], duration: float = 0.3, n: int = 1):
    return scene_from_toml(small_net_toml(duration=duration, n=n), overrides)


def test_cable_threads_are_the_lumped_model(tmp_path: Path) -> None:
    """Cosserat threads without bending and torsion are cables: 3 DOF per node, and with one
    element per thread, pinned knots and lumped masses they are the lumped model itself."""
    cable = _net(["model.type=cosserat", "model.bending=false", "model.torsion=false",
                  "model.knots=pinned", *IMPLICIT])
    lumped = _net(["model.type=lumped", *IMPLICIT])
    p = prepare(cable)
    assert p.model.n_dof == 3 * p.structure.n_nodes
    a = run(cable, tmp_path / "c", progress=False)
    b = run(lumped, tmp_path / "l", progress=False)
    assert a.status == b.status == "ok"
    size = np.ptp(b.arrays["positions"][-1], axis=0).max()
    assert np.abs(a.arrays["positions"] - b.arrays["positions"]).max() <= 1e-8 * size
    assert b.arrays["tension"].max() > 1.0  # threads did go taut


@pytest.mark.slow
@pytest.mark.xfail(strict=False, reason="open: the adaptive implicit step is not accuracy-"
                   "controlled, and the default dt_max lets the rod and cable runs drift apart by the "
                   "same 1.2 m at every scale; the limit study needs error-controlled steps")
def test_cosserat_threads_approach_cables_as_bending_vanishes(tmp_path: Path) -> None:
    """EI and GJ scaled by 1e-4, 1e-6, 1e-8 of the solid section: the difference to the cable
    run falls monotonically (pinned knots, one element per thread, same integrator and step)."""
    solid_ei = 7.0e10 * np.pi * 1e-12 / 64
    solid_gj = 7.0e10 / 2.72 * np.pi * 1e-12 / 32
    cable = run(_net(["model.type=cosserat", "model.bending=false", "model.torsion=false",
                      "model.knots=pinned", *IMPLICIT], duration=0.2), tmp_path / "c", progress=False)
    errors = []
    for scale in (1e-4, 1e-6, 1e-8):
        rod = run(_net(["model.type=cosserat", "model.knots=pinned", *IMPLICIT,
                        f"materials[0].bending_stiffness={scale * solid_ei}",
                        f"materials[0].torsional_stiffness={scale * solid_gj}"], duration=0.2),
                  tmp_path / f"r{scale}", progress=False)
        assert rod.status == "ok", rod.message
        errors.append(np.abs(rod.arrays["positions"] - cable.arrays["positions"]).max())
    assert errors[0] > errors[1] > errors[2]
