"""The reference deployment: explicit and RK45 agree on the whole mouth-area history."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rodnet.cli import demo_scene_text
from rodnet.run import run
from rodnet.scene import scene_from_toml

OFF = ["output.vtk=false", "output.picture=false", "output.plot=false"]


@pytest.mark.slow  # about 100 s: RK45 at rtol 1e-8 on the whole net
def test_explicit_and_rk45_agree_on_the_reference_deployment(tmp_path: Path) -> None:
    explicit = run(scene_from_toml(demo_scene_text(), OFF), tmp_path / "e", progress=False)
    rk45 = run(scene_from_toml(demo_scene_text(), OFF + ["simulation.integrator=rk45"]),
               tmp_path / "r", progress=False)
    assert explicit.status == rk45.status == "ok"
    a, b = explicit.arrays["mouth_area"], rk45.arrays["mouth_area"]
    assert len(a) == len(b) == 301
    assert np.abs(a - b).max() <= 5e-3 * a.max()
    assert abs(explicit.summary["metrics"]["time_of_max_mouth_area"]
               - rk45.summary["metrics"]["time_of_max_mouth_area"]) <= 0.02
