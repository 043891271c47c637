"""VTU frames written as they are computed, and the ``.pvd`` file that makes them a time series.

meshio writes each frame (nodes as points, segments as VTK lines, point data ``velocity``, cell data
``tension``); the ``.pvd`` collection is a small XML file rewritten after every frame, so that a
run that stops early still leaves a readable series.
"""

from __future__ import annotations

from pathlib import Path
from xml.sax.saxutils import quoteattr

import meshio
import numpy as np
from numpy.typing import NDArray


class VtkSeries:
    """Writes ``<directory>/vtk/frame_NNNNN.vtu`` and ``<directory>/result.pvd``.

    Parameters
    ----------
    directory : Path
        The run's output directory.
    segments : (E, 2) int
        Node pairs drawn as lines.
    """

    def __init__(self, directory: Path, segments: NDArray[np.int64]) -> None:
        self.directory = directory
        self.frame_dir = directory / "vtk"
        self.frame_dir.mkdir(parents=True, exist_ok=True)
        for stale in self.frame_dir.glob("frame_*.vtu"):
            stale.unlink()
        self.cells = [("line", np.asarray(segments, dtype=np.int64))]
        self.entries: list[tuple[float, str]] = []

    def write(self, time: float, frame: dict[str, NDArray[np.float64]]) -> None:
        """Write one frame: ``positions`` (N, 3) as points, ``velocities`` as point data
        ``velocity``, and every per-element array (``tension`` [N], ``curvature``, ``twist``) as
        cell data."""
        name = f"vtk/frame_{len(self.entries):05d}.vtu"
        n_cells = len(self.cells[0][1])
        cell_data = {k: [np.asarray(a, float)] for k, a in frame.items()
                     if k in ("tension", "curvature", "twist") and len(a) == n_cells}
        mesh = meshio.Mesh(np.asarray(frame["positions"], float), self.cells,
                           point_data={"velocity": np.asarray(frame["velocities"], float)},
                           cell_data=cell_data)
        meshio.write(self.directory / name, mesh, file_format="vtu", compression=None)
        self.entries.append((time, name))
        self.write_pvd()

    def write_pvd(self) -> None:
        """(Re)write ``result.pvd`` listing every frame written so far."""
        lines = ['<?xml version="1.0"?>',
                 '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
                 "  <Collection>"]
        lines += [f'    <DataSet timestep="{t:.9g}" group="" part="0" file={quoteattr(f)}/>'
                  for t, f in self.entries]
        lines += ["  </Collection>", "</VTKFile>", ""]
        tmp = self.directory / "result.pvd.tmp"
        tmp.write_text("\n".join(lines))
        tmp.replace(self.directory / "result.pvd")
