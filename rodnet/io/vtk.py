"""VTU frames written as they are computed, the ``.pvd`` file that makes them a time series, and
the ``paraview.py`` script that shows them.

meshio writes each frame (nodes as points, segments as VTK lines, point data ``velocity`` and
``node_id``, cell data ``tension``, ``element_id`` and, when given, ``thread_id``); the ``.pvd``
collection is a small XML file rewritten after every frame, so that a run that stops early still
leaves a readable series, and ``paraview.py`` (:mod:`rodnet.io.paraview`) is rewritten with it.
Rigid bodies are more parts of the same series: at every frame, body ``b``'s surface triangles,
placed at the frame's ``body_positions`` and ``body_rotations`` when the frame holds them, go to
``vtk/body_B_NNNNN.vtu``, listed in the ``.pvd`` with ``part = b + 1`` (the threads are part
0), with the body's index and, when known, its motion as data. Every ``DataSet`` entry carries a ``name`` attribute ("threads", or the body's name),
which ParaView's PVD reader (5.11) shows as the block's name instead of ``Block-01``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from xml.sax.saxutils import quoteattr

import meshio
import numpy as np
from numpy.typing import NDArray

from rodnet.io.paraview import write_paraview_script
from rodnet.kernels.so3 import quat_to_matrix

THREADS_BLOCK = "threads"
"""Name of the threads' block in ``result.pvd``."""

BODY_STATE_KEYS = ("body_positions", "body_velocities", "body_angular_velocities")
"""The bodies' state a frame may carry, (B, 3) arrays named as in ``result.npz``: centre of
mass [m], its velocity [m/s], angular velocity in world axes [rad/s]."""


class VtkSeries:
    """Writes ``<directory>/vtk/frame_NNNNN.vtu``, ``<directory>/result.pvd`` and
    ``<directory>/paraview.py``.

    Parameters
    ----------
    directory : Path
        The run's output directory.
    segments : (E, 2) int
        Node pairs drawn as lines.
    bodies : sequence of (name, vertices (V, 3) float, faces (F, 3) int)
        Surfaces of the rigid bodies [m], written with every frame. When the frames hold
        ``body_positions`` (B, 3) and ``body_rotations`` (B, 4), the vertices are in the body
        frame (origin at the centre of mass) and each frame places them; otherwise they are
        world coordinates, written as they are (a caller may move ``self.bodies[b].points``
        before each :meth:`write`).
    thread : (E,) int, optional
        Thread index of every segment (``Structure.thread``), written as cell data
        ``thread_id``; left out when not given.
    """

    def __init__(self, directory: Path, segments: NDArray[np.int64],
                 bodies: Sequence[tuple[str, NDArray[np.float64], NDArray[np.int64]]] = (),
                 thread: NDArray[np.int64] | None = None) -> None:
        self.directory = Path(directory)
        self.frame_dir = self.directory / "vtk"
        self.frame_dir.mkdir(parents=True, exist_ok=True)
        for pattern in ("frame_*.vtu", "body_*.vtu"):
            for stale in self.frame_dir.glob(pattern):
                stale.unlink()
        segments = np.asarray(segments, dtype=np.int64)
        self.cells = [("line", segments)]
        self.element_id = np.arange(len(segments), dtype=np.int64)
        self.thread = None if thread is None else np.asarray(thread, dtype=np.int64)
        if self.thread is not None and self.thread.shape != (len(segments),):
            raise ValueError(f"thread must give one thread index per segment, shape "
                             f"({len(segments)},); got shape {self.thread.shape}")
        self.body_names = [str(name) for name, _, _ in bodies]
        self.bodies = [meshio.Mesh(np.asarray(v, float), [("triangle", np.asarray(f, np.int64))])
                       for _, v, f in bodies]
        self.entries: list[tuple[float, str]] = []
        self.parts: list[tuple[float, int, str]] = []
        self.tension_range = (np.inf, -np.inf)
        """Smallest and largest finite tension [N] over the frames written so far."""
        self.bounds = np.array([np.inf, -np.inf] * 3)
        """(xmin, xmax, ymin, ymax, zmin, zmax) [m] of nodes and bodies over those frames."""

    def write(self, time: float, frame: dict[str, NDArray[np.float64]],
              bodies: Mapping[str, NDArray[np.float64]] | None = None) -> None:
        """Write one frame and rewrite ``result.pvd`` and ``paraview.py``.

        Parameters
        ----------
        time : float
            Frame time [s].
        frame : dict
            ``positions`` (N, 3) [m] as points, ``velocities`` (N, 3) [m/s] as point data
            ``velocity``, and every per-element array (``tension`` [N], ``curvature``,
            ``twist`` [1/m]) as cell data; for rods the section triads ``d1, d2, d3`` of
            ``rotations`` (N, 4) as point data. With bodies, ``body_positions`` (B, 3) [m] and
            ``body_rotations`` (B, 4) (quaternions w, x, y, z, body to world) place the
            surfaces, and the :data:`BODY_STATE_KEYS` it holds are written on them.
        bodies : mapping, optional
            The bodies' state at this frame, any of :data:`BODY_STATE_KEYS`, each (B, 3), in
            place of those of ``frame``. Written on each body's surface (:meth:`_body_mesh`);
            without any, the surface carries its ``body_id`` only.
        """
        index = len(self.entries)
        name = f"vtk/frame_{index:05d}.vtu"
        positions = np.asarray(frame["positions"], float)
        n_cells = len(self.element_id)
        cell_data = {k: [np.asarray(a, float)] for k, a in frame.items()
                     if k in ("tension", "curvature", "twist") and len(a) == n_cells}
        cell_data["element_id"] = [self.element_id]
        if self.thread is not None:
            cell_data["thread_id"] = [self.thread]
        point_data = {"velocity": np.asarray(frame["velocities"], float),
                      "node_id": np.arange(len(positions), dtype=np.int64)}
        if len(frame.get("rotations", ())) == len(positions):   # rods: the section triads,
            triad = quat_to_matrix(np.asarray(frame["rotations"], float)).astype(np.float32)
            point_data.update(d1=triad[:, :, 0], d2=triad[:, :, 1], d3=triad[:, :, 2])  # to draw
        mesh = meshio.Mesh(positions, self.cells, point_data=point_data, cell_data=cell_data)
        meshio.write(self.directory / name, mesh, file_format="vtu", compression=None)
        self._track(positions, frame.get("tension"))
        if self.bodies:
            state = self._body_state(bodies if bodies is not None else
                                     {k: frame[k] for k in BODY_STATE_KEYS if k in frame})
            rotations = (quat_to_matrix(np.asarray(frame["body_rotations"], float))
                         if "body_positions" in frame and "body_rotations" in frame else None)
        for b in range(len(self.bodies)):
            points = np.asarray(self.bodies[b].points, float)
            if rotations is not None:
                points = np.asarray(frame["body_positions"][b], float) + points @ rotations[b].T
            body_name = f"vtk/body_{b}_{index:05d}.vtu"
            meshio.write(self.directory / body_name, self._body_mesh(b, points, state),
                         file_format="vtu", compression=None)
            self._track(points, None)
            self.parts.append((time, b + 1, body_name))
        self.entries.append((time, name))
        self.write_pvd()

    def _body_state(self, bodies: Mapping[str, NDArray[np.float64]] | None
                    ) -> dict[str, NDArray[np.float64]]:
        """The known keys of ``bodies`` as (B, 3) float arrays; refuse unknown keys or shapes."""
        if bodies is None:
            return {}
        unknown = sorted(set(bodies) - set(BODY_STATE_KEYS))
        if unknown:
            raise ValueError(f"bodies: unknown key(s) {unknown}; allowed: {list(BODY_STATE_KEYS)}")
        state = {k: np.asarray(v, dtype=float) for k, v in bodies.items()}
        for key, value in state.items():
            if value.shape != (len(self.bodies), 3):
                raise ValueError(f"bodies[{key!r}] must have shape ({len(self.bodies)}, 3) "
                                 f"(one row per body); got {value.shape}")
        return state

    def _body_mesh(self, b: int, points: NDArray[np.float64],
                   state: dict[str, NDArray[np.float64]]) -> meshio.Mesh:
        """Body ``b``'s surface at ``points`` (V, 3) [m] with cell data ``body_id`` and, from
        ``state``, cell data ``body_velocity`` [m/s] and ``angular_velocity`` [rad/s] (the same
        on every triangle, so that ParaView can colour by them) and point data ``velocity``
        [m/s], the rigid-body velocity ``v + omega x (p - c)`` of every vertex (needs all three
        keys), which matches the threads' point data of that name."""
        triangles = self.bodies[b].cells[0].data
        n = len(triangles)
        cell_data = {"body_id": [np.full(n, b, dtype=np.int64)]}
        if "body_velocities" in state:
            cell_data["body_velocity"] = [np.tile(state["body_velocities"][b], (n, 1))]
        if "body_angular_velocities" in state:
            cell_data["angular_velocity"] = [np.tile(state["body_angular_velocities"][b], (n, 1))]
        point_data = {}
        if all(k in state for k in BODY_STATE_KEYS):
            arm = points - state["body_positions"][b]
            point_data["velocity"] = state["body_velocities"][b] + np.cross(
                state["body_angular_velocities"][b], arm)
        return meshio.Mesh(points, [("triangle", triangles)], point_data=point_data,
                           cell_data=cell_data)

    def _track(self, points: NDArray[np.float64], tension: NDArray[np.float64] | None) -> None:
        """Widen :attr:`bounds` by ``points`` (P, 3) and :attr:`tension_range` by ``tension``
        (finite values only: a diverged frame must not spoil the colour range)."""
        points = np.asarray(points, float)
        points = points[np.isfinite(points).all(axis=1)]
        if len(points):
            self.bounds[0::2] = np.minimum(self.bounds[0::2], points.min(axis=0))
            self.bounds[1::2] = np.maximum(self.bounds[1::2], points.max(axis=0))
        if tension is not None:
            t = np.asarray(tension, float)
            t = t[np.isfinite(t)]
            if len(t):
                self.tension_range = (min(self.tension_range[0], float(t.min())),
                                      max(self.tension_range[1], float(t.max())))

    def block_names(self) -> list[str]:
        """Names of the series' blocks, in part order: ``threads``, then every body's name."""
        return [THREADS_BLOCK] + self.body_names

    def write_pvd(self) -> None:
        """(Re)write ``result.pvd`` listing every frame written so far, and ``paraview.py``
        with the tension range and bounds of those frames."""
        names = self.block_names()
        lines = ['<?xml version="1.0"?>',
                 '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
                 "  <Collection>"]
        lines += [f'    <DataSet timestep="{float(t)!r}" group="" part="0" name={quoteattr(names[0])} '
                  f'file={quoteattr(f)}/>' for t, f in self.entries]
        lines += [f'    <DataSet timestep="{float(t)!r}" group="" part="{part}" '
                  f'name={quoteattr(names[part])} file={quoteattr(f)}/>'
                  for t, part, f in self.parts]
        lines += ["  </Collection>", "</VTKFile>", ""]
        tmp = self.directory / "result.pvd.tmp"
        tmp.write_text("\n".join(lines))
        tmp.replace(self.directory / "result.pvd")
        write_paraview_script(self.directory, len(self.entries), self.tension_range, self.bounds,
                              self.body_names)
