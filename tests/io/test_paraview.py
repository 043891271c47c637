"""The VTK series is ready for ParaView: named blocks, node/element/thread ids, bodies that carry
data, and a ``paraview.py`` beside ``result.pvd`` that ParaView runs (the last two tests need
Debian's ``pvbatch`` / ``paraview`` and ``xvfb-run``; CI machines without them skip)."""

from __future__ import annotations

import ast
import os
import shutil
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import meshio
import numpy as np
import pytest

import rodnet
from rodnet.io.paraview import SCREENSHOT_NAME, SCRIPT_NAME, TUBE_FRACTION
from rodnet.io.vtk import VtkSeries
from rodnet.run import prepare
from tests.conftest import small_net_toml
from tests.contact.test_free_bodies import NET_AND_BOX as FREE_NET_AND_BOX

# the free-body test's net thrown at a tumbling box, renamed: a body name ParaView must make a
# valid XML tag of, and frames saved every 10 ms with VTK
NET_AND_BOX = (FREE_NET_AND_BOX.replace('name = "box"', 'name = "SL-8 stage"')
               .replace("duration = 0.12", "duration = 0.06")
               .replace("frame_interval = 1.0e-3", "frame_interval = 0.01")
               .replace("vtk = false", "vtk = true"))

PVBATCH = shutil.which("pvbatch")
PARAVIEW = shutil.which("paraview")
XVFB_RUN = shutil.which("xvfb-run")


def run_scene(text: str, directory: Path) -> rodnet.RunResult:
    r = rodnet.run(rodnet.scene_from_toml(text), directory, progress=False)
    assert r.status == "ok", r.message
    return r


def script_constants(path: Path) -> dict[str, object]:
    """The literal module-level assignments of a generated ``paraview.py`` (``TENSION_RANGE``,
    ``BOUNDS``, ...), read without running ParaView."""
    found = {}
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, ast.Assign) and isinstance(node.targets[0], ast.Name):
            try:
                found[node.targets[0].id] = ast.literal_eval(node.value)
            except ValueError:
                continue
    return found


def test_pvd_names_its_blocks(tmp_path: Path) -> None:
    r = run_scene(NET_AND_BOX, tmp_path)
    entries = ET.parse(tmp_path / "result.pvd").getroot().find("Collection")
    names = {}
    for entry in entries:
        names.setdefault(entry.get("part"), set()).add(entry.get("name"))
    assert names == {"0": {"threads"}, "1": {"SL-8 stage"}}
    assert len(entries) == 2 * len(r.arrays["time"])


def test_frames_hold_node_and_element_ids(tmp_path: Path) -> None:
    r = run_scene(small_net_toml(duration=0.05, vtk="true"), tmp_path)
    frame = meshio.read(tmp_path / "vtk" / "frame_00003.vtu")
    n, e = r.arrays["positions"].shape[1], len(r.arrays["segments"])
    np.testing.assert_array_equal(frame.point_data["node_id"], np.arange(n))
    np.testing.assert_array_equal(frame.cell_data["element_id"][0], np.arange(e))
    np.testing.assert_allclose(frame.cell_data["tension"][0], r.arrays["tension"][3])


def test_runs_write_thread_ids_and_body_motion(tmp_path: Path) -> None:
    r = run_scene(NET_AND_BOX, tmp_path)
    structure = prepare(rodnet.scene_from_toml(NET_AND_BOX)).structure
    frame = meshio.read(tmp_path / "vtk" / "frame_00002.vtu")
    np.testing.assert_array_equal(frame.cell_data["thread_id"][0], structure.thread)
    body = meshio.read(tmp_path / "vtk" / "body_0_00002.vtu")
    np.testing.assert_array_equal(body.cell_data["body_id"][0], 0)
    np.testing.assert_allclose(body.cell_data["body_velocity"][0][0],
                               r.arrays["body_velocities"][2, 0])
    np.testing.assert_allclose(body.cell_data["angular_velocity"][0][0],
                               r.arrays["body_angular_velocities"][2, 0])
    np.testing.assert_allclose(body.points.mean(axis=0), r.arrays["body_positions"][2, 0],
                               atol=1e-12)                     # a box's corners: its centre


def test_thread_ids_are_written_when_given(tmp_path: Path) -> None:
    structure = prepare(rodnet.scene_from_toml(small_net_toml())).structure
    series = VtkSeries(tmp_path, structure.segments, thread=structure.thread)
    x = structure.positions
    series.write(0.0, {"positions": x, "velocities": np.zeros_like(x),
                       "tension": np.zeros(len(structure.segments))})
    frame = meshio.read(tmp_path / "vtk" / "frame_00000.vtu")
    np.testing.assert_array_equal(frame.cell_data["thread_id"][0], structure.thread)
    assert len(np.unique(structure.thread)) == 2 * 5 * 4 + 4      # mesh and corner threads
    with pytest.raises(ValueError, match="one thread index per segment"):
        VtkSeries(tmp_path, structure.segments, thread=structure.thread[:-1])


def test_bodies_carry_their_index_and_motion(tmp_path: Path) -> None:
    corners = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    tetra = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    segments = np.array([[0, 1]])
    series = VtkSeries(tmp_path, segments, [("a", corners, tetra), ("b", corners + 2.0, tetra)])
    frame = {"positions": np.array([[5.0, 0, 0], [6, 0, 0]]), "velocities": np.zeros((2, 3)),
             "tension": np.array([1.5])}
    series.write(0.0, frame)                                   # the old call: no body state
    bare = meshio.read(tmp_path / "vtk" / "body_1_00000.vtu")
    np.testing.assert_array_equal(bare.cell_data["body_id"][0], [1, 1, 1, 1])
    state = {"body_positions": np.array([[0.0, 0, 0], [2, 2, 2]]),
             "body_velocities": np.array([[0.0, 0, 0], [1, 0, 0]]),
             "body_angular_velocities": np.array([[0.0, 0, 0], [0, 0, 3]])}
    series.write(0.1, frame, bodies=state)
    moving = meshio.read(tmp_path / "vtk" / "body_1_00001.vtu")
    arm = moving.points - [2.0, 2.0, 2.0]
    np.testing.assert_allclose(moving.point_data["velocity"],
                               [1.0, 0, 0] + np.cross([0, 0, 3.0], arm))
    np.testing.assert_allclose(moving.cell_data["angular_velocity"][0], [[0, 0, 3.0]] * 4)
    np.testing.assert_allclose(moving.cell_data["body_velocity"][0], [[1.0, 0, 0]] * 4)
    with pytest.raises(ValueError, match="unknown key"):
        series.write(0.2, frame, bodies={"omega": np.zeros((2, 3))})


def test_frames_with_body_poses_place_body_frame_surfaces(tmp_path: Path) -> None:
    """A frame that holds ``body_positions`` and ``body_rotations`` places the surfaces, given in
    the body frame, and its body state is written on them without the ``bodies`` keyword."""
    local = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    tetra = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    series = VtkSeries(tmp_path, np.array([[0, 1]]), [("a", local, tetra)])
    quarter_turn_z = [np.cos(np.pi / 4), 0.0, 0.0, np.sin(np.pi / 4)]
    series.write(0.0, {"positions": np.array([[5.0, 0, 0], [6, 0, 0]]),
                       "velocities": np.zeros((2, 3)), "tension": np.array([0.0]),
                       "body_positions": np.array([[1.0, 2.0, 3.0]]),
                       "body_rotations": np.array([quarter_turn_z]),
                       "body_velocities": np.array([[0.0, 0.0, 2.0]]),
                       "body_angular_velocities": np.array([[0.0, 0.0, 1.0]]),
                       "body_force": np.zeros((1, 3)), "contact_force": 0.0})
    body = meshio.read(tmp_path / "vtk" / "body_0_00000.vtu")
    world = [1.0, 2.0, 3.0] + local[:, [1, 0, 2]] * [-1.0, 1.0, 1.0]   # x -> y, y -> -x
    np.testing.assert_allclose(body.points, world, atol=1e-12)
    np.testing.assert_allclose(body.point_data["velocity"],
                               [0.0, 0, 2.0] + np.cross([0, 0, 1.0], world - [1.0, 2.0, 3.0]),
                               atol=1e-12)
    bounds = np.array(script_constants(tmp_path / SCRIPT_NAME)["BOUNDS"]).reshape(3, 2)
    np.testing.assert_allclose(bounds[:, 0], [0.0, 0.0, 0.0])        # the placed body, x from 0
    np.testing.assert_allclose(bounds[:, 1], [6.0, 3.0, 4.0])


def test_script_holds_the_run_tension_range_and_bounds(tmp_path: Path) -> None:
    r = run_scene(NET_AND_BOX, tmp_path)
    constants = script_constants(tmp_path / SCRIPT_NAME)
    tension = r.arrays["tension"]
    assert (tension[0] == 0).all() and tension.max() > 0   # the first frame is no guide
    assert constants["TENSION_RANGE"] == (tension.min(), tension.max())
    assert constants["BODIES"] == ["SL-8 stage"]
    assert constants["FRAMES"] == len(r.arrays["time"])
    bounds = np.array(constants["BOUNDS"]).reshape(3, 2)
    x = r.arrays["positions"].reshape(-1, 3)
    assert (bounds[:, 0] <= x.min(axis=0)).all() and (bounds[:, 1] >= x.max(axis=0)).all()
    body_vtu = meshio.read(tmp_path / "vtk" / "body_0_00003.vtu")
    assert (bounds[:, 0] <= body_vtu.points.min(axis=0)).all()
    assert (bounds[:, 1] >= body_vtu.points.max(axis=0)).all()
    assert constants["TUBE_RADIUS"] == pytest.approx(
        TUBE_FRACTION * np.linalg.norm(bounds[:, 1] - bounds[:, 0]))


def test_script_is_rewritten_with_the_pvd(tmp_path: Path) -> None:
    """A run stopped after any frame leaves a script for the frames written so far; at t = 0,
    where every tension is 0, the range is widened to one ParaView accepts."""
    series = VtkSeries(tmp_path, np.array([[0, 1]]))
    for k, tension in enumerate([0.0, 4.0, 2.5]):
        series.write(0.1 * k, {"positions": np.array([[0.0, 0, 0], [1, 0, 0]]),
                               "velocities": np.zeros((2, 3)), "tension": np.array([tension])})
        constants = script_constants(tmp_path / SCRIPT_NAME)
        assert constants["FRAMES"] == k + 1
        assert constants["TENSION_RANGE"] == ((0.0, 1.0) if k == 0 else (0.0, 4.0))
        assert constants["BODIES"] == []


def _image_is_not_blank(path: Path) -> None:
    png = path.read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000
    image = pytest.importorskip("matplotlib.image").imread(path)
    colours = np.unique(image[..., :3].reshape(-1, 3).round(2), axis=0)
    assert len(colours) > 20          # background, tubes in several colours, bodies, text


@pytest.mark.skipif(PVBATCH is None or XVFB_RUN is None,
                    reason="ParaView's pvbatch and xvfb-run are not on PATH (apt-get install "
                           "paraview xvfb); CI machines do not have them")
@pytest.mark.parametrize("scene", ["net", "net and box"])
def test_pvbatch_runs_the_script_and_saves_a_screenshot(tmp_path: Path, scene: str) -> None:
    out = tmp_path / "out"
    run_scene(NET_AND_BOX if scene == "net and box" else small_net_toml(0.3, vtk="true"), out)
    elsewhere = tmp_path / "elsewhere"                 # the script finds the series by itself
    elsewhere.mkdir()
    done = subprocess.run([XVFB_RUN, "-a", PVBATCH, str(out / SCRIPT_NAME)], cwd=elsewhere,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    _image_is_not_blank(out / SCREENSHOT_NAME)
    assert not any(elsewhere.iterdir())


@pytest.mark.skipif(PARAVIEW is None or XVFB_RUN is None,
                    reason="the ParaView GUI and xvfb-run are not on PATH")
@pytest.mark.slow
def test_the_gui_runs_the_script_without_saving(tmp_path: Path) -> None:
    """``paraview --script``: the GUI runs the script's text without ``__file__``; it must set
    up the view from the path it was written in and save nothing."""
    out = tmp_path / "out"
    run_scene(NET_AND_BOX, out)
    # a fresh profile whose first start does not stop at the modal welcome dialog
    version = subprocess.run([XVFB_RUN, "-a", PARAVIEW, "--version"], capture_output=True,
                             text=True, timeout=120).stdout.split()[-1]  # "paraview version 5.11.0"
    config = tmp_path / "home" / ".config" / "ParaView"
    config.mkdir(parents=True)
    (config / f"ParaView{version}.ini").write_text(
        "[General]\nGeneralSettings.ShowWelcomeDialog=0\n")
    env = dict(os.environ, HOME=str(tmp_path / "home"),
               XDG_CONFIG_HOME=str(tmp_path / "home" / ".config"))
    done = subprocess.run([XVFB_RUN, "-a", PARAVIEW, f"--script={out / SCRIPT_NAME}", "--exit"],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=180)
    assert done.returncode == 0 and "Traceback" not in done.stdout + done.stderr, done.stderr
    assert not (out / SCREENSHOT_NAME).exists()
