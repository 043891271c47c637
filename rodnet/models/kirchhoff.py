"""Kirchhoff threads: the lumped cable plus a bending hinge at every node inside a thread.

Equations: ``elements/kirchhoff/FORMULATION.md``. The segments, masses, supports and loads are
the lumped model's (:func:`rodnet.reference.lumped.build_lumped`); this module finds the hinges
(K1) and refuses the scenes the model cannot represent, naming the key.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from rodnet.config import Scene
from rodnet.errors import SceneError
from rodnet.topology import Structure

EXPLICIT = ("explicit", "rk45")
"""The integrators that run Kirchhoff threads: the hinges have no tangent for the others."""

STRAIGHT_COSINE = 1.0 - 1e-12
"""A stress-free hinge whose segments' cosine is below this is not straight."""


class Hinges(NamedTuple):
    """Bending hinges (K1): ``nodes`` (H, 3) int ``(a, b, c)``, ``stiffness`` (H,)
    ``k_h = EI / lbar`` [N m], ``tau`` (H,) retardation time [s], ``rest`` (H, 2) rest lengths of
    the segments ``(a, b)`` and ``(b, c)`` [m]."""

    nodes: NDArray[np.int64]
    stiffness: NDArray[np.float64]
    tau: NDArray[np.float64]
    rest: NDArray[np.float64]

    @classmethod
    def none(cls) -> Hinges:
        """No hinges: the lumped model and cables."""
        return cls(np.zeros((0, 3), np.int64), np.zeros(0), np.zeros(0), np.zeros((0, 2)))


def hinges_of(scene: Scene, structure: Structure) -> Hinges:
    """A hinge at the shared node of every two consecutive segments of a thread (K1).

    Raises
    ------
    SceneError
        When a thread is not straight in its stress-free state (a polyline rod with a corner).
    """
    seg, thread = structure.segments, structure.thread
    chained = (thread[:-1] == thread[1:]) & (seg[:-1, 1] == seg[1:, 0])
    first = np.flatnonzero(chained)
    nodes = np.column_stack([seg[first, 0], seg[first, 1], seg[first + 1, 1]]).astype(np.int64)
    rest = np.column_stack([structure.rest_length[first], structure.rest_length[first + 1]])
    _check_straight(scene, structure, nodes, thread[first])
    material = structure.material[first]
    EI = np.array([m.EI for m in scene.materials])[material]
    tau = np.array([m.retardation_time for m in scene.materials])[material]
    return Hinges(nodes, EI / rest.mean(axis=1), tau, rest)


def _check_straight(scene: Scene, structure: Structure, nodes: NDArray[np.int64],
                    thread: NDArray[np.int64]) -> None:
    x = structure.rest_positions
    e0, e1 = x[nodes[:, 1]] - x[nodes[:, 0]], x[nodes[:, 2]] - x[nodes[:, 1]]
    cosine = np.einsum("ij,ij->i", e0, e1) / (np.linalg.norm(e0, axis=1)
                                               * np.linalg.norm(e1, axis=1))
    bent = np.flatnonzero(cosine < STRAIGHT_COSINE)
    if len(bent):
        n_net = len(np.unique(structure.thread)) - len(scene.rods)
        rod = int(thread[bent[0]]) - n_net
        key = f"rods[{rod}].points" if 0 <= rod < len(scene.rods) else "net"
        value = scene.rods[rod].points if 0 <= rod < len(scene.rods) else None
        raise SceneError(key, value, "model.type = 'kirchhoff' needs straight stress-free "
                         "threads (its hinges carry no material frame for a curved rest shape); "
                         "use model.type = 'cosserat' for curved rods")


def check_kirchhoff(scene: Scene) -> None:
    """Refuse what Kirchhoff threads cannot represent, naming the key (FORMULATION.md, Limits)."""
    sim, model = scene.simulation, scene.model
    cosserat = "; use model.type = 'cosserat' for it"
    if sim.type == "static":
        raise SceneError("simulation.type", sim.type, "Kirchhoff threads run 'dynamic' only "
                         "(the hinges have no tangent for the static solver)" + cosserat)
    if scene.integrator not in EXPLICIT:
        raise SceneError("simulation.integrator", scene.integrator,
                         f"Kirchhoff threads run with {' or '.join(map(repr, EXPLICIT))} only "
                         "(the hinges have no tangent for implicit steps)" + cosserat)
    if scene.net is not None and model.knots != "pinned":
        raise SceneError("model.knots", model.knots, "Kirchhoff threads need 'pinned' knots: a "
                         "hinge joins segments of one thread, so the knots pass no moment" + cosserat)
    for i, support in enumerate(scene.supports):
        if support.dofs is None and support.fix == "clamp":
            raise SceneError(f"supports[{i}].fix", support.fix, "Kirchhoff threads have no "
                             "rotations to clamp: use fix = 'pin'" + cosserat)
