"""Start a run from a saved frame of an earlier run (``[initial] from``).

The earlier run's ``result.npz`` holds, per frame, the node positions and velocities, every
rotation node's quaternion and body-frame angular velocity (models with rotations) and the
bodies' pose and velocities. A run of the same structure starts from one of them: its time
continues from the frame's time (from 0 after a static run, whose frames are load steps).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

import numpy as np
from numpy.typing import NDArray

from rodnet.config import InitialSpec
from rodnet.errors import SceneError
from rodnet.state import BodyMotion, Configuration, State


def saved_frame(spec: InitialSpec) -> tuple[float, dict[str, NDArray[Any]]]:
    """The time [s] and the arrays of the frame ``spec`` names in ``spec.from_``'s results.

    Raises
    ------
    SceneError
        Naming ``initial.from``, ``initial.frame`` or ``initial.time`` when the folder has no
        results or no such frame.
    """
    folder = Path(str(spec.from_))
    path = folder / "result.npz"
    if not path.is_file():
        raise SceneError("initial.from", str(folder), "must be the output folder of an earlier "
                         "run (no result.npz there)")
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files}
    times = arrays["time"]
    if len(times) == 0:
        raise SceneError("initial.from", str(folder), "must hold at least one saved frame")
    if spec.time is not None:
        near = np.flatnonzero(np.abs(times - spec.time) <= 1e-9)
        if not len(near):
            raise SceneError("initial.time", spec.time, f"must be the time of a saved frame of "
                             f"{folder} ({times[0]:g} ... {times[-1]:g} s, "
                             f"{len(times)} frames)")
        k = int(near[0])
    else:
        if not -len(times) <= spec.frame < len(times):
            raise SceneError("initial.frame", spec.frame, f"must index the {len(times)} saved "
                             f"frames of {folder} (0 ... {len(times) - 1}, or -1 for the last)")
        k = spec.frame % len(times)
    frame = {key: value[k] for key, value in arrays.items()
             if key != "time" and value.ndim >= 1 and len(value) == len(times)}
    return (0.0 if _was_static(folder) else float(times[k])), frame


def _was_static(folder: Path) -> bool:
    """Whether the run in ``folder`` was static (its frame times are load factors: a dynamic
    run started from its equilibrium starts at t = 0)."""
    import json

    try:
        summary = json.loads((folder / "summary.json").read_text())
    except (OSError, ValueError):
        return False
    return summary.get("scene", {}).get("simulation", {}).get("type") == "static"


def restarted(state: State, frame: dict[str, NDArray[Any]],
              bodies_from: Callable[[dict[str, NDArray[Any]]], BodyMotion],
              bodies_move_in_state: bool, folder: str) -> State:
    """``state`` (the scene's own start) with the threads (and bodies) of ``frame``;
    ``bodies_from(frame)``: the bodies' motion from the frame's body arrays.

    Raises
    ------
    SceneError
        Naming ``initial.from`` when the frame's structure differs from the scene's.
    """
    x, quat = state.q.x, state.q.quat

    def check(ok: bool, what: str) -> None:
        if not ok:
            raise SceneError("initial.from", folder, f"must be a run of the same structure: {what}")

    check(frame["positions"].shape == x.shape,
          f"{len(frame['positions'])} nodes saved, {len(x)} in this scene")
    saved_quat = frame.get("rotation_node_quaternions", np.zeros((0, 4)))
    check(saved_quat.shape == quat.shape,
          f"{len(saved_quat)} rotation nodes saved, {len(quat)} in this scene (another model, "
          "knots or elements per thread?)")
    v = state.v.copy()
    n3 = x.size
    v[:n3] = frame["velocities"].ravel()
    if len(quat):
        v[n3:n3 + quat.size // 4 * 3] = frame["rotation_node_spins"].ravel()
    q = Configuration(frame["positions"].copy(), saved_quat.copy(), state.q.body_x,
                      state.q.body_quat)
    bodies = state.bodies
    if "body_positions" in frame:
        check(bodies is not None and len(bodies.position) == len(frame["body_positions"]),
              f"{len(frame['body_positions'])} bodies saved, "
              f"{0 if bodies is None else len(bodies.position)} in this scene")
        if bodies_move_in_state:
            raise SceneError("initial.from", folder, "a run with bodies starts from a saved "
                             "frame with the explicit integrator only (set simulation.integrator "
                             "= \"explicit\", or start from a run without bodies)")
        bodies = bodies_from(frame)
    friction = float(frame.get("friction_work", 0.0))
    return State(q, v, bodies, friction, float(frame.get("load_factor_energy", 0.0)))
