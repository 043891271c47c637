"""``deployment.mp4`` (or ``deployment.gif``): a movie of the saved frames of a run, one movie
frame per saved frame.

The threads are coloured by tension on one colour range over the whole run (so a colour means
the same force in every frame), the corner masses of a net are red and rigid bodies grey, each
frame carries its time, and the camera is fixed on the box that holds everything drawn over the
whole run. One off-screen pyvista plotter draws every frame: each frame only replaces the points
and the tensions of meshes built once, and the bodies are moved rigidly from their surfaces at
the first frame (rebuilt by :func:`rodnet.viz.figures.bodies_at_frame`). MP4 (H.264) goes through
imageio's ffmpeg plugin (the ``ffmpeg`` binary of the ``imageio-ffmpeg`` package), GIF through
Pillow.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rodnet.errors import SceneError
from rodnet.viz.figures import (TENSION, add_scale_and_view, add_threads, bodies_at_frame,
                                body_surface, corner_nodes, frame_label, thread_mesh,
                                headless_rendering)

FloatArray = NDArray[np.float64]

DEFAULT_SIZE = (800, 600)
"""Frame width and height [pixels]."""
MOVIE_SECONDS = 10.0
"""The default frame rate plays the saved frames in about this long [s] ..."""
FPS_RANGE = (5.0, 30.0)
"""... within these frame rates [1/s] (a long run makes a longer movie at 30 frames a second)."""
GIF_MAX_FPS = 50.0
"""GIF delays are whole hundredths of a second, and viewers slow down shorter ones than 2."""
SIZE_RANGE = (64, 4096)
"""Smallest and largest frame width or height [pixels]."""
REQUIRED_ARRAYS = ("time", "positions", "tension", "segments")
"""The arrays of ``result.npz`` a movie is drawn from."""


def default_fps(frames: int, gif: bool = False) -> float:
    """The frame rate [1/s] that plays ``frames`` saved frames in :data:`MOVIE_SECONDS`,
    clipped to :data:`FPS_RANGE` (the reference deployment's 301 frames: 30 per second,
    10.0 s, 3.3 times slower than the 3 s simulated)."""
    fps = float(np.clip(frames / MOVIE_SECONDS, *FPS_RANGE))
    return min(fps, GIF_MAX_FPS) if gif else fps


def parse_size(text: str) -> tuple[int, int]:
    """``WIDTHxHEIGHT`` in pixels, both even (the H.264 encoder halves the colour resolution)
    and within :data:`SIZE_RANGE`; raises ``ValueError`` naming what is allowed."""
    low, high = SIZE_RANGE
    allowed = (f"{text!r} is not WIDTHxHEIGHT in pixels with even numbers from {low} to "
               f"{high}, e.g. 800x600")
    parts = text.lower().split("x")
    if len(parts) != 2 or not all(p.strip().isdigit() for p in parts):
        raise ValueError(allowed)
    width, height = (int(p) for p in parts)
    if not all(low <= v <= high and v % 2 == 0 for v in (width, height)):
        raise ValueError(allowed)
    return width, height


def movie_target(directory: Path, output: Path | None, gif: bool, fps: float | None,
                 ) -> tuple[Path, bool]:
    """Check a movie request before anything is drawn; return where the movie goes and whether
    it is a GIF. Raises :class:`SceneError` naming the option (or ``OUTDIR``), the value and
    what is allowed.

    The folder must hold a run's results (:func:`check_results`). The movie goes to ``output``
    when given (its suffix, ``.mp4`` or ``.gif``, decides the format; ``gif`` asks for
    ``.gif``), else to ``directory/deployment.mp4`` or, with ``gif``, ``deployment.gif``. A GIF
    plays at most :data:`GIF_MAX_FPS` frames a second.
    """
    check_results(directory)
    if output is None:
        path = directory / ("deployment.gif" if gif else "deployment.mp4")
    else:
        path, allowed = output, [".gif"] if gif else [".mp4", ".gif"]
        if output.suffix.lower() not in allowed:
            raise SceneError("-o", str(output), "the movie file must end in "
                             f"{' or '.join(allowed)}" + (" with --gif" if gif else ""))
        if output.parent.exists() and not output.parent.is_dir():
            raise SceneError("-o", str(output), f"{output.parent} is not a folder")
        gif = output.suffix.lower() == ".gif"
    if gif and fps is not None and fps > GIF_MAX_FPS:
        raise SceneError("--fps", fps, f"a GIF plays at most {GIF_MAX_FPS:g} frames a second "
                         "(its delays are whole hundredths of a second)")
    return path, gif


def check_results(directory: Path) -> None:
    """Raise :class:`SceneError` naming ``directory`` and what it lacks unless it holds the
    results of a run with at least one saved frame: ``result.npz`` with
    :data:`REQUIRED_ARRAYS` and ``summary.json``."""
    what = ("it needs the output folder of a run (rodnet run SCENE -o DIR, rodnet demo -o DIR), "
            "which holds result.npz and summary.json")
    if not directory.is_dir():
        raise SceneError("OUTDIR", str(directory), f"is not a folder: {what}")
    missing = [n for n in ("result.npz", "summary.json") if not (directory / n).is_file()]
    if missing:
        raise SceneError("OUTDIR", str(directory), f"holds no {' and no '.join(missing)}: {what}")
    try:
        with np.load(directory / "result.npz") as data:
            lacking = [n for n in REQUIRED_ARRAYS if n not in data.files]
            frames = len(data["time"]) if "time" in data.files else 0
    except (OSError, ValueError) as exc:
        raise SceneError("OUTDIR", str(directory), f"result.npz cannot be read ({exc})") from None
    try:
        json.loads((directory / "summary.json").read_text())
    except (OSError, ValueError) as exc:
        raise SceneError("OUTDIR", str(directory), f"summary.json cannot be read ({exc})") from None
    if lacking:
        raise SceneError("OUTDIR", str(directory), "result.npz lacks the arrays "
                         f"{', '.join(lacking)}: it is not a result of this version's runs")
    if frames == 0:
        raise SceneError("OUTDIR", str(directory), "result.npz holds no frame: the run stopped "
                         "before its first frame was saved")


def tension_range(tension: FloatArray) -> tuple[float, float]:
    """The colour range [N] of the whole run, ``tension`` (F, E): smallest to largest finite
    value, widened to (low, low + 1 N) when every tension is the same (a colour map needs
    low < high)."""
    finite = tension[np.isfinite(tension)]
    low, high = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
    return (low, high) if high > low else (low, low + 1.0)


class BodyMotion:
    """The run's bodies over all frames: their surfaces at the first frame moved rigidly by
    ``body_positions`` and ``body_rotations`` (a body is rigid, so its surface at frame ``f`` is
    ``c_f + R_f R_0^T (x - c_0)``)."""

    def __init__(self, directory: Path, data: Any, summary: dict[str, Any]) -> None:
        from rodnet.kernels.so3 import quat_to_matrix

        self.names: list[str] = []
        self.missing: list[str] = []
        self.faces: list[NDArray[np.int64]] = []
        self._local: list[FloatArray] = []      # (V, 3) body-frame vertices
        self._index: list[int] = []
        if "body_positions" not in data:
            return
        bodies, self.missing = bodies_at_frame(directory, data, summary, 0)
        order = [spec["name"] for spec in summary.get("scene", {}).get("bodies", [])]
        self._centres = np.asarray(data["body_positions"], float)                # (F, B, 3)
        self._rotations = quat_to_matrix(np.asarray(data["body_rotations"], float))  # (F, B, 3, 3)
        for body in bodies:
            b = order.index(body.name)
            self.names.append(body.name)
            self.faces.append(body.faces)
            self._index.append(b)
            self._local.append((body.vertices - self._centres[0, b]) @ self._rotations[0, b])

    def vertices(self, frame: int) -> list[FloatArray]:
        """The world vertices (V, 3) [m] of each drawn body at ``frame``."""
        return [self._centres[frame, b] + local @ self._rotations[frame, b].T
                for b, local in zip(self._index, self._local)]


def run_bounds(positions: FloatArray, bodies: BodyMotion) -> FloatArray:
    """``(xmin, xmax, ymin, ymax, zmin, zmax)`` [m] of the nodes ``positions`` (F, N, 3) and the
    bodies over every frame."""
    low, high = np.nanmin(positions, axis=(0, 1)), np.nanmax(positions, axis=(0, 1))
    for frame in range(len(positions)) if bodies.names else ():
        for vertices in bodies.vertices(frame):
            low, high = np.minimum(low, vertices.min(axis=0)), np.maximum(high, vertices.max(axis=0))
    return np.column_stack([low, high]).ravel()


TALL_BOX_RATIO = 1.5
"""A box this many times longer along z than along x and y is laid across the frame."""


def lay_tall_box_across(plotter: Any, bounds: FloatArray, motion: FloatArray) -> None:
    """Roll the camera about its view direction so that z, the isometric view's up, runs across
    the (wide) frame when the box ``bounds`` (6,) [m] is :data:`TALL_BOX_RATIO` times longer
    along z than along x and y (a net thrown along z: tens of metres along the throw, a few
    across), pointing to the right where ``motion`` (3,) [m] (the run's displacement) has a
    positive z, and fit the camera to the box again. The view direction stays that of
    :func:`rodnet.viz.figures.add_scale_and_view`; any other box keeps z up."""
    extents = np.ptp(np.asarray(bounds, float).reshape(3, 2), axis=1)
    if extents[2] < TALL_BOX_RATIO * extents[:2].max():
        return
    camera = plotter.camera
    towards = np.subtract(camera.position, camera.focal_point)      # from the scene to the eye
    along = np.array([0.0, 0.0, 1.0 if motion[2] >= 0.0 else -1.0])
    up = np.cross(towards, along)      # normal to the long axis and the view: along is "right"
    camera.up = tuple(up / np.linalg.norm(up))
    plotter.reset_camera(bounds=list(bounds))
    camera.zoom(0.85)


def movie_frames(saved: int, every: int = 1) -> list[int]:
    """The saved frames a movie shows: every ``every``-th of the ``saved`` frames from the first,
    and the last one always."""
    frames = list(range(0, saved, every))
    return frames if frames[-1] == saved - 1 else frames + [saved - 1]


def render_movie(directory: Path, output: Path | None = None, fps: float | None = None,
                 size: tuple[int, int] = DEFAULT_SIZE, gif: bool = False, every: int = 1) -> Path:
    """Write the movie of the run in ``directory`` and return its path.

    Parameters
    ----------
    directory : Path
        A run's output folder.
    output : Path, optional
        The movie file, ``.mp4`` or ``.gif`` (the request is checked by :func:`movie_target`).
    fps : float, optional
        Frames per second of the movie (default :func:`default_fps` of its frame count).
    size : (2,) int
        Frame width and height [pixels], even.
    gif : bool
        Write a GIF (Pillow) instead of an MP4 (ffmpeg).
    every : int
        Draw every ``every``-th saved frame (and the last; :func:`movie_frames`).
    """
    directory = Path(directory)
    path, gif = movie_target(directory, output, gif, fps)
    data = dict(np.load(directory / "result.npz"))
    summary = json.loads((directory / "summary.json").read_text())
    frames = movie_frames(len(data["time"]), every)
    fps = default_fps(len(frames), gif) if fps is None else float(fps)
    path.parent.mkdir(parents=True, exist_ok=True)
    scene = _MovieScene(directory, data, summary, size)
    partial = path.with_name(f"{path.stem}.partial{path.suffix}")   # the encoder reads the suffix
    try:
        writer = _GifWriter(partial, fps) if gif else _Mp4Writer(partial, fps)
        try:
            for frame in frames:
                writer.append(scene.draw(frame))
        finally:
            writer.close()
        partial.replace(path)         # a movie already there stays until the new one is whole
    finally:
        scene.close()
        partial.unlink(missing_ok=True)
    return path


AFTER_RUN_EVERY = 2
"""``rodnet demo``'s movie shows every second saved frame: 151 of the reference deployment's
301, at 15 a second for 10 s, at half the cost of drawing and encoding them all."""


def movie_after_run(directory: Path) -> Path:
    """The movie ``rodnet demo`` writes after its run: ``directory/deployment.mp4`` of every
    :data:`AFTER_RUN_EVERY`-th saved frame, the other options their defaults."""
    return render_movie(directory, every=AFTER_RUN_EVERY)


class _MovieScene:
    """One off-screen plotter with the run's meshes, set to a frame by :meth:`draw`."""

    def __init__(self, directory: Path, data: Any, summary: dict[str, Any],
                 size: tuple[int, int]) -> None:
        headless_rendering(os.environ)   # before VTK is loaded
        import pyvista as pv
        from vtkmodules.vtkCommonCore import vtkUnsignedCharArray

        self.data, self.summary = data, summary
        self.bodies = BodyMotion(directory, data, summary)
        self.plotter = pv.Plotter(off_screen=True, window_size=size)
        self._pixels = vtkUnsignedCharArray()
        # no multisampling: measured, it doubles the time of a frame with software OpenGL
        self.plotter.ren_win.SetMultiSamples(0)
        self.threads = thread_mesh(data, 0)
        add_threads(self.plotter, self.threads, tension_range(data["tension"]))
        self.corners = corner_nodes(summary)
        self.corner_points = pv.PolyData(data["positions"][0][self.corners])
        if self.corners:
            self.plotter.add_mesh(self.corner_points, color="red", point_size=10,
                                  render_points_as_spheres=True)
        self.surfaces = [body_surface(v, f) for v, f in zip(self.bodies.vertices(0),
                                                             self.bodies.faces)]
        for surface in self.surfaces:
            self.plotter.add_mesh(surface, color="lightgrey")
        font = max(8, round(12 * size[1] / 600))
        # a plain text actor: a corner annotation costs about 30 ms a frame to re-lay out
        self.label = self.plotter.add_text("", position=(8, size[1] - 8 - 4 * font),
                                           font_size=font)
        # set up the render window first: show() would fit the camera to the first frame
        self.plotter.show(auto_close=False)
        bounds = self.bounds = run_bounds(data["positions"], self.bodies)
        # no labelled box: measured, its labels cost a third of the time of a frame
        add_scale_and_view(self.plotter, bounds, labelled_box=False)
        positions = data["positions"]
        lay_tall_box_across(self.plotter, bounds, np.nanmean(positions[-1] - positions[0], axis=0))

    def caption(self, frame: int) -> str:
        """The frame's time and, with bodies, its contact force."""
        text = frame_label(self.summary, float(self.data["time"][frame]))
        if "contact_force" in self.data:
            text += f"\ncontact force {float(self.data['contact_force'][frame]):.3g} N"
        if self.bodies.missing:
            text += f"\nnot drawn (mesh without VTK output): {', '.join(self.bodies.missing)}"
        return text

    def draw(self, frame: int) -> NDArray[np.uint8]:
        """Render ``frame``; return the image (H, W, 3), top row first."""
        from vtkmodules.util.numpy_support import vtk_to_numpy

        points = self.data["positions"][frame]
        self.threads.points = points
        self.threads.cell_data[TENSION] = self.data["tension"][frame]
        if self.corners:
            self.corner_points.points = points[self.corners]
        for surface, vertices in zip(self.surfaces, self.bodies.vertices(frame)):
            surface.points = vertices
        self.label.SetInput(self.caption(frame))
        # near and far planes around the whole run's box: pyvista's camera fits them to the
        # meshes as they are when it is moved (the first frame)
        self.plotter.renderer.ResetCameraClippingRange(*self.bounds)
        self.plotter.render()
        # the back buffer straight from the window: measured, 3 ms a frame less than
        # pyvista's image, which builds an image filter each time
        width, height = self.plotter.window_size
        self.plotter.ren_win.GetPixelData(0, 0, width - 1, height - 1, 0, self._pixels, 0)
        return np.ascontiguousarray(vtk_to_numpy(self._pixels).reshape(height, width, 3)[::-1])

    def close(self) -> None:
        self.plotter.close()


PRESET = "veryfast"
"""x264's speed preset of the MP4: on the reference deployment's 301 frames at 800 x 600 the
encoder took 2.4 - 3.1 s of CPU against 3.4 - 3.5 s at the default ``"medium"`` (two runs each
on a shared machine), for files of 0.96 and 0.93 MB."""


class _Mp4Writer:
    """H.264 in an MP4 through imageio's ffmpeg plugin."""

    def __init__(self, path: Path, fps: float) -> None:
        import imageio.v2 as imageio

        # macro_block_size 1: keep the size asked for (even sizes are all yuv420p needs);
        # quality 7 of 10 is x264's crf 15
        self._writer = imageio.get_writer(path, format="FFMPEG", mode="I", fps=fps,
                                          codec="libx264", pixelformat="yuv420p", quality=7,
                                          macro_block_size=1, ffmpeg_log_level="error",
                                          output_params=["-preset", PRESET])

    def append(self, image: NDArray[np.uint8]) -> None:
        self._writer.append_data(image)

    def close(self) -> None:
        self._writer.close()


class _GifWriter:
    """An endlessly looping GIF through Pillow; each frame gets its own 256-colour palette."""

    def __init__(self, path: Path, fps: float) -> None:
        self.path, self.delay_ms = path, 1000.0 / fps
        self.images: list[Any] = []

    def append(self, image: NDArray[np.uint8]) -> None:
        from PIL import Image

        # fast octree: measured 7 times faster than the default median cut, 1/255 off on average
        self.images.append(Image.fromarray(image).quantize(256, method=Image.Quantize.FASTOCTREE,
                                                           dither=Image.Dither.NONE))

    def close(self) -> None:
        if self.images:
            self.images[0].save(self.path, save_all=True, append_images=self.images[1:],
                                duration=self.delay_ms, loop=0)
