"""The frame recorder: every saved frame kept in memory, streamed to VTK, and checked.

Integrators hand it the time and the state; a frame function (the system's, given by the run)
turns the state into plain arrays. The recorder keeps them, writes them to the VTK series, and
runs the checks of a frame (the run's energy guard and the model's own), which end the run with
:class:`rodnet.errors.SimulationFailed`; the offending frame is not kept (a diverged state, whose
positions of 1e22 m had made the summary's metrics), so a failed run's results end at its last
good frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
from numpy.typing import NDArray

from rodnet.errors import SimulationFailed
from rodnet.io.vtk import VtkSeries
from rodnet.state import State

FrameFunction = Callable[[float, State], dict[str, Any]]
FrameCheck = Callable[[float, dict[str, Any]], None]

MONITORS = ("max_element_rotation", "inside_out_elements", "folded_elements")
"""Frame scalars the recorder tracks, without saving them: the largest (under their name), the
last frame's (``<name>_last``) and the number of frames where they are positive
(``<name>_frames``)."""

SHAPES = {"positions": ("N", 3), "velocities": ("N", 3), "rotations": ("N", 4), "tension": ("E",),
          "curvature": ("E",), "twist": ("E",), "kinetic_energy": (), "elastic_energy": (),
          "potential_energy": (), "load_factor_energy": (), "contact_energy": (),
          "contact_force": (), "contact_count": (), "contact_depth": (), "friction_work": (),
          "body_force": ("B", 3),
          "body_moment": ("B", 3), "body_positions": ("B", 3), "body_rotations": ("B", 4),
          "body_velocities": ("B", 3), "body_angular_velocities": ("B", 3),
          "rotation_node_quaternions": ("R", 4), "rotation_node_spins": ("R", 3),
          "section_forces": ("E", 3), "section_moments": ("E", 3),
          "support_reactions": ("S", 3)}
"""The arrays a frame may hold and their shape per frame (N nodes, E elements, B bodies, R
rotation nodes, S supported nodes)."""


@dataclass
class Recorder:
    """Keeps every frame in memory and streams it to VTK when asked.

    Parameters
    ----------
    frame_of : callable
        ``frame_of(t, state) -> dict`` of arrays (:data:`SHAPES`) and monitors (:data:`MONITORS`).
    vtk : VtkSeries or None
    checks : list of callables
        ``check(t, frame)`` raising :class:`SimulationFailed`; run on every kept frame.
    skip_first : bool
        Drop the first frame (a static run's unloaded start is not a load step).
    advice : str
        Appended to the message of a failed check: what the user should change.
    only : set of float, optional
        The times to keep; the integrators also stop at others (where a load switches on or
        off), which are passed over. None: every time handed over.
    """

    frame_of: FrameFunction
    vtk: VtkSeries | None = None
    checks: list[FrameCheck] = field(default_factory=list)
    skip_first: bool = False
    advice: str = ""
    only: set[float] | None = None
    time: list[float] = field(default_factory=list)
    frames: list[dict[str, Any]] = field(default_factory=list)
    monitors: dict[str, float] = field(default_factory=dict)

    def __call__(self, t: float, state: State) -> None:
        if self.skip_first:
            self.skip_first = False
            return
        if self.only is not None and t not in self.only:
            return
        frame = self.frame_of(t, state)
        monitors = {key: float(frame.pop(key)) for key in MONITORS if key in frame}
        try:   # a frame that fails its checks (a diverged state) is not kept
            for check in self.checks:
                check(t, frame)
        except SimulationFailed as exc:
            raise SimulationFailed(f"{exc}; {self.advice}" if self.advice else str(exc)) from None
        for key, value in monitors.items():
            self.monitors[key] = max(self.monitors.get(key, 0.0), value)
            self.monitors[f"{key}_last"] = value
            self.monitors[f"{key}_frames"] = self.monitors.get(f"{key}_frames", 0.0) + \
                float(value > 0.0)
        self.time.append(t)
        self.frames.append(frame)
        if self.vtk is not None:
            self.vtk.write(t, frame)

    def arrays(self, n_nodes: int, n_elements: int) -> dict[str, NDArray[Any]]:
        """``time`` (F,) and every array of the frames stacked (F, ...), e.g. ``positions`` and
        ``velocities`` (F, N, 3), ``tension`` (F, E); a run that saved no frame gets empty
        ``positions``, ``velocities`` and ``tension``."""
        out: dict[str, NDArray[Any]] = {"time": np.array(self.time)}
        if not self.frames:
            sizes = {"N": n_nodes, "E": n_elements}
            for key in ("positions", "velocities", "tension"):
                out[key] = np.zeros((0, *(sizes.get(d, d) for d in SHAPES[key])))
            return out
        for key in self.frames[0]:
            out[key] = np.array([f[key] for f in self.frames])
        return out


def mechanical_energy(frames: dict[str, Any], potential: bool) -> tuple[Any, Any]:
    """The energy [J] of a frame, or of the frames' stacked arrays (F,), that the energy checks
    watch, and its part in motion: ``motion`` = kinetic + elastic + the contact's penalty springs
    (with bodies), ``energy`` = ``motion`` plus, with ``potential``, the frame's
    ``potential_energy`` (gravity on the nodes and on the bodies, the dead forces) less its
    ``load_factor_energy`` (what the loads' time factors changed of it): constant where
    nothing dissipates."""
    motion = frames["kinetic_energy"] + frames["elastic_energy"] + frames.get("contact_energy", 0.0)
    if not potential:
        return motion, motion
    return motion + frames["potential_energy"] - frames.get("load_factor_energy", 0.0), motion


def energy_gain(energy: Any, start: float) -> Any:
    """How far ``energy`` [J] (a number or an array) rose above ``start``, 0 within round-off
    (1e-9 J plus 1e-9 of ``start``): what the energy checks measure."""
    gain = np.asarray(energy, dtype=float) - start
    return np.where(gain > 1e-9 + 1e-9 * abs(start), gain, 0.0)


def energy_guard(growth: float = 0.1, potential: bool = False,
                 forces: str = "gravity") -> FrameCheck:
    """A check that stops a run whose energy (:func:`mechanical_energy`), which nothing raises,
    rises.

    Without ``potential``, for scenes with nothing that does work on them (no gravity, no
    loads): the energy may not rise above the first frame's by more than ``growth`` of it.
    With ``potential``, for scenes where only forces with a potential do work (``forces``, for
    the message: gravity, loads without a moment; what their time factors changed of the
    potential, ``load_factor_energy``, taken out): the energy counts their potential and may not
    rise above the first frame's by more than ``growth`` of the largest energy in motion of the
    frames so far (the potential has no natural zero). An integrator
    that is not stable on a stiff nonlinear problem (the midpoint rule with contact at a large
    fixed step, symplectic Euler on a light rope pressed on a drum) would otherwise report a
    diverging run as done."""
    start: list[float] = []
    largest = [0.0]

    def check(t: float, frame: dict[str, Any]) -> None:
        now, motion = mechanical_energy(frame, potential)
        if not np.isfinite(now):
            raise SimulationFailed(f"the state became non-finite (NaN or inf) by t = {t:.6g} s")
        if not start:
            start.append(now)
        largest[0] = max(largest[0], motion)
        allowed = growth * (largest[0] if potential else start[0])
        if energy_gain(now, start[0]) > allowed:
            cause = f"nothing but {forces}, whose potential is counted, does work on the " \
                "structure" if potential else "nothing does work on the structure"
            raise SimulationFailed(
                f"the energy grew from {start[0]:.6g} J to {now:.6g} J by t = {t:.6g} s although "
                f"{cause}: the time integration is unstable at this step")

    return check
