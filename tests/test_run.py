"""Runs through the public entry points: outputs, failure handling, lean imports, VTK read-back."""

from __future__ import annotations

import io
import os
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rodnet.cli import main
from rodnet.integrate.frames import StepStats
from rodnet.models.lumped import LumpedModel
from rodnet.io.recorder import Recorder
from rodnet.run import RunResult, prepare, run
from rodnet.scene import scene_from_dict, scene_from_toml
from tests.conftest import small_net_toml


def test_outputs_follow_the_contract(tmp_path: Path) -> None:
    scene = scene_from_toml(small_net_toml(duration=0.2, vtk="true"))
    r = run(scene, tmp_path, progress=False)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["status"] == "ok" and summary["steps"] > 0 and summary["wall_time_s"] > 0
    for key in ("max_mouth_area", "time_of_max_mouth_area", "distance_at_max_mouth_area", "max_tension"):
        assert np.isfinite(summary["metrics"][key])
    assert summary["nodes"]["net:corner:3"] == 28 and summary["scene"]["net"]["packing"] == 0.2
    data = np.load(tmp_path / "result.npz")
    n_frames, n_nodes = 21, 25 + 4
    assert data["time"].shape == (n_frames,) and data["positions"].shape == (n_frames, n_nodes, 3)
    assert data["velocities"].shape == data["positions"].shape
    assert data["tension"].shape == (n_frames, 44) and data["mouth_area"].shape == (n_frames,)
    assert data["distance"][0] == 0.0
    np.testing.assert_allclose(data["mouth_area"][0], 0.2**2 * 2 * (2 * np.sqrt(2) + 1) ** 2, rtol=1e-12)
    assert summary["metrics"]["max_mouth_area"] == pytest.approx(data["mouth_area"].max())
    assert r.summary["frames"] == n_frames


def test_vtk_series_reads_back_in_pyvista(tmp_path: Path) -> None:
    pv = pytest.importorskip("pyvista")
    run(scene_from_toml(small_net_toml(duration=0.6, vtk="true")), tmp_path, progress=False)
    data = np.load(tmp_path / "result.npz")
    reader = pv.get_reader(str(tmp_path / "result.pvd"))
    assert reader.number_time_points == len(data["time"]) == 61
    reader.set_active_time_point(50)
    assert reader.active_time_value == pytest.approx(0.5)
    mesh = reader.read()[0]
    assert mesh.n_points == 29 and mesh.n_cells == 44
    np.testing.assert_allclose(mesh.cell_data["tension"], data["tension"][50])
    np.testing.assert_allclose(mesh.points, data["positions"][50])
    assert data["tension"][50].max() > 0


def test_the_series_times_are_the_results_times(tmp_path: Path) -> None:
    """result.pvd holds each frame's time as result.npz does, to the last bit, so a frame can
    be picked by the time summary.json gives (a frame interval of 0.035 s makes times such as
    0.24500000000000002, which 9 digits had rounded and pyvista then refused)."""
    pv = pytest.importorskip("pyvista")
    text = small_net_toml(duration=0.3, vtk="true").replace("frame_interval = 0.01",
                                                            "frame_interval = 0.035")
    r = run(scene_from_toml(text), tmp_path, progress=False)
    reader = pv.get_reader(str(tmp_path / "result.pvd"))
    assert list(reader.time_values) == [float(t) for t in r.arrays["time"]]
    reader.set_active_time_value(r.summary["metrics"]["time_of_max_mouth_area"])


def test_divergence_stops_with_message_and_keeps_frames(tmp_path: Path, monkeypatch) -> None:
    # A stability limit reported 20 times too large lets the step through the checks; the run
    # then blows up, and must say so and keep what it computed: the energy guard (nothing does
    # work on the net, so its energy cannot grow) or the integrator's own check stops it.
    real = LumpedModel.stable_step
    monkeypatch.setattr(LumpedModel, "stable_step",
                        lambda self, damped=True: 20.0 * real(self, damped))
    r = run(scene_from_toml(small_net_toml(duration=1.0, vtk="true")), tmp_path, progress=False)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert r.status == summary["status"] == "failed"
    assert "diverged" in summary["message"] or "energy grew" in summary["message"]
    data = np.load(tmp_path / "result.npz")
    assert 1 <= len(data["time"]) < 101 and np.isfinite(data["positions"]).all()
    assert len(list((tmp_path / "vtk").glob("*.vtu"))) == len(data["time"])


def test_interrupt_keeps_frames(tmp_path: Path, monkeypatch) -> None:
    original = Recorder.__call__

    def interrupt_after_five(self, t, state):
        if len(self.time) == 5:
            raise KeyboardInterrupt
        original(self, t, state)

    monkeypatch.setattr(Recorder, "__call__", interrupt_after_five)
    r = run(scene_from_toml(small_net_toml(duration=0.5)), tmp_path, progress=False)
    assert r.status == "interrupted" and "Ctrl-C" in r.message
    assert r.summary["signal"] == "SIGINT"
    assert len(np.load(tmp_path / "result.npz")["time"]) == 5


def test_compile_time_is_the_compiling_inside_the_timed_run(tmp_path: Path, monkeypatch,
                                                           capsys) -> None:
    """``compile_time_s`` sums numba's compile events during the time stepping (nested ones
    once): a frame that compiles for 0.6 s (a fake event around a sleep) is counted, and the
    command line says so."""
    import time

    from numba.core import event

    original = Recorder.__call__

    def compile_on_third_frame(self, t, state):
        if len(self.time) == 3:
            with event.trigger_event("numba:compile", data={}):
                with event.trigger_event("numba:compile", data={}):
                    time.sleep(0.6)
        original(self, t, state)

    scene = tmp_path / "scene.toml"
    scene.write_text(small_net_toml(duration=0.1))
    main(["run", str(scene), "-o", str(tmp_path / "warm")])   # the kernels compiled and cached
    monkeypatch.setattr(Recorder, "__call__", compile_on_third_frame)
    main(["run", str(scene), "-o", str(tmp_path / "o")])
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["compile_time_s"] == pytest.approx(0.6, abs=0.1)
    assert summary["compile_time_s"] < summary["wall_time_s"]
    assert "(0.6 s of it compiling kernels" in capsys.readouterr().out


def test_more_threads_than_numba_may_use_is_said(tmp_path: Path, capsys) -> None:
    """``--threads`` beyond numba's pool (NUMBA_NUM_THREADS, else the cores) runs on the pool
    and says so."""
    from rodnet.kernels.threads import available

    scene = tmp_path / "scene.toml"
    scene.write_text(small_net_toml(duration=0.05))
    asked = available() + 1
    assert main(["run", str(scene), "-o", str(tmp_path / "o"), "--threads", str(asked)]) == 0
    assert f"--threads {asked}: ran on {available()}" in capsys.readouterr().err


def test_an_empty_output_directory_is_refused(tmp_path: Path, monkeypatch, capsys) -> None:
    """``-o ''`` or ``output.directory = ""`` would write into the working directory: both are
    refused (exit 2), and nothing is written there."""
    monkeypatch.chdir(tmp_path)
    scene = tmp_path / "scene.toml"
    scene.write_text(small_net_toml(duration=0.05))
    with pytest.raises(SystemExit) as info:
        main(["run", str(scene), "-o", ""])
    assert info.value.code == 2 and "is empty" in capsys.readouterr().err
    assert main(["run", str(scene), "--set", 'output.directory=""']) == 2
    assert "output.directory = '': must be a non-empty path" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.toml"]


def test_a_moment_along_a_free_twist_is_named(tmp_path: Path) -> None:
    """A rod clamped but for its twist (r1), a static moment about its axis: no equilibrium.
    The run fails (it does not hang or return a state) and the message names the free twist
    as one of the causes."""
    from tests.validation.test_statics import RIGHT_ANGLE_FRAME

    scene = (RIGHT_ANGLE_FRAME.format(elements=4)
             .replace(", [1.0, 1.0, 0.0]]", "]")
             .replace('fix = "clamp"', 'dofs = ["x", "y", "z", "r2", "r3"]')
             .replace("force = [0.0, 0.0, -1.0e-4]", "moment = [0.01, 0.0, 0.0]"))
    r = run(scene_from_toml(scene), tmp_path, progress=False)
    assert r.status == "failed" and "singular" in r.message
    assert "no support holds its twist r1" in r.message


def test_an_error_outside_the_physics_keeps_the_frames_and_says_failed(tmp_path: Path,
                                                                        monkeypatch) -> None:
    """An exception that is not the simulation's (a full disk while writing a frame): the
    frames before it are written, summary.json says failed and why, and the error is raised
    (a run had said ok for results cut short)."""
    original = Recorder.__call__

    def full_disk_on_fourth_frame(self, t, state):
        if len(self.time) == 3:
            raise OSError(28, "No space left on device")
        original(self, t, state)

    monkeypatch.setattr(Recorder, "__call__", full_disk_on_fourth_frame)
    with pytest.raises(OSError):
        run(scene_from_toml(small_net_toml(duration=0.2)), tmp_path, progress=False)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["status"] == "failed" and "No space left on device" in summary["message"]
    assert len(np.load(tmp_path / "result.npz")["time"]) == 3


def test_a_closed_progress_stream_does_not_stop_the_run() -> None:
    """``rodnet run ... 2>&1 | head -2``: once the pipe is closed the progress lines are
    dropped (the run goes on) instead of raising into the integrator, which had ended the run
    early."""
    from rodnet.progress import Progress

    class ClosedPipe(io.StringIO):
        def write(self, text: str) -> int:
            raise BrokenPipeError(32, "Broken pipe")

    for enabled in (True, None):          # the bar, and the log lines of a pipe
        bar = Progress(1.0, enabled=enabled, stream=ClosedPipe())
        bar(0.5, 1e-3, StepStats())
        bar(1.0, 1e-3, StepStats())
        bar.close()
        assert not bar.enabled


def test_a_closed_output_pipe_ends_the_command_without_a_traceback(tmp_path: Path,
                                                                  monkeypatch) -> None:
    """``rodnet run ... | head -1``: the report lines after the closed pipe are dropped and the
    command returns the run's status (0) instead of raising BrokenPipeError; the results are
    written."""
    class ClosedPipe(io.StringIO):
        def write(self, text: str) -> int:
            raise BrokenPipeError(32, "Broken pipe")

    scene = tmp_path / "s.toml"
    scene.write_text(small_net_toml(duration=0.02))
    monkeypatch.setattr(sys, "stdout", ClosedPipe())
    monkeypatch.setattr(sys, "stderr", sys.stderr)   # the command sends both to os.devnull
    assert main(["run", str(scene), "-o", str(tmp_path / "o"), "--quiet"]) == 0
    assert json.loads((tmp_path / "o" / "summary.json").read_text())["status"] == "ok"


def test_cli_failed_run_exit_status(tmp_path: Path, monkeypatch) -> None:
    real = LumpedModel.stable_step
    monkeypatch.setattr(LumpedModel, "stable_step",
                        lambda self, damped=True: 20.0 * real(self, damped))
    scene = tmp_path / "s.toml"
    scene.write_text(small_net_toml(duration=1.0))
    assert main(["run", str(scene), "-o", str(tmp_path / "o"), "--quiet"]) == 1
    assert (tmp_path / "o" / "summary.json").exists()


def test_lumped_run_imports_neither_pyvista_nor_trimesh(tmp_path: Path) -> None:
    scene = tmp_path / "s.toml"
    scene.write_text(small_net_toml(duration=0.05, vtk="true"))
    code = (f"import sys\nfrom rodnet.cli import main\n"
            f"assert main(['run', {str(scene)!r}, '-o', {str(tmp_path / 'o')!r}, '--quiet']) == 0\n"
            "assert 'pyvista' not in sys.modules and 'trimesh' not in sys.modules\n"
            "assert 'matplotlib' not in sys.modules\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert not (tmp_path / "o" / "net.png").exists()  # nothing written that was not asked for


def _rendering_works() -> bool:
    probe = "import pyvista as pv; pv.Plotter(off_screen=True).screenshot()"
    try:
        return subprocess.run([sys.executable, "-c", probe], capture_output=True, timeout=120).returncode == 0
    except (subprocess.TimeoutExpired, OSError):
        return False


def test_demo_style_figures(tmp_path: Path) -> None:
    pytest.importorskip("pyvista")
    pytest.importorskip("matplotlib")
    if not _rendering_works():
        pytest.skip("off-screen rendering is not available on this machine (needs libegl1, libgl1-mesa-dri)")
    scene = tmp_path / "s.toml"
    scene.write_text(small_net_toml(duration=0.3) + "picture = true\nplot = true\n")
    assert main(["run", str(scene), "-o", str(tmp_path / "o"), "--quiet"]) == 0
    for name in ("net.png", "deployment.png"):
        png = (tmp_path / "o" / name).read_bytes()
        assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000


def test_failed_run_keeps_its_step_counts(tmp_path: Path, monkeypatch) -> None:
    real = LumpedModel.stable_step
    monkeypatch.setattr(LumpedModel, "stable_step",
                        lambda self, damped=True: 20.0 * real(self, damped))
    r = run(scene_from_toml(small_net_toml(duration=1.0)), tmp_path, progress=False)
    assert r.status == "failed" and r.summary["steps"] > 0


def test_explicit_step_ignores_a_segment_between_two_supported_nodes(tmp_path: Path) -> None:
    """A segment whose two ends are held does not move and sets no stability limit (S10); it
    used to make the limit 0 and the run crash on an infinite step count."""
    scene = scene_from_toml("""
[simulation]
duration = 0.01
integrator = "explicit"
[model]
type = "lumped"
axial = "linear"
[[materials]]
name = "steel"
density = 7800.0
youngs_modulus = 2.0e11
poisson_ratio = 0.3
diameter = 0.01
[[rods]]
name = "a"
material = "steel"
points = [[0, 0, 0], [1, 0, 0], [2, 0, 0]]
elements = 3
[[supports]]
node = "a:0"
fix = "pin"
[[supports]]
node = "a:1"
fix = "pin"
[[loads]]
node = "a:end"
force = [0.0, 0.0, -1.0]
[output]
vtk = false
""")
    free_part = prepare(scene).model
    assert 0.0 < free_part.stable_step() < 1e-3
    result = run(scene, tmp_path, progress=False)
    assert result.status == "ok"
    assert result.arrays["positions"][-1, -1, 2] < 0.0      # the free end moves down



ROLLUP = Path(__file__).parent.parent / "validation" / "cases" / "cantilever_rollup" / "scene.toml"


def test_warning_when_an_element_reaches_the_rotation_stop(tmp_path: Path, capsys) -> None:
    """The roll-up cantilever (EI = 98.17 N m^2, L = 1 m) as one element: an end moment M turns
    it by M L / EI, 800 N m by 8.1 rad, so the rotation stop (C52) holds it at 5 rad and the run
    warns, on the console and in summary.json; 300 N m (3.1 rad, the section's own answer)
    gives no warning."""
    one = ["--set", "rods[0].elements=1", "--set", "simulation.load_steps=20", "--quiet"]
    out = tmp_path / "far"
    assert main(["run", str(ROLLUP), "-o", str(out), "--set", "loads[0].moment=[0, 0, 800]", *one]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert len(summary["warnings"]) == 1 and "past the rotation stop at 5 rad" in summary["warnings"][0]
    assert "rodnet: warning: a rod element turned by 5.0" in capsys.readouterr().err
    rotations = np.load(out / "result.npz")["rotations"][-1]  # (2, 4): clamp, tip
    w = abs(float(np.dot(rotations[0], rotations[1])))  # cos of half the angle between the triads
    # the smallest angle between the triads, 2 pi - 5 rad: the tip stays at 5 rad, not 8.1
    assert 2.0 * np.arccos(min(w, 1.0)) == pytest.approx(2.0 * np.pi - 5.0, abs=0.01)
    out = tmp_path / "near"
    assert main(["run", str(ROLLUP), "-o", str(out), "--set", "loads[0].moment=[0, 0, 300]", *one]) == 0
    assert json.loads((out / "summary.json").read_text())["warnings"] == []


def test_two_supports_on_one_node_are_combined_and_said_so(tmp_path: Path) -> None:
    """A pin and a clamp on the cantilever's root: the run is the clamped one (tip deflection P
    L^3 / 3 EI within 1 %), with a warning naming both entries."""
    out = tmp_path / "two"
    text = ROLLUP.read_text()
    assert text.count("[[supports]]") == 1
    scene = tmp_path / "two.toml"
    scene.write_text(text + '\n[[supports]]\nnode = "beam:start"\nfix = "pin"\n')
    assert main(["run", str(scene), "-o", str(out), "--quiet", "--set",
                 "loads[0].moment=[0, 0, 0]", "--set", "loads[0].force=[0, 0, -1]"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    tip = np.load(out / "result.npz")["positions"][-1, summary["nodes"]["beam:end"]]
    EI = 2.0e11 * np.pi * 0.01**4 / 64
    assert tip[2] == pytest.approx(-1.0 / (3.0 * EI), rel=1e-2)
    assert summary["warnings"] == ["supports[0] and supports[1] hold the same node 0: the DOFs "
                                   "they fix are combined"]


def test_a_fixed_step_longer_than_the_frame_interval_is_said_so(tmp_path: Path) -> None:
    """A fixed implicit step of 0.05 s with frames every 0.01 s steps at 0.01 s (the steps land
    on the frames): the same frames as dt = 0.01 s, and a warning naming both keys."""
    frames = {}
    for dt in (0.05, 0.01):
        r = run(scene_from_toml(PINNED_ROD, ["simulation.integrator=backward-euler",
                                             f"simulation.dt={dt}", "simulation.duration=0.05",
                                             "output.frame_interval=0.01"]),
                tmp_path / str(dt), progress=False)
        frames[dt] = r
    def told(result: RunResult) -> list[str]:   # (backward Euler's energy loss is told too)
        return [w for w in result.summary["warnings"] if "output.frame_interval" in w]

    assert told(r) == []
    long = frames[0.05]
    assert long.summary["steps"] == 5
    np.testing.assert_allclose(long.arrays["positions"], frames[0.01].arrays["positions"],
                               rtol=0, atol=1e-12)
    assert len(told(long)) == 1
    assert told(long)[0].startswith("simulation.dt = 0.05 s is longer than "
                                    "output.frame_interval = 0.01 s")


def test_dt_max_below_the_default_dt_bounds_every_step(tmp_path: Path) -> None:
    """``dt_max`` alone (below the default ``dt`` of 1 ms) bounds the first step too: no step
    of the adaptive run is longer (it was raised to ``dt`` and ignored)."""
    r = run(scene_from_toml(PINNED_ROD, ["simulation.adaptive=true", "simulation.dt=1e-3",
                                         "simulation.dt_max=2e-4", "simulation.duration=0.01"]),
            tmp_path, progress=False)
    assert r.status == "ok", r.message
    assert r.summary["integrator"]["dt_max"] <= 2e-4 * (1 + 1e-12)
    assert r.summary["steps"] >= 0.01 / 2e-4


@pytest.mark.parametrize("model, duration", [("lumped", 0.002), ("cosserat", 2e-4)])
def test_an_explicit_step_set_by_the_viscosity_is_said_so(tmp_path: Path, model: str,
                                                          duration: float) -> None:
    """Kelvin-Voigt damping shortens the explicit limit (S10, C48) about as 1 / zeta: with a
    viscosity of 1e7 Pa s (tau 0.1 s) the 10 cm segments of the rod step at 3.3e-7 s instead of
    2.6e-4 s, and the warnings name the key; at 1e4 Pa s they say nothing. The same for
    Cosserat rods, whose explicit plan takes its own step (it said nothing before)."""
    said, limits = {}, {}
    for viscosity in (0.0, 1e4, 1e7):
        r = run(scene_from_toml(PINNED_ROD, [
            f"model.type={model}", "simulation.integrator=explicit", "simulation.adaptive=true",
            f"simulation.duration={duration}", f"materials[0].viscosity={viscosity}"]),
            tmp_path / str(viscosity), progress=False)
        assert r.status == "ok", r.message
        said[viscosity] = [w for w in r.summary["warnings"] if "materials.viscosity" in w]
        limits[viscosity] = r.summary["integrator"]["stable_step"]
    assert said[0.0] == said[1e4] == [] and len(said[1e7]) == 1
    assert "times shorter" in said[1e7][0]
    shorter = float(said[1e7][0].split(" times shorter")[0].split(", ")[-1])
    assert shorter == pytest.approx(limits[0.0] / limits[1e7], rel=0.01)


def test_an_element_held_at_both_ends_and_a_structure_held_everywhere(tmp_path: Path) -> None:
    """Clamps on the first two nodes of a rod leave its first element no bound (C48): the
    explicit plan's bent-element factors were NaN and the run 'diverged at t = nan'; now it
    runs as the cantilever of the rest. Clamps on every node leave nothing to move: refused
    naming supports, before anything is written."""
    two = PINNED_ROD.replace('fix = "pin"', 'fix = "clamp"') + \
        '[[supports]]\nnode = "r:1"\nfix = "clamp"\n'
    r = run(scene_from_toml(two, ["simulation.integrator=explicit", "simulation.adaptive=true",
                                  "simulation.duration=0.02"]), tmp_path / "two", progress=False)
    assert r.status == "ok", r.message
    z = r.arrays["positions"][:, -1, 2]
    assert np.isfinite(z).all() and z[-1] < -1e-4         # the free part falls
    every = two.replace("elements = 10", "elements = 1").replace('node = "r:1"', 'node = "r:end"')
    from rodnet.errors import SceneError
    with pytest.raises(SceneError) as info:
        run(scene_from_toml(every), tmp_path / "every", progress=False)
    assert info.value.key == "supports" and "nothing can move" in str(info.value)
    assert not (tmp_path / "every").exists()


def test_a_load_its_supports_take_whole_is_said_so(tmp_path: Path) -> None:
    """A force and a moment on the clamped root of the cantilever load nothing but the clamp:
    the rod stays straight and the run warns, naming the load; a force on the tip does not."""
    scene = tmp_path / "root.toml"
    scene.write_text(ROLLUP.read_text().replace('node = "beam:end"', 'node = "beam:start"', 1))
    out = tmp_path / "root"
    assert main(["run", str(scene), "-o", str(out), "--quiet", "--set",
                 "loads[0].force=[0, 0, -1]", "--set", "loads[0].moment=[0, 0, 5]"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    positions = np.load(out / "result.npz")["positions"]
    assert np.abs(positions[-1] - positions[0]).max() == 0.0
    assert len(summary["warnings"]) == 1
    assert summary["warnings"][0].startswith("loads[0] acts on node 0 ('beam:start')")
    out = tmp_path / "tip"
    assert main(["run", str(ROLLUP), "-o", str(out), "--quiet", "--set",
                 "loads[0].moment=[0, 0, 0]", "--set", "loads[0].force=[0, 0, -1]"]) == 0
    assert json.loads((out / "summary.json").read_text())["warnings"] == []


STEEL_BEAM = """
[simulation]
type = "static"
[model]
axial = "linear"
[[materials]]
name = "steel"
density = 7850.0
youngs_modulus = 2.0e11
diameter = 0.01
[[rods]]
name = "beam"
material = "steel"
points = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]
elements = {elements}
{rest}
[output]
vtk = false
"""
"""A static steel beam, 1 m x 10 mm, along x: ``{elements}`` and its supports and loads
(``{rest}``) to fill in."""


def test_a_twist_its_support_holds_is_said_so_and_a_bend_is_not(tmp_path: Path) -> None:
    """A moment along the rod's axis on a node whose support holds only its position and twist
    (r1) is taken whole by the support (outside check: no warning, while a fully held node's
    got one); a moment about a bending axis there bends the simply supported rod, untold."""
    beam = STEEL_BEAM.format(elements=10, rest="""
[[supports]]
node = "beam:start"
dofs = ["x", "y", "z", "r1"]
[[supports]]
node = "beam:end"
dofs = ["y", "z"]
[[loads]]
node = "beam:start"
moment = {moment}
""")
    told = {}
    for label, moment in (("twist", "[0.01, 0.0, 0.0]"), ("bend", "[0.0, 0.01, 0.0]")):
        r = run(scene_from_toml(beam.format(moment=moment)), tmp_path / label, progress=False)
        assert r.status == "ok", r.message
        told[label] = [w for w in r.summary["warnings"] if w.startswith("loads[0] acts on node 0")]
        moved = np.abs(r.arrays["positions"][-1] - r.arrays["positions"][0]).max()
        assert (moved == 0.0) == (label == "twist")
    assert told["twist"] and "(r1)" in told["twist"][0] and not told["bend"]


@pytest.mark.parametrize("axial", ["tension-only", "linear"])
def test_a_tension_only_column_folded_inside_out_is_said_so(tmp_path: Path, axial: str) -> None:
    """A clamped rod pushed along its axis by 10 N (a tenth of its Euler load): with the linear
    law it shortens by P L / EA and no warning; with the tension-only law nothing resists until
    every element has folded through itself, where only the regularising spring of C51 (0.01
    EA) holds the load, and the run says so."""
    out = tmp_path / axial
    assert main(["run", str(ROLLUP), "-o", str(out), "--quiet", "--set", f"model.axial={axial}",
                 "--set", "loads[0].moment=[0, 0, 0]", "--set", "loads[0].force=[-10, 0, 0]"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    tip = np.load(out / "result.npz")["positions"][-1, summary["nodes"]["beam:end"]]
    if axial == "linear":
        assert tip[0] == pytest.approx(1.0 - 10.0 / (2.0e11 * np.pi * 0.01**2 / 4), rel=1e-12)
        assert summary["warnings"] == []
    else:
        assert tip[0] < 0.0                       # through the clamp
        assert len(summary["warnings"]) == 1
        assert summary["warnings"][0].startswith("20 rod element(s) turned inside out")
        assert "model.axial = 'linear'" in summary["warnings"][0]



PUSHED_ROD = """
[simulation]
type = "dynamic"
duration = 0.05
gravity = [0.0, 0.0, 0.0]
[model]
type = "cosserat"
axial = "{axial}"
[[materials]]
name = "m"
density = 1000.0
youngs_modulus = 2.0e9
poisson_ratio = 0.4
diameter = 2.0e-3
[[rods]]
name = "r"
material = "m"
points = [[0, 0, 0], [0.2, 0, 0]]
elements = 10
[[masses]]
node = "r:start"
mass = 0.02
[[loads]]
node = "r:start"
force = [1.0, 0.0, 0.0]
[output]
frame_interval = 0.005
vtk = false
"""


@pytest.mark.parametrize("axial", ["tension-only", "linear"])
def test_a_rod_pushed_from_behind_through_itself_is_told_why(tmp_path: Path, axial: str) -> None:
    """A free rod whose 20 g end mass is pushed along the rod by 1 N: with the tension-only law
    the first element has no resistance to shortening, and the mass runs through it in about
    sqrt(2 L_e m / F) = 0.028 s (the element is 2 cm); the warning names the law, not the
    element count or the step (which would not help). With the linear law the rod pushes the
    rest along and nothing folds."""
    r = run(scene_from_toml(PUSHED_ROD.format(axial=axial)), tmp_path, progress=False)
    assert r.status == "ok", r.message
    x = r.arrays["positions"][-1]
    first = np.linalg.norm(x[1] - x[0])
    folded = [w for w in r.summary["warnings"] if "inside out" in w]
    if axial == "linear":
        assert first == pytest.approx(0.02, rel=1e-3) and folded == []
    else:
        assert first < 0.01 and len(folded) == 1
        assert "pushed them through themselves" in folded[0]
        assert "model.axial = 'linear'" in folded[0] and "more elements" not in folded[0]

PINNED_ROD = """
[simulation]
type = "dynamic"
duration = 0.2
gravity = [0.0, 0.0, -9.81]
integrator = "bdf2"
dt = 1e-4
adaptive = false
[model]
axial = "linear"
[[materials]]
name = "m"
density = 1000.0
youngs_modulus = 1e8
poisson_ratio = 0.3
diameter = 0.01
[[rods]]
name = "r"
material = "m"
points = [[0, 0, 0], [1, 0, 0]]
elements = 10
[[supports]]
node = "r:start"
fix = "pin"
[output]
vtk = false
frame_interval = 0.001
"""


def test_the_vtk_frames_carry_the_rods_section_triads(tmp_path: Path) -> None:
    """A rod along x starts with d1 = x, d2 = z, d3 = -y (rod_model.md, Node triads); every
    frame's d1, d2, d3 are the columns of its ``rotations`` in result.npz (single precision)."""
    meshio = pytest.importorskip("meshio")
    from rodnet.kernels.so3 import quat_to_matrix

    text = PINNED_ROD.replace("vtk = false", "vtk = true").replace("duration = 0.2",
                                                                  "duration = 0.02")
    r = run(scene_from_toml(text), tmp_path, progress=False)
    first = meshio.read(tmp_path / "vtk" / "frame_00000.vtu")
    np.testing.assert_allclose(first.point_data["d1"], np.tile([1.0, 0.0, 0.0], (11, 1)),
                               atol=1e-7)
    np.testing.assert_allclose(first.point_data["d3"], np.tile([0.0, -1.0, 0.0], (11, 1)),
                               atol=1e-7)
    last = meshio.read(tmp_path / "vtk" / f"frame_{len(r.arrays['time']) - 1:05d}.vtu")
    triads = quat_to_matrix(r.arrays["rotations"][-1])
    for k, name in enumerate(("d1", "d2", "d3")):
        np.testing.assert_allclose(last.point_data[name], triads[:, :, k], atol=1e-7)
    assert np.abs(triads[:, :, 0] - [1.0, 0.0, 0.0]).max() > 1e-3     # the rod has swung


def test_support_reactions_balance_the_momentum_of_a_swinging_rod(tmp_path: Path) -> None:
    """A rod pinned at one end falls from the horizontal: the rate of its momentum (central
    differences of the saved frames) is its weight plus the pin's reaction, to the frames'
    differencing error (measured 2e-4 of the largest force at 0.5 s)."""
    r = run(scene_from_toml(PINNED_ROD), tmp_path, progress=False)
    assert r.status == "ok", r.message
    t, v = r.arrays["time"], r.arrays["velocities"]
    reaction = r.arrays["support_reactions"][:, 0]                  # (F, 3)
    mass = prepare(scene_from_toml(PINNED_ROD)).mass                  # (N,)
    momentum = np.einsum("n,fni->fi", mass, v)
    rate = (momentum[2:] - momentum[:-2]) / (t[2:] - t[:-2])[:, None]
    forces = reaction[1:-1] + mass.sum() * np.array([0.0, 0.0, -9.81])
    assert np.abs(forces).max() > 0.5                               # the pin works
    assert np.abs(rate - forces).max() < 1e-3 * np.abs(forces).max()


def test_an_explicit_fixed_step_with_no_room_for_the_scaled_rotary_inertia_is_refused() -> None:
    """Fixed explicit steps of a Cosserat rod between ``ROTATION_SAFETY`` of the translations'
    limit and the limit itself were accepted with the rotary inertia raised 1e16 times (C49),
    which held the sections still: a cantilever given its second mode's velocities moved 2.7e-5
    m instead of 1e-3 m. Such a step is refused naming simulation.dt and the largest step that
    works; just below it the inertia is raised by tens, not by orders of magnitude."""
    import re

    from rodnet.errors import SceneError
    explicit = ["simulation.integrator=explicit", "simulation.adaptive=false"]
    with pytest.raises(SceneError) as info:
        prepare(scene_from_toml(PINNED_ROD, explicit + ["simulation.dt=1.0"]))
    assert info.value.key == "simulation.dt" and "scaled rotary inertia" in str(info.value)
    largest = float(re.search(r"use dt <= ([0-9.e+-]+) s", str(info.value)).group(1))
    with pytest.raises(SceneError, match="scaled rotary inertia"):
        prepare(scene_from_toml(PINNED_ROD, explicit + [f"simulation.dt={1.02 * largest}"]))
    below = explicit + [f"simulation.dt={0.98 * largest}"]
    built = prepare(scene_from_toml(PINNED_ROD, below)).built
    assert 1.0 < built.rotary_inertia_scale < 1e3


@pytest.mark.parametrize("model", ["lumped", "cosserat"])
def test_a_clamp_on_threads_without_rotations_is_a_pin_and_says_so(tmp_path: Path, capsys,
                                                                   model: str) -> None:
    """A horizontal 1 m cantilever, clamped, a 1 N tip force down: the lumped model has no
    rotations, so the clamp holds the node as a pin does and the thread hangs straight below
    it (tip at -1 m, stretched by 1 N / EA), with a warning naming the support; Cosserat rods
    are clamped, bend by P L^3 / 3 EI (within 1 % at 20 elements) and give no warning."""
    out = tmp_path / model
    # fifty load steps: in ten the chain ends folded on itself (test_statics.py)
    assert main(["run", str(ROLLUP), "-o", str(out), "--quiet", "--set", f"model.type={model}",
                 "--set", "loads[0].moment=[0, 0, 0]", "--set", "loads[0].force=[0, 0, -1]",
                 "--set", "simulation.load_steps=50"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    tip = np.load(out / "result.npz")["positions"][-1, summary["nodes"]["beam:end"]]
    EA, EI = 2.0e11 * np.pi * 0.01**2 / 4, 2.0e11 * np.pi * 0.01**4 / 64
    if model == "lumped":
        assert tip == pytest.approx([0.0, 0.0, -(1.0 + 1.0 / EA)], abs=1e-9)
        assert len(summary["warnings"]) == 1
        assert summary["warnings"][0].startswith("supports[0].fix = 'clamp' holds only the node's "
                                                 "position, as fix = 'pin' does")
        assert "rodnet: warning: supports[0].fix = 'clamp'" in capsys.readouterr().err
    else:
        assert tip[2] == pytest.approx(-1.0 / (3.0 * EI), rel=1e-2)
        assert summary["warnings"] == []


PENDULUM = """
[simulation]
type = "dynamic"
duration = 0.5
dt = {dt}
adaptive = false
integrator = "{integrator}"
gravity = [0.0, 0.0, -9.81]
[model]
axial = "linear"
[[materials]]
name = "steel"
density = 7800.0
youngs_modulus = 2.0e11
poisson_ratio = 0.3
diameter = 0.02
[[rods]]
name = "beam"
material = "steel"
points = [[0.0, 0.0, 0.0], [0.2, 0.0, 0.0]]
elements = 4
[[supports]]
node = "beam:start"
fix = "pin"
[output]
vtk = false
frame_interval = {dt}
"""
"""A stiff steel rod (0.2 m x 20 mm) on a pin, released horizontal: a pendulum whose axial
modes no fixed step of a millisecond resolves."""


LANDING = """
[simulation]
duration = 0.5
gravity = [0.0, 0.0, -9.81]
integrator = "midpoint"
adaptive = false
dt = {dt}
[model]
type = "cosserat"
bending = false
torsion = false
[[materials]]
name = "kevlar"
density = 1440.0
youngs_modulus = 7.0e10
diameter = 0.002
[[rods]]
name = "thread"
material = "kevlar"
points = [[-0.5, 0, 0.05], [0.5, 0, 0.05]]
elements = {elements}
[[masses]]
node = "thread:start"
mass = 0.1
[[masses]]
node = "thread:end"
mass = 0.1
[[bodies]]
name = "block"
shape = "box"
size = [2.0, 2.0, 0.2]
position = [0.0, 0.0, -0.1]
fixed = true
[contact]
stiffness = 1.0e5
friction = 0.0
[output]
frame_interval = 0.01
vtk = false
"""
"""A cable thread with 0.1 kg end masses dropped flat onto a box from 4 cm, no damping or
friction: the midpoint rule's penalty forces at the step's midpoint add energy where contact
switches on within a step (docs/contact.md)."""


@pytest.mark.parametrize("integrator, dt, stops", [("midpoint", 0.002, True),
                                                    ("generalized-alpha", 0.008, False)])
def test_energy_guard_counts_gravity(tmp_path: Path, integrator: str, dt: float,
                                     stops: bool) -> None:
    """Under constant gravity alone the energy with the weight's potential cannot rise. A
    thread bouncing on a box under the midpoint rule at a fixed 2 ms gains it: 0.10 J to 0.39 J
    by 0.35 s. The run stops on the energy and keeps its frames; generalized-alpha on a steel
    pendulum at 8 ms completes, its energy never above the start's. (The midpoint rule on
    that pendulum gained energy without bound at 4 ms until its stresses took the step's mean
    strains, C56: now within 1e-7 of it.)"""
    text = LANDING.format(dt=dt, elements=10) if integrator == "midpoint" else \
        PENDULUM.format(dt=dt, integrator=integrator)
    r = run(scene_from_toml(text), tmp_path, progress=False)
    data = np.load(tmp_path / "result.npz")
    if stops:
        assert r.status == "failed" and "energy grew" in r.message, r.message
        assert "gravity" in r.message
        assert 2 <= len(data["time"]) and np.isfinite(data["positions"]).all()
        return
    assert r.status == "ok", r.message
    mass = 7800.0 * np.pi * 0.01**2 * 0.2
    height = data["positions"][:, :, 2].mean(axis=1)     # equal node masses but the ends'
    assert height.min() < -0.05                           # it swings down
    assert data["tension"].max() < 3.0 * mass * 9.81      # about 1.5 mg at the bottom


def test_energy_guard_counts_constant_loads(tmp_path: Path) -> None:
    """A load constant in time has the potential ``-f . x``: the energy guard counts it, so a
    load of 1e-9 N does not switch the guard off. The bouncing thread of
    :func:`test_energy_guard_counts_gravity` with that load on one end still gains energy
    under the midpoint rule at 2 ms and still stops (it had run to the end as "ok", 71 times
    its energy on another such scene, outside check)."""
    loaded = LANDING.format(dt=0.002, elements=10) + \
        '[[loads]]\nnode = "thread:end"\nforce = [0.0, 0.0, 1.0e-9]\n'
    r = run(scene_from_toml(loaded), tmp_path, progress=False)
    assert r.status == "failed" and "energy grew" in r.message, r.message
    assert "gravity and loads" in r.message


PRESSED = """
[simulation]
duration = 0.2
gravity = [0.0, 0.0, 0.0]
integrator = "bdf2"
adaptive = false
dt = 0.001
[model]
type = "lumped"
[[materials]]
name = "kevlar"
density = 1440.0
youngs_modulus = 7.0e10
diameter = 0.001
[[rods]]
name = "t"
material = "kevlar"
points = [[0.0, 0.0, 0.0025], [0.1, 0.0, 0.0025]]
elements = 1
[[masses]]
node = "t:start"
mass = 0.005
[[masses]]
node = "t:end"
mass = 0.005
[[loads]]
node = "t:start"
force = [0.0, 0.0, -5.0]
[[loads]]
node = "t:end"
force = [0.0, 0.0, -5.0]
[[bodies]]
name = "b"
shape = "box"
size = [0.3, 0.3, 0.1]
position = [0.05, 0.0, -0.05]
fixed = true
[contact]
stiffness = 1.0e6
friction = 0.0
[output]
frame_interval = 0.01
vtk = false
"""
"""A short thread pressed 2 mm down onto a box by 10 N (outside check): it lands at 2 m/s
within the first frame interval, and BDF2's 1 ms steps, far longer than the contact's period
(0.4 ms), damp the landing."""


def test_an_energy_loss_between_frames_is_told_in_joules(tmp_path: Path) -> None:
    """The energy lost is the loads' work on the way down, ``10 N x 2 mm`` = 0.02 J, about a
    thousand times the largest energy in motion at a saved frame: the warning gives the joules
    and says the motion fell between the frames (it had said "fell by 1.16e+05 %")."""
    r = run(scene_from_toml(PRESSED), tmp_path, progress=False)
    assert r.status == "ok", r.message
    a = r.arrays
    motion = a["kinetic_energy"] + a["elastic_energy"] + a["contact_energy"]
    lost = (motion + a["potential_energy"])[0] - (motion + a["potential_energy"])[-1]
    assert lost == pytest.approx(10.0 * 0.002, rel=0.02)
    told = [w for w in r.summary["warnings"] if w.startswith("the energy fell by")]
    assert len(told) == 1 and f"{lost:.3g} J, " in told[0] and "between the frames" in told[0]


LINE_LOADED = """
[simulation]
duration = 0.02
integrator = "{integrator}"
gravity = [0.0, 0.0, 0.0]
[model]
type = "lumped"
axial = "linear"
[[materials]]
name = "m"
density = 1440.0
youngs_modulus = 7.0e10
diameter = 1.0e-3
[[rods]]
name = "t"
material = "m"
points = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]
elements = 1
[[supports]]
node = "t:start"
[[masses]]
node = "t:end"
mass = 1.0
[output]
frame_interval = 0.0005
vtk = false
"""
"""A 1 kg mass on a 1 m thread (k = EA / L = 5.5e4 N/m, period 27 ms) pulled along the thread
from rest; a one-element thread lumps its load half on each end."""


@pytest.mark.parametrize("integrator", ["explicit", "bdf2", "rk45"])
def test_a_line_load_alone_does_work_without_stopping_the_run(tmp_path: Path,
                                                             integrator: str) -> None:
    """A suddenly applied line load is the scene's only load: the energy it puts in is not an
    instability (the energy guard had stopped every such run on its first loaded step). The
    mass swings to twice the static stretch, as under the same force given as a point load."""
    text = LINE_LOADED.format(integrator=integrator)
    line = run(scene_from_toml(text + '[[line_loads]]\non = "t"\n'
                               'force_per_length = [200.0, 0.0, 0.0]\n'), tmp_path / "line",
               progress=False)
    point = run(scene_from_toml(text + '[[loads]]\nnode = "t:end"\nforce = [100.0, 0.0, 0.0]\n'),
                tmp_path / "point", progress=False)
    assert line.status == "ok" and point.status == "ok", line.message
    stretch = line.arrays["positions"][:, 1, 0] - 1.0
    static = 100.0 / (7.0e10 * np.pi / 4 * 1e-6)
    assert stretch.max() == pytest.approx(2.0 * static, rel=0.02)   # amplification 2, 20 ms
    np.testing.assert_allclose(stretch, point.arrays["positions"][:, 1, 0] - 1.0,
                               atol=1e-9 * static)


FREE_ROD = (PINNED_ROD[:PINNED_ROD.index("[[supports]]")]
            .replace("gravity = [0.0, 0.0, -9.81]", "gravity = [0.0, 0.0, 0.0]")
            .replace("points = [[0, 0, 0], [1, 0, 0]]\nelements = 10",
                     "points = [[0, 0, 0], [0.5, 0, 0], [0.5, 0.5, 0.2]]\nelements = 8\n"
                     "velocity = [0.0, 0.3, 1.0]\nangular_velocity = [3.0, -2.0, 5.0]")
            + "[output]\nvtk = false\nframe_interval = 0.005\n")
"""The bent rod thrown spinning in free space, for 0.05 s (PINNED_ROD without its pin)."""


@pytest.mark.parametrize("integrator", ["explicit", "midpoint"])
def test_the_outputs_give_the_angular_momentum_of_a_free_rod(tmp_path: Path,
                                                            integrator: str) -> None:
    """A bent rod thrown spinning in free space: its angular momentum summed from result.npz
    (node_mass, rotation_node_inertia, which explicit runs raise by C49, and the rotation
    nodes' quaternions and spins) is constant; the node masses add up to rho A L."""
    from rodnet.kernels import so3
    r = run(scene_from_toml(FREE_ROD, [f"simulation.integrator={integrator}",
                                       "simulation.adaptive=true", "simulation.duration=0.05"]),
            tmp_path, progress=False)
    assert r.status == "ok", r.message
    a = r.arrays
    m, J = a["node_mass"], a["rotation_node_inertia"]
    assert m.sum() == pytest.approx(1000.0 * np.pi * 0.01**2 / 4 * (0.5 + np.hypot(0.5, 0.2)),
                                    rel=1e-12)
    x, v = a["positions"], a["velocities"]
    q, w = a["rotation_node_quaternions"], a["rotation_node_spins"]

    def drift(inertia: np.ndarray) -> float:
        L = np.einsum("n,fni->fi", m, np.cross(x, v))
        for f in range(len(x)):
            L[f] += sum(so3.quat_to_matrix(q[f, k]) @ (inertia[k] * w[f, k])
                        for k in range(len(inertia)))
        return float(np.abs(L - L[0]).max() / np.linalg.norm(L[0]))
    assert drift(J) < 1e-10
    assert drift(1.1 * J) > 1e-6       # the sections trade momentum with the centreline


@pytest.mark.parametrize("model", ['type = "lumped"', 'type = "cosserat"\nbending = false\ntorsion = false',
                                   'type = "cosserat"\nknots = "pinned"',
                                   'type = "kirchhoff"\nknots = "pinned"'])
def test_the_scene_in_the_summary_runs_the_same_model(tmp_path: Path, model: str) -> None:
    """summary.json's scene, run again, is the same run: it left out bending = torsion =
    false of cable threads once, and ran them again as Cosserat rods."""
    text = small_net_toml(duration=0.02).replace('type = "lumped"', model)
    first = run(scene_from_toml(text), tmp_path / "first", progress=False)
    again = run(scene_from_dict(first.summary["scene"]), tmp_path / "again", progress=False)
    assert first.status == again.status == "ok"
    recorded = [{k: v for k, v in r.summary["scene"].items() if k != "output"}
                for r in (first, again)]
    assert recorded[0] == recorded[1]
    np.testing.assert_array_equal(again.arrays["positions"], first.arrays["positions"])
    assert again.arrays["positions"].shape == first.arrays["positions"].shape


def test_a_run_too_large_to_keep_or_to_step_is_refused_before_it_starts(tmp_path: Path) -> None:
    """A duration written in milliseconds as seconds asked numpy for 7.45 GiB of frame times
    and ended in a traceback; a stiffness many orders too high ended in an overflow inside the
    explicit loop. Both are bad input now, and nothing is written."""
    from rodnet.errors import SceneError

    too_long = small_net_toml(duration=1e7)
    with pytest.raises(SceneError, match=r"output\.frame_interval = 0\.01: saves 1e\+09 frames"):
        run(scene_from_toml(too_long), tmp_path / "long", progress=False)
    stiff = small_net_toml(duration=0.02).replace("[[materials]]", "[[materials]]\naxial_stiffness = 1e20")
    with pytest.raises(SceneError, match=r"simulation\.integrator = 'explicit': the explicit "
                                         r"stability limit of this scene is"):
        run(scene_from_toml(stiff), tmp_path / "stiff", progress=False)
    # a limit that rounds to zero is said so ("0 s ... inf steps" before, outside check)
    viscous = small_net_toml(duration=0.02).replace("viscosity = 2000000.0", "viscosity = 1e15")
    with pytest.raises(SceneError, match=r"stability limit of this scene rounds to 0 s: "):
        run(scene_from_toml(viscous), tmp_path / "viscous", progress=False)
    assert not (tmp_path / "long").exists() and not (tmp_path / "stiff").exists()


def test_a_frame_interval_longer_than_the_run_still_saves_its_end(tmp_path: Path) -> None:
    r = run(scene_from_toml(small_net_toml(duration=0.02).replace(
        "frame_interval = 0.01", "frame_interval = 1.0e8")), tmp_path / "o", progress=False)
    assert r.status == "ok" and list(r.arrays["time"]) == [0.0, 0.02] and r.summary["steps"] > 0


def test_an_error_no_check_caught_is_one_paragraph(tmp_path: Path, capsys, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """An overflow that no check of the scene caught (a diameter of 1e300 m did, before the
    materials had bounds) was a traceback; it is one paragraph and exit status 1."""
    module = sys.modules["rodnet.run"]   # the package's ``run`` is the function

    def overflow(*args, **kwargs):  # type: ignore[no-untyped-def]
        raise OverflowError("(34, 'Numerical result out of range')")

    monkeypatch.setattr(module, "run", overflow)
    monkeypatch.delenv("RODNET_TRACEBACK", raising=False)
    scene = tmp_path / "net.toml"
    scene.write_text(small_net_toml(duration=0.02))
    assert main(["run", str(scene), "-o", str(tmp_path / "o")]) == 1
    err = capsys.readouterr().err
    assert "an error the scene's checks did not catch: OverflowError" in err
    assert "nothing was written" in err and "Traceback" not in err


UNDAMPED_NET = """
[simulation]
duration = 0.3
integrator = "explicit"
explicit_safety = {safety}
[model]
type = "lumped"
elements_per_thread = 2
[[materials]]
name = "kevlar"
density = 1440.0
youngs_modulus = 7.0e10
diameter = 1.0e-3
viscosity = 0.0
[net]
nodes_per_side = 5
mesh_length = 0.5
material = "kevlar"
packing = 0.1
corner_mass = 0.5
corner_thread_length = 0.5
launch_speed = 15.0
launch_angle_deg = 40.0
[output]
frame_interval = 0.005
vtk = false
"""
"""An outside check's undamped 5 x 5 net (its first snap at about 0.19 s)."""


def test_an_undamped_explicit_net_that_gains_energy_says_so(tmp_path: Path) -> None:
    """Undamped threads snapping at the default explicit step gain energy (this net: +45 %
    over 1 s in the outside check), below the guard's 100 %; the run warns with the rise, and
    at half the step the energy holds within the warning's 5 %."""
    rises = {}
    for safety in (0.5, 0.25):
        r = run(scene_from_toml(UNDAMPED_NET.format(safety=safety)), tmp_path / str(safety),
                progress=False)
        assert r.status == "ok", r.message
        energy = r.arrays["kinetic_energy"] + r.arrays["elastic_energy"]
        rises[safety] = energy.max() / energy[0] - 1.0
        told = [w for w in r.summary["warnings"] if "energy rose by" in w]
        assert bool(told) == (rises[safety] > 0.05), (safety, rises[safety])
    assert rises[0.5] > 0.05 > rises[0.25], rises


def _rope_over_drum(safety: float) -> str:
    """An Atwood machine: a light undamped rope (30 lumped segments) over a fixed frictionless
    drum of radius 5 cm, 1.2 kg and 1 kg at its ends, under gravity, explicit (outside check)."""
    arc = np.linspace(np.pi, 0.0, 25)
    r = 0.0515
    points = [[-r, 0.0, -0.3]] + [[r * np.cos(a), 0.0, r * np.sin(a)] for a in arc] + \
        [[r, 0.0, -0.3]]
    return f"""
[simulation]
duration = 0.5
gravity = [0.0, 0.0, -9.81]
integrator = "explicit"
explicit_safety = {safety}
[model]
type = "lumped"
[[materials]]
name = "rope"
density = 1000.0
youngs_modulus = 1.0e9
diameter = 0.002
mass_per_length = 0.002
axial_stiffness = 1.0e5
viscosity = 0.0
[[rods]]
name = "rope"
material = "rope"
points = {[[float(round(c, 9)) for c in p] for p in points]}
elements = 30
[[masses]]
node = "rope:start"
mass = 1.2
[[masses]]
node = "rope:end"
mass = 1.0
[[bodies]]
name = "drum"
shape = "cylinder"
size = [0.1, 0.1, 0.2]
orientation_deg = [90.0, 0.0, 0.0]
fixed = true
[contact]
stiffness = 1.0e5
damping = 0.0
friction = 0.0
[output]
frame_interval = 0.002
vtk = false
"""


def test_an_explicit_run_that_gains_energy_under_gravity_is_stopped(tmp_path: Path) -> None:
    """A light rope pressed on a drum by its weight, undamped, at the default explicit step:
    the energy with gravity's potential grows without bound (1e8 times by 0.46 s in the outside
    check, which the run reported as done). It is stopped once it has gained as much as it
    has in motion, warns with the rise, and keeps its frames up to the last one within that
    (the frame that failed the check is not kept). (At half the step the energy stays within
    3.4 % of the energy in motion over the 0.5 s, in 2.1 million steps.)"""
    r = run(scene_from_toml(_rope_over_drum(0.5)), tmp_path, progress=False)
    assert r.status == "failed" and "energy grew" in r.message and "gravity" in r.message
    assert any("energy, the potential of gravity included, rose by" in w
               for w in r.summary["warnings"])
    a = r.arrays
    motion = a["kinetic_energy"] + a["elastic_energy"] + a["contact_energy"]
    energy = motion + a["potential_energy"]
    gained = energy[-1] - energy[0]
    assert 0.05 * motion.max() < gained <= motion.max(), gained / motion.max()
    assert 10 < len(a["time"]) < 250


def test_the_last_frame_is_at_duration_and_every_run_has_its_reactions(tmp_path: Path) -> None:
    """6 x 0.05 s is 0.30000000000000004 in floating point: the last frame is stamped (and the
    run ends) at duration itself; a scene without supports has support_reactions (F, 0, 3)."""
    text = small_net_toml(duration=0.3).replace("frame_interval = 0.01", "frame_interval = 0.05")
    r = run(scene_from_toml(text), tmp_path / "o", progress=False)
    assert r.arrays["time"][-1] == 0.3 and len(r.arrays["time"]) == 7
    assert r.arrays["support_reactions"].shape == (7, 0, 3)


def test_keys_set_to_no_effect_are_told(tmp_path: Path) -> None:
    """An outside check found these accepted without a word."""
    text = small_net_toml(duration=0.02) + (
        '[contact]\nstiffness = 1.0e4\n[[loads]]\nnode = "net:knot:0"\nforce = [1.0, 0.0, 0.0]\n'
        "start = 0.05\n")
    r = run(scene_from_toml(text), tmp_path / "o", progress=False)
    assert r.status == "ok", r.message
    warnings = " | ".join(r.summary["warnings"])
    assert "[contact] has no effect" in warnings
    assert "loads[0].start = 0.05 s is not before simulation.duration = 0.02 s" in warnings
    from tests.conftest import falling_thread_toml
    rod = falling_thread_toml(duration=0.01).replace("elements = 20",
                                                     "elements = 20\nrotation_center = [0.0, 0.0, 0.0]")
    r = run(scene_from_toml(rod), tmp_path / "rod", progress=False)
    assert any("rods[0].rotation_center has no effect" in w for w in r.summary["warnings"])


def test_a_rod_whose_ends_meet_is_told_it_is_open(tmp_path: Path) -> None:
    """A ring given as a polyline back to its first point (outside check): its end nodes are
    not joined, so it is a split ring; the run says so (a nearly closed C does not)."""
    def ring(gap: float) -> str:
        angles = np.linspace(0.0, 2.0 * np.pi - gap, 13)
        points = [[float(np.cos(a)), float(np.sin(a)), 0.0] for a in angles]
        return f"""
[simulation]
type = "static"
[model]
axial = "linear"
[[materials]]
name = "steel"
density = 7850.0
youngs_modulus = 2.0e11
diameter = 0.01
[[rods]]
name = "ring"
material = "steel"
points = {points}
elements = 12
[[supports]]
node = "ring:3"
fix = "clamp"
[[loads]]
node = "ring:9"
force = [0.0, 0.01, 0.0]
[output]
vtk = false
"""
    told = {}
    for gap in (0.0, 0.1):
        r = run(scene_from_toml(ring(gap)), tmp_path / str(gap), progress=False)
        assert r.status == "ok", r.message
        told[gap] = [w for w in r.summary["warnings"] if "rods[0].points ends where it starts" in w]
    assert told[0.0] and not told[0.1]


def test_fix_beside_dofs_is_told_to_have_no_effect(tmp_path: Path) -> None:
    """``fix = "clamp"`` with ``dofs = ["y", "z"]`` is a roller (outside check: a propped
    cantilever's deflection where fixed-fixed was meant): dofs is the whole set, and the run
    says that fix did nothing; without fix the same support is not warned of, and a support
    with neither key is a clamp."""
    beam = STEEL_BEAM.format(elements=32, rest="""
[[supports]]
node = "beam:start"
[[supports]]
node = "beam:end"
{end}
[[loads]]
node = "beam:16"
force = [0.0, 0.0, -10.0]
""")
    sag = {}
    for label, end in (("both", 'fix = "clamp"\ndofs = ["y", "z"]'), ("dofs", 'dofs = ["y", "z"]'),
                       ("clamp", "")):
        r = run(scene_from_toml(beam.format(end=end)), tmp_path / label, progress=False)
        assert r.status == "ok", r.message
        told = [w for w in r.summary["warnings"] if "supports[1].fix = 'clamp' has no effect" in w]
        assert bool(told) == (label == "both")
        sag[label] = -r.arrays["positions"][-1, 16, 2]
    EI = 2.0e11 * np.pi * 0.01 ** 4 / 64.0
    assert sag["both"] == pytest.approx(sag["dofs"], rel=1e-12)
    assert sag["both"] == pytest.approx(10.0 * 7 / 768 / EI, rel=0.01)   # propped cantilever
    assert sag["clamp"] == pytest.approx(10.0 / 192 / EI, rel=0.01)      # fixed-fixed


def test_an_implicit_run_that_gains_energy_says_so(tmp_path: Path) -> None:
    """The thread of ``LANDING`` as three elements, under the midpoint rule at a fixed 1.5 ms
    (seven equal steps a frame), gains 6.9 % of its largest energy in motion at its bounces,
    below the guard's 10 % (an outside check's spinning rod: 4.4 % over an hour, without a
    word): the run warns. At 1 ms (0.9 %), and with BDF2 at 1.5 ms, nothing is said. (This test's
    scene was a steel pendulum under the midpoint rule at 2 ms, +6 % until the rule took the
    step's mean strains, C56; then one element, +6.7 % with the last step of each frame cut
    short, 4.4 % in equal steps.)"""
    for integrator, dt, rises in (("midpoint", 0.0015, True), ("midpoint", 0.001, False),
                                  ("bdf2", 0.0015, False)):
        text = LANDING.format(dt=dt, elements=3).replace('"midpoint"', f'"{integrator}"')
        r = run(scene_from_toml(text), tmp_path / f"{integrator}{dt}", progress=False)
        assert r.status == "ok", r.message
        a = r.arrays
        motion = a["kinetic_energy"] + a["elastic_energy"] + a["contact_energy"]
        gain = (motion + a["potential_energy"] - (motion + a["potential_energy"])[0]).max()
        assert (gain > 0.05 * motion.max()) == rises, (integrator, dt, gain / motion.max())
        told = [w for w in r.summary["warnings"] if w.startswith("the energy, the potential of gravity")]
        assert bool(told) == rises


HEAD_ON = """
[simulation]
duration = 0.04
integrator = "{integrator}"
[model]
type = "lumped"
axial = "linear"
[[materials]]
name = "rodmat"
density = 1000.0
youngs_modulus = 1.0e8
diameter = 0.02
[[rods]]
name = "rod"
material = "rodmat"
points = [[-1.12, 0.0, 0.0], [-0.12, 0.0, 0.0]]
elements = 50
velocity = [1.0, 0.0, 0.0]
[[bodies]]
name = "ball"
shape = "sphere"
size = [0.2, 0.2, 0.2]
mass = 0.3141592653589793
[contact]
stiffness = 1.0e7
damping = 0.0
friction = {friction}
[output]
frame_interval = 0.0005
vtk = false
"""


@pytest.mark.parametrize("integrator, friction, told", [
    ("bdf2", 0.0, True), ("generalized-alpha", 0.0, True), ("explicit", 0.0, False),
    ("bdf2", 0.3, False)])
def test_a_conservative_impact_that_loses_energy_says_so(tmp_path: Path, integrator: str,
                                                         friction: float, told: bool) -> None:
    """An elastic rod (1 m, 50 elements) hitting a free sphere of its mass head-on, nothing in
    the scene dissipating: at default steps BDF2 and generalized-alpha lose 24 % and 10 % of
    the energy to their numerical damping at the contact (an outside check: the sphere's exit
    velocity 5.7 and 3.4 % low) and say so; the explicit run keeps it (+0.03 %); with friction
    in the scene the loss is not the scheme's alone, and nothing is said."""
    r = run(scene_from_toml(HEAD_ON.format(integrator=integrator, friction=friction)),
            tmp_path / "out", progress=False)
    assert r.status == "ok", r.message
    a = r.arrays
    energy = a["kinetic_energy"] + a["elastic_energy"] + a["contact_energy"]
    loss = 1.0 - energy[-1] / energy[0]
    assert (loss > 0.05) == (integrator != "explicit"), loss
    warned = [w for w in r.summary["warnings"] if w.startswith("the energy fell")]
    assert bool(warned) == told
    if told:
        assert f"{100 * loss:.3g} %" in warned[0]


PUSHED_THROUGH = """
[simulation]
duration = 0.02
integrator = "{integrator}"
[[materials]]
name = "kevlar"
density = 1440.0
youngs_modulus = 7.0e10
diameter = 0.001
[[rods]]
name = "r"
material = "kevlar"
points = [[0.2282, 0.0714, -0.1409], [0.27393, 0.23638, 0.30585]]
elements = 1
[[loads]]
node = "r:end"
force = [-3.7526, -0.2271, -4.4846]
[output]
vtk = false
"""
"""One free tension-only Cosserat element (0.48 m of 1 mm Kevlar) whose end a 5.9 N force pushes
back through the other end (an outside check's scene). The midpoint rule, with the stresses of
the midpoint configuration's strains, shrank its steps to 1e-8 s here and crawled (11,000 steps
in 30 s for 4e-4 s of the 0.02 s); with those of the step's mean strains (C56) it takes 99."""


def test_an_implicit_run_that_finds_no_usable_step_stops_and_says_why(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A step control that accepts only steps of about 1e-9 s (an error estimate that grows as
    ``(h / 1e-9 s)^3`` times the tolerance) makes the run crawl: it stops after
    ``CRAWL_STEPS`` steps towards one frame, says why and keeps its frames. The scene itself
    runs: the midpoint rule (which crawled on it before C56) and BDF2 in under 300 steps."""
    from rodnet.integrate import implicit

    for integrator in ("midpoint", "bdf2"):
        done = run(scene_from_toml(PUSHED_THROUGH.format(integrator=integrator)),
                   tmp_path / integrator, progress=False)
        assert done.status == "ok" and done.summary["steps"] < 300, done.message
    monkeypatch.setattr(implicit, "CRAWL_STEPS", 300)   # 20,000 in a run: about a minute here
    for integrator, scheme in (("bdf2", implicit.BDF2), ("midpoint", implicit.Midpoint)):
        monkeypatch.setattr(scheme, "local_error",
                            lambda self, old, new, h: 1e-6 * (h / 1e-9) ** 3)
        r = run(scene_from_toml(PUSHED_THROUGH.format(integrator=integrator),
                                ["simulation.error_tolerance=1e-6"]), tmp_path / f"crawl-{integrator}",
                progress=False)
        assert r.status == "failed" and "steps since the last frame" in r.message, r.message
        assert "supports or stiffness" in r.message and len(r.arrays["time"]) == 1
        # the damping integrators are advised to the others only (a failed BDF2 run was told
        # to try bdf2, outside check)
        assert ("another integrator (bdf2" in r.message) == (integrator == "midpoint")


def test_a_diverged_explicit_run_ends_at_its_last_good_frame(tmp_path: Path) -> None:
    """A 5 x 5 net with the linear axial law, no damping, at the explicit stability estimate
    itself (``explicit_safety = 1``) diverges within the first frame interval (an outside
    check's scene). The frame that failed the energy guard (positions of 4e22 m) is not kept,
    and the summary's metrics come from the frames kept: they had read 4.0e27 N of tension
    and 4.3e30 m^2 of mouth area."""
    text = small_net_toml(duration=0.3, viscosity=0.0)
    r = run(scene_from_toml(text, ["model.axial=linear", "simulation.explicit_safety=1.0"]),
            tmp_path, progress=False)
    assert r.status == "failed" and "energy grew" in r.message, r.message
    a, metrics = r.arrays, r.summary["metrics"]
    assert len(a["time"]) >= 1 and np.abs(a["positions"]).max() < 100.0
    assert metrics["max_tension"] == metrics["max_tension_at_frames"] < 1e4
    assert metrics["max_mouth_area"] < 100.0


def test_a_viscous_explicit_step_is_said_before_the_run(tmp_path: Path,
                                                        capfd: pytest.CaptureFixture[str]) -> None:
    """A step that the threads' viscosity shortens is said before the run, with the steps it
    takes (an explicit run of 7.8e8 steps had started without notice, outside check), and in
    the summary's warnings after it."""
    r = run(scene_from_toml(PINNED_ROD, ["model.type=lumped", "simulation.integrator=explicit",
                                         "simulation.adaptive=true", "simulation.duration=0.002",
                                         "materials[0].viscosity=1e7"]),
            tmp_path, progress=True)
    assert r.status == "ok", r.message
    first = capfd.readouterr().err.splitlines()[0]
    assert first.startswith("rodnet: warning: the explicit stability limit") and \
        "materials.viscosity" in first
    steps = float(first.split("(about ")[1].split(" steps")[0])
    assert steps == pytest.approx(r.summary["steps"], rel=0.01)
    assert any("materials.viscosity" in w for w in r.summary["warnings"])


def test_what_the_scene_alone_decides_is_said_before_the_run(tmp_path: Path,
                                                             capfd: pytest.CaptureFixture[str]
                                                             ) -> None:
    """A warning that the scene decides (here a fixed step longer than the frame interval) is
    printed before the first progress line, not only with the summary (a stopped run told it
    125 s late, outside check)."""
    r = run(scene_from_toml(PINNED_ROD, ["simulation.adaptive=false", "simulation.dt=0.02",
                                         "output.frame_interval=0.01",
                                         "simulation.duration=0.04"]),
            tmp_path, progress=True)
    assert r.status == "ok", r.message
    lines = capfd.readouterr().err.splitlines()
    assert lines[0].startswith("rodnet: warning: simulation.dt = 0.02 s is longer than "
                               "output.frame_interval")
    assert any("is longer than output.frame_interval" in w for w in r.summary["warnings"])


def test_the_time_left_follows_the_pace_since_the_last_line(monkeypatch: pytest.MonkeyPatch
                                                            ) -> None:
    """A run that slows down is told the pace of its last stretch, not the average of its easy
    start (an outside check found the estimate optimistic)."""
    import io

    from rodnet import progress
    from rodnet.integrate.frames import StepStats

    clock = {"now": 0.0}
    monkeypatch.setattr(progress.time, "perf_counter", lambda: clock["now"])
    out = io.StringIO()
    bar = progress.Progress(10.0, enabled=None, stream=out)   # log lines: not a terminal
    # 1 s of wall per simulated second for the first half, then 10 s per simulated second
    for t in np.arange(0.25, 10.01, 0.25):
        clock["now"] += 0.25 if t <= 5.0 else 2.5
        bar(float(t), 0.25, StepStats())
    lines = out.getvalue().splitlines()
    at_60 = [line for line in lines if "(60 %)" in line][0]
    # 4 simulated seconds left at 10 s each; the average (15 s for 6) would say 10 s
    assert "about 40 s left" in at_60
