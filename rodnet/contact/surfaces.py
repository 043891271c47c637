"""What a run with rigid bodies writes: contact time series, body poses and body surfaces.

:class:`ContactLog` sits between an integrator and the run's frame recorder: for every saved frame
it records the contact totals (:func:`rodnet.contact.forces.contact_state`), the friction work
done so far (``stats.extra["friction_work"]``, summed by the integrators step by step) and the
bodies' state (``contact.motion``), moves the body surfaces of the recorder's VTK series to the
frame's poses, and hands the frame on. :func:`body_surfaces` gives each body's surface as triangles in world
coordinates for the VTK series. Result names are in ``docs/contact.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rodnet.contact.bodies import BodyContact
from rodnet.contact.forces import contact_state
from rodnet.contact.geometry import Box, Cylinder, Shape, Sphere
from rodnet.integrate.frames import StepStats

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

CYLINDER_SIDES = 64
SPHERE_RINGS = 24


@dataclass
class ContactLog:
    """Frame sink that records contact and forwards the frame to ``recorder``.

    Parameters
    ----------
    contact : BodyContact
    recorder : callable
        The run's recorder; it must keep a ``time`` list of the frames it kept (a static run's
        recorder drops its first call, and so does the log).
    stats : StepStats
        The integrator's counters; ``extra["friction_work"]`` is read at every frame.
    """

    contact: BodyContact
    recorder: Any
    stats: StepStats
    total_force: list[float] = field(default_factory=list)
    count: list[int] = field(default_factory=list)
    body_force: list[FloatArray] = field(default_factory=list)
    body_moment: list[FloatArray] = field(default_factory=list)
    friction_work: list[float] = field(default_factory=list)
    poses: dict[str, list[FloatArray]] = field(default_factory=lambda: {
        "position": [], "quaternion": [], "velocity": [], "omega": []})
    _started: bool = False

    def __call__(self, t: float, q: Any, v: FloatArray) -> None:
        contact = self.contact
        if not self._started:  # the start frame comes before the integrator touches the bodies
            contact.motion.set(contact.start_motion())
            self._started = True
        self._move_vtk_bodies()
        kept = len(self.recorder.time)
        try:
            self.recorder(t, q, v)
        finally:
            if len(self.recorder.time) > kept:
                x = np.asarray(getattr(q, "x", q)).reshape(-1, 3)  # rods: q.x; else x
                state = contact_state(contact, x, np.asarray(v)[:x.size].reshape(-1, 3))
                self.total_force.append(state.total_force)
                self.count.append(state.count)
                self.body_force.append(state.body_force)
                self.body_moment.append(state.body_moment)
                self.friction_work.append(self.stats.extra.get("friction_work", 0.0))
                for key, values in self.poses.items():
                    values.append(np.array(getattr(contact.motion, key)))

    def _move_vtk_bodies(self) -> None:
        """Put the free bodies' surfaces of the recorder's VTK series at their current pose."""
        vtk = getattr(self.recorder, "vtk", None)
        if vtk is None or not self.contact.free.any():
            return
        motion = self.contact.motion
        for b in np.flatnonzero(self.contact.free):
            local = surface_triangles(self.contact.shapes[b])[0]
            vtk.bodies[b].points = motion.position[b] + local @ motion.rotation[b].T

    def arrays(self) -> dict[str, NDArray[Any]]:
        """``contact_force`` [N], ``contact_count``, ``friction_work`` [J] (F,);
        ``body_force`` [N], ``body_moment`` [N m] (about the centre of mass),
        ``body_positions`` [m], ``body_velocities`` [m/s] and ``body_angular_velocities``
        (world axes) [rad/s] (F, B, 3); ``body_rotations`` (F, B, 4) quaternions (w, x, y, z);
        ``body_names`` (B,)."""
        frames, bodies = len(self.total_force), self.contact.n_bodies

        def stacked(values: list[FloatArray], width: int) -> FloatArray:
            return np.array(values, dtype=np.float64).reshape(frames, bodies, width)

        return {
            "contact_force": np.array(self.total_force, dtype=np.float64),
            "contact_count": np.array(self.count, dtype=np.int64),
            "friction_work": np.array(self.friction_work, dtype=np.float64),
            "body_force": stacked(self.body_force, 3),
            "body_moment": stacked(self.body_moment, 3),
            "body_positions": stacked(self.poses["position"], 3),
            "body_rotations": stacked(self.poses["quaternion"], 4),
            "body_velocities": stacked(self.poses["velocity"], 3),
            "body_angular_velocities": stacked(self.poses["omega"], 3),
            "body_names": np.array(self.contact.names, dtype=str),
        }

    def add_results(self, arrays: dict[str, NDArray[Any]], summary: dict[str, Any]) -> None:
        """Add :meth:`arrays` to the run's ``arrays``, and to its ``summary`` the ``bodies``
        (name to index), the ``contact`` time series (``time``, ``force``, ``count``,
        ``friction_work``) and the metrics ``max_contact_force``, ``max_contact_count`` and
        ``friction_work``."""
        arrays.update(self.arrays())
        force = np.array(self.total_force)
        summary["bodies"] = {name: i for i, name in enumerate(self.contact.names)}
        summary["contact"] = {"time": [float(t) for t in arrays["time"]], "force": force.tolist(),
                              "count": [int(c) for c in self.count],
                              "friction_work": [float(w) for w in self.friction_work]}
        summary.setdefault("metrics", {}).update({
            "max_contact_force": float(force.max(initial=0.0)),
            "max_contact_count": int(max(self.count, default=0)),
            "friction_work": float(self.stats.extra.get("friction_work", 0.0))})


def _box_surface(h: tuple[float, float, float]) -> tuple[FloatArray, IntArray]:
    corners = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    faces = [(a, b, c) for a, b, c, d in quads] + [(a, c, d) for a, b, c, d in quads]
    return corners * np.asarray(h), np.array(faces, dtype=np.int64)


def _cylinder_surface(c: Cylinder) -> tuple[FloatArray, IntArray]:
    n = CYLINDER_SIDES
    angle = 2.0 * np.pi * np.arange(n) / n
    ring = np.stack([c.radius * np.cos(angle), c.radius * np.sin(angle)], axis=1)
    z = 0.5 * c.length
    local = np.vstack([np.column_stack([ring, np.full(n, -z)]), np.column_stack([ring, np.full(n, z)]),
                       [[0.0, 0.0, -z], [0.0, 0.0, z]]])
    i, j = np.arange(n), (np.arange(n) + 1) % n
    faces = np.vstack([np.column_stack([i, j, n + j]), np.column_stack([i, n + j, n + i]),
                       np.column_stack([np.full(n, 2 * n), j, i]),
                       np.column_stack([np.full(n, 2 * n + 1), n + i, n + j])])
    # the cylinder's axis is body axis ``c.axis``: rotate z onto it
    order = {0: [2, 0, 1], 1: [1, 2, 0], 2: [0, 1, 2]}[c.axis]
    return local[:, order], faces.astype(np.int64)


def _sphere_surface(s: Sphere) -> tuple[FloatArray, IntArray]:
    rings, sides = SPHERE_RINGS, 2 * SPHERE_RINGS
    polar = np.pi * np.arange(1, rings) / rings
    azimuth = 2.0 * np.pi * np.arange(sides) / sides
    p, a = np.meshgrid(polar, azimuth, indexing="ij")
    body = np.stack([np.sin(p) * np.cos(a), np.sin(p) * np.sin(a), np.cos(p)], axis=-1).reshape(-1, 3)
    local = s.radius * np.vstack([[[0.0, 0.0, 1.0]], body, [[0.0, 0.0, -1.0]]])
    top, bottom = 0, len(local) - 1

    def vid(r: IntArray, k: IntArray) -> IntArray:
        return 1 + r * sides + k % sides

    k = np.arange(sides)
    faces = [np.column_stack([np.full(sides, top), vid(np.zeros_like(k), k), vid(np.zeros_like(k), k + 1)]),
             np.column_stack([np.full(sides, bottom), vid(np.full_like(k, rings - 2), k + 1),
                              vid(np.full_like(k, rings - 2), k)])]
    for r in range(rings - 2):
        rr = np.full_like(k, r)
        faces.append(np.column_stack([vid(rr, k), vid(rr + 1, k), vid(rr + 1, k + 1)]))
        faces.append(np.column_stack([vid(rr, k), vid(rr + 1, k + 1), vid(rr, k + 1)]))
    return local, np.vstack(faces).astype(np.int64)


def surface_triangles(shape: Shape) -> tuple[FloatArray, IntArray]:
    """Triangulated surface of ``shape`` in its body frame: vertices (V, 3) [m], faces (F, 3)."""
    if isinstance(shape, Box):
        return _box_surface(shape.half_extents)
    if isinstance(shape, Cylinder):
        return _cylinder_surface(shape)
    if isinstance(shape, Sphere):
        return _sphere_surface(shape)
    return np.asarray(shape.vertices), np.asarray(shape.faces)  # type: ignore[attr-defined]


def body_surfaces(model: Any) -> list[tuple[str, FloatArray, IntArray]]:
    """``(name, vertices (V, 3) in world coordinates [m], faces (F, 3))`` of every body of
    ``model``; empty for a model without bodies."""
    contact: BodyContact | None = getattr(model, "contact", None)
    if contact is None:
        return []
    out = []
    for b, shape in enumerate(contact.shapes):
        local, faces = surface_triangles(shape)
        world = contact.position[b] + local @ contact.rotation[b].T  # the start pose
        out.append((contact.names[b], world, faces))
    return out
