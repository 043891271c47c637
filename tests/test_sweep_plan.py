"""Planning a sweep (no dask): the --vary forms, the grid, the Latin hypercube times the grid,
integer keys, and refusals of bad options by name."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rodnet.errors import SceneError
from rodnet.sweep import parse_vary, plan
from tests.conftest import small_net_toml

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def scene(tmp_path: Path) -> Path:
    path = tmp_path / "net.toml"
    path.write_text(small_net_toml(duration=0.1))
    return path


def test_vary_forms() -> None:
    grid = parse_vary("net.direction=[1, 0, 0], [0,0,1] ,\"a,b\"")
    assert grid.values == ("[1, 0, 0]", "[0,0,1]", '"a,b"') and not grid.sampled
    ranged = parse_vary("net.launch_speed=5:25.5")
    assert ranged.sampled and (ranged.low, ranged.high, ranged.integer) == (5.0, 25.5, False)
    assert parse_vary("net.nodes_per_side=3:9").integer
    for bad, says in [("net.launch_speed", "KEY=V1,V2"), ("net.launch_speed=9:5", "LOW < HIGH"),
                      ("net.launch_speed=1,,2", "empty value"), ("net.launch_speed=a:3", "LOW:HIGH")]:
        with pytest.raises(SceneError, match=says) as info:
            parse_vary(bad)
        assert info.value.key == "--vary" and info.value.value == bad


def test_the_grid_is_every_combination_in_vary_order(scene: Path) -> None:
    sweep = plan(scene, ["net.launch_speed=8,12", "simulation.integrator=explicit,rk45,bdf2"],
                 ["simulation.duration=0.05"])
    assert sweep.keys == ["net.launch_speed", "simulation.integrator"]
    assert [dict(r.values) for r in sweep.runs] == [
        {"net.launch_speed": s, "simulation.integrator": i}
        for s in (8, 12) for i in ("explicit", "rk45", "bdf2")]
    assert sweep.overrides(sweep.runs[5]) == ["simulation.duration=0.05", "net.launch_speed=12",
                                              'simulation.integrator="bdf2"']


def test_planning_imports_no_dask(scene: Path) -> None:
    code = ("import sys; from rodnet.sweep import plan; "
            f"plan({str(scene)!r}, ['net.launch_speed=8,12']); print('dask' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(ROOT)}, timeout=120)
    assert done.stdout.strip() == "False", done.stderr


def test_latin_hypercube_times_the_grid(scene: Path) -> None:
    vary = ["net.launch_speed=6:14", "net.nodes_per_side=3:7", "net.packing=0.2,0.4"]
    sweep = plan(scene, vary, samples=5, seed=7)
    assert len(sweep.runs) == 10
    runs = [dict(r.values) for r in sweep.runs]
    speeds = np.array([r["net.launch_speed"] for r in runs[::2]])
    # one sample in each fifth of [6, 14]: a Latin hypercube
    assert sorted(np.floor((speeds - 6.0) / 1.6).astype(int)) == [0, 1, 2, 3, 4]
    assert [r["net.launch_speed"] for r in runs[1::2]] == list(speeds)   # times the grid
    assert [r["net.packing"] for r in runs] == [0.2, 0.4] * 5
    sides = [r["net.nodes_per_side"] for r in runs]
    assert all(isinstance(n, int) and 3 <= n <= 7 for n in sides)
    assert [dict(r.values) for r in plan(scene, vary, samples=5, seed=7).runs] == runs
    assert [dict(r.values) for r in plan(scene, vary, samples=5, seed=8).runs] != runs


@pytest.mark.parametrize("vary, sets, samples, key", [
    ([], [], None, "--vary"),
    (["net.launch_speed=5:9"], [], None, "--vary"),
    (["net.launch_speed=5,9"], [], 4, "--samples"),
    (["net.launch_speed=5,9", "net.launch_speed=6"], [], None, "--vary"),
    (["net.launch_speed=5,9"], ["net.launch_speed=3"], None, "--set"),
    # one key in the two spellings --set takes (the sweep had run the second's values under
    # the first's labels, and dropped a --set so spelt; outside check)
    (["materials[0].viscosity=1e6,2e6", "materials.0.viscosity=5e6"], [], None, "--vary"),
    (["materials[0].viscosity=1e6,2e6"], ["materials.0.viscosity=5e6"], None, "--set"),
    (["net.launch_speed=15,15.0"], [], None, "--vary"),   # the same run twice (outside check)
    (["net.launch_speeed=5,9"], [], None, "net.launch_speeed"),
    (["simulation.integrator=explicit,leapfrog"], [], None, "simulation.integrator"),
])
def test_bad_options_are_refused_by_name(scene: Path, vary: list[str], sets: list[str],
                                         samples: int | None, key: str) -> None:
    with pytest.raises(SceneError) as info:
        plan(scene, vary, sets, samples)
    assert info.value.key == key


def test_a_run_the_checks_refuse_is_named(scene: Path) -> None:
    """Refused as ``rodnet run`` refuses it: here by the explicit stability limit, a check made
    when the model is built, not when the file is read."""
    with pytest.raises(SceneError, match=r"stability limit.*in run 1 of the sweep") as info:
        plan(scene, ["simulation.dt=1e-5,0.5"], ["simulation.adaptive=false"])
    assert info.value.key == "simulation.dt" and info.value.value == 0.5
