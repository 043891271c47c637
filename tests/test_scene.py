"""Scene parsing: strict keys, types and ranges; overrides; errors name key, value and what is allowed."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from rodnet.cli import demo_scene_text, main
from rodnet.errors import SceneError
from rodnet.run import prepare
from rodnet.scene import load_scene, scene_from_toml
from tests.conftest import small_net_toml

BAD = [  # (override, key named in the message, a word of the allowed range)
    ("net.packing=1.5", "net.packing", "(0, 1]"),
    ("net.packing=0", "net.packing", "(0, 1]"),
    ("net.nodes_per_side=1", "net.nodes_per_side", ">= 2"),
    ("net.mesh_length=-1.0", "net.mesh_length", "> 0"),
    ("net.corner_thread_length=0", "net.corner_thread_length", "> 0"),
    ("simulation.rho_inf=1.5", "simulation.rho_inf", "[0, 1]"),
    ("simulation.dt=-1e-3", "simulation.dt", "> 0"),
    ("simulation.integrator=verlet", "simulation.integrator", "one of"),
    ("net.nodes_per_side=2.5", "net.nodes_per_side", "integer"),
    ("net.packing=\"dense\"", "net.packing", "number"),
    ("net.direction=[0, 0]", "net.direction", "3 numbers"),
    ("net.direction=[0, 0, 0]", "net.direction", "non-zero"),
    ("net.colour=1", "net.colour", "unknown key"),
    ("materials[0].youngs_modulus=0", "materials[0].youngs_modulus", "> 0"),
    ("materials[0].diameter=-1e-3", "materials[0].diameter", "> 0"),
    ("materials[0].poisson_ratio=0.7", "materials[0].poisson_ratio", "(-1, 0.5)"),
    ("materials[0].viscosity=-1", "materials[0].viscosity", ">= 0"),
    ("net.material=\"steel\"", "net.material", "materials"),
    ("model.elements_per_thread=0", "model.elements_per_thread", ">= 1"),
    ("output.frame_interval=0", "output.frame_interval", "> 0"),
    ("simulation.adaptive=1", "simulation.adaptive", "true or false"),
]


@pytest.mark.parametrize("override,key,allowed", BAD)
def test_bad_values_are_named(override: str, key: str, allowed: str) -> None:
    with pytest.raises(SceneError) as info:
        scene_from_toml(small_net_toml(), [override])
    assert info.value.key == key
    assert allowed in str(info.value)


@pytest.mark.parametrize("override,message", [
    ("net.packing=true", "net.packing = true: must be a number"),
    ("net.direction=[0, nan, 1]", "net.direction[1] = nan: must be a finite number"),
    ("materials[3].density=1.0", "--set = 'materials[3].density=1.0': the index [3] of materials "
                                 "must be an integer 0..0 in this scene"),
    ("materials[x].density=1", "--set = 'materials[x].density=1': the index [x] of materials "
                               "must be an integer 0..0"),
    ("simulation.gravity=-9.81", "simulation.gravity = -9.81: must be an array of 3 numbers"),
    ("materials[0].diameter=1e150", "materials[0].diameter = 1e+150: must be at most 1000"),
    ("materials[0].youngs_modulus=1e100", "materials[0].youngs_modulus = 1e+100: must be at most "
                                          "1e+15"),
    ("materials[0].diameter=1e-300", "materials[0].diameter = 1e-300: must be at least 1e-9 m"),
    ("materials.density=1000", "materials.density = 1000: names an array of tables: give the "
                               "entry's index, as in materials[0].density"),
    ("rods[0].elements=5", "rods[0].elements = 5: indexes [[rods]], which this scene does not "
                           "have"),
])
def test_bad_values_are_shown_as_a_scene_writes_them(override: str, message: str) -> None:
    """The value in a message is TOML (true, not Python's True), and an array's bad component
    and a list's bad index are named as the scene's key paths write them."""
    with pytest.raises(SceneError) as info:
        scene_from_toml(small_net_toml(), [override])
    assert str(info.value).startswith(message)


def test_unknown_section_and_missing_key() -> None:
    with pytest.raises(SceneError, match="unknown section"):
        scene_from_toml(small_net_toml() + "\n[netz]\nx = 1\n")
    with pytest.raises(SceneError, match="materials\\[0\\].density.*required"):
        scene_from_toml(small_net_toml().replace("density = 1440.0", ""))


def test_selector_naming_nothing_is_caught_before_the_run() -> None:
    text = small_net_toml() + '\n[[loads]]\nnode = "net:knot:99"\nforce = [0, 0, 1]\n'
    with pytest.raises(SceneError) as info:
        prepare(scene_from_toml(text))
    assert info.value.key == "loads[0].node" and "net:knot:0..24" in str(info.value)


def test_explicit_step_above_stability_limit_is_refused() -> None:
    scene = scene_from_toml(small_net_toml(), ["simulation.adaptive=false", "simulation.dt=1e-3"])
    with pytest.raises(SceneError, match="stability limit"):
        prepare(scene)


def test_overrides_set_values() -> None:
    scene = scene_from_toml(small_net_toml(), ["simulation.dt=5e-4", "net.center=[0, 0, 1]",
                                               "model.axial=linear", "materials[0].viscosity=0"])
    assert scene.simulation.dt == 5e-4 and scene.net.center == (0.0, 0.0, 1.0)
    assert scene.model.axial == "linear" and scene.materials[0].viscosity == 0.0


@pytest.mark.parametrize("override", ["net.packing=2", "model.kink_strain=0.5", "simulation.integrator=bogus",
                                      "net.nodes_per_side=1"])
def test_cli_bad_input_exits_nonzero_and_writes_nothing(tmp_path: Path, override: str,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    scene = tmp_path / "scene.toml"
    scene.write_text(small_net_toml())
    out = tmp_path / "out"
    assert main(["run", str(scene), "-o", str(out), "--set", override, "--quiet"]) == 2
    assert not out.exists()
    err = capsys.readouterr().err
    assert "bad input" in err and override.split("=")[0] in err


def test_missing_scene_file(tmp_path: Path) -> None:
    with pytest.raises(SceneError, match="cannot read"):
        load_scene(tmp_path / "nope.toml")


def test_demo_scene_is_the_validation_case() -> None:
    case = Path(__file__).parents[1] / "validation/cases/deploy_reference/scene.toml"
    assert case.read_text() == demo_scene_text()


def test_help_imports_neither_pyvista_nor_trimesh() -> None:
    code = ("import sys\nfrom rodnet.cli import main\n"
            "try:\n    main(['--help'])\nexcept SystemExit:\n    pass\n"
            "assert 'pyvista' not in sys.modules and 'trimesh' not in sys.modules, 'heavy import'\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


def test_cosserat_net_refuses_rk45() -> None:
    with pytest.raises(SceneError) as info:
        prepare(scene_from_toml(small_net_toml(integrator="rk45"), ["model.type=cosserat"]))
    assert info.value.key == "simulation.integrator" and "generalized-alpha" in str(info.value)
    assert "explicit" in str(info.value)


def test_a_polyline_that_turns_straight_back_is_refused() -> None:
    """A vertex where the polyline reverses (its two members would lie on each other) is
    named; a turn just short of it is a corner and runs."""
    rod = """
[[materials]]
name = "steel"
density = 7800.0
youngs_modulus = 2.0e11
diameter = 0.01
[[rods]]
name = "r"
material = "steel"
points = {points}
[[supports]]
node = "r:start"
"""
    with pytest.raises(SceneError) as info:
        scene_from_toml(rod.format(points="[[0, 0, 0], [1, 0, 0], [2, 0, 0], [1.5, 0, 0]]"))
    assert info.value.key == "rods[0].points" and "turns straight back at point 2" in str(info.value)
    scene_from_toml(rod.format(points="[[0, 0, 0], [1, 0, 0], [2, 0, 0], [1.5, 0, 0.001]]"))
