"""The net at its maximum mouth area (pyvista, off screen) and the deployment time series
(matplotlib). Both read a finished output directory; :func:`render_in_subprocess` runs them in a
child process so that a machine without working OpenGL loses the picture, never the run.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np


def render_in_subprocess(directory: Path, picture: bool, plot: bool, timeout_s: float = 300.0) -> list[str]:
    """Write ``net.png`` and/or ``deployment.png`` in ``directory``; return warnings, if any."""
    env = dict(os.environ)
    env.setdefault("PYVISTA_OFF_SCREEN", "true")
    args = [sys.executable, "-m", "rodnet.viz.figures", str(directory)]
    args += ["--picture"] if picture else []
    args += ["--plot"] if plot else []
    try:
        done = subprocess.run(args, env=env, capture_output=True, text=True, timeout=timeout_s)
    except subprocess.TimeoutExpired:
        return [f"rendering timed out after {timeout_s:.0f} s; the results are complete without it"]
    if done.returncode != 0:
        tail = (done.stderr.strip().splitlines() or [f"exit status {done.returncode}"])[-1]
        return [f"could not draw the figures ({tail}); the results are complete without them. "
                "Headless rendering needs libegl1 and libgl1-mesa-dri (see the README)."]
    return []


def plot_deployment(directory: Path) -> Path:
    """Mouth area and distance against time, ``deployment.png``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    data = np.load(directory / "result.npz")
    fig, ax = plt.subplots(figsize=(7, 4), constrained_layout=True)
    ax.plot(data["time"], data["mouth_area"], color="tab:blue")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("mouth area [m$^2$]", color="tab:blue")
    twin = ax.twinx()
    twin.plot(data["time"], data["distance"], color="tab:orange")
    twin.set_ylabel("distance travelled [m]", color="tab:orange")
    ax.set_title("Net deployment")
    path = directory / "deployment.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def picture_at_max_area(directory: Path) -> Path:
    """The net at maximum mouth area, threads coloured by tension, ``net.png``."""
    import pyvista as pv

    data = np.load(directory / "result.npz")
    summary = json.loads((directory / "summary.json").read_text())
    frame = int(np.argmax(data["mouth_area"])) if "mouth_area" in data else len(data["time"]) - 1
    segments = data["segments"]
    points = data["positions"][frame]
    lines = np.column_stack([np.full(len(segments), 2), segments]).ravel()
    mesh = pv.PolyData(points, lines=lines)
    mesh.cell_data["tension [N]"] = data["tension"][frame]
    plotter = pv.Plotter(off_screen=True, window_size=(1000, 800))
    plotter.add_mesh(mesh, scalars="tension [N]", cmap="viridis", line_width=2)
    corners = [summary["nodes"][f"net:corner:{k}"] for k in range(4)] if "net:corner:0" in summary["nodes"] else []
    if corners:
        plotter.add_mesh(pv.PolyData(points[corners]), color="red", point_size=12,
                         render_points_as_spheres=True)
    plotter.add_text(f"t = {data['time'][frame]:.2f} s", font_size=12)
    plotter.view_isometric()
    path = directory / "net.png"
    plotter.screenshot(str(path))
    plotter.close()
    return path


if __name__ == "__main__":
    target = Path(sys.argv[1])
    if "--plot" in sys.argv:
        plot_deployment(target)
    if "--picture" in sys.argv:
        picture_at_max_area(target)
