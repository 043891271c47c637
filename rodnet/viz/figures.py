"""The net at its maximum mouth area (pyvista, off screen) and the deployment time series
(matplotlib). Both read a finished output directory; :func:`render_in_subprocess` runs them, and
the movie of :mod:`rodnet.viz.movie`, in a child process so that a machine without working
OpenGL loses the picture, never the run.

For a run with rigid bodies the picture also draws the bodies at that frame and marks the
thread nodes in contact, and the plot gains panels of the contact force, the targets' motion and
the energies (:func:`deployment_panels`). The bodies' surfaces are rebuilt from what the output
directory holds, with no need to find the scene file: a box, cylinder or sphere from its
``shape`` and ``size`` in ``summary.json``'s scene (the same triangles the VTK series gets,
:func:`rodnet.contact.surfaces.surface_triangles`), placed by ``body_positions`` and
``body_rotations`` of ``result.npz``; a triangle mesh, whose file is named relative to a scene
file the output does not record, from the frame's ``vtk/body_B_NNNNN.vtu`` when the run wrote
VTK output (else it is left out and the picture says so).
"""

from __future__ import annotations

import ctypes.util
import json
import os
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path
from collections.abc import MutableMapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def headless_rendering(env: MutableMapping[str, str]) -> None:
    """Without an X display (``DISPLAY`` unset or empty), have VTK draw with EGL straight away
    where libEGL is installed (the README's set-up installs it): VTK tries an X server first and
    prints a warning about the missing one before it falls back to EGL anyway."""
    if not env.get("DISPLAY") and "VTK_DEFAULT_OPENGL_WINDOW" not in env and \
            ctypes.util.find_library("EGL"):
        env["VTK_DEFAULT_OPENGL_WINDOW"] = "vtkEGLRenderWindow"


def render_in_subprocess(directory: Path, picture: bool, plot: bool, movie: bool = False,
                         timeout_s: float = 300.0) -> list[str]:
    """Write ``net.png``, ``deployment.png`` and/or ``deployment.mp4`` (:mod:`rodnet.viz.movie`)
    in ``directory`` from a child process (:mod:`rodnet.viz.worker`); return warnings, if any:
    one for the figures, one for the movie, saying why each is missing."""
    env = dict(os.environ)
    env.setdefault("PYVISTA_OFF_SCREEN", "true")
    headless_rendering(env)
    tasks = [name for name, asked in (("picture", picture), ("plot", plot), ("movie", movie))
             if asked]
    args = [sys.executable, "-m", "rodnet.viz.worker", str(directory)] + [f"--{t}" for t in tasks]
    try:
        done = subprocess.run(args, env=env, capture_output=True, text=True, timeout=timeout_s)
    except subprocess.TimeoutExpired as exc:
        out = exc.stdout.decode() if isinstance(exc.stdout, bytes) else exc.stdout or ""
        finished = {line[5:] for line in out.splitlines() if line.startswith("done ")}
        if set(tasks) <= finished:
            return []
        files = {"picture": "net.png", "plot": "deployment.png", "movie": "deployment.mp4"}
        return [f"rendering timed out after {timeout_s:.0f} s; the results are complete without "
                f"{', '.join(files[t] for t in tasks if t not in finished)}"]
    finished = {line[5:] for line in done.stdout.splitlines() if line.startswith("done ")}
    errors = done.stderr.strip().splitlines()

    def why(task: str) -> str:
        own = [line for line in errors if line.startswith(f"{task} failed: ")]
        return own[-1][len(task) + 9:] if own else (errors or [f"exit status {done.returncode}"])[-1]

    warnings = []
    figures = [t for t in ("picture", "plot") if t in tasks and t not in finished]
    if figures:
        warnings.append(f"could not draw the figures ({why(figures[0])}); the results are "
                        "complete without them. Headless rendering needs libegl1 and "
                        "libgl1-mesa-dri (see the README).")
    if "movie" in tasks and "movie" not in finished:
        warnings.append(f"could not write the movie ({why('movie')}); the results are complete "
                        "without it. It needs off-screen rendering (libegl1, libgl1-mesa-dri) "
                        "and the ffmpeg of imageio-ffmpeg (pip install -e '.[viz]').")
    return warnings


def draw_run_figures(result: Any, output: Any, movie: bool = False) -> list[str]:
    """Draw what ``rodnet run`` draws after a run: for a completed net run whose scene asks for
    them (``output.picture``, ``output.plot``), ``net.png`` and ``deployment.png`` in its
    directory (:func:`render_in_subprocess`).

    Parameters
    ----------
    result : rodnet.run.RunResult
        The run.
    output : rodnet.config.OutputSpec
        The scene's ``[output]``.
    movie : bool
        Also write ``deployment.mp4`` (``rodnet demo``).

    Returns
    -------
    warnings : list of str
        Why a figure could not be drawn, if it could not.
    """
    if result.status == "ok" and (output.picture or output.plot or movie) \
            and "mouth_area" in result.arrays:
        return render_in_subprocess(result.directory, output.picture, output.plot, movie)
    return []


# ---------------------------------------------------------------------------------------------
# deployment.png


@dataclass(frozen=True)
class Curve:
    """One line of a panel: ``values`` (F,) against the run's ``time``."""

    label: str
    values: FloatArray


@dataclass(frozen=True)
class Panel:
    """One axes of ``deployment.png``: curves on the left axis and, optionally, on a right one."""

    title: str
    ylabel: str
    curves: list[Curve]
    right_ylabel: str = ""
    right_curves: list[Curve] = field(default_factory=list)


def deployment_panels(data: Any) -> list[Panel]:
    """The panels of ``deployment.png`` for the arrays of ``result.npz`` (a mapping).

    Without bodies: one panel, mouth area (left) and distance (right). With bodies, in this
    order: that panel (for a net), the contact force (sum of the contact point force
    magnitudes) [N], the bodies' speed [m/s] (left) and spin, the magnitude of the angular
    velocity [deg/s] (right), and the energies [J] (kinetic, elastic, and contact when the
    results hold a ``contact_energy``).
    """
    panels = []
    if "mouth_area" in data:
        panels.append(Panel("Net deployment", "mouth area [m$^2$]",
                            [Curve("mouth area", data["mouth_area"])], "distance travelled [m]",
                            [Curve("distance", data["distance"])]))
    if "body_positions" not in data:
        return panels
    names = [str(n) for n in data["body_names"]]
    panels.append(Panel("Contact force", "contact force [N]",
                        [Curve("sum of contact point forces", data["contact_force"])]))
    speed = np.linalg.norm(data["body_velocities"], axis=2)                  # (F, B)
    spin = np.degrees(np.linalg.norm(data["body_angular_velocities"], axis=2))
    panels.append(Panel("Target velocity and spin", "speed [m/s]",
                        [Curve(f"{n} speed", speed[:, b]) for b, n in enumerate(names)],
                        "spin [deg/s]",
                        [Curve(f"{n} spin", spin[:, b]) for b, n in enumerate(names)]))
    energies = [Curve(label, data[key]) for label, key in
                (("kinetic", "kinetic_energy"), ("elastic", "elastic_energy"),
                 ("contact", "contact_energy")) if key in data]
    panels.append(Panel("Energy", "energy [J]", energies))
    return panels


def _draw_panel(ax: Any, time: FloatArray, panel: Panel, legend: bool) -> None:
    """Draw ``panel`` on ``ax``; a right axis only when the panel has right curves."""
    left_colours = ["tab:blue", "tab:green", "tab:purple", "tab:brown"]
    right_colours = ["tab:orange", "tab:red", "tab:pink", "tab:olive"]
    for k, curve in enumerate(panel.curves):
        ax.plot(time, curve.values, color=left_colours[k % 4], label=curve.label)
    ax.set_xlabel("time [s]")
    ax.set_ylabel(panel.ylabel, color=left_colours[0] if panel.right_curves else "black")
    ax.set_title(panel.title)
    handles, labels = ax.get_legend_handles_labels()
    if panel.right_curves:
        twin = ax.twinx()
        for k, curve in enumerate(panel.right_curves):
            twin.plot(time, curve.values, color=right_colours[k % 4], label=curve.label)
        twin.set_ylabel(panel.right_ylabel, color=right_colours[0])
        more = twin.get_legend_handles_labels()
        handles, labels = handles + more[0], labels + more[1]
    if legend:
        ax.legend(handles, labels, fontsize=8, loc="best")


def plot_deployment(directory: Path) -> Path:
    """Draw :func:`deployment_panels` to ``deployment.png``: a single panel as one figure, more
    as a grid of two columns."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    data = dict(np.load(directory / "result.npz"))
    panels = deployment_panels(data)
    if len(panels) <= 1:
        fig, axes = plt.subplots(figsize=(7, 4), constrained_layout=True, squeeze=False)
    else:
        rows = (len(panels) + 1) // 2
        fig, axes = plt.subplots(rows, 2, figsize=(12, 4 * rows), constrained_layout=True,
                                 squeeze=False)
    flat = axes.ravel()
    for ax, panel in zip(flat, panels):
        _draw_panel(ax, data["time"], panel, legend=len(panels) > 1)
    for ax in flat[len(panels):]:
        ax.set_visible(False)
    path = directory / "deployment.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


# ---------------------------------------------------------------------------------------------
# net.png


@dataclass(frozen=True)
class BodyAtFrame:
    """A body's surface at one frame: world ``vertices`` (V, 3) [m], ``faces`` (T, 3), and the
    signed distance of world points (P, 3) to it [m] (negative inside)."""

    name: str
    vertices: FloatArray
    faces: NDArray[np.int64]
    distance: Any


def bodies_at_frame(directory: Path, data: Any, summary: dict[str, Any], frame: int,
                    ) -> tuple[list[BodyAtFrame], list[str]]:
    """The run's bodies at ``frame`` (see the module docstring for where the surfaces come
    from) and the names of the bodies that could not be drawn."""
    from rodnet.contact.shapes import shape_from_scene
    from rodnet.contact.surfaces import surface_triangles
    from rodnet.kernels.so3 import quat_to_matrix

    specs = summary.get("scene", {}).get("bodies", [])
    found, missing = [], []
    for b, spec in enumerate(specs):
        position = np.asarray(data["body_positions"][frame, b], float)
        rotation = quat_to_matrix(np.asarray(data["body_rotations"][frame, b], float))
        if spec["shape"] != "mesh":
            shape = shape_from_scene(spec["shape"], tuple(spec["size"]))
            local, faces = surface_triangles(shape)

            def distance(points: FloatArray, shape: Any = shape, c: FloatArray = position,
                         r: FloatArray = rotation) -> FloatArray:
                return shape.query((np.asarray(points) - c) @ r).distance   # exact, body frame

            found.append(BodyAtFrame(spec["name"], position + local @ rotation.T, faces, distance))
            continue
        vtu = directory / "vtk" / f"body_{b}_{frame:05d}.vtu"
        if not vtu.is_file():
            missing.append(spec["name"])
            continue
        import meshio

        mesh = meshio.read(vtu)
        found.append(BodyAtFrame(spec["name"], np.asarray(mesh.points, float),
                                 mesh.cells_dict["triangle"], _mesh_distance(mesh)))
    return found, missing


def _mesh_distance(mesh: Any) -> Any:
    """Signed distance [m] of points to a closed triangle mesh (VTK's implicit poly-data
    distance, exact for the triangles)."""
    import pyvista as pv

    faces = mesh.cells_dict["triangle"]
    surface = pv.PolyData(np.asarray(mesh.points, float),
                          np.column_stack([np.full(len(faces), 3), faces]).ravel())

    def distance(points: FloatArray) -> FloatArray:
        probe = pv.PolyData(np.asarray(points, float)).compute_implicit_distance(surface)
        return np.asarray(probe["implicit_distance"], float)

    return distance


def contact_nodes(points: FloatArray, bodies: list[BodyAtFrame], summary: dict[str, Any],
                  ) -> NDArray[np.bool_]:
    """(N,) True for the nodes at ``points`` (N, 3) [m] that touch a body: closer to its
    surface than the thread radius plus the contact law's smoothing gap, where the penalty
    force starts (N1). The radius is half the largest material diameter (one radius per node
    is not in the results); contact between nodes, on a segment, is not marked."""
    scene = summary.get("scene", {})
    radius = 0.5 * max((m["diameter"] for m in scene.get("materials", [])), default=0.0)
    reach = radius + float(scene.get("contact", {}).get("smoothing", 0.0))
    touching = np.zeros(len(points), dtype=bool)
    for body in bodies:
        touching |= body.distance(points) < reach
    return touching


TENSION = "tension [N]"
"""Name of the threads' cell scalars in the pictures and the movie (the title of the colour bar)."""


def thread_mesh(data: Any, frame: int) -> Any:
    """The threads at ``frame`` as a pyvista ``PolyData``: the nodes (N, 3) [m] as points, the
    ``segments`` of ``result.npz`` as lines, and cell scalars :data:`TENSION` (E,) [N]."""
    import pyvista as pv

    segments = data["segments"]
    lines = np.column_stack([np.full(len(segments), 2), segments]).ravel()
    mesh = pv.PolyData(np.array(data["positions"][frame], float), lines=lines)
    mesh.cell_data[TENSION] = data["tension"][frame]
    return mesh


def add_threads(plotter: Any, mesh: Any, clim: tuple[float, float] | None = None) -> None:
    """Draw the threads of :func:`thread_mesh` coloured by tension (viridis) with a vertical
    colour bar at the right; ``clim`` (low, high) [N] fixes the colour range (default: the
    mesh's range)."""
    plotter.add_mesh(mesh, scalars=TENSION, cmap="viridis", line_width=2, clim=clim,
                     scalar_bar_args=dict(title=TENSION, vertical=True, position_x=0.88,
                                          position_y=0.25, width=0.05, height=0.5,
                                          title_font_size=16, label_font_size=14, n_labels=5,
                                          fmt="%.3g"))


def frame_label(summary: dict[str, Any], time: float) -> str:
    """The caption of a frame: ``t = 1.23 s``, or for a static run, whose frame times are load
    factors, ``load factor 0.50``."""
    if summary.get("scene", {}).get("simulation", {}).get("type") == "static":
        return f"load factor {time:.2f}"
    return f"t = {time:.2f} s"


def corner_nodes(summary: dict[str, Any]) -> list[int]:
    """The node indices of a net's four corner masses (none for rods)."""
    nodes = summary.get("nodes", {})
    return [nodes[f"net:corner:{k}"] for k in range(4)] if "net:corner:0" in nodes else []


def body_surface(vertices: FloatArray, faces: NDArray[np.int64]) -> Any:
    """A body's triangles, ``vertices`` (V, 3) [m] and ``faces`` (T, 3), as pyvista
    ``PolyData``."""
    import pyvista as pv

    return pv.PolyData(np.array(vertices, float),
                       np.column_stack([np.full(len(faces), 3), faces]).ravel())


def add_scale_and_view(plotter: Any, bounds: Any = None, labelled_box: bool = True) -> None:
    """Labelled axes of the box ``bounds`` (6,) [m] (default: everything drawn; left out when
    not ``labelled_box``), an axes triad, and an isometric camera on that box, zoomed out to
    leave the right margin to the colour bar."""
    box = np.asarray(plotter.bounds if bounds is None else bounds, float)
    extent = float(np.ptp(box.reshape(3, 2), axis=1).max())
    decimals = int(np.clip(2 - np.floor(np.log10(extent)), 0, 6)) if extent > 0 else 3
    if labelled_box:
        plotter.show_bounds(bounds=list(box), xtitle="x [m]", ytitle="y [m]", ztitle="z [m]",
                            grid=False, location="outer", ticks="outside", font_size=10,
                            fmt=f"%.{decimals}f", n_xlabels=3, n_ylabels=3, n_zlabels=3)
    plotter.add_axes(line_width=3, labels_off=False)
    plotter.view_isometric(bounds=list(box))
    plotter.camera_set = True   # else the camera getter fits the view to the actors again
    plotter.camera.zoom(0.85)


def picture_at_max_area(directory: Path) -> Path:
    """The net at maximum mouth area, threads coloured by tension, ``net.png``; with bodies,
    their surfaces (grey) at that frame and the nodes in contact (magenta, :func:`contact_nodes`;
    the corner masses are red).
    An axes triad and labelled bounds in metres give the orientation and the scale."""
    import pyvista as pv

    data = dict(np.load(directory / "result.npz"))
    summary = json.loads((directory / "summary.json").read_text())
    frame = int(np.argmax(data["mouth_area"])) if "mouth_area" in data else len(data["time"]) - 1
    points = data["positions"][frame]
    plotter = pv.Plotter(off_screen=True, window_size=(1000, 800))
    add_threads(plotter, thread_mesh(data, frame))
    corners = corner_nodes(summary)
    if corners:
        plotter.add_mesh(pv.PolyData(points[corners]), color="red", point_size=12,
                         render_points_as_spheres=True)
    text = frame_label(summary, data["time"][frame])
    if "body_positions" in data:
        text += _draw_bodies(plotter, directory, data, summary, frame, points)
    plotter.add_text(text, font_size=12)
    add_scale_and_view(plotter)
    path = directory / "net.png"
    plotter.screenshot(str(path))
    plotter.close()
    return path


def _draw_bodies(plotter: Any, directory: Path, data: Any, summary: dict[str, Any], frame: int,
                 points: FloatArray) -> str:
    """Add the bodies and the contact nodes to ``plotter``; return the caption's lines."""
    import pyvista as pv

    bodies, missing = bodies_at_frame(directory, data, summary, frame)
    for body in bodies:
        plotter.add_mesh(body_surface(body.vertices, body.faces), color="lightgrey")
    touching = contact_nodes(points, bodies, summary)
    if touching.any():
        plotter.add_mesh(pv.PolyData(points[touching]), color="magenta", point_size=10,
                         render_points_as_spheres=True, label="node in contact")
    text = (f"\ncontact: {int(data['contact_count'][frame])} points, "
            f"{float(data['contact_force'][frame]):.3g} N; magenta: {int(touching.sum())} nodes "
            "touching")
    if missing:
        text += f"\nnot drawn (mesh without VTK output): {', '.join(missing)}"
    return text
