"""``rodnet demo``: Cosserat threads and the lumped reference side by side, ``--quick`` the lumped
reference alone, and a bad override refused before anything runs."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rodnet.cli import main

SHORT = ["--quiet", "--set", "simulation.duration=0.02", "--set", "output.vtk=false",
         "--set", "output.picture=false", "--set", "output.plot=false"]


def _summary(folder: Path) -> dict:
    return json.loads((folder / "summary.json").read_text())


def test_demo_runs_both_models_and_compares_them(tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    assert main(["demo", "-o", str(out), *SHORT]) == 0, capsys.readouterr().err
    rods, lumped = _summary(out), _summary(out / "lumped")
    assert rods["scene"]["model"]["type"] == "cosserat"
    assert rods["scene"]["model"]["knots"] == "pinned"
    assert rods["scene"]["model"]["bending"] and rods["scene"]["model"]["torsion"]
    assert lumped["scene"]["model"]["type"] == "lumped"
    assert rods["status"] == lumped["status"] == "ok"
    # 20 ms after the throw both nets are carried by the corner masses: the same mouth area
    a, b = rods["metrics"]["max_mouth_area"], lumped["metrics"]["max_mouth_area"]
    assert abs(a - b) <= 0.01 * b
    printed = capsys.readouterr().out
    assert "max_mouth_area" in printed and "difference" in printed
    pytest.importorskip("matplotlib")
    assert (out / "comparison.png").stat().st_size > 10_000


def test_quick_demo_is_the_lumped_reference_alone(tmp_path: Path) -> None:
    """... and draws the movie, which the output keys do not turn off, unless --no-movie."""
    out = tmp_path / "out"
    assert main(["demo", "--quick", "--no-movie", "-o", str(out), *SHORT]) == 0
    assert _summary(out)["scene"]["model"]["type"] == "lumped"
    assert not (out / "lumped").exists() and not (out / "comparison.png").exists()
    assert not (out / "deployment.mp4").exists()
    pytest.importorskip("pyvista")
    pytest.importorskip("imageio_ffmpeg")
    assert main(["demo", "--quick", "-o", str(tmp_path / "movie"), *SHORT]) == 0
    assert (tmp_path / "movie" / "deployment.mp4").stat().st_size > 1000


def test_a_bad_override_runs_neither_model(tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    assert main(["demo", "-o", str(out), *SHORT, "--set", "net.packing=1.5"]) == 2
    assert "net.packing" in capsys.readouterr().err
    assert not out.exists()


def test_model_overrides_change_the_cosserat_run_only(tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert main(["demo", "-o", str(out), *SHORT, "--set", "model.knots=rigid",
                 "--set", "simulation.duration=0.01"]) == 0
    assert _summary(out)["scene"]["model"]["knots"] == "rigid"
    lumped = _summary(out / "lumped")
    assert lumped["scene"]["model"]["type"] == "lumped"
    assert lumped["simulated_time_s"] == pytest.approx(0.01)
