"""Kirchhoff threads: the lumped cable plus a bending hinge at every node inside a thread.

Equations: ``elements/kirchhoff/FORMULATION.md``. The segments, masses, supports and loads are
the lumped model's (:func:`rodnet.models.lumped.build_lumped`); this module finds the hinges
(K1) and refuses the scenes the model cannot represent, naming the key (which integrators and
run types it takes is in the model table, :mod:`rodnet.models.registry`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from rodnet.config import Scene
from rodnet.errors import SceneError
from rodnet.kernels.hinge import Hinges
from rodnet.models.lumped import FloatArray, LumpedModel, build_lumped
from rodnet.state import Configuration
from rodnet.topology import Structure

STRAIGHT_COSINE = 1.0 - 1e-12
"""A stress-free hinge whose segments' cosine is below this is not straight."""


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


def build_kirchhoff(scene: Scene, structure: Structure,
                    ) -> tuple[LumpedModel, Configuration, FloatArray]:
    """The lumped model of the scene with a bending hinge at every node inside a thread
    (``model.bending``; without it, the cable), its initial configuration and velocities.

    Raises
    ------
    SceneError
        For a clamp (the hinges carry no rotations to clamp) or a thread that is not straight in
        its stress-free state.
    """
    cosserat = "; use model.type = 'cosserat' for it"
    for i, support in enumerate(scene.supports):
        if support.clamped:
            raise SceneError(f"supports[{i}].fix", support.fix or "clamp (the default)",
                             "Kirchhoff threads have no rotations to clamp: use fix = 'pin'"
                             + cosserat)
    hinges = hinges_of(scene, structure) if scene.model.bending else None
    return build_lumped(scene, structure, hinges)
