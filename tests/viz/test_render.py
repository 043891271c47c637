"""``rodnet render``: the movie of a run's saved frames (MP4 and GIF), tension colours, bodies,
refused input, and the movie ``rodnet demo`` writes after its run (rendering tests are skipped
where off-screen rendering does not work)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import rodnet
from rodnet.cli import EXIT_BAD_INPUT, main
from rodnet.viz.figures import bodies_at_frame, render_in_subprocess
from rodnet.viz.movie import BodyMotion
from tests.conftest import small_net_toml
from tests.viz.rendering import SPHERE_TARGET, require_offscreen

iio = pytest.importorskip("imageio.v3")

REPO = Path(__file__).resolve().parents[2]
SIZE = (320, 240)


def _render(outdir: Path, *options: str) -> subprocess.CompletedProcess[str]:
    """``rodnet render OUTDIR --size 320x240 OPTIONS`` of this source tree, in a child process
    (an OpenGL crash fails the test, not the test run)."""
    require_offscreen()
    env = dict(os.environ, PYTHONPATH=str(REPO))
    return subprocess.run([sys.executable, "-m", "rodnet", "render", str(outdir),
                           "--size", "x".join(map(str, SIZE)), *options],
                          capture_output=True, text=True, env=env, timeout=300)


def _frames(path: Path) -> np.ndarray:
    """Every frame of a movie, (F, H, W, 3) int."""
    return iio.imread(path, index=None)[..., :3].astype(int)


def _scene_area(frames: np.ndarray) -> np.ndarray:
    """(H, W) True away from the caption (top quarter), the axes triad (lower left) and the
    colour bar (right fifth): where only threads, corner masses and bodies are drawn."""
    height, width = frames.shape[-3:-1]
    area = np.ones((height, width), dtype=bool)
    area[: height // 4] = False
    area[int(0.7 * height):, : width // 4] = False
    area[:, int(0.8 * width):] = False
    return area


@pytest.fixture(scope="module")
def net_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The small net for 0.6 s: slack at first, taut from about 0.34 s (61 frames)."""
    out = tmp_path_factory.mktemp("net")
    result = rodnet.run(rodnet.scene_from_toml(small_net_toml(duration=0.6)), out, progress=False)
    assert result.status == "ok", result.message
    return out


@pytest.fixture(scope="module")
def net_movie(net_run: Path) -> np.ndarray:
    done = _render(net_run)
    assert done.returncode == 0, done.stderr
    assert str(net_run / "deployment.mp4") in done.stdout
    return _frames(net_run / "deployment.mp4")


def test_the_mp4_has_every_saved_frame_at_the_size_asked(net_run: Path,
                                                         net_movie: np.ndarray) -> None:
    frames = len(np.load(net_run / "result.npz")["time"])
    assert net_movie.shape == (frames, SIZE[1], SIZE[0], 3)
    # the documented default: the frames in 10 s, at 5 to 30 frames a second
    assert iio.immeta(net_run / "deployment.mp4")["fps"] == pytest.approx(
        np.clip(frames / 10.0, 5.0, 30.0))
    # the net moves: its pixels change between the first, a middle and the last frame
    area = _scene_area(net_movie)
    first, middle, last = (net_movie[k][area] for k in (0, frames // 2, frames - 1))
    assert np.abs(first - middle).mean() > 1.0 and np.abs(middle - last).mean() > 1.0


def test_threads_take_the_colour_of_their_tension(net_run: Path, net_movie: np.ndarray) -> None:
    tension = np.load(net_run / "result.npz")["tension"]
    assert tension[0].max() == 0.0                     # packed and slack at the start
    taut = int(np.argmax(tension.max(axis=1)))         # the frame of the run's largest tension
    r, g, b = (net_movie[..., c] for c in range(3))
    # viridis above about 60 % of the range (green to yellow); 0 N is dark purple
    upper = (g > 110) & (g > b + 30) & (r < 245) & _scene_area(net_movie)
    assert upper[0].sum() == 0
    assert upper[taut].sum() >= 10


def _every(saved: int, n: int) -> int:
    """Frames of a movie of every n-th of ``saved`` frames, the last one included."""
    return len(range(0, saved, n)) + (1 if (saved - 1) % n else 0)


def test_the_gif_has_every_third_frame_at_the_rate_asked(net_run: Path) -> None:
    done = _render(net_run, "--gif", "--fps", "10", "--every", "3")
    assert done.returncode == 0, done.stderr
    gif = net_run / "deployment.gif"
    frames = _frames(gif)
    saved = len(np.load(net_run / "result.npz")["time"])
    assert frames.shape == (_every(saved, 3), SIZE[1], SIZE[0], 3)
    assert iio.immeta(gif, index=0)["duration"] == 100            # ms: 10 frames a second
    assert np.abs(frames[0] - frames[-1]).mean() > 1.0


def test_a_body_is_drawn(tmp_path: Path, net_run: Path, net_movie: np.ndarray) -> None:
    out = tmp_path / "capture"
    scene = rodnet.scene_from_toml(small_net_toml(duration=0.1) + SPHERE_TARGET)
    assert rodnet.run(scene, out, progress=False).status == "ok"
    movie = tmp_path / "capture.mp4"
    done = _render(out, "-o", str(movie))
    assert done.returncode == 0, done.stderr
    frames = _frames(movie)
    assert len(frames) == len(np.load(out / "result.npz")["time"])

    def grey(frames: np.ndarray) -> np.ndarray:
        """Pixels of the light grey of a shaded body, per frame (F,)."""
        neutral = (frames.max(axis=-1) - frames.min(axis=-1) < 12)
        light = (frames.min(axis=-1) > 100) & (frames.max(axis=-1) < 235)
        return (neutral & light & _scene_area(frames)).sum(axis=(1, 2))

    # the sphere covers a disc of many pixels in every frame; the net alone has next to none
    assert grey(frames).min() >= 50 and grey(net_movie).max() < 20


def test_a_tumbling_body_is_moved_rigidly_from_its_first_frame(tmp_path: Path) -> None:
    tumbling = SPHERE_TARGET.replace('shape = "sphere"', 'shape = "box"').replace(
        "size = [1.0, 1.0, 1.0]", "size = [1.0, 0.6, 0.3]").replace(
        "fixed = true", "mass = 10.0\nvelocity = [0.5, 0.0, 0.0]\n"
        "angular_velocity_deg = [90.0, 200.0, -45.0]")
    result = rodnet.run(rodnet.scene_from_toml(small_net_toml(duration=0.3) + tumbling),
                        tmp_path, progress=False)
    assert result.status == "ok", result.message
    data = dict(np.load(tmp_path / "result.npz"))
    summary = json.loads((tmp_path / "summary.json").read_text())
    motion = BodyMotion(tmp_path, data, summary)
    last = len(data["time"]) - 1
    rebuilt, _ = bodies_at_frame(tmp_path, data, summary, last)     # from the shape itself
    moved = motion.vertices(last)[0]
    assert np.ptp(moved - motion.vertices(0)[0], axis=0).max() > 0.1   # it turned and moved
    np.testing.assert_allclose(moved, rebuilt[0].vertices, atol=1e-9)


def test_a_folder_without_results_is_refused(tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["render", str(tmp_path)]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert str(tmp_path) in err and "result.npz" in err and "summary.json" in err
    (tmp_path / "summary.json").write_text("{}")
    assert main(["render", str(tmp_path)]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert "no result.npz" in err and "no summary.json" not in err
    assert not list(tmp_path.glob("deployment.*"))
    with pytest.raises(SystemExit) as stop:                             # argparse: status 2
        main(["render", str(tmp_path), "--size", "321x240"])
    assert stop.value.code == EXIT_BAD_INPUT and "321x240" in capsys.readouterr().err


def test_a_bad_movie_name_is_refused(net_run: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for options in (["-o", "movie.avi"], ["--gif", "-o", "movie.mp4"]):
        assert main(["render", str(net_run), *options]) == EXIT_BAD_INPUT
        assert options[-1] in capsys.readouterr().err


def test_the_demo_writes_the_movie_and_a_missing_encoder_is_a_warning(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    require_offscreen()
    out = tmp_path / "demo"
    monkeypatch.setenv("PYTHONPATH", str(REPO))                  # the child renders this tree
    status = main(["demo", "-o", str(out), "--quiet", "--set", "simulation.duration=0.05",
                   "--set", "output.picture=false", "--set", "output.plot=false"])
    assert status == 0, capsys.readouterr().err
    frames = _frames(out / "deployment.mp4")                   # every second saved frame
    assert len(frames) == _every(len(np.load(out / "result.npz")["time"]), 2)
    assert frames.shape[1:] == (600, 800, 3)
    # without ffmpeg the movie is a warning, and a movie already there is kept
    before = (out / "deployment.mp4").read_bytes()
    monkeypatch.setenv("IMAGEIO_FFMPEG_EXE", str(tmp_path / "no-ffmpeg"))
    warnings = render_in_subprocess(out, picture=False, plot=False, movie=True)
    assert len(warnings) == 1 and "could not write the movie" in warnings[0]
    assert "no-ffmpeg" in warnings[0]
    assert (out / "deployment.mp4").read_bytes() == before
    assert sorted(p.name for p in out.glob("deployment*")) == ["deployment.mp4"]
