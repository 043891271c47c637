"""The reference deployment: explicit and RK45 agree on the whole mouth-area history."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rodnet.cli import demo_scene_text
from rodnet.run import run
from rodnet.scene import scene_from_toml

OFF = ["output.vtk=false", "output.picture=false", "output.plot=false"]


@pytest.mark.slow  # about 60 s: RK45 at rtol 1e-6 on the whole net
def test_explicit_and_rk45_agree_on_the_reference_deployment(tmp_path: Path) -> None:
    """Up to the largest mouth area within 0.25 % of it (measured: 0.11 %); over the whole 3 s
    within 1 % (measured: 0.62 %; against RK45 at rtol 1e-8, 0.71 %): after the maximum the
    corner masses snap back and explicit runs at other steps or from a 1 nm shifted start differ
    from each other by 0.2 - 0.7 % (docs/lumped_model.md, Accuracy)."""
    explicit = run(scene_from_toml(demo_scene_text(), OFF), tmp_path / "e", progress=False)
    rk45 = run(scene_from_toml(demo_scene_text(), OFF + ["simulation.integrator=rk45"]),
               tmp_path / "r", progress=False)
    assert explicit.status == rk45.status == "ok"
    a, b = explicit.arrays["mouth_area"], rk45.arrays["mouth_area"]
    assert len(a) == len(b) == 301
    until = slice(0, int(np.argmax(b)) + 1)
    assert np.abs(a - b)[until].max() <= 2.5e-3 * b.max()
    assert np.abs(a - b).max() <= 1e-2 * b.max()
    assert abs(explicit.summary["metrics"]["time_of_max_mouth_area"]
               - rk45.summary["metrics"]["time_of_max_mouth_area"]) <= 0.02
