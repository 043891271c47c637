"""Two runs of a deployment side by side (``rodnet demo``'s comparison): histories on common
frame times, two integrators of one net, and the figure."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rodnet.run import run
from rodnet.scene import scene_from_toml
from rodnet.viz.compare import compare_runs, plot_comparison
from tests.conftest import small_net_toml

def _run(tmp: Path, name: str, text: str, overrides: list[str]) -> Path:
    result = run(scene_from_toml(text, overrides, source=name), tmp / name, progress=False)
    assert result.status == "ok", result.message
    return result.directory


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    tmp = tmp_path_factory.mktemp("compare")
    text = small_net_toml(duration=0.4)
    return {"lumped": _run(tmp, "lumped", text, []),
            "coarse": _run(tmp, "coarse", text.replace("frame_interval = 0.01",
                                                       "frame_interval = 0.02"), []),
            "rk45": _run(tmp, "rk45", text, ["simulation.integrator=rk45"])}


def test_same_model_on_other_frames_differs_only_between_frames(runs: dict[str, Path]) -> None:
    """The run compared with itself saved every other frame: equal at the common frames (up to
    explicit steps landing on other frame times), the linear interpolation between them (the
    mouth area is smooth: within 2 % of its range)."""
    c = compare_runs(runs["lumped"], runs["coarse"], ("every frame", "every other frame"))
    assert len(c.time) == 41
    area = c.histories["mouth_area"]
    np.testing.assert_allclose(area[0, ::2], area[1, ::2], rtol=1e-4)
    assert np.abs(area[0] - area[1]).max() < 0.02 * np.ptp(area[0])
    np.testing.assert_allclose(area[1, 1::2], 0.5 * (area[0, 0:-1:2] + area[0, 2::2]), rtol=1e-4)


def test_two_integrators_of_one_model_agree(runs: dict[str, Path]) -> None:
    """The explicit run against scipy's adaptive RK45 of the same net: mouth area within 0.5 %
    and distance within 2 % of their largest values over the whole history, and not one run
    twice. (The largest tension at a frame is not compared: the first threads snap taut at the
    last frames, where it is 15 N against 9 N.)"""
    c = compare_runs(runs["lumped"], runs["rk45"], ("explicit", "rk45"))
    assert 0.0 < c.largest_difference("mouth_area")[1] < 0.005
    assert c.largest_difference("distance")[1] < 0.02
    assert (c.histories["largest_tension"] >= 0.0).all()


def test_figure_and_refusals(runs: dict[str, Path], tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    c = compare_runs(runs["lumped"], runs["rk45"], ("explicit", "rk45"))
    path = plot_comparison(c, tmp_path / "comparison.png")
    assert path.stat().st_size > 10_000
    with pytest.raises(FileNotFoundError, match="no result.npz"):
        compare_runs(tmp_path, runs["lumped"], ("a", "b"))
