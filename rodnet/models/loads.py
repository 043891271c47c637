"""The dead loads of a scene on the nodes of its structure: ``[[loads]]`` as given,
``[[line_loads]]`` lumped on the nodes (each element's share ``q l0`` split half and half on its
ends, the consistent load of a linear element), and, when gravity has a time factor
(``simulation.gravity_ramp`` or ``gravity_table``), the node weights; each with its time factor.
Gravity without a time factor stays the models' constant weight (:func:`constant_gravity`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rodnet.config import Scene
from rodnet.kernels.schedule import LoadSchedule, schedule_of
from rodnet.topology import Structure


@dataclass(frozen=True)
class DeadLoads:
    """``nodes`` (L,), ``force`` (L, 3) [N], ``moment`` (L, 3) [N m] and their time factors;
    the first ``len(scene.loads)`` are the ``[[loads]]`` entries in order."""

    nodes: NDArray[np.int64]
    force: NDArray[np.float64]
    moment: NDArray[np.float64]
    schedule: LoadSchedule


def constant_gravity(scene: Scene) -> NDArray[np.float64]:
    """(3,) the gravity the models apply as a constant weight [m/s^2]: the scene's, or zero
    when it has a time factor (then it is among the :func:`dead_loads`)."""
    return np.zeros(3) if scene.simulation.gravity_scheduled else \
        np.asarray(scene.simulation.gravity, float)


def dead_loads(scene: Scene, structure: Structure, node_mass: NDArray[np.float64]) -> DeadLoads:
    """The scene's point and line loads (and scheduled weights of ``node_mass`` (N,) [kg]) on
    the structure's nodes."""
    nodes = [structure.node(l.node, f"loads[{i}].node") for i, l in enumerate(scene.loads)]
    force = [l.force for l in scene.loads]
    timing = list(scene.loads)
    for line in scene.line_loads:
        on = _segments_on(line.on, scene, structure)
        segments = structure.segments[on]
        share = np.zeros((structure.n_nodes, 3))
        half = 0.5 * structure.rest_length[on]
        for end in (0, 1):
            np.add.at(share, segments[:, end], half[:, None] * np.asarray(line.force_per_length))
        loaded = np.flatnonzero(np.abs(share).sum(axis=1) > 0.0)
        nodes += loaded.tolist()
        force += share[loaded].tolist()
        timing += [line] * len(loaded)
    for gravity in _gravity_timing(scene):
        weighted = np.flatnonzero(node_mass > 0.0)
        nodes += weighted.tolist()
        force += (node_mass[weighted, None] * np.asarray(scene.simulation.gravity, float)).tolist()
        timing += [gravity] * len(weighted)
    n = len(nodes)
    return DeadLoads(np.array(nodes, dtype=np.int64), np.array(force, float).reshape(n, 3),
                     np.array([l.moment for l in scene.loads] + [(0.0, 0.0, 0.0)]
                              * (n - len(scene.loads)), float).reshape(n, 3),
                     schedule_of(timing))


def timings(scene: Scene) -> list[object]:
    """The time factors of the scene (every load, line load and scheduled gravity), with
    ``ramp``, ``table``, ``start`` and ``stop``: where they jump or kink, the steppers land."""
    return [*scene.loads, *scene.line_loads, *_gravity_timing(scene)]


def _gravity_timing(scene: Scene) -> list[_GravityTiming]:
    """Gravity's time factor, when it has one (else none)."""
    sim = scene.simulation
    return [_GravityTiming(sim.gravity_ramp, sim.gravity_table)] if sim.gravity_scheduled else []


@dataclass(frozen=True)
class _GravityTiming:
    """Gravity's time factor in the form of a load's."""

    ramp: float
    table: tuple[tuple[float, float], ...] | None
    start: float = 0.0
    stop: float | None = None


def _segments_on(on: str, scene: Scene, structure: Structure) -> NDArray[np.int64]:
    """Indices of the segments of the rod named ``on``, or of every net thread for "net"."""
    rod_nodes = {name: {structure.selectors[f"{name}:{k}"] for k in range(rod.elements + 1)}
                 for name, rod in ((r.name, r) for r in scene.rods)}
    seg = structure.segments
    if on == "net":
        in_rods = set().union(*rod_nodes.values()) if rod_nodes else set()
        return np.array([k for k, (a, b) in enumerate(seg) if a not in in_rods], dtype=np.int64)
    nodes = rod_nodes[on]
    return np.array([k for k, (a, b) in enumerate(seg) if a in nodes and b in nodes],
                    dtype=np.int64)
