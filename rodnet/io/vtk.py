"""VTU frames written as they are computed, and the ``.pvd`` file that makes them a time series.

meshio writes each frame (nodes as points, segments as VTK lines, point data ``velocity``, cell data
``tension``); the ``.pvd`` collection is a small XML file rewritten after every frame, so that a
run that stops early still leaves a readable series. Rigid bodies are more parts of the same
series: at every frame, body ``b``'s surface triangles go to ``vtk/body_B_NNNNN.vtu``, listed in
the ``.pvd`` with ``part = b + 1`` (the threads are part 0).
"""

from __future__ import annotations

from collections.abc import Sequence
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
    bodies : sequence of (name, vertices (V, 3) float, faces (F, 3) int)
        Surfaces of the rigid bodies in world coordinates [m], written with every frame.
    """

    def __init__(self, directory: Path, segments: NDArray[np.int64],
                 bodies: Sequence[tuple[str, NDArray[np.float64], NDArray[np.int64]]] = ()) -> None:
        self.directory = directory
        self.frame_dir = directory / "vtk"
        self.frame_dir.mkdir(parents=True, exist_ok=True)
        for pattern in ("frame_*.vtu", "body_*.vtu"):
            for stale in self.frame_dir.glob(pattern):
                stale.unlink()
        self.cells = [("line", np.asarray(segments, dtype=np.int64))]
        self.bodies = [meshio.Mesh(np.asarray(v, float), [("triangle", np.asarray(f, np.int64))])
                       for _, v, f in bodies]
        self.entries: list[tuple[float, str]] = []
        self.parts: list[tuple[float, int, str]] = []

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
        for b, surface in enumerate(self.bodies):
            body_name = f"vtk/body_{b}_{len(self.entries):05d}.vtu"
            meshio.write(self.directory / body_name, surface, file_format="vtu", compression=None)
            self.parts.append((time, b + 1, body_name))
        self.entries.append((time, name))
        self.write_pvd()

    def write_pvd(self) -> None:
        """(Re)write ``result.pvd`` listing every frame written so far."""
        lines = ['<?xml version="1.0"?>',
                 '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
                 "  <Collection>"]
        lines += [f'    <DataSet timestep="{t:.9g}" group="" part="0" file={quoteattr(f)}/>'
                  for t, f in self.entries]
        lines += [f'    <DataSet timestep="{t:.9g}" group="" part="{part}" file={quoteattr(f)}/>'
                  for t, part, f in self.parts]
        lines += ["  </Collection>", "</VTKFile>", ""]
        tmp = self.directory / "result.pvd.tmp"
        tmp.write_text("\n".join(lines))
        tmp.replace(self.directory / "result.pvd")
